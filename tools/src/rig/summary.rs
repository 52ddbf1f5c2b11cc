//! What a run did, in numbers (`<stamp>-run.json`) and in words.

use super::shared::Shared;
use crate::report::Report;
use crate::state::{ClockState, InsState};
use serde::Serialize;
use spherecal_hal::velodyne::SkipStats;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Counts of a run (also written as `<log dir>/<stamp>-run.json`).
#[derive(Debug, Clone, Default, Serialize)]
pub struct RunSummary {
    /// Seconds run.
    pub seconds: f64,
    /// Datagrams received: data port, position port.
    pub received: [u64; 2],
    /// What each port heard (senders, product, return mode, rpm, PPS, NMEA): data, position.
    pub heard: [super::hearing::Heard; 2],
    /// Times the aligner's windows moved around a converged calibration, and their last
    /// margin beyond the spheres [m] (None: never; the site's a-priori margin throughout).
    pub windows_moved: u64,
    /// ...
    pub live_margin_m: Option<f64>,
    /// ... and where they first moved (None: never).
    pub first_move: Option<FirstMove>,
    /// Datagrams the kernel dropped (socket buffer full): data, position.
    pub kernel_drops: [u64; 2],
    /// Datagrams with a kernel receive time.
    pub kernel_stamped: u64,
    /// Datagrams handed to the aligner's rings: data, position.
    pub enqueued: [u64; 2],
    /// Ring drops: data, position, INS, datagram log, serial log.
    pub ring_drops: [u64; 5],
    /// Datagrams skipped by reason (wrong port, length, bad packet).
    pub skipped: Vec<(String, u64)>,
    /// Data packets aligned and windowed.
    pub data_packets: u64,
    /// Data packets refused because the LiDAR model is unknown or its product byte
    /// disagrees with the packet period (the board's `[lidar] model` or `--model` names it).
    #[serde(default)]
    pub model_refused: u64,
    /// Position packets seen by the aligner.
    pub position_packets: u64,
    /// Data packets the aligner could not time (no RMC and no INS yet).
    pub packets_without_time: u64,
    /// INS bytes read (the serial port's, or a POS MV's UDP payloads).
    pub ins_bytes: u64,
    /// The INS stream: frames, CRC failures, poses used and left out by InsStatus, gaps.
    pub ins: InsState,
    /// The LiDAR clock as its position packets tell it (PPS, RMC validity, stamp - RMC).
    pub clock: ClockState,
    /// ... PPS-locked with valid RMCs that agree with the stamps.
    pub clock_trusted: bool,
    /// The time offset the aligner applied at the end (INS time = LiDAR time + this) [s]:
    /// each converged solve that moves it by more than 1 ms moves the windows with it.
    pub time_offset_s: f64,
    /// Returns in the aligned packets.
    pub returns: u64,
    /// Returns georeferenced (near a window: the rest are only counted).
    pub georeferenced: u64,
    /// Returns not georeferenced: before the pose history, after it, in a gap wider than the
    /// allowed 50 ms.
    pub without_pose: [u64; 3],
    /// Returns windowed per sphere.
    pub windowed: Vec<u64>,
    /// Observations lost because the solver's queue was full.
    pub batch_drops: u64,
    /// Solves run.
    pub solves: u64,
    /// Raw log files written.
    pub log_files: Vec<PathBuf>,
    /// Datagrams and serial reads logged.
    pub logged: [u64; 2],
    /// The last calibration.
    pub calibration: Option<Report>,
    /// Problems met (a reader or the logger stopping early).
    pub errors: Vec<String>,
    /// Warnings said on the console (a silent INS, a silent port, another sender), with the
    /// run's second.
    pub warnings: Vec<String>,
    /// The INS's silences (no usable pose for more than a second): start [s since the
    /// start] and length [s].
    pub ins_silences: Vec<(f64, f64)>,
    /// Bytes that waited in the serial port from before the run: discarded, not framed.
    pub stale_serial_bytes: u64,
    /// Times the serial device went away and was opened again.
    #[serde(default)]
    pub serial_reopened: u64,
}

/// Where the aligner's windows first moved around a calibration: the returns windowed from
/// then on are `windowed` less these, those of data packets `packet` on.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FirstMove {
    /// The first data packet windowed in the new windows (0-based, arrival order: as
    /// `Observation::packet`).
    pub packet: u32,
    /// Returns windowed per sphere before the move.
    pub windowed: Vec<u64>,
}

/// What the threads hand back when a run ends.
pub(super) struct Ended {
    /// Per socket (data, position): skips, and datagrams with kernel receive times.
    pub skips: [(SkipStats, u64); 2],
    /// The serial stream's state.
    pub ins: InsState,
    /// The raw log files and records logged (datagrams, serial reads).
    pub logged: (Vec<PathBuf>, [u64; 2]),
    /// The last calibration.
    pub calibration: Option<Report>,
    /// The aligner's counts.
    pub align: spherecal::align::AlignStats,
    /// The LiDAR clock's state.
    pub clock: ClockState,
}

impl RunSummary {
    /// The summary from what the threads returned and the shared counters.
    pub(super) fn new(e: Ended, sh: &Shared<'_>, started: Instant) -> Self {
        let mut skipped: Vec<(String, u64)> = Vec::new();
        for l in e.skips.iter().flat_map(|s| s.0.lines()) {
            match skipped.iter_mut().find(|s| s.0 == l.reason) {
                Some(s) => s.1 += l.count,
                None => skipped.push((l.reason.to_string(), l.count)),
            }
        }
        let ld = |a: &[AtomicU64; 2]| a.each_ref().map(|x| x.load(Ordering::Relaxed));
        let w = &e.align.window;
        let steer = sh.solver.steer.get();
        Self {
            seconds: started.elapsed().as_secs_f64(),
            received: ld(&sh.readers.received),
            windows_moved: steer.windows_moved,
            live_margin_m: steer.windows.map(|x| x.1),
            first_move: sh.aligner.first_move.lock().ok().and_then(|m| m.clone()),
            heard: sh
                .readers
                .heard
                .each_ref()
                .map(|h| h.lock().map(|h| h.clone()).unwrap_or_default()),
            kernel_drops: ld(&sh.readers.kernel_drops),
            kernel_stamped: e.skips[0].1 + e.skips[1].1,
            enqueued: ld(&sh.readers.enqueued),
            ring_drops: sh.ring_drops.snapshot(),
            skipped,
            data_packets: e.align.data_packets,
            model_refused: e.align.model_refused,
            position_packets: e.align.position_packets,
            packets_without_time: e.align.packets_without_time,
            returns: w.points,
            georeferenced: w.georeferenced,
            without_pose: [w.before_history, w.after_history, w.in_gap],
            ins_bytes: sh.readers.ins_bytes.load(Ordering::Relaxed),
            clock_trusted: e.clock.trusted(),
            clock: e.clock,
            ins: e.ins,
            time_offset_s: steer.time_offset_ns as f64 * 1e-9,
            windowed: sh
                .aligner
                .windowed
                .iter()
                .map(|w| w.load(Ordering::Relaxed))
                .collect(),
            batch_drops: sh.aligner.batch_drops.load(Ordering::Relaxed),
            solves: sh.solver.solves.load(Ordering::Relaxed),
            log_files: e.logged.0,
            logged: e.logged.1,
            calibration: e.calibration,
            warnings: sh
                .said
                .warnings
                .lock()
                .map(|mut v| std::mem::take(&mut *v))
                .unwrap_or_default(),
            ins_silences: sh
                .readers
                .ins_watch
                .silences
                .lock()
                .map(|v| v.clone())
                .unwrap_or_default(),
            stale_serial_bytes: sh.readers.ins_watch.stale_bytes.load(Ordering::Relaxed),
            serial_reopened: sh.readers.ins_watch.reopens.load(Ordering::Relaxed),
            errors: sh
                .said
                .errors
                .lock()
                .map(|mut v| std::mem::take(&mut *v))
                .unwrap_or_default(),
        }
    }
}

/// The run's counts in words (printed when the run ends).
pub fn render(s: &RunSummary) -> String {
    use std::fmt::Write as _;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "run: {:.1} s; datagrams received data {} position {} (kernel drops {}/{}, {} with kernel receive times); enqueued {}/{}; ring drops data {} position {} INS {} log {}/{}",
        s.seconds,
        s.received[0],
        s.received[1],
        s.kernel_drops[0],
        s.kernel_drops[1],
        s.kernel_stamped,
        s.enqueued[0],
        s.enqueued[1],
        s.ring_drops[0],
        s.ring_drops[1],
        s.ring_drops[2],
        s.ring_drops[3],
        s.ring_drops[4]
    );
    for (reason, n) in &s.skipped {
        let _ = writeln!(o, "  skipped {n}: {reason}");
    }
    if s.model_refused > 0 {
        let _ = writeln!(
            o,
            "  NOT aligned {}: data packets of an unknown LiDAR model or whose product byte disagrees with their period (see heard:; set the board's [lidar] model or run --model)",
            s.model_refused
        );
    }
    let _ = writeln!(
        o,
        "aligned {} data packets ({} without time), {} position packets; INS {} bytes; windows {:?}; {} solves",
        s.data_packets,
        s.packets_without_time,
        s.position_packets,
        s.ins_bytes,
        s.windowed,
        s.solves
    );
    if let (Some(m), Some(margin)) = (&s.first_move, s.live_margin_m) {
        let since: Vec<u64> = s
            .windowed
            .iter()
            .zip(&m.windowed)
            .map(|(a, b)| a.saturating_sub(*b))
            .collect();
        let _ = writeln!(
            o,
            "windows: around the calibration from data packet {} (moved {} times, last margin {:.2} m); windowed since {:?}",
            m.packet, s.windows_moved, margin, since
        );
    }
    let _ = writeln!(
        o,
        "clock: {}{}",
        s.clock.describe(),
        if s.clock_trusted {
            ""
        } else {
            " (NOT trusted: not PPS-locked with valid RMCs)"
        }
    );
    if s.ins.posmv.is_some() {
        let _ = writeln!(o, "{}", s.ins.describe());
    } else {
        let _ = writeln!(o, "serial: {}", s.ins.describe());
    }
    let _ = writeln!(
        o,
        "time offset applied at the end: {:+.6} s (INS time = LiDAR time + this)",
        s.time_offset_s
    );
    let _ = writeln!(
        o,
        "{} returns; without a pose: {} before the INS history, {} after it, {} in INS gaps",
        s.returns, s.without_pose[0], s.without_pose[1], s.without_pose[2]
    );
    if !s.ins_silences.is_empty() {
        let listed: Vec<String> = s
            .ins_silences
            .iter()
            .take(8)
            .map(|(a, d)| format!("{d:.1} s from t={a:.1} s"))
            .collect();
        let _ = writeln!(
            o,
            "WARNING: the INS gave no usable pose {} time(s): {}",
            s.ins_silences.len(),
            listed.join(", ")
        );
    }
    if s.stale_serial_bytes > 0 {
        let _ = writeln!(
            o,
            "serial: {} bytes waiting from before the run were discarded",
            s.stale_serial_bytes
        );
    }
    if s.serial_reopened > 0 {
        let _ = writeln!(
            o,
            "serial: the device went away and was opened again {} time(s)",
            s.serial_reopened
        );
    }
    let _ = writeln!(
        o,
        "logged {} datagrams, {} serial reads in {} files",
        s.logged[0],
        s.logged[1],
        s.log_files.len()
    );
    if let Some(r) = &s.calibration {
        o.push_str(&crate::report::render(r, None));
    }
    for e in &s.errors {
        let _ = writeln!(o, "error: {e}");
    }
    o
}

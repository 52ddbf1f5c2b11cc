//! What the rig's threads share: counters and latest values only (no locks on the packet
//! path), the rings' drop counts, and the guards that count a thread out however it ends.

use super::readers::LidarPort;
use super::{hearing, ins_watch, watch};
use spherecal::velodyne::PpsStatus;
use spherecal::vn200::pose::{ins_mode, InsMode};
use spherecal_hal::udp::DropProbe;
use spherecal_hal::velodyne::Ports;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, AtomicU8, AtomicUsize, Ordering};
use std::sync::Mutex;

pub(super) const NONE_U8: u8 = u8::MAX;

/// Items dropped because a ring was full, per ring (the readers never block).
#[derive(Default)]
pub(super) struct RingDrops {
    pub(super) data: AtomicU64,
    pub(super) position: AtomicU64,
    pub(super) ins: AtomicU64,
    pub(super) datagram_log: AtomicU64,
    pub(super) serial_log: AtomicU64,
}

impl RingDrops {
    /// The LiDAR ring of this port's reader.
    pub(super) fn lidar(&self, port: LidarPort) -> &AtomicU64 {
        match port {
            LidarPort::Data => &self.data,
            LidarPort::Position => &self.position,
        }
    }

    /// data, position, INS, datagram log, serial log (the summary's order).
    pub(super) fn snapshot(&self) -> [u64; 5] {
        [
            &self.data,
            &self.position,
            &self.ins,
            &self.datagram_log,
            &self.serial_log,
        ]
        .map(|a| a.load(Ordering::Relaxed))
    }
}

/// What the threads share, grouped by the thread that writes it (counters and latest values:
/// no locks on the packet path); each group is read by the status line and the summary.
pub(super) struct Shared<'a> {
    /// Set by the status thread (SIGINT, SIGTERM, `--duration`) or a failing thread.
    pub(super) stop: &'a AtomicBool,
    /// The readers' counts.
    pub(super) readers: ReadersOut,
    /// The aligner's.
    pub(super) aligner: AlignerOut,
    /// The solver's.
    pub(super) solver: SolverOut,
    /// Items dropped by full rings (the readers' and the logger's).
    pub(super) ring_drops: RingDrops,
    /// The logger has written everything it was given.
    pub(super) logger_done: AtomicBool,
    /// Errors and warnings said on the console.
    pub(super) said: Said,
}

/// What the readers write.
pub(super) struct ReadersOut {
    /// Readers still running (the logger runs until every reader is out).
    pub(super) running: AtomicUsize,
    /// Datagrams received per LiDAR port (data, position).
    pub(super) received: [AtomicU64; 2],
    /// ... and put on the aligner's rings.
    pub(super) enqueued: [AtomicU64; 2],
    /// The kernel's own drops per socket (read through `drop_probes`).
    pub(super) kernel_drops: [AtomicU64; 2],
    pub(super) drop_probes: [DropProbe; 2],
    /// INS bytes read.
    pub(super) ins_bytes: AtomicU64,
    /// The INS's latest mode ([`NONE_U8`]: none yet).
    pub(super) ins_mode: AtomicU8,
    /// What each port hears: data, position.
    pub(super) heard: [Mutex<hearing::Heard>; 2],
    /// Whether the INS speaks.
    pub(super) ins_watch: ins_watch::InsWatch,
}

/// What the aligner writes.
pub(super) struct AlignerOut {
    /// Set when the aligner's loop is left ([`AlignerGuard`]).
    pub(super) gone: AtomicBool,
    /// The latest PPS status ([`NONE_U8`]: none yet).
    pub(super) pps: AtomicU8,
    /// The latest packet's lag behind the INS [ns] (`i64::MIN`: none yet).
    pub(super) lag_ns: AtomicI64,
    /// Data packets aligned.
    pub(super) aligned: AtomicU64,
    /// Returns windowed per sphere.
    pub(super) windowed: Vec<AtomicU64>,
    /// When the windows first moved around a calibration (set once).
    pub(super) first_move: Mutex<Option<super::summary::FirstMove>>,
    /// Returns that got no pose so far.
    pub(super) without_pose: AtomicU64,
    /// Returns dropped because the solver's batch channel was full.
    pub(super) batch_drops: AtomicU64,
    /// The LiDAR clock as the position packets told it so far and the LiDAR data's first GPS
    /// time [s] (the solver's clock facts read them).
    pub(super) clock: Mutex<(crate::state::ClockState, Option<f64>)>,
}

/// What the solver writes.
pub(super) struct SolverOut {
    /// Solves run.
    pub(super) solves: AtomicU64,
    /// The solve under way (`r<N>`: its round N) or how the last one ended (`<how>:<rounds>`).
    pub(super) solve_state: Mutex<String>,
    /// The latest calibration: the parameters and their sigmas (deg, m).
    pub(super) calibration: Mutex<Option<([f64; 6], [f64; 6])>>,
    /// The back-edge: the time offset and windows the solver tells the aligner to use.
    pub(super) steer: watch::Watch<watch::Steer>,
    /// The latest estimate of the time offset and its sigma [s].
    pub(super) time_offset: Mutex<Option<(f64, f64)>>,
    /// The verdict after the latest solve.
    pub(super) verdict: Mutex<Option<crate::verdict::Verdict>>,
}

/// Errors and warnings said on the console (run.json keeps them).
#[derive(Default)]
pub(super) struct Said {
    pub(super) errors: Mutex<Vec<String>>,
    pub(super) warnings: Mutex<Vec<String>>,
}

/// A reader thread's handle (as embassy-sync's `Watch` hands each task its sender or
/// receiver): what it writes, its counts, the rings' drops and its errors, and what it reads,
/// the stop and the aligner's end.
#[derive(Clone, Copy)]
pub(super) struct ReaderHandle<'s> {
    pub(super) readers: &'s ReadersOut,
    pub(super) ring_drops: &'s RingDrops,
    pub(super) aligner: &'s AlignerOut,
    pub(super) stop: &'s AtomicBool,
    pub(super) said: &'s Said,
}

/// The logger's and the syncer's handle: the log rings' drops, its end and its errors, and
/// the readers still running.
#[derive(Clone, Copy)]
pub(super) struct LoggerHandle<'s> {
    pub(super) readers: &'s ReadersOut,
    pub(super) ring_drops: &'s RingDrops,
    pub(super) logger_done: &'s AtomicBool,
    pub(super) said: &'s Said,
}

/// The aligner's handle: what it writes, and the solver's steer it reads.
#[derive(Clone, Copy)]
pub(super) struct AlignerHandle<'s> {
    pub(super) aligner: &'s AlignerOut,
    pub(super) solver: &'s SolverOut,
}

/// The solver's handle: what it writes and its errors, and what it reads: what the ports
/// hear and the INS watch (the readers'), the LiDAR clock (the aligner's).
#[derive(Clone, Copy)]
pub(super) struct SolverHandle<'s> {
    pub(super) solver: &'s SolverOut,
    pub(super) readers: &'s ReadersOut,
    pub(super) aligner: &'s AlignerOut,
    pub(super) said: &'s Said,
}

/// Counts a reader out however it ends (the logger runs until every reader is out).
pub(super) struct ReaderGuard<'s>(pub(super) &'s ReadersOut);

impl Drop for ReaderGuard<'_> {
    fn drop(&mut self) {
        self.0.running.fetch_sub(1, Ordering::Release);
    }
}

/// Set when the aligner's loop is left, by its end or by a panic: readers stop waiting to
/// hand it their End, and (on a panic) everything stops.
pub(super) struct AlignerGuard<'s, 'a>(pub(super) &'s Shared<'a>);

impl Drop for AlignerGuard<'_, '_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.said.error("the aligner failed; stopping".into());
            self.0.stop.store(true, Ordering::Relaxed);
        }
        self.0.aligner.gone.store(true, Ordering::Release);
    }
}

impl<'a> Shared<'a> {
    /// A reader thread's handle.
    pub(super) fn reader(&self) -> ReaderHandle<'_> {
        ReaderHandle {
            readers: &self.readers,
            ring_drops: &self.ring_drops,
            aligner: &self.aligner,
            stop: self.stop,
            said: &self.said,
        }
    }

    /// The logger's handle.
    pub(super) fn logger(&self) -> LoggerHandle<'_> {
        LoggerHandle {
            readers: &self.readers,
            ring_drops: &self.ring_drops,
            logger_done: &self.logger_done,
            said: &self.said,
        }
    }

    /// The aligner's handle.
    pub(super) fn aligner(&self) -> AlignerHandle<'_> {
        AlignerHandle {
            aligner: &self.aligner,
            solver: &self.solver,
        }
    }

    /// The solver's handle.
    pub(super) fn solver(&self) -> SolverHandle<'_> {
        SolverHandle {
            solver: &self.solver,
            readers: &self.readers,
            aligner: &self.aligner,
            said: &self.said,
        }
    }

    /// Nothing counted yet; `readers` threads to wait for, `spheres` windows, the two sockets'
    /// kernel drop counts read through `drop_probes`; an Ouster's packet format, columns per
    /// frame and IMU port for what the ports hear.
    pub(super) fn new(
        stop: &'a AtomicBool,
        readers: usize,
        spheres: usize,
        drop_probes: [DropProbe; 2],
        (ports, ouster): (Ports, Option<(spherecal::ouster::Format, u32, u16)>),
    ) -> Self {
        let mut heard = [ports.data, ports.position].map(hearing::Heard::new);
        heard[0].ouster_format = ouster.map(|(f, w, _)| (f, w));
        heard[1].ouster_imu = ouster.is_some_and(|(_, _, imu)| imu == ports.position);
        Self {
            stop,
            readers: ReadersOut {
                running: AtomicUsize::new(readers),
                received: Default::default(),
                enqueued: Default::default(),
                kernel_drops: Default::default(),
                drop_probes,
                ins_bytes: AtomicU64::new(0),
                ins_mode: AtomicU8::new(NONE_U8),
                heard: heard.map(Mutex::new),
                ins_watch: ins_watch::InsWatch::default(),
            },
            aligner: AlignerOut {
                gone: AtomicBool::new(false),
                pps: AtomicU8::new(NONE_U8),
                lag_ns: AtomicI64::new(i64::MIN),
                aligned: AtomicU64::new(0),
                windowed: (0..spheres).map(|_| AtomicU64::new(0)).collect(),
                first_move: Mutex::new(None),
                without_pose: AtomicU64::new(0),
                batch_drops: AtomicU64::new(0),
                clock: Mutex::new((crate::state::ClockState::default(), None)),
            },
            solver: SolverOut {
                solves: AtomicU64::new(0),
                solve_state: Mutex::new(String::new()),
                calibration: Mutex::new(None),
                steer: watch::Watch::new(),
                time_offset: Mutex::new(None),
                verdict: Mutex::new(None),
            },
            ring_drops: Default::default(),
            logger_done: AtomicBool::new(false),
            said: Said::default(),
        }
    }
}

impl ReadersOut {
    /// Read the sockets' kernel drop counts (a closed socket keeps its last count).
    pub(super) fn poll_kernel_drops(&self) {
        for (p, k) in self.drop_probes.iter().zip(&self.kernel_drops) {
            if let Some(n) = p.read() {
                k.store(n, Ordering::Relaxed);
            }
        }
    }
}

impl Said {
    /// An error, said in the summary (run.json keeps them).
    pub(super) fn error(&self, e: String) {
        if let Ok(mut v) = self.errors.lock() {
            v.push(e);
        }
    }

    /// A warning said on the console, kept for run.json (the first 200).
    pub(super) fn warn(&self, w: String) {
        if let Ok(mut v) = self.warnings.lock() {
            if v.len() < 200 {
                v.push(w);
            }
        }
    }
}

pub(super) fn pps_name(b: u8) -> &'static str {
    match b {
        NONE_U8 => "none",
        b => match PpsStatus::from(b) {
            PpsStatus::Absent => "absent",
            PpsStatus::Synchronizing => "syncing",
            PpsStatus::Locked => "locked",
            PpsStatus::Error => "error",
            PpsStatus::Unknown(_) => "unknown",
        },
    }
}

pub(super) fn ins_name(b: u8) -> &'static str {
    match b {
        NONE_U8 => "none",
        b => match ins_mode(u16::from(b)) {
            InsMode::NotTracking => "not-tracking",
            InsMode::Aligning => "aligning",
            InsMode::Tracking => "tracking",
            InsMode::GnssLost => "gnss-lost",
        },
    }
}

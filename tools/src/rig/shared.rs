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

/// What the threads share (counters only: no locks on the packet path).
pub(super) struct Shared<'a> {
    pub(super) stop: &'a AtomicBool,
    pub(super) readers: AtomicUsize,
    pub(super) aligner_gone: AtomicBool,
    pub(super) logger_done: AtomicBool,
    pub(super) received: [AtomicU64; 2],
    pub(super) enqueued: [AtomicU64; 2],
    pub(super) kernel_drops: [AtomicU64; 2],
    pub(super) drop_probes: [DropProbe; 2],
    pub(super) ring_drops: RingDrops,
    pub(super) ins_bytes: AtomicU64,
    pub(super) pps: AtomicU8,
    pub(super) ins_mode: AtomicU8,
    pub(super) lag_ns: AtomicI64,
    pub(super) aligned: AtomicU64,
    pub(super) windowed: Vec<AtomicU64>,
    pub(super) batch_drops: AtomicU64,
    pub(super) solves: AtomicU64,
    /// The solve under way (`r<N>`: its round N) or how the last one ended (`<how>:<rounds>`).
    pub(super) solve_state: Mutex<String>,
    pub(super) calibration: Mutex<Option<([f64; 6], [f64; 6])>>,
    /// The back-edge: the time offset and windows the solver tells the aligner to use.
    pub(super) steer: watch::Watch<watch::Steer>,
    /// The latest estimate of the time offset and its sigma [s].
    pub(super) time_offset: Mutex<Option<(f64, f64)>>,
    pub(super) errors: Mutex<Vec<String>>,
    /// What each port hears: data, position.
    pub(super) heard: [Mutex<hearing::Heard>; 2],
    /// The verdict after the latest solve.
    pub(super) verdict: Mutex<Option<crate::verdict::Verdict>>,
    /// Whether the INS speaks.
    pub(super) ins_watch: ins_watch::InsWatch,
    /// Returns that got no pose so far.
    pub(super) without_pose: AtomicU64,
    /// Warnings said on the console (run.json keeps them).
    pub(super) warnings: Mutex<Vec<String>>,
    /// The LiDAR clock as the position packets told it so far and the LiDAR data's first GPS
    /// time [s] (the aligner publishes them, the solver's clock facts read them).
    pub(super) clock: Mutex<(crate::state::ClockState, Option<f64>)>,
}

/// Counts a reader out however it ends (the logger runs until every reader is out).
pub(super) struct ReaderGuard<'s, 'a>(pub(super) &'s Shared<'a>);

impl Drop for ReaderGuard<'_, '_> {
    fn drop(&mut self) {
        self.0.readers.fetch_sub(1, Ordering::Release);
    }
}

/// Set when the aligner's loop is left, by its end or by a panic: readers stop waiting to
/// hand it their End, and (on a panic) everything stops.
pub(super) struct AlignerGuard<'s, 'a>(pub(super) &'s Shared<'a>);

impl Drop for AlignerGuard<'_, '_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.error("the aligner failed; stopping".into());
            self.0.stop.store(true, Ordering::Relaxed);
        }
        self.0.aligner_gone.store(true, Ordering::Release);
    }
}

impl<'a> Shared<'a> {
    /// Nothing counted yet; `readers` threads to wait for, `spheres` windows, the two sockets'
    /// kernel drop counts read through `drop_probes`.
    pub(super) fn new(
        stop: &'a AtomicBool,
        readers: usize,
        spheres: usize,
        drop_probes: [DropProbe; 2],
        ports: Ports,
    ) -> Self {
        Self {
            stop,
            readers: AtomicUsize::new(readers),
            aligner_gone: AtomicBool::new(false),
            logger_done: AtomicBool::new(false),
            received: Default::default(),
            enqueued: Default::default(),
            kernel_drops: Default::default(),
            drop_probes,
            ring_drops: Default::default(),
            ins_bytes: AtomicU64::new(0),
            pps: AtomicU8::new(NONE_U8),
            ins_mode: AtomicU8::new(NONE_U8),
            lag_ns: AtomicI64::new(i64::MIN),
            aligned: AtomicU64::new(0),
            windowed: (0..spheres).map(|_| AtomicU64::new(0)).collect(),
            batch_drops: AtomicU64::new(0),
            solves: AtomicU64::new(0),
            solve_state: Mutex::new(String::new()),
            calibration: Mutex::new(None),
            steer: watch::Watch::new(),
            time_offset: Mutex::new(None),
            errors: Mutex::new(Vec::new()),
            heard: [ports.data, ports.position].map(|p| Mutex::new(hearing::Heard::new(p))),
            verdict: Mutex::new(None),
            ins_watch: ins_watch::InsWatch::default(),
            without_pose: AtomicU64::new(0),
            clock: Mutex::new((crate::state::ClockState::default(), None)),
            warnings: Mutex::new(Vec::new()),
        }
    }

    /// Read the sockets' kernel drop counts (a closed socket keeps its last count).
    pub(super) fn poll_kernel_drops(&self) {
        for (p, k) in self.drop_probes.iter().zip(&self.kernel_drops) {
            if let Some(n) = p.read() {
                k.store(n, Ordering::Relaxed);
            }
        }
    }

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

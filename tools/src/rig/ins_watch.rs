//! Whether the INS is speaking: when its reader last handed over a usable pose and last read
//! any bytes, and the silences the status loop says in words (a WARNING when a silence passes
//! [`SILENT_MS`], again every [`SILENT_AGAIN_S`], and when the poses come back) and records
//! in `run.json`.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// An INS silent this long is a WARNING [ms] (a VN-200 sends 200 poses a second).
pub const SILENT_MS: u64 = 1_000;
/// A silence that goes on is said again this often [s].
pub const SILENT_AGAIN_S: f64 = 10.0;

/// The INS reader's last signs of life, in ms since `origin` (`u64::MAX`: none yet).
pub struct InsWatch {
    origin: Instant,
    pose_ms: AtomicU64,
    bytes_ms: AtomicU64,
    /// Silences: start [s since the origin] and length [s].
    pub silences: Mutex<Vec<(f64, f64)>>,
    /// Bytes that waited in the serial port's buffer from before the run, discarded.
    pub stale_bytes: AtomicU64,
    /// Since when the serial device has been gone [ms since the origin] (`u64::MAX`: it is
    /// there).
    lost_ms: AtomicU64,
    /// Times the serial device was opened again after it went away.
    pub reopens: AtomicU64,
    /// What the reader has to say on the console (device lost, reopened), taken by the status
    /// loop.
    said: Mutex<Vec<String>>,
    /// The INS clock's steps so far (GPS s, step s), for the solver's clock facts.
    steps: Mutex<Vec<(f64, f64)>>,
}

/// What the INS is doing, for the status line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speaking {
    /// Usable poses within the last second (or the run has just started).
    Yes,
    /// No usable pose for this long [s], and no bytes either.
    Silent(f64),
    /// Bytes, but no usable pose for this long [s] (frames the aligner cannot use: not
    /// tracking, no pose fields, corrupt).
    Unusable(f64),
    /// The serial device went away this long ago [s] (a USB adapter unplugged or
    /// re-enumerating): the reader is opening it again.
    Lost(f64),
}

impl Default for InsWatch {
    fn default() -> Self {
        Self {
            origin: Instant::now(),
            pose_ms: AtomicU64::new(u64::MAX),
            bytes_ms: AtomicU64::new(u64::MAX),
            silences: Mutex::new(Vec::new()),
            stale_bytes: AtomicU64::new(0),
            lost_ms: AtomicU64::new(u64::MAX),
            reopens: AtomicU64::new(0),
            said: Mutex::new(Vec::new()),
            steps: Mutex::new(Vec::new()),
        }
    }
}

impl InsWatch {
    /// The INS clock's steps as the reader found them so far.
    pub fn set_clock_steps(&self, steps: &[(f64, f64)]) {
        if let Ok(mut s) = self.steps.lock() {
            s.clear();
            s.extend_from_slice(steps);
        }
    }

    /// See [`Self::set_clock_steps`].
    pub fn clock_steps(&self) -> Vec<(f64, f64)> {
        self.steps.lock().map(|s| s.clone()).unwrap_or_default()
    }

    fn now_ms(&self) -> u64 {
        self.origin.elapsed().as_millis() as u64
    }

    /// A usable pose went to the aligner.
    pub fn pose(&self) {
        self.pose_ms.store(self.now_ms(), Ordering::Relaxed);
    }

    /// Bytes (or a datagram) arrived.
    pub fn bytes(&self) {
        self.bytes_ms.store(self.now_ms(), Ordering::Relaxed);
    }

    /// The serial device went away (`line`: the words for the console).
    pub fn lost(&self, line: String) {
        self.lost_ms.store(self.now_ms(), Ordering::Relaxed);
        self.say(line);
    }

    /// The serial device is back (`line`: the words for the console).
    pub fn reopened(&self, line: String) {
        self.lost_ms.store(u64::MAX, Ordering::Relaxed);
        self.reopens.fetch_add(1, Ordering::Relaxed);
        self.say(line);
    }

    fn say(&self, line: String) {
        if let Ok(mut v) = self.said.lock() {
            v.push(line);
        }
    }

    /// The lines the reader left to say.
    pub fn take_said(&self) -> Vec<String> {
        self.said
            .lock()
            .map(|mut v| std::mem::take(&mut *v))
            .unwrap_or_default()
    }

    /// Seconds since the origin.
    pub fn now_s(&self) -> f64 {
        self.origin.elapsed().as_secs_f64()
    }

    /// What the INS is doing now.
    pub fn speaking(&self) -> Speaking {
        let now = self.now_ms();
        let since = |at: u64| {
            if at == u64::MAX {
                now
            } else {
                now.saturating_sub(at)
            }
        };
        let (pose, bytes) = (
            since(self.pose_ms.load(Ordering::Relaxed)),
            since(self.bytes_ms.load(Ordering::Relaxed)),
        );
        let lost = self.lost_ms.load(Ordering::Relaxed);
        if lost != u64::MAX {
            Speaking::Lost(since(lost) as f64 * 1e-3)
        } else if pose <= SILENT_MS {
            Speaking::Yes
        } else if bytes <= SILENT_MS {
            Speaking::Unusable(pose as f64 * 1e-3)
        } else {
            Speaking::Silent(pose as f64 * 1e-3)
        }
    }
}

/// The status loop's memory of a silence: when it started, when it was last said.
#[derive(Debug, Default)]
pub struct SilenceTalk {
    since: Option<f64>,
    said: f64,
    returns_at_start: u64,
}

impl SilenceTalk {
    /// The words for this tick, if any: the INS `now` (from `w`), `without_pose` returns so
    /// far. Records a silence that ended.
    pub fn tick(&mut self, w: &InsWatch, now: Speaking, without_pose: u64) -> Option<String> {
        let t = w.now_s();
        match (now, self.since) {
            (Speaking::Yes, None) => None,
            (Speaking::Yes, Some(start)) => {
                self.since = None;
                let len = t - start;
                if let Ok(mut v) = w.silences.lock() {
                    v.push((start, len));
                }
                Some(format!(
                    "INS back after {len:.1} s without a usable pose ({} returns had none)",
                    without_pose.saturating_sub(self.returns_at_start)
                ))
            }
            (Speaking::Silent(s) | Speaking::Unusable(s) | Speaking::Lost(s), None) => {
                let start = t - s;
                self.since = Some(start);
                self.said = t;
                self.returns_at_start = without_pose;
                Some(format!(
                    "WARNING: {} {s:.1} s (since t={start:.1} s): returns get no pose and are not georeferenced meanwhile; check the INS's cable, power and output",
                    match now {
                        Speaking::Silent(_) => "the INS has been silent for",
                        Speaking::Lost(_) => "the INS's serial device has been gone for",
                        _ => "the INS sends nothing usable (no pose, or not tracking) for",
                    }
                ))
            }
            (Speaking::Silent(s) | Speaking::Unusable(s) | Speaking::Lost(s), Some(_)) => {
                (t - self.said >= SILENT_AGAIN_S).then(|| {
                    self.said = t;
                    format!(
                        "WARNING: the INS is still {} ({s:.1} s; {} returns without a pose)",
                        match now {
                            Speaking::Silent(_) => "silent",
                            Speaking::Lost(_) => "gone (its serial device: opening it again)",
                            _ => "unusable",
                        },
                        without_pose.saturating_sub(self.returns_at_start)
                    )
                })
            }
        }
    }

    /// At the end of the run: a silence still going on is recorded.
    pub fn close(&mut self, w: &InsWatch) {
        if let Some(start) = self.since.take() {
            if let Ok(mut v) = w.silences.lock() {
                v.push((start, w.now_s() - start));
            }
        }
    }
}

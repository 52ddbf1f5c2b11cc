//! Time for code that waits (embassy's `Instant`/`Timer` split, in small): the host's clocks,
//! or a mock clock that only moves when told, so that pacing and deadlines are tested without
//! sleeping.

pub use spherecal::time::HostTime;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::sync::OnceLock;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Monotonic nanoseconds since the first call in this process.
pub fn monotonic_ns() -> u64 {
    static BASE: OnceLock<Instant> = OnceLock::new();
    let base = BASE.get_or_init(Instant::now);
    u64::try_from(base.elapsed().as_nanos()).unwrap_or(u64::MAX)
}

/// The host's wall clock now (negative before 1970).
pub fn wall() -> HostTime {
    HostTime(match SystemTime::now().duration_since(UNIX_EPOCH) {
        Ok(d) => i64::try_from(d.as_nanos()).unwrap_or(i64::MAX),
        Err(e) => -i64::try_from(e.duration().as_nanos()).unwrap_or(i64::MAX),
    })
}

/// A clock that can be read and waited on.
pub trait Clock: Sync {
    /// Monotonic nanoseconds since an arbitrary start.
    fn mono_ns(&self) -> u64;
    /// The wall clock.
    fn wall(&self) -> HostTime;
    /// Block for `d`.
    fn sleep(&self, d: Duration);
}

/// The host's clocks: [`monotonic_ns`], [`wall`] and a real sleep.
#[derive(Debug, Clone, Copy, Default)]
pub struct SystemClock;

impl Clock for SystemClock {
    fn mono_ns(&self) -> u64 {
        monotonic_ns()
    }
    fn wall(&self) -> HostTime {
        wall()
    }
    fn sleep(&self, d: Duration) {
        std::thread::sleep(d);
    }
}

/// A clock that moves only by [`MockClock::advance`] and by its own `sleep` (which advances it
/// by exactly the time asked for and returns at once).
#[derive(Debug, Default)]
pub struct MockClock {
    mono: AtomicU64,
    wall: AtomicI64,
}

impl MockClock {
    /// A clock at monotonic 0 and wall-clock `wall`.
    pub fn new(wall: HostTime) -> Self {
        Self {
            mono: AtomicU64::new(0),
            wall: AtomicI64::new(wall.0),
        }
    }

    /// Move both clocks on by `d`.
    pub fn advance(&self, d: Duration) {
        let ns = u64::try_from(d.as_nanos()).unwrap_or(u64::MAX);
        self.mono.fetch_add(ns, Ordering::SeqCst);
        self.wall
            .fetch_add(i64::try_from(ns).unwrap_or(i64::MAX), Ordering::SeqCst);
    }
}

impl Clock for MockClock {
    fn mono_ns(&self) -> u64 {
        self.mono.load(Ordering::SeqCst)
    }
    fn wall(&self) -> HostTime {
        HostTime(self.wall.load(Ordering::SeqCst))
    }
    fn sleep(&self, d: Duration) {
        self.advance(d);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mock_moves_only_when_told() {
        let c = MockClock::new(HostTime(1_000));
        assert_eq!((c.mono_ns(), c.wall().0), (0, 1_000));
        c.sleep(Duration::from_millis(3));
        c.advance(Duration::from_nanos(7));
        assert_eq!((c.mono_ns(), c.wall().0), (3_000_007, 3_001_007));
    }
}

//! A latest-value cell with a version (embassy-sync's `Watch` pattern, for threads): one
//! sender publishes, each receiver sees the latest value once after every change. The rig's
//! one back-edge, solver -> aligner, is a [`Watch<Steer>`].

use spherecal::georef::Params;
use std::sync::Mutex;

/// What the solver tells the aligner after a converged solve.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Steer {
    /// The time offset to apply to the LiDAR clock [ns].
    pub time_offset_ns: i64,
    /// The windows around a converged solution: its parameters [rad, m] and the margin
    /// beyond the spheres [m] (None: the a-priori windows).
    pub windows: Option<(Params, f64)>,
    /// How many times the windows moved.
    pub windows_moved: u64,
}

/// The cell: the latest value and how many values were sent.
#[derive(Debug, Default)]
pub struct Watch<T> {
    cell: Mutex<(u64, T)>,
}

impl<T: Clone + Default> Watch<T> {
    /// Holding `T::default()`, version 0.
    pub fn new() -> Self {
        Self {
            cell: Mutex::new((0, T::default())),
        }
    }

    /// Publish the value `f` makes from the current one, if it makes one.
    pub fn send_if(&self, f: impl FnOnce(&T) -> Option<T>) {
        if let Ok(mut c) = self.cell.lock() {
            if let Some(v) = f(&c.1) {
                *c = (c.0 + 1, v);
            }
        }
    }

    /// The latest value.
    pub fn get(&self) -> T {
        self.cell.lock().map(|c| c.1.clone()).unwrap_or_default()
    }

    /// A receiver that has seen nothing yet.
    pub fn receiver(&self) -> Receiver<'_, T> {
        Receiver {
            watch: self,
            seen: 0,
        }
    }
}

/// One reader of a [`Watch`].
#[derive(Debug)]
pub struct Receiver<'a, T> {
    watch: &'a Watch<T>,
    seen: u64,
}

impl<T: Clone + Default> Receiver<'_, T> {
    /// The latest value if it changed since this receiver last looked.
    pub fn changed(&mut self) -> Option<T> {
        let c = self.watch.cell.lock().ok()?;
        (c.0 != self.seen).then(|| {
            self.seen = c.0;
            c.1.clone()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_change_is_seen_once_and_only_the_latest() {
        let w: Watch<u32> = Watch::new();
        let mut r = w.receiver();
        assert_eq!(r.changed(), None);
        w.send_if(|_| Some(1));
        w.send_if(|v| Some(v + 1));
        assert_eq!(r.changed(), Some(2));
        assert_eq!(r.changed(), None);
        w.send_if(|_| None);
        assert_eq!(r.changed(), None);
        let mut late = w.receiver();
        assert_eq!(late.changed(), Some(2));
        assert_eq!(w.get(), 2);
    }

    #[test]
    fn a_receiver_on_another_thread_sees_the_change() {
        let w: Watch<u32> = Watch::new();
        std::thread::scope(|s| {
            let mut r = w.receiver();
            s.spawn(|| w.send_if(|_| Some(7)));
            let t0 = std::time::Instant::now();
            loop {
                if let Some(v) = r.changed() {
                    assert_eq!(v, 7);
                    break;
                }
                assert!(t0.elapsed().as_secs() < 5);
                std::thread::yield_now();
            }
        });
    }
}

//! The solver's scratch: the core's fixed-capacity workspace, allocated once and lent to each
//! solve (the rig keeps one for all its solves).

use spherecal::align::window::Observation;
use spherecal::calib::consensus::Candidate;
use spherecal::calib::fork::Fork;
use spherecal::calib::nav::Row;
use spherecal::calib::room::Room;
use spherecal::calib::solve::{Helper, Workspace};

/// Cells of the detection's vote grid (64^3: 512 KB).
pub const GRID_CELLS: usize = 64 * 64 * 64;
/// Kept returns a detect-and-solve round solves on at most (8.6 MB).
pub const KEPT_CAPACITY: usize = 50_000;
/// Returns in one slice of time at most (longer ones are split).
pub const SLICE_CAPACITY: usize = 32_768;

/// The first round's candidates at most (four per slice of 0.4 s: 16 spheres seen for 100 s).
pub const CANDIDATE_CAPACITY: usize = 16_384;

/// The solver's scratch, owned.
#[derive(Debug, Clone)]
pub struct Scratch {
    grid: Vec<u16>,
    kept: Growing<Observation>,
    keys: Vec<spherecal::calib::extract::Key>,
    cands: Growing<Candidate>,
    idx: Growing<usize>,
    nav: Growing<spherecal::calib::nav::Piece>,
    /// The second worker's detection scratch ([`Scratch::with_helper`]).
    helper: Option<Lane>,
}

/// A second worker's scratch: its vote grid, slice index and candidate room, and the
/// navigation model's rows.
#[derive(Debug, Clone)]
struct Lane {
    grid: Vec<u16>,
    keys: Vec<spherecal::calib::extract::Key>,
    cands: Growing<Candidate>,
    rows: Growing<Row>,
}

/// The navigation model's rows made in one turn of the final fit's two workers (~250 B each:
/// up to 4 MB, written as a solve uses it; table1-real's 2,421 rows take one turn).
pub const NAV_ROWS: usize = 16_384;

/// Runs the second piece of work on a thread of its own, the first on the caller's.
#[derive(Debug, Clone, Copy, Default)]
pub struct Threads;

impl Fork for Threads {
    fn join(&self, a: &mut dyn FnMut(), b: &mut (dyn FnMut() + Send)) {
        std::thread::scope(|s| {
            s.spawn(b);
            a();
        });
    }
}

/// Room that grows on use up to a capacity, written as it grows: a survey of a few minutes
/// uses a few MB of the 22 MB the kept returns, the candidates and the navigation pieces could
/// need, and writing all of it up front took 4-13 ms of every `calibrate` (table1,
/// table1-real).
#[derive(Debug, Clone)]
struct Growing<T> {
    items: Vec<T>,
    capacity: usize,
    fill: T,
}

impl<T: Clone> Growing<T> {
    fn new(capacity: usize, fill: T) -> Self {
        Self {
            items: Vec::new(),
            capacity,
            fill,
        }
    }
}

impl<T: Clone + std::fmt::Debug> Room<T> for Growing<T> {
    fn room(&mut self, n: usize) -> &mut [T] {
        let k = n.min(self.capacity);
        if self.items.len() < k {
            self.items.resize(k, self.fill.clone());
        }
        &mut self.items[..k]
    }
}

/// Pieces of the navigation model's time line (each ~10 kB; 0.25-0.5 s each: 1,024 hold
/// 4-8 minutes of sphere returns).
pub const NAV_PIECES: usize = 1024;

impl Default for Scratch {
    /// With the navigation model's pieces.
    fn default() -> Self {
        Self::with_pieces(NAV_PIECES)
    }
}

impl Scratch {
    /// For solves under `s`: room for the navigation model's pieces (up to 10 MB, written as
    /// a solve uses them) only when `s` has one.
    pub fn for_settings(s: &spherecal::calib::Settings) -> Self {
        Self::with_pieces(if s.nav.is_some() { NAV_PIECES } else { 0 })
    }

    fn with_pieces(pieces: usize) -> Self {
        Self {
            grid: vec![0; GRID_CELLS],
            kept: Growing::new(KEPT_CAPACITY, Observation::default()),
            keys: vec![Default::default(); SLICE_CAPACITY],
            cands: Growing::new(CANDIDATE_CAPACITY, Candidate::default()),
            idx: Growing::new(CANDIDATE_CAPACITY, 0),
            nav: Growing::new(pieces, spherecal::calib::nav::Piece::EMPTY),
            helper: None,
        }
    }

    /// With a second worker on its own thread for the per-sphere work and the navigation
    /// model's rows (the solve's answer is the same, in less time on two cores): 1 MB more, and
    /// up to 4 MB for the rows under a navigation model.
    pub fn with_helper(mut self) -> Self {
        self.helper = Some(Lane {
            grid: vec![0; GRID_CELLS],
            keys: vec![Default::default(); SLICE_CAPACITY],
            cands: Growing::new(CANDIDATE_CAPACITY, Candidate::default()),
            rows: Growing::new(NAV_ROWS, Row::EMPTY),
        });
        self
    }

    /// The workspace the core's solve borrows.
    pub fn workspace(&mut self) -> Workspace<'_> {
        Workspace {
            grid: &mut self.grid,
            kept: &mut self.kept,
            keys: &mut self.keys,
            cands: &mut self.cands,
            idx: &mut self.idx,
            nav: &mut self.nav,
            helper: self.helper.as_mut().map(|h| Helper {
                fork: &Threads,
                grid: &mut h.grid,
                keys: &mut h.keys,
                cands: &mut h.cands,
                rows: &mut h.rows,
            }),
        }
    }

    /// The navigation model's pieces the last solve left (its `Solution::nav` says how many).
    pub fn nav_pieces(&self) -> &[spherecal::calib::nav::Piece] {
        &self.nav.items
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn room_grows_on_use_to_its_capacity_and_keeps_what_it_grew() {
        let mut g = Growing::new(5, 0u8);
        assert!(g.items.is_empty(), "nothing written before a use");
        g.room(2).fill(7);
        assert_eq!(g.items, [7, 7]);
        assert_eq!(g.room(1), &[7]);
        assert_eq!(g.room(9).len(), 5);
        assert_eq!(g.items, [7, 7, 0, 0, 0]);
    }

    #[test]
    fn a_white_solve_writes_no_navigation_pieces() {
        let mut s = Scratch::for_settings(&spherecal::calib::Settings::default());
        assert!(s.workspace().nav.room(10).is_empty());
        assert!(s.nav_pieces().is_empty());
    }
}

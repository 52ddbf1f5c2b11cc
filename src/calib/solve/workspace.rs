//! The scratch the caller lends the solve ([`Workspace`]) and its second worker ([`Helper`]):
//! the per-sphere work split in two groups of spheres of about equal returns, the second on the
//! helper's lane beside the first ([`side_by_side`]); without a helper all in the first.

use crate::align::window::Observation;
use crate::calib::consensus::Candidate;
use crate::calib::extract;
use crate::calib::fork::Fork;
use crate::calib::room::Room;

/// The solver's scratch, from the caller (no heap in the core).
#[derive(Debug)]
pub struct Workspace<'a> {
    /// The detection's vote grid, all zero (64^3 = 262,144 cells suit windows of a few metres;
    /// fewer cells make coarser votes).
    pub grid: &'a mut [u16],
    /// Room for the kept returns of a round (all spheres; 50,000 are ample); a round that keeps
    /// more solves on an evenly spread subset (the last solve always uses every kept return).
    pub kept: &'a mut dyn Room<Observation>,
    /// A slice's index by x; its length caps a slice's returns (32,768 is ample: 0.4 s of a
    /// window rarely holds 10,000).
    pub keys: &'a mut [extract::Key],
    /// Room for the first round's candidates (up to four per slice of each window; more are
    /// dropped).
    pub cands: &'a mut (dyn Room<Candidate> + Send),
    /// Room for candidate indices, as much as for `cands`.
    pub idx: &'a mut dyn Room<usize>,
    /// Room for the navigation model's pieces of the time line (128 suit a survey of a few
    /// minutes at a correlation time of seconds; with fewer the pieces are made longer).
    pub nav: &'a mut dyn Room<crate::calib::nav::Piece>,
    /// A second worker for the per-sphere work (`None`: the spheres one after the other on
    /// this scratch): the spheres are split in two groups of about equal returns, the second
    /// worked on with the helper's scratch beside the first. The answer is the same.
    pub helper: Option<Helper<'a>>,
}

/// The second worker's scratch (as [`Workspace`]'s fields of the same names) and how it runs.
#[derive(Debug)]
pub struct Helper<'a> {
    /// Runs the second group (and the second half of the navigation fit's rows) beside the
    /// first.
    pub fork: &'a dyn Fork,
    /// Its vote grid, all zero.
    pub grid: &'a mut [u16],
    /// Its slice index, as long as [`Workspace::keys`] (whose length caps a slice).
    pub keys: &'a mut [extract::Key],
    /// Room for its candidates (the first round's of the second group, before they join the
    /// first's).
    pub cands: &'a mut (dyn Room<Candidate> + Send),
    /// Room for the navigation model's rows, both workers' (each evaluation of the final fit
    /// makes them in two halves side by side, [`crate::calib::nav::Split`]): room for every
    /// row makes them in one turn (none: the caller's thread makes them all).
    pub rows: &'a mut (dyn Room<crate::calib::nav::Row> + Send + Sync),
}

impl Helper<'_> {
    /// Its worker and rows for the navigation model's final fit.
    pub(super) fn split(&mut self) -> crate::calib::nav::Split<'_> {
        crate::calib::nav::Split {
            fork: self.fork,
            rows: &mut *self.rows,
        }
    }
}

/// One worker's detection scratch.
pub(in crate::calib::solve) struct Lane<'l> {
    pub(in crate::calib::solve) grid: &'l mut [u16],
    pub(in crate::calib::solve) keys: &'l mut [extract::Key],
    pub(in crate::calib::solve) cands: &'l mut (dyn Room<Candidate> + Send),
}

impl Workspace<'_> {
    /// The caller's lane, and the helper's with its fork when one was lent.
    fn lanes(&mut self) -> (Lane<'_>, Option<(&dyn Fork, Lane<'_>)>) {
        let mine = Lane {
            grid: &mut *self.grid,
            keys: &mut *self.keys,
            cands: &mut *self.cands,
        };
        let other = self.helper.as_mut().map(|h| {
            let lane = Lane {
                grid: &mut *h.grid,
                keys: &mut *h.keys,
                cands: &mut *h.cands,
            };
            (h.fork, lane)
        });
        (mine, other)
    }
}

/// Where spheres with `lens` returns split in two groups of about equal returns: the second
/// group's first sphere (`lens.len()` when there is only one group).
pub(super) fn halves(lens: &[usize]) -> usize {
    let total: usize = lens.iter().sum();
    let (mut before, mut best) = (0usize, (usize::MAX, lens.len()));
    for (k, n) in lens.iter().enumerate().take(lens.len().saturating_sub(1)) {
        before += n;
        let gap = before.abs_diff(total - before);
        if gap < best.0 {
            best = (gap, k + 1);
        }
    }
    best.1
}

/// Where [`side_by_side`]'s two groups of the spheres with `lens` returns split: in halves
/// with a helper, else all in the first.
pub(super) fn groups(ws: &Workspace<'_>, lens: &[usize]) -> usize {
    match ws.helper {
        Some(_) => halves(lens),
        None => lens.len(),
    }
}

/// `a` on the caller's lane and `b` on the helper's beside it, when one was lent; else `a`,
/// then `b`, on the caller's lane.
pub(super) fn side_by_side(
    ws: &mut Workspace<'_>,
    mut a: impl FnMut(&mut Lane<'_>),
    mut b: impl FnMut(&mut Lane<'_>) + Send,
) {
    let (mut mine, other) = ws.lanes();
    match other {
        Some((fork, mut lane)) => fork.join(&mut || a(&mut mine), &mut || b(&mut lane)),
        None => {
            a(&mut mine);
            b(&mut mine);
        }
    }
}

/// A tiny scratch for the tests: room for four of everything, and a helper's.
#[cfg(test)]
pub(in crate::calib::solve) struct TinyScratch {
    grid: [u16; 8],
    kept: [Observation; 4],
    keys: [extract::Key; 4],
    cands: [Candidate; 4],
    idx: [usize; 4],
    nav: [crate::calib::nav::Piece; 1],
    helper: (
        [u16; 8],
        [extract::Key; 4],
        [Candidate; 4],
        [crate::calib::nav::Row; 2],
    ),
}

#[cfg(test)]
impl TinyScratch {
    pub(in crate::calib::solve) fn new() -> Self {
        Self {
            grid: [0; 8],
            kept: [Observation::default(); 4],
            keys: [extract::Key::default(); 4],
            cands: [Candidate::default(); 4],
            idx: [0; 4],
            nav: [crate::calib::nav::Piece::EMPTY; 1],
            helper: (
                [0; 8],
                [extract::Key::default(); 4],
                [Candidate::default(); 4],
                [crate::calib::nav::Row::EMPTY; 2],
            ),
        }
    }

    /// Its workspace, with a helper running in turn when `helped`.
    pub(in crate::calib::solve) fn workspace(&mut self, helped: bool) -> Workspace<'_> {
        let (grid, keys, cands, rows) = &mut self.helper;
        Workspace {
            grid: &mut self.grid,
            kept: &mut self.kept,
            keys: &mut self.keys,
            cands: &mut self.cands,
            idx: &mut self.idx,
            nav: &mut self.nav,
            helper: helped.then_some(Helper {
                fork: &crate::calib::fork::InTurn,
                grid,
                keys,
                cands,
                rows,
            }),
        }
    }
}

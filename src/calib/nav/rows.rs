//! The joint least squares' rows: each return's linearised row at the state with its weight's
//! variance parts ([`Row`]), made on this thread or in two halves side by side with a second
//! worker ([`Split`]), always handed on in the spheres' and time order.

use super::joint::Joint;
use super::{piece_of, Piece, P};
use crate::align::window::{Observation, MAX_TARGETS};
use crate::calib::fork::Fork;
use crate::calib::lm::{row_q, Vec6, VecQ, Q};
use crate::calib::noise::Noise;
use crate::calib::objective::{Linearised, Problem, SphereObs};
use crate::calib::room::Room;
use crate::time::GpsTime;
use core::ops::Range;
use nalgebra::Vector3;

/// A second worker for the joint least squares' rows (lent by `solve::Helper`): each
/// evaluation makes its rows in two halves side by side into `rows`, then sums them in order,
/// so the sums are one worker's to the last bit.
#[derive(Debug)]
pub struct Split<'a> {
    /// Runs the second half beside the first.
    pub fork: &'a dyn Fork,
    /// Room for the rows of both halves, up to half each (more rows are made in turns).
    pub rows: &'a mut (dyn Room<Row> + Send + Sync),
}

/// What every row of an evaluation is linearised with ([`Joint::at`]).
struct At<'p> {
    pb: Problem<'p>,
    /// At the state.
    lin: Linearised,
    /// At the globals the weights are taken at.
    held: Linearised,
}

/// One return's linearised row: the global row's `Q` entries, its sphere's centre (`-n`), its
/// piece's six (position, rotation), the residual and the absolute weight.
#[derive(Debug, Clone, Copy)]
pub struct Row {
    pub(super) sphere: usize,
    /// Its piece of the time line.
    pub(super) piece: usize,
    pub(super) time: GpsTime,
    pub(super) jq: VecQ,
    pub(super) jc: [f64; 3],
    pub(super) je: Vec6,
    pub(super) res: f64,
    pub(super) w: f64,
    /// Its variance's parts ([`Joint::parts`]).
    pub(super) var: Parts,
}

/// A residual's variance parts [m^2] ([`Joint::parts`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Parts {
    /// The declared white noise ([`Noise::variance`]).
    pub(super) white: f64,
    /// Its radial part ([`Noise::radial_variance`]).
    pub(super) radial: f64,
    /// The footprint's spread at the incidence, before the share.
    pub(super) spread: f64,
    /// The navigation process's wander within the piece.
    pub(super) wander: f64,
}

impl Row {
    /// A row's room before it is written.
    pub const EMPTY: Self = Self {
        sphere: 0,
        piece: 0,
        time: GpsTime(0),
        jq: VecQ::from_array_storage(nalgebra::ArrayStorage([[0.0; Q]; 1])),
        jc: [0.0; 3],
        je: Vec6::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; 1])),
        res: 0.0,
        w: 0.0,
        var: Parts {
            white: 0.0,
            radial: 0.0,
            spread: 0.0,
            wander: 0.0,
        },
    };

    /// Its cluster: its sphere and its time within `cluster_ns` (neighbours on one sphere
    /// share the footprint's and the cap's errors).
    pub(super) fn cluster(&self, cluster_ns: i64) -> (usize, i64) {
        (self.sphere, self.time.0.div_euclid(cluster_ns.max(1)))
    }
}

impl Joint<'_, '_> {
    /// A residual's variance parts in a piece of `len_s`, its grazing factor `grazing`: the
    /// white noise, its radial part (what `weights::spread_share` tests against), the
    /// footprint's spread, and the process's wander within the piece, `len / 3 tau` of the
    /// navigation error's variance along a beam (the position's and the rotations' at the
    /// return's range, each over a direction averaged over the sphere's cap). Its weight is
    /// `1 / (white x the factor + share x spread + wander)`, the spread where the beam met the
    /// sphere at the state the weights are taken at ([`Self::hold`]). The weights take the
    /// white variance whole, not its radial part: near the silhouette what the footprint's
    /// bloom model leaves is no smaller (weighed by the radial part, table1-real's pitch was
    /// biased by -0.34 sigma over 100 seeds).
    fn parts(&self, pb: &Problem<'_>, o: &Observation, len_s: f64, grazing: f64) -> Parts {
        let white = pb.weights.map_or(1e-4, |n| n.variance(o)).max(1e-12);
        let radial = pb
            .weights
            .map_or(1e-4, |n| n.radial_variance(o, grazing))
            .max(1e-12);
        let spread = pb
            .weights
            .map_or(0.0, |n: Noise| n.spread_variance(o, grazing));
        let sg = self.model.sigmas();
        let r = f64::from(o.range);
        let pos = (sg[0] * sg[0] + sg[1] * sg[1] + sg[2] * sg[2]) / 3.0;
        let rot = r * r * 2.0 / 3.0 * (sg[3] * sg[3] + sg[4] * sg[4] + sg[5] * sg[5]) / 3.0;
        let wander = (pos + rot) * len_s / (3.0 * self.model.correlation_s);
        Parts {
            white,
            radial,
            spread,
            wander,
        }
    }

    /// The linearisations a row needs: at the state, and at the globals the weights are taken
    /// at ([`Self::hold`]).
    fn at(&self) -> At<'_> {
        let pb = self.problem();
        let lin = pb.linearised(&self.b());
        let held_b: [f64; P] = core::array::from_fn(|i| self.held[i]);
        At {
            pb,
            lin,
            held: Linearised::at(&held_b),
        }
    }

    /// Return `o` of sphere `j`: its linearised row at the state, with its piece of `pieces`
    /// (`None`: no residual, a return on the sphere's centre).
    fn row(&self, at: &At<'_>, j: usize, o: &Observation, pieces: &[Piece]) -> Option<Row> {
        let pb = &at.pb;
        let target = &pb.spheres[j].target;
        let (nu0, nu1) = (self.z[P + 1], self.z[P + 2]);
        let cj = Q + 3 * j;
        let held_centre = Vector3::new(self.held[cj], self.held[cj + 1], self.held[cj + 2]);
        let i = piece_of(pieces, o.time);
        let c = pieces[i].correction(self.centre(j));
        let r = at.lin.row_corrected(o, target, pb.dt_at(o), &c)?;
        let n = r.normal;
        let var = self.parts(pb, o, pieces[i].len_s(), r.grazing);
        // The weight's spread where the beam met the sphere at the held state.
        let spread = if self.spread > 0.0 && var.spread > 0.0 {
            let g = at
                .held
                .grazing(
                    o,
                    target,
                    pb.dt_at(o),
                    &pieces[i].held_correction(held_centre),
                )
                .unwrap_or(r.grazing);
            self.spread * pb.weights.map_or(0.0, |n| n.spread_variance(o, g))
        } else {
            0.0
        };
        Some(Row {
            sphere: j,
            piece: i,
            time: o.time,
            jq: row_q(&r.row, r.grazing, self.clock, pb.since_ref(o)),
            // The sphere's centre: -n (n: the residual's direction, the bloom's gradient in it).
            jc: [-n.x, -n.y, -n.z],
            je: Vec6::from(r.pose_row()),
            res: r.residual - nu0 - nu1 * r.grazing,
            w: 1.0 / (var.white * self.factor + spread + var.wander),
            var,
        })
    }

    /// Each return's linearised row at the state, in the spheres' order and each sphere's
    /// time order, with its piece: `f(piece, row)`.
    pub(super) fn each_row(&self, pieces: &mut [Piece], mut f: impl FnMut(&mut Piece, &Row)) {
        let at = self.at();
        for (j, sp) in at.pb.spheres.iter().enumerate().take(MAX_TARGETS) {
            for o in sp.obs {
                if let Some(r) = self.row(&at, j, o, pieces) {
                    f(&mut pieces[r.piece], &r);
                }
            }
        }
    }

    /// As [`Self::each_row`], the rows made in turns of two halves side by side (`split`), each
    /// turn's handed to `f` in order.
    pub(super) fn each_row_split(
        &self,
        split: &mut Split<'_>,
        pieces: &mut [Piece],
        mut f: impl FnMut(&mut Piece, &Row),
    ) {
        let at = self.at();
        let spheres = &at.pb.spheres[..at.pb.spheres.len().min(MAX_TARGETS)];
        let total: usize = spheres.iter().map(|s| s.obs.len()).sum();
        let fork = split.fork;
        let room = split.rows.room(total);
        let half = room.len() / 2;
        if half == 0 {
            return self.each_row(pieces, f);
        }
        let (mine, theirs) = room.split_at_mut(half);
        let mut from = 0;
        while from < total {
            let mid = (from + half).min(total);
            let to = (mid + half).min(total);
            let (mut a, mut b) = (0, 0);
            let view: &[Piece] = pieces;
            fork.join(
                &mut || a = self.rows_into(&at, spheres, from..mid, view, mine),
                &mut || b = self.rows_into(&at, spheres, mid..to, view, theirs),
            );
            for r in mine[..a].iter().chain(&theirs[..b]) {
                f(&mut pieces[r.piece], r);
            }
            from = to;
        }
    }

    /// The rows of the returns `range` (counted over `spheres` in order) into `out`, in order:
    /// how many (a return without a row has none; `out` holds at least `range`'s length).
    fn rows_into(
        &self,
        at: &At<'_>,
        spheres: &[SphereObs<'_>],
        range: Range<usize>,
        pieces: &[Piece],
        out: &mut [Row],
    ) -> usize {
        let (mut n, mut base) = (0, 0);
        for (j, sp) in spheres.iter().enumerate() {
            let (lo, hi) = (range.start.max(base), range.end.min(base + sp.obs.len()));
            for o in sp
                .obs
                .get(lo.saturating_sub(base)..hi.saturating_sub(base))
                .unwrap_or(&[])
            {
                if let (Some(r), Some(slot)) = (self.row(at, j, o, pieces), out.get_mut(n)) {
                    *slot = r;
                    n += 1;
                }
            }
            base += sp.obs.len();
        }
        n
    }
}

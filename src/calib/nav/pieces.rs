//! The navigation model's pieces: the survey's time line cut into spans of 0.25-0.5 s
//! ([`NavModel::piece_s`]), each with its navigation error and the elimination's scratch.

use super::{Mat6G1, MatG6, NavModel, G};
use crate::align::window::MAX_TARGETS;
use crate::calib::lm::{Mat6, Vec6};
use crate::calib::objective::NavCorrection;
use crate::calib::objective::Problem;
use crate::calib::room::Room;
use crate::time::GpsTime;
use nalgebra::Vector3;

/// One piece of the time line: its span, its navigation error (the estimate) and the
/// elimination's scratch.
#[derive(Debug, Clone, Copy)]
pub struct Piece {
    /// First and last return's time.
    pub start: GpsTime,
    /// See `start`.
    pub end: GpsTime,
    /// Returns in it.
    pub n: usize,
    /// The estimated navigation error: N, E, D [m], rotation about N, E, D [rad].
    pub error: [f64; 6],
    /// Its 1 sigma (posterior) once [`refine`] returns; during the iterations the step
    /// [`Joint::step`] last computed for it.
    pub sigma: [f64; 6],
    /// The error the weights are taken at ([`super::joint::Joint::hold`]).
    pub(super) held: [f64; 6],
    /// [`escape_steps`]' copies of `error`: the minimum found, the best other start's.
    pub(super) kept: [f64; 6],
    pub(super) best: [f64; 6],
    pub(super) d: Mat6,
    pub(super) b: MatG6,
    pub(super) g: Vec6,
    pub(super) c: Mat6,
    pub(super) y: Mat6G1,
    /// The chain's own posterior block (of `M^-1`: the globals held), [`Joint::chain_blocks`].
    pub(super) s: Mat6,
    /// The chain prior's diagonal information of its own error and of its link to the next
    /// piece ([`Joint::chain`]), set once per solve by [`Joint::start`].
    pub(super) own: [f64; 6],
    pub(super) link: [f64; 6],
    /// The Cholesky factor of `c` ([`Joint::step`]'s forward recursion), packed.
    pub(super) chol: Mat6,
    /// Its sums and error before a trial step, put back when the step is rejected.
    pub(super) before: BeforeTrial,
}

/// A piece's sums `(d, b, g)` and error before a trial step of [`super::steps::iterate`]:
/// a rejected step puts them back instead of evaluating again.
#[derive(Debug, Clone, Copy)]
pub(super) struct BeforeTrial {
    pub(super) d: Mat6,
    pub(super) b: MatG6,
    pub(super) g: Vec6,
    pub(super) error: [f64; 6],
}

impl Piece {
    /// An empty piece.
    pub const EMPTY: Self = Self {
        start: GpsTime(0),
        end: GpsTime(0),
        n: 0,
        error: [0.0; 6],
        sigma: [0.0; 6],
        held: [0.0; 6],
        kept: [0.0; 6],
        best: [0.0; 6],
        d: Mat6::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; 6])),
        b: MatG6::from_array_storage(nalgebra::ArrayStorage([[0.0; G]; 6])),
        g: Vec6::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; 1])),
        c: Mat6::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; 6])),
        y: Mat6G1::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; G + 1])),
        s: Mat6::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; 6])),
        own: [0.0; 6],
        link: [0.0; 6],
        chol: Mat6::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; 6])),
        before: BeforeTrial {
            d: Mat6::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; 6])),
            b: MatG6::from_array_storage(nalgebra::ArrayStorage([[0.0; G]; 6])),
            g: Vec6::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; 1])),
            error: [0.0; 6],
        },
    };

    /// Its span [s].
    pub(super) fn len_s(&self) -> f64 {
        (self.end.0 - self.start.0) as f64 * 1e-9
    }

    pub(super) fn mid_s(&self) -> f64 {
        (self.start.0 as f64 + self.end.0 as f64) * 0.5e-9
    }

    /// Its error taken out of a return on a sphere whose centre moved by `centre`.
    pub(super) fn correction(&self, centre: Vector3<f64>) -> NavCorrection {
        Self::correction_at(&self.error, centre)
    }

    /// As [`Self::correction`] at the error the weights are taken at.
    pub(super) fn held_correction(&self, centre: Vector3<f64>) -> NavCorrection {
        Self::correction_at(&self.held, centre)
    }

    fn correction_at(e: &[f64; 6], centre: Vector3<f64>) -> NavCorrection {
        NavCorrection {
            position: Vector3::new(e[0], e[1], e[2]),
            rotation: Vector3::new(e[3], e[4], e[5]),
            centre,
        }
    }
}

/// Cut the returns' time line into pieces of at most `len_s` (a gap over 1 s ends one too)
/// into `out`; the number made, or `None` when more would be needed than `out` holds.
pub fn cut(pb: &Problem<'_>, len_s: f64, out: &mut [Piece]) -> Option<usize> {
    each_piece(pb, len_s, |m, start, end, n| {
        *out.get_mut(m)? = Piece {
            start,
            end,
            n,
            ..Piece::EMPTY
        };
        Some(())
    })
}

/// How many pieces [`cut`] makes at `len_s`.
fn count(pb: &Problem<'_>, len_s: f64) -> usize {
    each_piece(pb, len_s, |_, _, _, _| Some(())).unwrap_or(0)
}

/// [`cut`]'s walk: each piece (its index, first and last return's time, returns) to `put`,
/// which ends the walk with `None`; the number of pieces.
fn each_piece(
    pb: &Problem<'_>,
    len_s: f64,
    mut put: impl FnMut(usize, GpsTime, GpsTime, usize) -> Option<()>,
) -> Option<usize> {
    let len_ns = (len_s * 1e9) as i64;
    let gap_ns = 1_000_000_000i64.min(len_ns);
    // A k-way merge of the spheres' returns (each in time order).
    let mut at = [0usize; MAX_TARGETS];
    let mut m = 0usize;
    let mut cur: Option<(i64, i64, usize)> = None;
    loop {
        let mut best: Option<(usize, i64)> = None;
        for (j, s) in pb.spheres.iter().enumerate().take(MAX_TARGETS) {
            if let Some(o) = s.obs.get(at[j]) {
                if best.is_none_or(|(_, t)| o.time.0 < t) {
                    best = Some((j, o.time.0));
                }
            }
        }
        let Some((j, t)) = best else { break };
        at[j] += 1;
        cur = match cur {
            Some((s, e, n)) if t - s <= len_ns && t - e <= gap_ns => Some((s, t, n + 1)),
            Some((s, e, n)) => {
                put(m, GpsTime(s), GpsTime(e), n)?;
                m += 1;
                Some((t, t, 1))
            }
            None => Some((t, t, 1)),
        };
    }
    if let Some((s, e, n)) = cur {
        put(m, GpsTime(s), GpsTime(e), n)?;
        m += 1;
    }
    Some(m)
}

/// Cut into at most `out.len()` pieces: `model`'s length, doubled until they fit.
pub fn cut_for(pb: &Problem<'_>, model: &NavModel, out: &mut [Piece]) -> usize {
    let mut len = model.piece_s();
    for _ in 0..20 {
        if let Some(m) = cut(pb, len, out) {
            return m;
        }
        len *= 2.0;
    }
    0
}

/// [`cut_for`] into room lent for as many pieces as `model`'s length makes ([`count`]): all of
/// them when the room has them, else as the room's length allows.
pub fn cut_in(pb: &Problem<'_>, model: &NavModel, room: &mut dyn Room<Piece>) -> usize {
    cut_for(pb, model, room.room(count(pb, model.piece_s())))
}

/// The piece of a return at `t` (the pieces cover every return, in order).
pub(super) fn piece_of(pieces: &[Piece], t: GpsTime) -> usize {
    pieces
        .partition_point(|p| p.end.0 < t.0)
        .min(pieces.len().saturating_sub(1))
}

//! The navigation errors that wander (DESIGN.md "Navigation errors that wander"): a real GNSS/INS
//! solution is off by centimetres that stay for tens of seconds, first-order Gauss-Markov per
//! axis. The least squares estimate them with the mounting: the survey's time line is cut into
//! pieces of 0.25-0.5 s ([`NavModel::piece_s`]), each with its own error `e_i` (position N, E, D
//! and a small rotation about N, E, D) and the process's prior — `e_0 ~ N(0, S)`,
//! `e_i | e_(i-1) ~ N(phi e_(i-1), (1 - phi^2) S)`, `phi = exp(-gap / tau)` — and the sphere
//! centres with their survey's sigma. The answer maximises the likelihood of the returns
//! (white noise: range, the INS's own white noise, quantisation) and those priors; the
//! covariance of the mounting is the inverse of its information with every nuisance
//! marginalised (the pieces eliminated by the block-tridiagonal Schur complement, the centres
//! with the rest). A parameter the data no longer pin (all centres free over flat water: the
//! vertical lever arm) shows as a condition number no survey passes.

use super::lm::{conditioning, Clock, LmResult, Mat6, MatQ, DRIFT, Q};
use super::objective::Problem;
use crate::align::window::MAX_TARGETS;
use crate::georef::P;
use crate::time::GpsTime;
use nalgebra::{SMatrix, SVector};

mod joint;
mod pieces;
mod robust;
mod rows;
mod steps;
#[cfg(test)]
mod tests;
mod weights;

use joint::Joint;
use pieces::piece_of;
pub use pieces::{cut, cut_for, cut_in, Piece};
pub use rows::{Row, Split};
use steps::iterate;

/// The navigation errors' model: per axis a first-order Gauss-Markov process.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavModel {
    /// Position 1 sigma: horizontal, vertical [m].
    pub position_sigma: [f64; 2],
    /// Attitude 1 sigma: roll and pitch, heading [rad].
    pub attitude_sigma: [f64; 2],
    /// Correlation time [s].
    pub correlation_s: f64,
}

impl NavModel {
    /// No navigation error that wanders (the INS's errors white, in the weights), but the
    /// joint least squares' sphere centres with their survey's sigma: the white model with a
    /// declared survey (DESIGN.md "Navigation errors that wander"). The pieces are held at
    /// zero by their prior.
    pub const WHITE: NavModel = NavModel {
        position_sigma: [0.0; 2],
        attitude_sigma: [0.0; 2],
        correlation_s: 1e9,
    };

    /// Whether this is [`Self::WHITE`]: no error that wanders.
    pub fn is_white(&self) -> bool {
        self.sigmas().iter().all(|s| *s == 0.0)
    }

    /// The six sigmas: N, E, D [m]; rotation about N, E, D [rad] (roll and pitch share one
    /// sigma, so about any horizontal axis; heading is about down).
    pub fn sigmas(&self) -> [f64; 6] {
        let [h, v] = self.position_sigma;
        let [rp, hd] = self.attitude_sigma;
        [h, h, v, rp, rp, hd]
    }

    /// The pieces' length [s]: a 240th of the correlation time, 0.25-0.5 s. A first-order
    /// process is rough: within a piece of length L it wanders by `sigma^2 L / 3 tau` about
    /// the piece's mean, shared by every return of the piece; what matters is that wander
    /// times the piece's returns against the white noise, so the length is short in seconds
    /// whatever tau (the Monte Carlo `honesty::sigmas_are_honest_on_exact_returns`: at
    /// tau / 6 the pitch's and the vertical lever arm's RMS z-scores were 3.1 and 3.2; at
    /// 2 s with tau = 60 s 1.8 and 1.6; at 0.5 s 1.25 (tau 15 s) and 1.14 (60 s) for pitch;
    /// at 0.25 s 1.10 and 1.09). The wander left in a piece is added to each return's
    /// variance ([`Joint::weight`]). Too many for the workspace: doubled ([`cut_for`]).
    pub fn piece_s(&self) -> f64 {
        if self.is_white() {
            // Nothing to estimate in a piece: as long as the data run without a gap.
            return 3600.0;
        }
        (self.correlation_s / 240.0).clamp(0.25, 0.5)
    }

    /// The process's correlation between two pieces, `exp(-gap / tau)` of their middles.
    fn phi(&self, a: &Piece, b: &Piece) -> f64 {
        libm::exp(-(b.mid_s() - a.mid_s()).abs() / self.correlation_s)
    }
}

/// The global parameters: the lm's `Q` (the six, the time offset, the two nuisance terms, the
/// drift) and three per sphere centre.
pub const G: usize = Q + 3 * MAX_TARGETS;
type MatG = SMatrix<f64, G, G>;
type VecG = SVector<f64, G>;
/// G x 6.
type MatG6 = SMatrix<f64, G, 6>;
/// 6 x (G + 1): a piece's rows of `M^-1 [B^T | g]`.
type Mat6G1 = SMatrix<f64, 6, { G + 1 }>;

/// What the navigation model's least squares found besides [`LmResult`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavFit {
    /// Pieces used.
    pub pieces: usize,
    /// Each sphere's centre correction from its surveyed one [m, NED] and its 1 sigma.
    pub centre: [[f64; 3]; MAX_TARGETS],
    /// See `centre`.
    pub centre_sigma: [[f64; 3]; MAX_TARGETS],
    /// The white noise's variance factor found (1: as the noise model says).
    pub variance_factor: f64,
    /// The share of the footprint's spread at incidence the residuals show (1: as the
    /// beam's divergence says; 0: none; [`weights::spread_share`]).
    pub spread_share: f64,
    /// The largest step between consecutive pieces against the model's: `|e_i - phi e_(i-1)|`
    /// over `sigma sqrt(1 - phi^2)` on the worst axis (an INS jump shows as tens), the piece
    /// it happened at and the step (N, E, D [m], rotation [rad]).
    pub worst_step: (f64, GpsTime, [f64; 6]),
}

/// A prior on the mounting (a vessel survey's lever arms, a parameter the data cannot
/// determine held at its a-priori value): each of the six `centre` [rad, m] with its
/// information `info` (1 / sigma^2; 0: none).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MountPrior {
    /// The a-priori values.
    pub centre: [f64; P],
    /// Their information (0: no prior).
    pub info: [f64; P],
}

impl MountPrior {
    /// From the a-priori values and their sigmas (0 or not finite: no prior).
    pub fn of(centre: &[f64; P], sigma: &[f64; P]) -> Self {
        Self {
            centre: *centre,
            info: core::array::from_fn(|i| {
                let s = sigma[i];
                if s.is_finite() && s > 0.0 {
                    1.0 / (s * s)
                } else {
                    0.0
                }
            }),
        }
    }

    /// Whether any parameter has a prior.
    pub fn any(&self) -> bool {
        self.info.iter().any(|i| *i > 0.0)
    }
}

/// Refine `b0` under the navigation model by Levenberg-Marquardt over the mounting (and the
/// clock as `clock` says), the nuisance terms, the sphere centres (prior sigma `centre_sigma`
/// per sphere [m]; 0: held at the survey) and the pieces' errors (`pieces`: at least one; cut
/// with [`cut_for`]). At most `max_iter` iterations per pass; between passes (at most four)
/// the weights are taken again at the pass's solution (iteratively reweighted): where each
/// beam meets its sphere, whether the footprint's spread at incidence shows
/// ([`weights::spread_share`]), and the white noise's variance factor, with the design effect of
/// returns within `cluster_ns` of each other on one sphere. The covariance is the inverse of
/// the mounting's information with every other parameter marginalised, widened where the
/// residuals show more than the weights say (cluster-robust, [`robust`]); `sigma_classic`
/// is the information's alone. `mount`: the prior on the mounting (none:
/// [`MountPrior::default`]); under white errors the design effect is left to the robust
/// covariance. `split`: a second worker for each evaluation's rows (the answer is the same).
#[allow(clippy::too_many_arguments)]
pub fn refine<'a>(
    pb: &'a Problem<'_>,
    b0: &[f64; P],
    model: &NavModel,
    centre_sigma: &[f64],
    mount: &MountPrior,
    pieces: &mut [Piece],
    split: Option<Split<'a>>,
    max_iter: usize,
    cluster_ns: i64,
    clock: Clock,
) -> (LmResult, NavFit) {
    let clock = Clock {
        dt: clock.dt,
        drift: clock.dt && clock.drift,
    };
    let mut at = Joint::start(pb, b0, model, centre_sigma, pieces, clock);
    at.mount = *mount;
    at.split = split;
    let (mut sums, mut iterations, converged) =
        weights::passes(&mut at, pieces, max_iter, cluster_ns);
    if converged {
        (sums, iterations) = escape_steps(&mut at, pieces, max_iter, sums, iterations);
    }
    let converged = converged && sums.cost.is_finite() && at.z.iter().all(|x| x.is_finite());
    let h = at.reduced(&sums, pieces);
    let classic = h.and_then(|h| h.try_inverse());
    at.chain_blocks(pieces);
    let cov = classic.map(|c| robust::covariance(&at, pieces, &c, cluster_ns));
    let nan = f64::NAN;
    let var = |i: usize| cov.map_or(nan, |c| c[(i, i)].max(0.0));
    let sigma: [f64; P] = core::array::from_fn(|i| libm::sqrt(var(i)));
    let sigma_dt = if clock.dt { libm::sqrt(var(P)) } else { 0.0 };
    let covariance: Mat6 = cov.map_or(Mat6::from_element(nan), |c| {
        c.fixed_view::<P, P>(0, 0).into_owned()
    });
    let mut correlation = Mat6::zeros();
    let mut dt_correlation = [0.0; P];
    for i in 0..P {
        for j in 0..P {
            correlation[(i, j)] = covariance[(i, j)] / (sigma[i] * sigma[j]);
        }
        if clock.dt {
            dt_correlation[i] = cov.map_or(nan, |c| c[(i, P)]) / (sigma[i] * sigma_dt);
        }
    }
    // The mounting's (and clock's) information with everything else marginalised: what the
    // data and priors leave to pin it.
    let info_q: MatQ = classic.map_or(MatQ::from_element(nan), |c| {
        let block = c.fixed_view::<Q, Q>(0, 0).into_owned();
        let mut keep = block;
        if !clock.dt {
            keep[(P, P)] = 1.0;
        }
        if !clock.drift {
            keep[(DRIFT, DRIFT)] = 1.0;
        }
        keep.try_inverse().unwrap_or(MatQ::from_element(nan))
    });
    let (condition, weakest) = conditioning(&info_q, clock.dt);
    let sigma_drift = if clock.drift {
        libm::sqrt(var(DRIFT))
    } else {
        0.0
    };
    posterior_sigmas(pieces, cov.as_ref());
    let mut fit = NavFit {
        pieces: pieces.len(),
        centre: [[0.0; 3]; MAX_TARGETS],
        centre_sigma: [[0.0; 3]; MAX_TARGETS],
        variance_factor: at.factor,
        spread_share: at.spread,
        worst_step: worst_step(model, pieces),
    };
    for j in 0..pb.spheres.len().min(MAX_TARGETS) {
        let cj = Q + 3 * j;
        fit.centre[j] = [at.z[cj], at.z[cj + 1], at.z[cj + 2]];
        fit.centre_sigma[j] = core::array::from_fn(|k| libm::sqrt(var(cj + k)));
    }
    let lm = LmResult {
        b: at.b(),
        dt: at.z[P],
        estimated_dt: clock.dt,
        drift: at.z[DRIFT],
        sigma_drift,
        estimated_drift: clock.drift,
        radius_offset: at.z[P + 1],
        iterations,
        converged,
        n: sums.n,
        rms: libm::sqrt(sums.raw / sums.n.max(1) as f64),
        normal: info_q.fixed_view::<P, P>(0, 0).into_owned(),
        covariance,
        sigma,
        sigma_dt,
        sigma_classic: core::array::from_fn(|i| {
            classic.map_or(nan, |c| libm::sqrt(c[(i, i)].max(0.0)))
        }),
        clusters: pieces.len(),
        correlation,
        dt_correlation,
        condition,
        weakest,
    };
    (lm, fit)
}

/// The sigmas [`refine`] would give the six and the time offset (0 when held) on these returns
/// at `b`, with the white noise as the weights say (variance factor 1) and no data noise: the
/// planner's prediction and the rig's on the data so far. `None` where the information is
/// singular. `pieces` as for [`refine`] ([`cut_for`]).
pub fn predict(
    pb: &Problem<'_>,
    b: &[f64; P],
    model: &NavModel,
    centre_sigma: &[f64],
    pieces: &mut [Piece],
    clock: Clock,
) -> Option<[f64; P + 1]> {
    let clock = Clock {
        dt: clock.dt,
        drift: clock.dt && clock.drift,
    };
    let mut at = Joint::start(pb, b, model, centre_sigma, pieces, clock);
    // The footprint's spread as `pb`'s noise states it (a solve takes it where its residuals
    // show it; the caller states what it expects: the plan its scenario's, the rig the
    // share its last solve found).
    at.spread = 1.0;
    let sums = at.evaluate(pieces);
    let cov = at.reduced(&sums, pieces)?.try_inverse()?;
    let s: [f64; P + 1] = core::array::from_fn(|i| {
        if i < P || clock.dt {
            libm::sqrt(cov[(i, i)].max(0.0))
        } else {
            0.0
        }
    });
    s.iter().all(|v| v.is_finite()).then_some(s)
}

/// Each piece's posterior sigma into its `sigma`: its block of the chain's `M^-1` (left by
/// [`Joint::chain_blocks`]) plus what the globals' uncertainty `cov` adds,
/// `(M^-1 B^T)_i cov (B M^-1)_i`.
fn posterior_sigmas(pieces: &mut [Piece], cov: Option<&MatG>) {
    for p in pieces.iter_mut() {
        let total = match cov {
            Some(c) => {
                let yb = p.y.fixed_view::<6, G>(0, 0);
                p.s + yb * c * yb.transpose()
            }
            None => p.s,
        };
        p.sigma = core::array::from_fn(|k| match total[(k, k)] {
            v if v.is_nan() => f64::NAN,
            v => libm::sqrt(v.max(0.0)),
        });
    }
}

/// The largest step between consecutive pieces in the model's sigmas ([`NavFit::worst_step`]).
fn worst_step(model: &NavModel, pieces: &[Piece]) -> (f64, GpsTime, [f64; 6]) {
    let (sigmas, k, step) = worst_step_at(model, pieces);
    (sigmas, pieces.get(k).map_or(GpsTime(0), |p| p.start), step)
}

/// [`worst_step`] with the index of the piece after the step.
fn worst_step_at(model: &NavModel, pieces: &[Piece]) -> (f64, usize, [f64; 6]) {
    let mut worst = (0.0, 0, [0.0; 6]);
    let sg = model.sigmas();
    for (i, w) in pieces.windows(2).enumerate() {
        let phi = model.phi(&w[0], &w[1]);
        let step: [f64; 6] = core::array::from_fn(|k| w[1].error[k] - phi * w[0].error[k]);
        for k in 0..6 {
            let sd = sg[k] * libm::sqrt((1.0 - phi * phi).max(1e-12));
            if sd > 0.0 && step[k].abs() / sd > worst.0 {
                worst = (step[k].abs() / sd, i + 1, step);
            }
        }
    }
    worst
}

/// A step between pieces beyond this many sigmas is tried from the other side's start.
const ESCAPE_SIGMAS: f64 = 4.0;
/// A run of pieces ends at a gap of this many seconds (a turn, a sphere out of view).
const RUN_GAP_S: f64 = 2.0;
/// The starts tried: (the run before the step?, at most this many pieces of it).
const RUNS: [(bool, usize); 6] = [
    (true, 2),
    (false, 2),
    (true, 8),
    (false, 8),
    (true, usize::MAX),
    (false, usize::MAX),
];

/// A step between consecutive pieces far beyond the model's is either the navigation's (an
/// INS that jumped: [`Refusal::NavigationJump`](super::solve::Refusal)) or a second minimum:
/// where a run of pieces holds a few returns on one side of one sphere (the first scan lines
/// of a pass, from 40 m), a sphere shifted several centimetres across and one shifted
/// tens of centimetres down fit them alike, and the pieces start from zero. So for the worst
/// step beyond [`ESCAPE_SIGMAS`] (up to three times), the run before it (back to a gap of
/// [`RUN_GAP_S`]) is started from the piece after the step, then the run after it from the
/// piece before; the lowest cost of the three minima is kept (a real jump's data keep it).
fn escape_steps(
    at: &mut Joint<'_, '_>,
    pieces: &mut [Piece],
    max_iter: usize,
    mut sums: joint::Sums,
    mut iterations: usize,
) -> (joint::Sums, usize) {
    // The run of pieces before (`back`) or after piece `k`'s step, at most `len` of them and
    // not past a gap of `RUN_GAP_S`.
    let run = |pieces: &[Piece], k: usize, back: bool, len: usize| -> (usize, usize) {
        let gap = |a: &Piece, b: &Piece| (b.start.0 - a.end.0) as f64 * 1e-9 > RUN_GAP_S;
        if back {
            let mut a = k - 1;
            while a > 0 && k - a < len && !gap(&pieces[a - 1], &pieces[a]) {
                a -= 1;
            }
            (a, k)
        } else {
            let mut b = k + 1;
            while b < pieces.len() && b - k < len && !gap(&pieces[b - 1], &pieces[b]) {
                b += 1;
            }
            (k, b)
        }
    };
    for _ in 0..3 {
        let (sigmas, k, _) = worst_step_at(&at.model, pieces);
        if sigmas <= ESCAPE_SIGMAS || k == 0 {
            break;
        }
        let (z0, cost0) = (at.z, sums.cost);
        for p in pieces.iter_mut() {
            p.kept = p.error;
        }
        let mut best: Option<(f64, [f64; G])> = None;
        let mut tried = (usize::MAX, usize::MAX);
        for (back, len) in RUNS {
            let (a, b) = run(pieces, k, back, len);
            if (a, b) == tried {
                continue;
            }
            tried = (a, b);
            at.z = z0;
            for p in pieces.iter_mut() {
                p.error = p.kept;
            }
            let from = if back {
                pieces[k].error
            } else {
                pieces[k - 1].error
            };
            for p in &mut pieces[a..b] {
                p.error = from;
            }
            let (s, it, ok) = iterate(at, pieces, max_iter);
            iterations += it;
            let lowest = best.as_ref().map_or(cost0, |b| b.0);
            if ok && s.cost.is_finite() && s.cost < lowest * (1.0 - 1e-9) {
                best = Some((s.cost, at.z));
                for p in pieces.iter_mut() {
                    p.best = p.error;
                }
            }
        }
        match best {
            Some((_, z)) => {
                at.z = z;
                for p in pieces.iter_mut() {
                    p.error = p.best;
                }
                sums = at.evaluate(pieces);
            }
            None => {
                at.z = z0;
                for p in pieces.iter_mut() {
                    p.error = p.kept;
                }
                sums = at.evaluate(pieces);
                break;
            }
        }
    }
    (sums, iterations)
}

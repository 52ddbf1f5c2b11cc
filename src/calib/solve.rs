//! The whole solve: find each sphere's returns among the clutter of its window
//! ([`super::extract`]), solve the six parameters on them against the surveyed centres
//! (Nelder-Mead on eq. 6, the authors' method), re-georeference, re-detect with a tighter prior
//! and shell, until the kept returns stop changing; then Levenberg-Marquardt on the kept
//! returns for the answer and its uncertainty, and the checks.
//!
//! Rounds. Round 1 knows nothing of where the sphere appears (a wrong a-priori mounting moves it
//! by metres): each slice of time is searched over its whole window, and only detections whose
//! cap is clearly curved are accepted; the returns within `tau0` of each detected sphere are
//! kept. After each solve the shell `tau` becomes `shell_sigmas` robust sigmas of the kept
//! returns' residuals against the surveyed spheres (sigma = 1.4826 x the median |residual|, from
//! a fixed log-spaced histogram: no heap, no sort), never below `shell_floor`, and the prior
//! radius three times the RMS offset of the slices' apparent spheres from the surveyed ones (at
//! least three shells): later rounds detect only near the surveyed centre. The last round keeps
//! the returns within the shell of the *surveyed* sphere, in the slices where the sphere was
//! detected there.
//!
//! A sphere detected in too few slices to give `min_points` returns is reported as not found
//! and left out; the others calibrate if at least two remain.
//!
//! Refusals (the solution is still reported): fewer than two spheres found (a single sphere
//! cannot fix a rotation about the line to it); a condition number of the unit-diagonal normal
//! matrix above `max_condition` = 1e3 (the weakest combination of parameters is then determined
//! 30 times worse than the best, and some pair correlates beyond 0.998: table1's four passes give
//! 7, a single pass 1.3e4 with roll, heading and z inseparable); the least squares not
//! converged; a residual RMS above `max_dispersion` times what the noise model predicts
//! (range, INS attitude x range, INS position, quantisation); a pass whose sphere, re-fitted to
//! its own calibrated returns, sits off the surveyed centre by more than its uncertainty allows
//! (chi-square over `max_pass_chi2` and more than `pass_offset_floor`): each pass must agree, not
//! only the average (an unestimated clock offset moves passes in opposite directions along the
//! track and cancels in the mean).

use super::consensus::{
    consensus, Ambiguity, Bounds, Candidate, Consensus, ConsensusSettings, Search,
};
use super::extract::{self, Directions, ExtractSettings, Verdict};
use super::lm::Clock;
use super::lm::{refine, LmResult};
use super::nelder_mead::{minimize, NmResult, NmSettings};
use super::objective::{Noise, Problem, SphereObs, TimeOffset};
use super::sphere_fit::fit_center;
use super::{DegM, Params, P};
use crate::georef::Mount;
use crate::time::GpsTime;
use crate::window::{Observation, Target, MAX_TARGETS};
use core::ops::Range;
use nalgebra::Vector3;

/// Most passes (sightings of a sphere) reported per solve; later ones are added to the last.
pub const MAX_PASSES: usize = 128;

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Nelder-Mead settings (coordinates in degrees and metres).
    pub nm: NmSettings,
    /// Initial simplex step per parameter (deg, deg, deg, m, m, m).
    pub step: [f64; P],
    /// LM iteration cap.
    pub lm_iter: usize,
    /// Fewest returns per sphere.
    pub min_points: usize,
    /// Largest acceptable condition number.
    pub max_condition: f64,
    /// Condition number above which the geometry counts as weak and the parameters with a
    /// large share of its weakest direction are named (below it every parameter is well
    /// determined, whatever that direction is).
    pub weak_condition: f64,
    /// The range noise the sensor is specified for, 1 sigma [m] (VLP-16: 3 cm).
    pub range_noise: f64,
    /// The INS attitude noise, 1 sigma [rad].
    pub attitude_noise: f64,
    /// The INS position noise, 1 sigma [m].
    pub position_noise: f64,
    /// Over-dispersion: the residual RMS may be at most this many times what the noise model
    /// predicts.
    pub max_dispersion: f64,
    /// A pass's sphere centre offset fails the consistency test beyond this chi-square (3
    /// degrees of freedom; 25: p = 1.4e-5) ...
    pub max_pass_chi2: f64,
    /// ... and this many metres.
    pub pass_offset_floor: f64,
    /// A held time offset is contradicted when the data, free to estimate it, move it by more
    /// than this many of its sigmas ...
    pub held_dt_sigmas: f64,
    /// ... and this many seconds.
    pub held_dt_floor: f64,
    /// The shell: this many robust sigmas ...
    pub shell_sigmas: f64,
    /// ... but at least this [m].
    pub shell_floor: f64,
    /// Detect-and-solve rounds at most.
    pub max_rounds: usize,
    /// Returns of one sphere this close in time share INS errors: one cluster for the
    /// covariance [ns].
    pub cluster_ns: i64,
    /// Returns per sphere Nelder-Mead evaluates (evenly spread; LM uses all).
    pub nm_points: usize,
    /// Sphere extraction.
    pub extract: ExtractSettings,
    /// Estimate the time offset between the clocks with the six.
    pub estimate_dt: bool,
    /// Estimate its drift too (a LiDAR clock without PPS: its crystal runs fast or slow by
    /// tens of ppm).
    pub estimate_drift: bool,
    /// The first round's consensus over the slices' candidates.
    pub consensus: ConsensusSettings,
    /// The margin the windows were made with around the start mounting [m]: the mounting may
    /// move at most this far in each lever-arm component, and each angle at most as far as moves
    /// the nearest windowed return by twice this (at most 45 deg): a mounting beyond would have
    /// left the spheres outside their windows.
    pub margin: f64,
}

impl Settings {
    /// The clock parameters estimated with the six.
    pub fn clock(&self) -> Clock {
        Clock {
            dt: self.estimate_dt,
            drift: self.estimate_dt && self.estimate_drift,
        }
    }

    /// The noise model of the residuals.
    pub fn noise(&self) -> Noise {
        Noise {
            range: self.range_noise,
            attitude: self.attitude_noise,
            position: self.position_noise,
        }
    }
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            nm: NmSettings::default(),
            step: [1.0, 1.0, 1.0, 0.1, 0.1, 0.1],
            lm_iter: 100,
            min_points: 30,
            max_condition: 1e3,
            weak_condition: 100.0,
            range_noise: 0.03,
            attitude_noise: 0.05f64.to_radians(),
            position_noise: 0.03,
            max_dispersion: 2.0,
            max_pass_chi2: 25.0,
            pass_offset_floor: 0.003,
            held_dt_sigmas: 5.0,
            held_dt_floor: 0.001,
            shell_sigmas: 3.5,
            shell_floor: 0.004,
            max_rounds: 12,
            cluster_ns: 20_000_000,
            nm_points: 100,
            extract: ExtractSettings::default(),
            estimate_dt: true,
            estimate_drift: false,
            consensus: ConsensusSettings::default(),
            margin: 3.0,
        }
    }
}

/// Why a solution is not claimed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Refusal {
    /// Fewer than two spheres given (the site's).
    TooFewTargets {
        /// Spheres given.
        given: usize,
    },
    /// Fewer than two spheres found among the clutter.
    TooFewSpheres {
        /// Spheres found.
        have: usize,
    },
    /// A sphere with too few returns.
    TooFewPoints {
        /// Sphere index.
        sphere: usize,
        /// Returns used.
        have: usize,
        /// Needed.
        need: usize,
    },
    /// The data cannot determine all six parameters well.
    IllConditioned {
        /// Condition number.
        condition: f64,
        /// Limit.
        limit: f64,
    },
    /// The least squares did not converge (stalled, or non-finite).
    NotConverged {
        /// Iterations taken.
        iterations: usize,
    },
    /// The residuals are far above what the sensors' noise explains.
    OverDispersed {
        /// RMS [m].
        rms: f64,
        /// What the noise model predicts [m].
        predicted: f64,
    },
    /// In one pass the calibrated returns leave a sphere off its surveyed centre, beyond its
    /// uncertainty: the model does not fit (along the track: a time offset or a lever-arm x
    /// error; across it: the boresight).
    Inconsistent {
        /// Sphere index.
        sphere: usize,
        /// Index of the pass in [`Solution::passes`].
        pass: usize,
        /// The fitted minus surveyed centre [m, NED].
        offset: [f64; 3],
        /// Its component along the track [m].
        along_track: f64,
        /// Its chi-square (3 degrees of freedom).
        chi2: f64,
    },
    /// Two mountings put different candidates on a sphere and explain the survey nearly as well
    /// (a buoy or a fender of the sphere's size beside it, at the same place relative to every
    /// sphere, or passes that cannot tell them apart).
    Ambiguous(Ambiguity),
    /// The solve left the box the start values and the windows' margin allow.
    OutOfBounds {
        /// Parameter index (0-2 angles, 3-5 lever arm).
        parameter: usize,
        /// Its change from the start [rad or m].
        change: f64,
        /// The allowance [rad or m].
        limit: f64,
    },
    /// The time offset is not the same over the survey: one pass's returns put it elsewhere,
    /// beyond its uncertainty (an INS clock step, a LiDAR clock drifting without PPS).
    ClockInconsistent {
        /// Sphere index.
        sphere: usize,
        /// Index of the pass in [`Solution::passes`].
        pass: usize,
        /// The pass's first and last return.
        start: GpsTime,
        /// ...
        end: GpsTime,
        /// Them in seconds after the first windowed return.
        into: [f64; 2],
        /// The offset its returns give minus the solution's there [s].
        shift: f64,
        /// Its sigma [s].
        sigma: f64,
    },
    /// The time offset was held, and the data, free to estimate it, put it elsewhere: the
    /// mounting has absorbed the clock error (a lever-arm x of speed x offset).
    TimeOffsetContradicted {
        /// The offset held [s] (on top of what the pipeline applied).
        held: f64,
        /// The offset the data give [s].
        found: f64,
        /// Its sigma [s].
        sigma: f64,
    },
}

/// Counts of windowed returns by [`Verdict`] (indexed by its number).
pub type Tally = [u32; 8];

/// Per sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereReport {
    /// Returns in the a-priori window.
    pub windowed: usize,
    /// Returns kept (used by the solution).
    pub used: usize,
    /// The sphere was found among the clutter (enough returns in detected slices).
    pub found: bool,
    /// Slices of time with window returns, and those where the sphere was detected.
    pub slices: u32,
    /// ...
    pub detected: u32,
    /// Windowed returns by verdict.
    pub verdicts: Tally,
    /// RMS of the kept returns' residuals with the starting values [m].
    pub rms_before: f64,
    /// ... with the solution [m].
    pub rms_after: f64,
    /// Fitted minus surveyed centre [m, NED].
    pub center_offset: Option<Vector3<f64>>,
    /// Slices of its window the first round's consensus explains (with the mounting all
    /// spheres agree on).
    pub agreed: u32,
    /// Why it was not found.
    pub lost: Option<Lost>,
}

/// Why a sphere was not found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lost {
    /// No returns in its window.
    NoReturns,
    /// Nothing sphere-like detected in its window.
    NotDetected,
    /// Sphere-like things detected, none where the mounting the other spheres agree on puts it
    /// (clutter, a decoy, or the sphere hidden).
    Disagrees,
    /// Detected, but fewer returns kept than a sphere needs.
    TooFewReturns,
    /// The solve stopped before any returns were kept (the refusal says why).
    Stopped,
}

/// One pass over one sphere: its window's returns on one course ([`find_passes`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassReport {
    /// Sphere index.
    pub sphere: u8,
    /// First and last windowed return.
    pub start: GpsTime,
    /// ...
    pub end: GpsTime,
    /// Slices of time, and those where the sphere was detected.
    pub slices: u32,
    /// ...
    pub detected: u32,
    /// Mean inliers of its detections (the detection score).
    pub mean_inliers: f32,
    /// Windowed returns by verdict.
    pub verdicts: Tally,
    /// The sphere's centre fitted (radius fixed) to the pass's kept returns with the solution,
    /// minus the surveyed one [m, NED] (zero with fewer than 10 returns).
    pub centre_offset: [f32; 3],
    /// Its component along the track (the platform's mean horizontal velocity) [m].
    pub along_track: f32,
    /// Its chi-square against its uncertainty (3 degrees of freedom).
    pub chi2: f32,
    /// The time offset the pass's own returns give, minus the solution's at its time [s]
    /// (with the mounting held; 0 with fewer than 10 returns).
    pub dt_shift: f32,
    /// Its 1-sigma [s] (0: not estimated).
    pub dt_sigma: f32,
}

/// One detect-and-solve round.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Round {
    /// The shell (inlier band) used [m].
    pub tau: f64,
    /// The prior radius used (`None`: the whole window) [m].
    pub prior: Option<f64>,
    /// Returns kept, all spheres.
    pub kept: usize,
    /// Slices where a sphere was detected, all spheres.
    pub detected: u32,
    /// The parameters after the round's solve.
    pub b: Params,
    /// The time offset after the round's solve [s].
    pub dt: f64,
}

/// How the detect-and-solve rounds ended (argmin's `TerminationReason`, for these rounds).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Termination {
    /// No round ran: fewer than two spheres were given.
    #[default]
    NotStarted,
    /// The kept sets barely changed and the parameters stood still.
    Settled,
    /// The kept sets came back to an earlier round's (a few returns at the shell's edge going
    /// in and out).
    Cycle,
    /// A round found fewer than two spheres.
    TooFewSpheres,
    /// The rounds could not go on: the spheres are ambiguous or the mounting left its bounds
    /// (the refusal says which).
    Stopped,
    /// `Settings::max_rounds` rounds ran without settling.
    MaxRounds,
}

impl Termination {
    /// A stable name (the report's `termination` key).
    pub fn name(self) -> &'static str {
        match self {
            Termination::NotStarted => "not_started",
            Termination::Settled => "settled",
            Termination::Cycle => "cycle",
            Termination::TooFewSpheres => "too_few_spheres",
            Termination::Stopped => "stopped",
            Termination::MaxRounds => "max_rounds",
        }
    }

    /// In words.
    pub fn words(self) -> &'static str {
        match self {
            Termination::NotStarted => "no round ran (fewer than two spheres given)",
            Termination::Settled => "the kept returns and the mounting settled",
            Termination::Cycle => {
                "the kept returns went round a cycle (returns at the shell's edge in and out)"
            }
            Termination::TooFewSpheres => "a round found fewer than two spheres",
            Termination::Stopped => {
                "the rounds could not go on (ambiguous spheres or a mounting out of bounds)"
            }
            Termination::MaxRounds => "the rounds reached their limit without settling",
        }
    }
}

/// The answer and everything known about it.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// The mounting parameters.
    pub b: Params,
    /// The time offset between the clocks on top of what the pipeline applied [s] (INS minus
    /// LiDAR) at `t_ref`; 0 when not estimated.
    pub dt: f64,
    /// Its drift [s/s] (0 when not estimated).
    pub drift: f64,
    /// The time `dt` refers to (the middle of the windowed returns).
    pub t_ref: GpsTime,
    /// The Nelder-Mead stage.
    pub nm: NmResult<P>,
    /// The LM stage (covariance, correlation, conditioning).
    pub lm: Option<LmResult>,
    /// Eq. 6 at the solution over the kept returns [m].
    pub l1: f64,
    /// Detect-and-solve rounds.
    pub rounds: usize,
    /// How they ended.
    pub termination: Termination,
    /// What each round did.
    pub log: heapless::Vec<Round, 16>,
    /// The final shell half-width [m].
    pub shell: f64,
    /// Per sphere.
    pub spheres: heapless::Vec<SphereReport, MAX_TARGETS>,
    /// Per pass over each sphere.
    pub passes: heapless::Vec<PassReport, MAX_PASSES>,
    /// RMS of fitted minus surveyed centres [m].
    pub center_rms: Option<f64>,
    /// Parameters the data determine poorly: with a condition number above
    /// [`Settings::weak_condition`], those with a share above 0.3 of the weakest direction
    /// (the eigenvector of the scaled normal matrix's smallest eigenvalue); the six, then the
    /// time offset. None on a well-conditioned solution.
    pub weak: [bool; P + 1],
    /// With the time offset held: what the data give when free to estimate it (offset, sigma
    /// [s]), the test of the held value.
    pub dt_free: Option<(f64, f64)>,
    /// The residual RMS the noise model predicts [m].
    pub predicted_rms: f64,
    /// The first round's consensus over the slices' candidates.
    pub consensus: Option<Consensus>,
    /// The box the mounting had to stay in.
    pub bounds: Bounds,
    /// Why the solution is not claimed, if it is not.
    pub refusal: Option<Refusal>,
}

fn with_problem<R>(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    stride: usize,
    time: TimeOffset,
    weights: Option<Noise>,
    f: impl FnOnce(&Problem<'_>) -> R,
) -> R {
    let mut spheres: heapless::Vec<SphereObs<'_>, MAX_TARGETS> = heapless::Vec::new();
    for (j, t) in targets.iter().enumerate().take(MAX_TARGETS) {
        let _ = spheres.push(SphereObs {
            target: *t,
            obs: &obs[j][..used[j]],
        });
    }
    f(&Problem {
        spheres: &spheres,
        stride,
        dt: time.dt,
        drift: time.drift,
        t_ref: time.t_ref,
        weights,
    })
}

/// A median of positive values to 1 % from 256 log-spaced bins between 1e-5 and 100 m.
struct Histogram {
    bins: [u32; 256],
    n: u32,
}

impl Histogram {
    const LO: f64 = 1e-5;
    const DECADES: f64 = 7.0;
    fn new() -> Self {
        Self {
            bins: [0; 256],
            n: 0,
        }
    }
    fn add(&mut self, v: f64) {
        let x = libm::log10(v.max(Self::LO) / Self::LO) / Self::DECADES * 256.0;
        let i = if x.is_finite() {
            (x as usize).min(255)
        } else {
            255
        };
        self.bins[i] += 1;
        self.n += 1;
    }
    fn median(&self) -> f64 {
        let mut acc = 0;
        for (i, &c) in self.bins.iter().enumerate() {
            acc += c;
            if 2 * acc >= self.n {
                return Self::LO * libm::pow(10.0, (i as f64 + 0.5) / 256.0 * Self::DECADES);
            }
        }
        Self::LO * libm::pow(10.0, Self::DECADES)
    }
}

/// Signed residual of one observation.
fn residual(o: &Observation, t: &Target, b: &[f64; P], time: &TimeOffset) -> f64 {
    let m = Mount::from_params(&Params(*b));
    (o.georef_dt(&m, time.at(o)) - t.center).norm() - t.radius
}

/// The residual RMS the noise model predicts over the kept returns ([`Noise::variance`]: range
/// noise, INS attitude noise times the range, INS position noise, the 2 mm range quantisation;
/// each return's own INS sigmas where the trajectory's accuracy file gives them).
fn predicted_rms(obs: &[&mut [Observation]], used: &[usize], s: &Settings) -> f64 {
    let noise = s.noise();
    let (mut s2, mut n) = (0.0, 0usize);
    for (v, &u) in obs.iter().zip(used) {
        for o in &v[..u] {
            s2 += noise.variance(o);
            n += 1;
        }
    }
    libm::sqrt(s2 / n.max(1) as f64)
}

/// The least squares are weighted by the noise model when the trajectory's accuracy file gave
/// any kept return its own INS sigmas (the returns' variances then differ along the survey);
/// otherwise every residual counts alike, as in the paper.
fn weights(obs: &[&mut [Observation]], used: &[usize], s: &Settings) -> Option<Noise> {
    obs.iter()
        .zip(used)
        .any(|(v, &u)| v[..u.min(v.len())].iter().any(|o| o.ins_sigma != [0.0; 2]))
        .then(|| s.noise())
}

/// Each pass's sphere centre (fitted, radius fixed, to its kept returns with the solution)
/// against the surveyed one: its offset, along-track component and chi-square into `passes`;
/// returns the worst pass as a refusal if any fails (beyond `max_pass_chi2` and
/// `pass_offset_floor`). The uncertainty: the fit's, from the pass's residual scatter (at least
/// 1 mm), inflated by the returns per 20 ms cluster (they share INS errors).
#[allow(clippy::too_many_arguments)]
fn consistency(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    b: &[f64; P],
    time: &TimeOffset,
    s: &Settings,
    passes: &mut heapless::Vec<PassReport, MAX_PASSES>,
) -> Option<Refusal> {
    let mount = Mount::from_params(&Params(*b));
    let mut worst: Option<(f64, Refusal)> = None;
    for (k, p) in passes.iter_mut().enumerate() {
        let j = usize::from(p.sphere);
        let (Some(t), Some(v)) = (targets.get(j), obs.get(j)) else {
            continue;
        };
        let kept = v[..used[j]]
            .iter()
            .filter(|o| o.time >= p.start && o.time <= p.end);
        let Some(fit) = fit_with_covariance(kept.clone(), &mount, time, t) else {
            continue;
        };
        let (d, jtj, rms, n) = fit;
        // Clusters of 20 ms: returns within one share INS errors.
        let mut clusters = 0usize;
        let mut last = i64::MIN;
        let mut vel = Vector3::<f64>::zeros();
        for o in kept {
            let c = o.time.0.div_euclid(s.cluster_ns.max(1));
            if c != last {
                clusters += 1;
                last = c;
            }
            vel += o.velocity.cast::<f64>();
        }
        let inflate = n as f64 / clusters.max(1) as f64;
        let s2 = rms.max(1e-3) * rms.max(1e-3) * inflate;
        let chi2 = d.dot(&(jtj * d)) / s2;
        vel.z = 0.0;
        let along = if vel.norm() > 0.0 {
            d.dot(&(vel / vel.norm()))
        } else {
            0.0
        };
        p.centre_offset = [d.x as f32, d.y as f32, d.z as f32];
        p.along_track = along as f32;
        p.chi2 = chi2 as f32;
        if chi2 > s.max_pass_chi2
            && d.norm() > s.pass_offset_floor
            && worst.as_ref().is_none_or(|(c, _)| chi2 > *c)
        {
            worst = Some((
                chi2,
                Refusal::Inconsistent {
                    sphere: j,
                    pass: k,
                    offset: [d.x, d.y, d.z],
                    along_track: along,
                    chi2,
                },
            ));
        }
    }
    worst.map(|(_, r)| r)
}

/// Each pass's own time offset: the returns of one pass over one sphere, with the mounting and
/// the time offset model held, fitted for a shift of the offset and a radius offset (`r_k = c -
/// J_k shift`, `J_k = dr/ddt`, the platform's motion along the surface normal); its sigma from
/// the fit's scatter inflated by the returns per cluster, as [`consistency`]. Into `passes`;
/// the pass furthest off as a refusal when it is off by more than `held_dt_sigmas` sigmas and
/// `held_dt_floor` seconds: a clock that steps or drifts moves some passes and not others.
fn pass_clocks(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    b: &[f64; P],
    time: &TimeOffset,
    s: &Settings,
    passes: &mut heapless::Vec<PassReport, MAX_PASSES>,
) -> Option<Refusal> {
    let lin = super::objective::Linearised::at(b);
    let first = passes.iter().map(|p| p.start.0).min().unwrap_or(0);
    let mut worst: Option<(f64, Refusal)> = None;
    for (k, p) in passes.iter_mut().enumerate() {
        let j = usize::from(p.sphere);
        let (Some(t), Some(v)) = (targets.get(j), obs.get(j)) else {
            continue;
        };
        let kept = v[..used[j]]
            .iter()
            .filter(|o| o.time >= p.start && o.time <= p.end);
        // Sums for the two-parameter fit, and the clusters.
        let (mut n, mut sj, mut sr, mut sjj, mut sjr, mut srr) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut clusters, mut last) = (0usize, i64::MIN);
        for o in kept {
            let Some(row) = lin.row(o, t, time.at(o)) else {
                continue;
            };
            let (jd, r) = (row.row[6], row.residual);
            n += 1.0;
            sj += jd;
            sr += r;
            sjj += jd * jd;
            sjr += jd * r;
            srr += r * r;
            let c = o.time.0.div_euclid(s.cluster_ns.max(1));
            if c != last {
                clusters += 1;
                last = c;
            }
        }
        if n < 10.0 {
            continue;
        }
        let vjj = sjj - sj * sj / n;
        if vjj.is_nan() || vjj <= 0.0 {
            continue;
        }
        // r = c + J kk; a residual r at the model's offset is what -J (dt_data - dt_model)
        // leaves, so the pass's own offset is the model's minus kk.
        let kk = (sjr - sj * sr / n) / vjj;
        let c = (sr - kk * sj) / n;
        // Residual scatter (at least 1 mm), inflated by the returns per cluster.
        let e2 =
            (srr - 2.0 * c * sr - 2.0 * kk * sjr + n * c * c + 2.0 * c * kk * sj + kk * kk * sjj)
                / (n - 2.0).max(1.0);
        let s2 = e2.max(1e-6) * n / clusters.max(1) as f64;
        let sigma = libm::sqrt(s2 / vjj);
        let shift = -kk;
        p.dt_shift = shift as f32;
        p.dt_sigma = sigma as f32;
        let z = shift.abs() / sigma;
        if z > s.held_dt_sigmas
            && shift.abs() > s.held_dt_floor
            && worst.as_ref().is_none_or(|(w, _)| z > *w)
        {
            worst = Some((
                z,
                Refusal::ClockInconsistent {
                    sphere: j,
                    pass: k,
                    start: p.start,
                    end: p.end,
                    into: [
                        (p.start.0 - first) as f64 * 1e-9,
                        (p.end.0 - first) as f64 * 1e-9,
                    ],
                    shift,
                    sigma,
                },
            ));
        }
    }
    worst.map(|(_, r)| r)
}

/// A sphere's centre fitted (radius fixed) to returns with a mounting and time offset, minus
/// the surveyed one: (offset, `J^T J`, residual RMS, count); `None` with fewer than 10 returns
/// or a singular geometry.
fn fit_with_covariance<'a>(
    obs: impl Iterator<Item = &'a Observation> + Clone,
    mount: &Mount,
    time: &TimeOffset,
    t: &Target,
) -> Option<(Vector3<f64>, nalgebra::Matrix3<f64>, f64, usize)> {
    let pts = obs.map(|o| o.georef_dt(mount, time.at(o)));
    if pts.clone().count() < 10 {
        return None;
    }
    let c = fit_center(pts.clone(), t.radius, t.center)?;
    let (mut jtj, mut e2, mut n) = (nalgebra::Matrix3::zeros(), 0.0, 0usize);
    for x in pts {
        let dv = x - c;
        let norm = dv.norm();
        if norm == 0.0 {
            continue;
        }
        let g = dv / norm;
        jtj += g * g.transpose();
        e2 += (norm - t.radius) * (norm - t.radius);
        n += 1;
    }
    Some((c - t.center, jtj, libm::sqrt(e2 / n.max(1) as f64), n))
}

/// Move the kept observations to the front in time order (the others follow in no particular
/// order); returns how many are kept.
fn partition(v: &mut [Observation]) -> usize {
    let mut k = 0;
    for i in 0..v.len() {
        if v[i].work.verdict == Verdict::Kept as u8 {
            v.swap(i, k);
            k += 1;
        }
    }
    v[..k].sort_unstable_by_key(|o| (o.time, o.channel, o.block));
    k
}

/// The fingerprint of a kept set.
fn fingerprint(h: u64, v: &[Observation]) -> u64 {
    let mut h = h;
    for o in v {
        h = (h ^ o.time.0 as u64 ^ (u64::from(o.channel) << 56)).wrapping_mul(0x100_0000_01b3);
    }
    (h ^ v.len() as u64).wrapping_mul(0x100_0000_01b3)
}

/// The solver's scratch, from the caller (no heap in the core).
#[derive(Debug)]
pub struct Workspace<'a> {
    /// The detection's vote grid, all zero (64^3 = 262,144 cells suit windows of a few metres;
    /// fewer cells make coarser votes).
    pub grid: &'a mut [u16],
    /// Room for the kept returns of a round (all spheres); a round that keeps more solves on an
    /// evenly spread subset (the last solve always uses every kept return).
    pub kept: &'a mut [Observation],
    /// A slice's index by x; its length caps a slice's returns (32,768 is ample: 0.4 s of a
    /// window rarely holds 10,000).
    pub keys: &'a mut [(f32, u32)],
    /// The first round's candidates (up to four per slice of each window; more are dropped).
    pub cands: &'a mut [Candidate],
    /// Candidate indices, as long as `cands`.
    pub idx: &'a mut [usize],
}

/// How far the slices' apparent spheres (fitted to their kept returns, fixed radius) lie from
/// the surveyed one with the current mounting, into `h` (slices with eight or more kept
/// returns: a slice's fit is poor with fewer). `v` holds kept returns grouped by slice.
fn apparent_offsets(v: &[Observation], r: f64, h: &mut Histogram) {
    for sl in extract::slices(v) {
        let kept = v[sl].iter().map(|o| {
            Vector3::new(
                f64::from(o.work.x[0]),
                f64::from(o.work.x[1]),
                f64::from(o.work.x[2]),
            )
        });
        if kept.len() < 8 {
            continue;
        }
        if let Some(c) = fit_center(kept, r, Vector3::zeros()) {
            h.add(c.norm());
        }
    }
}

/// Detect the sphere in every slice of one sphere's observations (grouped by slice, in time
/// order of slices) and tag them; `surveyed`: keep around the surveyed centre (the last
/// round) rather than the detection. Returns (kept, slices, detected); with `passes` (this
/// sphere's), also counts each pass's slices and detections.
#[allow(clippy::too_many_arguments)]
fn extract_sphere(
    v: &mut [Observation],
    t: &Target,
    tau: f64,
    prior: Option<f64>,
    surveyed: bool,
    grid: &mut [u16],
    keys: &mut [(f32, u32)],
    dirs: &Directions,
    st: &ExtractSettings,
    noise: &Noise,
    mut passes: Option<&mut [PassReport]>,
) -> (usize, u32, u32) {
    let (mut kept, mut slices, mut detected) = (0, 0, 0);
    let mut start = 0;
    while start < v.len() {
        let Some(sl) = extract::slices(&v[start..]).next() else {
            break;
        };
        let sl = start + sl.start..start + sl.end;
        start = sl.end;
        slices += 1;
        let t0 = v[sl.clone()]
            .iter()
            .map(|o| o.time)
            .min()
            .unwrap_or(GpsTime(0));
        let det = extract::detect(&v[sl.clone()], keys, t.radius, tau, prior, grid, dirs, st);
        match det {
            Some(d) => {
                detected += 1;
                let c = if surveyed { [0.0; 3] } else { d.center };
                kept += extract::keep(&mut v[sl.clone()], c, t.radius, tau, noise);
            }
            None => extract::tag(&mut v[sl.clone()], Verdict::Undetected),
        }
        if let Some(p) = passes.as_deref_mut().and_then(|ps| pass_of(ps, t0)) {
            p.slices += 1;
            if let Some(d) = det {
                p.detected += 1;
                p.mean_inliers += d.inliers as f32;
            }
        }
    }
    (kept, slices, detected)
}

/// The pass holding time `t` (the last one starting at or before it).
fn pass_of(ps: &mut [PassReport], t: GpsTime) -> Option<&mut PassReport> {
    let i = ps.partition_point(|p| p.start <= t);
    ps.get_mut(i.checked_sub(1)?)
}

/// The passes over one sphere: its windowed returns (in time order) split where the platform's
/// course has turned more than 90 deg from the pass's first course, and at gaps longer than
/// `gap_ns` (a second visit on the same course); a piece shorter than `min_ns` after a turn
/// (the turn itself) joins the pass before it. The course decides, not the window: a level
/// scan sees a sphere's window from everywhere, a tilted one only when abeam, and turns show
/// the sphere in fragments. Appended to `out` (beyond its capacity the last one is extended).
fn find_passes(
    v: &[Observation],
    j: usize,
    gap_ns: i64,
    min_ns: i64,
    out: &mut heapless::Vec<PassReport, MAX_PASSES>,
) {
    /// Slower than this the course is not defined [m/s].
    const MOVING: f32 = 0.3;
    let course = |o: &Observation| {
        let (n, e) = (o.velocity.x, o.velocity.y);
        let s = libm::sqrtf(n * n + e * e);
        (s > MOVING).then(|| [n / s, e / s])
    };
    let first = out.len();
    let mut last: Option<GpsTime> = None;
    let mut first_course: Option<[f32; 2]> = None;
    for o in v {
        let c = course(o);
        let gap = last.is_none_or(|l| o.time.0 - l.0 > gap_ns);
        let turned =
            matches!((first_course, c), (Some(a), Some(b)) if a[0] * b[0] + a[1] * b[1] < 0.0);
        if turned && !gap {
            join_short(out, first, min_ns);
        }
        last = Some(o.time);
        if gap || turned || first_course.is_none() {
            first_course = c;
        }
        if (gap || turned) && !out.is_full() {
            let _ = out.push(PassReport {
                sphere: j as u8,
                start: o.time,
                end: o.time,
                slices: 0,
                detected: 0,
                mean_inliers: 0.0,
                verdicts: [0; 8],
                centre_offset: [0.0; 3],
                along_track: 0.0,
                chi2: 0.0,
                dt_shift: 0.0,
                dt_sigma: 0.0,
            });
        } else if let Some(p) = out.last_mut() {
            p.end = o.time;
        }
    }
    join_short(out, first, min_ns);
}

/// The last pass joins the one before it (of the same sphere, from index `first` of `out`)
/// when it is shorter than `min_ns` and follows it within `min_ns`.
fn join_short(out: &mut heapless::Vec<PassReport, MAX_PASSES>, first: usize, min_ns: i64) {
    let n = out.len();
    if n < first + 2 {
        return;
    }
    let (prev, last) = (out[n - 2], out[n - 1]);
    if last.end.0 - last.start.0 < min_ns && last.start.0 - prev.end.0 <= min_ns {
        out[n - 2].end = last.end;
        out.pop();
    }
}

/// Move the returns of a sphere farther than `reach` from its surface (with the current
/// georeference) behind the others, tagged `OutsideShell`; the near ones keep their order.
/// Returns how many are near.
fn compact(v: &mut [Observation], r: f64, reach: f64) -> usize {
    let (r, reach) = (r as f32, reach as f32);
    let mut w = 0;
    for i in 0..v.len() {
        let x = v[i].work.x;
        let d = libm::sqrtf(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        if (d - r).abs() <= reach {
            v.swap(i, w);
            w += 1;
        } else {
            v[i].work.verdict = Verdict::OutsideShell as u8;
        }
    }
    w
}

/// Copy the kept returns of every sphere into `buf` (at most its length, evenly spread when
/// they do not fit); returns each sphere's range in `buf`.
fn gather(
    obs: &[&mut [Observation]],
    active: &[usize],
    kept: &[usize],
    buf: &mut [Observation],
) -> [Range<usize>; MAX_TARGETS] {
    let total: usize = kept.iter().sum();
    let stride = total.div_ceil(buf.len().max(1)).max(1);
    let mut out: [Range<usize>; MAX_TARGETS] = core::array::from_fn(|_| 0..0);
    let mut w = 0;
    for (j, v) in obs.iter().enumerate().take(MAX_TARGETS) {
        let start = w;
        let kept = v[..active[j]]
            .iter()
            .filter(|o| o.work.verdict == Verdict::Kept as u8);
        for (k, o) in kept.enumerate() {
            if k.is_multiple_of(stride) && w < buf.len() {
                buf[w] = *o;
                w += 1;
            }
        }
        out[j] = start..w;
    }
    out
}

/// Each sphere's windowed returns in time order (once: the scan-line segments, whose lengths
/// do not depend on the mounting, and the slices), georeferenced with the start `b0`,
/// unclassified; and the passes over each sphere.
fn prepare(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    b0: &Params,
    st: &ExtractSettings,
    slices: usize,
) -> heapless::Vec<PassReport, MAX_PASSES> {
    let mount0 = Mount::from_params(b0);
    for (v, t) in obs.iter_mut().zip(targets) {
        v.sort_unstable_by_key(|o| (o.time, o.channel, o.block));
        extract::georeference(v, t, &mount0, &TimeOffset::default());
        extract::runs(v, st.firing_ns, st.jump);
        extract::assign_slices(v, st.slice_ns, slices);
        extract::tag(v, Verdict::Unclassified);
    }
    let mut passes = heapless::Vec::new();
    for (j, v) in obs.iter().enumerate() {
        find_passes(v, j, st.pass_gap_ns, st.pass_min_ns, &mut passes);
    }
    passes
}

/// `buf` cut at the ends of consecutive `ranges` (the first starting at 0): one slice each.
fn split_ranges<'b>(
    buf: &'b mut [Observation],
    ranges: &[Range<usize>],
) -> heapless::Vec<&'b mut [Observation], MAX_TARGETS> {
    let mut part = heapless::Vec::new();
    let mut rest = buf;
    let mut pos = 0;
    for r in ranges {
        let (head, tail) = core::mem::take(&mut rest).split_at_mut(r.end - pos);
        let _ = part.push(head);
        rest = tail;
        pos = r.end;
    }
    part
}

impl Solution {
    /// The time offset model of the answer.
    pub fn time(&self) -> TimeOffset {
        TimeOffset {
            dt: self.dt,
            drift: self.drift,
            t_ref: self.t_ref,
        }
    }

    /// Nothing solved yet: the start `b0`, the first shell `tau0`.
    fn start(b0: &Params, tau0: f64) -> Self {
        Self {
            b: *b0,
            dt: 0.0,
            drift: 0.0,
            t_ref: GpsTime(0),
            nm: NmResult {
                x: b0.deg_m().0,
                f: f64::INFINITY,
                iterations: 0,
                evaluations: 0,
                converged: false,
            },
            lm: None,
            l1: f64::INFINITY,
            rounds: 0,
            termination: Termination::NotStarted,
            log: heapless::Vec::new(),
            shell: tau0,
            spheres: heapless::Vec::new(),
            passes: heapless::Vec::new(),
            center_rms: None,
            weak: [false; P + 1],
            dt_free: None,
            predicted_rms: 0.0,
            consensus: None,
            bounds: Bounds::none(b0),
            refusal: None,
        }
    }
}

/// Solve from `b0` with every sphere's windowed returns (reordered in place: the
/// kept ones first, in time order; each tagged with its [`Verdict`]).
pub fn solve(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    b0: &Params,
    s: &Settings,
    ws: &mut Workspace<'_>,
) -> Solution {
    let n = targets.len().min(obs.len()).min(MAX_TARGETS);
    let targets = &targets[..n];
    let obs = &mut obs[..n];
    let mut windowed = [0usize; MAX_TARGETS];
    for j in 0..n {
        windowed[j] = obs[j].len();
    }
    let mut passes = prepare(targets, obs, b0, &s.extract, ws.keys.len());
    let mut sol = Solution::start(b0, s.extract.tau0);
    sol.bounds = bounds(obs, b0, s.margin);
    if n < 2 {
        sol.refusal = Some(Refusal::TooFewTargets { given: n });
        return sol;
    }
    // 1. Rounds: detect and keep, solve, tighten, until the kept sets stop changing.
    let t_ref = middle_time(obs);
    let mut r = Rounds::start(b0, windowed, s.extract.tau0, sol.bounds, t_ref);
    sol.t_ref = t_ref;
    run_rounds(targets, obs, s, ws, &passes, &mut r, &mut sol);
    sol.shell = r.tau;
    sol.consensus = r.consensus;
    if let Some(end) = r.end {
        // The rounds could not go on: ambiguous spheres or a mounting out of bounds.
        sol.b = Params(r.b);
        sol.dt = r.time.dt;
        sol.drift = r.time.drift;
        sol.t_ref = r.time.t_ref;
        let none = [0usize; MAX_TARGETS];
        let per = PerSphere {
            windowed: &windowed,
            used: &none,
            tallies: &[[0; 8]; MAX_TARGETS],
            counts: &r.counts,
        };
        sphere_reports(targets, obs, &per, b0, &r.time, &mut sol);
        for (j, sp) in sol.spheres.iter_mut().enumerate() {
            sp.agreed = r
                .consensus
                .map_or(0, |c| c.support.get(j).copied().unwrap_or(0));
            sp.lost = Some(Lost::Stopped);
        }
        sol.passes = passes;
        sol.refusal = Some(end);
        return sol;
    }
    // 2. The last extraction, around the surveyed spheres.
    let (used, tallies) = last_extraction(targets, obs, s, ws, &mut r, &mut passes);
    sol.passes = passes;
    let found = (0..n).filter(|&j| used[j] > 0).count();
    // 3. Least squares on the kept returns: the answer and its uncertainty.
    final_fit(targets, obs, &used[..n], found, s, &mut r, &mut sol);
    // 4. Per sphere.
    let per = PerSphere {
        windowed: &windowed,
        used: &used,
        tallies: &tallies,
        counts: &r.counts,
    };
    sphere_reports(targets, obs, &per, b0, &r.time, &mut sol);
    lost_reasons(s, &mut sol);
    // 5. Checks.
    if found < 2 {
        sol.refusal = Some(Refusal::TooFewSpheres { have: found });
        return sol;
    }
    sol.refusal = checks(targets, obs, &used[..n], s, &mut sol);
    sol
}

/// The box the mounting must stay in: each lever-arm component within `margin` of the start
/// (a larger error would leave the spheres outside windows made with that margin), each angle
/// within the angle that moves the nearest windowed return (at least 1 m away) by twice the
/// margin, between 5 and 45 deg.
fn bounds(obs: &[&mut [Observation]], b0: &Params, margin: f64) -> Bounds {
    if !(margin.is_finite() && margin > 0.0) {
        return Bounds::none(b0);
    }
    let near = obs
        .iter()
        .flat_map(|v| v.iter())
        .map(|o| f64::from(o.range))
        .fold(f64::INFINITY, f64::min)
        .max(1.0);
    let angle = if near.is_finite() {
        libm::atan(2.0 * margin / near)
    } else {
        core::f64::consts::FRAC_PI_4
    };
    Bounds {
        start: b0.0,
        angle: angle.clamp(5f64.to_radians(), 45f64.to_radians()),
        lever: margin,
    }
}

/// The middle of the windowed returns' times (the time offset's reference: its drift then
/// barely correlates with it).
fn middle_time(obs: &[&mut [Observation]]) -> GpsTime {
    let (mut lo, mut hi) = (i64::MAX, i64::MIN);
    for o in obs.iter().flat_map(|v| v.iter()) {
        lo = lo.min(o.time.0);
        hi = hi.max(o.time.0);
    }
    if lo > hi {
        GpsTime(0)
    } else {
        GpsTime(lo + (hi - lo) / 2)
    }
}

/// Why each sphere not found was lost.
fn lost_reasons(s: &Settings, sol: &mut Solution) {
    let c = sol.consensus;
    for (j, sp) in sol.spheres.iter_mut().enumerate() {
        sp.agreed = c.map_or(0, |c| c.support.get(j).copied().unwrap_or(0));
        if sp.lost.is_some() {
            continue;
        }
        sp.lost = if sp.used >= s.min_points {
            None
        } else if sp.windowed == 0 {
            Some(Lost::NoReturns)
        } else if c.is_some_and(|c| c.slices.get(j).copied().unwrap_or(0) == 0) {
            Some(Lost::NotDetected)
        } else if c.is_some_and(|c| c.support.get(j).copied().unwrap_or(0) < 3) {
            Some(Lost::Disagrees)
        } else {
            Some(Lost::TooFewReturns)
        };
    }
}

/// What the rounds carry from one to the next and into the last extraction.
struct Rounds {
    /// The parameters [rad, m] (plain numbers for the optimisers).
    b: [f64; P],
    /// The time offset model.
    time: TimeOffset,
    /// The shell half-width [m].
    tau: f64,
    /// The prior radius (`None`: from afar, the whole window) [m].
    prior: Option<f64>,
    /// Each sphere's returns still taking part (the others are far from it).
    active: [usize; MAX_TARGETS],
    /// Each sphere's slices and detections in the latest extraction.
    counts: [(u32, u32); MAX_TARGETS],
    /// The box the mounting must stay in.
    bounds: Bounds,
    /// The first round's consensus.
    consensus: Option<Consensus>,
    /// Why the rounds could not go on (the solution is refused).
    end: Option<Refusal>,
}

impl Rounds {
    fn start(
        b0: &Params,
        windowed: [usize; MAX_TARGETS],
        tau0: f64,
        bounds: Bounds,
        t_ref: GpsTime,
    ) -> Self {
        Self {
            b: b0.0,
            time: TimeOffset {
                dt: 0.0,
                drift: 0.0,
                t_ref,
            },
            tau: tau0,
            prior: None,
            active: windowed,
            counts: [(0, 0); MAX_TARGETS],
            bounds,
            consensus: None,
            end: None,
        }
    }

    /// The mounting is outside its box: the refusal naming the parameter furthest out.
    fn out_of_bounds(&self) -> Option<Refusal> {
        if self.bounds.contains(&self.b) {
            return None;
        }
        let u = self.bounds.usage(&self.b);
        let i = (0..P).max_by(|&a, &b| u[a].total_cmp(&u[b])).unwrap_or(0);
        let limit = if i < 3 {
            self.bounds.angle
        } else {
            self.bounds.lever
        };
        Some(Refusal::OutOfBounds {
            parameter: i,
            change: u[i] * limit,
            limit,
        })
    }
}

/// Rounds until the kept sets barely change and the parameters stand still (to a tenth of the
/// 1e-3 deg / 1e-3 m the method aims for), the kept sets go round a cycle (a few returns at
/// the shell's edge in, out), fewer than two spheres are found, or `max_rounds`.
fn run_rounds(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    passes: &[PassReport],
    r: &mut Rounds,
    sol: &mut Solution,
) {
    let mut prints: heapless::Vec<u64, 4> = heapless::Vec::new();
    let mut last_kept: Option<usize> = None;
    sol.termination = Termination::MaxRounds;
    for round in 0..s.max_rounds {
        sol.rounds = round + 1;
        let (b_before, dt_before) = (r.b, r.time.dt);
        let Some((total, print, next_prior)) = one_round(targets, obs, s, ws, passes, r, sol)
        else {
            sol.termination = if r.end.is_some() {
                Termination::Stopped
            } else {
                Termination::TooFewSpheres
            };
            break;
        };
        if let Some(out) = r.out_of_bounds() {
            r.end = Some(out);
            sol.termination = Termination::Stopped;
            break;
        }
        let moved = Params(r.b)
            .deg_m()
            .0
            .iter()
            .zip(Params(b_before).deg_m().0)
            .map(|(a, c)| (a - c).abs())
            .fold(0.0, f64::max)
            .max((r.time.dt - dt_before).abs() * 20.0);
        let still =
            last_kept.is_some_and(|k: usize| k.abs_diff(total) * 200 <= total) && moved < 2e-3;
        let cycle = prints.contains(&print);
        let settled = r.prior.is_some() && (still || cycle);
        r.prior = Some(next_prior);
        last_kept = Some(total);
        if prints.is_full() {
            prints.remove(0);
        }
        let _ = prints.push(print);
        if settled {
            sol.termination = if still {
                Termination::Settled
            } else {
                Termination::Cycle
            };
            break;
        }
    }
}

/// One round: extract each sphere's returns, solve on the kept ones, the next shell. Returns
/// the returns kept, their fingerprint and the next prior radius; `None` when fewer than two
/// spheres are found.
fn one_round(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    passes: &[PassReport],
    r: &mut Rounds,
    sol: &mut Solution,
) -> Option<(usize, u64, f64)> {
    let n = targets.len();
    let round_tau = r.tau;
    let kept = if r.prior.is_none() {
        first_extract(targets, obs, s, ws, passes, r)?
    } else {
        round_extract(targets, obs, s, ws, r)?
    };
    let ranges = gather(obs, &r.active[..n], &kept[..n], ws.kept);
    let buf = &mut *ws.kept;
    let mut print = 0xcbf2_9ce4_8422_2325u64;
    for rg in ranges.iter().take(n) {
        print = fingerprint(print, &buf[rg.clone()]);
    }
    let mut part = split_ranges(buf, &ranges[..n]);
    let lens: [usize; MAX_TARGETS] = core::array::from_fn(|j| part.get(j).map_or(0, |p| p.len()));
    round_solve(targets, &mut part, &lens, s, r, sol);
    let next_prior = next_shell(targets, &mut part, &lens, s, r);
    let total: usize = kept[..n].iter().sum();
    let _ = sol.log.push(Round {
        tau: round_tau,
        prior: r.prior,
        kept: total,
        detected: r.counts[..n].iter().map(|c| c.1).sum(),
        b: Params(r.b),
        dt: r.time.dt,
    });
    Some((total, print, next_prior))
}

/// The first round: every sphere-like candidate of every slice ([`extract::detect_all`]), the
/// consensus over them ([`consensus`]) for the mounting and the candidates that are the spheres,
/// and the returns within `tau` of those kept. The consensus mounting becomes the rounds'
/// parameters; an ambiguous sphere ends the rounds. `None` when fewer than two spheres are
/// agreed on.
fn first_extract(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    passes: &[PassReport],
    r: &mut Rounds,
) -> Option<[usize; MAX_TARGETS]> {
    let n = targets.len();
    let dirs = Directions::default();
    let mount = Mount::from_params(&Params(r.b));
    let mut nc = 0;
    let mut found = extract::Candidates::new();
    for j in 0..n {
        let v = &mut obs[j][..r.active[j]];
        extract::georeference(v, &targets[j], &mount, &r.time);
        extract::tag(v, Verdict::Undetected);
        let (mut slices, mut detected) = (0, 0);
        let mut start = 0;
        loop {
            let Some(sl) = extract::slices(&v[start..]).next() else {
                break;
            };
            let sl = start + sl.start..start + sl.end;
            start = sl.end;
            slices += 1;
            let slice = &v[sl.clone()];
            extract::detect_all(
                slice,
                ws.keys,
                targets[j].radius,
                r.tau,
                None,
                ws.grid,
                &dirs,
                &s.extract,
                extract::MAX_CANDIDATES,
                &mut found,
            );
            detected += u32::from(!found.is_empty());
            // The pose of the slice's middle return carries its candidates.
            let rep = &slice[slice.len() / 2];
            let group = passes
                .iter()
                .rposition(|p| usize::from(p.sphere) == j && p.start <= rep.time)
                .unwrap_or(0);
            for d in &found {
                let Some(c) = Candidate::new(d.center, rep, &targets[j], &mount, &r.time) else {
                    continue;
                };
                if let Some(slot) = ws.cands.get_mut(nc) {
                    *slot = Candidate {
                        sphere: j as u8,
                        group: group as u16,
                        slice: rep.work.slice,
                        inliers: d.inliers,
                        ..c
                    };
                    nc += 1;
                }
            }
        }
        r.counts[j] = (slices, detected);
    }
    let mut search = Search {
        cands: &mut ws.cands[..nc],
        targets,
        time: r.time,
        bounds: r.bounds,
        settings: s.consensus,
    };
    let Some(c) = consensus(&mut search, &r.b, ws.idx) else {
        // Not three candidates apart, or no mounting within the bounds explains any.
        r.consensus = Some(Consensus {
            b: r.b,
            score: 0.0,
            support: [0; MAX_TARGETS],
            slices: core::array::from_fn(|j| r.counts[j].1),
            rms: f64::NAN,
            hypotheses: 0,
            ambiguous: None,
        });
        return None;
    };
    r.consensus = Some(c);
    if let Some(a) = c.ambiguous {
        r.end = Some(Refusal::Ambiguous(a));
        return None;
    }
    // Keep the returns of the chosen candidates (slices and candidates are in one order).
    let mut kept = [0usize; MAX_TARGETS];
    let cands = &ws.cands[..nc];
    let mut k = 0;
    for j in 0..n {
        let v = &mut obs[j][..r.active[j]];
        let mut start = 0;
        loop {
            let Some(sl) = extract::slices(&v[start..]).next() else {
                break;
            };
            let sl = start + sl.start..start + sl.end;
            start = sl.end;
            let id = v[sl.start + sl.len() / 2].work.slice;
            while k < nc
                && (usize::from(cands[k].sphere) < j
                    || (usize::from(cands[k].sphere) == j && cands[k].slice < id))
            {
                k += 1;
            }
            let mut chosen = None;
            while k < nc && usize::from(cands[k].sphere) == j && cands[k].slice == id {
                if cands[k].chosen {
                    chosen = Some(cands[k].detected);
                }
                k += 1;
            }
            if let Some(at) = chosen {
                kept[j] += extract::keep(&mut v[sl], at, targets[j].radius, r.tau, &s.noise());
            }
        }
    }
    r.b = c.b;
    if (0..n).filter(|&j| kept[j] >= s.min_points).count() < 2 {
        return None;
    }
    for (j, v) in obs.iter_mut().enumerate() {
        if kept[j] < s.min_points {
            kept[j] = 0;
            extract::tag(&mut v[..r.active[j]], Verdict::Undetected);
        }
    }
    Some(kept)
}

/// Each sphere's returns extracted with the current parameters, shell and prior; spheres with
/// fewer than `min_points` take no part (kept 0, tagged undetected). `None` when fewer than
/// two are found.
fn round_extract(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    r: &mut Rounds,
) -> Option<[usize; MAX_TARGETS]> {
    let n = targets.len();
    let dirs = Directions::default();
    let mount = Mount::from_params(&Params(r.b));
    let mut kept = [0usize; MAX_TARGETS];
    for j in 0..n {
        let v = &mut obs[j][..r.active[j]];
        extract::georeference(v, &targets[j], &mount, &r.time);
        if let Some(p) = r.prior {
            // Returns far from the sphere (a few prior radii beyond its surface, at least
            // half a metre) cannot become its returns any more: they leave the rounds.
            r.active[j] = compact(v, targets[j].radius, (4.0 * p).max(0.5) + r.tau);
        }
        let v = &mut obs[j][..r.active[j]];
        let (k, sl, det) = extract_sphere(
            v,
            &targets[j],
            r.tau,
            r.prior,
            false,
            ws.grid,
            ws.keys,
            &dirs,
            &s.extract,
            &s.noise(),
            None,
        );
        r.counts[j] = (sl, det);
        kept[j] = k;
    }
    if (0..n).filter(|&j| kept[j] >= s.min_points).count() < 2 {
        return None;
    }
    for (j, v) in obs.iter_mut().enumerate() {
        if kept[j] < s.min_points {
            kept[j] = 0;
        }
        if kept[j] == 0 {
            extract::tag(&mut v[..r.active[j]], Verdict::Undetected);
        }
    }
    Some(kept)
}

/// The round's solve on the kept returns `part`: from afar (no prior yet) Nelder-Mead on eq. 6
/// (L1) over at most `nm_points` returns per sphere, evenly spread, with a restart; close,
/// least squares (time order for its clusters).
fn round_solve(
    targets: &[Target],
    part: &mut [&mut [Observation]],
    lens: &[usize; MAX_TARGETS],
    s: &Settings,
    r: &mut Rounds,
    sol: &mut Solution,
) {
    let n = targets.len();
    if r.prior.is_none() {
        let most = lens[..n].iter().copied().max().unwrap_or(1);
        let stride = most.div_ceil(s.nm_points.max(1)).max(1);
        let mut nm = with_problem(targets, part, lens, stride, r.time, None, |pb| {
            minimize::<P, 7>(
                |x| pb.l1(&DegM(*x).params().0),
                &Params(r.b).deg_m().0,
                &s.step,
                &s.nm,
            )
        });
        nm.evaluations += sol.nm.evaluations;
        nm.iterations += sol.nm.iterations;
        sol.nm = nm;
        r.b = DegM(nm.x).params().0;
    } else {
        for p in part.iter_mut().take(n) {
            p.sort_unstable_by_key(|o| (o.time, o.channel, o.block));
        }
        let w = weights(part, &lens[..n], s);
        let lm = with_problem(targets, part, lens, 1, r.time, w, |pb| {
            refine(pb, &r.b, s.lm_iter, s.cluster_ns, s.clock())
        });
        r.b = lm.b;
        if lm.dt.is_finite() && lm.drift.is_finite() {
            r.time.dt = lm.dt;
            r.time.drift = lm.drift;
        }
    }
}

/// The next shell (from the kept returns' median residual against the surveyed spheres, into
/// `r.tau`) and the next prior radius (from their apparent offsets), returned.
fn next_shell(
    targets: &[Target],
    part: &mut [&mut [Observation]],
    lens: &[usize; MAX_TARGETS],
    s: &Settings,
    r: &mut Rounds,
) -> f64 {
    let med = with_problem(targets, part, lens, 1, r.time, None, |pb| {
        let mut h = Histogram::new();
        pb.residuals(&r.b, |_, e| h.add(e.abs()));
        h.median()
    });
    let widest = s
        .extract
        .tau0
        .max(0.5 * targets.iter().map(|t| t.radius).fold(0.0, f64::max));
    r.tau = (s.shell_sigmas * 1.4826 * med).clamp(s.shell_floor, widest);
    let mount = Mount::from_params(&Params(r.b));
    let mut offsets = Histogram::new();
    for j in (0..targets.len()).filter(|&j| lens[j] > 0) {
        part[j].sort_unstable_by_key(|o| o.work.slice);
        extract::georeference(part[j], &targets[j], &mount, &r.time);
        apparent_offsets(part[j], targets[j].radius, &mut offsets);
    }
    let off = if offsets.n > 0 { offsets.median() } else { 1.0 };
    (4.0 * off).max(3.0 * r.tau).max(0.02)
}

/// The last extraction: around the surveyed spheres, in the slices where the sphere is
/// detected near them, attachments (a stand, a deck) rejected; spheres with too few returns
/// are not found. Returns each sphere's kept count (the kept ones first in `obs`) and its
/// verdict tallies; the passes get theirs.
fn last_extraction(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    r: &mut Rounds,
    passes: &mut [PassReport],
) -> ([usize; MAX_TARGETS], [[u32; 8]; MAX_TARGETS]) {
    let dirs = Directions::default();
    let tau = r.tau;
    let mount = Mount::from_params(&Params(r.b));
    let mut used = [0usize; MAX_TARGETS];
    let mut tallies = [[0u32; 8]; MAX_TARGETS];
    for j in 0..targets.len() {
        let v = &mut obs[j][..r.active[j]];
        extract::georeference(v, &targets[j], &mount, &r.time);
        let mine = {
            let a = passes.partition_point(|p| usize::from(p.sphere) < j);
            let b = passes.partition_point(|p| usize::from(p.sphere) <= j);
            &mut passes[a..b]
        };
        let (_, sl, det) = extract_sphere(
            v,
            &targets[j],
            tau,
            Some(r.prior.unwrap_or(3.0 * tau).max(3.0 * tau)),
            true,
            ws.grid,
            ws.keys,
            &dirs,
            &s.extract,
            &s.noise(),
            Some(&mut *mine),
        );
        r.counts[j] = (sl, det);
        // What meets the sphere (its stand, a deck) is recognised around the surveyed centre.
        let kept = v
            .iter()
            .filter(|o| o.work.verdict == Verdict::Kept as u8)
            .count() as u32;
        extract::reject_attachments(v, targets[j].radius, tau, &dirs, (kept / 33).max(8));
        used[j] = partition(obs[j]);
        if used[j] < s.min_points {
            extract::tag(obs[j], Verdict::NotFound);
            used[j] = 0;
        }
        for o in obs[j].iter() {
            let k = usize::from(o.work.verdict).min(7);
            tallies[j][k] += 1;
            if let Some(p) = pass_of(mine, o.time) {
                p.verdicts[k] += 1;
            }
        }
        for p in mine.iter_mut() {
            if p.detected > 0 {
                p.mean_inliers /= p.detected as f32;
            }
        }
    }
    (used, tallies)
}

/// Least squares on the kept returns (with at least two spheres found); with the offset held,
/// the same returns with it free test the held value. Sets the answer and eq. 6 at it.
fn final_fit(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    found: usize,
    s: &Settings,
    r: &mut Rounds,
    sol: &mut Solution,
) {
    let w = weights(obs, used, s);
    let lm = (found >= 2).then(|| {
        with_problem(targets, obs, used, 1, r.time, w, |pb| {
            refine(pb, &r.b, s.lm_iter, s.cluster_ns, s.clock())
        })
    });
    if let Some(l) = &lm {
        r.b = l.b;
        r.time.dt = l.dt;
        r.time.drift = l.drift;
    }
    if let (false, Some(l)) = (s.estimate_dt, &lm) {
        // Where the data move the offset, and its sigma at the held solution (no iteration:
        // the motion model is first order in the offset, exact at the held value and not far
        // from it). The free fit need not converge: far from the truth it stalls on the way (a
        // 0.3 s error stops after 0.14 s, its own sigma inflated by the misfit), which is
        // evidence enough against the held value.
        let free_clock = Clock {
            dt: true,
            drift: s.estimate_drift,
        };
        let (free, at_held) = with_problem(targets, obs, used, 1, r.time, w, |pb| {
            (
                refine(pb, &l.b, s.lm_iter, s.cluster_ns, free_clock),
                refine(pb, &l.b, 0, s.cluster_ns, free_clock),
            )
        });
        let sigma = at_held.sigma_dt;
        if free.dt.is_finite() && sigma.is_finite() && sigma > 0.0 {
            sol.dt_free = Some((free.dt, sigma));
        }
    }
    sol.b = Params(r.b);
    sol.dt = r.time.dt;
    sol.drift = r.time.drift;
    sol.t_ref = r.time.t_ref;
    sol.lm = lm;
    sol.l1 = with_problem(targets, obs, used, 1, r.time, None, |pb| pb.l1(&r.b));
}

/// Per-sphere counts gathered on the way to the answer.
struct PerSphere<'a> {
    windowed: &'a [usize; MAX_TARGETS],
    used: &'a [usize; MAX_TARGETS],
    tallies: &'a [[u32; 8]; MAX_TARGETS],
    counts: &'a [(u32, u32); MAX_TARGETS],
}

/// Each sphere's report (residual RMS at the start and at the answer, its centre fitted with
/// the answer) and the RMS of the centre offsets.
fn sphere_reports(
    targets: &[Target],
    obs: &[&mut [Observation]],
    per: &PerSphere<'_>,
    b0: &Params,
    time: &TimeOffset,
    sol: &mut Solution,
) {
    let mount = sol.b.mount();
    let (mut c2, mut nc) = (0.0, 0);
    for (j, t) in targets.iter().enumerate() {
        let kept = &obs[j][..per.used[j]];
        let rms = |bb: &[f64; P]| {
            let s2: f64 = kept
                .iter()
                .map(|o| libm::pow(residual(o, t, bb, time), 2.0))
                .sum();
            libm::sqrt(s2 / kept.len().max(1) as f64)
        };
        let center = fit_center(
            kept.iter().map(|o| o.georef_dt(&mount, time.at(o))),
            t.radius,
            t.center,
        )
        .map(|c| c - t.center);
        if let Some(d) = center {
            c2 += d.norm_squared();
            nc += 1;
        }
        let _ = sol.spheres.push(SphereReport {
            windowed: per.windowed[j],
            used: per.used[j],
            found: per.used[j] > 0,
            slices: per.counts[j].0,
            detected: per.counts[j].1,
            verdicts: per.tallies[j],
            rms_before: rms(&b0.0),
            rms_after: rms(&sol.b.0),
            center_offset: center,
            agreed: 0,
            lost: None,
        });
    }
    sol.center_rms = (nc > 0).then(|| libm::sqrt(c2 / nc as f64));
}

/// The quality checks on a least-squares answer: the weak parameters, then the first reason
/// to refuse it — a held time offset the data contradict, not converged, ill-conditioned,
/// residuals over-dispersed against the noise model, a pass inconsistent with the others.
fn checks(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    s: &Settings,
    sol: &mut Solution,
) -> Option<Refusal> {
    let lm = sol.lm?;
    // Every unit vector has components above 0.3: the direction only matters when it is weak.
    let weak_geometry = lm.condition.is_nan() || lm.condition > s.weak_condition;
    for (w, &v) in sol.weak.iter_mut().zip(&lm.weakest) {
        *w = weak_geometry && v.abs() > 0.3;
    }
    let (b, time, dt) = (sol.b.0, sol.time(), sol.dt);
    let predicted = predicted_rms(obs, used, s);
    sol.predicted_rms = predicted;
    let worst = consistency(targets, obs, used, &b, &time, s, &mut sol.passes);
    let clock = pass_clocks(targets, obs, used, &b, &time, s, &mut sol.passes);
    let contradicted = sol.dt_free.filter(|&(f, sg)| {
        let d = (f - dt).abs();
        d > s.held_dt_floor && d > s.held_dt_sigmas * sg
    });
    // A held offset the data contradict comes first: it is the cause, and the mounting fitted
    // around it may fail to converge or fit badly only because of it.
    if let Some((found, sigma)) = contradicted {
        Some(Refusal::TimeOffsetContradicted {
            held: dt,
            found,
            sigma,
        })
    } else if !lm.converged {
        Some(Refusal::NotConverged {
            iterations: lm.iterations,
        })
    } else if lm.condition.is_nan() || lm.condition > s.max_condition {
        Some(Refusal::IllConditioned {
            condition: lm.condition,
            limit: s.max_condition,
        })
    } else if clock.is_some() {
        // A clock that steps or drifts also spreads the residuals and moves passes' centres:
        // the cause first.
        clock
    } else if lm.rms.is_nan() || lm.rms > s.max_dispersion * predicted {
        Some(Refusal::OverDispersed {
            rms: lm.rms,
            predicted,
        })
    } else {
        worst
    }
}

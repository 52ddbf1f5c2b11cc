//! The whole solve: Nelder-Mead on eq. 6 from the a-priori values (the authors' method), then
//! re-windowing and Levenberg-Marquardt until the windows stop changing, then the checks.
//!
//! Windows from the a-priori values also catch returns that are not on the spheres (the tripod,
//! the dock). After each solve every windowed return is kept only if its distance to the
//! sphere's surface is within `shell_sigmas` robust sigmas (sigma = 1.4826 x the median
//! |residual| of the kept returns, from a fixed log-spaced histogram: no heap, no sort), never
//! below `shell_floor`; Nelder-Mead runs again on the new windows, until they stop changing.
//!
//! Refusals (the solution is still reported): fewer than two spheres (a single sphere cannot fix
//! a rotation about the line to it); fewer than `min_points` returns on a sphere; a condition
//! number of the unit-diagonal normal matrix above `max_condition` = 1e3 (the weakest
//! combination of parameters is then determined 30 times worse than the best, and some pair
//! correlates beyond 0.998: table1's four passes give 7, a single pass 1.3e4 with roll, heading
//! and z inseparable); an RMS above `max_rms`.

use super::lm::{refine, LmResult};
use super::nelder_mead::{minimize, NmResult, NmSettings};
use super::objective::{Problem, SphereObs};
use super::sphere_fit::fit_center;
use super::{from_deg_m, to_deg_m, P};
use crate::window::{Observation, Target, MAX_TARGETS};
use nalgebra::Vector3;

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
    /// Largest acceptable residual RMS [m].
    pub max_rms: f64,
    /// Re-window shell: this many robust sigmas ...
    pub shell_sigmas: f64,
    /// ... but at least this [m].
    pub shell_floor: f64,
    /// Re-windowing rounds at most.
    pub max_rounds: usize,
    /// Returns of one sphere this close in time share INS errors: one cluster for the
    /// covariance [ns].
    pub cluster_ns: i64,
    /// Returns per sphere Nelder-Mead evaluates (evenly spread; LM uses all).
    pub nm_points: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            nm: NmSettings::default(),
            step: [1.0, 1.0, 1.0, 0.1, 0.1, 0.1],
            lm_iter: 100,
            min_points: 30,
            max_condition: 1e3,
            max_rms: 0.1,
            shell_sigmas: 3.5,
            shell_floor: 0.005,
            max_rounds: 10,
            cluster_ns: 20_000_000,
            nm_points: 100,
        }
    }
}

/// Why a solution is not claimed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Refusal {
    /// Fewer than two spheres.
    TooFewSpheres {
        /// Spheres given.
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
    /// The residuals are far above the range noise.
    RmsTooHigh {
        /// RMS [m].
        rms: f64,
        /// Limit [m].
        limit: f64,
    },
}

/// Per sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereReport {
    /// Returns in the a-priori window.
    pub windowed: usize,
    /// Returns kept after re-windowing.
    pub used: usize,
    /// RMS of the kept returns' residuals with the starting values [m].
    pub rms_before: f64,
    /// ... with the solution [m].
    pub rms_after: f64,
    /// Fitted minus surveyed centre [m, NED].
    pub center_offset: Option<Vector3<f64>>,
}

/// The answer and everything known about it.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// [roll, pitch, heading (rad), x, y, z (m)].
    pub b: [f64; P],
    /// The Nelder-Mead stage.
    pub nm: NmResult<P>,
    /// The LM stage (covariance, correlation, conditioning).
    pub lm: Option<LmResult>,
    /// Eq. 6 at the solution over the kept returns [m].
    pub l1: f64,
    /// Re-windowing rounds.
    pub rounds: usize,
    /// Per sphere.
    pub spheres: heapless::Vec<SphereReport, MAX_TARGETS>,
    /// RMS of fitted minus surveyed centres [m].
    pub center_rms: Option<f64>,
    /// Parameters the data determine poorly (large share of the weakest direction).
    pub weak: [bool; P],
    /// Why the solution is not claimed, if it is not.
    pub refusal: Option<Refusal>,
}

fn with_problem<R>(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    f: impl FnOnce(&Problem<'_>) -> R,
) -> R {
    with_problem_stride(targets, obs, used, 1, f)
}

fn with_problem_stride<R>(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    stride: usize,
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

/// The first sphere with fewer than `min` returns, as a refusal.
fn too_few(used: &[usize], min: usize) -> Option<Refusal> {
    let (sphere, &have) = used.iter().enumerate().find(|(_, &u)| u < min)?;
    Some(Refusal::TooFewPoints {
        sphere,
        have,
        need: min,
    })
}

/// Signed residual of one observation.
fn residual(o: &Observation, t: &Target, b: &[f64; P]) -> f64 {
    let m = crate::georef::Mount::from_params(b);
    (o.georef(&m) - t.center).norm() - t.radius
}

/// Keep the returns within the shell at the front of each sphere's slice; returns the counts
/// and a fingerprint of the kept set.
fn rewindow(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    used: &mut [usize],
    b: &[f64; P],
    shell: f64,
) -> u64 {
    let mount = crate::georef::Mount::from_params(b);
    let mut print = 0u64;
    for (j, t) in targets.iter().enumerate() {
        let v = &mut obs[j];
        let mut k = 0;
        for i in 0..v.len() {
            if ((v[i].georef(&mount) - t.center).norm() - t.radius).abs() <= shell {
                v.swap(i, k);
                print = print
                    .wrapping_mul(0x100_0000_01B3)
                    .wrapping_add(v[k].time.0 as u64);
                k += 1;
            }
        }
        used[j] = k;
    }
    print
}

/// Solve from `b0` ([rad, m]) with every sphere's windowed returns (reordered in place: the
/// kept ones first).
pub fn solve(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    b0: &[f64; P],
    s: &Settings,
) -> Solution {
    let n = targets.len().min(obs.len()).min(MAX_TARGETS);
    let targets = &targets[..n];
    let obs = &mut obs[..n];
    let mut used = [0usize; MAX_TARGETS];
    for j in 0..n {
        used[j] = obs[j].len();
    }
    let windowed = used;
    let mut sol = Solution {
        b: *b0,
        nm: NmResult {
            x: to_deg_m(b0),
            f: f64::INFINITY,
            iterations: 0,
            evaluations: 0,
            converged: false,
        },
        lm: None,
        l1: f64::INFINITY,
        rounds: 0,
        spheres: heapless::Vec::new(),
        center_rms: None,
        weak: [false; P],
        refusal: None,
    };
    if n < 2 {
        sol.refusal = Some(Refusal::TooFewSpheres { have: n });
        return sol;
    }
    if let Some(r) = too_few(&used[..n], s.min_points) {
        sol.refusal = Some(r);
        return sol;
    }

    // 1. Nelder-Mead on eq. 6 (L1), in degrees and metres, re-windowing after each solve until
    //    the windows stop changing.
    let mut b = *b0;
    let mut last_print = None;
    let mut evaluations = 0;
    let mut iterations = 0;
    for round in 0..s.max_rounds {
        sol.rounds = round + 1;
        // Nelder-Mead sees at most `nm_points` returns per sphere (evenly spread); the least
        // squares at the end uses all.
        let most = used[..n].iter().copied().max().unwrap_or(1);
        let stride = most.div_ceil(s.nm_points.max(1)).max(1);
        let mut nm = with_problem_stride(targets, obs, &used, stride, |pb| {
            minimize::<P, 7>(|x| pb.l1(&from_deg_m(x)), &to_deg_m(&b), &s.step, &s.nm)
        });
        evaluations += nm.evaluations;
        iterations += nm.iterations;
        nm.evaluations = evaluations;
        nm.iterations = iterations;
        sol.nm = nm;
        b = from_deg_m(&nm.x);
        let med = with_problem(targets, obs, &used, |pb| {
            let mut h = Histogram::new();
            pb.residuals(&b, |_, r| h.add(r.abs()));
            h.median()
        });
        let shell = (s.shell_sigmas * 1.4826 * med).max(s.shell_floor);
        let print = rewindow(targets, obs, &mut used[..n], &b, shell);
        if (0..n).any(|j| used[j] < s.min_points) || last_print == Some(print) {
            break;
        }
        last_print = Some(print);
    }

    // 2. Least squares on the final windows: the answer and its uncertainty.
    // Time order within each sphere, for the clusters of the covariance.
    for j in 0..n {
        obs[j][..used[j]].sort_unstable_by_key(|o| o.time);
    }
    let lm = (!(0..n).any(|j| used[j] < s.min_points)).then(|| {
        with_problem(targets, obs, &used, |pb| {
            refine(pb, &b, s.lm_iter, s.cluster_ns)
        })
    });
    if let Some(r) = &lm {
        b = r.b;
    }
    sol.b = b;
    sol.lm = lm;
    sol.l1 = with_problem(targets, obs, &used, |pb| pb.l1(&b));

    // 3. Per sphere: RMS before/after over the kept returns, centre fit.
    let mount = crate::georef::Mount::from_params(&b);
    let mut c2 = 0.0;
    let mut nc = 0;
    for j in 0..n {
        let t = &targets[j];
        let kept = &obs[j][..used[j]];
        let rms = |bb: &[f64; P]| {
            let s2: f64 = kept
                .iter()
                .map(|o| libm::pow(residual(o, t, bb), 2.0))
                .sum();
            libm::sqrt(s2 / kept.len().max(1) as f64)
        };
        let center = fit_center(kept.iter().map(|o| o.georef(&mount)), t.radius, t.center)
            .map(|c| c - t.center);
        if let Some(d) = center {
            c2 += d.norm_squared();
            nc += 1;
        }
        let _ = sol.spheres.push(SphereReport {
            windowed: windowed[j],
            used: used[j],
            rms_before: rms(b0),
            rms_after: rms(&b),
            center_offset: center,
        });
    }
    sol.center_rms = (nc > 0).then(|| libm::sqrt(c2 / nc as f64));

    // 4. Checks.
    if let Some(r) = too_few(&used[..n], s.min_points) {
        sol.refusal = Some(r);
        return sol;
    }
    let Some(lm) = sol.lm else {
        sol.refusal = Some(Refusal::TooFewPoints {
            sphere: 0,
            have: used[0],
            need: s.min_points,
        });
        return sol;
    };
    for i in 0..P {
        sol.weak[i] = lm.weakest[i].abs() > 0.3;
    }
    if lm.condition.is_nan() || lm.condition > s.max_condition {
        sol.refusal = Some(Refusal::IllConditioned {
            condition: lm.condition,
            limit: s.max_condition,
        });
    } else if lm.rms.is_nan() || lm.rms > s.max_rms {
        sol.refusal = Some(Refusal::RmsTooHigh {
            rms: lm.rms,
            limit: s.max_rms,
        });
    }
    sol
}

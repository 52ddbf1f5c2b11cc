//! Levenberg-Marquardt on the signed distances `||x_k(b) - c_j|| - r_j` with the analytic
//! Jacobian (Marquardt 1963, with the diagonal scaling of the damping), and what the normal
//! matrix says about the answer: covariance `sigma^2 (J^T J)^-1` with
//! `sigma^2 = sum r^2 / (n - 6)`, correlations, and the condition number of the normal matrix
//! scaled to unit diagonal (units cancel, so degrees and metres compare).
//!
//! The returns of one pass over a sphere share the INS error of the same few samples, so the
//! residuals are not independent and `sigma^2 (J^T J)^-1` is too optimistic (by about 2x on
//! table1-noisy). The reported uncertainty is therefore the cluster-robust ("sandwich")
//! covariance `(J^T J)^-1 (sum_g s_g s_g^T) (J^T J)^-1`, `s_g = sum_{k in g} J_k r_k`, over
//! clusters of returns of one sphere within `cluster_ns` of each other (Liang & Zeger 1986,
//! with the usual G/(G-1) (n-1)/(n-p) correction), and never less than the classic one.
//!
//! Two nuisance parameters are estimated with the six: `||x - c|| - r - dr - k g`. `dr` is a
//! radius offset common to all spheres (a LiDAR range bias, a sphere's paint, and the isotropic
//! part of what noise across the surface adds); `k g` is the inflation range noise causes where
//! a beam grazes the sphere: a range error e along a beam at angle (u.n) to the normal moves the
//! return by e (u.n) radially but adds e^2 (1 - (u.n)^2) / 2r to its distance from the centre, so
//! with `g = 1 - (u.n)^2` and `k = sigma_r^2 / 2r` (errors in variables). With a fixed radius
//! either would leak into the lever arm (measured: -1.8 sigma mean bias in y on table1-noisy).
//! The reported covariance of the six is the marginal one.
//!
//! The time offset between the clocks (`dt`, INS minus LiDAR, beyond what the pipeline applied
//! to the poses) is estimated with the six when asked: a time offset moves each return by
//! `dt (v + omega x R (a + R_li q))` (the platform's motion, to first order), so it shows along
//! the track, with opposite signs on passes in opposite directions, scaled by the speed and the
//! turn rate.

use super::objective::{Problem, P7};
use crate::georef::P;
use nalgebra::{Cholesky, SMatrix, SVector, SymmetricEigen};

/// 6x6.
pub type Mat6 = SMatrix<f64, P, P>;
/// 6-vector.
pub type Vec6 = SVector<f64, P>;
/// The six, the time offset, the two nuisance parameters (radius offset, grazing inflation)
/// and the time offset's drift.
pub const Q: usize = P + 4;
/// Q x Q.
pub type MatQ = SMatrix<f64, Q, Q>;
pub(crate) type VecQ = SVector<f64, Q>;
/// Index of the time offset in the parameter vector.
const DT: usize = P;
/// Index of the time offset's drift.
pub(crate) const DRIFT: usize = P + 3;

/// Which clock parameters are estimated with the six.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Clock {
    /// The time offset.
    pub dt: bool,
    /// Its drift (needs `dt`).
    pub drift: bool,
}

/// What LM found and how well the data determine it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmResult {
    /// Parameters [rad, m].
    pub b: [f64; P],
    /// The time offset on top of the observations' poses [s] (the problem's own when not
    /// estimated).
    pub dt: f64,
    /// The time offset was estimated.
    pub estimated_dt: bool,
    /// The time offset's drift [s/s] (the problem's own when not estimated).
    pub drift: f64,
    /// Its 1-sigma (0 when not estimated).
    pub sigma_drift: f64,
    /// The drift was estimated.
    pub estimated_drift: bool,
    /// Common radius offset [m] (what the spheres' apparent radius differs by).
    pub radius_offset: f64,
    /// Iterations taken.
    pub iterations: usize,
    /// Steps became negligible before the cap.
    pub converged: bool,
    /// Observations.
    pub n: usize,
    /// RMS of the residuals (unweighted) [m].
    pub rms: f64,
    /// `J^T J` of the six at the solution.
    pub normal: Mat6,
    /// Covariance of b.
    pub covariance: Mat6,
    /// 1-sigma of each parameter [rad, m]: the larger of the cluster-robust and the classic.
    pub sigma: [f64; P],
    /// 1-sigma of the time offset [s] (0 when not estimated).
    pub sigma_dt: f64,
    /// The classic 1-sigma, `sqrt(diag(sigma^2 (J^T J)^-1))`.
    pub sigma_classic: [f64; P],
    /// Clusters of correlated returns used for the robust covariance.
    pub clusters: usize,
    /// Correlation matrix of the six.
    pub correlation: Mat6,
    /// Correlation of the time offset with each of the six.
    pub dt_correlation: [f64; P],
    /// Condition number of the unit-diagonal normal matrix (of the six and the time offset
    /// when it is estimated).
    pub condition: f64,
    /// Eigenvector of the smallest eigenvalue of the scaled normal matrix (which combination
    /// of parameters the data pin down least): the six, then the time offset.
    pub weakest: [f64; P7],
}

/// The full row of one residual: the six, the time offset (when estimated), the nuisance
/// terms and the drift (the time offset's times `since`, the seconds from the reference time,
/// when estimated).
pub(crate) fn row_q(row: &[f64; P7], g: f64, clock: Clock, since: f64) -> VecQ {
    VecQ::from_column_slice(&[
        row[0],
        row[1],
        row[2],
        row[3],
        row[4],
        row[5],
        if clock.dt { row[6] } else { 0.0 },
        -1.0,
        -g,
        if clock.drift { row[6] * since } else { 0.0 },
    ])
}

/// The problem at parameters `z` (the six, the time offset, the two nuisance terms).
struct At<'a, 'p> {
    pb: &'a Problem<'p>,
    z: [f64; Q],
    clock: Clock,
}

impl At<'_, '_> {
    fn b(&self) -> [f64; P] {
        core::array::from_fn(|i| self.z[i])
    }

    fn problem(&self) -> Problem<'_> {
        Problem {
            dt: self.z[DT],
            drift: self.z[DRIFT],
            ..*self.pb
        }
    }

    /// `J^T W J`, `J^T W r`, the weighted cost, the count and the unweighted sum of squares
    /// (W: the problem's weights, or the identity).
    fn normal_equations(&self) -> (MatQ, VecQ, f64, usize, f64) {
        let mut jtj = MatQ::zeros();
        let mut jtr = VecQ::zeros();
        let (mut cost, mut raw) = (0.0, 0.0);
        let mut n = 0;
        let (nu0, nu1) = (self.z[P + 1], self.z[P + 2]);
        let pb = self.problem();
        pb.jacobian_with(&self.b(), |_, o, r, row, g| {
            let j = row_q(row, g, self.clock, pb.since_ref(o));
            let r = r - nu0 - nu1 * g;
            let w = pb.weight(o);
            jtj += j * j.transpose() * w;
            jtr += j * (r * w);
            cost += w * r * r;
            raw += r * r;
            n += 1;
        });
        if !self.clock.dt {
            // The time offset is held: its equation is dt = dt.
            jtj[(DT, DT)] = 1.0;
        }
        if !self.clock.drift {
            jtj[(DRIFT, DRIFT)] = 1.0;
        }
        (jtj, jtr, cost, n, raw)
    }

    /// The cluster-robust middle term `sum_g s_g s_g^T` and the number of clusters.
    /// Observations of each sphere must be in time order.
    fn meat(&self, cluster_ns: i64) -> (MatQ, usize) {
        let mut m = MatQ::zeros();
        let mut g = VecQ::zeros();
        let mut key: Option<(usize, i64)> = None;
        let mut clusters = 0;
        let (nu0, nu1) = (self.z[P + 1], self.z[P + 2]);
        let pb = self.problem();
        pb.jacobian_with(&self.b(), |j, o, r, row, gz| {
            let k = (j, o.time.0.div_euclid(cluster_ns.max(1)));
            if key != Some(k) {
                if key.is_some() {
                    m += g * g.transpose();
                }
                g = VecQ::zeros();
                key = Some(k);
                clusters += 1;
            }
            g +=
                row_q(row, gz, self.clock, pb.since_ref(o)) * ((r - nu0 - nu1 * gz) * pb.weight(o));
        });
        if key.is_some() {
            m += g * g.transpose();
        }
        (m, clusters)
    }
}

/// Where the iterations ended: `J^T J`, the cost and the number of returns.
struct Normal {
    jtj: MatQ,
    cost: f64,
    n: usize,
    /// The unweighted sum of squares.
    raw: f64,
}

/// The largest squared Gauss-Newton step, in sigmas, left at a point no step improves for it
/// to count as the minimum.
const STALL_SIGMA2: f64 = 0.04;

/// Levenberg-Marquardt steps from `at` (Marquardt's diagonal scaling, lambda x10 / /10), at
/// most `max_iter`: the last accepted point, its normal equations, the iterations and whether
/// it converged (a negligible step or decrease, or no step lowers the cost and a Gauss-Newton
/// step would not either).
fn iterate<'p, 'o>(mut at: At<'p, 'o>, max_iter: usize) -> (At<'p, 'o>, Normal, usize, bool) {
    let (mut jtj, mut jtr, mut cost, mut n, mut raw) = at.normal_equations();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut converged = false;
    while iterations < max_iter {
        iterations += 1;
        let mut a = jtj;
        for i in 0..Q {
            a[(i, i)] += lambda * jtj[(i, i)].max(1e-12);
        }
        let Some(ch) = Cholesky::new(a) else {
            lambda *= 10.0;
            continue;
        };
        let delta = ch.solve(&(-jtr));
        let trial = At {
            z: core::array::from_fn(|i| at.z[i] + delta[i]),
            ..at
        };
        let (tj, tr, tc, tn, traw) = trial.normal_equations();
        if tc <= cost {
            at = trial;
            let small =
                delta.iter().all(|d| d.abs() < 1e-11) || (cost - tc) <= 1e-15 * cost.max(1e-30);
            (jtj, jtr, cost, n, raw) = (tj, tr, tc, tn, traw);
            lambda = (lambda / 10.0).max(1e-12);
            if small {
                converged = true;
                break;
            }
        } else {
            lambda *= 10.0;
            // The step did not lower the cost: at a minimum if the Gauss-Newton step left is
            // within a fifth of a sigma (its squared length in the metric of the covariance,
            // `g^T (J^T J)^-1 g / s^2`, under 0.04: the spread grows by under 2 % in
            // quadrature; the grazing term's factor is held fixed in the Jacobian, so at the
            // minimum its gradient is not quite zero). Said at once: damping it further
            // (to 1e12, as it was) moved the state by nothing and took 15 of a round's 20
            // evaluations. Else a stall once no damping helps. (Under 1e-6 of the cost, as it
            // was, refused 2 % of noisy table1 surveys stalled at 0.07 sigma.)
            converged = within_a_fifth(&jtj, &jtr, cost, n);
            if converged || lambda > 1e12 {
                break;
            }
        }
    }
    if !converged && iterations >= max_iter {
        // Still lowering the cost at the cap: a minimum by the same rule.
        converged = within_a_fifth(&jtj, &jtr, cost, n);
    }
    (at, Normal { jtj, cost, n, raw }, iterations, converged)
}

/// Whether the Gauss-Newton step left is within a fifth of a sigma (see [`iterate`]).
fn within_a_fifth(jtj: &MatQ, jtr: &VecQ, cost: f64, n: usize) -> bool {
    let predicted = Cholesky::new(*jtj).map_or(f64::INFINITY, |c| jtr.dot(&c.solve(jtr)));
    let s2 = cost / n.saturating_sub(Q).max(1) as f64;
    predicted <= STALL_SIGMA2 * s2.max(1e-300)
}

/// The condition number of the normal matrix of the six (and the time offset when estimated)
/// scaled to unit diagonal, and the eigenvector of its smallest eigenvalue (the weakest
/// direction).
pub(crate) fn conditioning(jtj: &MatQ, estimate_dt: bool) -> (f64, [f64; P7]) {
    // Scale the normal matrix of the six (and the time offset when estimated) to unit
    // diagonal; its eigenvalues give the conditioning.
    let k = if estimate_dt { P7 } else { P };
    let mut scaled = SMatrix::<f64, P7, P7>::identity();
    for i in 0..k {
        for j in 0..k {
            scaled[(i, j)] = jtj[(i, j)] / libm::sqrt(jtj[(i, i)] * jtj[(j, j)]).max(1e-300);
        }
    }
    // Bounded iterations: a non-finite matrix gives no decomposition (and an infinite
    // condition number: refused). A held time offset is an identity row: it neither weakens
    // nor conditions anything (its eigenvalue 1 is left out).
    match SymmetricEigen::try_new(scaled, f64::EPSILON, 200) {
        Some(eig) if eig.eigenvalues.iter().all(|e| e.is_finite()) => {
            let (mut lo, mut hi, mut lo_i) = (f64::INFINITY, 0f64, 0);
            for (i, &e) in eig.eigenvalues.iter().enumerate() {
                if !estimate_dt && eig.eigenvectors[(DT, i)].abs() > 0.999 {
                    continue;
                }
                if e < lo {
                    lo = e;
                    lo_i = i;
                }
                hi = hi.max(e);
            }
            let mut weakest = [0.0; P7];
            for (i, w) in weakest.iter_mut().enumerate() {
                *w = eig.eigenvectors[(i, lo_i)];
            }
            (if lo > 0.0 { hi / lo } else { f64::INFINITY }, weakest)
        }
        _ => (f64::INFINITY, [0.0; P7]),
    }
}

/// Refine `b0` by Levenberg-Marquardt, at most `max_iter` iterations; returns within
/// `cluster_ns` of each other on one sphere count as one cluster for the covariance. `clock`:
/// the time offset (and its drift) estimated with the six, from the problem's `dt` (and
/// `drift`).
pub fn refine(
    pb: &Problem<'_>,
    b0: &[f64; P],
    max_iter: usize,
    cluster_ns: i64,
    clock: Clock,
) -> LmResult {
    let clock = Clock {
        dt: clock.dt,
        drift: clock.dt && clock.drift,
    };
    let estimate_dt = clock.dt;
    let mut z = [0.0; Q];
    z[..P].copy_from_slice(b0);
    z[DT] = pb.dt;
    z[DRIFT] = pb.drift;
    let at = At { pb, z, clock };
    let (at, Normal { jtj, cost, n, raw }, iterations, converged) = iterate(at, max_iter);
    let b = at.b();
    let converged = converged && cost.is_finite() && at.z.iter().all(|x| x.is_finite());
    // Degrees of freedom: a held time offset or drift is no parameter.
    let params = Q - usize::from(!clock.dt) - usize::from(!clock.drift);
    let dof = n.saturating_sub(params).max(1) as f64;
    let s2 = cost / dof;
    let inv = jtj.try_inverse();
    let (mid, clusters) = at.meat(cluster_ns);
    let g = clusters as f64;
    let corr = if clusters > 1 {
        g / (g - 1.0) * (n as f64 - 1.0) / dof
    } else {
        1.0
    };
    // The marginal covariances of the six and the time offset: the top-left 7x7 block.
    let block = |m: MatQ| -> SMatrix<f64, P7, P7> { m.fixed_view::<P7, P7>(0, 0).into_owned() };
    let classic = inv
        .map(|m| block(m * s2))
        .unwrap_or_else(|| SMatrix::from_element(f64::INFINITY));
    let robust = inv.map(|m| block(m * mid * m * corr)).unwrap_or(classic);
    let mut sig7 = [0.0; P7];
    let mut sigma_classic = [0.0; P];
    for i in 0..P7 {
        let c = libm::sqrt(classic[(i, i)].max(0.0));
        sig7[i] = libm::sqrt(robust[(i, i)].max(0.0)).max(c);
        if i < P {
            sigma_classic[i] = c;
        }
    }
    if !estimate_dt {
        sig7[DT] = 0.0;
    }
    // The reported covariance: the robust one, scaled up where the classic is larger.
    let mut cov7 = robust;
    for i in 0..P7 {
        for j in 0..P7 {
            let (ri, rj) = (
                libm::sqrt(robust[(i, i)].max(1e-300)),
                libm::sqrt(robust[(j, j)].max(1e-300)),
            );
            cov7[(i, j)] = robust[(i, j)] / (ri * rj) * sig7[i] * sig7[j];
        }
    }
    let covariance: Mat6 = cov7.fixed_view::<P, P>(0, 0).into_owned();
    let mut correlation = Mat6::zeros();
    let mut dt_correlation = [0.0; P];
    for i in 0..P {
        for j in 0..P {
            correlation[(i, j)] = covariance[(i, j)] / (sig7[i] * sig7[j]);
        }
        if estimate_dt {
            dt_correlation[i] = cov7[(i, DT)] / (sig7[i] * sig7[DT]);
        }
    }
    let (condition, weakest) = conditioning(&jtj, estimate_dt);
    let sigma_drift = if clock.drift {
        inv.map_or(f64::INFINITY, |m| {
            let robust = (m * mid * m * corr)[(DRIFT, DRIFT)];
            let classic = m[(DRIFT, DRIFT)] * s2;
            libm::sqrt(robust.max(classic).max(0.0))
        })
    } else {
        0.0
    };
    LmResult {
        b,
        dt: at.z[DT],
        estimated_dt: estimate_dt,
        drift: at.z[DRIFT],
        sigma_drift,
        estimated_drift: clock.drift,
        radius_offset: at.z[P + 1],
        iterations,
        converged,
        n,
        rms: libm::sqrt(raw / n.max(1) as f64),
        normal: jtj.fixed_view::<P, P>(0, 0).into_owned(),
        covariance,
        sigma: core::array::from_fn(|i| sig7[i]),
        sigma_dt: sig7[DT],
        sigma_classic,
        clusters,
        correlation,
        dt_correlation,
        condition,
        weakest,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::window::{Observation, Target};
    use crate::calib::noise::Noise;
    use crate::calib::objective::SphereObs;
    use crate::frames::rotation;
    use crate::time::GpsTime;
    use nalgebra::Vector3;

    /// Returns on two spheres, made exactly by a known mounting from random poses.
    fn exact(b: &[f64; P], t: &[Target; 2]) -> std::vec::Vec<std::vec::Vec<Observation>> {
        let mut rng = crate::sim::Rng::new(4);
        let m = crate::georef::Mount::from_params(&crate::georef::Params(*b));
        let mut out = std::vec![std::vec::Vec::new(), std::vec::Vec::new()];
        for (j, tg) in t.iter().enumerate() {
            for k in 0..400 {
                let r_ig = rotation(
                    rng.range(-0.05, 0.05),
                    rng.range(-0.05, 0.05),
                    rng.range(-3.0, 3.0),
                );
                let position = Vector3::new(rng.range(-30.0, 30.0), rng.range(5.0, 30.0), 0.0);
                // A point on the sphere facing the sensor, back to the LiDAR frame.
                let sensor = position + r_ig * m.lever;
                let to = (tg.center - sensor).normalize();
                let n = (-to
                    + Vector3::new(
                        rng.range(-0.5, 0.5),
                        rng.range(-0.5, 0.5),
                        rng.range(-0.5, 0.5),
                    ))
                .normalize();
                let x = tg.center + n * tg.radius;
                let q = m.r_li.transpose() * (r_ig.transpose() * (x - position) - m.lever);
                out[j].push(Observation {
                    q_l: q.cast(),
                    position,
                    r_ig: r_ig.cast(),
                    time: GpsTime(k * 1_000_000),
                    range: q.norm() as f32,
                    ..Observation::default()
                });
            }
        }
        out
    }

    /// Two spheres 20 m apart and a mounting (rad, m).
    const TARGETS: [Target; 2] = [
        Target {
            center: Vector3::new(0.0, 0.0, -1.6),
            radius: 0.19,
        },
        Target {
            center: Vector3::new(20.0, 0.0, -1.5),
            radius: 0.19,
        },
    ];
    const TRUTH: [f64; P] = [3.13, -0.78, 0.02, 1.5, -1.24, -1.36];

    /// Refine from `start` on the two spheres' returns `o`, with `weights`.
    fn solve(
        o: &[std::vec::Vec<Observation>],
        start: &[f64; P],
        weights: Option<Noise>,
    ) -> LmResult {
        let s = [
            SphereObs {
                target: TARGETS[0],
                obs: &o[0],
            },
            SphereObs {
                target: TARGETS[1],
                obs: &o[1],
            },
        ];
        let pb = Problem {
            spheres: &s,
            stride: 1,
            dt: 0.0,
            drift: 0.0,
            t_ref: GpsTime(0),
            weights,
            footprint: None,
        };
        refine(&pb, start, 100, 20_000_000, Clock::default())
    }

    #[test]
    fn converges_on_exact_data_and_not_on_nan() {
        let (t, truth) = (TARGETS, TRUTH);
        let mut obs = exact(&truth, &t);
        let start = [3.12, -0.77, 0.03, 1.45, -1.2, -1.3];
        let pb = |o: &[std::vec::Vec<Observation>]| solve(o, &start, None);
        let r = pb(&obs);
        assert!(r.converged, "{r:?}");
        for (i, (got, want)) in r.b.iter().zip(truth).enumerate() {
            assert!((got - want).abs() < 1e-5, "{i}: {got} vs {want}");
        }
        // One return with a NaN position: no finite cost, no convergence claimed.
        obs[0][7].position.x = f64::NAN;
        let r = pb(&obs);
        assert!(!r.converged);
        assert!(r.condition.is_infinite() || r.condition.is_nan() || !r.rms.is_finite());
    }
    /// A quarter of one sphere's returns carry a 10 cm position error and say so through their
    /// own INS sigma (1 m): weighted, the solution ignores them; unweighted, they pull it.
    #[test]
    fn weights_follow_the_returns_own_sigmas() {
        let (t, truth) = (TARGETS, TRUTH);
        let mut obs = exact(&truth, &t);
        for o in obs[0].iter_mut().take(100) {
            o.position.x += 0.1;
            o.ins_sigma = [1.0, 0.0];
        }
        let noise = Noise {
            range: 0.03,
            attitude: 0.0005,
            position: 0.02,
            spread: 0.0,
        };
        // Hand value of one variance: 3 cm, 0.5 mrad x 10 m, 1 m (its own), quantisation.
        let probe = Observation {
            range: 10.0,
            ins_sigma: [1.0, 0.0],
            ..Observation::default()
        };
        let want = 0.03f64.powi(2) + 0.005f64.powi(2) + 1.0 + 0.002f64.powi(2) / 12.0;
        assert!((noise.variance(&probe) - want).abs() < 1e-12);
        let err = |weights: Option<Noise>| {
            let r = solve(&obs, &truth, weights);
            assert!(r.converged, "{r:?}");
            // The worst error as a displacement at 20 m: angles x 20 m, lever arm as is.
            (0..P)
                .map(|i| (r.b[i] - truth[i]).abs() * if i < 3 { 20.0 } else { 1.0 })
                .fold(0.0, f64::max)
        };
        let (plain, weighted) = (err(None), err(Some(noise)));
        // Measured: 5.1 mm unweighted, 0.007 mm weighted.
        assert!(plain > 3e-3, "unweighted: {plain}");
        assert!(weighted < 0.02 * plain, "weighted {weighted} vs {plain}");
    }
}

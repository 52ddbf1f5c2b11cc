//! The calibration's accuracy before it is run (the survey planner, and the rig's verdict on
//! the data so far): the covariance of the least-squares estimate [`super::lm`] makes (the six,
//! the time offset and the two nuisance terms, unweighted as the solver is without an
//! accuracy file) from the geometry of the returns and a noise model alone, no data noise:
//!
//! `cov = A^-1 M A^-1`, `A = sum_k j_k j_k^T`, `M = E[(sum_k j_k e_k)(sum_k j_k e_k)^T]`
//!
//! (the sandwich of a linear estimator; Bjorck 1996, "Numerical methods for least squares
//! problems", 1.1.3), with `j_k` the residual's gradient ([`Problem::jacobian_with`]) and `e_k`
//! its error:
//! - range noise along the beam, `sigma^2 = sigma_0^2 + (R sigma_b tan(theta))^2` (the
//!   footprint's spread at incidence theta, tan capped at 10, as the simulator draws it), and
//!   the range quantisation (`unit^2 / 12`), both times `cos(theta)^2` (only the radial part
//!   moves the residual); independent per return;
//! - the INS position and attitude errors, white per INS sample, which the pose interpolation
//!   shares between every return from one sample to the next: return k at fraction f between
//!   samples i and i+1 takes `(1 - f) eta_i + f eta_{i+1}`, so `M` gets `S_i Sigma S_i^T` with
//!   `S_i = sum_k w_ki j_k g_k^T` (g: the residual's derivative by the INS position and by
//!   roll, pitch, heading).
//!
//! Information adds: an [`Info`] per pass and sphere, summed, gives any combination of them
//! (what a pass contributes, what a new one would add) without tracing again.

use super::lm::{conditioning, row_q, Clock, MatQ, DRIFT, Q};
use super::objective::{Linearised, P7};
use crate::align::window::{Observation, Target};
use crate::georef::P;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// The residual's sensitivity to one INS sample's errors: Q x 6 (position N, E, D; roll,
/// pitch, heading).
type SMat = SMatrix<f64, Q, 6>;

/// What the errors of the residuals are made of (1 sigma each).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModel {
    /// Range noise at normal incidence [m].
    pub range: f64,
    /// The beam's 1-sigma half-angle along the scan for the incidence term [rad] (the full
    /// divergence / 4; 0: range noise independent of incidence).
    pub beam_sigma: f64,
    /// The range quantisation step [m] (VLP-16: 2 mm; VLP-32C: 4 mm).
    pub range_unit: f64,
    /// INS position noise per axis and sample [m].
    pub position: f64,
    /// INS attitude noise per angle and sample [rad].
    pub attitude: f64,
    /// INS sample period [ns] (samples at whole multiples of it in GPS time).
    pub ins_period_ns: i64,
    /// The beam's footprint whose bloom the estimator takes out (its rows `n + k`,
    /// [`crate::calib::footprint`]); `None`: an ideal ray.
    pub footprint: Option<crate::calib::footprint::Footprint>,
}

impl NoiseModel {
    /// The range variance of a return at range `r` and `cos(incidence)` [m^2], quantisation
    /// included.
    pub fn range_variance(&self, r: f64, cos: f64) -> f64 {
        let tan = (libm::sqrt((1.0 - cos * cos).max(0.0)) / cos.max(1e-6)).min(10.0);
        let spread = r * self.beam_sigma * tan;
        self.range * self.range + spread * spread + self.range_unit * self.range_unit / 12.0
    }
}

/// The information returns bring: `A` and `M` (over the six, the time offset, the radius
/// offset and the grazing term), and how many returns. Sums of them are the information of
/// the union.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Info {
    /// `sum j j^T`.
    pub a: MatQ,
    /// The middle of the sandwich.
    pub m: MatQ,
    /// Returns.
    pub n: u32,
}

impl Default for Info {
    fn default() -> Self {
        Self {
            a: MatQ::zeros(),
            m: MatQ::zeros(),
            n: 0,
        }
    }
}

impl core::ops::AddAssign<&Info> for Info {
    fn add_assign(&mut self, o: &Info) {
        self.a += o.a;
        self.m += o.m;
        self.n += o.n;
    }
}

impl Info {
    /// The same information `k` times over (a pass driven `k` times; `k` < 1: returns lost).
    pub fn scaled(&self, k: f64) -> Self {
        Self {
            a: self.a * k,
            m: self.m * k,
            n: (f64::from(self.n) * k) as u32,
        }
    }

    /// The information of returns of several spheres, `(sphere, observation)` in time order
    /// across the spheres (returns of two spheres between the same INS samples share their
    /// errors), at mounting `b`: added to `self`.
    pub fn add_returns<'o>(
        &mut self,
        targets: &[Target],
        returns: impl IntoIterator<Item = (usize, &'o Observation)>,
        b: &[f64; P],
        noise: &NoiseModel,
    ) {
        let lin = Linearised::at(b).with_footprint(noise.footprint);
        let period = noise.ins_period_ns.max(1);
        let p2 = noise.position * noise.position;
        let a2 = noise.attitude * noise.attitude;
        let sig2: [f64; 6] = [p2, p2, p2, a2, a2, a2];
        let flush = |m: &mut MatQ, s: &SMat| {
            for (c, v) in sig2.iter().enumerate() {
                if *v > 0.0 {
                    let col = s.column(c);
                    *m += col * col.transpose() * *v;
                }
            }
        };
        // The open samples: i and i + 1.
        let mut open: Option<i64> = None;
        let (mut s0, mut s1) = (SMat::zeros(), SMat::zeros());
        for (j, o) in returns {
            let Some(target) = targets.get(j) else {
                continue;
            };
            let Some(r) = lin.row(o, target, 0.0) else {
                continue;
            };
            let (g, jv) = (
                r.grazing,
                row_q(
                    &r.row,
                    r.grazing,
                    Clock {
                        dt: true,
                        drift: false,
                    },
                    0.0,
                ),
            );
            self.a += jv * jv.transpose();
            self.n += 1;
            // Range noise, radial part.
            let cos2 = (1.0 - g).clamp(0.0, 1.0);
            let var = noise.range_variance(f64::from(o.range), libm::sqrt(cos2)) * cos2;
            self.m += jv * jv.transpose() * var;
            // INS errors: the normal against the return's move by the INS position and by
            // its roll, pitch, heading ([`attitude_moves`]); a rotation about `a` turns the
            // footprint's bloom by `-a . turn` ([`super::objective::Row::turn`]: per `eps = -a`, as
            // [`super::objective::Row::pose_row`]).
            let gi = {
                let (n, mv) = (r.normal, attitude_moves(&o.rot(), &r.arm));
                let mut g = SVector::<f64, 6>::from_column_slice(&[
                    n.x,
                    n.y,
                    n.z,
                    n.dot(&mv[0]),
                    n.dot(&mv[1]),
                    n.dot(&mv[2]),
                ]);
                if r.turn != [0.0; 3] {
                    let t = Vector3::from(r.turn);
                    for (k, a) in attitude_axes(&o.rot()).iter().enumerate() {
                        g[3 + k] += a.dot(&t);
                    }
                }
                g
            };
            let t = o.time.0;
            let i = t.div_euclid(period);
            let f = (t - i * period) as f64 / period as f64;
            match open {
                Some(k) if k == i => {}
                Some(k) if k + 1 == i => {
                    flush(&mut self.m, &s0);
                    s0 = s1;
                    s1 = SMat::zeros();
                }
                // Earlier (not in time order): its own samples, flushed at once.
                Some(k) if i < k => {
                    let jg = jv * gi.transpose();
                    flush(&mut self.m, &(jg * (1.0 - f)));
                    flush(&mut self.m, &(jg * f));
                    continue;
                }
                Some(_) => {
                    flush(&mut self.m, &s0);
                    flush(&mut self.m, &s1);
                    s0 = SMat::zeros();
                    s1 = SMat::zeros();
                }
                None => {}
            }
            open = Some(i);
            let jg = jv * gi.transpose();
            s0 += jg * (1.0 - f);
            s1 += jg * f;
        }
        flush(&mut self.m, &s0);
        flush(&mut self.m, &s1);
    }
}

/// How a point `R x` moves per radian of roll, pitch and heading of `R` (DESIGN.md: `R =
/// Rz(heading) Ry(pitch) Rx(roll)`), with `w = R x`: roll turns about the body x axis,
/// `R (e_x x x)`; pitch about the once-yawed y axis `Rz e_y = (-sin h, cos h, 0)`; heading
/// about the site's down axis. No trig: `(cos h, sin h)` is the first column's horizontal
/// direction.
pub fn attitude_moves(r: &Matrix3<f64>, w: &Vector3<f64>) -> [Vector3<f64>; 3] {
    let x = r.transpose() * w;
    let axes = attitude_axes(r);
    [
        r * Vector3::x().cross(&x),
        axes[1].cross(w),
        axes[2].cross(w),
    ]
}

/// The axes (site frame) roll, pitch and heading of `R` turn about ([`attitude_moves`]).
pub fn attitude_axes(r: &Matrix3<f64>) -> [Vector3<f64>; 3] {
    let (c, s) = (r[(0, 0)], r[(1, 0)]);
    let h = libm::hypot(c, s);
    let pitch = if h > 0.0 {
        Vector3::new(-s / h, c / h, 0.0)
    } else {
        Vector3::y()
    };
    [r.column(0).into_owned(), pitch, Vector3::z()]
}

/// The predicted accuracy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Predicted {
    /// 1 sigma of the six and the time offset [rad, m, s] (infinite: not determined).
    pub sigma: [f64; P7],
    /// Their correlations.
    pub correlation: SMatrix<f64, P7, P7>,
    /// Condition number of the unit-diagonal normal matrix of the six and the time offset
    /// (as [`super::lm::LmResult::condition`]).
    pub condition: f64,
    /// The weakest combination (eigenvector of the smallest eigenvalue).
    pub weakest: [f64; P7],
    /// Returns.
    pub n: u32,
}

impl Predicted {
    /// The covariance `A^-1 M A^-1` of the information, marginal to the six and the time
    /// offset (the nuisance terms estimated alongside).
    pub fn of(info: &Info) -> Self {
        let (condition, weakest) = conditioning(&info.a, true);
        let inf = Self {
            sigma: [f64::INFINITY; P7],
            correlation: SMatrix::identity(),
            condition,
            weakest,
            n: info.n,
        };
        // Scaled to unit diagonal before inverting (degrees, metres and seconds differ by
        // orders of magnitude).
        let mut d = SVector::<f64, Q>::zeros();
        // The drift is not predicted: held (an identity row).
        let mut a = info.a;
        a[(DRIFT, DRIFT)] = 1.0;
        for i in 0..Q {
            let v = a[(i, i)];
            if !(v > 0.0 && v.is_finite()) {
                return inf;
            }
            d[i] = 1.0 / libm::sqrt(v);
        }
        let dm = MatQ::from_diagonal(&d);
        let Some(inv) = (dm * a * dm).try_inverse() else {
            return inf;
        };
        let ainv = dm * inv * dm;
        let cov = ainv * info.m * ainv;
        let mut sigma = [0.0; P7];
        for (i, s) in sigma.iter_mut().enumerate() {
            let v = cov[(i, i)];
            *s = if v.is_finite() && v >= 0.0 && condition.is_finite() {
                libm::sqrt(v)
            } else {
                f64::INFINITY
            };
        }
        let mut correlation = SMatrix::<f64, P7, P7>::identity();
        for i in 0..P7 {
            for j in 0..P7 {
                correlation[(i, j)] = cov[(i, j)] / (sigma[i] * sigma[j]).max(1e-300);
            }
        }
        Self {
            sigma,
            correlation,
            condition,
            weakest,
            n: info.n,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::georef::{Mount, Params};
    use crate::time::GpsTime;

    /// How a point moves with roll, pitch and heading, against finite differences of
    /// `frames::rotation` (independent of the closed forms), at attitudes up to 80 deg of
    /// pitch and every heading.
    #[test]
    fn attitude_moves_match_finite_differences() {
        let mut rng = crate::sim::Rng::new(17);
        for _ in 0..200 {
            let rph = [
                rng.range(-1.5, 1.5),
                rng.range(-1.4, 1.4),
                rng.range(-3.2, 3.2),
            ];
            let x = Vector3::new(
                rng.range(-30.0, 30.0),
                rng.range(-30.0, 30.0),
                rng.range(-5.0, 5.0),
            );
            let r = crate::frames::rotation(rph[0], rph[1], rph[2]);
            let mv = attitude_moves(&r, &(r * x));
            for k in 0..3 {
                let (mut p, mut m) = (rph, rph);
                p[k] += 1e-6;
                m[k] -= 1e-6;
                let fd = (crate::frames::rotation(p[0], p[1], p[2]) * x
                    - crate::frames::rotation(m[0], m[1], m[2]) * x)
                    / 2e-6;
                assert!(
                    (fd - mv[k]).norm() < 1e-6 * (1.0 + fd.norm()),
                    "angle {k}: {fd} vs {}",
                    mv[k]
                );
            }
        }
    }

    /// Returns on a sphere seen head-on (the beam along the normal, cos = 1) with range noise
    /// only: every residual's error is the whole range error, independent per return, so the
    /// middle of the sandwich is sigma^2 times the normal matrix (and the covariance the
    /// classic sigma^2 (J^T J)^-1).
    #[test]
    fn range_noise_enters_as_its_radial_part() {
        let noise = NoiseModel {
            range: 0.03,
            beam_sigma: 0.0,
            range_unit: 0.0,
            position: 0.0,
            attitude: 0.0,
            ins_period_ns: 5_000_000,
            footprint: None,
        };
        let t = Target {
            center: Vector3::new(10.0, 0.0, 0.0),
            radius: 0.2,
        };
        let b = [0.0; P];
        let m = Mount::from_params(&Params(b));
        // Points on the near cap, each seen from its own sensor position along its normal.
        let mut obs = std::vec::Vec::new();
        for k in 0..50 {
            let a = (k as f64 - 25.0) * 0.02;
            let nrm = Vector3::new(-libm::cos(a), libm::sin(a), 0.0);
            let x = t.center + nrm * t.radius;
            let sensor = x + nrm * 5.0;
            let q = m.r_li.transpose() * (x - sensor);
            obs.push(Observation {
                q_l: q.cast(),
                position: sensor,
                time: GpsTime(k * 100_000_000),
                range: 5.0,
                ..Observation::default()
            });
        }
        let mut info = Info::default();
        info.add_returns(&[t], obs.iter().map(|o| (0, o)), &b, &noise);
        assert_eq!(info.n, 50);
        // Head-on: cos = 1, every residual's error has variance 0.03^2: M = sigma^2 A.
        let d = info.m - info.a * 9e-4;
        assert!(d.norm() < 1e-9 * info.m.norm(), "{d}");
    }
}

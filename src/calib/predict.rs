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

use super::lm::{conditioning, row_q, MatQ, Q};
use super::objective::{rotation_and_derivatives, Problem, SphereObs, P7};
use super::P;
use crate::frames::roll_pitch_heading;
use crate::window::{Observation, Target};
use nalgebra::{SMatrix, SVector, Vector3};

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

    /// The information of one sphere's returns (`obs` in time order) at mounting `b`:
    /// added to `self`.
    pub fn add_sphere(
        &mut self,
        target: &Target,
        obs: &[Observation],
        b: &[f64; P],
        noise: &NoiseModel,
    ) {
        self.add_returns(
            core::slice::from_ref(target),
            obs.iter().map(|o| (0, o)),
            b,
            noise,
        );
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
        let r_li = crate::frames::rotation(b[0], b[1], b[2]);
        let lever = Vector3::new(b[3], b[4], b[5]);
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
            let spheres = [SphereObs {
                target: *target,
                obs: core::slice::from_ref(o),
            }];
            let pb = Problem {
                spheres: &spheres,
                stride: 1,
                dt: 0.0,
                weights: None,
            };
            let mut one = None;
            pb.jacobian_with(b, |_, _, _, row, g| one = Some((*row, g)));
            let Some((row, g)) = one else {
                continue;
            };
            let jv = row_q(&row, g, true);
            self.a += jv * jv.transpose();
            self.n += 1;
            // Range noise, radial part.
            let cos2 = (1.0 - g).clamp(0.0, 1.0);
            let var = noise.range_variance(f64::from(o.range), libm::sqrt(cos2)) * cos2;
            self.m += jv * jv.transpose() * var;
            // INS errors: the normal, and the point relative to the INS in the site frame.
            let rot = o.rot();
            let w = lever + r_li * o.q();
            let d = o.position + rot * w - target.center;
            let norm = d.norm();
            if norm == 0.0 {
                continue;
            }
            let nrm = d / norm;
            let rph = roll_pitch_heading(&rot);
            let (_, dr) = rotation_and_derivatives(&[rph[0], rph[1], rph[2], 0.0, 0.0, 0.0]);
            let gi = SVector::<f64, 6>::from_column_slice(&[
                nrm.x,
                nrm.y,
                nrm.z,
                nrm.dot(&(dr[0] * w)),
                nrm.dot(&(dr[1] * w)),
                nrm.dot(&(dr[2] * w)),
            ]);
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
        for i in 0..Q {
            let v = info.a[(i, i)];
            if !(v > 0.0 && v.is_finite()) {
                return inf;
            }
            d[i] = 1.0 / libm::sqrt(v);
        }
        let dm = MatQ::from_diagonal(&d);
        let Some(inv) = (dm * info.a * dm).try_inverse() else {
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

    /// Returns on a sphere of radius r seen head-on (the beam along the normal) from a
    /// platform that does not rotate: the residual is the range error, so a single
    /// parameter, the radius offset, is the mean of n independent errors: sigma / sqrt(n),
    /// by hand. Here we check the diagonal of M against sum cos^2 sigma^2 j j^T directly.
    #[test]
    fn range_noise_enters_as_its_radial_part() {
        let noise = NoiseModel {
            range: 0.03,
            beam_sigma: 0.0,
            range_unit: 0.0,
            position: 0.0,
            attitude: 0.0,
            ins_period_ns: 5_000_000,
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
        info.add_sphere(&t, &obs, &b, &noise);
        assert_eq!(info.n, 50);
        // Head-on: cos = 1, every residual's error has variance 0.03^2: M = sigma^2 A.
        let d = info.m - info.a * 9e-4;
        assert!(d.norm() < 1e-9 * info.m.norm(), "{d}");
    }
}

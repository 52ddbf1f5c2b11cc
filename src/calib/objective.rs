//! The objective of eq. 6 and the signed residuals of the least-squares refinement.
//!
//! For observation k of sphere j, eq. 3 is `x_k = P_k + R_k (a + R_li(theta) q_k)`, so
//! `x_k - c_j = u_k + R_k a + R_k R_li q_k` with `u_k = P_k - c_j`. `R_li` is built once per
//! evaluation (six trig calls); each observation then costs two 3x3 products and a square root.

use super::footprint::Footprint;
use super::noise::Noise;
use crate::align::window::{Observation, Target};
use crate::frames::rotation;
use crate::georef::P;
use nalgebra::{Matrix3, Vector3};

/// One sphere's observations and its surveyed target.
#[derive(Debug, Clone, Copy)]
pub struct SphereObs<'a> {
    /// The sphere.
    pub target: Target,
    /// Its windowed returns (only the first `used` take part).
    pub obs: &'a [Observation],
}

/// The time offset between the clocks as the solver models it (INS minus LiDAR, beyond what the
/// pipeline applied): `dt + drift (t - t_ref)` [s].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TimeOffset {
    /// The offset at `t_ref` [s].
    pub dt: f64,
    /// Its rate [s/s].
    pub drift: f64,
    /// The reference time.
    pub t_ref: crate::time::GpsTime,
}

impl TimeOffset {
    /// A constant offset.
    pub const fn constant(dt: f64) -> Self {
        Self {
            dt,
            drift: 0.0,
            t_ref: crate::time::GpsTime(0),
        }
    }

    /// The offset at `o`'s time [s].
    #[inline]
    pub fn at(&self, o: &Observation) -> f64 {
        if self.drift == 0.0 {
            self.dt
        } else {
            self.dt + self.drift * (o.time.0 - self.t_ref.0) as f64 * 1e-9
        }
    }
}

/// The problem: spheres with their observations.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// The spheres.
    pub spheres: &'a [SphereObs<'a>],
    /// [`Self::l1`] uses every `stride`-th observation of each sphere (1 = all).
    pub stride: usize,
    /// The time offset [s] to apply on top of the observations' poses (the INS clock minus the
    /// LiDAR's, beyond what the pipeline applied), to first order ([`Observation::georef_dt`]),
    /// at `t_ref`.
    pub dt: f64,
    /// Its rate of change [s/s] (a LiDAR clock without PPS runs on its own crystal): the offset
    /// of a return at time t is `dt + drift (t - t_ref)`.
    pub drift: f64,
    /// The time `dt` refers to.
    pub t_ref: crate::time::GpsTime,
    /// Weighted least squares with this noise model (each residual by the inverse of its
    /// variance), or `None`: every residual alike.
    pub weights: Option<Noise>,
    /// The beam's footprint: each residual less its expected bloom ([`Footprint::bloom`]), or
    /// `None`: an ideal ray.
    pub footprint: Option<Footprint>,
}

impl Problem<'_> {
    /// Seconds from `t_ref` to `o`.
    #[inline]
    pub fn since_ref(&self, o: &Observation) -> f64 {
        (o.time.0 - self.t_ref.0) as f64 * 1e-9
    }

    /// The rows' common part at mounting `b`, with this problem's footprint.
    pub fn linearised(&self, b: &[f64; P]) -> Linearised {
        Linearised::at(b).with_footprint(self.footprint)
    }

    /// The time offset model.
    #[inline]
    pub fn time(&self) -> TimeOffset {
        TimeOffset {
            dt: self.dt,
            drift: self.drift,
            t_ref: self.t_ref,
        }
    }

    /// The time offset at `o` [s]: `dt + drift (t - t_ref)`.
    #[inline]
    pub fn dt_at(&self, o: &Observation) -> f64 {
        self.time().at(o)
    }

    /// The least-squares weight of `o` (1 without a noise model).
    #[inline]
    pub fn weight(&self, o: &Observation) -> f64 {
        self.weights.as_ref().map_or(1.0, |n| n.weight(o))
    }
}

/// The parameters with the time offset: b and dt.
pub const P7: usize = P + 1;

/// `R_li` and its derivatives by roll, pitch and heading (DESIGN.md convention).
pub fn rotation_and_derivatives(b: &[f64; P]) -> (Matrix3<f64>, [Matrix3<f64>; 3]) {
    let (r, p, h) = (b[0], b[1], b[2]);
    let (sr, cr) = libm::sincos(r);
    let (sp, cp) = libm::sincos(p);
    let (sh, ch) = libm::sincos(h);
    let rz = Matrix3::new(ch, -sh, 0.0, sh, ch, 0.0, 0.0, 0.0, 1.0);
    let ry = Matrix3::new(cp, 0.0, sp, 0.0, 1.0, 0.0, -sp, 0.0, cp);
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cr, -sr, 0.0, sr, cr);
    let drz = Matrix3::new(-sh, -ch, 0.0, ch, -sh, 0.0, 0.0, 0.0, 0.0);
    let dry = Matrix3::new(-sp, 0.0, cp, 0.0, 0.0, 0.0, -cp, 0.0, -sp);
    let drx = Matrix3::new(0.0, 0.0, 0.0, 0.0, -sr, -cr, 0.0, cr, -sr);
    let rzy = rz * ry;
    (rzy * rx, [rzy * drx, rz * dry * rx, drz * ry * rx])
}

/// The skew matrix of a vector: `skew(w) v = w x v`.
#[inline]
fn skew(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

impl Problem<'_> {
    /// Observations in all.
    pub fn len(&self) -> usize {
        self.spheres.iter().map(|s| s.obs.len()).sum()
    }

    /// No observations.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// `x_k - c_j` for a mounting (`R_li`, lever `a`) with the time offset applied.
    #[inline]
    fn offset(
        &self,
        o: &Observation,
        c: &Vector3<f64>,
        r_li: &Matrix3<f64>,
        a: &Vector3<f64>,
    ) -> Vector3<f64> {
        let w = o.rot() * (a + r_li * o.q());
        let d = (o.position - c) + w;
        let dt = self.dt_at(o);
        if dt == 0.0 {
            d
        } else {
            let (v, om): (Vector3<f64>, Vector3<f64>) = (o.velocity.cast(), o.omega.cast());
            d + (v + om.cross(&w)) * dt
        }
    }

    /// Eq. 6: the L1 sum of `| ||x_k(b) - c_j|| - r_j |` [m].
    pub fn l1(&self, b: &[f64; P]) -> f64 {
        let r_li = rotation(b[0], b[1], b[2]);
        let a = Vector3::new(b[3], b[4], b[5]);
        let mut sum = 0.0;
        for s in self.spheres {
            let (c, r) = (s.target.center, s.target.radius);
            for o in s.obs.iter().step_by(self.stride.max(1)) {
                sum += (self.offset(o, &c, &r_li, &a).norm() - r).abs();
            }
        }
        sum
    }

    /// Visit every signed residual `||x_k - c_j|| - r_j` (sphere index, residual).
    pub fn residuals(&self, b: &[f64; P], mut f: impl FnMut(usize, f64)) {
        let r_li = rotation(b[0], b[1], b[2]);
        let a = Vector3::new(b[3], b[4], b[5]);
        for (j, s) in self.spheres.iter().enumerate() {
            for o in s.obs {
                f(
                    j,
                    self.offset(o, &s.target.center, &r_li, &a).norm() - s.target.radius,
                );
            }
        }
    }

    /// Visit every residual with its gradient by b (analytic: `n = (x - c)/||x - c||`,
    /// `dr/da = M^T n`, `dr/dtheta_i = (M^T n) . (dR_li/dtheta_i q_k)` with `M = (I + dt
    /// skew(omega)) R_k`).
    pub fn jacobian(&self, b: &[f64; P], mut f: impl FnMut(f64, &[f64; P])) {
        self.jacobian_with(b, |_, _, r, row, _| {
            let six = [row[0], row[1], row[2], row[3], row[4], row[5]];
            f(r, &six)
        });
    }

    /// As [`Self::jacobian`], with the derivative by the time offset as a seventh entry
    /// (`dr/ddt = n . (v + omega x R (a + R_li q))`; by the drift it is that times
    /// [`Self::since_ref`]), the sphere index, the observation, and
    /// the grazing factor `1 - (u.n)^2` of its beam `u` on the surface normal `n` (0 head-on,
    /// 1 tangent).
    pub fn jacobian_with(
        &self,
        b: &[f64; P],
        mut f: impl FnMut(usize, &Observation, f64, &[f64; P7], f64),
    ) {
        let lin = self.linearised(b);
        for (j, s) in self.spheres.iter().enumerate() {
            for o in s.obs {
                if let Some(r) = lin.row(o, &s.target, self.dt_at(o)) {
                    f(j, o, r.residual, &r.row, r.grazing);
                }
            }
        }
    }
}

/// A pose's navigation error and a sphere centre's correction, taken out of a residual
/// ([`Linearised::row_corrected`]): the reported position is the true one plus `position`,
/// the reported attitude the true one turned by the small rotation `rotation` (site NED
/// axes) [m, rad].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavCorrection {
    /// Position error [m, NED].
    pub position: Vector3<f64>,
    /// Attitude error as a rotation vector [rad, NED axes].
    pub rotation: Vector3<f64>,
    /// The sphere centre's correction from the surveyed one [m, NED].
    pub centre: Vector3<f64>,
}

impl NavCorrection {
    /// No correction.
    pub const NONE: Self = Self {
        position: Vector3::new(0.0, 0.0, 0.0),
        rotation: Vector3::new(0.0, 0.0, 0.0),
        centre: Vector3::new(0.0, 0.0, 0.0),
    };
}

/// The mounting's rotation, its derivatives and the lever arm: what every residual's
/// gradient at `b` needs (six trig calls, once).
#[derive(Debug, Clone, Copy)]
pub struct Linearised {
    r_li: Matrix3<f64>,
    d: [Matrix3<f64>; 3],
    a: Vector3<f64>,
    /// The beam's footprint, whose bloom each residual is corrected by (`None`: a ray).
    footprint: Option<Footprint>,
}

/// A return's geometry ([`Linearised::pose`]): the corrected attitude, the beam in the
/// INS frame `R_li q`, the arm `R (a + R_li q)`, how the platform moves it, the point less
/// the centre.
struct Pose {
    rot: Matrix3<f64>,
    y: Vector3<f64>,
    w: Vector3<f64>,
    moved: Vector3<f64>,
    dx: Vector3<f64>,
}

/// One residual and its gradient ([`Problem::jacobian_with`]).
#[derive(Debug, Clone, Copy)]
pub struct Row {
    /// `||x - c|| - r` [m].
    pub residual: f64,
    /// Its derivatives by the six and the time offset.
    pub row: [f64; P7],
    /// The grazing factor `1 - (u.n)^2`.
    pub grazing: f64,
    /// The residual's direction (site frame): the surface normal at the return, plus the
    /// footprint's bloom gradient `k` when the residual is corrected by it
    /// ([`Footprint::bloom`]): a centre or the position moved by `d` moves the residual by
    /// `-normal . d`.
    pub normal: Vector3<f64>,
    /// The bloom's change as an attitude correction `eps` turns the beam with it: the
    /// rotation rows are `normal x arm - turn` ([`crate::calib::nav`]'s pieces).
    pub turn: [f64; 3],
    /// The return relative to the INS in the site frame before the time offset,
    /// `R_ig (a + R_li q)`.
    pub arm: Vector3<f64>,
}

impl Row {
    /// The residual's change by a navigation piece's error (position N, E, D; rotation
    /// `eps` about N, E, D: the arm loses `eps x arm`, the beam turns with it):
    /// `[-normal, normal x arm - turn]`.
    pub fn pose_row(&self) -> [f64; 6] {
        let (n, nw) = (self.normal, self.normal.cross(&self.arm));
        [
            -n.x,
            -n.y,
            -n.z,
            nw.x - self.turn[0],
            nw.y - self.turn[1],
            nw.z - self.turn[2],
        ]
    }
}

impl Linearised {
    /// At mounting `b`.
    pub fn at(b: &[f64; P]) -> Self {
        let (r_li, d) = rotation_and_derivatives(b);
        Self {
            r_li,
            d,
            a: Vector3::new(b[3], b[4], b[5]),
            footprint: None,
        }
    }

    /// The same, each residual corrected by the bloom of `footprint` (`None`: a ray).
    pub fn with_footprint(self, footprint: Option<Footprint>) -> Self {
        Self { footprint, ..self }
    }

    /// The residual of `o` against `target` with the time offset `dt`, and its gradient
    /// (`None` at the centre itself).
    #[inline]
    pub fn row(&self, o: &Observation, target: &Target, dt: f64) -> Option<Row> {
        self.row_corrected(o, target, dt, &NavCorrection::NONE)
    }

    /// The grazing factor `1 - (u.n)^2` of `o`'s beam on `target`, as [`Self::row_corrected`]
    /// gives it (`None` at the centre itself): where a residual's weight is taken.
    pub fn grazing(
        &self,
        o: &Observation,
        target: &Target,
        dt: f64,
        c: &NavCorrection,
    ) -> Option<f64> {
        let Pose { rot, y, dx, .. } = self.pose(o, target, dt, c);
        let (norm, yn) = (dx.norm(), y.norm());
        if norm == 0.0 || yn == 0.0 {
            return None;
        }
        let cos = y.dot(&(rot.transpose() * dx)) / (yn * norm);
        Some(1.0 - cos * cos)
    }

    /// The return's geometry at this mounting, the pose corrected by `c`.
    #[inline]
    fn pose(&self, o: &Observation, target: &Target, dt: f64, c: &NavCorrection) -> Pose {
        let reported = o.rot();
        // R_true = (I - [eps]x) R_reported: the arm loses eps x arm (the mounting's gradient
        // with the same rotation, so that the Jacobian is the residual's).
        let rot = reported - skew(&c.rotation) * reported;
        let y = self.r_li * o.q();
        let w = rot * (self.a + y);
        let (v, om): (Vector3<f64>, Vector3<f64>) = (o.velocity.cast(), o.omega.cast());
        let moved = v + om.cross(&w);
        let dx = (o.position - c.position - (target.center + c.centre)) + w + moved * dt;
        Pose {
            rot,
            y,
            w,
            moved,
            dx,
        }
    }

    /// As [`Self::row`] with the pose corrected by `c` (its navigation error taken out: the
    /// position less `c.position`, the attitude turned back by `c.rotation`) and the centre
    /// moved by `c.centre`.
    #[inline]
    pub fn row_corrected(
        &self,
        o: &Observation,
        target: &Target,
        dt: f64,
        c: &NavCorrection,
    ) -> Option<Row> {
        let q = o.q();
        let Pose {
            rot,
            y,
            w,
            moved,
            dx,
        } = self.pose(o, target, dt, c);
        let om: Vector3<f64> = o.omega.cast();
        let norm = dx.norm();
        if norm == 0.0 {
            return None;
        }
        let n = dx / norm;
        let (mut residual, mut dir) = (norm - target.radius, n);
        let (mut bore, mut turn) = ([0.0; 3], [0.0; 3]);
        let (rho, hz) = (y.norm(), libm::hypot(q.x, q.y));
        if let Some(fp) = self.footprint.filter(|_| rho > 0.0 && hz > 0.0) {
            // The beam and the scan's direction (horizontal in the LiDAR frame).
            let sl = Vector3::new(-q.y / hz, q.x / hz, 0.0);
            let (u, s) = (rot * y / rho, rot * (self.r_li * sl));
            let bloom = fp.bloom(&dx, &u, &s, rho, target.radius);
            residual -= bloom.e;
            dir += bloom.k;
            // The boresight and the attitude turn the footprint with the beam.
            for (t, d) in bore.iter_mut().zip(&self.d) {
                *t = bloom.turned(&(rot * (d * q) / rho), &(rot * (d * sl)));
            }
            for (k, t) in turn.iter_mut().enumerate() {
                let axis = Vector3::ith(k, 1.0);
                *t = bloom.turned(&-axis.cross(&u), &-axis.cross(&s));
            }
        }
        let m = if dt == 0.0 {
            rot
        } else {
            rot + skew(&om) * rot * dt
        };
        let g = m.transpose() * dir;
        let row = [
            g.dot(&(self.d[0] * q)) - bore[0],
            g.dot(&(self.d[1] * q)) - bore[1],
            g.dot(&(self.d[2] * q)) - bore[2],
            g.x,
            g.y,
            g.z,
            dir.dot(&moved),
        ];
        // The beam R_ig y against the normal: (R y).n = y.(R^T n).
        let yn = y.norm();
        let cos = if yn > 0.0 {
            y.dot(&(rot.transpose() * n)) / yn
        } else {
            1.0
        };
        Some(Row {
            residual,
            row,
            grazing: 1.0 - cos * cos,
            normal: dir,
            turn,
            arm: w,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Rng;
    use crate::time::GpsTime;

    fn random_obs(rng: &mut Rng, n: usize) -> std::vec::Vec<Observation> {
        (0..n)
            .map(|_| Observation {
                q_l: Vector3::new(
                    rng.range(-20.0, 20.0) as f32,
                    rng.range(-20.0, 20.0) as f32,
                    rng.range(-3.0, 3.0) as f32,
                ),
                position: Vector3::new(
                    rng.range(-30.0, 30.0),
                    rng.range(-30.0, 30.0),
                    rng.range(-1.0, 1.0),
                ),
                r_ig: rotation(
                    rng.range(-0.1, 0.1),
                    rng.range(-0.1, 0.1),
                    rng.range(-3.0, 3.0),
                )
                .cast(),
                time: GpsTime(0),
                range: 10.0,
                ..Observation::default()
            })
            .collect()
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let mut rng = Rng::new(11);
        let obs = random_obs(&mut rng, 50);
        let t = Target {
            center: Vector3::new(1.0, 2.0, -1.5),
            radius: 0.19,
        };
        let spheres = [SphereObs {
            target: t,
            obs: &obs,
        }];
        let pb = Problem {
            spheres: &spheres,
            stride: 1,
            dt: 0.0,
            drift: 0.0,
            t_ref: GpsTime(0),
            weights: None,
            footprint: None,
        };
        let b = [3.13, -0.78, 0.02, 1.5, -1.24, -1.36];
        let mut rows = std::vec::Vec::new();
        pb.jacobian(&b, |r, row| rows.push((r, *row)));
        for i in 0..P {
            let h = 1e-6;
            let (mut bp, mut bm) = (b, b);
            bp[i] += h;
            bm[i] -= h;
            let (mut rp, mut rm) = (std::vec::Vec::new(), std::vec::Vec::new());
            pb.residuals(&bp, |_, r| rp.push(r));
            pb.residuals(&bm, |_, r| rm.push(r));
            for k in 0..obs.len() {
                let fd = (rp[k] - rm[k]) / (2.0 * h);
                assert!(
                    (fd - rows[k].1[i]).abs() < 1e-6 * (1.0 + fd.abs()),
                    "param {i} obs {k}: {fd} vs {}",
                    rows[k].1[i]
                );
            }
        }
        // With a time offset: every derivative, the offset's too, against finite differences.
        let obs_moving: std::vec::Vec<Observation> = obs
            .iter()
            .map(|o| Observation {
                velocity: Vector3::new(2.0, -1.0, 0.1),
                omega: Vector3::new(0.02, -0.05, 0.3),
                ..*o
            })
            .collect();
        let spheres_m = [SphereObs {
            target: t,
            obs: &obs_moving,
        }];
        let at = |dt: f64| Problem {
            spheres: &spheres_m,
            stride: 1,
            dt,
            drift: 0.0,
            t_ref: GpsTime(0),
            weights: None,
            footprint: None,
        };
        let dt = 0.05;
        let mut rows7 = std::vec::Vec::new();
        at(dt).jacobian_with(&b, |_, _, r, row, _| rows7.push((r, *row)));
        for i in 0..P7 {
            let h = 1e-6;
            let (mut rp, mut rm) = (std::vec::Vec::new(), std::vec::Vec::new());
            if i < P {
                let (mut bp, mut bm) = (b, b);
                bp[i] += h;
                bm[i] -= h;
                at(dt).residuals(&bp, |_, r| rp.push(r));
                at(dt).residuals(&bm, |_, r| rm.push(r));
            } else {
                at(dt + h).residuals(&b, |_, r| rp.push(r));
                at(dt - h).residuals(&b, |_, r| rm.push(r));
            }
            for k in 0..obs.len() {
                let fd = (rp[k] - rm[k]) / (2.0 * h);
                assert!(
                    (fd - rows7[k].1[i]).abs() < 1e-6 * (1.0 + fd.abs()),
                    "dt: param {i} obs {k}: {fd} vs {}",
                    rows7[k].1[i]
                );
            }
        }
        // L1 is the sum of |residuals|.
        let mut s = 0.0;
        pb.residuals(&b, |_, r| s += r.abs());
        assert!((s - pb.l1(&b)).abs() < 1e-9);
    }

    #[test]
    fn derivative_matrices_match_the_rotation() {
        let b = [0.3, -0.4, 2.0, 0.0, 0.0, 0.0];
        let (r, d) = rotation_and_derivatives(&b);
        assert!((r - rotation(0.3, -0.4, 2.0)).norm() < 1e-15);
        for i in 0..3 {
            let (mut bp, mut bm) = (b, b);
            bp[i] += 1e-7;
            bm[i] -= 1e-7;
            let fd = (rotation(bp[0], bp[1], bp[2]) - rotation(bm[0], bm[1], bm[2])) / 2e-7;
            assert!((fd - d[i]).norm() < 1e-7);
        }
    }
}

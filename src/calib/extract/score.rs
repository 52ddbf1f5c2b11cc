//! Scoring a candidate centre: the returns sorted by x for range queries ([`Sorted`]), their
//! MSAC support and free-space violations, the fixed-radius refinement and the plane test.

use super::{dot, norm, sub, V3};
use crate::align::window::Observation;
use nalgebra::{Matrix3, Vector3};

/// What a candidate centre explains in a slice.
#[derive(Debug, Clone, Copy, Default)]
pub struct Support {
    /// MSAC weight of the inliers.
    pub weight: f32,
    /// Inliers.
    pub inliers: u32,
    /// Free-space violations.
    pub violations: u32,
    /// Visible-side returns in the collar just outside the sphere.
    pub collar: u32,
}

/// A slice of observations with its index sorted by x (`keys`: x and the observation's
/// index): the returns near a point are a contiguous run of the index.
#[derive(Debug, Clone, Copy)]
pub struct Sorted<'a> {
    /// The observations (any order).
    pub obs: &'a [Observation],
    /// (x, index), by x.
    pub keys: &'a [(f32, u32)],
}

impl<'a> Sorted<'a> {
    /// Index `obs` by x into `keys` (at least as long as `obs`; the rest is left alone).
    pub fn new(obs: &'a [Observation], keys: &'a mut [(f32, u32)]) -> Self {
        let n = obs.len().min(keys.len());
        for (i, (k, o)) in keys.iter_mut().zip(obs).enumerate() {
            *k = (o.work.x[0], i as u32);
        }
        keys[..n].sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        Self {
            obs: &obs[..n],
            keys: &keys[..n],
        }
    }

    /// The returns whose x lies within `reach` of `cx`.
    pub fn near(&self, cx: f32, reach: f32) -> impl Iterator<Item = &'a Observation> + Clone {
        let a = self.keys.partition_point(|k| k.0 < cx - reach);
        let b = self.keys.partition_point(|k| k.0 <= cx + reach);
        let obs = self.obs;
        self.keys[a..b.max(a)]
            .iter()
            .map(move |k| &obs[k.1 as usize])
    }
}

/// What a candidate centre `c` (relative) of radius `r` with band `tau` explains among the
/// returns near it (of an x-sorted slice): inliers, returns inside the solid sphere, returns in
/// the collar just outside it.
pub fn support(obs: &Sorted<'_>, c: V3, r: f32, tau: f32) -> Support {
    let mut s = Support::default();
    let collar = r + tau + (2.0 * tau).max(0.05);
    let inner = r - tau.max(0.02);
    for o in obs.near(c[0], collar) {
        let d = sub(o.work.x, c);
        let e2 = dot(d, d);
        if e2 > collar * collar {
            continue;
        }
        let dist = libm::sqrtf(e2);
        let e = dist - r;
        let visible = dot(d, o.work.u) <= 0.25 * dist;
        if e.abs() < tau {
            // The visible side: the outward normal faces the sensor.
            if visible {
                s.weight += 1.0 - (e / tau) * (e / tau);
                s.inliers += 1;
            }
        } else if dist < inner {
            s.violations += 1;
        } else if e > 0.0 && visible {
            // Just outside: a cylinder or a surface that goes on where a sphere ends.
            s.collar += 1;
        }
    }
    s
}

/// Returns seen through the candidate sphere: the beam from the sensor to the return passes
/// through the solid sphere before reaching it (every return of the slice is checked).
/// Going back from the return along its beam, `x - s u`, the beam is nearest the centre at
/// `s = d.u`.
pub fn seen_through(obs: &[Observation], c: V3, r: f32, tau: f32) -> u32 {
    let inner = r - tau.max(0.02);
    let mut n = 0;
    for o in obs {
        let d = sub(o.work.x, c);
        let along = dot(d, o.work.u);
        if along > r && along < o.range {
            let perp2 = dot(d, d) - along * along;
            if perp2 < inner * inner {
                n += 1;
            }
        }
    }
    n
}

/// Fit a sphere centre of radius `r` (fixed) to the visible-side returns within `band` of the
/// surface around `c` (Gauss-Newton, a few steps).
pub fn refine(obs: &Sorted<'_>, mut c: V3, r: f32, band: f32) -> V3 {
    for _ in 0..4 {
        let mut jtj = Matrix3::<f32>::zeros();
        let mut jtr = Vector3::<f32>::zeros();
        let mut n = 0;
        let reach = r + band;
        for o in obs.near(c[0], reach) {
            let d = sub(o.work.x, c);
            let e2 = dot(d, d);
            if e2 > reach * reach {
                continue;
            }
            let dist = libm::sqrtf(e2);
            let e = dist - r;
            if e.abs() > band || dist <= 0.0 || dot(d, o.work.u) > 0.25 * dist {
                continue;
            }
            let j = Vector3::new(-d[0] / dist, -d[1] / dist, -d[2] / dist);
            jtj += j * j.transpose();
            jtr += j * e;
            n += 1;
        }
        if n < 4 {
            return c;
        }
        let Some(ch) = jtj.cholesky() else { return c };
        let step = ch.solve(&(-jtr));
        if !step.iter().all(|x| x.is_finite()) {
            return c;
        }
        c = [c[0] + step.x, c[1] + step.y, c[2] + step.z];
        if step.norm() < 1e-4 {
            break;
        }
    }
    c
}

/// RMS distances of the inliers of `c` from the sphere and from their best plane: a cap of a
/// sphere is fitted better by the sphere; a plane patch (deck, wall) equally well by a plane.
pub fn plane_vs_sphere(obs: &Sorted<'_>, c: V3, r: f32, tau: f32) -> (f32, f32) {
    let (mut n, mut m, mut e2) = (0f32, [0f32; 3], 0f32);
    let inlier = |o: &Observation| {
        let d = sub(o.work.x, c);
        let dist = norm(d);
        let e = dist - r;
        (e.abs() < tau && dot(d, o.work.u) <= 0.25 * dist).then_some(e)
    };
    let obs = obs.near(c[0], r + tau);
    for o in obs.clone() {
        if let Some(e) = inlier(o) {
            n += 1.0;
            e2 += e * e;
            for (k, mk) in m.iter_mut().enumerate() {
                *mk += o.work.x[k];
            }
        }
    }
    if n < 4.0 {
        return (0.0, 0.0);
    }
    let m = [m[0] / n, m[1] / n, m[2] / n];
    let mut cov = Matrix3::<f32>::zeros();
    for o in obs {
        if inlier(o).is_some() {
            let d = Vector3::from(sub(o.work.x, m));
            cov += d * d.transpose();
        }
    }
    let Some(ev) = eigenvalues(cov) else {
        return (0.0, 0.0);
    };
    let lo = ev.iter().copied().fold(f32::INFINITY, f32::min).max(0.0);
    (libm::sqrtf(e2 / n), libm::sqrtf(lo / n))
}

/// Eigenvalues of a symmetric 3x3 matrix, with the iterations bounded (`None` when they do not
/// converge, e.g. on a NaN).
pub(super) fn eigenvalues(m: Matrix3<f32>) -> Option<[f32; 3]> {
    let e = nalgebra::SymmetricEigen::try_new(m, f32::EPSILON, 100)?;
    let v = [e.eigenvalues[0], e.eigenvalues[1], e.eigenvalues[2]];
    v.iter().all(|x| x.is_finite()).then_some(v)
}

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

/// A return in a slice's index: where it is (its `work.x`, held here so that a query reads
/// the index, not the 160-byte returns it passes over) and its index in the slice.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Key {
    /// The return's `work.x` [m].
    pub x: [f32; 3],
    /// Its index in the slice.
    pub i: u32,
}

/// A slice of observations with its index sorted by x (`keys`): the returns near a point are
/// a contiguous run of the index.
#[derive(Debug, Clone, Copy)]
pub struct Sorted<'a> {
    /// The observations (any order).
    pub obs: &'a [Observation],
    /// Their keys, by x.
    pub keys: &'a [Key],
}

impl<'a> Sorted<'a> {
    /// Index `obs` by x into `keys` (at least as long as `obs`; the rest is scratch): by x in
    /// its total order, equal x by index.
    pub fn new(obs: &'a [Observation], keys: &'a mut [Key]) -> Self {
        let n = obs.len().min(keys.len());
        for (i, (k, o)) in keys.iter_mut().zip(obs).enumerate() {
            *k = Key {
                x: o.work.x,
                i: i as u32,
            };
        }
        if 2 * n <= keys.len() {
            let (a, b) = keys.split_at_mut(n);
            radix_sort(a, &mut b[..n]);
        } else {
            keys[..n].sort_unstable_by(|a, b| a.x[0].total_cmp(&b.x[0]).then(a.i.cmp(&b.i)));
        }
        Self {
            obs: &obs[..n],
            keys: &keys[..n],
        }
    }

    /// The keys whose x lies within `reach` of `cx`.
    fn slab(&self, cx: f32, reach: f32) -> &'a [Key] {
        let a = self.keys.partition_point(|k| k.x[0] < cx - reach);
        let b = self.keys.partition_point(|k| k.x[0] <= cx + reach);
        &self.keys[a..b.max(a)]
    }

    /// The returns whose x lies within `reach` of `cx`.
    pub fn near(&self, cx: f32, reach: f32) -> impl Iterator<Item = &'a Observation> + Clone {
        let obs = self.obs;
        self.slab(cx, reach).iter().map(move |k| &obs[k.i as usize])
    }

    /// The returns within `reach` of `c` (`|x - c|^2 <= reach^2`, as the callers test it).
    pub fn within(&self, c: V3, reach: f32) -> impl Iterator<Item = &'a Observation> + Clone {
        let obs = self.obs;
        self.slab(c[0], reach)
            .iter()
            .filter(move |k| {
                let d = sub(k.x, c);
                dot(d, d) <= reach * reach
            })
            .map(move |k| &obs[k.i as usize])
    }
}

/// `f32::total_cmp`'s order as an unsigned integer's.
#[inline]
fn ordered(x: f32) -> u32 {
    let b = x.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// Sort `keys` (indices in increasing order) by x, stably: a least-significant-byte-first
/// radix sort through `tmp` (as long as `keys`), a byte all keys share skipped. The order is
/// [`Sorted::new`]'s comparison sort's, in linear time (table1's slices indexed: 3.4 -> 2.0 ms).
fn radix_sort(keys: &mut [Key], tmp: &mut [Key]) {
    let n = keys.len();
    let (mut src, mut dst) = (keys, tmp);
    let mut in_tmp = false;
    for shift in [0u32, 8, 16, 24] {
        let mut count = [0usize; 256];
        for k in src.iter() {
            count[((ordered(k.x[0]) >> shift) & 0xff) as usize] += 1;
        }
        if count.contains(&n) {
            continue;
        }
        let mut at = 0;
        for c in count.iter_mut() {
            (*c, at) = (at, at + *c);
        }
        for k in src.iter() {
            let b = ((ordered(k.x[0]) >> shift) & 0xff) as usize;
            dst[count[b]] = *k;
            count[b] += 1;
        }
        core::mem::swap(&mut src, &mut dst);
        in_tmp = !in_tmp;
    }
    if in_tmp {
        // The sorted keys are in the scratch: back where they belong.
        dst.copy_from_slice(src);
    }
}

/// What a candidate centre `c` (relative) of radius `r` with band `tau` explains among the
/// returns near it (of an x-sorted slice): inliers, returns inside the solid sphere, returns in
/// the collar just outside it.
pub fn support(obs: &Sorted<'_>, c: V3, r: f32, tau: f32) -> Support {
    let mut s = Support::default();
    let collar = r + tau + (2.0 * tau).max(0.05);
    let inner = r - tau.max(0.02);
    for o in obs.within(c, collar) {
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
        for o in obs.within(c, reach) {
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

#[cfg(test)]
mod tests {
    use super::{radix_sort, Key};
    use crate::sim::rng::Rng;

    /// The radix sort puts keys in the comparison sort's order (x's total order, then index):
    /// negatives, both zeros, ties, infinities and NaN, at lengths that take 1-4 byte passes.
    #[test]
    fn the_radix_sort_is_the_total_order_by_x_then_index() {
        let mut rng = Rng::new(5);
        for n in [0usize, 1, 2, 7, 300, 3000] {
            let mut keys: heapless::Vec<Key, 3000> = heapless::Vec::new();
            for i in 0..n {
                let x = match i % 9 {
                    0 => 0.0,
                    1 => -0.0,
                    2 => f32::INFINITY,
                    3 => f32::NAN,
                    4 => 1.25,
                    _ => rng.range(-40.0, 40.0) as f32,
                };
                let _ = keys.push(Key {
                    x: [x, 0.5, -0.5],
                    i: i as u32,
                });
            }
            let mut want = keys.clone();
            want.sort_unstable_by(|a, b| a.x[0].total_cmp(&b.x[0]).then(a.i.cmp(&b.i)));
            let mut tmp = [Key::default(); 3000];
            radix_sort(&mut keys, &mut tmp[..n]);
            let bits = |v: &[Key]| {
                v.iter()
                    .map(|k| (k.x[0].to_bits(), k.i))
                    .collect::<heapless::Vec<_, 3000>>()
            };
            assert_eq!(bits(&keys), bits(&want), "n = {n}");
        }
    }
}

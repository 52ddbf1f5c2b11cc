//! [`super::expected`] tabulated once per sensor, for the least squares' every row: the
//! quadrature costs 64 Gaussians a call and a solve makes hundreds of thousands of calls.
//!
//! Over the limb the expected residual in units of the footprint's width towards the centre,
//! `e / sigma_u`, is smooth in the axis's distance outside the limb in those widths `q`, in
//! the direction (`w = sin^2` of its angle from the scan) and in the footprint's width over
//! the radius `t` (spaced in `sqrt t`): a table of `q x w x t`, cubic in `q`, linear in the others.
//! Deeper inside, where the footprint lies on the cap, a Gauss-Hermite rule without the rim
//! takes over (within 0.01 mm).

use super::quad::{Limb, LIMB_REACH, NQ, NT, NW, Q_LO, Q_STEP, T_HI};

/// The tables the build script made (`build.rs`, from `make.rs` over `quad.rs`).
mod made {
    include!(concat!(env!("OUT_DIR"), "/footprint_table.rs"));
}

/// The expected residual over the limb for footprints of widths `(s, kappa s)`.
#[derive(Debug, Clone, Copy)]
pub struct Table {
    kappa: f64,
    v: &'static [f32; NQ * NW * NT],
}

/// The Velodynes' footprint: 3.0 by 1.5 mrad (the manuals' beam divergence tables), so
/// `kappa = 0.5`.
pub static HALF: Table = Table {
    kappa: 0.5,
    v: &made::HALF,
};

/// Gauss-Hermite nodes and weights for a standard normal (probabilists', 4 points).
const GH4: [(f64, f64); 4] = [
    (-2.334_414_218_338_977, 0.045_875_854_768_068_5),
    (-0.741_963_784_302_725_8, 0.454_124_145_231_931_5),
    (0.741_963_784_302_725_8, 0.454_124_145_231_931_5),
    (2.334_414_218_338_977, 0.045_875_854_768_068_5),
];

/// The expected residual where the footprint lies on the cap (the axis six widths and more
/// inside the limb): `E[h^2] = r^2 - |m|^2 - s0^2 - s1^2` exactly, `E[h]` by 4 x 4
/// Gauss-Hermite points (the cap's height is smooth there: the rule is exact to degree 7).
pub fn inside(m: [f64; 2], s: [f64; 2], r: f64) -> f64 {
    inside_with_gradient(m, s, r).0
}

/// [`inside`] and its gradient by `m`, in the same pass: `e = sqrt(|m|^2 + h^2) - r` with
/// `h = E[h^2] / E[h]`, so `de = (m + h dh) / (e + r)`, `dh = (dE[h^2] - h dE[h]) / E[h]`,
/// `dE[h^2] = -2 m` and `dE[h]` the rule's sum of `-(x, y) / sqrt(r^2 - x^2 - y^2)`.
pub fn inside_with_gradient(m: [f64; 2], s: [f64; 2], r: f64) -> (f64, [f64; 2]) {
    let d2 = m[0] * m[0] + m[1] * m[1];
    let (mut eh, mut deh) = (0.0, [0.0; 2]);
    for (a, wa) in GH4 {
        for (c, wc) in GH4 {
            let (x, y) = (m[0] + a * s[0], m[1] + c * s[1]);
            let z2 = r * r - x * x - y * y;
            if z2 > 0.0 {
                let z = libm::sqrt(z2);
                let w = wa * wc;
                eh += w * z;
                deh[0] -= w * x / z;
                deh[1] -= w * y / z;
            }
        }
    }
    let eh2 = r * r - d2 - s[0] * s[0] - s[1] * s[1];
    if eh <= 0.0 {
        let d = libm::sqrt(d2);
        let g = if d > 0.0 {
            [m[0] / d, m[1] / d]
        } else {
            [0.0; 2]
        };
        return (d - r, g);
    }
    let h = eh2 / eh;
    let len = libm::sqrt(d2 + h * h);
    let mut g = [0.0; 2];
    if len > 0.0 {
        for k in 0..2 {
            let dh = (-2.0 * m[k] - h * deh[k]) / eh;
            g[k] = (m[k] + h * dh) / len;
        }
    }
    (len - r, g)
}

impl Table {
    /// The table for footprints whose across-scan width is `kappa` times the along-scan one,
    /// if one was made.
    pub fn for_ratio(kappa: f64) -> Option<&'static Self> {
        ((kappa - HALF.kappa).abs() < 1e-6).then_some(&HALF)
    }

    /// [`super::expected`] from the table; `None` where it does not apply (another width
    /// ratio, a footprint wider than [`T_HI`] of the radius).
    pub fn expected(&self, m: [f64; 2], s: [f64; 2], r: f64) -> Option<f64> {
        self.expected_with_gradient(m, s, r).map(|(e, _)| e)
    }

    /// [`Self::expected`] and its gradient by `m`: the interpolant's own derivative over the
    /// limb (cubic in `q`, linear in `w`); inside, where the cap's rule takes over, central
    /// differences at a twentieth of the narrower width.
    pub fn expected_with_gradient(
        &self,
        m: [f64; 2],
        s: [f64; 2],
        r: f64,
    ) -> Option<(f64, [f64; 2])> {
        if s[0] <= 0.0 || r <= 0.0 || (s[1] - self.kappa * s[0]).abs() > 1e-6 * s[0] {
            return None;
        }
        let t = s[0] / r;
        if t > T_HI {
            return None;
        }
        let Limb { d, w, su, q } = Limb::of(m, s, r);
        if q < Q_LO {
            return Some(inside_with_gradient(m, s, r));
        }
        if q < Q_LO + 1.0 {
            // The cap's rule, blended into the table over its first width.
            let at = |m: [f64; 2]| self.blended(m, s, r, t);
            let h = 0.05 * s[0].min(s[1]);
            let mut g = [0.0; 2];
            for (k, gk) in g.iter_mut().enumerate() {
                let (mut a, mut b) = (m, m);
                a[k] += h;
                b[k] -= h;
                *gk = (at(a) - at(b)) / (2.0 * h);
            }
            return Some((at(m), g));
        }
        let held = q > LIMB_REACH;
        let (v, dv_dq, dv_dw) = self.interpolate(q.min(LIMB_REACH), w, t);
        // Chain rule: e = su(w) v(q, w); q = (d - r) / su; w = m1^2 / d^2.
        let dd = [m[0] / d, m[1] / d];
        let d4 = d * d * d * d;
        let dw = [
            -2.0 * m[1] * m[1] * m[0] / d4,
            2.0 * m[1] * m[0] * m[0] / d4,
        ];
        let dsu_dw = (s[1] * s[1] - s[0] * s[0]) / (2.0 * su);
        let mut g = [0.0; 2];
        for k in 0..2 {
            let dsu = dsu_dw * dw[k];
            let dq = if held {
                0.0
            } else {
                dd[k] / su - (d - r) / (su * su) * dsu
            };
            g[k] = dsu * v + su * (dv_dq * dq + dv_dw * dw[k]);
        }
        Some((su * v, g))
    }

    /// The table's value and its derivatives by `q` and `w` at `(q, w, t)`.
    fn interpolate(&self, q: f64, w: f64, t: f64) -> (f64, f64, f64) {
        let fq = (q - Q_LO) / Q_STEP;
        let iq = fq as usize;
        let xq = fq - iq as f64;
        let fw = w * (NW - 1) as f64;
        let iw = (fw as usize).min(NW - 2);
        let xw = fw - iw as f64;
        let ft = libm::sqrt(t / T_HI) * (NT - 1) as f64;
        let it = (ft as usize).min(NT - 2);
        let xt = (ft - it as f64).min(1.0);
        let (mut v, mut vq, mut vw) = (0.0, 0.0, 0.0);
        for (jt, wt) in [(it, 1.0 - xt), (it + 1, xt)] {
            for (jw, ww, sw) in [(iw, 1.0 - xw, -1.0), (iw + 1, xw, 1.0)] {
                let row = &self.v[(jt * NW + jw) * NQ..(jt * NW + jw + 1) * NQ];
                let at =
                    |k: isize| f64::from(row[(iq as isize + k).clamp(0, NQ as isize - 1) as usize]);
                let (p0, p1, p2, p3) = (at(-1), at(0), at(1), at(2));
                // Catmull-Rom: c(x) = p1 + x (a + x (b + x c3)) / 2.
                let a = p2 - p0;
                let b = 2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3;
                let c3 = 3.0 * (p1 - p2) + p3 - p0;
                let c = p1 + 0.5 * xq * (a + xq * (b + xq * c3));
                let dc = 0.5 * (a + xq * (2.0 * b + 3.0 * xq * c3));
                v += wt * ww * c;
                vq += wt * ww * dc / Q_STEP;
                vw += wt * sw * c * (NW - 1) as f64;
            }
        }
        (v, vq, vw)
    }

    /// The value where the cap's rule takes over: blended into the table over its first
    /// width.
    fn blended(&self, m: [f64; 2], s: [f64; 2], r: f64, t: f64) -> f64 {
        let Limb { w, su, q, .. } = Limb::of(m, s, r);
        if q < Q_LO {
            return inside(m, s, r);
        }
        let b = q - Q_LO;
        let e = su * self.interpolate(q.min(LIMB_REACH), w, t).0;
        if b < 1.0 {
            b * e + (1.0 - b) * inside(m, s, r)
        } else {
            e
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table against the brute-force integral, between its nodes, beams from 3 m to 50 m
    /// on spheres of 0.07-0.25 m, from the middle to beyond the reach (held there): within
    /// 0.1 mm, the gradient within 0.01 (to just inside the reach).
    #[test]
    fn the_table_follows_the_integral() {
        let brute = super::super::tests::brute;
        let (mut worst, mut worst_g): (f64, f64) = (0.0, 0.0);
        for (range, r) in [
            (3.0, 0.25),
            (30.0, 0.19),
            (45.0, 0.25),
            (50.0, 0.24),
            (14.0, 0.07),
        ] {
            let s = [0.75e-3 * range, 0.375e-3 * range];
            for k in 0..97 {
                let th = f64::from(k) * 0.173;
                let su = libm::hypot(libm::cos(th) * s[0], libm::sin(th) * s[1]);
                let q = f64::from(k % 23) * 0.41 - 5.3;
                let d = (r + su * q).max(0.0);
                let m = [d * libm::cos(th), d * libm::sin(th)];
                let (e, g) = HALF.expected_with_gradient(m, s, r).expect("in the table");
                let eb = brute(super::super::quad::within_reach(m, s, r), s, r);
                worst = worst.max((e - eb).abs());
                assert!(
                    (e - eb).abs() < 1e-4,
                    "{range} m, r {r}, m {m:?}: {e} vs {eb}"
                );
                if q > LIMB_REACH - 0.1 {
                    continue;
                }
                let h = 0.05 * s[1];
                for i in 0..2 {
                    let (mut a, mut b) = (m, m);
                    a[i] += h;
                    b[i] -= h;
                    let gb = (brute(a, s, r) - brute(b, s, r)) / (2.0 * h);
                    worst_g = worst_g.max((g[i] - gb).abs());
                    assert!(
                        (g[i] - gb).abs() < 0.01,
                        "{range} m, r {r}, m {m:?} {i}: {g:?} vs {gb}"
                    );
                }
            }
        }
        assert!(worst > 0.0 && worst_g > 0.0);
    }

    /// The cap's rule against the brute-force integral six widths and more inside the limb:
    /// within 0.01 mm.
    #[test]
    fn inside_the_cap_rule_is_the_integral() {
        for (range, r) in [(3.0, 0.25), (30.0, 0.19), (50.0, 0.24), (14.0, 0.07)] {
            let s = [0.75e-3 * range, 0.375e-3 * range];
            for k in 0..20 {
                let th = f64::from(k) * 0.31;
                let su = libm::hypot(libm::cos(th) * s[0], libm::sin(th) * s[1]);
                let d = (r - su * (6.0 + f64::from(k % 5))).max(0.0);
                let m = [d * libm::cos(th), d * libm::sin(th)];
                let (a, b) = (inside(m, s, r), super::super::tests::brute(m, s, r));
                assert!(
                    (a - b).abs() < 1e-5,
                    "{range} m, r {r}, m {m:?}: {a} vs {b}"
                );
                // The gradient against central differences of the rule.
                let g = inside_with_gradient(m, s, r).1;
                let h = 1e-3 * s[1];
                for k in 0..2 {
                    let (mut p, mut q) = (m, m);
                    p[k] += h;
                    q[k] -= h;
                    let fd = (inside(p, s, r) - inside(q, s, r)) / (2.0 * h);
                    assert!(
                        (g[k] - fd).abs() < 1e-6 * (1.0 + fd.abs()),
                        "{range} m, r {r}, m {m:?}, axis {k}: {} vs {fd}",
                        g[k]
                    );
                }
            }
        }
    }

    /// Another width ratio, or a footprint wider than half the radius, is not in the table.
    #[test]
    fn outside_the_table_it_says_so() {
        let table = HALF;
        assert!(table.expected([0.1, 0.0], [0.01, 0.01], 0.2).is_none());
        assert!(table.expected([0.1, 0.0], [0.04, 0.02], 0.2).is_none());
        assert!(table.expected([0.1, 0.0], [0.02, 0.01], 0.2).is_some());
    }
}

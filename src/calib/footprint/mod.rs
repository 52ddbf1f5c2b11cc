//! A diverging beam's return from a sphere (the mixed pixel over its footprint, Hebert &
//! Krotkov 1992): the footprint, a Gaussian of 1-sigma half-angles `sigma` along and across the
//! scan, lights the sphere's visible cap; the return's range is the energy-weighted mean range
//! over what it lit (energy `G cos(incidence)`), placed on the beam's axis. Near the limb part
//! of the footprint misses, so the point blooms outwards (up to the footprint's width outside
//! the surface); over the middle the cap's curvature puts it slightly inside. The residual a
//! return is expected to have, and its gradient, for the least squares to take out.

mod beam;
mod quad;
#[cfg(test)]
mod rows;
mod table;
pub use beam::{Bloom, Footprint};
pub use quad::{Limb, LIMB_REACH};
pub use table::Table;

/// The residual `||x - c|| - r` a return is expected to have for a sphere of radius `r` whose
/// centre is `m` [m] from the beam's axis (along, across the scan) in the plane across it, the
/// footprint's 1-sigma widths there `s` [m].
pub fn expected(m: [f64; 2], s: [f64; 2], r: f64) -> f64 {
    quad::expected_in(m, s, r)
}

/// [`expected`] and its gradient by `m` (central differences at a twentieth of the
/// footprint's narrower width: the quadrature's own slope, closer to the integral's than the
/// quadrature of the Gaussian's derivative, test `the_gradient_matches_the_integrals_slope`).
pub fn expected_with_gradient(m: [f64; 2], s: [f64; 2], r: f64) -> (f64, [f64; 2]) {
    let e = expected(m, s, r);
    let d = 0.05 * s[0].min(s[1]);
    let de = |k: usize| {
        let (mut a, mut b) = (m, m);
        a[k] += d;
        b[k] -= d;
        (expected(a, s, r) - expected(b, s, r)) / (2.0 * d)
    };
    (e, [de(0), de(1)])
}

#[cfg(test)]
mod tests {
    use super::quad::within_reach;
    use super::*;

    /// The expected residual by brute force: the cap's moments summed over a square grid a
    /// fortieth of the narrower width apart, within 5 widths of the axis.
    pub(crate) fn brute(m: [f64; 2], s: [f64; 2], r: f64) -> f64 {
        let step = s[0].min(s[1]) / 40.0;
        let n = (5.0 * s[0].max(s[1]) / step) as i32;
        let (mut i1, mut i2) = (0.0, 0.0);
        for a in -n..=n {
            for c in -n..=n {
                // The footprint point (along, across) from the axis; the sphere's centre at m.
                let (xa, xc) = (f64::from(a) * step, f64::from(c) * step);
                let h2 = r * r - (xa - m[0]).powi(2) - (xc - m[1]).powi(2);
                if h2 <= 0.0 {
                    continue;
                }
                let g = libm::exp(-0.5 * ((xa / s[0]).powi(2) + (xc / s[1]).powi(2)));
                i1 += g * libm::sqrt(h2);
                i2 += g * h2;
            }
        }
        let h = i2 / i1;
        libm::sqrt(m[0] * m[0] + m[1] * m[1] + h * h) - r
    }

    /// Against the brute-force integral, beams from 3 m to 80 m on spheres of 0.1-0.25 m, the
    /// axis anywhere from the middle to 2.5 widths outside the limb: within 0.7 mm.
    #[test]
    fn the_quadrature_matches_a_brute_force_integral() {
        let mut worst: f64 = 0.0;
        for (range, r) in [(3.0, 0.25), (30.0, 0.25), (80.0, 0.15), (50.0, 0.1)] {
            let s = [0.75e-3 * range, 0.375e-3 * range];
            for k in 0..24 {
                let th = f64::from(k) * 0.27;
                let su = libm::hypot(libm::cos(th) * s[0], libm::sin(th) * s[1]);
                let d = (r + 2.5 * su) * f64::from(k % 8 + 1) / 8.0;
                let m = [d * libm::cos(th), d * libm::sin(th)];
                let (e, b) = (expected(m, s, r), brute(within_reach(m, s, r), s, r));
                worst = worst.max((e - b).abs());
                assert!(
                    (e - b).abs() < 7e-4,
                    "{range} m, r {r}, m {m:?}: {e} vs {b}"
                );
            }
        }
        assert!(worst > 1e-6, "the two rules differ somewhere: {worst}");
    }

    /// The gradient against the brute-force integral's slope (central differences), from the
    /// middle to just inside the reach: within 0.05 (the quadrature across a limb that
    /// cuts the footprint; a row off by that is a weight, not a bias: the residual is within
    /// 0.7 mm).
    #[test]
    fn the_gradient_matches_the_integrals_slope() {
        let (range, r) = (30.0, 0.25);
        let s = [0.75e-3 * range, 0.375e-3 * range];
        for k in 0..40 {
            let th = f64::from(k) * 0.61;
            let su = libm::hypot(libm::cos(th) * s[0], libm::sin(th) * s[1]);
            let d = r + su * (f64::from(k % 10) * 0.5 - 2.8);
            let m = [d * libm::cos(th), d * libm::sin(th)];
            if d - r > (LIMB_REACH - 0.1) * su {
                continue;
            }
            let (_, g) = expected_with_gradient(m, s, r);
            let h = 0.05 * s[1];
            for i in 0..2 {
                let (mut a, mut b) = (m, m);
                a[i] += h;
                b[i] -= h;
                let fb = (brute(a, s, r) - brute(b, s, r)) / (2.0 * h);
                assert!((fb - g[i]).abs() < 0.05, "{m:?} {i}: {fb} vs {}", g[i]);
            }
        }
    }

    #[test]
    fn a_narrow_beam_returns_on_the_surface() {
        let s = [1e-5, 1e-5];
        for m in [[0.0, 0.0], [0.1, 0.05], [0.0, 0.18]] {
            assert!(expected(m, s, 0.2).abs() < 1e-5, "{m:?}");
        }
    }

    #[test]
    fn over_the_middle_the_curvature_puts_it_inside() {
        // e = -(s0^2 + s1^2) / (2 r) to second order at the middle.
        let (s, r) = ([0.02, 0.01], 0.2);
        let e = expected([0.0, 0.0], s, r);
        let want = -(s[0] * s[0] + s[1] * s[1]) / (2.0 * r);
        assert!((e - want).abs() < 0.1 * want.abs(), "{e} vs {want}");
    }

    #[test]
    fn beyond_the_limb_it_blooms_outwards() {
        let (s, r) = ([0.02, 0.01], 0.2);
        // The axis misses by one sigma along the scan: the point is outside.
        let e = expected([r + 0.02, 0.0], s, r);
        assert!(e > 0.01 && e < 0.05, "{e}");
        // Far beyond: held where the sphere's returns end (continuous, not following it).
        let edge = expected([r + 3.0 * s[0], 0.0], s, r);
        assert!(edge > 0.02 && edge < 0.07, "{edge}");
        assert!((expected([r + 0.2, 0.0], s, r) - edge).abs() < 1e-12);
        assert!((expected([r + 3.0 * s[0] + 1e-9, 0.0], s, r) - edge).abs() < 1e-6);
        let (e, g) = expected_with_gradient([r, 0.0], s, r);
        assert!(e > 0.0 && g[0] > 0.0 && g[1].abs() < 1e-6, "{e} {g:?}");
    }
}
#[cfg(test)]
mod sweep {
    /// Across the limb, along or across the scan, the expected residual grows smoothly: its
    /// slope between 0 and 1 (no staircase from quadrature nodes the limb cuts: the 8-point
    /// Gauss-Hermite rule across had slopes up to 5.5 there).
    #[test]
    fn the_limb_profile_is_smooth() {
        let (rr, r) = (30.0, 0.25);
        let s = [0.75e-3 * rr, 0.375e-3 * rr];
        for k in -12..=12 {
            let k = f64::from(k) * 0.25;
            let (_, ga) = super::expected_with_gradient([r + k * s[0], 0.0], s, r);
            let (_, gc) = super::expected_with_gradient([0.0, r + k * s[1]], s, r);
            assert!(ga[0] > -0.05 && ga[0] < 1.0, "{k} along {ga:?}");
            assert!(gc[1] > -0.05 && gc[1] < 1.0, "{k} across {gc:?}");
        }
    }
}

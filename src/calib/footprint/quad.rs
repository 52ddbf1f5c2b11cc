//! The footprint's integrals by quadrature: the hot path's rule where no table applies, and
//! the finer rule the table is made with (this file is also the build script's, which makes
//! the table: `libm` only).

/// Gauss-Legendre nodes and weights on [-1, 1] (8 points).
pub const GL8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];
/// The footprint's reach in the integrals [1-sigma widths]: the Gaussian beyond carries
/// 6e-5 of the energy, less than the quadrature's own error.
pub const WINDOW: f64 = 4.0;
/// 1 / sqrt(2 pi).
pub const INV_SQRT_TAU: f64 = 0.398_942_280_401_432_7;

/// The lit cap's moments `[int G h, int G h^2]` for a sphere of radius `r` whose centre is at
/// `m` (along, across the scan) from the beam's axis in the plane across it, a footprint of
/// 1-sigma widths `s` there [m] (`h` the cap's height over that plane). Across: `y = r sin
/// phi`, along: the chord's `x = l sin psi` (the rim's square roots go into the measure), `pa` x `pb`
/// panels of 8 Gauss-Legendre points over `window` widths. The hot path's 1 x 1 over
/// [`WINDOW`] is within 0.7 mm of a brute-force integral for beams of 3 / 1.5 mrad from 3 to
/// 80 m on spheres of 0.1-0.25 m (test `the_quadrature_matches_a_brute_force_integral`).
pub fn moments_in(m: [f64; 2], s: [f64; 2], r: f64, pa: usize, pb: usize, window: f64) -> [f64; 2] {
    let mut i = [0.0; 2];
    let ylo = (-m[1] - window * s[1]).max(-r) / r;
    let yhi = (-m[1] + window * s[1]).min(r) / r;
    if ylo >= yhi {
        return i;
    }
    let (p0, p1) = (libm::asin(ylo.max(-1.0)), libm::asin(yhi.min(1.0)));
    let phalf = (p1 - p0) * 0.5 / pa as f64;
    for panel in 0..pa {
        let pmid = p0 + phalf * (2 * panel + 1) as f64;
        for (tz, wz) in GL8 {
            let phi = pmid + phalf * tz;
            let (sp, cp) = (libm::sin(phi), libm::cos(phi));
            let zz = (r * sp + m[1]) / s[1];
            let wy = wz * phalf * r * cp * libm::exp(-0.5 * zz * zz) * INV_SQRT_TAU / s[1];
            let l = r * cp;
            if l <= 0.0 {
                continue;
            }
            let lo = (-m[0] - window * s[0]).max(-l) / l;
            let hi = (-m[0] + window * s[0]).min(l) / l;
            if lo >= hi {
                continue;
            }
            let (a, b) = (libm::asin(lo.max(-1.0)), libm::asin(hi.min(1.0)));
            let half = (b - a) * 0.5 / pb as f64;
            let mut j = [0.0; 2];
            for q in 0..pb {
                let mid = a + half * (2 * q + 1) as f64;
                for (t, v) in GL8 {
                    let psi = mid + half * t;
                    let u = (l * libm::sin(psi) + m[0]) / s[0];
                    let h = l * libm::cos(psi);
                    // dx = l cos psi dpsi = h dpsi.
                    let g = v * libm::exp(-0.5 * u * u) * h * h;
                    j[0] += g;
                    j[1] += g * h;
                }
            }
            let k = wy * half * INV_SQRT_TAU / s[0];
            i[0] += k * j[0];
            i[1] += k * j[1];
        }
    }
    i
}

/// How far outside the limb [1-sigma widths of the footprint towards the centre] the model
/// follows the bloom: beyond, `e` is held. Physically returns come from up to ~3 widths out
/// (the lit share then under Phi(-3) = 1.3e-3, a VLP-16's threshold for a white sphere past
/// 12 m), but there `e` grows with the axis's distance at a slope of ~0.9, and a navigation
/// solve with pieces buys residual through it (moving a group of returns outwards explains
/// them): NOTES "Issue 46" session 38 measured 3 / 1.5 / 0.5 widths on the drone (z mean
/// +0.031 / +0.023 / +0.019 m on floating spheres; drone-noisy at 0.5 as without the model)
/// with table1-real within the item at each.
pub const LIMB_REACH: f64 = 0.5;

/// Where a beam's axis passes a sphere of radius `r` whose centre is `m` from it (along,
/// across the scan), for a footprint of widths `s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limb {
    /// The centre's distance from the axis [m].
    pub d: f64,
    /// `sin^2` of that direction's angle from the scan.
    pub w: f64,
    /// The footprint's width in that direction [m].
    pub su: f64,
    /// The axis's distance outside the limb in those widths (negative: inside).
    pub q: f64,
}

impl Limb {
    /// The limb coordinates of `m`.
    pub fn of(m: [f64; 2], s: [f64; 2], r: f64) -> Self {
        let d2 = m[0] * m[0] + m[1] * m[1];
        let d = libm::sqrt(d2);
        let w = if d2 > 0.0 { m[1] * m[1] / d2 } else { 0.0 };
        let su = width(s, w);
        Self {
            d,
            w,
            su,
            q: (d - r) / su,
        }
    }
}

/// `m` held at [`LIMB_REACH`] outside the limb (its direction kept): the expected residual
/// does not follow the bloom farther out.
pub fn within_reach(m: [f64; 2], s: [f64; 2], r: f64) -> [f64; 2] {
    let l = Limb::of(m, s, r);
    if l.q <= LIMB_REACH {
        return m;
    }
    let k = (r + LIMB_REACH * l.su) / l.d;
    [m[0] * k, m[1] * k]
}

/// The expected residual ([`super::expected`]) by the hot path's rule.
pub fn expected_in(m: [f64; 2], s: [f64; 2], r: f64) -> f64 {
    unheld_in(within_reach(m, s, r), s, r, (1, 1, WINDOW))
}

/// The expected residual by the rule `(panels across, panels along, window)`, not held at the
/// reach.
pub fn unheld_in(m: [f64; 2], s: [f64; 2], r: f64, rule: (usize, usize, f64)) -> f64 {
    let i = moments_in(m, s, r, rule.0, rule.1, rule.2);
    let d = libm::hypot(m[0], m[1]);
    if i[0] <= 1e-9 * r * r {
        // Nothing lit between the quadrature's points: the limit of a lit crescent shrinking
        // to the tangent (h -> 0).
        return d - r;
    }
    let h = i[1] / i[0];
    libm::sqrt(d * d + h * h) - r
}

/// The table ([`super::Table`]): its first `q` [widths inside the limb]; below it the cap's
/// rule.
pub const Q_LO: f64 = -6.0;
/// Its step in `q`.
pub const Q_STEP: f64 = 0.125;
/// Points in `q`: `Q_LO` to two steps beyond [`LIMB_REACH`] (the cubic's last interval).
pub const NQ: usize = ((LIMB_REACH - Q_LO) / Q_STEP) as usize + 3;
/// Points in `w = sin^2` of the direction's angle from the scan, 0 to 1.
pub const NW: usize = 9;
/// Points in `sqrt t`, `t` the along-scan width over the radius, from 0 ...
pub const NT: usize = 16;
/// ... to this: a wider footprint reaches the sphere's middle from `Q_LO` (where the table's
/// lines at fixed `q` fold over it), and takes the hot path's quadrature.
pub const T_HI: f64 = 0.16;

/// The footprint's width towards the centre for `w = sin^2` of the direction's angle.
pub fn width(s: [f64; 2], w: f64) -> f64 {
    libm::sqrt(s[0] * s[0] * (1.0 - w) + s[1] * s[1] * w)
}

//! The joint least squares' weights, iteratively reweighted between passes: where each beam
//! meets its sphere ([`Joint::hold`]), whether the footprint's spread at incidence shows
//! ([`spread_share`]), and the white noise's variance factor ([`white_noise_factor`]).

use super::joint::{Joint, Sums};
use super::steps::iterate;
use super::{robust, Piece, Q};

/// Up to four passes of Levenberg-Marquardt at most `max_iter` iterations each, the weights
/// taken again after each (within a pass they stay put): the last pass's sums (at the
/// weights the covariance takes), its iterations and whether it converged.
pub(super) fn passes(
    at: &mut Joint<'_, '_>,
    pieces: &mut [Piece],
    max_iter: usize,
    cluster_ns: i64,
) -> (Sums, usize, bool) {
    let (mut iterations, mut converged) = (0, false);
    let mut sums = at.evaluate(pieces);
    for pass in 0..4 {
        (sums, iterations, converged) = iterate(at, pieces, max_iter);
        // Iteratively reweighted: within a pass the weights stay put; after it they are
        // taken at its solution (where each beam meets its sphere), with the footprint's
        // share (tested after the first two passes) and the white noise's factor its
        // residuals show.
        let share = if pass < 2 {
            spread_share(at, pieces, &sums)
        } else {
            None
        };
        at.hold(pieces);
        let before = at.spread;
        at.spread = share.unwrap_or(before);
        let moved = (at.spread - before).abs() > 0.05 * before.max(0.1);
        // Under white errors the clusters' correlation is the robust covariance's to carry.
        let clusters = if at.model.is_white() { 0 } else { cluster_ns };
        let s2 = white_noise_factor(at, pieces, &sums, clusters);
        if !(s2.is_finite() && s2 > 0.0) || ((s2 - 1.0).abs() < 0.05 && !moved) {
            if at.spread > 0.0 {
                // The sums at the weights (held anew) the covariance takes.
                sums = at.evaluate(pieces);
            }
            break;
        }
        at.factor *= s2;
        if at.spread > 0.0 {
            // One scale cannot tell the two parts apart: with the spread taken at the
            // divergence's (above what the residuals show), the white part's would shrink
            // towards 0 pass by pass (drone-noisy 0.04-0.16), weighing the returns met
            // square on as if noise-free. Held at least the declared.
            at.factor = at.factor.max(1.0);
        }
        sums = at.evaluate(pieces);
    }
    (sums, iterations, converged)
}

/// The white noise's variance factor at the state: the weighted residuals' mean square over
/// their degrees of freedom (the pieces count by what the data, not their priors, fix of them:
/// trace D (D + prior)^-1), times the design effect of returns that share a cluster (one
/// sphere within `cluster_ns`: the beam's footprint and the sphere's cap give neighbours alike
/// errors) `sum_g (sum_k sqrt(w) r)^2 / sum w r^2`, at least 1.
fn white_noise_factor(
    at: &Joint<'_, '_>,
    pieces: &mut [Piece],
    sums: &Sums,
    cluster_ns: i64,
) -> f64 {
    let mut p_eff = (Q + 3 * at.pb.spheres.len()) as f64;
    for (i, p) in pieces.iter().enumerate() {
        let (own, _) = at.chain(pieces, i);
        let mut full = p.d;
        for k in 0..6 {
            full[(k, k)] += own[k];
        }
        if let Some(inv) = full.try_inverse() {
            p_eff += (p.d * inv).trace().clamp(0.0, 6.0);
        }
    }
    let dof = (sums.n as f64 - p_eff).max(1.0);
    let (mut wss, mut clustered, mut cluster_sum) = (0.0, 0.0, 0.0);
    let mut key: Option<(usize, i64)> = None;
    at.each_row(pieces, |_, r| {
        wss += r.w * r.res * r.res;
        let k = r.cluster(cluster_ns);
        if key != Some(k) {
            clustered += cluster_sum * cluster_sum;
            cluster_sum = 0.0;
            key = Some(k);
        }
        cluster_sum += libm::sqrt(r.w) * r.res;
    });
    clustered += cluster_sum * cluster_sum;
    let design = if wss > 0.0 {
        (clustered / wss).max(1.0)
    } else {
        1.0
    };
    wss / dof * design
}

/// Most the footprint's spread at incidence is taken to add: 4x the variance its divergence
/// says (a beam twice as wide).
const MAX_SPREAD_SHARE: f64 = 4.0;
/// The share of the footprint's spread the kept residuals show where the answer spreads by
/// all of it: drone-noisy, weighed with the spread, regresses a `c1` of 0.20-0.35 (median
/// 0.30) over 100 seeds while its calibrations spread as the whole of it says. The
/// extraction keeps, of the grazing returns, those near the answer it extracts around (a
/// survey without an extraction shows 0.9-0.95 of it: `nav::tests`, whose sigmas stay
/// honest weighed at the 3x that then gives).
const SHOWN_SPREAD_SHARE: f64 = 0.3;
/// The least share of the footprint's spread the residuals must show (and 3 of its sigmas)
/// for the spread to be taken.
const MIN_SPREAD_SHARE: f64 = 0.25;

/// Whether the residuals show the footprint's spread at incidence
/// ([`crate::calib::noise::Noise::spread_variance`]), and the share of it the weights
/// then take. A beam's footprint on a surface inclined to it spans `R sigma tan(theta)` in
/// range, so a LiDAR whose range grows so at grazing incidence gives the returns near a
/// sphere's silhouette (those that pin the lever arm across the beams and the time offset)
/// a noise several times that of those that meet it square on; weighed alike, their
/// information is overstated (drone-noisy, 100 seeds: roll and x RMS z 1.32).
///
/// The test: each squared residual over `1 - h` (its leverage, [`robust::with_leverage`]: a
/// piece or a centre follows the grazing returns), less the pieces' wander, regressed on the
/// two variance parts the physics gives, `c0 white cos(theta)^2 + c1 spread` (a range error
/// moves the residual by its radial part), each weighted by its variance's inverse squared (a
/// squared Gaussian's variance is `2 var^2`). A solve starts without the spread; weighed so,
/// the grazing returns pin the most and their residuals fall shortest (drone-noisy c1
/// 0.12-0.46 +- 0.014), so a c1 of 3 sigma has it tried; weighed with it, it is kept where
/// c1 is at least [`MIN_SPREAD_SHARE`] and 3 sigma (drone-noisy, whose LiDAR's range grows
/// so: 0.20-1.3, median 0.30, +- 0.09; table1-real, whose does not: -0.01 to 0.02 +-
/// 0.01-0.07), at `c1` over the share the residuals show of it ([`SHOWN_SPREAD_SHARE`]), at
/// least the beam's divergence and at most [`MAX_SPREAD_SHARE`]: the residuals' own share
/// falls short of what the answer spreads by, and the surveys whose residuals show more of it
/// spread further (drone-noisy over 100 seeds: taken at `c1`, roll and x RMS z 1.20 and 1.29;
/// at 1, 1.06 and 1.21, the 20 seeds whose final `c1` was largest at x RMS z 1.38, z 1.66;
/// at `c1 / 0.3`, 0.99 and 1.15). Else 0. `None` without a declared spread (an ideal ray) or
/// where the two parts cannot be told apart.
fn spread_share(at: &Joint<'_, '_>, pieces: &mut [Piece], sums: &Sums) -> Option<f64> {
    if at.pb.weights.is_none_or(|n| n.spread <= 0.0) {
        return None;
    }
    let h_inv = at.reduced(sums, pieces)?.try_inverse()?;
    at.chain_blocks(pieces);
    let (mut aa, mut ab, mut bb, mut ay, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
    robust::with_leverage(at, pieces, &h_inv, |r, _, hat| {
        let (a, b) = (r.var.radial, r.var.spread);
        let u = r.w * r.w;
        let y = r.res * r.res / (1.0 - hat).max(0.05) - r.var.wander;
        aa += u * a * a;
        ab += u * a * b;
        bb += u * b * b;
        ay += u * a * y;
        by += u * b * y;
    });
    let det = aa * bb - ab * ab;
    if !det.is_finite() || det <= 1e-9 * aa * bb {
        return None;
    }
    let c1 = (aa * by - ab * ay) / det;
    // The regression's own sigma of c1 (a squared residual's variance `2 var^2`).
    let sd = libm::sqrt(2.0 * aa / det);
    Some(if at.spread == 0.0 {
        // Weighed without it (as a solve starts) the grazing returns pin the most and
        // their residuals fall shortest: shown at all (3 sigma), it is tried.
        if c1 >= 3.0 * sd {
            1.0
        } else {
            0.0
        }
    } else if c1 >= MIN_SPREAD_SHARE && c1 >= 3.0 * sd {
        (c1 / SHOWN_SPREAD_SHARE).clamp(1.0, MAX_SPREAD_SHARE)
    } else {
        0.0
    })
}

//! The joint least squares' Levenberg-Marquardt steps and their stopping rules (as
//! [`crate::calib::lm`]'s, over the state of [`super::joint::Joint`]).

use super::joint::{Joint, Sums};
use super::Piece;
use crate::calib::nav::P;

/// Whether the Gauss-Newton step from the state moves the mounting (and the clock) by under
/// half its sigma: its spread grows by at most 12 % in quadrature.
fn half_sigma_step(at: &mut Joint<'_, '_>, sums: &Sums, pieces: &mut [Piece]) -> bool {
    step_within(at, sums, pieces, 0.5)
}

/// Whether the Gauss-Newton step left moves the mounting (and the clock) by under `k` of its
/// sigma.
fn step_within(at: &mut Joint<'_, '_>, sums: &Sums, pieces: &mut [Piece], k: f64) -> bool {
    match (at.step(sums, pieces, 0.0), at.reduced(sums, pieces)) {
        (Some(dz), Some(h)) => h
            .try_inverse()
            .is_some_and(|c| (0..=P).all(|i| dz[i].abs() <= k * libm::sqrt(c[(i, i)].max(0.0)))),
        _ => false,
    }
}

/// A step still lowering the cost by under this share of it is checked against
/// [`SETTLED_SIGMAS`] ...
const SLOW_GAIN: f64 = 1e-6;
/// ... and ends the iterations when the Gauss-Newton step left is within this many sigmas
/// of every global (a thousandth of its variance): the rest is polish no answer shows.
const SETTLED_SIGMAS: f64 = 0.03;

/// Levenberg-Marquardt steps on the joint state (as [`super::lm`]'s): the last sums, the
/// iterations and whether a negligible step or decrease ended them. A rejected step puts the
/// state and its sums back as they were ([`Joint::keep`]), without evaluating again.
pub(super) fn iterate(
    at: &mut Joint<'_, '_>,
    pieces: &mut [Piece],
    max_iter: usize,
) -> (Sums, usize, bool) {
    let mut sums = at.evaluate(pieces);
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut converged = false;
    let mut tried_gn = false;
    while iterations < max_iter {
        iterations += 1;
        let Some(dz) = at.step(&sums, pieces, lambda) else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
            continue;
        };
        // Try the step (the pieces' steps are in their `sigma` scratch).
        let z0 = at.keep(pieces);
        at.apply(&dz, pieces);
        let trial = at.evaluate(pieces);
        if trial.cost <= sums.cost && trial.cost.is_finite() {
            let gain = sums.cost - trial.cost;
            let small = dz.iter().all(|d| d.abs() < 1e-11) || gain <= 1e-12 * sums.cost.max(1e-30);
            sums = trial;
            lambda = (lambda / 10.0).max(1e-12);
            if small
                || (gain <= SLOW_GAIN * sums.cost && step_within(at, &sums, pieces, SETTLED_SIGMAS))
            {
                converged = true;
                break;
            }
        } else {
            at.put_back(z0, pieces);
            lambda *= 10.0;
            if lambda > 1e8 && !tried_gn {
                // Marquardt's steps fail: one undamped Gauss-Newton step before giving up.
                tried_gn = true;
                if let Some(dz) = at.step(&sums, pieces, 0.0) {
                    let z0 = at.keep(pieces);
                    at.apply(&dz, pieces);
                    let trial = at.evaluate(pieces);
                    if trial.cost.is_finite() && trial.cost < sums.cost {
                        sums = trial;
                        lambda = 1e-6;
                        continue;
                    }
                    at.put_back(z0, pieces);
                }
            }
            if lambda > 1e8 {
                // No step lowers the cost (the Jacobian holds the grazing factor and the
                // corrected attitude fixed, so at the minimum the gradient is not quite zero):
                // a minimum if the Gauss-Newton step left moves the mounting (and the clock)
                // by under half its sigma (its spread grows by at most 12 % in quadrature), else a stall.
                converged = half_sigma_step(at, &sums, pieces);
                break;
            }
        }
    }
    if !converged && iterations >= max_iter {
        // Steps still lowering the cost at the cap (a crawl along the pieces' weakly damped
        // directions): a minimum by the same rule.
        converged = half_sigma_step(at, &sums, pieces);
    }
    // Gauss-Newton to the end: the pieces' and centres' directions are nearly linear and
    // weakly damped by their priors alone, where Marquardt's steps crawl.
    if converged {
        for _ in 0..20 {
            let Some(dz) = at.step(&sums, pieces, 0.0) else {
                break;
            };
            let z0 = at.keep(pieces);
            at.apply(&dz, pieces);
            let trial = at.evaluate(pieces);
            if trial.cost.is_finite() && trial.cost <= sums.cost {
                let gain = sums.cost - trial.cost;
                sums = trial;
                iterations += 1;
                if gain <= 1e-9 * sums.cost.max(1e-30) {
                    break;
                }
            } else {
                at.put_back(z0, pieces);
                break;
            }
        }
    }
    (sums, iterations, converged)
}

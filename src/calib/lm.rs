//! Levenberg-Marquardt on the signed distances `||x_k(b) - c_j|| - r_j` with the analytic
//! Jacobian (Marquardt 1963, with the diagonal scaling of the damping), and what the normal
//! matrix says about the answer: covariance `sigma^2 (J^T J)^-1` with
//! `sigma^2 = sum r^2 / (n - 6)`, correlations, and the condition number of the normal matrix
//! scaled to unit diagonal (units cancel, so degrees and metres compare).

use super::objective::Problem;
use super::P;
use nalgebra::{Cholesky, SMatrix, SVector, SymmetricEigen};

/// 6x6.
pub type Mat6 = SMatrix<f64, P, P>;
/// 6-vector.
pub type Vec6 = SVector<f64, P>;

/// What LM found and how well the data determine it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmResult {
    /// Parameters [rad, m].
    pub b: [f64; P],
    /// Iterations taken.
    pub iterations: usize,
    /// Steps became negligible before the cap.
    pub converged: bool,
    /// Observations.
    pub n: usize,
    /// RMS of the residuals [m].
    pub rms: f64,
    /// `J^T J` at the solution.
    pub normal: Mat6,
    /// Covariance of b.
    pub covariance: Mat6,
    /// 1-sigma of each parameter [rad, m].
    pub sigma: [f64; P],
    /// Correlation matrix.
    pub correlation: Mat6,
    /// Condition number of the unit-diagonal normal matrix.
    pub condition: f64,
    /// Eigenvector of the smallest eigenvalue of the scaled normal matrix (which combination
    /// of parameters the data pin down least).
    pub weakest: [f64; P],
}

fn normal_equations(pb: &Problem<'_>, b: &[f64; P]) -> (Mat6, Vec6, f64, usize) {
    let mut jtj = Mat6::zeros();
    let mut jtr = Vec6::zeros();
    let mut cost = 0.0;
    let mut n = 0;
    pb.jacobian(b, |r, row| {
        let j = Vec6::from_column_slice(row);
        jtj += j * j.transpose();
        jtr += j * r;
        cost += r * r;
        n += 1;
    });
    (jtj, jtr, cost, n)
}

/// Refine `b0` by Levenberg-Marquardt, at most `max_iter` iterations.
pub fn refine(pb: &Problem<'_>, b0: &[f64; P], max_iter: usize) -> LmResult {
    let mut b = *b0;
    let (mut jtj, mut jtr, mut cost, mut n) = normal_equations(pb, &b);
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut converged = false;
    while iterations < max_iter {
        iterations += 1;
        let mut a = jtj;
        for i in 0..P {
            a[(i, i)] += lambda * jtj[(i, i)].max(1e-12);
        }
        let Some(ch) = Cholesky::new(a) else {
            lambda *= 10.0;
            continue;
        };
        let delta = ch.solve(&(-jtr));
        let mut trial = b;
        for i in 0..P {
            trial[i] += delta[i];
        }
        let (tj, tr, tc, tn) = normal_equations(pb, &trial);
        if tc <= cost {
            b = trial;
            let small = delta.iter().all(|d| d.abs() < 1e-11) || (cost - tc) <= 1e-15 * cost.max(1e-30);
            (jtj, jtr, cost, n) = (tj, tr, tc, tn);
            lambda = (lambda / 10.0).max(1e-12);
            if small {
                converged = true;
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e12 {
                converged = true;
                break;
            }
        }
    }
    let dof = n.saturating_sub(P).max(1) as f64;
    let s2 = cost / dof;
    let covariance = jtj.try_inverse().map(|m| m * s2).unwrap_or_else(|| Mat6::from_element(f64::INFINITY));
    let mut sigma = [0.0; P];
    for (i, s) in sigma.iter_mut().enumerate() {
        *s = covariance[(i, i)].max(0.0).sqrt();
    }
    let mut correlation = Mat6::zeros();
    for i in 0..P {
        for j in 0..P {
            correlation[(i, j)] = covariance[(i, j)] / (sigma[i] * sigma[j]);
        }
    }
    // Scale the normal matrix to unit diagonal; its eigenvalues give the conditioning.
    let mut scaled = jtj;
    for i in 0..P {
        for j in 0..P {
            scaled[(i, j)] = jtj[(i, j)] / (jtj[(i, i)] * jtj[(j, j)]).sqrt().max(1e-300);
        }
    }
    let eig = SymmetricEigen::new(scaled);
    let (mut lo, mut hi, mut lo_i) = (f64::INFINITY, 0f64, 0);
    for (i, &e) in eig.eigenvalues.iter().enumerate() {
        if e < lo {
            lo = e;
            lo_i = i;
        }
        hi = hi.max(e);
    }
    let condition = if lo > 0.0 { hi / lo } else { f64::INFINITY };
    let mut weakest = [0.0; P];
    for (i, w) in weakest.iter_mut().enumerate() {
        *w = eig.eigenvectors[(i, lo_i)];
    }
    LmResult { b, iterations, converged, n, rms: (cost / n.max(1) as f64).sqrt(), normal: jtj, covariance, sigma, correlation, condition, weakest }
}

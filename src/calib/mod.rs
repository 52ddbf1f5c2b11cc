//! Calibration: the six installation parameters b = [roll, pitch, heading, ax, ay, az] from
//! the sphere windows.
//!
//! - [`objective`]: eq. 6, `sum_j sum_k | ||x_k(b) - c_j|| - r_j |` (L1), and the signed
//!   residuals with their analytic Jacobian.
//! - [`nelder_mead`]: fixed-iteration Nelder-Mead (Lagarias et al. 1998, as MATLAB's
//!   fminsearch) on static arrays, with restarts from the best vertex.
//! - [`lm`]: Levenberg-Marquardt on the signed distances, covariance `sigma^2 (J^T J)^-1`,
//!   correlations and the condition number.
//! - [`sphere_fit`]: each sphere's centre fitted (fixed radius) with the calibrated values.
//! - [`solve`]: all of it with re-windowing and the quality checks that refuse to claim a
//!   solution the data cannot support.

pub mod consensus;
pub mod extract;
pub mod footprint;
pub mod fork;
pub(crate) mod histogram;
pub mod lm;
pub mod nav;
pub mod nelder_mead;
pub mod noise;
pub mod objective;
pub mod predict;
pub mod room;
pub mod solve;
pub mod sphere_fit;

pub use objective::Problem;
pub use solve::{solve, Refusal, Settings, Solution, Termination};

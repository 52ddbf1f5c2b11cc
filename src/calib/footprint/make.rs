//! The table's entries (`build.rs` only: this file is compiled into the build script beside
//! `quad.rs`, not into the core).

use crate::quad::{unheld_in, width, NT, NW, Q_LO, Q_STEP, T_HI};

/// The table's first `t` (where it is 0).
const T_MIN: f64 = 1e-4;
/// The rule the table is made with: 6 panels across, 3 along, over 6 widths (the table,
/// interpolated, is within 0.1 mm of a brute-force integral: test
/// `the_table_follows_the_integral`).
const TABLE_RULE: (usize, usize, f64) = (6, 3, 6.0);

/// The table's `t` at index `it`.
fn t_at(it: usize) -> f64 {
    let x = it as f64 / (NT - 1) as f64;
    (x * x * T_HI).max(T_MIN)
}

/// The table's entry `(it, iw, iq)` for footprints of widths `(t, kappa t)` on a unit sphere:
/// `e / sigma_u`.
pub fn table_entry(kappa: f64, it: usize, iw: usize, iq: usize) -> f32 {
    let t = t_at(it);
    let s = [t, kappa * t];
    let w = iw as f64 / (NW - 1) as f64;
    let su = width(s, w);
    let d = 1.0 + (Q_LO + Q_STEP * iq as f64) * su;
    let m = [d * libm::sqrt(1.0 - w), d * libm::sqrt(w)];
    (unheld_in(m, s, 1.0, TABLE_RULE) / su) as f32
}

//! Nelder-Mead on `N` parameters with static arrays and bounded work: the algorithm of Lagarias,
//! Reeds, Wright and Wright (1998) as MATLAB's fminsearch runs it (reflection 1, expansion 2,
//! contraction 1/2, shrink 1/2; stop when every vertex is within `tol_x` of the best in every
//! coordinate and every value within `tol_f`), with an iteration cap and a fixed number of
//! restarts from the best vertex. The caller scales the coordinates (degrees and metres here)
//! and gives the initial step per coordinate, so a 180 deg roll does not get a 9 deg step.

/// Settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NmSettings {
    /// Iteration cap per start.
    pub max_iter: usize,
    /// Coordinate tolerance (the caller's units).
    pub tol_x: f64,
    /// Function-value tolerance.
    pub tol_f: f64,
    /// Restarts from the best vertex after convergence.
    pub restarts: usize,
}

impl Default for NmSettings {
    fn default() -> Self {
        // The paper's tolerance: 1e-4 (m for the objective and the lever, deg for the angles).
        Self {
            max_iter: 2000,
            tol_x: 1e-4,
            tol_f: 1e-4,
            restarts: 1,
        }
    }
}

/// The outcome.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NmResult<const N: usize> {
    /// The best vertex.
    pub x: [f64; N],
    /// Its value.
    pub f: f64,
    /// Iterations, all starts.
    pub iterations: usize,
    /// Function evaluations.
    pub evaluations: usize,
    /// The last start met the tolerances (not the cap).
    pub converged: bool,
}

fn combine<const N: usize>(a: &[f64; N], b: &[f64; N], t: f64) -> [f64; N] {
    // a + t (b - a)
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = a[i] + t * (b[i] - a[i]);
    }
    out
}

/// Minimise `f` from `x0` with the initial simplex `x0 + step_i e_i`. `M` must be `N + 1`.
pub fn minimize<const N: usize, const M: usize>(
    mut f: impl FnMut(&[f64; N]) -> f64,
    x0: &[f64; N],
    step: &[f64; N],
    s: &NmSettings,
) -> NmResult<N> {
    let mut evals = 0usize;
    let mut eval = |x: &[f64; N], evals: &mut usize| {
        *evals += 1;
        let v = f(x);
        if v.is_nan() {
            f64::INFINITY
        } else {
            v
        }
    };
    let mut best = *x0;
    let mut best_f = eval(&best, &mut evals);
    let mut iterations = 0;
    let mut converged = false;
    for _start in 0..=s.restarts {
        // Simplex: x0 and x0 + step_i e_i.
        let mut v = [[0.0; N]; M];
        let mut fv = [0.0; M];
        v[0] = best;
        fv[0] = best_f;
        for i in 1..M.min(N + 1) {
            v[i] = best;
            v[i][i - 1] += step[i - 1];
            fv[i] = eval(&v[i], &mut evals);
        }
        converged = false;
        let mut it = 0;
        while it < s.max_iter {
            // Order by value (insertion sort: M is small).
            for i in 1..M {
                let mut j = i;
                while j > 0 && fv[j] < fv[j - 1] {
                    fv.swap(j, j - 1);
                    v.swap(j, j - 1);
                    j -= 1;
                }
            }
            let spread_f = fv.iter().fold(0f64, |m, &x| m.max((x - fv[0]).abs()));
            let spread_x = v.iter().skip(1).fold(0f64, |m, x| {
                x.iter()
                    .zip(&v[0])
                    .fold(m, |m, (a, b)| m.max((a - b).abs()))
            });
            if spread_f <= s.tol_f && spread_x <= s.tol_x {
                converged = true;
                break;
            }
            it += 1;
            // Centroid of all but the worst.
            let mut c = [0.0; N];
            for x in v.iter().take(M - 1) {
                for k in 0..N {
                    c[k] += x[k] / (M - 1) as f64;
                }
            }
            let worst = M - 1;
            let xr = combine(&c, &v[worst], -1.0);
            let fr = eval(&xr, &mut evals);
            if fr < fv[0] {
                let xe = combine(&c, &v[worst], -2.0);
                let fe = eval(&xe, &mut evals);
                if fe < fr {
                    (v[worst], fv[worst]) = (xe, fe);
                } else {
                    (v[worst], fv[worst]) = (xr, fr);
                }
                continue;
            }
            if fr < fv[worst - 1] {
                (v[worst], fv[worst]) = (xr, fr);
                continue;
            }
            let shrink = if fr < fv[worst] {
                let xc = combine(&c, &xr, 0.5);
                let fc = eval(&xc, &mut evals);
                if fc <= fr {
                    (v[worst], fv[worst]) = (xc, fc);
                    false
                } else {
                    true
                }
            } else {
                let xcc = combine(&c, &v[worst], 0.5);
                let fcc = eval(&xcc, &mut evals);
                if fcc < fv[worst] {
                    (v[worst], fv[worst]) = (xcc, fcc);
                    false
                } else {
                    true
                }
            };
            if shrink {
                for i in 1..M {
                    v[i] = combine(&v[0], &v[i], 0.5);
                    fv[i] = eval(&v[i], &mut evals);
                }
            }
        }
        iterations += it;
        let (i, &fb) =
            fv.iter().enumerate().fold(
                (0, &f64::INFINITY),
                |a, (i, x)| if x < a.1 { (i, x) } else { a },
            );
        let improved = fb < best_f;
        if fb <= best_f {
            best = v[i];
            best_f = fb;
        }
        if !improved && converged {
            break;
        }
    }
    NmResult {
        x: best,
        f: best_f,
        iterations,
        evaluations: evals,
        converged,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rosenbrock() {
        // Minimum 0 at (1, 1) (Rosenbrock 1960); the classic start (-1.2, 1).
        let f = |x: &[f64; 2]| 100.0 * (x[1] - x[0] * x[0]).powi(2) + (1.0 - x[0]).powi(2);
        let s = NmSettings {
            max_iter: 5000,
            tol_x: 1e-10,
            tol_f: 1e-14,
            restarts: 2,
        };
        let r = minimize::<2, 3>(f, &[-1.2, 1.0], &[0.1, 0.1], &s);
        assert!(r.converged);
        assert!(
            (r.x[0] - 1.0).abs() < 1e-6 && (r.x[1] - 1.0).abs() < 1e-6,
            "{:?}",
            r
        );
        assert!(r.f < 1e-12);
    }

    #[test]
    fn quadratic_with_known_minimum_in_six_dimensions() {
        // f = sum w_i (x_i - m_i)^2 + a cross term; minimum 0 at m.
        let m = [179.5, -44.9, 1.2, 1.5, -1.24, -1.36];
        let w = [1.0, 2.0, 0.5, 40.0, 60.0, 30.0];
        let f = |x: &[f64; 6]| {
            let mut s = 0.0;
            for i in 0..6 {
                s += w[i] * (x[i] - m[i]).powi(2);
            }
            s + 0.3 * (x[0] - m[0]) * (x[3] - m[3])
        };
        let s = NmSettings {
            max_iter: 20_000,
            tol_x: 1e-9,
            tol_f: 1e-16,
            restarts: 3,
        };
        let r = minimize::<6, 7>(
            f,
            &[181.787, -42.423, 2.431, 1.312, -1.205, -1.759],
            &[1.0, 1.0, 1.0, 0.1, 0.1, 0.1],
            &s,
        );
        for (i, (x, want)) in r.x.iter().zip(&m).enumerate() {
            assert!((x - want).abs() < 1e-6, "{i}: {:?}", r.x);
        }
    }

    #[test]
    fn bounded_work_and_nan_safe() {
        let s = NmSettings {
            max_iter: 10,
            restarts: 0,
            ..NmSettings::default()
        };
        let r = minimize::<2, 3>(
            |x| {
                if x[0] > 3.5 {
                    f64::NAN
                } else {
                    x[0] * x[0] + x[1] * x[1]
                }
            },
            &[3.0, 3.0],
            &[1.0, 1.0],
            &s,
        );
        assert!(r.iterations <= 10 && !r.converged);
        assert!(r.f.is_finite());
    }
}

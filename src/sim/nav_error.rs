//! Navigation errors that wander: a GNSS/INS solution's position and attitude errors are
//! correlated over tens of seconds (the Kalman filter follows GNSS errors that change with the
//! satellite geometry, multipath and the atmosphere), not white per output sample. Each axis is
//! a first-order Gauss-Markov process (Gelb, *Applied Optimal Estimation*, 1974, table 3.4-1;
//! Brown & Hwang, *Introduction to Random Signals and Applied Kalman Filtering*, 4th ed.,
//! sec. 2.9): `x(k+1) = phi x(k) + sqrt(1 - phi^2) sigma w(k)`, `phi = exp(-dt / tau)`,
//! autocorrelation `sigma^2 exp(-|lag| / tau)`, started in its stationary distribution.
//! The attitude's processes are the navigation frame's misalignment about north, east and down
//! (an INS's tilt and heading errors, the psi angles of its error model: Titterton & Weston,
//! *Strapdown Inertial Navigation Technology*, 2nd ed., sec. 12.3): they stay put in the level
//! frame while the vessel turns, so its roll and pitch errors trade places with the heading.

use super::rng::Rng;

/// The correlated part of an INS's errors, per axis, 1 sigma.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Correlated {
    /// Position: horizontal (north and east each), vertical (down) [m].
    pub position_sigma: [f64; 2],
    /// Attitude: roll and pitch (each), heading [rad].
    pub attitude_sigma: [f64; 2],
    /// Correlation time `tau` [s]; 0 with every sigma 0: no correlated error.
    pub correlation_s: f64,
}

impl Correlated {
    /// Whether it adds anything.
    pub fn is_on(&self) -> bool {
        self.correlation_s > 0.0
            && self
                .position_sigma
                .iter()
                .chain(&self.attitude_sigma)
                .any(|s| *s > 0.0)
    }

    /// Per axis sigma of the processes: north, east, down [m]; the misalignment about north,
    /// east (roll and pitch's sigma) and down (heading's) [rad].
    pub fn sigmas(&self) -> [f64; 6] {
        let [h, v] = self.position_sigma;
        let [rp, hd] = self.attitude_sigma;
        [h, h, v, rp, rp, hd]
    }
}

/// One sample of the navigation error: position north, east, down [m] (the reported position
/// minus the true one) and roll, pitch, heading [rad] (reported minus true; from
/// [`GaussMarkov::step`]: the misalignment about north, east, down, which the INS turns into
/// those).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NavError(pub [f64; 6]);

/// The six Gauss-Markov processes, stepped once per INS output sample.
#[derive(Debug, Clone)]
pub struct GaussMarkov {
    sigma: [f64; 6],
    phi: f64,
    drive: f64,
    x: [f64; 6],
    rng: Rng,
}

impl GaussMarkov {
    /// The process for samples `dt_s` apart, its first value drawn from the stationary
    /// distribution (its own random stream, `seed`: the white noise of other streams is the same
    /// with and without it).
    pub fn new(c: &Correlated, dt_s: f64, seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        let sigma = if c.is_on() { c.sigmas() } else { [0.0; 6] };
        let phi = if c.correlation_s > 0.0 {
            libm::exp(-dt_s.max(0.0) / c.correlation_s)
        } else {
            0.0
        };
        let x = core::array::from_fn(|i| rng.gauss(sigma[i]));
        Self {
            sigma,
            phi,
            drive: libm::sqrt((1.0 - phi * phi).max(0.0)),
            x,
            rng,
        }
    }

    /// The current error, then one step on.
    pub fn step(&mut self) -> NavError {
        let now = NavError(self.x);
        for i in 0..6 {
            if self.sigma[i] > 0.0 {
                self.x[i] = self.phi * self.x[i] + self.drive * self.rng.gauss(self.sigma[i]);
            }
        }
        now
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(tau: f64) -> Correlated {
        Correlated {
            position_sigma: [0.03, 0.06],
            attitude_sigma: [0.01f64.to_radians(), 0.02f64.to_radians()],
            correlation_s: tau,
        }
    }

    /// Off: zero errors, nothing drawn.
    #[test]
    fn off_is_zero() {
        let mut g = GaussMarkov::new(&Correlated::default(), 0.005, 1);
        assert!(!Correlated::default().is_on());
        for _ in 0..10 {
            assert_eq!(g.step(), NavError::default());
        }
        let no_tau = Correlated {
            correlation_s: 0.0,
            ..c(1.0)
        };
        assert!(!no_tau.is_on());
    }

    /// Over many independent runs: the variance is sigma^2 at the start and 30 s on
    /// (stationary), and the correlation of samples tau apart is exp(-1) = 0.368, 3 tau apart
    /// exp(-3) = 0.050 (Monte Carlo, 4,000 runs: the sample correlation's sd is ~0.015).
    #[test]
    fn stationary_with_the_exponential_autocorrelation() {
        let (tau, dt, runs) = (10.0, 0.05, 4_000);
        let cf = c(tau);
        let s = cf.sigmas();
        let lags = [0usize, (tau / dt) as usize, (3.0 * tau / dt) as usize];
        // Per axis: sums of x0^2, x(lag)^2 and x0 x(lag).
        let mut acc = [[[0.0f64; 3]; 3]; 6];
        for r in 0..runs {
            let mut g = GaussMarkov::new(&cf, dt, 1_000 + r);
            let x0 = g.step().0;
            let mut k = 0;
            for (li, &lag) in lags.iter().enumerate() {
                let mut x = x0;
                while k < lag {
                    x = g.step().0;
                    k += 1;
                }
                for a in 0..6 {
                    acc[a][li][0] += x0[a] * x0[a];
                    acc[a][li][1] += x[a] * x[a];
                    acc[a][li][2] += x0[a] * x[a];
                }
            }
        }
        for a in 0..6 {
            for (li, want) in [1.0, (-1.0f64).exp(), (-3.0f64).exp()].iter().enumerate() {
                let [s00, sll, s0l] = acc[a][li];
                let n = runs as f64;
                // The variance at both ends: sigma^2 within 6 % (sd of a variance ~2.2 %).
                for v in [s00 / n, sll / n] {
                    let ratio = v / (s[a] * s[a]);
                    assert!((0.94..1.06).contains(&ratio), "axis {a} lag {li}: {ratio}");
                }
                let rho = s0l / (s00 * sll).sqrt();
                assert!(
                    (rho - want).abs() < 0.05,
                    "axis {a} lag {li}: {rho} vs {want}"
                );
            }
        }
    }

    /// Samples 5 ms apart at tau = 15 s hardly move: one step changes the error by
    /// sigma sqrt(2 dt / tau) ~ 2.6 % of sigma.
    #[test]
    fn wanders_slowly() {
        let mut g = GaussMarkov::new(&c(15.0), 0.005, 7);
        let mut prev = g.step().0;
        let mut worst = 0.0f64;
        for _ in 0..2_000 {
            let x = g.step().0;
            worst = worst.max((x[0] - prev[0]).abs() / 0.03);
            prev = x;
        }
        assert!(worst < 0.15 && worst > 0.02, "{worst}");
    }
}

//! The noise model of a residual: what its variance is made of (the range, the INS, the
//! quantisation, the footprint's spread at incidence), and the least squares' weights.

use crate::align::window::Observation;

/// The noise model of one residual (1 sigma): the sensor's range noise, the INS attitude noise
/// times the range, the INS position noise and the 2 mm range quantisation, added in variance.
/// An observation's own INS sigmas ([`Observation::ins_sigma`], from the trajectory's accuracy
/// file) replace the model's where given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Range noise [m].
    pub range: f64,
    /// INS attitude noise [rad].
    pub attitude: f64,
    /// INS position noise [m].
    pub position: f64,
    /// The beam's 1-sigma half-angle along the scan whose footprint spreads the range over
    /// an inclined surface [rad] (0: none): at incidence `theta` the range noise grows by
    /// `R spread tan(theta)`, whose radial part adds `(R spread sin(theta))^2` to a
    /// residual's variance ([`Self::spread_variance`]; [`crate::calib::predict`]).
    pub spread: f64,
}

impl Noise {
    /// The residual variance the model predicts for `o` [m^2].
    #[inline]
    pub fn variance(&self, o: &Observation) -> f64 {
        let [pos, att] = o.ins_sigma;
        let own = |s: f32, model: f64| if s > 0.0 { f64::from(s) } else { model };
        self.at(
            f64::from(o.range),
            own(pos, self.position),
            own(att, self.attitude),
        )
    }

    /// The variance at range `r` with INS sigmas `pos` [m] and `att` [rad].
    #[inline]
    fn at(&self, r: f64, pos: f64, att: f64) -> f64 {
        self.range * self.range + (r * att) * (r * att) + pos * pos + 0.002 * 0.002 / 12.0
    }

    /// The variance of `o`'s residual, its grazing factor `1 - (u.n)^2` given: the range
    /// noise and quantisation by their radial part `cos(theta)^2` (a range error `e` moves
    /// the residual by `e cos(theta)`), the INS's whole (it moves the point across the beam
    /// too) [m^2]. Without the footprint's spread ([`Self::spread_variance`]).
    #[inline]
    pub fn radial_variance(&self, o: &Observation, grazing: f64) -> f64 {
        // Less the range's part (`at(0, 0, 0)`) off the radial.
        self.variance(o) - self.at(0.0, 0.0, 0.0) * grazing.clamp(0.0, 1.0)
    }

    /// The same noise with the footprint's spread's variance `share` times this one's.
    pub fn with_spread_share(self, share: f64) -> Self {
        Self {
            spread: self.spread * libm::sqrt(share.max(0.0)),
            ..self
        }
    }

    /// What the footprint's spread at incidence adds to `o`'s residual variance, its
    /// grazing factor `1 - (u.n)^2` = `sin(theta)^2` given [m^2].
    #[inline]
    pub fn spread_variance(&self, o: &Observation, grazing: f64) -> f64 {
        let s = f64::from(o.range) * self.spread;
        s * s * grazing.clamp(0.0, 1.0)
    }

    /// How much noisier `o` is than the model alone says: the square root of its variance over
    /// the model's at its range, at least 1 (1 without its own INS sigmas).
    #[inline]
    pub fn inflation(&self, o: &Observation) -> f64 {
        let own = self.variance(o);
        let model = self.at(f64::from(o.range), self.position, self.attitude);
        libm::sqrt(own / model.max(1e-12)).max(1.0)
    }

    /// The least-squares weight of `o`: (1 cm)^2 over its variance (the scale cancels in the
    /// estimate and its covariance; 1 cm keeps the weights near 1).
    #[inline]
    pub fn weight(&self, o: &Observation) -> f64 {
        1e-4 / self.variance(o).max(1e-12)
    }
}

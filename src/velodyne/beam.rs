//! One laser's geometry ([`Beam`]): its elevation, azimuth offset and vertical offset from the
//! manuals' tables ([`super::tables`]) with their sines and cosines, computed once.

/// One laser's geometry: the manual's values and their trigonometry (f64; the decoder casts).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beam {
    /// Elevation angle w [deg], positive up.
    pub elevation_deg: f64,
    /// Azimuth offset [deg] added to the interpolated azimuth (clockwise, as the azimuth).
    pub azimuth_offset_deg: f64,
    /// Vertical beam-origin offset [m] added to z.
    pub vertical_offset_m: f64,
    /// cos w.
    pub cos_el: f64,
    /// sin w.
    pub sin_el: f64,
    /// cos of the azimuth offset.
    pub cos_az: f64,
    /// sin of the azimuth offset.
    pub sin_az: f64,
}

impl Beam {
    /// The azimuth offset [rad].
    #[inline]
    pub fn azimuth_offset_rad(&self) -> f64 {
        self.azimuth_offset_deg.to_radians()
    }
}

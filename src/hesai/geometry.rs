//! The unit's angle corrections and a return's point in the sensor frame (PandarXT-32 manual,
//! appendix "Angle Correction"; the same for the QT):
//!
//! ```text
//! azimuth   = block azimuth + the channel's azimuth offset   (clockwise from +y, seen from above)
//! elevation = the channel's elevation
//! p = d (cos(el) sin(az), cos(el) cos(az), sin(el))
//! ```
//!
//! The sensor frame is the Velodyne's (x right, y forward, z up). The block's sine and cosine
//! are computed once per block and each channel's offset is added by the angle-sum identities
//! from tables: no trigonometry per return.

/// Most channels a model read here has.
pub const MAX_CHANNELS: usize = 128;

/// A unit's angle corrections: per channel the elevation and the azimuth offset [deg] and
/// their sines and cosines.
#[derive(Debug, Clone)]
pub struct Corrections {
    channels: usize,
    el_deg: [f64; MAX_CHANNELS],
    az_deg: [f64; MAX_CHANNELS],
    el_cos: [f64; MAX_CHANNELS],
    el_sin: [f64; MAX_CHANNELS],
    az_cos: [f64; MAX_CHANNELS],
    az_sin: [f64; MAX_CHANNELS],
}

impl Corrections {
    /// From the correction file's columns (one row per channel, 1 to [`MAX_CHANNELS`], as
    /// long as each other); `None` when they are not (lengths, non-finite or beyond +-90 deg
    /// elevation, +-180 deg azimuth).
    pub fn new(elevation_deg: &[f64], azimuth_deg: &[f64]) -> Option<Self> {
        let channels = elevation_deg.len();
        if channels == 0 || channels > MAX_CHANNELS || azimuth_deg.len() != channels {
            return None;
        }
        let ok = elevation_deg
            .iter()
            .all(|e| e.is_finite() && e.abs() <= 90.0)
            && azimuth_deg
                .iter()
                .all(|a| a.is_finite() && a.abs() <= 180.0);
        if !ok {
            return None;
        }
        let mut c = Self {
            channels,
            el_deg: [0.0; MAX_CHANNELS],
            az_deg: [0.0; MAX_CHANNELS],
            el_cos: [0.0; MAX_CHANNELS],
            el_sin: [0.0; MAX_CHANNELS],
            az_cos: [0.0; MAX_CHANNELS],
            az_sin: [0.0; MAX_CHANNELS],
        };
        for i in 0..channels {
            (c.el_deg[i], c.az_deg[i]) = (elevation_deg[i], azimuth_deg[i]);
            (c.el_sin[i], c.el_cos[i]) = libm::sincos(elevation_deg[i].to_radians());
            (c.az_sin[i], c.az_cos[i]) = libm::sincos(azimuth_deg[i].to_radians());
        }
        Some(c)
    }

    /// Channels corrected.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The geometry of a block at azimuth `centideg` [0.01 deg].
    pub fn block(&self, centideg: u16) -> BlockGeometry<'_> {
        let deg = f64::from(centideg) * 0.01;
        let (sin, cos) = libm::sincos(deg.to_radians());
        BlockGeometry {
            c: self,
            deg,
            sin,
            cos,
        }
    }
}

/// One block's azimuth with the corrections: the point of each channel's return.
#[derive(Debug, Clone, Copy)]
pub struct BlockGeometry<'a> {
    c: &'a Corrections,
    deg: f64,
    sin: f64,
    cos: f64,
}

impl BlockGeometry<'_> {
    /// Channel `ch`'s return at `distance_m` in the sensor frame [m] (a channel beyond the
    /// corrections' is taken modulo them).
    #[inline]
    pub fn xyz(&self, ch: usize, distance_m: f64) -> [f64; 3] {
        let c = self.c;
        let i = ch % c.channels;
        let sin_az = self.sin * c.az_cos[i] + self.cos * c.az_sin[i];
        let cos_az = self.cos * c.az_cos[i] - self.sin * c.az_sin[i];
        let xy = distance_m * c.el_cos[i];
        [xy * sin_az, xy * cos_az, distance_m * c.el_sin[i]]
    }

    /// Channel `ch`'s corrected azimuth [deg, 0..360) and elevation [deg] (for listings).
    pub fn angles_deg(&self, ch: usize) -> (f64, f64) {
        let i = ch % self.c.channels;
        let a = self.deg + self.c.az_deg[i];
        let az = a - 360.0 * libm::floor(a / 360.0);
        (az, self.c.el_deg[i])
    }
}

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

    /// The time between two firings of one channel of the model with this many channels
    /// [ns] ([`super::Model::laser_period_ns`]; `None` for a count no model has).
    pub fn laser_period_ns(&self) -> Option<i64> {
        super::Model::of_channels(self.channels).map(|m| i64::from(m.laser_period_ns()))
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

/// The returns of `p` as points of the Velodyne decoder's kind (sensor frame, its axes;
/// `offset_ns` after the packet's first firing; `laser` and `channel` the Hesai channel) into
/// `out`: what georeferencing takes from any LiDAR. Returns that first firing's time after the
/// packet's absolute time [ns] (negative: before it). A dual firing's return identical to its
/// other block's is put once (the later block's); a channel the corrections lack is skipped.
pub fn points<T: AsRef<[u8]>>(
    p: &super::DataPacket<T>,
    c: &Corrections,
    out: &mut crate::velodyne::PointBuf,
) -> i64 {
    use crate::velodyne::{Point, Return};
    out.clear();
    let model = p.model();
    let n = p.return_mode().returns();
    let mut first = i64::MAX;
    for b in 0..model.blocks() {
        for ch in 0..model.channels() {
            first = first.min(p.firing_offset_ns(b, ch));
        }
    }
    let unit_m = f64::from(p.distance_unit_mm()) * 1e-3;
    let single = match p.return_mode() {
        super::ReturnMode::Single(0x38) => Return::Last,
        _ => Return::Strongest,
    };
    for b in 0..model.blocks() {
        let geo = c.block(p.azimuth(b));
        for ch in 0..model.channels().min(c.channels()) {
            let (dist, refl) = p.unit(b, ch);
            if dist == 0 || (n == 2 && b % 2 == 0 && p.unit(b + 1, ch) == (dist, refl)) {
                continue;
            }
            let range = f64::from(dist) * unit_m;
            let [x, y, z] = geo.xyz(ch, range);
            let (az, _) = geo.angles_deg(ch);
            let ret = match (n, b % 2) {
                (1, _) => single,
                (_, 0) => Return::DualLast,
                _ => Return::DualStrongest,
            };
            let offset = p.firing_offset_ns(b, ch) - first;
            let _ = out.push(Point {
                x: x as f32,
                y: y as f32,
                z: z as f32,
                azimuth: az.to_radians() as f32,
                offset_ns: u32::try_from(offset).unwrap_or(u32::MAX),
                distance_raw: dist,
                range: range as f32,
                intensity: refl,
                block: b as u8,
                channel: ch as u8,
                laser: ch as u8,
                ret,
            });
        }
    }
    first
}

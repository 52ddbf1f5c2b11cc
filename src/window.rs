//! Sphere windows: georeference each return with the a-priori mounting, keep those within
//! radius + margin of a surveyed centre, and store for each what the solver needs to
//! georeference it again for any boresight and lever arm: the return in the LiDAR frame
//! `q_l = d u_l + v_k e_z` (eq. 1 and the beam offset) and the platform pose (eqs. 2-3).
//!
//! The pose is interpolated once per firing sequence (16 firings, 34.6 us) and carried to each
//! firing with the INS velocity and angular rate (first order). Holding the attitude over a
//! sequence instead would cost up to 6.6e-5 rad (2 mm at 33 m) in a 1.9 rad/s turn: measured
//! on table1's turns, see tests/georef.rs.

use crate::align::{AlignError, Motion, PoseHistory};
use crate::georef::{Mount, PlatformPose};
use crate::time::GpsTime;
use crate::vlp16::{
    Point, PointBuf, COS_ELEVATION_F64, LASERS, SIN_ELEVATION_F64, VERTICAL_OFFSET_M,
};
use nalgebra::{Matrix3, Vector3};

/// Most targets the core handles.
pub const MAX_TARGETS: usize = 16;

/// A surveyed sphere in the site frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Centre, site NED [m].
    pub center: Vector3<f64>,
    /// Radius [m].
    pub radius: f64,
}

/// One windowed return: everything eq. 3 needs for any mounting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// The return in the LiDAR frame: `d u_l + v_k e_z` [m].
    pub q_l: Vector3<f64>,
    /// `P_g` at the firing time [m].
    pub position: Vector3<f64>,
    /// `R_ig` at the firing time.
    pub r_ig: Matrix3<f64>,
    /// Firing time.
    pub time: GpsTime,
    /// Range [m].
    pub range: f32,
    /// Laser id.
    pub laser: u8,
}

impl Observation {
    /// Eq. 3 for a mounting.
    #[inline]
    pub fn georef(&self, mount: &Mount) -> Vector3<f64> {
        self.position + self.r_ig * (mount.lever + mount.r_li * self.q_l)
    }
}

/// A fixed-capacity batch of observations of one sphere.
#[derive(Debug, Clone)]
pub struct Batch<const CAP: usize> {
    /// The observations.
    pub obs: heapless::Vec<Observation, CAP>,
    /// Returns that fell in the window after the batch was full.
    pub overflow: u64,
}

impl<const CAP: usize> Default for Batch<CAP> {
    fn default() -> Self {
        Self {
            obs: heapless::Vec::new(),
            overflow: 0,
        }
    }
}

/// Counts of the windowing stage.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WindowStats {
    /// Returns seen.
    pub points: u64,
    /// Returns georeferenced.
    pub georeferenced: u64,
    /// Returns before the pose history.
    pub before_history: u64,
    /// Returns after the pose history.
    pub after_history: u64,
    /// Returns in an INS gap.
    pub in_gap: u64,
    /// Returns kept, per target.
    pub windowed: [u64; MAX_TARGETS],
}

/// A georeferenced return, handed to the caller (for LAS output).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoPoint {
    /// Site NED [m].
    pub ned: Vector3<f64>,
    /// Firing time.
    pub time: GpsTime,
    /// Intensity.
    pub intensity: u8,
    /// Laser id.
    pub laser: u8,
    /// Which window it fell in.
    pub window: Option<u8>,
}

/// The sphere whose window (radius + margin) contains `x`, the nearest if several.
#[inline]
pub fn which_window(targets: &[Target], margin: f64, x: &Vector3<f64>) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (i, t) in targets.iter().enumerate() {
        let d2 = (x - t.center).norm_squared();
        let lim = t.radius + margin;
        if d2 <= lim * lim && best.is_none_or(|(_, b)| d2 < b) {
            best = Some((i, d2));
        }
    }
    best.map(|(i, _)| i)
}

/// The return of a decoded point in the LiDAR frame, f64 (eq. 1 + beam offset), from the raw
/// range and the decoded azimuth.
#[inline]
pub fn q_of(p: &Point) -> Vector3<f64> {
    let l = p.laser() % LASERS;
    let d = f64::from(p.distance_raw) * 0.002;
    let (s, c) = libm::sincos(f64::from(p.azimuth));
    let cw = COS_ELEVATION_F64[l] * d;
    Vector3::new(
        cw * s,
        cw * c,
        SIN_ELEVATION_F64[l] * d + VERTICAL_OFFSET_M[l],
    )
}

/// The windowing stage: georeference with the a-priori mounting and fill the batches.
#[derive(Debug)]
pub struct Windowing<'a, const CAP: usize> {
    /// The spheres.
    pub targets: &'a [Target],
    /// Window margin beyond the radius [m].
    pub margin: f64,
    /// The mounting used to georeference (a-priori, or an improved one).
    pub mount: Mount,
    /// One batch per target.
    pub batches: &'a mut [Batch<CAP>],
    /// Counts.
    pub stats: WindowStats,
}

impl<const CAP: usize> Windowing<'_, CAP> {
    /// Georeference and window the returns of one packet whose first firing is at `t0`;
    /// `each` sees every georeferenced return (for a point cloud).
    pub fn add_packet<const N: usize>(
        &mut self,
        t0: GpsTime,
        points: &PointBuf,
        history: &PoseHistory<N>,
        mut each: impl FnMut(&GeoPoint),
    ) {
        let mut key = u16::MAX;
        let mut pose: Option<(Motion, GpsTime)> = None;
        for p in points.as_slice() {
            self.stats.points += 1;
            let t = GpsTime(t0.0 + i64::from(p.offset_ns));
            // One interpolation per firing sequence (block, sequence).
            let k = u16::from(p.block) * 2 + p.sequence() as u16;
            if k != key {
                key = k;
                let seq_t =
                    GpsTime(t.0 - (p.laser() as i64) * i64::from(crate::vlp16::firing::FIRING_NS));
                pose = match history.interpolate(seq_t) {
                    Ok(m) => Some((m, seq_t)),
                    Err(e) => {
                        // Fall back to the firing's own time at the history's edges.
                        match history.interpolate(t) {
                            Ok(m) => Some((m, t)),
                            Err(_) => {
                                match e {
                                    AlignError::Empty | AlignError::BeforeHistory => {
                                        self.stats.before_history += 1
                                    }
                                    AlignError::AfterHistory => self.stats.after_history += 1,
                                    AlignError::Gap { .. } => self.stats.in_gap += 1,
                                }
                                key = u16::MAX;
                                None
                            }
                        }
                    }
                };
            }
            let Some((m, ts)) = &pose else { continue };
            let PlatformPose { position, r_ig } = m.advanced((t.0 - ts.0) as f64 * 1e-9);
            let q_l = q_of(p);
            let x = position + r_ig * (self.mount.lever + self.mount.r_li * q_l);
            self.stats.georeferenced += 1;
            let w = which_window(self.targets, self.margin, &x);
            if let Some(i) = w {
                if let Some(b) = self.batches.get_mut(i) {
                    let obs = Observation {
                        q_l,
                        position,
                        r_ig,
                        time: t,
                        range: p.distance_m(),
                        laser: p.laser() as u8,
                    };
                    if b.obs.push(obs).is_err() {
                        b.overflow += 1;
                    } else if i < MAX_TARGETS {
                        self.stats.windowed[i] += 1;
                    }
                }
            }
            each(&GeoPoint {
                ned: x,
                time: t,
                intensity: p.intensity,
                laser: p.laser() as u8,
                window: w.map(|i| i as u8),
            });
        }
    }
}

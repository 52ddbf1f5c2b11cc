//! Sphere windows: georeference each return with the a-priori mounting, keep those within
//! radius + margin of a surveyed centre, and store for each what the solver needs to
//! georeference it again for any boresight and lever arm: the return in the LiDAR frame
//! `q_l = d u_l + v_k e_z` (eq. 1 and the beam offset) and the platform pose (eqs. 2-3).
//!
//! The pose is interpolated at most every 0.7 ms, and whenever a firing falls between other INS
//! samples, and carried to each firing with the INS velocity and angular rate: within one INS
//! segment the position is exactly linear and the attitude turns at a constant rate, so the
//! first-order carry errs by (rate dt)^2 / 2 < 2.5e-7 rad at 1 rad/s (8 um at 33 m). Holding
//! the attitude fixed over even one firing sequence would cost up to 6.6e-5 rad (2 mm at 33 m)
//! in table1's 1.9 rad/s turns (measured, tools/tests/e2e/georef.rs).
//!
//! Broad phase: for each carried pose the sphere centres are moved into the LiDAR frame once,
//! so a return far from every window costs one f32 distance test per sphere; only returns near a
//! window (or all of them when a point cloud is wanted) are georeferenced exactly.

use crate::align::{AlignError, Motion, PoseHistory};
use crate::georef::{Mount, PlatformPose};
use crate::time::GpsTime;
use crate::velodyne::Point;
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
    /// The return in the LiDAR frame: `d u_l + v_k e_z` [m] (f32: the decoder's precision).
    pub q_l: Vector3<f32>,
    /// `P_g` at the firing time [m].
    pub position: Vector3<f64>,
    /// `R_ig` at the firing time (f32: 1e-7 rad, 3 um at 30 m; half the memory traffic of
    /// the calibration's passes over 10^5 windowed returns).
    pub r_ig: Matrix3<f32>,
    /// Firing time (on the INS clock: the LiDAR's plus the time offset the pipeline applied).
    pub time: GpsTime,
    /// The platform's velocity then, site NED [m/s]: with `omega`, what moves the return when
    /// the time offset changes (`calib` estimates it).
    pub velocity: Vector3<f32>,
    /// The platform's angular rate then, in the site frame [rad/s].
    pub omega: Vector3<f32>,
    /// Range [m].
    pub range: f32,
    /// Data packet index (file or arrival order): with `block` and `channel`, where the return
    /// is in the capture.
    pub packet: u32,
    /// Block 0..11.
    pub block: u8,
    /// Channel 0..31 (laser id = channel % 16).
    pub channel: u8,
    /// Laser id.
    pub laser: u8,
    /// The trajectory's own 1-sigma at this return, from its accuracy file (POSPac smrmsg):
    /// position [m] and attitude [rad]; 0 where none is given (the solver's noise model then
    /// uses its settings). See [`crate::calib::noise::Noise`].
    pub ins_sigma: [f32; 2],
    /// The calibration's working state (the return with the current mounting, and its verdict);
    /// callers leave it at its default.
    pub work: Work,
}

impl Default for Observation {
    fn default() -> Self {
        Self {
            q_l: Vector3::zeros(),
            position: Vector3::zeros(),
            r_ig: Matrix3::identity(),
            time: GpsTime(0),
            velocity: Vector3::zeros(),
            omega: Vector3::zeros(),
            range: 0.0,
            packet: 0,
            block: 0,
            channel: 0,
            laser: 0,
            ins_sigma: [0.0; 2],
            work: Work::default(),
        }
    }
}

/// The calibration's working state of one observation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Work {
    /// The return with the current mounting, relative to its sphere's surveyed centre [m].
    pub x: [f32; 3],
    /// The beam's unit direction in the site frame.
    pub u: [f32; 3],
    /// Length of the scan-line segment the return belongs to [m] (`calib::extract::runs`).
    pub run: f32,
    /// The slice of time it belongs to (`calib::extract::assign_slices`).
    pub slice: u32,
    /// The extraction's verdict (`calib::extract::ReturnClass`).
    pub verdict: u8,
}

impl Observation {
    /// The return in the LiDAR frame, f64.
    #[inline]
    pub fn q(&self) -> Vector3<f64> {
        self.q_l.cast()
    }

    /// `R_ig`, f64.
    #[inline]
    pub fn rot(&self) -> Matrix3<f64> {
        self.r_ig.cast()
    }

    /// Eq. 3 for a mounting.
    #[inline]
    pub fn georef(&self, mount: &Mount) -> Vector3<f64> {
        self.position + self.rot() * (mount.lever + mount.r_li * self.q())
    }

    /// Eq. 3 for a mounting with the poses taken `dt` seconds later (first order: the
    /// platform moves `v dt` and turns `omega dt`; exact to (rate dt)^2 / 2).
    #[inline]
    pub fn georef_dt(&self, mount: &Mount, dt: f64) -> Vector3<f64> {
        let w = self.rot() * (mount.lever + mount.r_li * self.q());
        let (v, om): (Vector3<f64>, Vector3<f64>) = (self.velocity.cast(), self.omega.cast());
        self.position + w + (v + om.cross(&w)) * dt
    }

    /// Move the pose `dt` seconds later, as if aligned at an offset larger by `dt`: the position
    /// by `v dt`, the attitude by the rotation `omega dt` (exact for a constant turn rate; the
    /// position to (a dt)^2 / 2). Non-finite `dt` leaves it unchanged.
    pub fn rebase(&mut self, dt: f64) {
        if !dt.is_finite() {
            return;
        }
        let turn = nalgebra::Rotation3::new(self.omega.cast::<f64>() * dt);
        self.position += self.velocity.cast::<f64>() * dt;
        self.r_ig = (turn.into_inner() * self.rot()).cast();
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

/// Longest carry of an interpolated pose [ns].
const CARRY_NS: i64 = 700_000;
/// Half the span over which an observation's velocity and turn rate are taken (they move its
/// return when the time offset changes) [ns]; the pose history must reach this far past a
/// packet for the full span.
pub const RATE_SPAN_NS: i64 = 200_000_000;

/// An interpolated pose and what carrying it on needs.
struct Sequence {
    motion: Motion,
    time: GpsTime,
    position: Vector3<f64>,
    velocity: Vector3<f64>,
    /// `R_ig R_li`.
    m: Matrix3<f64>,
    /// `R_ig a`.
    r_lever: Vector3<f64>,
    /// Angular rate in the site frame, `R_ig w`.
    omega: Vector3<f64>,
    /// How far carrying the pose on can move a return within `CARRY_NS` (up to 150 m away).
    slack: f64,
    /// Each window in the LiDAR frame of this pose: centre and squared reach (radius + margin +
    /// slack), f32. `R_ig R_li` is a rotation, so distances are the same in both frames.
    windows: heapless::Vec<([f32; 3], f32), MAX_TARGETS>,
    /// The velocity and site-frame turn rate over [`RATE_SPAN_NS`] around it (for the
    /// observations; computed when the first return falls in a window).
    rates: Option<(Vector3<f32>, Vector3<f32>)>,
}

impl Sequence {
    fn new(motion: &Motion, time: GpsTime, mount: &Mount, targets: &[Target], margin: f64) -> Self {
        let r = motion.pose.r_ig;
        let m = r * mount.r_li;
        let r_lever = r * mount.lever;
        let slack =
            (motion.velocity.norm() + motion.rate.norm() * 150.0) * CARRY_NS as f64 * 1e-9 + 0.01;
        let mut windows = heapless::Vec::new();
        for t in targets.iter().take(MAX_TARGETS) {
            let c = m.transpose() * (t.center - motion.pose.position - r_lever);
            let reach = t.radius + margin + slack;
            let _ = windows.push(([c.x as f32, c.y as f32, c.z as f32], (reach * reach) as f32));
        }
        Self {
            windows,
            rates: None,
            motion: *motion,
            time,
            position: motion.pose.position,
            velocity: motion.velocity,
            m,
            r_lever,
            omega: r * motion.rate,
            slack,
        }
    }
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
    /// Georeference and window the returns of data packet number `packet` (file or arrival
    /// order) whose first firing is at `t0`; `each`, if given, sees every georeferenced return
    /// (for a point cloud). Without it, returns far from every window are only counted, not
    /// georeferenced exactly.
    pub fn add_packet<const N: usize>(
        &mut self,
        packet: u32,
        t0: GpsTime,
        points: &[Point],
        history: &PoseHistory<N>,
        mut each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
    ) {
        // Broad phase: the box around all windows.
        let (mut lo, mut hi) = (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        );
        for t in self.targets {
            let r = Vector3::repeat(t.radius + self.margin);
            lo = lo.inf(&(t.center - r));
            hi = hi.sup(&(t.center + r));
        }
        let mut seq: Option<Sequence> = None;
        let rates = |sq: &mut Sequence| -> (Vector3<f32>, Vector3<f32>) {
            *sq.rates.get_or_insert_with(|| {
                history
                    .smoothed_rates(sq.time, RATE_SPAN_NS)
                    .map_or((Vector3::zeros(), Vector3::zeros()), |(v, w)| {
                        (v.cast(), w.cast())
                    })
            })
        };
        for p in points {
            self.stats.points += 1;
            let t = GpsTime(t0.0 + i64::from(p.offset_ns));
            let fresh = seq.as_ref().is_some_and(|s| {
                t >= s.motion.segment.0
                    && t <= s.motion.segment.1
                    && (t.0 - s.time.0).abs() <= CARRY_NS
            });
            if !fresh {
                seq = match history.interpolate(t) {
                    Ok(m) => Some(Sequence::new(&m, t, &self.mount, self.targets, self.margin)),
                    Err(e) => {
                        match e {
                            AlignError::Empty | AlignError::BeforeHistory => {
                                self.stats.before_history += 1
                            }
                            AlignError::AfterHistory => self.stats.after_history += 1,
                            AlignError::Gap { .. } => self.stats.in_gap += 1,
                        }
                        None
                    }
                };
            }
            let Some(sq) = seq.as_mut() else { continue };
            // Broad phase in the LiDAR frame, f32: is the return near any window at all?
            if each.is_none()
                && !sq.windows.iter().any(|(c, r2)| {
                    let (dx, dy, dz) = (p.x - c[0], p.y - c[1], p.z - c[2]);
                    dx * dx + dy * dy + dz * dz <= *r2
                })
            {
                self.stats.georeferenced += 1;
                continue;
            }
            let dt = (t.0 - sq.time.0) as f64 * 1e-9;
            // The return in the LiDAR frame: the decoder's point (eq. 1 + beam offset).
            let q_l = Vector3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
            let q32 = Vector3::new(p.x, p.y, p.z);
            let x_r = sq.m * q_l + sq.r_lever;
            self.stats.georeferenced += 1;
            // Broad phase on the pose not yet carried on: off by at most `slack`.
            let a = sq.position + x_r;
            let near = a.x >= lo.x - sq.slack
                && a.x <= hi.x + sq.slack
                && a.y >= lo.y - sq.slack
                && a.y <= hi.y + sq.slack
                && a.z >= lo.z - sq.slack
                && a.z <= hi.z + sq.slack;
            if !near && each.is_none() {
                continue;
            }
            // Eq. 3 carried dt on: x = P + v dt + x_r + dt (omega x x_r), x_r = R(a + R_li q).
            let x = sq.position + sq.velocity * dt + x_r + sq.omega.cross(&x_r) * dt;
            let inside = near
                && x.x >= lo.x
                && x.x <= hi.x
                && x.y >= lo.y
                && x.y <= hi.y
                && x.z >= lo.z
                && x.z <= hi.z;
            let w = if inside {
                which_window(self.targets, self.margin, &x)
            } else {
                None
            };
            if let Some(i) = w {
                if let Some(b) = self.batches.get_mut(i) {
                    let PlatformPose { position, r_ig } = sq.motion.advanced(dt);
                    let (velocity, omega) = rates(sq);
                    let obs = Observation {
                        q_l: q32,
                        position,
                        r_ig: r_ig.cast(),
                        velocity,
                        omega,
                        time: t,
                        range: p.distance_m(),
                        packet,
                        block: p.block,
                        channel: p.channel,
                        laser: p.laser() as u8,
                        ins_sigma: [0.0; 2],
                        work: Work::default(),
                    };
                    if b.obs.push(obs).is_err() {
                        b.overflow += 1;
                    } else if i < MAX_TARGETS {
                        self.stats.windowed[i] += 1;
                    }
                }
            }
            let Some(each) = each.as_mut() else { continue };
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

/// Which azimuths from the LiDAR can reach a window while the platform is within one INS
/// segment: a data packet whose firings all miss them would only be counted by
/// [`Windowing::add_packet`] (seen, and georeferenced by its broad phase), so its decoding can
/// be spared. Conservative: each window's centre is allowed to move in the LiDAR frame as far
/// as the segment's speed and turn can move it from the pose it was taken at, and 0.1 deg
/// more; only packets inside the segment (every return with a pose, the rates the segment's).
#[derive(Debug, Clone)]
pub struct Reach {
    segment: (GpsTime, GpsTime),
    /// Each window's azimuth and half-width [rad]; `None`: a window is reachable at every
    /// azimuth (seen from above, below or inside).
    windows: Option<heapless::Vec<(f64, f64), MAX_TARGETS>>,
}

impl Reach {
    /// Over the INS segment holding `t0`, for these windows (`targets`, `margin`, `mount`);
    /// `None` where `t0` has no pose.
    pub fn at<const N: usize>(
        targets: &[Target],
        margin: f64,
        mount: &Mount,
        t0: GpsTime,
        history: &PoseHistory<N>,
    ) -> Option<Self> {
        let a = history.interpolate(t0).ok()?;
        let sq = Sequence::new(&a, t0, mount, targets, margin);
        let span = (a.segment.1 .0 - a.segment.0 .0) as f64 * 1e-9;
        let turn = a.rate.norm() * span;
        let lever = mount.lever.norm();
        let mut windows = heapless::Vec::new();
        for &(c, r2) in &sq.windows {
            let c = Vector3::new(f64::from(c[0]), f64::from(c[1]), f64::from(c[2]));
            // How far the centre can move in the LiDAR frame within the segment.
            let moved = a.velocity.norm() * span + turn * (c.norm() + lever) + 0.01;
            let reach = libm::sqrt(f64::from(r2)) + moved;
            let rho = libm::hypot(c.x, c.y);
            // Seen from (nearly) above or below, or from inside (or not a number): every
            // azimuth may reach it.
            let beside = rho > reach * 1.001 + 0.01;
            if !beside {
                return Some(Self {
                    segment: a.segment,
                    windows: None,
                });
            }
            let half = libm::asin(reach / rho) + 0.1f64.to_radians();
            let _ = windows.push((libm::atan2(c.x, c.y), half));
        }
        Some(Self {
            segment: a.segment,
            windows: Some(windows),
        })
    }

    /// Whether this holds returns fired from `t0` to `end`: the segment (its first sample
    /// still in `history`, whose samples only ever come after) holds them, short of its end
    /// (a firing at the next sample's time takes the next segment).
    pub fn holds<const N: usize>(
        &self,
        t0: GpsTime,
        end: GpsTime,
        history: &PoseHistory<N>,
    ) -> bool {
        let kept = history
            .span()
            .is_some_and(|(first, _)| first <= self.segment.0);
        kept && self.segment.0 <= t0 && end < self.segment.1
    }

    /// Whether no firing within these azimuths [rad] (each block's lowest and highest,
    /// [`crate::velodyne::extent`]) can reach a window.
    pub fn misses(&self, blocks: &[(f32, f32)]) -> bool {
        let Some(windows) = &self.windows else {
            return false;
        };
        let tau = core::f64::consts::TAU;
        windows.iter().all(|&(centre, half)| {
            blocks.iter().all(|&(lo, hi)| {
                let (lo, hi) = (f64::from(lo), f64::from(hi));
                // The middle's angle from the window's, in -pi..pi.
                let d = 0.5 * (lo + hi) - centre;
                let d = d - tau * libm::round(d / tau);
                d.abs() > half + 0.5 * (hi - lo)
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hand case: at 2 m/s north turning 0.1 rad/s about down, 0.5 s later the pose is 1 m
    /// further north and turned 0.05 rad (a heading rotation, written out by hand).
    #[test]
    fn rebase_moves_the_pose_by_velocity_and_turn() {
        let mut o = Observation {
            position: Vector3::new(10.0, 20.0, -3.0),
            velocity: Vector3::new(2.0, 0.0, 0.0),
            omega: Vector3::new(0.0, 0.0, 0.1),
            r_ig: Matrix3::identity(),
            q_l: Vector3::new(5.0, 0.0, 0.0),
            ..Default::default()
        };
        o.rebase(0.5);
        assert!((o.position - Vector3::new(11.0, 20.0, -3.0)).norm() < 1e-12);
        let (c, s) = (0.05f64.cos(), 0.05f64.sin());
        let want = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        assert!((o.rot() - want).abs().max() < 1e-6, "{}", o.rot());
        // A point 5 m ahead in the body frame now lies 5 m along heading 0.05 rad.
        let p = o.georef(&Mount::new([0.0; 3], [0.0; 3]));
        assert!((p - Vector3::new(11.0 + 5.0 * c, 20.0 + 5.0 * s, -3.0)).norm() < 1e-5);
        // Non-finite: unchanged.
        let before = o;
        o.rebase(f64::NAN);
        assert_eq!(o.position, before.position);
    }
}

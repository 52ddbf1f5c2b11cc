//! The pose history: a fixed ring of INS pose samples and the pose at any firing time in between
//! (position linear, attitude by quaternion slerp, so a heading from 359 to 1 deg passes through
//! 0, never 180). A firing outside the history or between samples further apart than the
//! allowed gap is not georeferenced; the caller counts it.

use crate::frames::Geodetic;
use crate::frames::{rotation, LocalFrame};
use crate::georef::PlatformPose;
use crate::time::GpsTime;
use crate::vn200::pose::{Attitude, Pose};
use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion, Vector3};

/// One pose sample in the site frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSample {
    /// GPS time.
    pub time: GpsTime,
    /// INS position, site NED [m].
    pub position: Vector3<f64>,
    /// Attitude, body -> site NED.
    pub attitude: UnitQuaternion<f64>,
}

impl PoseSample {
    /// From position [m, site NED] and body -> site NED rotation.
    pub fn new(time: GpsTime, position: Vector3<f64>, r_ig: &Matrix3<f64>) -> Self {
        Self {
            time,
            position,
            attitude: UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
                *r_ig,
            )),
        }
    }

    /// From a VN-200 pose: WGS84 position and attitude relative to the local level, into the
    /// site frame. The body -> NED rotation is [`body_to_ned`].
    pub fn from_vn200(site: &LocalFrame, pose: &Pose) -> Option<Self> {
        let g = Geodetic {
            lat: pose.lat,
            lon: pose.lon,
            h: pose.h,
        };
        let local = body_to_ned(&pose.attitude)?;
        Some(Self::from_geodetic(site, pose.time, &g, &local))
    }

    /// From a WGS84 position and the attitude body -> local-level NED at it, into the site
    /// frame: every trajectory source (VN-200, SBET) goes through this one constructor.
    pub fn from_geodetic(
        site: &LocalFrame,
        time: GpsTime,
        g: &Geodetic,
        body_to_local: &Matrix3<f64>,
    ) -> Self {
        let r = site.from_local_level(g.lat, g.lon) * body_to_local;
        Self::new(time, site.to_ned(g), &r)
    }
}

/// The body -> local-level NED rotation of a VN-200 attitude. YawPitchRoll are the 3-2-1 Euler
/// angles (`Rz(yaw) Ry(pitch) Rx(roll)`); the quaternion (x, y, z, w: scalar last) is the same
/// rotation, `R(q)` with the Hamilton convention (VN-200 manual, Attitude Quaternion). Checked
/// on the real VN-310 files, which carry both: `R(q)` agrees with the Euler matrix to 3e-6, its
/// transpose is off by up to 2 (tools/tests/e2e/vn200_real_files.rs). `None` for a quaternion far from
/// unit norm.
pub fn body_to_ned(a: &Attitude) -> Option<Matrix3<f64>> {
    match *a {
        Attitude::YawPitchRoll([yaw, pitch, roll]) => Some(rotation(roll, pitch, yaw)),
        Attitude::Quaternion([x, y, z, w]) => {
            let q = Quaternion::new(w, x, y, z);
            let n = q.norm();
            if !(n > 0.9 && n < 1.1) {
                return None;
            }
            Some(
                UnitQuaternion::new_normalize(q)
                    .to_rotation_matrix()
                    .into_inner(),
            )
        }
    }
}

/// The interpolated pose and how it is changing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// The pose.
    pub pose: PlatformPose,
    /// Velocity, site NED [m/s].
    pub velocity: Vector3<f64>,
    /// Angular rate in the body frame [rad/s].
    pub rate: Vector3<f64>,
    /// The INS samples it lies between: within them position is exactly linear and the
    /// attitude turns at exactly `rate`.
    pub segment: (GpsTime, GpsTime),
}

impl Motion {
    /// The pose `dt` seconds later, to first order (for dt of microseconds: the error is
    /// (rate dt)^2 / 2, 1e-9 rad at 1 rad/s over 40 us).
    #[inline]
    pub fn advanced(&self, dt: f64) -> PlatformPose {
        let w = self.rate * dt;
        let skew = Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0);
        PlatformPose {
            position: self.pose.position + self.velocity * dt,
            r_ig: self.pose.r_ig + self.pose.r_ig * skew,
        }
    }
}

/// Why a firing has no pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlignError {
    /// No samples yet.
    Empty,
    /// Before the oldest sample kept.
    BeforeHistory,
    /// After the newest sample (more INS data may still come).
    AfterHistory,
    /// The two samples around it are further apart than allowed.
    Gap {
        /// Their separation [ns].
        ns: i64,
    },
}

/// A pose history of up to `N` samples in time order (a ring: the oldest is dropped).
#[derive(Debug, Clone)]
pub struct PoseHistory<const N: usize> {
    buf: [PoseSample; N],
    head: usize,
    len: usize,
    /// Largest separation of two samples to interpolate between [ns].
    pub max_gap_ns: i64,
    /// Samples refused because they were not newer than the newest.
    pub out_of_order: u64,
}

const ZERO: PoseSample = PoseSample {
    time: GpsTime(0),
    position: Vector3::new(0.0, 0.0, 0.0),
    attitude: UnitQuaternion::new_unchecked(Quaternion::new(1.0, 0.0, 0.0, 0.0)),
};

impl<const N: usize> PoseHistory<N> {
    /// An empty history allowing `max_gap_ns` between samples.
    pub const fn new(max_gap_ns: i64) -> Self {
        Self {
            buf: [ZERO; N],
            head: 0,
            len: 0,
            max_gap_ns,
            out_of_order: 0,
        }
    }

    /// Samples held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn at(&self, i: usize) -> &PoseSample {
        &self.buf[(self.head + i) % N]
    }

    /// The oldest and newest sample times.
    pub fn span(&self) -> Option<(GpsTime, GpsTime)> {
        (self.len > 0).then(|| (self.at(0).time, self.at(self.len - 1).time))
    }

    /// Append a sample newer than all held; `false` (and counted) otherwise.
    pub fn push(&mut self, s: PoseSample) -> bool {
        if self.len > 0 && s.time <= self.at(self.len - 1).time {
            self.out_of_order += 1;
            return false;
        }
        if N == 0 {
            return false;
        }
        if self.len == N {
            self.head = (self.head + 1) % N;
            self.len -= 1;
        }
        let i = (self.head + self.len) % N;
        self.buf[i] = s;
        self.len += 1;
        true
    }

    /// The two samples around `t` and the fraction between them.
    fn bracket(&self, t: GpsTime) -> Result<(&PoseSample, &PoseSample, f64), AlignError> {
        if self.len == 0 {
            return Err(AlignError::Empty);
        }
        if t < self.at(0).time {
            return Err(AlignError::BeforeHistory);
        }
        if t > self.at(self.len - 1).time {
            return Err(AlignError::AfterHistory);
        }
        // Binary search for the last sample at or before t.
        let (mut lo, mut hi) = (0, self.len - 1);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if self.at(mid).time <= t {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let (a, b) = if self.len == 1 {
            (self.at(0), self.at(0))
        } else {
            (self.at(lo), self.at(hi))
        };
        let dt = b.time.0 - a.time.0;
        if dt > self.max_gap_ns {
            return Err(AlignError::Gap { ns: dt });
        }
        let f = if dt == 0 {
            0.0
        } else {
            (t.0 - a.time.0) as f64 / dt as f64
        };
        Ok((a, b, f))
    }

    /// The platform's velocity [m/s] and angular rate in the site frame [rad/s] around `t`, by
    /// central differences over the poses `half_ns` before and after (the white noise of single
    /// samples averages out over the span; 0.2 s turns a 2 cm position noise at 200 Hz into
    /// 7 cm/s instead of 5.7 m/s). Near the ends of the history the span shrinks to what is
    /// there (down to the bracketing samples).
    pub fn smoothed_rates(&self, t: GpsTime, half_ns: i64) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let mut h = half_ns.max(1);
        loop {
            let a = self.interpolate(GpsTime(t.0.saturating_sub(h)));
            let b = self.interpolate(GpsTime(t.0.saturating_add(h)));
            if let (Ok(a), Ok(b)) = (a, b) {
                let span = 2.0 * h as f64 * 1e-9;
                let v = (b.pose.position - a.pose.position) / span;
                let turn = nalgebra::Rotation3::from_matrix_unchecked(
                    b.pose.r_ig * a.pose.r_ig.transpose(),
                );
                return Some((v, turn.scaled_axis() / span));
            }
            if h <= 1_000_000 {
                let m = self.interpolate(t).ok()?;
                return Some((m.velocity, m.pose.r_ig * m.rate));
            }
            h /= 2;
        }
    }

    /// The platform pose at `t`, with the velocity [m/s] and the body angular rate [rad/s]
    /// between the bracketing samples (so a caller can carry the pose a few microseconds on
    /// without another interpolation).
    pub fn interpolate(&self, t: GpsTime) -> Result<Motion, AlignError> {
        let (a, b, f) = self.bracket(t)?;
        let position = a.position.lerp(&b.position, f);
        let q = a
            .attitude
            .try_slerp(&b.attitude, f, 1e-12)
            .unwrap_or(a.attitude);
        let dt = (b.time.0 - a.time.0) as f64 * 1e-9;
        let (velocity, rate) = if dt > 0.0 {
            (
                (b.position - a.position) / dt,
                (a.attitude.inverse() * b.attitude).scaled_axis() / dt,
            )
        } else {
            (Vector3::zeros(), Vector3::zeros())
        };
        Ok(Motion {
            pose: PlatformPose {
                position,
                r_ig: q.to_rotation_matrix().into_inner(),
            },
            velocity,
            rate,
            segment: (a.time, b.time),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::roll_pitch_heading;

    fn sample(t_s: f64, n: f64, heading_deg: f64) -> PoseSample {
        PoseSample::new(
            GpsTime((t_s * 1e9).round() as i64),
            Vector3::new(n, 0.0, 0.0),
            &rotation(0.0, 0.0, heading_deg.to_radians()),
        )
    }

    #[test]
    fn heading_across_north_is_interpolated_through_zero() {
        let mut h: PoseHistory<8> = PoseHistory::new(1_000_000_000);
        h.push(sample(0.0, 0.0, 359.0));
        h.push(sample(0.01, 1.0, 1.0));
        let m = h.interpolate(GpsTime(5_000_000)).unwrap();
        let [_, _, heading] = roll_pitch_heading(&m.pose.r_ig);
        assert!(
            heading.to_degrees().abs() < 1e-9,
            "{}",
            heading.to_degrees()
        );
        assert!((m.pose.position.x - 0.5).abs() < 1e-12);
        assert!((m.velocity.x - 100.0).abs() < 1e-9);
        // 2 deg in 10 ms about body z (down): 200 deg/s.
        assert!((m.rate.z.to_degrees() - 200.0).abs() < 1e-6 && m.rate.x.abs() < 1e-12);
        // A quarter of the way: 359.5 deg; and carried on 1 ms: 359.7 deg.
        let m = h.interpolate(GpsTime(2_500_000)).unwrap();
        let hd = roll_pitch_heading(&m.pose.r_ig)[2]
            .to_degrees()
            .rem_euclid(360.0);
        assert!((hd - 359.5).abs() < 1e-9, "{hd}");
        let on = m.advanced(0.001);
        let hd = roll_pitch_heading(&on.r_ig)[2]
            .to_degrees()
            .rem_euclid(360.0);
        assert!((hd - 359.7).abs() < 1e-4, "{hd}");
    }

    #[test]
    fn outside_and_gaps_are_refused() {
        let mut h: PoseHistory<4> = PoseHistory::new(10_000_000);
        assert_eq!(h.interpolate(GpsTime(0)).err(), Some(AlignError::Empty));
        h.push(sample(1.0, 0.0, 0.0));
        h.push(sample(1.005, 0.0, 0.0));
        h.push(sample(1.5, 0.0, 0.0)); // a 495 ms INS gap
        assert_eq!(
            h.interpolate(GpsTime(999_000_000)).err(),
            Some(AlignError::BeforeHistory)
        );
        assert_eq!(
            h.interpolate(GpsTime(1_600_000_000)).err(),
            Some(AlignError::AfterHistory)
        );
        assert_eq!(
            h.interpolate(GpsTime(1_200_000_000)).err(),
            Some(AlignError::Gap { ns: 495_000_000 })
        );
        assert!(h.interpolate(GpsTime(1_002_000_000)).is_ok());
        // Out of order is refused and counted; the ring drops its oldest.
        assert!(!h.push(sample(1.2, 0.0, 0.0)));
        assert_eq!(h.out_of_order, 1);
        h.push(sample(1.51, 0.0, 0.0));
        h.push(sample(1.52, 0.0, 0.0));
        assert_eq!(h.len(), 4);
        assert_eq!(h.span().unwrap().0, GpsTime(1_005_000_000));
    }
}

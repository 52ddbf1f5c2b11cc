//! The timestamped pose a VN-200 message carries: GPS time, attitude, WGS84 position and INS
//! status (VN-200 manual, INS status word: bits 0-1 mode, 2 GNSS fix, 4 IMU error,
//! 5 mag/pressure error, 6 GNSS error).

use super::ascii::Ins;
use super::binary::Frame;
use crate::time::GpsTime;

/// Attitude as the sensor reported it (radians inside, DESIGN.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Attitude {
    /// Yaw (heading), pitch, roll [rad]: the 3-2-1 Euler angles body <- NED.
    YawPitchRoll([f64; 3]),
    /// Quaternion x, y, z, w (scalar last), as VectorNav sends it.
    Quaternion([f64; 4]),
}

/// INS filter mode (status bits 0-1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum InsMode {
    /// 0: not tracking.
    NotTracking,
    /// 1: aligning (solution not within specs).
    Aligning,
    /// 2: tracking.
    Tracking,
    /// 3: loss of GNSS for more than 45 s.
    GnssLost,
}

/// Mode of an INS status word.
pub fn ins_mode(status: u16) -> InsMode {
    match status & 0b11 {
        0 => InsMode::NotTracking,
        1 => InsMode::Aligning,
        2 => InsMode::Tracking,
        _ => InsMode::GnssLost,
    }
}

/// One pose sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// GPS time of the sample.
    pub time: GpsTime,
    /// Attitude.
    pub attitude: Attitude,
    /// Latitude [rad].
    pub lat: f64,
    /// Longitude [rad].
    pub lon: f64,
    /// Ellipsoidal height [m].
    pub h: f64,
    /// INS status word, when the message carries it.
    pub ins_status: Option<u16>,
}

fn finite<const N: usize>(v: &[f64; N]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl Pose {
    /// From a binary frame with time (TimeGps, or GpsTow + GpsWeek), attitude (YawPitchRoll,
    /// else Quaternion) and INS position (LLA). `None` if any is missing or not finite.
    pub fn from_frame(f: &Frame<'_>) -> Option<Self> {
        let time = f.gps_time()?;
        let attitude = match f.yaw_pitch_roll_deg() {
            Some(y) => Attitude::YawPitchRoll(y.map(|d| f64::from(d).to_radians())),
            None => Attitude::Quaternion(f.quaternion()?.map(f64::from)),
        };
        let lla = f.position_lla()?;
        Self::checked(time, attitude, lla, f.ins_status())
    }

    /// From a `$VNINS` sentence.
    pub fn from_ins(s: &Ins) -> Option<Self> {
        let time = s.gps_time()?;
        Self::checked(
            time,
            Attitude::YawPitchRoll(s.ypr_deg.map(f64::to_radians)),
            s.lla,
            Some(s.status),
        )
    }

    fn checked(
        time: GpsTime,
        attitude: Attitude,
        lla: [f64; 3],
        ins_status: Option<u16>,
    ) -> Option<Self> {
        let ok = match attitude {
            Attitude::YawPitchRoll(a) => finite(&a),
            Attitude::Quaternion(q) => finite(&q),
        };
        if !ok || !finite(&lla) || lla[0].abs() > 90.0 || lla[1].abs() > 360.0 {
            return None;
        }
        Some(Self {
            time,
            attitude,
            lat: lla[0].to_radians(),
            lon: lla[1].to_radians(),
            h: lla[2],
            ins_status,
        })
    }
}

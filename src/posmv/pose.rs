//! The timestamped pose Group 1 (or 102/103) carries, on the GPS time scale.
//!
//! Time: the first of time 1 and time 2 that is GPS or UTC seconds of the week (ICD Table 3;
//! time 1 is UTC by default, and POS time, seconds since power-on, until the GNSS receiver
//! has a time solution). The week comes from outside (the capture's RMC date or the user):
//! GPS = week + seconds (+ leap seconds for UTC). Attitude: Tate-Bryant roll, pitch, heading,
//! the same 3-2-1 sequence as the SBET's (DESIGN.md).

use super::group::{TimeFields, TimeType};
use super::nav::{Alignment, Navigation, SensorNavigation};
use crate::time::GpsTime;

/// A pose from the POS MV.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// GPS time of validity.
    pub time: GpsTime,
    /// Latitude, longitude [rad], height [m].
    pub lat: f64,
    /// Longitude [rad].
    pub lon: f64,
    /// Height [m] (the altitude the POS MV outputs; ellipsoidal unless a geoid is set in it).
    pub h: f64,
    /// Roll, pitch, heading [rad].
    pub rph: [f64; 3],
    /// Group 1's alignment status (Groups 102/103 carry none: `FullNavigation` is assumed
    /// only when a Group 1 said so; see the reader).
    pub alignment: Alignment,
}

/// Why a group's pose is not usable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PoseError {
    /// Neither time is GPS or UTC: the POS has no GNSS time yet (POS time since power-on).
    NoGnssTime,
    /// A field holds the ICD's invalid value (NaN, all ones) or is out of its range.
    Invalid,
}

impl PoseError {
    /// A short name for counting.
    pub fn reason(self) -> &'static str {
        match self {
            PoseError::NoGnssTime => "time on the POS clock (no GNSS time yet)",
            PoseError::Invalid => "invalid position or attitude",
        }
    }
}

/// The GPS time of a group's time fields, given the GPS week and leap seconds.
pub fn gps_time(t: &TimeFields, week: u16, leap_seconds: i64) -> Result<GpsTime, PoseError> {
    let sow = [(t.time1, t.time1_type), (t.time2, t.time2_type)]
        .into_iter()
        .find_map(|(s, k)| match k {
            TimeType::Gps => Some(s),
            TimeType::Utc => Some(s + leap_seconds as f64),
            _ => None,
        })
        .ok_or(PoseError::NoGnssTime)?;
    if !(0.0..=604_800.0 + 86_400.0).contains(&sow) {
        return Err(PoseError::Invalid);
    }
    GpsTime::from_week_tow_s(week, sow).ok_or(PoseError::Invalid)
}

fn checked(
    time: GpsTime,
    lla: [f64; 3],
    rph: [f64; 3],
    alignment: Alignment,
) -> Result<Pose, PoseError> {
    let finite = lla.iter().chain(rph.iter()).all(|x| x.is_finite());
    if !finite
        || lla[0].abs() > 90.0
        || lla[1].abs() > 360.0
        || lla[2].abs() > 100_000.0
        || rph[0].abs() > 180.0
        || rph[1].abs() > 90.0
        || rph[2].abs() > 360.0
    {
        return Err(PoseError::Invalid);
    }
    Ok(Pose {
        time,
        lat: lla[0].to_radians(),
        lon: lla[1].to_radians(),
        h: lla[2],
        rph: rph.map(f64::to_radians),
        alignment,
    })
}

impl Pose {
    /// From Group 1.
    pub fn from_navigation(
        n: &Navigation,
        week: u16,
        leap_seconds: i64,
    ) -> Result<Self, PoseError> {
        checked(
            gps_time(&n.time, week, leap_seconds)?,
            n.lla,
            n.rph,
            n.alignment,
        )
    }

    /// From Group 102/103, with the alignment the last Group 1 reported.
    pub fn from_sensor(
        n: &SensorNavigation,
        week: u16,
        leap_seconds: i64,
        alignment: Alignment,
    ) -> Result<Self, PoseError> {
        checked(
            gps_time(&n.time, week, leap_seconds)?,
            n.lla,
            n.rph,
            alignment,
        )
    }
}

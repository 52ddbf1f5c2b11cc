//! The standard navigation messages the VectorNav ROS 2 driver also publishes
//! (dawonn/vectornav `vn_sensor_msgs`, from each CommonGroup, every one with the group's header):
//! `sensor_msgs/msg/Imu` (the attitude quaternion; with the driver's default `use_enu` turned
//! from FRD->NED into RFU->ENU), `sensor_msgs/msg/NavSatFix` (the INS position, WGS 84
//! ellipsoidal height, the GNSS fix) and `sensor_msgs/msg/TimeReference` (`vectornav/time_gps`:
//! `time_ref` = the group's GPS time). Together they give what a CommonGroup gives but the INS
//! mode ([`NavFrame::common`]); without the time reference they have no GPS time at all.

use super::cdr::{Error, Reader};
use super::{CommonGroup, Header, InsStatus, Time};

/// `sensor_msgs/msg/Imu` (orientation and the specific force; the rates are not read).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Imu<'a> {
    /// Header (the driver's receive time).
    pub header: Header<'a>,
    /// Orientation x, y, z, w.
    pub orientation: [f64; 4],
    /// Linear acceleration (specific force) [m/s^2].
    pub linear_acceleration: [f64; 3],
}

impl<'a> Imu<'a> {
    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let q = r.f64x3("orientation")?;
        let orientation = [q[0], q[1], q[2], r.f64("orientation")?];
        for _ in 0..9 {
            r.f64("orientation_covariance")?;
        }
        r.f64x3("angular_velocity")?;
        for _ in 0..9 {
            r.f64("angular_velocity_covariance")?;
        }
        let linear_acceleration = r.f64x3("linear_acceleration")?;
        for _ in 0..9 {
            r.f64("linear_acceleration_covariance")?;
        }
        Ok(Self {
            header,
            orientation,
            linear_acceleration,
        })
    }

    /// Whether the message is in the ROS frames (body RFU, world ENU: the driver's `use_enu`,
    /// its default) or the sensor's (FRD, NED), from the specific force's vertical: gravity's
    /// reaction is up, +z in RFU and -z in FRD. None when it is under 3 m/s^2 (a level platform
    /// always has about 9.8).
    pub fn enu(&self) -> Option<bool> {
        let z = self.linear_acceleration[2];
        (z.abs() >= 3.0).then_some(z > 0.0)
    }

    /// The sensor's own attitude quaternion (x, y, z, w: FRD body to NED, as a VN-200 sends
    /// it), undoing the driver's `q_rfu2enu = q_ned2enu * q_frd2ned * q_rfu2frd` when `enu`
    /// (both fixed rotations are pi about (1, 1, 0), their own inverses).
    pub fn vn_quaternion(&self, enu: bool) -> [f64; 4] {
        Self::quaternion_from(self.orientation, enu)
    }

    /// [`Self::vn_quaternion`] of an orientation `q` (x, y, z, w).
    pub fn quaternion_from(q: [f64; 4], enu: bool) -> [f64; 4] {
        if !enu {
            return q;
        }
        let c = [
            core::f64::consts::FRAC_1_SQRT_2,
            core::f64::consts::FRAC_1_SQRT_2,
            0.0,
            0.0,
        ];
        mul(&mul(&c, &q), &c)
    }
}

/// Hamilton product of quaternions stored x, y, z, w (tf2's).
fn mul(a: &[f64; 4], b: &[f64; 4]) -> [f64; 4] {
    let [ax, ay, az, aw] = *a;
    let [bx, by, bz, bw] = *b;
    [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
}

/// `sensor_msgs/msg/NavSatFix`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavSatFix<'a> {
    /// Header.
    pub header: Header<'a>,
    /// `NavSatStatus.status`: -1 no fix, 0 fix, 1 SBAS, 2 GBAS.
    pub status: i8,
    /// Latitude, longitude [deg], altitude above the WGS 84 ellipsoid [m].
    pub lla: [f64; 3],
}

impl<'a> NavSatFix<'a> {
    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let status = r.u8("status")? as i8;
        r.u16("service")?;
        let lla = r.f64x3("latitude, longitude, altitude")?;
        for _ in 0..9 {
            r.f64("position_covariance")?;
        }
        r.u8("position_covariance_type")?;
        Ok(Self {
            header,
            status,
            lla,
        })
    }
}

/// `sensor_msgs/msg/TimeReference`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TimeReference<'a> {
    /// Header (the host's time of the reference).
    pub header: Header<'a>,
    /// The external clock's time.
    pub time_ref: Time,
    /// Its source ("gps" from the VectorNav driver).
    pub source: &'a str,
}

/// Seconds from the Unix epoch to the GPS epoch (1980-01-06).
const GPS_EPOCH_UNIX_S: i64 = 315_964_800;
/// How far the host clock may be from the reference for the reference to be read [s].
const HOST_SLACK_S: i64 = 86_400;

impl<'a> TimeReference<'a> {
    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let time_ref = Time::read(&mut r)?;
        let source = r.string("source")?;
        Ok(Self {
            header,
            time_ref,
            source,
        })
    }

    /// GPS time minus the header's host time [ns], reading `time_ref` as the GPS time
    /// (the VectorNav driver's `time_gps`: ns since 1980-01-06) or as UTC (Unix time, as
    /// NMEA drivers publish it), whichever lies within a day of the host's clock; None when
    /// neither does (a host clock not set, another kind of reference).
    pub fn gps_minus_host_ns(&self, leap_seconds: i64) -> Option<i64> {
        let host = self.header.stamp.ns();
        let r = self.time_ref.ns();
        let slack = HOST_SLACK_S * 1_000_000_000;
        // As GPS time: its Unix time is r + epoch - leap.
        let as_gps_unix = r + (GPS_EPOCH_UNIX_S - leap_seconds) * 1_000_000_000;
        if (as_gps_unix - host).abs() <= slack {
            return Some(r - host);
        }
        if (r - host).abs() <= slack {
            return Some(r - (GPS_EPOCH_UNIX_S - leap_seconds) * 1_000_000_000 - host);
        }
        None
    }
}

/// One navigation solution as the three messages of one stamp give it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavFrame {
    /// GPS time [ns since 1980-01-06].
    pub gps_ns: i64,
    /// The sensor's quaternion (FRD to NED).
    pub quaternion: [f64; 4],
    /// Latitude, longitude [deg], ellipsoidal height [m].
    pub lla: [f64; 3],
    /// The GNSS has a fix.
    pub fix: bool,
}

impl NavFrame {
    /// As the CommonGroup it was published from, but for the INS mode, which these messages do
    /// not carry: tracking (2) when the GNSS has a fix, else not tracking (0).
    pub fn common<'h>(&self, header: Header<'h>) -> Option<CommonGroup<'h>> {
        let gps = u64::try_from(self.gps_ns).ok()?;
        Some(CommonGroup {
            header,
            group_fields: CommonGroup::TIMEGPS
                | CommonGroup::QUATERNION
                | CommonGroup::POSITION
                | CommonGroup::INSSTATUS,
            timestartup: 0,
            timegps: gps,
            yawpitchroll: [0.0; 3],
            quaternion: self.quaternion,
            angularrate: [0.0; 3],
            position: self.lla,
            velocity: [0.0; 3],
            insstatus: InsStatus {
                mode: if self.fix { 2 } else { 0 },
                gps_fix: self.fix,
                errors: [false; 4],
                gps_heading_ins: false,
                gps_compass: false,
            },
            syncincnt: 0,
            timegpspps: 0,
        })
    }
}

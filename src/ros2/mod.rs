//! ROS 2 messages of the sensors' drivers, as a rosbag2 stores them (CDR, [`cdr`]): the
//! Velodyne driver's raw packets (`velodyne_msgs/msg/VelodyneScan`, ros-drivers/velodyne branch
//! `ros2`) and the VectorNav driver's parsed groups (`vectornav_msgs/msg/CommonGroup`,
//! `TimeGroup`, `InsGroup`, `AttitudeGroup`, dawonn/vectornav branch `ros2`) and the Hesai's and
//! Ouster's raw packets (`pandar_msgs/msg/PandarScan`, `ouster_sensor_msgs/msg/PacketMsg`,
//! [`pandar`]). Views over borrowed bytes, parsed once and
//! checked: a truncated or malformed message is an [`cdr::Error`] with its offset, never a
//! panic (PROTOCOLS.md "ROS 2 messages").

pub mod cdr;
pub mod cloud;
pub mod nav;
pub mod pandar;
pub mod raw;

pub use pandar::{PacketMsg, PandarScan};

use cdr::{Error, Reader};

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds (of the host's clock in a bag).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds.
    pub nanosec: u32,
}

impl Time {
    fn read(r: &mut Reader<'_>) -> Result<Self, Error> {
        Ok(Self {
            sec: r.i32("stamp.sec")?,
            nanosec: r.u32("stamp.nanosec")?,
        })
    }

    /// Nanoseconds since the clock's epoch.
    pub fn ns(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header<'a> {
    /// When (the driver's host time).
    pub stamp: Time,
    /// The frame's name.
    pub frame_id: &'a str,
}

impl<'a> Header<'a> {
    fn read(r: &mut Reader<'a>) -> Result<Self, Error> {
        Ok(Self {
            stamp: Time::read(r)?,
            frame_id: r.string("header.frame_id")?,
        })
    }
}

/// One Velodyne data packet's UDP payload length (`uint8[1206] data`).
pub const PACKET: usize = 1206;

/// `velodyne_msgs/msg/VelodyneScan`: a header and the raw packets of (about) one rotation, each
/// `builtin_interfaces/Time stamp` + `uint8[1206] data`.
#[derive(Debug, Clone)]
pub struct VelodyneScan<'a> {
    /// The scan's header.
    pub header: Header<'a>,
    /// Its packets.
    pub count: u32,
    packets: Reader<'a>,
}

impl<'a> VelodyneScan<'a> {
    /// Parse a CDR message; every packet is checked to be there ([`Self::packets`] cannot
    /// fail).
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let count = r.count(8 + PACKET, "packets")?;
        let packets = r.clone();
        for _ in 0..count {
            Time::read(&mut r)?;
            r.bytes(PACKET, "packet data")?;
        }
        Ok(Self {
            header,
            count,
            packets,
        })
    }

    /// The packets: each its stamp and payload.
    pub fn packets(&self) -> impl Iterator<Item = (Time, &'a [u8; PACKET])> + '_ {
        let mut r = self.packets.clone();
        (0..self.count).map_while(move |_| {
            let t = Time::read(&mut r).ok()?;
            let d = r.bytes(PACKET, "packet data").ok()?.try_into().ok()?;
            Some((t, d))
        })
    }
}

/// `vectornav_msgs/msg/InsStatus` (VN-200 user manual 10.2.2, unpacked by the driver).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct InsStatus {
    /// 0 not tracking, 1 aligning, 2 tracking, 3 loss of GNSS.
    pub mode: u8,
    /// GNSS fix.
    pub gps_fix: bool,
    /// Errors: time, IMU, magnetometer/pressure, GNSS.
    pub errors: [bool; 4],
    /// GNSS heading used by the INS, GNSS compass.
    pub gps_heading_ins: bool,
    /// ...
    pub gps_compass: bool,
}

impl InsStatus {
    fn read(r: &mut Reader<'_>) -> Result<Self, Error> {
        let e = "insstatus";
        Ok(Self {
            mode: r.u8(e)?,
            gps_fix: r.bool(e)?,
            errors: [r.bool(e)?, r.bool(e)?, r.bool(e)?, r.bool(e)?],
            gps_heading_ins: r.bool(e)?,
            gps_compass: r.bool(e)?,
        })
    }

    /// The status word the VN-200 sends (bits 0-1 mode, bit 2 GNSS fix, 4-7 errors, 8-9 the
    /// GNSS heading flags), for the same gating as a serial stream.
    pub fn word(&self) -> u16 {
        let mut w = u16::from(self.mode & 3) | u16::from(self.gps_fix) << 2;
        for (k, e) in self.errors.iter().enumerate() {
            w |= u16::from(*e) << (4 + k);
        }
        w | u16::from(self.gps_heading_ins) << 8 | u16::from(self.gps_compass) << 9
    }
}

/// `vectornav_msgs/msg/CommonGroup`: the Common group the driver parsed (only the fields whose
/// bit is set in `group_fields` hold data).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommonGroup<'a> {
    /// Header (the host's receive time).
    pub header: Header<'a>,
    /// Which fields hold data ([`CommonGroup::TIMEGPS`] ...).
    pub group_fields: u16,
    /// Time since startup [ns].
    pub timestartup: u64,
    /// GPS time [ns since 1980-01-06].
    pub timegps: u64,
    /// Yaw, pitch, roll [deg].
    pub yawpitchroll: [f64; 3],
    /// Attitude quaternion x, y, z, w.
    pub quaternion: [f64; 4],
    /// Angular rate [rad/s].
    pub angularrate: [f64; 3],
    /// Latitude, longitude [deg], height [m].
    pub position: [f64; 3],
    /// NED velocity [m/s].
    pub velocity: [f64; 3],
    /// INS status.
    pub insstatus: InsStatus,
    /// SyncIn count.
    pub syncincnt: u32,
    /// Time since the last PPS as the driver stores it (declared uint16).
    pub timegpspps: u16,
}

impl<'a> CommonGroup<'a> {
    /// `group_fields` bit: TimeStartup.
    pub const TIMESTARTUP: u16 = 0x0001;
    /// ... TimeGps.
    pub const TIMEGPS: u16 = 0x0002;
    /// ... YawPitchRoll.
    pub const YAWPITCHROLL: u16 = 0x0008;
    /// ... Quaternion.
    pub const QUATERNION: u16 = 0x0010;
    /// ... Position.
    pub const POSITION: u16 = 0x0040;
    /// ... Velocity.
    pub const VELOCITY: u16 = 0x0080;
    /// ... InsStatus.
    pub const INSSTATUS: u16 = 0x1000;

    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let group_fields = r.u16("group_fields")?;
        let timestartup = r.u64("timestartup")?;
        let timegps = r.u64("timegps")?;
        r.u64("timesyncin")?;
        let yawpitchroll = r.f64x3("yawpitchroll")?;
        let q = r.f64x3("quaternion")?;
        let quaternion = [q[0], q[1], q[2], r.f64("quaternion")?];
        let angularrate = r.f64x3("angularrate")?;
        let position = r.f64x3("position")?;
        let velocity = r.f64x3("velocity")?;
        for k in ["accel", "imu_accel", "imu_rate", "magpres_mag"] {
            r.f64x3(k)?;
        }
        for k in ["magpres_temp", "magpres_pres", "deltatheta_dtime"] {
            r.f32(k)?;
        }
        for k in ["deltatheta_dtheta", "deltatheta_dvel"] {
            r.f64x3(k)?;
        }
        let insstatus = InsStatus::read(&mut r)?;
        let syncincnt = r.u32("syncincnt")?;
        let timegpspps = r.u16("timegpspps")?;
        Ok(Self {
            header,
            group_fields,
            timestartup,
            timegps,
            yawpitchroll,
            quaternion,
            angularrate,
            position,
            velocity,
            insstatus,
            syncincnt,
            timegpspps,
        })
    }

    /// Whether the fields of `bits` all hold data.
    pub fn has(&self, bits: u16) -> bool {
        self.group_fields & bits == bits
    }
}

/// The longest frame [`CommonGroup::vn200_frame`] writes (header 8, payload 86, CRC 2).
pub const VN200_FRAME_MAX: usize = 96;

impl CommonGroup<'_> {
    /// The VN-200 binary frame this group was parsed from, as far as the group keeps it: the
    /// Common group's TimeStartup, TimeGps, YawPitchRoll, Quaternion, Position and InsStatus (those whose
    /// bit is set), with the filter's own sigmas when given (Attitude.YprU [deg], Ins.PosU
    /// [m]: another message of the driver's). Attitudes go back to the sensor's f32. Returns
    /// the frame's length; `None` when the group holds none of those fields.
    pub fn vn200_frame(
        &self,
        ypru: Option<[f32; 3]>,
        posu: Option<f32>,
        out: &mut [u8; VN200_FRAME_MAX],
    ) -> Option<usize> {
        use crate::vn200::binary::{emit, Masks};
        use crate::vn200::fields::Group;
        let mut masks = Masks::default();
        let mut p = [0u8; 88];
        let mut at = 0;
        let mut put = |b: &[u8]| {
            p[at..at + b.len()].copy_from_slice(b);
            at += b.len();
        };
        if self.has(Self::TIMESTARTUP) {
            masks = masks.with(Group::Common, 0);
            put(&self.timestartup.to_le_bytes());
        }
        if self.has(Self::TIMEGPS) {
            masks = masks.with(Group::Common, 1);
            put(&self.timegps.to_le_bytes());
        }
        if self.has(Self::YAWPITCHROLL) {
            masks = masks.with(Group::Common, 3);
            for v in self.yawpitchroll {
                put(&(v as f32).to_le_bytes());
            }
        }
        if self.has(Self::QUATERNION) {
            masks = masks.with(Group::Common, 4);
            for v in self.quaternion {
                put(&(v as f32).to_le_bytes());
            }
        }
        if self.has(Self::POSITION) {
            masks = masks.with(Group::Common, 6);
            for v in self.position {
                put(&v.to_le_bytes());
            }
        }
        if self.has(Self::INSSTATUS) {
            masks = masks.with(Group::Common, 12);
            put(&self.insstatus.word().to_le_bytes());
        }
        if masks == Masks::default() || masks == Masks::default().with(Group::Common, 0) {
            return None;
        }
        if let Some(u) = ypru {
            masks = masks.with(Group::Attitude, 8);
            for v in u {
                put(&v.to_le_bytes());
            }
        }
        if let Some(u) = posu {
            masks = masks.with(Group::Ins, 9);
            put(&u.to_le_bytes());
        }
        emit(out, &masks, &p[..at]).ok()
    }
}

/// `vectornav_msgs/msg/InsGroup`: the INS group the driver parsed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InsGroup<'a> {
    /// Header.
    pub header: Header<'a>,
    /// Which fields hold data ([`InsGroup::POSU`] ...).
    pub group_fields: u16,
    /// INS status.
    pub insstatus: InsStatus,
    /// Latitude, longitude [deg], height [m].
    pub poslla: [f64; 3],
    /// NED velocity [m/s].
    pub velned: [f64; 3],
    /// The filter's position 1-sigma [m].
    pub posu: f32,
    /// ... velocity [m/s].
    pub velu: f32,
}

impl<'a> InsGroup<'a> {
    /// `group_fields` bit: InsStatus.
    pub const INSSTATUS: u16 = 0x0001;
    /// ... PosLla.
    pub const POSLLA: u16 = 0x0002;
    /// ... PosU.
    pub const POSU: u16 = 0x0200;

    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let group_fields = r.u16("group_fields")?;
        let insstatus = InsStatus::read(&mut r)?;
        let poslla = r.f64x3("poslla")?;
        r.f64x3("posecef")?;
        r.f64x3("velbody")?;
        let velned = r.f64x3("velned")?;
        for k in ["velecef", "magecef", "accelecef", "linearaccelecef"] {
            r.f64x3(k)?;
        }
        let posu = r.f32("posu")?;
        let velu = r.f32("velu")?;
        Ok(Self {
            header,
            group_fields,
            insstatus,
            poslla,
            velned,
            posu,
            velu,
        })
    }

    /// Whether the fields of `bits` all hold data.
    pub fn has(&self, bits: u16) -> bool {
        self.group_fields & bits == bits
    }
}

/// `vectornav_msgs/msg/AttitudeGroup`: the Attitude group the driver parsed (its YprU is what
/// the filter states of its attitude errors).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeGroup<'a> {
    /// Header.
    pub header: Header<'a>,
    /// Which fields hold data ([`AttitudeGroup::YPRU`] ...).
    pub group_fields: u16,
    /// Yaw, pitch, roll [deg].
    pub yawpitchroll: [f64; 3],
    /// The filter's yaw, pitch, roll 1-sigma [deg].
    pub ypru: [f64; 3],
}

impl<'a> AttitudeGroup<'a> {
    /// `group_fields` bit: YawPitchRoll.
    pub const YAWPITCHROLL: u16 = 0x0002;
    /// ... YprU.
    pub const YPRU: u16 = 0x0100;

    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let group_fields = r.u16("group_fields")?;
        // VpeStatus: u8, bool, bool, u8, bool, u8, bool, bool, bool (UM001 4.7.1).
        for _ in 0..9 {
            r.u8("vpestatus")?;
        }
        let yawpitchroll = r.f64x3("yawpitchroll")?;
        r.f64x3("quaternion")?;
        r.f64("quaternion")?;
        for _ in 0..9 {
            r.f32("dcm")?;
        }
        for k in ["magned", "accelned", "linearaccelbody", "linearaccelned"] {
            r.f64x3(k)?;
        }
        let ypru = r.f64x3("ypru")?;
        Ok(Self {
            header,
            group_fields,
            yawpitchroll,
            ypru,
        })
    }

    /// Whether the fields of `bits` all hold data.
    pub fn has(&self, bits: u16) -> bool {
        self.group_fields & bits == bits
    }
}

/// `vectornav_msgs/msg/TimeGroup`: the Time group the driver parsed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeGroup<'a> {
    /// Header.
    pub header: Header<'a>,
    /// Which fields hold data ([`TimeGroup::TIMEGPS`] ...).
    pub group_fields: u16,
    /// GPS time [ns since 1980-01-06].
    pub timegps: u64,
    /// GPS time of week [ns].
    pub gpstow: u64,
    /// GPS week.
    pub gpsweek: u16,
    /// Time since the last PPS [ns].
    pub timegpspps: u64,
    /// UTC: year (since 2000), month, day, hour, minute, second, and milliseconds.
    pub timeutc: ([u8; 6], u16),
    /// Time, date and UTC time valid (UM001 4.7.1).
    pub timestatus: [bool; 3],
}

impl<'a> TimeGroup<'a> {
    /// `group_fields` bit: TimeGps.
    pub const TIMEGPS: u16 = 0x0002;
    /// ... GpsTow.
    pub const GPSTOW: u16 = 0x0004;
    /// ... GpsWeek.
    pub const GPSWEEK: u16 = 0x0008;
    /// ... TimeGpsPps.
    pub const TIMEGPSPPS: u16 = 0x0020;
    /// ... TimeStatus.
    pub const TIMESTATUS: u16 = 0x0200;

    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let group_fields = r.u16("group_fields")?;
        r.u64("timestartup")?;
        let timegps = r.u64("timegps")?;
        let gpstow = r.u64("gpstow")?;
        let gpsweek = r.u16("gpsweek")?;
        r.u64("timesyncin")?;
        let timegpspps = r.u64("timegpspps")?;
        let mut utc = [0u8; 6];
        for u in utc.iter_mut() {
            *u = r.u8("timeutc")?;
        }
        let ms = r.u16("timeutc.ms")?;
        r.u32("syncincnt")?;
        r.u32("syncoutcnt")?;
        let e = "timestatus";
        let timestatus = [r.bool(e)?, r.bool(e)?, r.bool(e)?];
        Ok(Self {
            header,
            group_fields,
            timegps,
            gpstow,
            gpsweek,
            timegpspps,
            timeutc: (utc, ms),
            timestatus,
        })
    }

    /// Whether the fields of `bits` all hold data.
    pub fn has(&self, bits: u16) -> bool {
        self.group_fields & bits == bits
    }
}

#[cfg(test)]
mod tests;

//! The groups a calibration uses, parsed and emitted: Group 1 (vessel position, velocity,
//! attitude & dynamics; ICD Table 4, alignment status Table 5), Groups 102/103 (sensor 1/2;
//! Table 29), Group 2 (vessel navigation performance metrics; Table 6) and Group 7 (PPS time
//! recovery and status; Table 15). Offsets below are from the first data byte (after the
//! time/distance fields).

use super::group::{emit_group, f32_at, f64_at, le32, Group, TimeFields};
use super::Error;

/// Group 1's alignment status (Table 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Alignment {
    /// 0: full navigation, the user's accuracies are met.
    FullNavigation,
    /// 1: fine alignment active (RMS heading error below 15 deg).
    FineAlign,
    /// 2: GC CHI 2 (aligning with GPS, heading error above 15 deg).
    GcChi2,
    /// 3: PC CHI 2 (aligning without GPS, above 15 deg).
    PcChi2,
    /// 4: GC CHI 1 (with GPS, above 45 deg).
    GcChi1,
    /// 5: PC CHI 1 (without GPS, above 45 deg).
    PcChi1,
    /// 6: coarse levelling.
    CoarseLeveling,
    /// 7: initial solution assigned.
    InitialSolution,
    /// 8: no valid solution.
    NoSolution,
    /// Anything else (255 is the ICD's invalid byte).
    Other(u8),
}

impl Alignment {
    /// From the status byte.
    pub fn from_byte(b: u8) -> Self {
        match b {
            0 => Self::FullNavigation,
            1 => Self::FineAlign,
            2 => Self::GcChi2,
            3 => Self::PcChi2,
            4 => Self::GcChi1,
            5 => Self::PcChi1,
            6 => Self::CoarseLeveling,
            7 => Self::InitialSolution,
            8 => Self::NoSolution,
            x => Self::Other(x),
        }
    }

    /// The status byte.
    pub fn to_byte(self) -> u8 {
        match self {
            Self::FullNavigation => 0,
            Self::FineAlign => 1,
            Self::GcChi2 => 2,
            Self::PcChi2 => 3,
            Self::GcChi1 => 4,
            Self::PcChi1 => 5,
            Self::CoarseLeveling => 6,
            Self::InitialSolution => 7,
            Self::NoSolution => 8,
            Self::Other(x) => x,
        }
    }

    /// Only full navigation meets the user's accuracies (Table 5).
    pub fn is_navigating(self) -> bool {
        self == Self::FullNavigation
    }

    /// In words.
    pub fn name(self) -> &'static str {
        match self {
            Self::FullNavigation => "full navigation",
            Self::FineAlign => "fine alignment",
            Self::GcChi2 | Self::GcChi1 => "aligning with GPS",
            Self::PcChi2 | Self::PcChi1 => "aligning without GPS",
            Self::CoarseLeveling => "coarse levelling",
            Self::InitialSolution => "initial solution",
            Self::NoSolution => "no valid solution",
            Self::Other(_) => "unknown status",
        }
    }
}

/// Group 7's time synchronization status (Table 15).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TimeSync {
    /// 0: not synchronized to GPS time.
    NotSynchronized,
    /// 1: synchronizing (10-20 s).
    Synchronizing,
    /// 2: fully synchronized (< 10 us).
    Synchronized,
    /// 3: using the last good clock offset (no PPS or time message lately).
    OldOffset,
    /// Anything else.
    Other(u8),
}

impl TimeSync {
    /// From the status byte.
    pub fn from_byte(b: u8) -> Self {
        match b {
            0 => Self::NotSynchronized,
            1 => Self::Synchronizing,
            2 => Self::Synchronized,
            3 => Self::OldOffset,
            x => Self::Other(x),
        }
    }

    /// The status byte.
    pub fn to_byte(self) -> u8 {
        match self {
            Self::NotSynchronized => 0,
            Self::Synchronizing => 1,
            Self::Synchronized => 2,
            Self::OldOffset => 3,
            Self::Other(x) => x,
        }
    }

    /// Times can be trusted to the PPS (synchronized, or coasting on the last offset).
    pub fn is_trusted(self) -> bool {
        matches!(self, Self::Synchronized | Self::OldOffset)
    }
}

fn check<T: AsRef<[u8]>>(g: &Group<T>, id: &[u16], count: u16) -> Result<(), Error> {
    if g.is_message() || !id.contains(&g.id()) {
        return Err(Error::WrongGroup { found: g.id() });
    }
    if g.byte_count() != count {
        return Err(Error::WrongSize {
            id: g.id(),
            expected: count,
            found: g.byte_count(),
        });
    }
    Ok(())
}

fn put_f64(b: &mut [u8], at: usize, v: f64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

fn put_f32(b: &mut [u8], at: usize, v: f32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn f32x3(d: &[u8], at: usize) -> [f32; 3] {
    [f32_at(d, at), f32_at(d, at + 4), f32_at(d, at + 8)]
}

/// Position, velocity, attitude and wander angle: the first 68 data bytes of Groups 1 and
/// 102/103 (Tables 4 and 29 share them).
type Pva = ([f64; 3], [f32; 3], [f64; 3], f64);

fn read_pva(d: &[u8]) -> Pva {
    (
        [f64_at(d, 0), f64_at(d, 8), f64_at(d, 16)],
        f32x3(d, 24),
        [f64_at(d, 36), f64_at(d, 44), f64_at(d, 52)],
        f64_at(d, 60),
    )
}

fn write_pva(d: &mut [u8], (lla, velocity, rph, wander): Pva) {
    for (i, v) in lla.iter().enumerate() {
        put_f64(d, 8 * i, *v);
    }
    for (i, v) in velocity.iter().enumerate() {
        put_f32(d, 24 + 4 * i, *v);
    }
    for (i, v) in rph.iter().enumerate() {
        put_f64(d, 36 + 8 * i, *v);
    }
    put_f64(d, 60, wander);
}

fn write_f32s(d: &mut [u8], at: usize, v: &[f32]) {
    for (i, x) in v.iter().enumerate() {
        put_f32(d, at + 4 * i, *x);
    }
}

/// Group 1: the vessel's (reference point's) position, velocity, attitude and dynamics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Navigation {
    /// Time/distance fields.
    pub time: TimeFields,
    /// Latitude [deg], longitude [deg], altitude [m].
    pub lla: [f64; 3],
    /// North, east, down velocity [m/s].
    pub velocity: [f32; 3],
    /// Roll, pitch, heading [deg] (Tate-Bryant: pitch from local level, roll about the
    /// pitched axis; heading true, 0..360).
    pub rph: [f64; 3],
    /// Wander angle [deg].
    pub wander: f64,
    /// Track angle [deg] and speed [m/s].
    pub track_speed: [f32; 2],
    /// Angular rate about the longitudinal, transverse, down axes [deg/s].
    pub rate: [f32; 3],
    /// Longitudinal, transverse, down acceleration [m/s^2].
    pub accel: [f32; 3],
    /// Alignment status.
    pub alignment: Alignment,
}

impl Navigation {
    /// Group ID.
    pub const ID: u16 = 1;
    /// Byte count (Table 4).
    pub const BYTE_COUNT: u16 = 132;

    /// Parse a checked Group 1.
    pub fn parse<T: AsRef<[u8]>>(g: &Group<T>) -> Result<Self, Error> {
        check(g, &[Self::ID], Self::BYTE_COUNT)?;
        let d = g.data();
        let (lla, velocity, rph, wander) = read_pva(d);
        Ok(Self {
            time: g.time_fields(),
            lla,
            velocity,
            rph,
            wander,
            track_speed: [f32_at(d, 68), f32_at(d, 72)],
            rate: f32x3(d, 76),
            accel: f32x3(d, 88),
            alignment: Alignment::from_byte(d[100]),
        })
    }

    /// Write the group into `out`; its length (140), or `None` if `out` is too short.
    pub fn emit(&self, out: &mut [u8]) -> Option<usize> {
        let mut d = [0u8; 101];
        write_pva(&mut d, (self.lla, self.velocity, self.rph, self.wander));
        write_f32s(&mut d, 68, &self.track_speed);
        write_f32s(&mut d, 76, &self.rate);
        write_f32s(&mut d, 88, &self.accel);
        d[100] = self.alignment.to_byte();
        emit_group(Self::ID, &self.time, &d, out)
    }
}

/// Groups 102/103: a sensor's (1 or 2) position, velocity, attitude, heave and dynamics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorNavigation {
    /// 102 (sensor 1) or 103 (sensor 2).
    pub id: u16,
    /// Time/distance fields.
    pub time: TimeFields,
    /// Latitude [deg], longitude [deg], altitude [m].
    pub lla: [f64; 3],
    /// Along-track, across-track, down velocity [m/s].
    pub velocity: [f32; 3],
    /// Roll, pitch, heading [deg] (Tate-Bryant).
    pub rph: [f64; 3],
    /// Wander angle [deg].
    pub wander: f64,
    /// Heave [m], positive down.
    pub heave: f32,
    /// Angular rates [deg/s].
    pub rate: [f32; 3],
    /// Accelerations [m/s^2].
    pub accel: [f32; 3],
}

impl SensorNavigation {
    /// Byte count (Table 29).
    pub const BYTE_COUNT: u16 = 128;

    /// Parse a checked Group 102 or 103.
    pub fn parse<T: AsRef<[u8]>>(g: &Group<T>) -> Result<Self, Error> {
        check(g, &[102, 103], Self::BYTE_COUNT)?;
        let d = g.data();
        let (lla, velocity, rph, wander) = read_pva(d);
        Ok(Self {
            id: g.id(),
            time: g.time_fields(),
            lla,
            velocity,
            rph,
            wander,
            heave: f32_at(d, 68),
            rate: f32x3(d, 72),
            accel: f32x3(d, 84),
        })
    }

    /// Write the group; its length (136).
    pub fn emit(&self, out: &mut [u8]) -> Option<usize> {
        let mut d = [0u8; 96];
        write_pva(&mut d, (self.lla, self.velocity, self.rph, self.wander));
        put_f32(&mut d, 68, self.heave);
        write_f32s(&mut d, 72, &self.rate);
        write_f32s(&mut d, 84, &self.accel);
        emit_group(self.id, &self.time, &d, out)
    }
}

/// Group 2: RMS errors of the vessel's navigation solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metrics {
    /// Time/distance fields.
    pub time: TimeFields,
    /// North, east, down position RMS [m].
    pub position_rms: [f32; 3],
    /// North, east, down velocity RMS [m/s].
    pub velocity_rms: [f32; 3],
    /// Roll, pitch, heading RMS [deg].
    pub attitude_rms: [f32; 3],
    /// Error ellipse semi-major, semi-minor [m], orientation [deg].
    pub ellipse: [f32; 3],
}

impl Metrics {
    /// Group ID.
    pub const ID: u16 = 2;
    /// Byte count (Table 6).
    pub const BYTE_COUNT: u16 = 80;

    /// Parse a checked Group 2.
    pub fn parse<T: AsRef<[u8]>>(g: &Group<T>) -> Result<Self, Error> {
        check(g, &[Self::ID], Self::BYTE_COUNT)?;
        let d = g.data();
        Ok(Self {
            time: g.time_fields(),
            position_rms: f32x3(d, 0),
            velocity_rms: f32x3(d, 12),
            attitude_rms: f32x3(d, 24),
            ellipse: f32x3(d, 36),
        })
    }

    /// Write the group; its length (88).
    pub fn emit(&self, out: &mut [u8]) -> Option<usize> {
        let mut d = [0u8; 48];
        let all = [
            self.position_rms,
            self.velocity_rms,
            self.attitude_rms,
            self.ellipse,
        ];
        write_f32s(&mut d, 0, all.as_flattened());
        emit_group(Self::ID, &self.time, &d, out)
    }
}

/// Group 7: the time of the last PPS and the POS's synchronization to GPS time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PpsTime {
    /// Time/distance fields (the PPS's time).
    pub time: TimeFields,
    /// PPS pulses since power-up.
    pub pps_count: u32,
    /// Synchronization status.
    pub sync: TimeSync,
}

impl PpsTime {
    /// Group ID.
    pub const ID: u16 = 7;
    /// Byte count (Table 15).
    pub const BYTE_COUNT: u16 = 36;

    /// Parse a checked Group 7.
    pub fn parse<T: AsRef<[u8]>>(g: &Group<T>) -> Result<Self, Error> {
        check(g, &[Self::ID], Self::BYTE_COUNT)?;
        let d = g.data();
        Ok(Self {
            time: g.time_fields(),
            pps_count: le32(d, 0),
            sync: TimeSync::from_byte(d[4]),
        })
    }

    /// Write the group; its length (44).
    pub fn emit(&self, out: &mut [u8]) -> Option<usize> {
        let mut d = [0u8; 5];
        d[..4].copy_from_slice(&self.pps_count.to_le_bytes());
        d[4] = self.sync.to_byte();
        emit_group(Self::ID, &self.time, &d, out)
    }
}

/// Group 3: the primary GNSS receiver's status; the calibration takes the GPS week and the
/// GPS - UTC offset from it (Table 7: variable length, 20 bytes per channel; Table 9).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssStatus {
    /// Time/distance fields.
    pub time: TimeFields,
    /// Navigation solution status (Table 9: -1 unknown, 0 no data, 1-2 C/A, 3-4 DGPS, 5-7 RTK,
    /// ...).
    pub solution: i8,
    /// Satellites tracked.
    pub satellites: u8,
    /// Channels in the group (their status blocks are not kept).
    pub channels: u16,
    /// HDOP, VDOP.
    pub dop: [f32; 2],
    /// GPS/UTC week number (0: not available).
    pub week: u32,
    /// GPS time - UTC time [s].
    pub utc_offset: f64,
    /// GNSS receiver type (Table 12).
    pub receiver: u16,
}

impl GnssStatus {
    /// Group ID.
    pub const ID: u16 = 3;

    /// Parse a checked Group 3 (byte count 76 + 20 per channel).
    pub fn parse<T: AsRef<[u8]>>(g: &Group<T>) -> Result<Self, Error> {
        if g.is_message() || g.id() != Self::ID {
            return Err(Error::WrongGroup { found: g.id() });
        }
        let d = g.data();
        let c = if d.len() >= 4 {
            usize::from(super::group::le16(d, 2))
        } else {
            usize::MAX
        };
        let expected = 76 + c;
        if !c.is_multiple_of(20) || usize::from(g.byte_count()) != expected || d.len() < 44 + c {
            return Err(Error::WrongSize {
                id: Self::ID,
                expected: u16::try_from(expected).unwrap_or(u16::MAX),
                found: g.byte_count(),
            });
        }
        let k = 4 + c;
        Ok(Self {
            time: g.time_fields(),
            solution: d[0] as i8,
            satellites: d[1],
            channels: (c / 20) as u16,
            dop: [f32_at(d, k), f32_at(d, k + 4)],
            week: le32(d, k + 14),
            utc_offset: f64_at(d, k + 18),
            receiver: super::group::le16(d, k + 34),
        })
    }

    /// Write the group with no channel blocks; its length (84).
    pub fn emit(&self, out: &mut [u8]) -> Option<usize> {
        let mut d = [0u8; 44];
        d[0] = self.solution as u8;
        d[1] = self.satellites;
        put_f32(&mut d, 4, self.dop[0]);
        put_f32(&mut d, 8, self.dop[1]);
        d[18..22].copy_from_slice(&self.week.to_le_bytes());
        put_f64(&mut d, 22, self.utc_offset);
        d[38..40].copy_from_slice(&self.receiver.to_le_bytes());
        emit_group(Self::ID, &self.time, &d, out)
    }
}

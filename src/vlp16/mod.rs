//! Velodyne VLP-16 (Puck) wire formats: data packets (UDP 2368) and position packets (UDP 8308).
//!
//! References: VLP-16 User Manual 63-9243 Rev. E, section 9 ("Sensor Data") and appendix B
//! (timing), and `docs/PROTOCOLS.md`, which records where real devices differ from it.
//!
//! - [`data`]: the 1206-byte data packet view ([`DataPacket`]) with its emit side.
//! - [`position`]: the 512-byte position packet view ([`PositionPacket`]), PPS status and the
//!   NMEA sentence parsed into UTC.
//! - [`firing`]: per-firing time offsets, azimuth interpolation and the point in the sensor frame.
//!
//! Laser geometry (manual table 9-1 and section 9.3.1.3): [`ELEVATION_DEG`],
//! [`VERTICAL_OFFSET_M`].

pub mod data;
pub mod firing;
pub mod position;

pub use data::{BlockRepr, DataPacket, DataRepr};
pub use firing::{decode, Point, PointBuf, Return, POINTS_PER_PACKET};
pub use position::{NmeaTime, PositionPacket, PositionRepr, PpsStatus};

use core::fmt;

/// UDP destination port of data packets (manual section 9.3, factory default).
pub const DATA_PORT: u16 = 2368;
/// UDP destination port of position packets (manual section 9.4, factory default).
pub const POSITION_PORT: u16 = 8308;

/// Lasers per firing sequence.
pub const LASERS: usize = 16;

/// Laser id (firing order 0..15) -> elevation angle in degrees (manual table 9-1).
pub const ELEVATION_DEG: [i8; LASERS] =
    [-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15];

/// cos(elevation) per laser id: the table that spares a trig call per point.
pub(crate) const COS_ELEVATION: [f32; LASERS] = [
    0.965_925_8,
    0.999_847_7,
    0.974_370_06,
    0.998_629_5,
    0.981_627_2,
    0.996_194_7,
    0.987_688_34,
    0.992_546_15,
    0.992_546_15,
    0.987_688_34,
    0.996_194_7,
    0.981_627_2,
    0.998_629_5,
    0.974_370_06,
    0.999_847_7,
    0.965_925_8,
];

/// sin(elevation) per laser id.
pub(crate) const SIN_ELEVATION: [f32; LASERS] = [
    -0.258_819_04,
    0.017_452_406,
    -0.224_951_05,
    0.052_335_955,
    -0.190_809,
    0.087_155_74,
    -0.156_434_46,
    0.121_869_34,
    -0.121_869_34,
    0.156_434_46,
    -0.087_155_74,
    0.190_809,
    -0.052_335_955,
    0.224_951_05,
    -0.017_452_406,
    0.258_819_04,
];

/// Vertical beam-origin offset per laser id, metres, added to z (manual section 9.3.1.3;
/// = 41.91 mm * tan(-elevation), rounded as the manual prints it).
pub const VERTICAL_OFFSET_M: [f64; LASERS] = [
    0.0112, -0.0007, 0.0097, -0.0022, 0.0081, -0.0037, 0.0066, -0.0051, 0.0051, -0.0066, 0.0037,
    -0.0081, 0.0022, -0.0097, 0.0007, -0.0112,
];

/// cos(elevation) per laser id, f64, for georeferencing (eq. 1).
#[allow(clippy::excessive_precision)]
pub const COS_ELEVATION_F64: [f64; LASERS] = [
    0.9659258262890683,
    0.9998476951563913,
    0.9743700647852352,
    0.9986295347545738,
    0.981627183447664,
    0.9961946980917455,
    0.9876883405951378,
    0.992546151641322,
    0.992546151641322,
    0.9876883405951378,
    0.9961946980917455,
    0.981627183447664,
    0.9986295347545738,
    0.9743700647852352,
    0.9998476951563913,
    0.9659258262890683,
];

/// sin(elevation) per laser id, f64.
#[allow(clippy::excessive_precision)]
pub const SIN_ELEVATION_F64: [f64; LASERS] = [
    -0.25881904510252074,
    0.01745240643728351,
    -0.224951054343865,
    0.052335956242943835,
    -0.1908089953765448,
    0.08715574274765817,
    -0.15643446504023087,
    0.12186934340514748,
    -0.12186934340514748,
    0.15643446504023087,
    -0.08715574274765817,
    0.1908089953765448,
    -0.052335956242943835,
    0.224951054343865,
    -0.01745240643728351,
    0.25881904510252074,
];

/// Elevation of a laser in radians.
pub fn elevation_rad(laser: usize) -> f64 {
    f64::from(ELEVATION_DEG[laser % LASERS]).to_radians()
}

/// Return mode byte at data-packet offset 1204 (manual section 9.3.1.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ReturnMode {
    /// 0x37: single return, strongest.
    Strongest,
    /// 0x38: single return, last.
    Last,
    /// 0x39: dual return (blocks in pairs: even = last, odd = strongest or second strongest).
    Dual,
}

impl ReturnMode {
    /// Parse the wire byte.
    pub fn from_byte(b: u8) -> Result<Self, Error> {
        match b {
            0x37 => Ok(Self::Strongest),
            0x38 => Ok(Self::Last),
            0x39 => Ok(Self::Dual),
            found => Err(Error::UnknownReturnMode { found }),
        }
    }

    /// The wire byte.
    pub fn to_byte(self) -> u8 {
        match self {
            Self::Strongest => 0x37,
            Self::Last => 0x38,
            Self::Dual => 0x39,
        }
    }

    /// Data packets per second at any rotation rate (manual appendix B: 754 single, 1508 dual).
    pub fn packets_per_second(self) -> f64 {
        let per = 1e6 / (12.0 * 110.592); // 753.5 packets/s with 12 single-return blocks
        match self {
            Self::Dual => 2.0 * per,
            _ => per,
        }
    }
}

/// Product id byte at data-packet offset 1205. Not to be trusted alone: early VLP-16 firmware
/// writes 0x21 (PROTOCOLS.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Product {
    /// 0x21: HDL-32E, or a VLP-16 on early firmware.
    Hdl32eOrEarlyVlp16,
    /// 0x22: VLP-16 / Puck LITE.
    Vlp16,
    /// 0x24: Puck Hi-Res.
    PuckHiRes,
    /// Anything else.
    Other(u8),
}

impl From<u8> for Product {
    fn from(b: u8) -> Self {
        match b {
            0x21 => Self::Hdl32eOrEarlyVlp16,
            0x22 => Self::Vlp16,
            0x24 => Self::PuckHiRes,
            other => Self::Other(other),
        }
    }
}

/// Why bytes are not a VLP-16 packet. Each variant says what was expected and what was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Error {
    /// The buffer is shorter than the packet layout needs.
    Truncated {
        /// Bytes the layout needs.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// A data block does not start with 0xFF 0xEE.
    BadBlockFlag {
        /// Block index 0..11.
        block: u8,
        /// The two bytes found, big-endian as they appear on the wire.
        found: u16,
    },
    /// A block azimuth above 36000 hundredths of a degree (36000 is read as 0).
    BadAzimuth {
        /// Block index 0..11.
        block: u8,
        /// The value found.
        found: u16,
    },
    /// A return-mode byte other than 0x37, 0x38, 0x39.
    UnknownReturnMode {
        /// The byte found.
        found: u8,
    },
    /// The position packet's NMEA field holds no parsable sentence.
    BadNmea,
}

impl Error {
    /// A short, stable name for counting skips by reason.
    pub fn reason(&self) -> &'static str {
        match self {
            Error::Truncated { .. } => "truncated packet",
            Error::BadBlockFlag { .. } => "bad block flag",
            Error::BadAzimuth { .. } => "bad azimuth",
            Error::UnknownReturnMode { .. } => "unknown return mode",
            Error::BadNmea => "bad NMEA sentence",
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Truncated { expected, got } => {
                write!(
                    f,
                    "truncated VLP-16 packet: expected {expected} bytes, got {got}"
                )
            }
            Error::BadBlockFlag { block, found } => write!(
                f,
                "data block {block}: expected flag 0xFFEE, found 0x{found:04X}"
            ),
            Error::BadAzimuth { block, found } => write!(
                f,
                "data block {block}: azimuth {found} above 36000 (0.01 deg)"
            ),
            Error::UnknownReturnMode { found } => write!(
                f,
                "return mode byte 0x{found:02X}: expected 0x37, 0x38 or 0x39"
            ),
            Error::BadNmea => write!(f, "position packet: no parsable NMEA sentence"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Error {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trig_tables_match_elevations() {
        for l in 0..LASERS {
            let w = elevation_rad(l);
            assert!((f64::from(COS_ELEVATION[l]) - libm::cos(w)).abs() < 1e-7);
            assert!((f64::from(SIN_ELEVATION[l]) - libm::sin(w)).abs() < 1e-7);
        }
    }

    #[test]
    fn f64_trig_tables_match_elevations() {
        for l in 0..LASERS {
            let w = elevation_rad(l);
            assert!((COS_ELEVATION_F64[l] - libm::cos(w)).abs() < 1e-16);
            assert!((SIN_ELEVATION_F64[l] - libm::sin(w)).abs() < 1e-16);
        }
    }

    #[test]
    fn vertical_offsets_follow_the_manual_formula() {
        // Manual 9.3.1.3: offset = 41.91 mm * tan(-elevation), printed to 0.1 mm.
        for (l, &off) in VERTICAL_OFFSET_M.iter().enumerate() {
            let v = 0.04191 * libm::tan(-elevation_rad(l));
            assert!((off - v).abs() < 0.00006, "laser {l}");
        }
    }

    #[test]
    fn packet_rates_match_the_manual() {
        assert!((ReturnMode::Strongest.packets_per_second() - 754.0).abs() < 1.0);
        assert!((ReturnMode::Dual.packets_per_second() - 1508.0).abs() < 1.0);
    }
}

#[cfg(test)]
#[path = "tests.rs"]
mod tests_packets;

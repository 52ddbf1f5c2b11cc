//! Velodyne wire formats: data packets (UDP 2368) and position packets (UDP 8308) of the
//! VLP-16 / Puck LITE, Puck Hi-Res, HDL-32E and VLP-32C.
//!
//! References: VLP-16 User Manual 63-9243 Rev. E, section 9 ("Sensor Data") and appendix B
//! (timing); the other models' manuals as [`model`] cites them; and `docs/PROTOCOLS.md`, which
//! records where real devices differ from them.
//!
//! - [`data`]: the 1206-byte data packet view ([`DataPacket`]) with its emit side (one layout
//!   for every model).
//! - [`position`]: the 512-byte position packet view ([`PositionPacket`]), PPS status and the
//!   NMEA sentence parsed into UTC.
//! - [`model`]: each model's lasers, firing timing and range unit; [`Detector`] checks the
//!   product byte against the packet period.
//! - [`firing`]: per-firing time offsets, azimuth interpolation and the point in the sensor frame.

pub mod beam;
pub mod data;
pub mod extent;
pub mod firing;
pub mod model;
pub mod position;
mod tables;

pub use beam::Beam;
pub use data::{BlockRepr, DataPacket, DataRepr};
pub use extent::{extent, Extent};
pub use firing::{decode, decode_as, Point, PointBuf, Return, POINTS_PER_PACKET};
pub use model::{Detector, Identity, Model, MAX_LASERS};
pub use position::{NmeaTime, PositionPacket, PositionRepr, PpsStatus};

use core::fmt;

/// UDP destination port of data packets (manual section 9.3, factory default).
pub const DATA_PORT: u16 = 2368;
/// UDP destination port of position packets (manual section 9.4, factory default).
pub const POSITION_PORT: u16 = 8308;

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
}

/// Why bytes are not a Velodyne packet. Each variant says what was expected and what was found.
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
    /// A product-id byte (offset 1205) no known model writes.
    UnknownProduct {
        /// The byte found.
        found: u8,
    },
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
            Error::UnknownProduct { .. } => "unknown product byte",
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Truncated { expected, got } => {
                write!(
                    f,
                    "truncated Velodyne packet: expected {expected} bytes, got {got}"
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
            Error::UnknownProduct { found } => write!(
                f,
                "product byte 0x{found:02X}: not a VLP-16 (0x22), Puck Hi-Res (0x24), HDL-32E \
                 (0x21) or VLP-32C (0x28); choose the model with --model"
            ),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Error {}

#[cfg(test)]
#[path = "tests.rs"]
mod tests_packets;

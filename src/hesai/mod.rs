//! Hesai PandarXT16 / XT32 / QT64 / QT128 point cloud data packets (UDP 2368) and GPS
//! packets (UDP 10110): checked views, the per-unit angle corrections that turn a return into a
//! point, and each return's firing time.
//!
//! References: Hesai "PandarXT-32 User Manual" and "PandarXT-16 User Manual" (3.1 Point cloud
//! data packet, 3.2 GPS data packet, appendix "Absolute Time and Laser Firing Time"), "PandarQT
//! User Manual" (the same sections, 4 blocks of 64 channels), "QT128C2X User Manual" (2 blocks of
//! 128 channels, CRCs and functional safety); `docs/PROTOCOLS.md` records what
//! real packets showed (tier4/nebula's decoder test bags).
//!
//! - [`packet`]: the data packet view ([`DataPacket`]): pre-header, header, blocks, tail.
//! - [`gps`]: the GPS packet view ([`GpsPacket`]): date, time, NMEA, PPS lock.
//! - [`geometry`]: the angle corrections ([`Corrections`]) and a return's point.
//!
//! Unlike an Ouster's, a Hesai packet says which layout it has (protocol version, channels and
//! blocks in its header); the angles are the unit's own correction file.

pub mod geometry;
pub mod gps;
pub mod packet;

pub use geometry::{points, BlockGeometry, Corrections, MAX_CHANNELS};
pub use gps::GpsPacket;
pub use packet::{DataPacket, Model, ReturnMode};

use crate::time::UtcDateTime;
use core::fmt;

/// A date and time as a Hesai sends them (`year` in full; month, day, hour, minute, second),
/// `None` when they are not one.
fn date_time(year: i32, [month, day, hour, minute, second]: [u8; 5]) -> Option<UtcDateTime> {
    let ok = (1..=12).contains(&month)
        && (1..=31).contains(&day)
        && hour < 24
        && minute < 60
        && second <= 60;
    ok.then_some(UtcDateTime {
        year,
        month,
        day,
        hour,
        minute,
        second,
        nanos: 0,
    })
}

/// UDP destination port of point cloud data packets (the factory default "LiDAR
/// Destination Port").
pub const DATA_PORT: u16 = 2368;
/// UDP destination port of GPS packets (the default "GPS Port").
pub const GPS_PORT: u16 = 10110;

/// What is wrong with a packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// Not the start of a Hesai packet (`0xEE 0xFF` for data, `0xFF 0xEE` for GPS).
    Start {
        /// The first two bytes.
        found: [u8; 2],
    },
    /// A protocol version, channel and block count that is none of the models read here.
    Layout {
        /// Protocol version major and minor.
        version: [u8; 2],
        /// Channels ("Laser Num").
        channels: u8,
        /// Blocks per packet.
        blocks: u8,
    },
    /// The length is not the one the header's layout gives.
    Length {
        /// What the layout gives [bytes].
        expected: usize,
        /// What arrived.
        got: usize,
    },
    /// A tail return-mode byte that is none of the manual's.
    ReturnMode {
        /// The byte.
        found: u8,
    },
    /// A QT128 packet whose body or tail CRC-32 disagrees (damaged).
    Crc {
        /// The packet's.
        stored: u32,
        /// The bytes'.
        computed: u32,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Start { found } => write!(
                f,
                "Hesai packet starting {:02x} {:02x} where a data packet starts ee ff",
                found[0], found[1]
            ),
            Error::Layout {
                version,
                channels,
                blocks,
            } => write!(
                f,
                "Hesai protocol {}.{} with {channels} channels x {blocks} blocks: not a PandarXT16 (6.1, 16 x 8), XT32 (6.1, 32 x 8), QT64 (3.1, 64 x 4) or QT128 (3.2, 128 x 2)",
                version[0], version[1]
            ),
            Error::Length { expected, got } => write!(
                f,
                "Hesai packet of {got} bytes where its header's layout gives {expected}"
            ),
            Error::ReturnMode { found } => write!(
                f,
                "Hesai return mode {found:#04x}: not one of the manual's (0x33-0x3e)"
            ),
            Error::Crc { stored, computed } => write!(
                f,
                "Hesai CRC-32 {stored:#010x} where the packet's bytes give {computed:#010x}"
            ),
        }
    }
}

#[cfg(test)]
impl std::error::Error for Error {}

#[cfg(test)]
mod tests;

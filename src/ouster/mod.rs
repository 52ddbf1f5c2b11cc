//! Ouster OS0 / OS1 / OS2 lidar packets (UDP 7502): checked views of every column and pixel
//! for the profiles firmware 2.x and 3.x send, and the beam geometry that turns a pixel's range
//! into a point in the sensor frame.
//!
//! References: Ouster "Sensor Data" (firmware user manual, sections "Lidar Data Packet Format"
//! for the LEGACY layout and "Lidar Data Profiles" for the others) and "Lidar Range to XYZ"
//! (eq. 1-3 of the coordinate frames chapter); `docs/PROTOCOLS.md` records what real captures
//! showed.
//!
//! - [`profile`]: the packet's layout as the sensor's metadata declares it ([`Format`]).
//! - [`packet`]: the lidar packet view ([`LidarPacket`]): header, columns, pixels.
//! - [`geometry`]: the beams' angles and origin offset, the lidar-to-sensor transform, and
//!   the point of a pixel ([`Intrinsics::point`]).
//!
//! Unlike a Velodyne's, an Ouster packet does not say which layout it has: the metadata does,
//! and [`LidarPacket::new_checked`] refuses a packet whose length or type disagrees with it.

pub mod geometry;
pub mod packet;
pub mod profile;

pub use geometry::{BeamPoint, ColumnGeometry, Intrinsics, MAX_BEAMS, MAX_COLUMNS};
pub use packet::{Column, LidarPacket, Pixel};
pub use profile::{Format, HeaderKind, Profile};

use core::fmt;

/// UDP destination port of lidar packets (the sensor's default `udp_port_lidar`).
pub const LIDAR_PORT: u16 = 7502;
/// UDP destination port of IMU packets (the default `udp_port_imu`).
pub const IMU_PORT: u16 = 7503;

/// What is wrong with a packet or a format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// The packet's length is not the one its format gives.
    Length {
        /// What the format gives [bytes].
        expected: usize,
        /// What arrived.
        got: usize,
    },
    /// A profile header's packet type is not a lidar packet's (1).
    PacketType {
        /// What the header holds.
        found: u16,
    },
    /// The footer's CRC-64 disagrees with the packet (a packet of firmware 3.x damaged).
    Crc {
        /// The footer's.
        stored: u64,
        /// The packet's.
        computed: u64,
    },
    /// A format outside what a sensor sends (beams, columns, or a packet over 65,535 bytes).
    Format,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Length { expected, got } => write!(
                f,
                "Ouster lidar packet of {got} bytes where the metadata's format gives {expected}"
            ),
            Error::PacketType { found } => write!(
                f,
                "Ouster packet type {found:#06x} where a lidar packet has 0x0001"
            ),
            Error::Crc { stored, computed } => write!(
                f,
                "Ouster packet footer CRC-64 {stored:#018x} where the packet's is {computed:#018x}"
            ),
            Error::Format => write!(
                f,
                "an Ouster data format outside 1-128 beams, 1-64 columns per packet"
            ),
        }
    }
}

#[cfg(test)]
impl std::error::Error for Error {}

//! Applanix POS MV real-time output: the `$GRP` groups of its Ethernet Display (UDP 5600),
//! Real-Time Data (UDP 5602) and Logging Data (TCP 5603) ports, and of its logged `.000`
//! files, which hold the same bytes (POS MV V5 User ICD, PUBS-ICD-004089 rev. 10, section 3).
//!
//! - [`group`]: the checked group view (Table 2: `$GRP`, ID, byte count, time/distance fields,
//!   data, pad, checksum, `$#`) and the emit side that pads and checksums.
//! - [`nav`]: Group 1 (vessel position, velocity, attitude & dynamics, Table 4), Group 102/103
//!   (sensor 1/2, Table 29), Group 2 (performance metrics, Table 6) and Group 7 (PPS time
//!   recovery and status, Table 15), each with its emit side.
//! - [`framer`]: the streaming framer: any chunking in, checked groups (and `$MSG` messages)
//!   out, resync after garbage, checksum failures counted; fixed buffer, no heap.
//! - [`pose`]: the timestamped pose Group 1 (or 102/103) carries, with the reasons one is not
//!   usable (time on the POS clock, invalid fields, alignment).
//!
//! Byte order is Intel (little-endian) throughout (Appendix A); a field of all-ones bytes is
//! the ICD's invalid value (Table 85).

pub mod framer;
pub mod group;
pub mod nav;
pub mod pose;

pub use framer::{Framed, Framer, Item, Stats};
pub use group::{emit_group, Group, TimeFields, TimeType};
pub use nav::{Alignment, GnssStatus, Metrics, Navigation, PpsTime, SensorNavigation, TimeSync};
pub use pose::{Pose, PoseError};

use core::fmt;

/// UDP port of the Display Port (ICD section 2; about 1 Hz).
pub const DISPLAY_PORT: u16 = 5600;
/// UDP port of the Real-Time Data Port (ICD section 2; up to the IMU rate).
pub const REALTIME_PORT: u16 = 5602;
/// TCP port of the Logging Data Port.
pub const LOGGING_PORT: u16 = 5603;

/// Why bytes are not a valid POS MV group.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// Fewer bytes than the header or the byte count needs.
    Truncated {
        /// Bytes needed (None: not even the 8-byte header).
        expected: Option<usize>,
        /// Bytes given.
        got: usize,
    },
    /// The first four bytes are neither `$GRP` nor `$MSG`.
    NoStart,
    /// The total length (byte count + 8) is not a multiple of four (Table 2's pad rule) or is
    /// shorter than the time/distance fields and footer.
    BadLength {
        /// The byte count field.
        byte_count: u16,
    },
    /// The last two bytes are not `$#`.
    BadEnd {
        /// The two bytes found.
        found: [u8; 2],
    },
    /// The 16-bit words of the group do not sum to zero (ICD 3.2.3).
    Checksum {
        /// The sum found (0 when valid).
        sum: u16,
    },
    /// A group whose byte count is not the one its table fixes.
    WrongSize {
        /// Group ID.
        id: u16,
        /// Byte count expected.
        expected: u16,
        /// Byte count found.
        found: u16,
    },
    /// A group other than the one asked for.
    WrongGroup {
        /// Group ID found.
        found: u16,
    },
}

impl Error {
    /// A short, stable name for counting skips by reason.
    pub fn reason(&self) -> &'static str {
        match self {
            Error::Truncated { .. } => "truncated group",
            Error::NoStart => "no $GRP start",
            Error::BadLength { .. } => "bad byte count",
            Error::BadEnd { .. } => "no $# end",
            Error::Checksum { .. } => "checksum failure",
            Error::WrongSize { .. } => "wrong group size",
            Error::WrongGroup { .. } => "wrong group",
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Truncated {
                expected: Some(e),
                got,
            } => write!(f, "POS MV group: expected {e} bytes, got {got}"),
            Error::Truncated {
                expected: None,
                got,
            } => write!(f, "POS MV group: {got} bytes, fewer than its 8-byte header"),
            Error::NoStart => write!(f, "POS MV group: expected $GRP or $MSG"),
            Error::BadLength { byte_count } => write!(
                f,
                "POS MV group: byte count {byte_count} is not a group length (a multiple of 4, \
                 minus 8, at least 30)"
            ),
            Error::BadEnd { found } => write!(
                f,
                "POS MV group: expected the end $#, found 0x{:02X} 0x{:02X}",
                found[0], found[1]
            ),
            Error::Checksum { sum } => write!(
                f,
                "POS MV group: its 16-bit words sum to 0x{sum:04X}, expected 0"
            ),
            Error::WrongSize {
                id,
                expected,
                found,
            } => write!(
                f,
                "POS MV group {id}: byte count {found}, the ICD's is {expected}"
            ),
            Error::WrongGroup { found } => {
                write!(f, "POS MV: group {found} is not the one asked for")
            }
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Error {}

#[cfg(test)]
mod tests;

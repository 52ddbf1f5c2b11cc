//! VectorNav VN-200 (and VN-100/300/310) serial protocol: binary output frames, ASCII `$VN`
//! sentences, and the other devices' NMEA that shares the line.
//!
//! - [`fields`]: the group/field table (PROTOCOLS.md "VectorNav binary output").
//! - [`binary`]: the checked frame view, typed accessors, the emit side, CRC-16/XMODEM.
//! - [`ascii`]: `$VN...` sentences with either checksum kind, typed INS/YMR/YPR/QTN/GPS and
//!   register replies.
//! - [`framer`]: the streaming framer: any chunking in, frames and sentences out, resync on
//!   0xFA / `$`, fixed buffer, no heap.
//! - [`pose`]: the timestamped pose a frame or `$VNINS` carries.
//! - [`command`]: the emit side of the ASCII commands that configure a unit (registers 5, 6,
//!   75-77) and the echoed register values read back.

pub mod ascii;
pub mod binary;
pub mod command;
pub mod fields;
pub mod framer;
pub mod pose;

pub use binary::{emit, Frame, Masks};
pub use fields::Group;
pub use framer::{Framed, Framer, Item, Stats};
pub use pose::{Attitude, Pose};

use core::fmt;

/// Why bytes are not a valid VectorNav frame or sentence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// More bytes are needed to decide.
    Incomplete,
    /// The first byte is not 0xFA.
    NoSync,
    /// A group byte with no group set.
    NoGroups,
    /// A group byte naming groups we do not know (a second group byte).
    UnknownGroup {
        /// The group byte.
        byte: u8,
    },
    /// A mask bit naming a field whose size we do not know.
    UnknownField {
        /// Group index.
        group: u8,
        /// Field bit.
        bit: u8,
    },
    /// A frame shorter or longer than its header says.
    Truncated {
        /// The length the header implies (None: not even the header is complete).
        expected: Option<usize>,
        /// The bytes given.
        got: usize,
    },
    /// The CRC over the frame does not match the one sent.
    Crc {
        /// Computed over the bytes.
        computed: u16,
        /// Sent in the frame.
        sent: u16,
    },
    /// A frame longer than the framer's buffer.
    TooLong {
        /// Its length.
        len: usize,
    },
    /// An output buffer too small for the frame.
    BufferTooSmall {
        /// Bytes needed.
        needed: usize,
    },
    /// An ASCII sentence whose checksum does not match.
    AsciiChecksum {
        /// Computed over the sentence.
        computed: u16,
        /// Sent after `*`.
        sent: u16,
    },
    /// An ASCII line that is not a well-formed sentence.
    BadSentence,
    /// A sentence with a missing or unparsable field.
    BadField {
        /// Field index (0 = first after the name).
        index: u8,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Incomplete => write!(f, "incomplete frame"),
            Error::NoSync => write!(f, "expected sync byte 0xFA"),
            Error::NoGroups => write!(f, "group byte 0x00: no groups"),
            Error::UnknownGroup { byte } => {
                write!(f, "group byte 0x{byte:02X} names unknown groups")
            }
            Error::UnknownField { group, bit } => {
                write!(f, "group {group} field bit {bit} is unknown")
            }
            Error::Truncated {
                expected: Some(e),
                got,
            } => write!(f, "frame length: expected {e} bytes, got {got}"),
            Error::Truncated {
                expected: None,
                got,
            } => write!(f, "frame header incomplete in {got} bytes"),
            Error::Crc { computed, sent } => write!(
                f,
                "CRC mismatch: computed 0x{computed:04X}, sent 0x{sent:04X}"
            ),
            Error::TooLong { len } => write!(f, "frame of {len} bytes exceeds the framer buffer"),
            Error::BufferTooSmall { needed } => {
                write!(f, "output buffer too small: {needed} bytes needed")
            }
            Error::AsciiChecksum { computed, sent } => {
                write!(
                    f,
                    "ASCII checksum mismatch: computed {computed:02X}, sent {sent:02X}"
                )
            }
            Error::BadSentence => write!(f, "malformed ASCII sentence"),
            Error::BadField { index } => write!(f, "ASCII field {index} missing or malformed"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Error {}

#[cfg(test)]
mod tests;

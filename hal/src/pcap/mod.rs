//! Capture files: classic libpcap (micro- and nanosecond, either byte order) and pcapng, read
//! as a stream with a fixed working buffer. Records are parsed with `pcap-file`, frames sliced
//! with `etherparse`'s lax slicer (real captures carry IPv4 lengths that do not match the frame:
//! PROTOCOLS.md), and the UDP payload is taken from the UDP length bounded by the captured bytes.
//!
//! Nothing is copied per packet: a [`Datagram`]'s payload borrows the reader's buffer.

//!
//! - [`read`]: [`PcapSource`], the streaming reader (classic and pcapng);
//! - [`chain`]: [`PcapChain`], several files (rotated logs) in time order as one source;
//! - [`slice`]: link layer -> IPv4 -> UDP ([`slice_udp`]) and its inverse for writers
//!   ([`build_udp_frame`]);
//! - [`write`]: [`PcapWriter`], classic pcap as tcpdump writes it.

use std::fmt;
use std::io;

pub mod chain;
pub mod defrag;
pub mod read;
pub mod slice;
pub mod write;

pub use chain::{ChainError, ChainFault, PcapChain};
pub use read::PcapSource;
pub use slice::{
    build_fragment_frame, build_udp_frame, slice_fragment, slice_udp, udp_fragments, Fragment,
    Piece, UdpEndpoints, FRAGMENT_BYTES,
};
pub use write::PcapWriter;

/// Largest record or block we accept; anything larger means a corrupt length field.
pub const MAX_RECORD: usize = 1 << 20;

/// Why a capture file cannot be read (further).
#[derive(Debug)]
#[non_exhaustive]
pub enum PcapError {
    /// The operating system refused a read.
    Io(io::Error),
    /// The first four bytes are neither a pcap nor a pcapng magic number.
    BadMagic {
        /// The bytes found.
        found: [u8; 4],
    },
    /// The file is shorter than its global header.
    TruncatedHeader {
        /// Bytes the header needs.
        expected: usize,
        /// Bytes in the file.
        got: usize,
    },
    /// A header, record or block that cannot be parsed; reading stops here.
    Corrupt {
        /// Byte offset of the record or block.
        offset: u64,
        /// What was wrong.
        what: String,
    },
}

impl fmt::Display for PcapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PcapError::Io(e) => write!(f, "read error: {e}"),
            PcapError::BadMagic { found } => write!(
                f,
                "offset 0: not a pcap or pcapng file (magic {:02X} {:02X} {:02X} {:02X}; expected \
                 D4 C3 B2 A1, 4D 3C B2 A1 or their byte swaps, or 0A 0D 0D 0A)",
                found[0], found[1], found[2], found[3]
            ),
            PcapError::TruncatedHeader { expected, got } => {
                write!(
                    f,
                    "offset 0: file header needs {expected} bytes, file has {got}"
                )
            }
            PcapError::Corrupt { offset, what } => write!(f, "offset {offset}: {what}"),
        }
    }
}

impl std::error::Error for PcapError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            PcapError::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<io::Error> for PcapError {
    fn from(e: io::Error) -> Self {
        PcapError::Io(e)
    }
}

//! spherecal-hal: the I/O boundary of spherecal.
//!
//! Small traits for what the core consumes ([`PacketSource`]: UDP datagrams with a receive
//! time) and their std implementations: classic pcap and pcapng files ([`pcap`]). The VLP-16
//! classifier ([`velodyne`]) sits on any packet source and counts every skipped frame by reason.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod clock;
pub mod console;
pub mod packet;
pub mod pcap;
pub mod rawlog;
pub mod rosbag;
pub mod sbet;
pub mod serial;
pub mod udp;
pub mod velodyne;

pub use packet::{Datagram, PacketSource, Record, SkipReason, Tap};

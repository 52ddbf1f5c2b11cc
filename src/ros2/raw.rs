//! spherecal's own raw-log messages (hal `rawlog::mcap_log`, schemas written into each file):
//! `spherecal_msgs/msg/Datagram` (a UDP datagram as received) and
//! `spherecal_msgs/msg/SerialChunk` (one serial read), so that an MCAP raw log reads back as
//! its pcap and serial logs would.

use super::cdr::{Error, Reader};
use super::Time;

/// `spherecal_msgs/msg/Datagram`: `Time stamp`, `uint8[4] src_addr`, `uint16 src_port`,
/// `uint16 dst_port`, `uint8[] payload`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Datagram<'a> {
    /// Receive time (host clock).
    pub stamp: Time,
    /// Sender's IPv4 address.
    pub src_addr: [u8; 4],
    /// Sender's port.
    pub src_port: u16,
    /// Destination port.
    pub dst_port: u16,
    /// The UDP payload.
    pub payload: &'a [u8],
}

impl<'a> Datagram<'a> {
    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let stamp = Time::read(&mut r)?;
        let a = r.bytes(4, "src_addr")?;
        let src_addr = [a[0], a[1], a[2], a[3]];
        let src_port = r.u16("src_port")?;
        let dst_port = r.u16("dst_port")?;
        let n = r.count(1, "payload")? as usize;
        let payload = r.bytes(n, "payload")?;
        Ok(Self {
            stamp,
            src_addr,
            src_port,
            dst_port,
            payload,
        })
    }
}

/// `spherecal_msgs/msg/SerialChunk`: `Time stamp`, `uint64 mono_ns`, `uint32 baud`,
/// `uint8[] data`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialChunk<'a> {
    /// Receive time (host wall clock).
    pub stamp: Time,
    /// Receive time (host monotonic clock) [ns].
    pub mono_ns: u64,
    /// The port's baud rate.
    pub baud: u32,
    /// The bytes read.
    pub data: &'a [u8],
}

impl<'a> SerialChunk<'a> {
    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let stamp = Time::read(&mut r)?;
        let mono_ns = r.u64("mono_ns")?;
        let baud = r.u32("baud")?;
        let n = r.count(1, "data")? as usize;
        let data = r.bytes(n, "data")?;
        Ok(Self {
            stamp,
            mono_ns,
            baud,
            data,
        })
    }
}

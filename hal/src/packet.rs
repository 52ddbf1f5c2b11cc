//! The packet-source trait: what a UDP socket and a capture file both deliver.

use std::fmt;
use std::net::Ipv4Addr;

pub use spherecal::time::HostTime;

/// One UDP/IPv4 datagram, borrowed from the source's buffer.
#[derive(Debug, Clone, Copy)]
pub struct Datagram<'a> {
    /// When it was received (the pcap record time, or the kernel's receive time on a socket).
    pub time: HostTime,
    /// Sender address.
    pub src_addr: Ipv4Addr,
    /// Sender port.
    pub src_port: u16,
    /// Destination port.
    pub dst_port: u16,
    /// UDP payload (from the UDP length field, bounded by the captured bytes).
    pub payload: &'a [u8],
    /// Byte offset of the record in its file (0 for live sockets).
    pub offset: u64,
}

/// Why a captured frame is not handed on.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum SkipReason {
    /// The capture's link type is not one we can slice (pcap LINKTYPE_ value).
    UnsupportedLinkType(u32),
    /// Not an IPv4 packet carrying UDP (ARP, IPv6, TCP, ...).
    NotIpv4Udp,
    /// An IPv4 fragment no datagram can hold (beyond 65,535 bytes, or past its datagram's end);
    /// the others are put back together by the capture reader.
    IpFragment,
    /// Fewer bytes were captured than were on the wire (snap length).
    TruncatedRecord {
        /// Bytes captured.
        captured: u32,
        /// Bytes on the wire.
        original: u32,
    },
    /// The file ends in the middle of a record.
    TruncatedFile {
        /// Bytes left in the file.
        left: usize,
    },
    /// A UDP port that is neither the data nor the position port.
    OtherPort(u16),
    /// A datagram from an address other than the sensor's (live input: the board's
    /// `sensor_addr`).
    OtherSender(Ipv4Addr),
    /// A payload whose length is not the one its port carries.
    WrongPayloadLength {
        /// Destination port.
        port: u16,
        /// Expected payload bytes.
        expected: usize,
        /// Bytes found.
        got: usize,
    },
    /// The bytes have the right length but are not a valid VLP-16 packet.
    Vlp16(spherecal::velodyne::Error),
    /// An Ouster lidar packet that is not the format its metadata declares.
    Ouster(spherecal::ouster::Error),
    /// A Hesai data or GPS packet that is damaged or of a layout not read.
    Hesai(spherecal::hesai::Error),
    /// A ROS 2 message (a bag's `VelodyneScan`) that does not parse as its type.
    BadMessage(spherecal::ros2::cdr::Error),
    /// A bag's `PointCloud2` that does not parse, or whose fields are not the ones read.
    BadCloud(spherecal::ros2::cloud::CloudError),
    /// A cell of a point cloud that is no return (NaN: an organised cloud's empty cell).
    EmptyCell,
    /// A point cloud's return that is not used: why.
    CloudPoint(&'static str),
}

impl SkipReason {
    /// A short, stable name for counting.
    pub fn name(&self) -> &'static str {
        match self {
            SkipReason::UnsupportedLinkType(_) => "unsupported link type",
            SkipReason::NotIpv4Udp => "not IPv4/UDP",
            SkipReason::IpFragment => "IPv4 fragment",
            SkipReason::TruncatedRecord { .. } => "truncated record",
            SkipReason::TruncatedFile { .. } => "truncated file",
            SkipReason::OtherPort(_) => "other port",
            SkipReason::OtherSender(_) => "other sender",
            SkipReason::WrongPayloadLength { .. } => "wrong payload length",
            SkipReason::Vlp16(e) => e.reason(),
            SkipReason::Ouster(spherecal::ouster::Error::PacketType { .. }) => {
                "not an Ouster lidar packet"
            }
            SkipReason::Ouster(spherecal::ouster::Error::Crc { .. }) => "Ouster CRC-64 mismatch",
            SkipReason::Ouster(_) => "not the metadata's packet format",
            SkipReason::Hesai(spherecal::hesai::Error::Layout { .. }) => "not a Hesai model read",
            SkipReason::Hesai(spherecal::hesai::Error::Crc { .. }) => "Hesai CRC-32 mismatch",
            SkipReason::Hesai(_) => "not a Hesai packet",
            SkipReason::BadMessage(_) => "ROS message not parsed",
            SkipReason::BadCloud(_) => "point cloud not read",
            SkipReason::EmptyCell => "empty cell of a point cloud",
            SkipReason::CloudPoint(why) => why,
        }
    }
}

impl fmt::Display for SkipReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SkipReason::UnsupportedLinkType(l) => write!(f, "unsupported link type {l}"),
            SkipReason::NotIpv4Udp => write!(f, "not an IPv4/UDP frame"),
            SkipReason::IpFragment => write!(f, "IPv4 fragment"),
            SkipReason::TruncatedRecord { captured, original } => {
                write!(
                    f,
                    "record truncated: {captured} of {original} bytes captured"
                )
            }
            SkipReason::TruncatedFile { left } => {
                write!(f, "file ends inside a record ({left} bytes left)")
            }
            SkipReason::OtherPort(p) => write!(f, "UDP port {p} is neither data nor position"),
            SkipReason::OtherSender(a) => write!(f, "datagram from {a}, not from the sensor"),
            SkipReason::WrongPayloadLength {
                port,
                expected,
                got,
            } => {
                write!(
                    f,
                    "UDP port {port}: expected a {expected}-byte payload, got {got}"
                )
            }
            SkipReason::Vlp16(e) => write!(f, "{e}"),
            SkipReason::Ouster(e) => write!(f, "{e}"),
            SkipReason::Hesai(e) => write!(f, "{e}"),
            SkipReason::BadMessage(e) => write!(f, "ROS 2 message: {e}"),
            SkipReason::BadCloud(e) => write!(f, "ROS 2 PointCloud2: {e}"),
            SkipReason::EmptyCell => write!(f, "a cell with no return (NaN)"),
            SkipReason::CloudPoint(why) => write!(f, "{why}"),
        }
    }
}

/// What a packet source yields: a datagram, a frame it skipped and why, or (a live source)
/// nothing within its read timeout.
#[derive(Debug, Clone)]
pub enum Record<'a> {
    /// A UDP/IPv4 datagram.
    Udp(Datagram<'a>),
    /// A live source had nothing within its read timeout (the caller may check for shutdown),
    /// or a chain of files moved to its next file; a single file never yields it.
    Idle,
    /// A skipped frame: its byte offset in the file and the reason.
    Skipped {
        /// Byte offset of the record.
        offset: u64,
        /// Why.
        reason: SkipReason,
    },
}

/// A source of UDP datagrams: a capture file, a socket, a simulator.
///
/// A lending iterator: each record borrows the source's buffer until the next call.
pub trait PacketSource {
    /// What can stop the source for good (I/O, a corrupt file header).
    type Error: std::error::Error + Send + Sync + 'static;

    /// The next record, or `None` at the end of the stream.
    fn next_record(&mut self) -> Result<Option<Record<'_>>, Self::Error>;
}

/// A source whose every datagram is first shown to a closure (the rig's raw log and receive
/// counter), as smoltcp's `PcapWriter` wraps a device: the reader downstream sees the same
/// records.
pub struct Tap<S, F> {
    inner: S,
    f: F,
}

impl<S, F> Tap<S, F> {
    /// `inner`, with `f` called on each of its datagrams.
    pub fn new(inner: S, f: F) -> Self {
        Self { inner, f }
    }

    /// The wrapped source.
    pub fn get_ref(&self) -> &S {
        &self.inner
    }
}

impl<S: PacketSource, F: FnMut(&Datagram<'_>)> PacketSource for Tap<S, F> {
    type Error = S::Error;

    fn next_record(&mut self) -> Result<Option<Record<'_>>, Self::Error> {
        let r = self.inner.next_record()?;
        if let Some(Record::Udp(d)) = &r {
            (self.f)(d);
        }
        Ok(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two datagrams and a skip from a fixed list.
    struct List(Vec<Option<&'static [u8]>>, usize);

    impl PacketSource for List {
        type Error = std::io::Error;
        fn next_record(&mut self) -> Result<Option<Record<'_>>, Self::Error> {
            let Some(item) = self.0.get(self.1) else {
                return Ok(None);
            };
            self.1 += 1;
            Ok(Some(match item {
                Some(p) => Record::Udp(Datagram {
                    time: HostTime(self.1 as i64),
                    src_addr: Ipv4Addr::LOCALHOST,
                    src_port: 1,
                    dst_port: 2,
                    payload: p,
                    offset: 0,
                }),
                None => Record::Skipped {
                    offset: 7,
                    reason: SkipReason::NotIpv4Udp,
                },
            }))
        }
    }

    #[test]
    fn tap_sees_every_datagram_and_passes_all_records_on() {
        let mut seen = Vec::new();
        let mut tap = Tap::new(
            List(vec![Some(b"a"), None, Some(b"bc")], 0),
            |d: &Datagram<'_>| seen.push((d.time.0, d.payload.to_vec())),
        );
        let mut kinds = Vec::new();
        while let Some(r) = tap.next_record().unwrap() {
            kinds.push(match r {
                Record::Udp(d) => d.payload.len(),
                Record::Skipped { offset, .. } => offset as usize * 100,
                Record::Idle => 0,
            });
        }
        assert_eq!(tap.get_ref().1, 3);
        drop(tap);
        assert_eq!(kinds, [1, 700, 2]);
        assert_eq!(seen, [(1, b"a".to_vec()), (3, b"bc".to_vec())]);
    }
}

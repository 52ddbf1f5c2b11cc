//! What the rings carry: LiDAR packets classified and checked once ([`LidarItem`], read as
//! [`LidarPacket`]), and poses ([`InsItem`]).

use super::*;
use spherecal::time::GpsTime;
use spherecal_hal::rosbag::clouds::Chunk;

/// What a LiDAR ring item holds (set once, by its checked constructors).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LidarKind {
    /// A data packet.
    Data,
    /// A position packet (its first 512 bytes).
    Position,
    /// Returns of a point cloud.
    Points,
    /// A Hesai data packet (its length held beside it).
    Hesai,
    /// A Hesai GPS packet (512 bytes).
    HesaiGps,
    /// Returns decoded and timed by the reader (an Ouster's), on GPS time.
    Timed,
    /// The stream ended.
    End,
}

/// An item on the LiDAR ring: a packet classified and checked once (smoltcp's `iface`: parse
/// once, pass the typed value down), its payload held in place, so a packet costs one copy
/// into the ring and no allocation. Read it as [`LidarItem::packet`].
#[derive(Clone)]
pub struct LidarItem {
    kind: LidarKind,
    /// When the host received it, if known.
    pub host: Option<HostTime>,
    /// The payload's length (a Hesai packet's 568-1127 bytes).
    len: u16,
    /// A timed chunk's first return [GPS ns].
    gps_ns: i64,
    /// A timed chunk's clock: the columns timed since the previous chunk.
    columns: ColumnsTimed,
    payload: Payload,
}

/// How many of an Ouster's columns were timed by a synchronised clock and how many by one
/// counting from power-on, since the previous timed chunk (the aligner adds them up in its
/// [`crate::state::OusterClock`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ColumnsTimed {
    /// Columns timed by PTP or the sync pulse.
    pub synchronised: u16,
    /// Columns timed by a free-running clock.
    pub free_running: u16,
}

/// What an item holds: a packet's bytes (data: all 1206; position: the first 512), or a
/// cloud's returns (about as many bytes).
#[derive(Clone)]
enum Payload {
    Bytes([u8; 1206]),
    Points(Chunk),
}

/// The checked packet a [`LidarItem`] holds.
pub enum LidarPacket<'a> {
    /// A data packet (1206 bytes).
    Data(DataPacket<&'a [u8]>),
    /// A position packet (its first 512 bytes).
    Position(PositionPacket<&'a [u8]>),
    /// Returns of a point cloud, timed on the host's clock.
    Points(&'a Chunk),
    /// A Hesai data packet.
    Hesai(spherecal::hesai::DataPacket<&'a [u8]>),
    /// A Hesai GPS packet.
    HesaiGps(spherecal::hesai::GpsPacket<&'a [u8]>),
    /// Returns fired after a GPS time (each its `offset_ns` later), decoded by the reader, and
    /// how the columns since the previous chunk were timed.
    Timed(GpsTime, &'a Chunk, ColumnsTimed),
    /// The stream ended.
    End,
}

impl LidarItem {
    fn holding(kind: LidarKind, host: Option<HostTime>, payload: &[u8]) -> Self {
        let mut bytes = [0u8; 1206];
        let n = payload.len().min(bytes.len());
        bytes[..n].copy_from_slice(&payload[..n]);
        Self {
            kind,
            host,
            len: n as u16,
            gps_ns: 0,
            columns: ColumnsTimed::default(),
            payload: Payload::Bytes(bytes),
        }
    }

    /// Returns fired after `t0` (GPS), received at `host`; the columns timed since the
    /// previous chunk.
    pub fn timed(t0: GpsTime, c: &Chunk, host: Option<HostTime>, columns: ColumnsTimed) -> Self {
        Self {
            kind: LidarKind::Timed,
            host,
            len: 0,
            gps_ns: t0.0,
            columns,
            payload: Payload::Points(*c),
        }
    }

    /// Returns of a point cloud.
    pub fn points(c: &Chunk) -> Self {
        Self {
            kind: LidarKind::Points,
            host: Some(c.t0),
            len: 0,
            gps_ns: 0,
            columns: ColumnsTimed::default(),
            payload: Payload::Points(*c),
        }
    }

    /// A Hesai data packet received at `host`.
    pub fn hesai<T: AsRef<[u8]>>(
        p: &spherecal::hesai::DataPacket<T>,
        host: Option<HostTime>,
    ) -> Self {
        Self::holding(LidarKind::Hesai, host, p.as_bytes())
    }

    /// A Hesai GPS packet received at `host`.
    pub fn hesai_gps<T: AsRef<[u8]>>(
        p: &spherecal::hesai::GpsPacket<T>,
        host: Option<HostTime>,
    ) -> Self {
        Self::holding(LidarKind::HesaiGps, host, p.as_bytes())
    }

    /// A data packet received at `host`.
    pub fn data<T: AsRef<[u8]>>(p: DataPacket<T>, host: Option<HostTime>) -> Self {
        Self::holding(LidarKind::Data, host, p.into_inner().as_ref())
    }

    /// A position packet received at `host`.
    pub fn position<T: AsRef<[u8]>>(p: PositionPacket<T>, host: Option<HostTime>) -> Self {
        Self::holding(LidarKind::Position, host, p.into_inner().as_ref())
    }

    /// The end of the stream.
    pub fn end() -> Self {
        Self::holding(LidarKind::End, None, &[])
    }

    /// The ring item for a received datagram, or why it is skipped.
    pub fn classify(d: &Datagram<'_>, ports: Ports) -> Result<Self, SkipReason> {
        let host = Some(d.time);
        Ok(match classify(d, ports)? {
            Vlp16Packet::Data { packet, .. } => Self::data(packet, host),
            Vlp16Packet::Position { packet, .. } => Self::position(packet, host),
        })
    }

    /// The checked packet it holds (its lengths are fixed: no view can index out of it).
    pub fn packet(&self) -> LidarPacket<'_> {
        match (&self.payload, self.kind) {
            (Payload::Bytes(b), LidarKind::Data) => {
                LidarPacket::Data(DataPacket::new_unchecked(&b[..]))
            }
            (Payload::Bytes(b), LidarKind::Position) => {
                LidarPacket::Position(PositionPacket::new_unchecked(&b[..512]))
            }
            (Payload::Points(c), LidarKind::Timed) => {
                LidarPacket::Timed(GpsTime(self.gps_ns), c, self.columns)
            }
            (Payload::Points(c), _) => LidarPacket::Points(c),
            (Payload::Bytes(b), LidarKind::Hesai) => {
                match spherecal::hesai::DataPacket::new_checked(&b[..usize::from(self.len)]) {
                    Ok(p) => LidarPacket::Hesai(p),
                    Err(_) => LidarPacket::End,
                }
            }
            (Payload::Bytes(b), LidarKind::HesaiGps) => {
                match spherecal::hesai::GpsPacket::new_checked(&b[..512]) {
                    Ok(p) => LidarPacket::HesaiGps(p),
                    Err(_) => LidarPacket::End,
                }
            }
            _ => LidarPacket::End,
        }
    }
}

/// An item on the INS ring.
#[derive(Debug, Clone, Copy)]
pub enum InsItem {
    /// A pose in the site frame and when the host received it, if known.
    Pose(PoseSample, Option<HostTime>),
    /// The stream ended.
    End,
}

//! A bag's messages as the sources the pipeline reads: the Velodyne driver's scans as UDP
//! datagrams ([`ScanPackets`], a [`PacketSource`]: each packet's 1206 bytes to the data port,
//! at the packet's stamp), and the VectorNav driver's groups as the VN-200 binary frames they
//! were parsed from ([`Vn200Bytes`], a [`ByteSource`]: the core's
//! [`CommonGroup::vn200_frame`], stamped with the message's header time), so that a bag goes
//! through the same framing, gating and alignment as a capture and a serial log.

use super::{BagError, Messages};
use crate::packet::{Datagram, HostTime, PacketSource, Record, SkipReason};
use crate::serial::{ByteSource, ReadOutcome, RxStamp};
use spherecal::ros2::{
    AttitudeGroup, CommonGroup, InsGroup, PacketMsg, PandarScan, VelodyneScan, VN200_FRAME_MAX,
};
use std::net::Ipv4Addr;

/// The address a bag's packets are said to come from (the sensor's factory default; a bag
/// does not keep it).
pub const SENSOR_ADDR: Ipv4Addr = Ipv4Addr::new(192, 168, 1, 201);

/// The packets of a topic of `velodyne_msgs/msg/VelodyneScan` (or a Hesai's
/// `pandar_msgs/msg/PandarScan`, or an Ouster's `ouster_sensor_msgs/msg/PacketMsg`), in order.
pub struct ScanPackets {
    msgs: Messages,
    /// What the messages are.
    kind: Kind,
    /// A topic of `spherecal_msgs/msg/Datagram` read too (an MCAP raw log's position packets).
    datagrams: Option<String>,
    /// The current scan's bytes.
    buf: Vec<u8>,
    /// Its packets: stamp, offset in `buf` and length.
    packets: Vec<(HostTime, usize, usize)>,
    next: usize,
    /// Where the current scan is in its file.
    at: u64,
    /// Scans read.
    pub scans: u64,
}

impl ScanPackets {
    /// Over `msgs` (one topic of scans).
    pub fn new(msgs: Messages) -> Self {
        Self::with_datagrams(msgs, None)
    }

    /// Over `msgs`: scans, and the raw datagrams of topic `datagrams` (an MCAP raw log's).
    pub fn with_datagrams(msgs: Messages, datagrams: Option<&str>) -> Self {
        Self {
            msgs,
            kind: Kind::Velodyne,
            datagrams: datagrams.map(Into::into),
            buf: Vec::new(),
            packets: Vec::new(),
            next: 0,
            at: 0,
            scans: 0,
        }
    }
}

/// The message type of a [`ScanPackets`]' topic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Velodyne,
    Pandar,
    /// One packet a message, said to go to this port.
    Ouster(u16),
}

impl ScanPackets {
    /// Its topic holds a Hesai's `PandarScan`s.
    pub fn is_pandar(&self) -> bool {
        self.kind == Kind::Pandar
    }

    /// Its topic holds an Ouster's `PacketMsg`s.
    pub fn is_ouster(&self) -> bool {
        matches!(self.kind, Kind::Ouster(_))
    }

    /// Over `msgs` (one topic of a Hesai's `PandarScan`s): each packet to the Hesai's data
    /// port.
    pub fn pandar(msgs: Messages) -> Self {
        Self {
            kind: Kind::Pandar,
            ..Self::new(msgs)
        }
    }

    /// Over `msgs` (an Ouster's `PacketMsg` topic): each message's bytes, stamped with its log
    /// time, to `port` (the metadata's lidar or IMU port).
    pub fn ouster(msgs: Messages, port: u16) -> Self {
        Self {
            kind: Kind::Ouster(port),
            ..Self::new(msgs)
        }
    }
}

impl PacketSource for ScanPackets {
    type Error = BagError;

    fn next_record(&mut self) -> Result<Option<Record<'_>>, BagError> {
        loop {
            if let Some(&(time, off, len)) = self.packets.get(self.next) {
                self.next += 1;
                return Ok(Some(Record::Udp(Datagram {
                    time,
                    src_addr: SENSOR_ADDR,
                    src_port: spherecal::velodyne::DATA_PORT,
                    dst_port: match self.kind {
                        Kind::Ouster(port) => port,
                        _ => spherecal::velodyne::DATA_PORT,
                    },
                    payload: &self.buf[off..off + len],
                    offset: self.at,
                })));
            }
            let Some(m) = self.msgs.next()? else {
                return Ok(None);
            };
            self.buf.clear();
            self.buf.extend_from_slice(m.data);
            self.at = m.at;
            self.packets.clear();
            self.next = 0;
            if self.datagrams.as_deref() == Some(m.topic.name.as_str()) {
                return Ok(Some(
                    match spherecal::ros2::raw::Datagram::parse(&self.buf) {
                        Ok(d) => Record::Udp(Datagram {
                            time: HostTime(d.stamp.ns()),
                            src_addr: Ipv4Addr::from(d.src_addr),
                            src_port: d.src_port,
                            dst_port: d.dst_port,
                            payload: d.payload,
                            offset: self.at,
                        }),
                        Err(e) => Record::Skipped {
                            offset: self.at,
                            reason: SkipReason::BadMessage(e),
                        },
                    },
                ));
            }
            self.scans += 1;
            let base = self.buf.as_ptr() as usize;
            let mut push = |t: spherecal::ros2::Time, d: &[u8]| {
                let off = d.as_ptr() as usize - base;
                self.packets.push((HostTime(t.ns()), off, d.len()));
            };
            let parsed = match self.kind {
                Kind::Pandar => {
                    PandarScan::parse(&self.buf).map(|s| s.packets().for_each(|(t, d)| push(t, d)))
                }
                Kind::Velodyne => VelodyneScan::parse(&self.buf)
                    .map(|s| s.packets().for_each(|(t, d)| push(t, &d[..]))),
                Kind::Ouster(_) => PacketMsg::parse(&self.buf).map(|p| {
                    let off = p.buf.as_ptr() as usize - base;
                    self.packets
                        .push((HostTime(m.log_time_ns), off, p.buf.len()));
                }),
            };
            match parsed {
                Ok(()) => {}
                Err(e) => {
                    return Ok(Some(Record::Skipped {
                        offset: self.at,
                        reason: SkipReason::BadMessage(e),
                    }))
                }
            }
        }
    }
}

/// What a [`Vn200Bytes`] met.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct InsBagStats {
    /// CommonGroup messages.
    pub common: u64,
    /// Frames made from them.
    pub frames: u64,
    /// CommonGroups with none of the fields a pose needs.
    pub empty: u64,
    /// Messages that did not parse as their type: count, and the first (where, why).
    pub bad: u64,
    /// The first bad message: its topic, where, and why.
    pub first_bad: Option<String>,
    /// Frames that carried the filter's YprU / PosU (from the Attitude / INS groups).
    pub with_sigmas: u64,
}

/// The VN-200 bytes a bag's VectorNav groups were parsed from: each `CommonGroup` as one
/// binary frame, with the YprU of the latest `AttitudeGroup` and the PosU of the latest
/// `InsGroup` (the driver publishes every group of a frame with the same stamp) when they are
/// within [`SIGMA_AGE_NS`] of it.
pub struct Vn200Bytes {
    msgs: Messages,
    common: String,
    ins: Option<String>,
    attitude: Option<String>,
    ypru: Option<(i64, [f32; 3])>,
    posu: Option<(i64, f32)>,
    /// What was met.
    pub stats: InsBagStats,
}

/// How far apart a sigma's message may be from the CommonGroup it is joined to [ns].
pub const SIGMA_AGE_NS: i64 = 1_000_000_000;

impl Vn200Bytes {
    /// Over `msgs`, which holds the topics `common` (CommonGroup) and, if given, `ins`
    /// (InsGroup) and `attitude` (AttitudeGroup).
    pub fn new(msgs: Messages, common: &str, ins: Option<&str>, attitude: Option<&str>) -> Self {
        Self {
            msgs,
            common: common.into(),
            ins: ins.map(Into::into),
            attitude: attitude.map(Into::into),
            ypru: None,
            posu: None,
            stats: InsBagStats::default(),
        }
    }

    /// Count a message that did not parse (the first one said in full).
    fn bad(stats: &mut InsBagStats, m: &super::Message<'_>, e: impl std::fmt::Display) {
        stats.bad += 1;
        if stats.first_bad.is_none() {
            stats.first_bad = Some(format!(
                "{} in {} at {}: {e}",
                m.topic.name,
                m.file.display(),
                m.at
            ));
        }
    }
}

impl ByteSource for Vn200Bytes {
    type Error = BagError;

    fn read_chunk(&mut self, buf: &mut [u8]) -> Result<ReadOutcome, BagError> {
        loop {
            let Some(m) = self.msgs.next()? else {
                return Ok(ReadOutcome::End);
            };
            // No copy of the topic or file per message: `m` borrows only `self.msgs`.
            let topic = m.topic.name.as_str();
            if self.attitude.as_deref() == Some(topic) {
                match AttitudeGroup::parse(m.data) {
                    Ok(a) if a.has(AttitudeGroup::YPRU) => {
                        self.ypru = Some((a.header.stamp.ns(), a.ypru.map(|v| v as f32)))
                    }
                    Ok(_) => {}
                    Err(e) => Self::bad(&mut self.stats, &m, e),
                }
                continue;
            }
            if self.ins.as_deref() == Some(topic) {
                match InsGroup::parse(m.data) {
                    Ok(g) if g.has(InsGroup::POSU) => {
                        self.posu = Some((g.header.stamp.ns(), g.posu))
                    }
                    Ok(_) => {}
                    Err(e) => Self::bad(&mut self.stats, &m, e),
                }
                continue;
            }
            if topic != self.common {
                continue;
            }
            let c = match CommonGroup::parse(m.data) {
                Ok(c) => c,
                Err(e) => {
                    Self::bad(&mut self.stats, &m, e);
                    continue;
                }
            };
            self.stats.common += 1;
            let t = c.header.stamp.ns();
            let near = |s: i64| (s - t).abs() <= SIGMA_AGE_NS;
            let ypru = self.ypru.filter(|u| near(u.0)).map(|u| u.1);
            let posu = self.posu.filter(|u| near(u.0)).map(|u| u.1);
            let mut frame = [0u8; VN200_FRAME_MAX];
            let Some(n) = c.vn200_frame(ypru, posu, &mut frame) else {
                self.stats.empty += 1;
                continue;
            };
            if n > buf.len() {
                // A caller's buffer smaller than one frame: an error, not a silent end.
                return Err(BagError::new(
                    m.file,
                    format!(
                        "a {n}-byte VN-200 frame does not fit the reader's {}-byte buffer",
                        buf.len()
                    ),
                ));
            }
            self.stats.frames += 1;
            if ypru.is_some() && posu.is_some() {
                self.stats.with_sigmas += 1;
            }
            buf[..n].copy_from_slice(&frame[..n]);
            let wall = HostTime(t);
            return Ok(ReadOutcome::Data {
                len: n,
                stamp: Some(RxStamp {
                    mono_ns: t.max(0) as u64,
                    wall,
                }),
            });
        }
    }
}

/// The serial reads of an MCAP raw log (`spherecal_msgs/msg/SerialChunk`), as they were read.
pub struct SerialBytes {
    msgs: Messages,
    /// Reads that did not parse, and the first's place and reason.
    pub bad: (u64, Option<String>),
    /// Reads, and the baud rate of the first.
    pub reads: (u64, Option<u32>),
    pending: Vec<u8>,
    pending_stamp: Option<RxStamp>,
}

impl SerialBytes {
    /// Over `msgs` (one topic of serial reads).
    pub fn new(msgs: Messages) -> Self {
        Self {
            msgs,
            bad: (0, None),
            reads: (0, None),
            pending: Vec::new(),
            pending_stamp: None,
        }
    }
}

impl ByteSource for SerialBytes {
    type Error = BagError;

    fn read_chunk(&mut self, buf: &mut [u8]) -> Result<ReadOutcome, BagError> {
        loop {
            // A read longer than the caller's buffer is handed on in pieces, each with its
            // stamp.
            if !self.pending.is_empty() {
                let n = self.pending.len().min(buf.len());
                buf[..n].copy_from_slice(&self.pending[..n]);
                self.pending.drain(..n);
                return Ok(ReadOutcome::Data {
                    len: n,
                    stamp: self.pending_stamp,
                });
            }
            let Some(m) = self.msgs.next()? else {
                return Ok(ReadOutcome::End);
            };
            match spherecal::ros2::raw::SerialChunk::parse(m.data) {
                Ok(c) => {
                    self.reads.0 += 1;
                    self.reads.1.get_or_insert(c.baud);
                    self.pending.extend_from_slice(c.data);
                    self.pending_stamp = Some(RxStamp {
                        mono_ns: c.mono_ns,
                        wall: HostTime(c.stamp.ns()),
                    });
                }
                Err(e) => {
                    self.bad.0 += 1;
                    if self.bad.1.is_none() {
                        self.bad.1 = Some(format!(
                            "{} in {} at {}: {e}",
                            m.topic.name,
                            m.file.display(),
                            m.at
                        ));
                    }
                }
            }
        }
    }
}

impl ScanPackets {
    /// The MCAP files found cut short so far ([`super::Messages::cut`]).
    pub fn cut(&self) -> &[(std::path::PathBuf, u64)] {
        self.msgs.cut()
    }
}

impl Vn200Bytes {
    /// The MCAP files found cut short so far ([`super::Messages::cut`]).
    pub fn cut(&self) -> &[(std::path::PathBuf, u64)] {
        self.msgs.cut()
    }
}

impl SerialBytes {
    /// The MCAP files found cut short so far ([`super::Messages::cut`]).
    pub fn cut(&self) -> &[(std::path::PathBuf, u64)] {
        self.msgs.cut()
    }
}

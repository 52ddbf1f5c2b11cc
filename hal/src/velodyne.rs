//! VLP-16 packets out of any [`PacketSource`](crate::PacketSource): classification by port and
//! length, and the count of everything skipped, by reason, with the first place it happened.

use crate::packet::{Datagram, HostTime, SkipReason};
use spherecal::velodyne::data::DATA_PACKET_LEN;
use spherecal::velodyne::position::POSITION_PACKET_LEN;
use spherecal::velodyne::{DataPacket, PositionPacket, DATA_PORT, POSITION_PORT};

/// The UDP ports a VLP-16 sends to (configurable on the sensor's web page).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ports {
    /// Data packets (default 2368).
    pub data: u16,
    /// Position packets (default 8308).
    pub position: u16,
}

impl Default for Ports {
    fn default() -> Self {
        Self {
            data: DATA_PORT,
            position: POSITION_PORT,
        }
    }
}

/// A datagram recognised as a VLP-16 packet.
#[derive(Debug, Clone, Copy)]
pub enum Vlp16Packet<'a> {
    /// A data packet (length and block flags checked).
    Data {
        /// Receive time.
        time: HostTime,
        /// Byte offset of the record in its file.
        offset: u64,
        /// The packet view.
        packet: DataPacket<&'a [u8]>,
    },
    /// A position packet (length checked).
    Position {
        /// Receive time.
        time: HostTime,
        /// Byte offset of the record in its file.
        offset: u64,
        /// The packet view.
        packet: PositionPacket<&'a [u8]>,
    },
}

/// Recognise a datagram by destination port and exact payload length.
pub fn classify<'a>(d: &Datagram<'a>, ports: Ports) -> Result<Vlp16Packet<'a>, SkipReason> {
    let got = d.payload.len();
    if d.dst_port == ports.data {
        if got != DATA_PACKET_LEN {
            return Err(SkipReason::WrongPayloadLength {
                port: d.dst_port,
                expected: DATA_PACKET_LEN,
                got,
            });
        }
        let packet = DataPacket::new_checked(d.payload).map_err(SkipReason::Vlp16)?;
        Ok(Vlp16Packet::Data {
            time: d.time,
            offset: d.offset,
            packet,
        })
    } else if d.dst_port == ports.position {
        if got != POSITION_PACKET_LEN {
            return Err(SkipReason::WrongPayloadLength {
                port: d.dst_port,
                expected: POSITION_PACKET_LEN,
                got,
            });
        }
        let packet = PositionPacket::new_checked(d.payload).map_err(SkipReason::Vlp16)?;
        Ok(Vlp16Packet::Position {
            time: d.time,
            offset: d.offset,
            packet,
        })
    } else {
        Err(SkipReason::OtherPort(d.dst_port))
    }
}

/// One line of [`SkipStats`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SkipLine {
    /// The reason's name ([`SkipReason::name`]).
    pub reason: &'static str,
    /// How many.
    pub count: u64,
    /// Byte offset of the first.
    pub first_offset: u64,
    /// The first one, in full.
    pub first: String,
}

/// Skips counted by reason, in order of first appearance. Allocates only when a new reason
/// appears.
#[derive(Debug, Clone, Default)]
pub struct SkipStats {
    lines: Vec<SkipLine>,
}

impl SkipStats {
    /// Count one skip.
    pub fn count(&mut self, offset: u64, reason: &SkipReason) {
        let name = reason.name();
        if let Some(l) = self.lines.iter_mut().find(|l| l.reason == name) {
            l.count += 1;
        } else {
            self.lines.push(SkipLine {
                reason: name,
                count: 1,
                first_offset: offset,
                first: reason.to_string(),
            });
        }
    }
    /// All lines.
    pub fn lines(&self) -> &[SkipLine] {
        &self.lines
    }
    /// Where the file ends inside a record (a capture cut short: a recording interrupted, a
    /// copy not finished), as the byte offset of that record, and what was left.
    pub fn truncated_file(&self) -> Option<(u64, &str)> {
        self.lines
            .iter()
            .find(|l| l.reason == "truncated file")
            .map(|l| (l.first_offset, l.first.as_str()))
    }
    /// Count for one reason name.
    pub fn get(&self, reason: &str) -> u64 {
        self.lines
            .iter()
            .find(|l| l.reason == reason)
            .map_or(0, |l| l.count)
    }
    /// Total skips.
    pub fn total(&self) -> u64 {
        self.lines.iter().map(|l| l.count).sum()
    }
}

//! The raw packets of the other LiDARs' ROS 2 drivers: `pandar_msgs/msg/PandarScan`
//! (tier4/nebula, `src/nebula_hesai/pandar_msgs`: a Hesai's packets, each
//! `builtin_interfaces/Time stamp` + `uint8[1500] data` + `uint32 size`, the packet's own length
//! within `data`) and `ouster_sensor_msgs/msg/PacketMsg` (ouster-ros: one packet, `uint8[] buf`).

use super::cdr::{Error, Reader};
use super::{Header, Time};

/// A `PandarPacket`'s data array length.
pub const PANDAR_DATA: usize = 1500;

/// `pandar_msgs/msg/PandarScan`: a header and the raw packets of (about) one rotation.
#[derive(Debug, Clone)]
pub struct PandarScan<'a> {
    /// The scan's header.
    pub header: Header<'a>,
    /// Its packets.
    pub count: u32,
    packets: Reader<'a>,
}

impl<'a> PandarScan<'a> {
    /// Parse a CDR message; every packet is checked to be there with a size within its array
    /// ([`Self::packets`] cannot fail).
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let count = r.count(8 + PANDAR_DATA + 4, "packets")?;
        let packets = r.clone();
        for _ in 0..count {
            Time::read(&mut r)?;
            r.bytes(PANDAR_DATA, "packet data")?;
            let offset = r.offset();
            let size = r.u32("packet size")?;
            if size as usize > PANDAR_DATA {
                return Err(Error::BadCount {
                    offset,
                    count: size,
                });
            }
        }
        Ok(Self {
            header,
            count,
            packets,
        })
    }

    /// The packets: each its stamp and its `size` bytes.
    pub fn packets(&self) -> impl Iterator<Item = (Time, &'a [u8])> + '_ {
        let mut r = self.packets.clone();
        (0..self.count).map_while(move |_| {
            let t = Time::read(&mut r).ok()?;
            let d = r.bytes(PANDAR_DATA, "packet data").ok()?;
            let n = r.u32("packet size").ok()? as usize;
            Some((t, d.get(..n)?))
        })
    }
}

/// `ouster_sensor_msgs/msg/PacketMsg` (ouster-ros): one lidar or IMU packet, `uint8[] buf`.
/// ouster-ros sizes `buf` one byte longer than the packet (its client's read buffer); the
/// decoder takes the packet from its start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PacketMsg<'a> {
    /// The bytes as recorded.
    pub buf: &'a [u8],
}

impl<'a> PacketMsg<'a> {
    /// Parse a CDR message.
    pub fn parse(b: &'a [u8]) -> Result<Self, Error> {
        let mut r = Reader::new(b)?;
        let n = r.count(1, "buf")? as usize;
        Ok(Self {
            buf: r.bytes(n, "buf")?,
        })
    }
}

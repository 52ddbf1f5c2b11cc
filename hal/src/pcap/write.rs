//! Writing classic pcap. Our own 40 lines rather than `pcap-file`'s writer: pcap-file 2.0's
//! `PcapWriter` gives no access to the file it wraps (only `into_writer`), so the rig could not
//! flush and fdatasync its raw log twice a second (rawlog.rs) without closing it.

use super::PcapError;
use crate::packet::HostTime;
use std::io;

/// A classic pcap writer (little-endian, microsecond stamps, Ethernet), as tcpdump writes
/// (pcap-savefile(5): 24-byte global header, 16-byte record headers).
pub struct PcapWriter<W: io::Write> {
    inner: W,
}

impl<W: io::Write> PcapWriter<W> {
    /// Write the global header.
    pub fn new(mut w: W) -> Result<Self, PcapError> {
        let mut h = [0u8; 24];
        h[0..4].copy_from_slice(&0xA1B2_C3D4u32.to_le_bytes());
        h[4..6].copy_from_slice(&2u16.to_le_bytes());
        h[6..8].copy_from_slice(&4u16.to_le_bytes());
        // thiszone, sigfigs: 0.
        h[16..20].copy_from_slice(&65_535u32.to_le_bytes());
        h[20..24].copy_from_slice(&1u32.to_le_bytes()); // LINKTYPE_ETHERNET
        w.write_all(&h).map_err(|e| PcapError::Corrupt {
            offset: 0,
            what: format!("writing pcap header: {e}"),
        })?;
        Ok(Self { inner: w })
    }

    /// Write one frame with its capture time.
    pub fn write_frame(&mut self, time: HostTime, frame: &[u8]) -> Result<(), PcapError> {
        let us = time.0.max(0) / 1000;
        let (sec, usec) = ((us / 1_000_000) as u32, (us % 1_000_000) as u32);
        let len = u32::try_from(frame.len()).unwrap_or(u32::MAX);
        let mut h = [0u8; 16];
        h[0..4].copy_from_slice(&sec.to_le_bytes());
        h[4..8].copy_from_slice(&usec.to_le_bytes());
        h[8..12].copy_from_slice(&len.to_le_bytes());
        h[12..16].copy_from_slice(&len.to_le_bytes());
        self.inner
            .write_all(&h)
            .and_then(|()| self.inner.write_all(frame))
            .map_err(|e| PcapError::Corrupt {
                offset: 0,
                what: format!("writing pcap record: {e}"),
            })
    }

    /// The underlying writer.
    pub fn into_inner(self) -> W {
        self.inner
    }

    /// The underlying writer, to flush it.
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.inner
    }
}

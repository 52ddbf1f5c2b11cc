//! Capture files: classic libpcap (micro- and nanosecond, either byte order) and pcapng, read
//! as a stream with a fixed working buffer. Records are parsed with `pcap-file`, frames sliced
//! with `etherparse`'s lax slicer (real captures carry IPv4 lengths that do not match the frame:
//! PROTOCOLS.md), and the UDP payload is taken from the UDP length bounded by the captured bytes.
//!
//! Nothing is copied per packet: a [`Datagram`]'s payload borrows the reader's buffer.

use crate::packet::{Datagram, HostTime, PacketSource, Record, SkipReason};
use etherparse::{EtherType, LaxNetSlice, LaxSlicedPacket, TransportSlice};
use pcap_file::pcap::PcapParser;
use pcap_file::pcapng::{Block, PcapNgParser};
use pcap_file::{DataLink, Endianness, TsResolution};
use std::fmt;
use std::io::{self, Read};
use std::net::Ipv4Addr;

/// Largest record or block we accept; anything larger means a corrupt length field.
pub const MAX_RECORD: usize = 1 << 20;
const READ_CHUNK: usize = 256 * 1024;

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

enum Format {
    /// Before the file header has been read.
    Pending,
    Classic {
        parser: PcapParser,
        link: u32,
        nanos: bool,
        big: bool,
    },
    Ng {
        parser: PcapNgParser,
        big: bool,
    },
}

/// A classic pcap or pcapng file read as a stream of [`Record`]s.
pub struct PcapSource<R: Read> {
    reader: R,
    buf: Vec<u8>,
    start: usize,
    end: usize,
    /// File offset of `buf[0]`.
    base: u64,
    eof: bool,
    done: bool,
    format: Format,
}

impl PcapSource<io::BufReader<std::fs::File>> {
    /// Open a file.
    pub fn open(path: impl AsRef<std::path::Path>) -> Result<Self, PcapError> {
        let f = std::fs::File::open(path)?;
        Self::new(io::BufReader::with_capacity(64 * 1024, f))
    }
}

impl<'s> PcapSource<&'s [u8]> {
    /// Read a capture held in memory.
    pub fn from_bytes(bytes: &'s [u8]) -> Result<Self, PcapError> {
        Self::new(bytes)
    }
}

const PCAPNG_SHB: [u8; 4] = [0x0A, 0x0D, 0x0D, 0x0A];

impl<R: Read> PcapSource<R> {
    /// Read the global header (pcap) or first section header (pcapng).
    pub fn new(reader: R) -> Result<Self, PcapError> {
        let mut s = Self {
            reader,
            buf: vec![0; READ_CHUNK],
            start: 0,
            end: 0,
            base: 0,
            eof: false,
            done: false,
            format: Format::Pending,
        };
        s.fill(24)?;
        let head = &s.buf[..s.end];
        if head.len() < 4 {
            return Err(PcapError::TruncatedHeader {
                expected: 24,
                got: head.len(),
            });
        }
        let magic = [head[0], head[1], head[2], head[3]];
        match magic {
            PCAPNG_SHB => {
                let need = s
                    .ng_block_len_at(0, None)
                    .map_err(|what| PcapError::Corrupt { offset: 0, what })?;
                if need > MAX_RECORD {
                    return Err(PcapError::Corrupt {
                        offset: 0,
                        what: format!("section header claims {need} bytes"),
                    });
                }
                s.fill(need)?;
                if s.end < need {
                    return Err(PcapError::TruncatedHeader {
                        expected: need,
                        got: s.end,
                    });
                }
                let (rest, parser) =
                    PcapNgParser::new(&s.buf[..s.end]).map_err(|e| PcapError::Corrupt {
                        offset: 0,
                        what: format!("pcapng section header: {e}"),
                    })?;
                let used = s.end - rest.len();
                let big = parser.section().endianness == Endianness::Big;
                s.start = used;
                s.format = Format::Ng { parser, big };
            }
            [0xD4, 0xC3, 0xB2, 0xA1]
            | [0xA1, 0xB2, 0xC3, 0xD4]
            | [0x4D, 0x3C, 0xB2, 0xA1]
            | [0xA1, 0xB2, 0x3C, 0x4D] => {
                if s.end < 24 {
                    return Err(PcapError::TruncatedHeader {
                        expected: 24,
                        got: s.end,
                    });
                }
                let (_, parser) =
                    PcapParser::new(&s.buf[..24]).map_err(|e| PcapError::Corrupt {
                        offset: 0,
                        what: format!("pcap global header: {e}"),
                    })?;
                let h = parser.header();
                s.format = Format::Classic {
                    link: u32::from(h.datalink),
                    nanos: h.ts_resolution == TsResolution::NanoSecond,
                    big: h.endianness == Endianness::Big,
                    parser,
                };
                s.start = 24;
            }
            found => return Err(PcapError::BadMagic { found }),
        }
        Ok(s)
    }

    /// Is this a pcapng file?
    pub fn is_pcapng(&self) -> bool {
        matches!(self.format, Format::Ng { .. })
    }

    /// Make at least `need` bytes available from `start`, reading more as needed (fewer only at
    /// the end of the file).
    fn fill(&mut self, need: usize) -> Result<(), PcapError> {
        if self.end - self.start >= need || self.eof {
            return Ok(());
        }
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.base += self.start as u64;
            self.end -= self.start;
            self.start = 0;
        }
        if self.buf.len() < need {
            self.buf.resize(need.max(READ_CHUNK), 0);
        }
        while self.end < need {
            match self.reader.read(&mut self.buf[self.end..]) {
                Ok(0) => {
                    self.eof = true;
                    break;
                }
                Ok(n) => self.end += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
        }
        Ok(())
    }

    /// Total length of the pcapng block at `start + at`, in the given (or the section's) order.
    fn ng_block_len_at(&self, at: usize, big: Option<bool>) -> Result<usize, String> {
        let b = &self.buf[self.start + at..self.end];
        if b.len() < 12 {
            return Err(format!("block header needs 12 bytes, {} left", b.len()));
        }
        let big = if b[..4] == PCAPNG_SHB {
            match [b[8], b[9], b[10], b[11]] {
                [0x1A, 0x2B, 0x3C, 0x4D] => true,
                [0x4D, 0x3C, 0x2B, 0x1A] => false,
                bom => return Err(format!("section header byte-order magic {bom:02X?}")),
            }
        } else {
            big.unwrap_or(false)
        };
        let raw = [b[4], b[5], b[6], b[7]];
        let len = if big {
            u32::from_be_bytes(raw)
        } else {
            u32::from_le_bytes(raw)
        } as usize;
        if len < 12 || !len.is_multiple_of(4) {
            return Err(format!(
                "block length {len} (must be >= 12 and a multiple of 4)"
            ));
        }
        Ok(len)
    }

    fn offset(&self) -> u64 {
        self.base + self.start as u64
    }

    /// Make a whole record of `header` bytes whose length the closure reads available; returns
    /// its length, or `None` (with `done` set) if the file ends inside it.
    fn whole_record(
        &mut self,
        header: usize,
        len_of: impl Fn(&Self) -> Result<usize, String>,
    ) -> Result<Option<usize>, PcapError> {
        self.fill(header)?;
        if self.end == self.start {
            self.done = true;
            return Ok(None);
        }
        if self.end - self.start < header {
            return Ok(None);
        }
        let len = len_of(self).map_err(|what| PcapError::Corrupt {
            offset: self.offset(),
            what,
        })?;
        if len > MAX_RECORD {
            return Err(PcapError::Corrupt {
                offset: self.offset(),
                what: format!(
                    "record claims {len} bytes (more than {MAX_RECORD}): corrupt length field"
                ),
            });
        }
        self.fill(len)?;
        if self.end - self.start < len {
            return Ok(None);
        }
        Ok(Some(len))
    }

    fn truncated_tail(&mut self) -> Option<Record<'_>> {
        if self.done {
            return None;
        }
        self.done = true;
        Some(Record::Skipped {
            offset: self.offset(),
            reason: SkipReason::TruncatedFile {
                left: self.end - self.start,
            },
        })
    }
}

impl<R: Read> PacketSource for PcapSource<R> {
    type Error = PcapError;

    fn next_record(&mut self) -> Result<Option<Record<'_>>, PcapError> {
        if self.done {
            return Ok(None);
        }
        match self.format {
            Format::Pending => Ok(None),
            Format::Classic { big, .. } => {
                let len_of = move |s: &Self| {
                    let b = &s.buf[s.start + 8..s.start + 12];
                    let raw = [b[0], b[1], b[2], b[3]];
                    Ok(16
                        + if big {
                            u32::from_be_bytes(raw)
                        } else {
                            u32::from_le_bytes(raw)
                        } as usize)
                };
                let Some(len) = self.whole_record(16, len_of)? else {
                    return Ok(self.truncated_tail());
                };
                let offset = self.offset();
                let at = self.start;
                self.start += len;
                let Format::Classic {
                    ref parser,
                    link,
                    nanos,
                    ..
                } = self.format
                else {
                    return Ok(None);
                };
                let (_, raw) = parser
                    .next_raw_packet(&self.buf[at..at + len])
                    .map_err(|e| PcapError::Corrupt {
                        offset,
                        what: format!("pcap record: {e}"),
                    })?;
                let frac = u64::from(raw.ts_frac) * if nanos { 1 } else { 1000 };
                let time = HostTime(i128::from(raw.ts_sec) * 1_000_000_000 + i128::from(frac));
                let data: &[u8] = match raw.data {
                    std::borrow::Cow::Borrowed(d) => d,
                    std::borrow::Cow::Owned(_) => &self.buf[at + 16..at + len],
                };
                Ok(Some(frame_record(
                    link,
                    data,
                    raw.incl_len,
                    raw.orig_len,
                    time,
                    offset,
                )))
            }
            Format::Ng { .. } => {
                // Walk past non-packet blocks (section and interface headers update the parser).
                let len = loop {
                    let big = match self.format {
                        Format::Ng { big, .. } => big,
                        _ => false,
                    };
                    let Some(len) =
                        self.whole_record(12, move |s: &Self| s.ng_block_len_at(0, Some(big)))?
                    else {
                        return Ok(self.truncated_tail());
                    };
                    let ty = &self.buf[self.start..self.start + 4];
                    let raw_ty = if big {
                        u32::from_be_bytes([ty[0], ty[1], ty[2], ty[3]])
                    } else {
                        u32::from_le_bytes([ty[0], ty[1], ty[2], ty[3]])
                    };
                    if matches!(raw_ty, 2 | 3 | 6) {
                        break len;
                    }
                    let offset = self.offset();
                    let at = self.start;
                    self.start += len;
                    if let Format::Ng {
                        ref mut parser,
                        ref mut big,
                    } = self.format
                    {
                        parser.next_block(&self.buf[at..at + len]).map_err(|e| {
                            PcapError::Corrupt {
                                offset,
                                what: format!("pcapng block: {e}"),
                            }
                        })?;
                        *big = parser.section().endianness == Endianness::Big;
                    }
                };
                let offset = self.offset();
                let at = self.start;
                self.start += len;
                let Format::Ng { ref mut parser, .. } = self.format else {
                    return Ok(None);
                };
                let (_, block) =
                    parser
                        .next_block(&self.buf[at..at + len])
                        .map_err(|e| PcapError::Corrupt {
                            offset,
                            what: format!("pcapng block: {e}"),
                        })?;
                let (iface, ts_raw, data, orig) = match block {
                    Block::EnhancedPacket(p) => (
                        p.interface_id,
                        Some(p.timestamp.as_nanos()),
                        p.data,
                        p.original_len,
                    ),
                    Block::SimplePacket(p) => (0, None, p.data, p.original_len),
                    Block::Packet(p) => (
                        u32::from(p.interface_id),
                        Some(u128::from(p.timestamp)),
                        p.data,
                        p.original_len,
                    ),
                    _ => {
                        return Err(PcapError::Corrupt {
                            offset,
                            what: "block type changed between peek and parse".into(),
                        })
                    }
                };
                let Some(idb) = parser.interfaces().get(iface as usize) else {
                    return Err(PcapError::Corrupt {
                        offset,
                        what: format!(
                            "packet names interface {iface}, which no interface block describes"
                        ),
                    });
                };
                let link = u32::from(idb.linktype);
                let time = HostTime(ts_raw.map_or(0, |t| ng_time_ns(t, tsresol(idb))));
                let data: &[u8] = match data {
                    std::borrow::Cow::Borrowed(d) => d,
                    std::borrow::Cow::Owned(_) => {
                        return Err(PcapError::Corrupt {
                            offset,
                            what: "unexpected owned packet data".into(),
                        })
                    }
                };
                Ok(Some(frame_record(
                    link,
                    data,
                    data.len() as u32,
                    orig,
                    time,
                    offset,
                )))
            }
        }
    }
}

fn tsresol(
    idb: &pcap_file::pcapng::blocks::interface_description::InterfaceDescriptionBlock<'_>,
) -> u8 {
    use pcap_file::pcapng::blocks::interface_description::InterfaceDescriptionOption;
    idb.options
        .iter()
        .find_map(|o| match o {
            InterfaceDescriptionOption::IfTsResol(r) => Some(*r),
            _ => None,
        })
        .unwrap_or(6)
}

/// pcapng timestamp units -> nanoseconds (if_tsresol: bit 7 clear = 10^-n s, set = 2^-n s;
/// default 10^-6).
fn ng_time_ns(units: u128, resol: u8) -> i128 {
    let n = u32::from(resol & 0x7F);
    let ns = if resol & 0x80 == 0 {
        if n <= 9 {
            units.saturating_mul(10u128.pow(9 - n))
        } else {
            units / 10u128.saturating_pow(n - 9)
        }
    } else if n < 64 {
        units.saturating_mul(1_000_000_000) >> n
    } else {
        0
    };
    i128::try_from(ns).unwrap_or(i128::MAX)
}

/// Slice a captured frame down to its UDP payload, or say why not.
fn frame_record(
    link: u32,
    data: &[u8],
    captured: u32,
    original: u32,
    time: HostTime,
    offset: u64,
) -> Record<'_> {
    if captured < original {
        return Record::Skipped {
            offset,
            reason: SkipReason::TruncatedRecord { captured, original },
        };
    }
    match slice_udp(link, data) {
        Ok((src_addr, src_port, dst_port, payload)) => Record::Udp(Datagram {
            time,
            src_addr,
            src_port,
            dst_port,
            payload,
            offset,
        }),
        Err(reason) => Record::Skipped { offset, reason },
    }
}

/// Link layer -> IPv4 -> UDP, laxly; the payload runs to the UDP length or the captured end.
pub fn slice_udp(link: u32, frame: &[u8]) -> Result<(Ipv4Addr, u16, u16, &[u8]), SkipReason> {
    let sliced = match DataLink::from(link) {
        DataLink::ETHERNET => {
            LaxSlicedPacket::from_ethernet(frame).map_err(|_| SkipReason::NotIpv4Udp)?
        }
        DataLink::RAW | DataLink::IPV4 => {
            LaxSlicedPacket::from_ip(frame).map_err(|_| SkipReason::NotIpv4Udp)?
        }
        DataLink::NULL | DataLink::LOOP => {
            LaxSlicedPacket::from_ip(frame.get(4..).ok_or(SkipReason::NotIpv4Udp)?)
                .map_err(|_| SkipReason::NotIpv4Udp)?
        }
        DataLink::LINUX_SLL => {
            let proto = frame.get(14..16).ok_or(SkipReason::NotIpv4Udp)?;
            LaxSlicedPacket::from_ether_type(
                EtherType(u16::from_be_bytes([proto[0], proto[1]])),
                &frame[16..],
            )
        }
        DataLink::LINUX_SLL2 => {
            let proto = frame.get(0..2).ok_or(SkipReason::NotIpv4Udp)?;
            let rest = frame.get(20..).ok_or(SkipReason::NotIpv4Udp)?;
            LaxSlicedPacket::from_ether_type(
                EtherType(u16::from_be_bytes([proto[0], proto[1]])),
                rest,
            )
        }
        _ => return Err(SkipReason::UnsupportedLinkType(link)),
    };
    let Some(LaxNetSlice::Ipv4(ip)) = &sliced.net else {
        return Err(SkipReason::NotIpv4Udp);
    };
    let h = ip.header();
    if h.is_fragmenting_payload() {
        return Err(SkipReason::IpFragment);
    }
    let Some(TransportSlice::Udp(udp)) = &sliced.transport else {
        return Err(SkipReason::NotIpv4Udp);
    };
    // Where the UDP header sits in the frame: the payload is cut by the UDP length, not by the
    // IPv4 total length (which some recorders fill with a canned value).
    let udp_at = udp.slice().as_ptr() as usize - frame.as_ptr() as usize;
    let after = &frame[udp_at + 8..];
    let udp_len = usize::from(udp.length());
    let payload = if udp_len >= 8 && udp_len - 8 <= after.len() {
        &after[..udp_len - 8]
    } else {
        after
    };
    Ok((
        h.source_addr(),
        udp.source_port(),
        udp.destination_port(),
        payload,
    ))
}

/// Addresses of a sensor's UDP frames (VLP-16 factory defaults: 192.168.1.201 broadcasting to
/// 255.255.255.255, source MAC 60:76:88 Velodyne OUI).
#[derive(Debug, Clone, Copy)]
pub struct UdpEndpoints {
    /// Source MAC.
    pub src_mac: [u8; 6],
    /// Destination MAC.
    pub dst_mac: [u8; 6],
    /// Source IPv4.
    pub src_ip: [u8; 4],
    /// Destination IPv4.
    pub dst_ip: [u8; 4],
}

impl Default for UdpEndpoints {
    fn default() -> Self {
        Self {
            src_mac: [0x60, 0x76, 0x88, 0x10, 0x20, 0x30],
            dst_mac: [0xFF; 6],
            src_ip: [192, 168, 1, 201],
            dst_ip: [255, 255, 255, 255],
        }
    }
}

/// Build an Ethernet II / IPv4 / UDP frame around `payload` into `out` (cleared first), with
/// correct lengths and IPv4 and UDP checksums. Fails only for a payload over 65507 bytes.
pub fn build_udp_frame(
    out: &mut Vec<u8>,
    ep: &UdpEndpoints,
    src_port: u16,
    dst_port: u16,
    payload: &[u8],
) -> io::Result<()> {
    out.clear();
    let b = etherparse::PacketBuilder::ethernet2(ep.src_mac, ep.dst_mac)
        .ipv4(ep.src_ip, ep.dst_ip, 64)
        .udp(src_port, dst_port);
    out.reserve(b.size(payload.len()));
    b.write(out, payload).map_err(io::Error::other)
}

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

//! The streaming capture reader: classic libpcap and pcapng through a fixed working buffer.

use super::defrag::{Added, Reassembly};
use super::slice::{slice_fragment, slice_udp};
use super::{PcapError, MAX_RECORD};
use crate::packet::{Datagram, HostTime, PacketSource, Record, SkipReason};
use pcap_file::pcap::PcapParser;
use pcap_file::pcapng::{Block, PcapNgParser};
use pcap_file::{Endianness, TsResolution};
use std::io::{self, Read};

const READ_CHUNK: usize = 256 * 1024;

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
    /// IPv4 datagrams larger than the link's MTU, put back together.
    defrag: Reassembly,
}

/// A record read: where its frame is in the buffer and what the record header said.
struct FrameAt {
    link: u32,
    data: std::ops::Range<usize>,
    captured: u32,
    original: u32,
    time: HostTime,
    offset: u64,
}

/// What the next record is.
enum Raw {
    /// A frame.
    Frame(FrameAt),
    /// The end, or a record that is not a frame.
    Other(Option<Record<'static>>),
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
            defrag: Reassembly::default(),
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

    /// Nothing more will come (the last call returned `None`, or no header was read).
    pub fn finished(&self) -> bool {
        self.done || matches!(self.format, Format::Pending)
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

    fn truncated_tail(&mut self) -> Option<Record<'static>> {
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

impl<R: Read> PcapSource<R> {
    /// The next classic pcap record (16-byte header, then the frame).
    fn next_classic(&mut self) -> Result<Raw, PcapError> {
        let Format::Classic { big, .. } = self.format else {
            return Ok(Raw::Other(None));
        };
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
            return Ok(Raw::Other(self.truncated_tail()));
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
            return Ok(Raw::Other(None));
        };
        let (_, raw) = parser
            .next_raw_packet(&self.buf[at..at + len])
            .map_err(|e| PcapError::Corrupt {
                offset,
                what: format!("pcap record: {e}"),
            })?;
        let frac = u64::from(raw.ts_frac) * if nanos { 1 } else { 1000 };
        // u32 seconds (to 2106) and a fraction below 2^32 us fit an i64 of nanoseconds.
        let time = HostTime(i64::from(raw.ts_sec) * 1_000_000_000 + frac as i64);
        let data: &[u8] = match raw.data {
            std::borrow::Cow::Borrowed(d) => d,
            std::borrow::Cow::Owned(_) => &self.buf[at + 16..at + len],
        };
        let from = data.as_ptr() as usize - self.buf.as_ptr() as usize;
        Ok(Raw::Frame(FrameAt {
            link,
            data: from..from + data.len(),
            captured: raw.incl_len,
            original: raw.orig_len,
            time,
            offset,
        }))
    }

    /// Walk past pcapng blocks that carry no packet (section and interface headers update the
    /// parser) to the next packet block: its length, or `None` at a truncated tail.
    fn ng_next_packet_block(&mut self) -> Result<Option<usize>, PcapError> {
        loop {
            let big = match self.format {
                Format::Ng { big, .. } => big,
                _ => false,
            };
            let Some(len) =
                self.whole_record(12, move |s: &Self| s.ng_block_len_at(0, Some(big)))?
            else {
                return Ok(None);
            };
            let ty = &self.buf[self.start..self.start + 4];
            let raw_ty = if big {
                u32::from_be_bytes([ty[0], ty[1], ty[2], ty[3]])
            } else {
                u32::from_le_bytes([ty[0], ty[1], ty[2], ty[3]])
            };
            if matches!(raw_ty, 2 | 3 | 6) {
                return Ok(Some(len));
            }
            let offset = self.offset();
            let at = self.start;
            self.start += len;
            if let Format::Ng {
                ref mut parser,
                ref mut big,
            } = self.format
            {
                parser
                    .next_block(&self.buf[at..at + len])
                    .map_err(|e| PcapError::Corrupt {
                        offset,
                        what: format!("pcapng block: {e}"),
                    })?;
                *big = parser.section().endianness == Endianness::Big;
            }
        }
    }

    /// The next pcapng packet (enhanced, simple or obsolete packet block), timed with its
    /// interface's resolution.
    fn next_ng(&mut self) -> Result<Raw, PcapError> {
        let Some(len) = self.ng_next_packet_block()? else {
            return Ok(Raw::Other(self.truncated_tail()));
        };
        let offset = self.offset();
        let at = self.start;
        self.start += len;
        let Format::Ng { ref mut parser, .. } = self.format else {
            return Ok(Raw::Other(None));
        };
        let corrupt = |what: String| PcapError::Corrupt { offset, what };
        let (_, block) = parser
            .next_block(&self.buf[at..at + len])
            .map_err(|e| corrupt(format!("pcapng block: {e}")))?;
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
            _ => return Err(corrupt("block type changed between peek and parse".into())),
        };
        let Some(idb) = parser.interfaces().get(iface as usize) else {
            return Err(corrupt(format!(
                "packet names interface {iface}, which no interface block describes"
            )));
        };
        let link = u32::from(idb.linktype);
        let time = HostTime(ts_raw.map_or(0, |t| ng_time_ns(t, tsresol(idb))));
        let std::borrow::Cow::Borrowed(data) = data else {
            return Err(corrupt("unexpected owned packet data".into()));
        };
        let from = data.as_ptr() as usize - self.buf.as_ptr() as usize;
        Ok(Raw::Frame(FrameAt {
            link,
            data: from..from + data.len(),
            captured: data.len() as u32,
            original: orig,
            time,
            offset,
        }))
    }
}

impl<R: Read> PacketSource for PcapSource<R> {
    type Error = PcapError;

    fn next_record(&mut self) -> Result<Option<Record<'_>>, PcapError> {
        loop {
            if self.done {
                return Ok(None);
            }
            let raw = match self.format {
                Format::Pending => return Ok(None),
                Format::Classic { .. } => self.next_classic()?,
                Format::Ng { .. } => self.next_ng()?,
            };
            let f = match raw {
                Raw::Other(r) => return Ok(r),
                Raw::Frame(f) => f,
            };
            // An IPv4 fragment: held until its datagram is whole (frames of one record never
            // reach the caller; the datagram is timed and placed at its last fragment).
            if f.captured >= f.original {
                if let Some(frag) = slice_fragment(f.link, &self.buf[f.data.clone()]) {
                    match self.defrag.add(&frag) {
                        Added::Held => continue,
                        Added::Bad => {
                            return Ok(Some(Record::Skipped {
                                offset: f.offset,
                                reason: SkipReason::IpFragment,
                            }))
                        }
                        Added::Complete if frag.protocol != 17 => {
                            return Ok(Some(Record::Skipped {
                                offset: f.offset,
                                reason: SkipReason::NotIpv4Udp,
                            }))
                        }
                        Added::Complete => {
                            let payload = self.defrag.payload();
                            return Ok(Some(datagram_record(frag.src, payload, f.time, f.offset)));
                        }
                    }
                }
            }
            return Ok(Some(frame_record(
                f.link,
                &self.buf[f.data],
                f.captured,
                f.original,
                f.time,
                f.offset,
            )));
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
/// default 10^-6), saturating at the i64 limit (year 2262).
fn ng_time_ns(units: u128, resol: u8) -> i64 {
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
    i64::try_from(ns).unwrap_or(i64::MAX)
}

/// A reassembled datagram's IP payload as a UDP datagram (the UDP header, then the data up
/// to the UDP length), or why not.
fn datagram_record(
    src_addr: std::net::Ipv4Addr,
    ip_payload: &[u8],
    time: HostTime,
    offset: u64,
) -> Record<'_> {
    if ip_payload.len() < 8 {
        return Record::Skipped {
            offset,
            reason: SkipReason::NotIpv4Udp,
        };
    }
    let be = |i: usize| u16::from_be_bytes([ip_payload[i], ip_payload[i + 1]]);
    let len = usize::from(be(4));
    let data = &ip_payload[8..];
    let payload = if len >= 8 && len - 8 <= data.len() {
        &data[..len - 8]
    } else {
        data
    };
    Record::Udp(Datagram {
        time,
        src_addr,
        src_port: be(0),
        dst_port: be(2),
        payload,
        offset,
    })
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

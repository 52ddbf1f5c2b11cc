//! Raw logging on the rig: every datagram received on the LiDAR sockets into classic pcap files,
//! every serial read into serial logs (`.vnlog`, format in [`crate::serial`]), both rotated by
//! size. The writer hands its bytes to the OS with [`PcapLog::flush`] and another thread makes
//! them durable (`fdatasync`) on the handle it returns; a rotation syncs the old file first.
//!
//! Files are `DIR/PREFIX-NNN.EXT` (`NNN` from 000): each one is complete in itself (its own
//! pcap or log header), so any piece decodes alone.

pub mod mcap_log;

use crate::packet::HostTime;
use crate::pcap::{build_fragment_frame, build_udp_frame, PcapWriter, UdpEndpoints};
use crate::serial::{LogWriter, RxStamp};
pub use mcap_log::McapLog;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::net::Ipv4Addr;
use std::path::{Path, PathBuf};

/// Write buffer per open file.
const BUFFER: usize = 1 << 20;

/// A file format the raw logs rotate: how a file starts, and where its bytes go.
pub trait Format {
    /// The writer over one file, its header written.
    type Writer;
    /// File name extension.
    const EXT: &'static str;
    /// Bytes of the file header.
    const HEADER: u64;
    /// Write the header on a new file.
    fn start(&self, file: BufWriter<File>) -> io::Result<Self::Writer>;
    /// The buffered file under a writer.
    fn file(w: &mut Self::Writer) -> &mut BufWriter<File>;
}

/// Classic pcap (Ethernet), as [`PcapWriter`] writes it; holds the frame being rebuilt.
pub struct Pcap {
    frame: Vec<u8>,
}

impl Format for Pcap {
    type Writer = PcapWriter<BufWriter<File>>;
    const EXT: &'static str = "pcap";
    const HEADER: u64 = 24;
    fn start(&self, file: BufWriter<File>) -> io::Result<Self::Writer> {
        PcapWriter::new(file).map_err(io::Error::other)
    }
    fn file(w: &mut Self::Writer) -> &mut BufWriter<File> {
        w.get_mut()
    }
}

/// The serial log format of [`crate::serial`], with the port's baud rate in its header.
pub struct Vnlog {
    baud: u32,
}

impl Format for Vnlog {
    type Writer = LogWriter<BufWriter<File>>;
    const EXT: &'static str = "vnlog";
    const HEADER: u64 = 16;
    fn start(&self, file: BufWriter<File>) -> io::Result<Self::Writer> {
        LogWriter::new(file, self.baud)
    }
    fn file(w: &mut Self::Writer) -> &mut BufWriter<File> {
        w.get_mut()
    }
}

/// Rotating files of one format: `DIR/PREFIX-NNN.EXT`, a new one (header first) before a
/// record would take the current one past the size limit.
pub struct Rotating<F: Format> {
    format: F,
    dir: PathBuf,
    prefix: String,
    limit: u64,
    out: F::Writer,
    /// Bytes in the current file.
    written: u64,
    files: Vec<PathBuf>,
    /// Records written.
    pub records: u64,
}

/// Rotating pcap files of received datagrams (rebuilt as Ethernet/IPv4/UDP frames with the
/// sender's address and ports, the receive time as the record time).
pub type PcapLog = Rotating<Pcap>;

/// Rotating serial logs.
pub type SerialLog = Rotating<Vnlog>;

fn open(
    dir: &Path,
    prefix: &str,
    ext: &str,
    index: usize,
) -> io::Result<(PathBuf, BufWriter<File>)> {
    let path = dir.join(format!("{prefix}-{index:03}.{ext}"));
    let f = File::create(&path)
        .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
    Ok((path, BufWriter::with_capacity(BUFFER, f)))
}

impl<F: Format> Rotating<F> {
    fn create(dir: &Path, prefix: &str, limit: u64, format: F) -> io::Result<Self> {
        let (path, file) = open(dir, prefix, F::EXT, 0)?;
        Ok(Self {
            out: format.start(file)?,
            format,
            dir: dir.to_path_buf(),
            prefix: prefix.to_string(),
            limit: limit.max(1),
            written: F::HEADER,
            files: vec![path],
            records: 0,
        })
    }

    /// Make room for a record of `need` bytes: start the next file (the current one synced to
    /// the disk first) if this one would pass the limit and a file may end here (`may_end`:
    /// not inside a datagram's fragments); count the record.
    fn room(&mut self, need: usize, may_end: bool) -> io::Result<()> {
        if may_end && self.written > F::HEADER && self.written + need as u64 > self.limit {
            self.sync()?;
            let (path, file) = open(&self.dir, &self.prefix, F::EXT, self.files.len())?;
            self.out = self.format.start(file)?;
            self.files.push(path);
            self.written = F::HEADER;
        }
        self.written += need as u64;
        self.records += 1;
        Ok(())
    }

    /// Flush to the disk (not only the OS).
    pub fn sync(&mut self) -> io::Result<()> {
        let w = F::file(&mut self.out);
        w.flush()?;
        w.get_ref().sync_data()
    }

    /// Hand the buffered bytes to the OS and return a second handle on the file, so that
    /// another thread can `sync_data` it while this one goes on writing (a slow disk then
    /// delays durability, not logging).
    pub fn flush(&mut self) -> io::Result<File> {
        let w = F::file(&mut self.out);
        w.flush()?;
        w.get_ref().try_clone()
    }

    /// The files written so far, in order.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }
}

impl Rotating<Pcap> {
    /// Start `DIR/PREFIX-000.pcap`; rotate past `limit` bytes.
    pub fn create_pcap(dir: &Path, prefix: &str, limit: u64) -> io::Result<Self> {
        let frame = Vec::with_capacity(2048);
        Self::create(dir, prefix, limit, Pcap { frame })
    }

    /// Append a datagram from `src` to `dst` received at `time`.
    pub fn write(
        &mut self,
        time: HostTime,
        src: (Ipv4Addr, u16),
        dst: (Ipv4Addr, u16),
        payload: &[u8],
    ) -> io::Result<()> {
        let ep = UdpEndpoints {
            src_ip: src.0.octets(),
            dst_ip: dst.0.octets(),
            ..UdpEndpoints::default()
        };
        build_udp_frame(&mut self.format.frame, &ep, src.1, dst.1, payload)?;
        self.room(16 + self.format.frame.len(), true)?;
        self.out
            .write_frame(time, &self.format.frame)
            .map_err(io::Error::other)
    }

    /// Append one IPv4 fragment (`id`, byte `offset` in the IP payload, "more fragments") of a
    /// UDP datagram from `src` to `dst` received at `time`, as the wire carried it
    /// ([`build_fragment_frame`]; the capture reader reassembles them). A file rotates only
    /// before a first fragment; only a datagram's last fragment counts as a record.
    pub fn write_fragment(
        &mut self,
        time: HostTime,
        (src, dst): (Ipv4Addr, Ipv4Addr),
        frag: (u16, usize, bool),
        bytes: &[u8],
    ) -> io::Result<()> {
        let ep = UdpEndpoints {
            src_ip: src.octets(),
            dst_ip: dst.octets(),
            ..UdpEndpoints::default()
        };
        build_fragment_frame(&mut self.format.frame, &ep, frag, bytes)?;
        // A datagram's fragments stay in one file (a reader reassembles them file by file).
        self.room(16 + self.format.frame.len(), frag.1 == 0)?;
        if frag.2 {
            self.records -= 1;
        }
        self.out
            .write_frame(time, &self.format.frame)
            .map_err(io::Error::other)
    }
}

impl Rotating<Vnlog> {
    /// Start `DIR/PREFIX-000.vnlog`; rotate past `limit` bytes.
    pub fn create_vnlog(dir: &Path, prefix: &str, limit: u64, baud: u32) -> io::Result<Self> {
        Self::create(dir, prefix, limit, Vnlog { baud })
    }

    /// Append one read.
    pub fn write(&mut self, stamp: RxStamp, bytes: &[u8]) -> io::Result<()> {
        self.room(crate::serial::RECORD_HEADER + bytes.len(), true)?;
        self.out.record(stamp, bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pcap::PcapSource;
    use crate::serial::read_byte_file;
    use crate::{PacketSource, Record};

    fn tmp(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("spherecal-rawlog-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// 100 datagrams over 3-kB files: several pieces, each a valid pcap, together every
    /// datagram in order with its time, addresses and ports.
    #[test]
    fn pcap_pieces_hold_every_datagram() {
        let dir = tmp("pcap");
        let mut log = PcapLog::create_pcap(&dir, "lidar", 3000).unwrap();
        let src = (Ipv4Addr::new(192, 168, 1, 201), 2368);
        let dst = (Ipv4Addr::new(192, 168, 1, 77), 2368);
        for i in 0..100u32 {
            let payload = vec![i as u8; 100 + i as usize];
            log.write(
                HostTime(1_700_000_000_000_000_000 + i64::from(i) * 1000),
                src,
                dst,
                &payload,
            )
            .unwrap();
        }
        log.sync().unwrap();
        let files = log.files().to_vec();
        assert!(files.len() > 3, "{files:?}");
        let mut i = 0u32;
        for f in &files {
            assert!(std::fs::metadata(f).unwrap().len() <= 3000 + 16 + 42 + 200);
            let mut s = PcapSource::open(f).unwrap();
            while let Some(r) = s.next_record().unwrap() {
                let Record::Udp(d) = r else { panic!("{r:?}") };
                assert_eq!(d.payload, vec![i as u8; 100 + i as usize].as_slice());
                assert_eq!((d.src_addr, d.src_port, d.dst_port), (src.0, 2368, 2368));
                assert_eq!(d.time.0, 1_700_000_000_000_000_000 + i64::from(i) * 1000);
                i += 1;
            }
        }
        assert_eq!(i, 100);
    }

    /// Datagrams longer than the link's MTU (an Ouster's 12,544-byte lidar packets, and one of
    /// 65,507 bytes: UDP's most) written as the IPv4 fragments the sender cut, between whole
    /// short ones: the capture reader reassembles each, whole, at its time; a record each.
    #[test]
    fn fragments_read_back_as_their_datagrams() {
        let dir = tmp("fragments");
        // (Files of 20 kB: they rotate between datagrams, never inside one.)
        let mut log = PcapLog::create_pcap(&dir, "lidar", 20_000).unwrap();
        let (src, dst) = (
            Ipv4Addr::new(169, 254, 10, 2),
            Ipv4Addr::new(169, 254, 10, 1),
        );
        let big = |n: usize, i: usize| (0..n).map(|k| (k * 7 + i) as u8).collect::<Vec<u8>>();
        let sizes = [12_544, 100, 1472, 1473, 24_832, 65_507, 3];
        for (i, &n) in sizes.iter().enumerate() {
            let t = HostTime(1_700_000_000_000_000_000 + i as i64 * 1000);
            let payload = big(n, i);
            let pieces: Vec<_> = crate::pcap::udp_fragments(7502, 7502, &payload)
                .unwrap()
                .collect();
            assert_eq!(pieces.len(), (n + 8).div_ceil(1480));
            if pieces.len() == 1 {
                log.write(t, (src, 7502), (dst, 7502), &payload).unwrap();
                continue;
            }
            for p in pieces {
                let mut bytes = p.udp_header.map(|h| h.to_vec()).unwrap_or_default();
                bytes.extend_from_slice(p.payload);
                assert!(p.offset % 8 == 0 && (bytes.len() == 1480 || !p.more));
                log.write_fragment(t, (src, dst), (i as u16, p.offset, p.more), &bytes)
                    .unwrap();
            }
        }
        assert!(crate::pcap::udp_fragments(1, 2, &[0; 65_508]).is_none());
        assert_eq!(log.records, sizes.len() as u64);
        log.sync().unwrap();
        assert!(log.files().len() >= 3, "{:?}", log.files());
        let mut got = Vec::new();
        for f in log.files() {
            let mut s = PcapSource::open(f).unwrap();
            while let Some(r) = s.next_record().unwrap() {
                let Record::Udp(d) = r else { panic!("{r:?}") };
                let i = got.len();
                assert_eq!(d.payload, big(sizes[i], i).as_slice(), "datagram {i}");
                assert_eq!((d.src_addr, d.dst_port), (src, 7502));
                assert_eq!(d.time.0, 1_700_000_000_000_000_000 + i as i64 * 1000);
                got.push(d.payload.len());
            }
        }
        assert_eq!(got, sizes);
    }

    #[test]
    fn serial_pieces_hold_every_read() {
        let dir = tmp("serial");
        let mut log = SerialLog::create_vnlog(&dir, "ins", 500, 921_600).unwrap();
        let mut want = Vec::new();
        for i in 0..50u8 {
            let chunk = vec![i; 1 + usize::from(i)];
            want.extend_from_slice(&chunk);
            let stamp = RxStamp {
                mono_ns: u64::from(i),
                wall: HostTime(i64::from(i) * 10),
            };
            log.write(stamp, &chunk).unwrap();
        }
        log.sync().unwrap();
        let mut got = Vec::new();
        let mut stamps = 0;
        for f in log.files() {
            let (bytes, st) = read_byte_file(f).unwrap();
            got.extend_from_slice(&bytes);
            stamps += st.unwrap().len();
        }
        assert!(log.files().len() > 3);
        assert_eq!(got, want);
        assert_eq!(stamps, 50);
    }
}

//! Raw logging on the rig: every datagram received on the LiDAR sockets into classic pcap files,
//! every serial read into serial logs (`.vnlog`, format in [`crate::serial`]), both rotated by
//! size. The writer hands its bytes to the OS with [`PcapLog::flush`] and another thread makes
//! them durable (`fdatasync`) on the handle it returns; a rotation syncs the old file first.
//!
//! Files are `DIR/PREFIX-NNN.EXT` (`NNN` from 000): each one is complete in itself (its own
//! pcap or log header), so any piece decodes alone.

use crate::packet::HostTime;
use crate::pcap::{build_udp_frame, PcapWriter, UdpEndpoints};
use crate::serial::{LogWriter, RxStamp};
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::net::Ipv4Addr;
use std::path::{Path, PathBuf};

/// Write buffer per open file.
const BUFFER: usize = 1 << 20;

/// What both raw logs share: the folder, naming, rotation size and the files written.
#[derive(Debug, Clone)]
pub struct Rotation {
    dir: PathBuf,
    prefix: String,
    ext: &'static str,
    limit: u64,
    index: u32,
    /// Bytes in the current file.
    pub written: u64,
    /// Files opened so far, in order.
    pub files: Vec<PathBuf>,
}

impl Rotation {
    fn new(dir: &Path, prefix: &str, ext: &'static str, limit: u64) -> Self {
        Self {
            dir: dir.to_path_buf(),
            prefix: prefix.to_string(),
            ext,
            limit: limit.max(1),
            index: 0,
            written: 0,
            files: Vec::new(),
        }
    }

    fn next_file(&mut self) -> io::Result<BufWriter<File>> {
        let path = self
            .dir
            .join(format!("{}-{:03}.{}", self.prefix, self.index, self.ext));
        self.index += 1;
        let f = File::create(&path)
            .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
        self.files.push(path);
        self.written = 0;
        Ok(BufWriter::with_capacity(BUFFER, f))
    }

    fn full(&self, next: usize) -> bool {
        self.written > 0 && self.written + next as u64 > self.limit
    }
}

fn durable(w: &mut BufWriter<File>) -> io::Result<()> {
    w.flush()?;
    w.get_ref().sync_data()
}

/// Hand the buffered bytes to the OS and return a second handle on the file, so that another
/// thread can `sync_data` it while this one goes on writing (a slow disk then delays
/// durability, not logging).
fn handed_over(w: &mut BufWriter<File>) -> io::Result<File> {
    w.flush()?;
    w.get_ref().try_clone()
}

/// Rotating pcap files of received datagrams (rebuilt as Ethernet/IPv4/UDP frames with the
/// sender's address and ports, the receive time as the record time).
pub struct PcapLog {
    rot: Rotation,
    out: PcapWriter<BufWriter<File>>,
    frame: Vec<u8>,
    /// Datagrams written.
    pub records: u64,
}

impl PcapLog {
    /// Start `DIR/PREFIX-000.pcap`; rotate past `limit` bytes.
    pub fn create(dir: &Path, prefix: &str, limit: u64) -> io::Result<Self> {
        let mut rot = Rotation::new(dir, prefix, "pcap", limit);
        let out = PcapWriter::new(rot.next_file()?).map_err(io::Error::other)?;
        rot.written = 24;
        Ok(Self {
            rot,
            out,
            frame: Vec::with_capacity(2048),
            records: 0,
        })
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
        build_udp_frame(&mut self.frame, &ep, src.1, dst.1, payload)?;
        let need = 16 + self.frame.len();
        if self.rot.full(need) {
            durable(self.out.get_mut())?;
            self.out = PcapWriter::new(self.rot.next_file()?).map_err(io::Error::other)?;
            self.rot.written = 24;
        }
        self.out
            .write_frame(time, &self.frame)
            .map_err(io::Error::other)?;
        self.rot.written += need as u64;
        self.records += 1;
        Ok(())
    }

    /// Flush to the disk (not only the OS).
    pub fn sync(&mut self) -> io::Result<()> {
        durable(self.out.get_mut())
    }

    /// Flush to the OS; a handle on the current file to `sync_data` elsewhere.
    pub fn flush(&mut self) -> io::Result<File> {
        handed_over(self.out.get_mut())
    }

    /// The files written so far.
    pub fn files(&self) -> &[PathBuf] {
        &self.rot.files
    }
}

/// Rotating serial logs.
pub struct SerialLog {
    rot: Rotation,
    out: LogWriter<BufWriter<File>>,
    baud: u32,
    /// Reads written.
    pub records: u64,
}

impl SerialLog {
    /// Start `DIR/PREFIX-000.vnlog`; rotate past `limit` bytes.
    pub fn create(dir: &Path, prefix: &str, limit: u64, baud: u32) -> io::Result<Self> {
        let mut rot = Rotation::new(dir, prefix, "vnlog", limit);
        let out = LogWriter::new(rot.next_file()?, baud)?;
        rot.written = 16;
        Ok(Self {
            rot,
            out,
            baud,
            records: 0,
        })
    }

    /// Append one read.
    pub fn write(&mut self, stamp: RxStamp, bytes: &[u8]) -> io::Result<()> {
        let need = crate::serial::RECORD_HEADER + bytes.len();
        if self.rot.full(need) {
            durable(self.out.get_mut())?;
            self.out = LogWriter::new(self.rot.next_file()?, self.baud)?;
            self.rot.written = 16;
        }
        self.out.record(stamp, bytes)?;
        self.rot.written += need as u64;
        self.records += 1;
        Ok(())
    }

    /// Flush to the disk (not only the OS).
    pub fn sync(&mut self) -> io::Result<()> {
        durable(self.out.get_mut())
    }

    /// Flush to the OS; a handle on the current file to `sync_data` elsewhere.
    pub fn flush(&mut self) -> io::Result<File> {
        handed_over(self.out.get_mut())
    }

    /// The files written so far.
    pub fn files(&self) -> &[PathBuf] {
        &self.rot.files
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
        let mut log = PcapLog::create(&dir, "lidar", 3000).unwrap();
        let src = (Ipv4Addr::new(192, 168, 1, 201), 2368);
        let dst = (Ipv4Addr::new(192, 168, 1, 77), 2368);
        for i in 0..100u32 {
            let payload = vec![i as u8; 100 + i as usize];
            log.write(
                HostTime(1_700_000_000_000_000_000 + i128::from(i) * 1000),
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
                assert_eq!(d.time.0, 1_700_000_000_000_000_000 + i128::from(i) * 1000);
                i += 1;
            }
        }
        assert_eq!(i, 100);
    }

    #[test]
    fn serial_pieces_hold_every_read() {
        let dir = tmp("serial");
        let mut log = SerialLog::create(&dir, "ins", 500, 921_600).unwrap();
        let mut want = Vec::new();
        for i in 0..50u8 {
            let chunk = vec![i; 1 + usize::from(i)];
            want.extend_from_slice(&chunk);
            let stamp = RxStamp {
                mono_ns: u64::from(i),
                wall_ns: i64::from(i) * 10,
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

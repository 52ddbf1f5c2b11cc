//! The raw log as MCAP (board `[log] format = "mcap"`): every datagram and serial read in a
//! rosbag2 folder `DIR/PREFIX/` that Foxglove and `ros2 bag` open and `spherecal --bag` reads
//! back: `PREFIX_N.mcap` files rotated by size like the pcap and serial logs (each a complete
//! MCAP file) and a `metadata.yaml` listing them (rewritten at each rotation and at the end; a
//! folder without it is read by file name). Messages are CDR (ros2msg schemas in the file):
//! - `/velodyne_packets` `velodyne_msgs/msg/VelodyneScan`: the data packets, [`SCAN_PACKETS`]
//!   per message, each stamped with its receive time (as the ROS 2 Velodyne driver records);
//! - `/spherecal/datagrams` `spherecal_msgs/msg/Datagram`: every other datagram (position
//!   packets, POS MV groups) with its addresses, so nothing of the pcap log is lost;
//! - `/spherecal/serial` `spherecal_msgs/msg/SerialChunk`: each serial read (the VN-200's
//!   bytes) with its receive stamps and the port's baud rate.

use crate::packet::HostTime;
use crate::serial::RxStamp;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::net::Ipv4Addr;
use std::path::{Path, PathBuf};

/// Data packets per `VelodyneScan` (the ROS 2 driver's npackets for a VLP-16 at 600 rpm).
pub const SCAN_PACKETS: usize = 76;
/// Bytes per MCAP chunk (~0.2 s of a VLP-16's packets).
pub const CHUNK_BYTES: u64 = 256 << 10;
/// The data packets' topic.
pub const SCAN_TOPIC: &str = "/velodyne_packets";
/// Every other datagram's topic.
pub const DATAGRAM_TOPIC: &str = "/spherecal/datagrams";
/// The serial reads' topic.
pub const SERIAL_TOPIC: &str = "/spherecal/serial";
/// The datagrams' type.
pub const DATAGRAM_TYPE: &str = "spherecal_msgs/msg/Datagram";
/// The serial reads' type.
pub const SERIAL_TYPE: &str = "spherecal_msgs/msg/SerialChunk";

const TIME_DEF: &str = "================================================================================\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
const SCAN_DEF: &str = "std_msgs/Header header\nvelodyne_msgs/VelodynePacket[] packets\n================================================================================\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n================================================================================\nMSG: velodyne_msgs/VelodynePacket\nbuiltin_interfaces/Time stamp\nuint8[1206] data\n";
const DATAGRAM_DEF: &str = "# A UDP datagram as received: when, from where, to which port.\nbuiltin_interfaces/Time stamp\nuint8[4] src_addr\nuint16 src_port\nuint16 dst_port\nuint8[] payload\n";
const SERIAL_DEF: &str = "# One read of a serial port: wall-clock and monotonic receive times, the baud rate.\nbuiltin_interfaces/Time stamp\nuint64 mono_ns\nuint32 baud\nuint8[] data\n";

/// A CDR message being built (XCDR1 little endian; alignment from the end of the
/// encapsulation header).
struct Cdr(Vec<u8>);

impl Cdr {
    fn new(out: &mut Vec<u8>) -> Cdr {
        let mut v = std::mem::take(out);
        v.clear();
        v.extend_from_slice(&[0, 1, 0, 0]);
        Cdr(v)
    }
    fn align(&mut self, n: usize) {
        while !(self.0.len() - 4).is_multiple_of(n) {
            self.0.push(0);
        }
    }
    fn u16(&mut self, v: u16) {
        self.align(2);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn time(&mut self, t: HostTime) {
        self.u32(t.0.div_euclid(1_000_000_000) as i32 as u32);
        self.u32(t.0.rem_euclid(1_000_000_000) as u32);
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
    }
    fn bytes(&mut self, b: &[u8]) {
        self.u32(b.len() as u32);
        self.0.extend_from_slice(b);
    }
}

/// The open file: its MCAP writer and a second handle to sync it.
struct Open {
    w: mcap::Writer<BufWriter<File>>,
    file: File,
    channels: [u16; 3],
}

/// Rotating MCAP raw logs.
pub struct McapLog {
    /// The bag folder.
    dir: PathBuf,
    prefix: String,
    /// Messages per topic, and the first and last log times.
    counts: [u64; 3],
    span: Option<(i64, i64)>,
    limit: u64,
    baud: u32,
    /// The LiDAR's data port (its 1206-byte datagrams go into the scans).
    data_port: u16,
    out: Option<Open>,
    files: Vec<PathBuf>,
    /// Bytes of messages in the current file.
    written: u64,
    /// The data packets of the scan being gathered: receive time and payload.
    scan: Vec<(HostTime, [u8; 1206])>,
    /// Each channel's next sequence number.
    sequence: [u32; 3],
    buf: Vec<u8>,
    /// Datagrams written.
    pub datagrams: u64,
    /// Serial reads written.
    pub reads: u64,
}

fn err(e: mcap::McapError) -> io::Error {
    io::Error::other(e.to_string())
}

impl McapLog {
    /// Start the bag folder `DIR/PREFIX/` with `PREFIX_0.mcap`; rotate past `limit` bytes; the
    /// LiDAR sends its data packets to `data_port` (in the bag the scans stand for that
    /// port's datagrams; other datagrams keep their ports); the serial port runs at `baud`.
    pub fn create(
        dir: &Path,
        prefix: &str,
        limit: u64,
        data_port: u16,
        baud: u32,
    ) -> io::Result<Self> {
        let dir = dir.join(prefix);
        std::fs::create_dir_all(&dir)
            .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", dir.display())))?;
        let mut l = Self {
            dir,
            prefix: prefix.to_string(),
            counts: [0; 3],
            span: None,
            limit: limit.max(1),
            baud,
            data_port,
            out: None,
            files: Vec::new(),
            written: 0,
            scan: Vec::with_capacity(SCAN_PACKETS),
            sequence: [0; 3],
            buf: Vec::with_capacity(SCAN_PACKETS * 1220),
            datagrams: 0,
            reads: 0,
        };
        l.start()?;
        Ok(l)
    }

    fn start(&mut self) -> io::Result<()> {
        let path = self
            .dir
            .join(format!("{}_{}.mcap", self.prefix, self.files.len()));
        let f = File::create(&path)
            .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
        let file = f.try_clone()?;
        let mut w = mcap::WriteOptions::new()
            .profile("ros2")
            .library("spherecal raw log")
            .compression(None)
            // Chunks with their message indexes: readers order the messages by time (a scan is
            // logged after the position packets and serial reads received during it), and a
            // crash loses what came since the last flush (the logger's, every 0.5 s, closes the
            // chunk being filled).
            .use_chunks(true)
            .chunk_size(Some(CHUNK_BYTES))
            .create(BufWriter::with_capacity(1 << 20, f))
            .map_err(err)?;
        let mut channels = [0u16; 3];
        for (k, (topic, ty, def)) in [
            (
                SCAN_TOPIC,
                "velodyne_msgs/msg/VelodyneScan",
                SCAN_DEF.to_string(),
            ),
            (
                DATAGRAM_TOPIC,
                DATAGRAM_TYPE,
                format!("{DATAGRAM_DEF}{TIME_DEF}"),
            ),
            (SERIAL_TOPIC, SERIAL_TYPE, format!("{SERIAL_DEF}{TIME_DEF}")),
        ]
        .into_iter()
        .enumerate()
        {
            let def = if k == 0 {
                format!("{def}{TIME_DEF}")
            } else {
                def
            };
            let schema = w.add_schema(ty, "ros2msg", def.as_bytes()).map_err(err)?;
            channels[k] = w
                .add_channel(schema, topic, "cdr", &BTreeMap::new())
                .map_err(err)?;
        }
        self.out = Some(Open { w, file, channels });
        self.files.push(path);
        self.written = 0;
        Ok(())
    }

    /// Write the message in `self.buf` on channel `k` at `time`, rotating first if the file
    /// would pass the limit (unless the file is being finished).
    fn put(&mut self, k: usize, time: HostTime, may_rotate: bool) -> io::Result<()> {
        let need = self.buf.len() as u64 + 40;
        if may_rotate && self.written > 0 && self.written + need > self.limit {
            // The message waits while the partial scan closes the old file.
            let msg = std::mem::take(&mut self.buf);
            self.finish_file()?;
            self.buf = msg;
            self.start()?;
        }
        self.written += need;
        self.counts[k] += 1;
        self.span = Some(
            self.span
                .map_or((time.0, time.0), |(a, b)| (a.min(time.0), b.max(time.0))),
        );
        let seq = self.sequence[k];
        self.sequence[k] = seq.wrapping_add(1);
        let Some(o) = self.out.as_mut() else {
            return Err(io::Error::other("the MCAP log is closed"));
        };
        let t = time.0.max(0) as u64;
        o.w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: o.channels[k],
                sequence: seq,
                log_time: t,
                publish_time: t,
            },
            &self.buf,
        )
        .map_err(err)
    }

    /// Write the gathered data packets as one `VelodyneScan`.
    fn put_scan(&mut self, may_rotate: bool) -> io::Result<()> {
        let Some(&(last, _)) = self.scan.last() else {
            return Ok(());
        };
        let mut c = Cdr::new(&mut self.buf);
        c.time(last);
        c.string("velodyne");
        c.u32(self.scan.len() as u32);
        for (t, p) in &self.scan {
            c.time(*t);
            c.0.extend_from_slice(p);
        }
        self.buf = c.0;
        self.scan.clear();
        self.put(0, last, may_rotate)
    }

    /// Append a datagram from `src` to `dst` received at `time`: a 1206-byte payload to the
    /// data port joins the scan being gathered, anything else is written as it is.
    pub fn write_datagram(
        &mut self,
        time: HostTime,
        src: (Ipv4Addr, u16),
        dst: (Ipv4Addr, u16),
        payload: &[u8],
    ) -> io::Result<()> {
        self.datagrams += 1;
        if dst.1 == self.data_port && payload.len() == 1206 {
            let mut p = [0u8; 1206];
            p.copy_from_slice(payload);
            self.scan.push((time, p));
            if self.scan.len() >= SCAN_PACKETS {
                self.put_scan(true)?;
            }
            return Ok(());
        }
        let mut c = Cdr::new(&mut self.buf);
        c.time(time);
        c.0.extend_from_slice(&src.0.octets());
        c.u16(src.1);
        c.u16(dst.1);
        c.bytes(payload);
        self.buf = c.0;
        self.put(1, time, true)
    }

    /// Append one serial read.
    pub fn write_serial(&mut self, stamp: RxStamp, bytes: &[u8]) -> io::Result<()> {
        self.reads += 1;
        let mut c = Cdr::new(&mut self.buf);
        c.time(stamp.wall);
        c.u64(stamp.mono_ns);
        c.u32(self.baud);
        c.bytes(bytes);
        self.buf = c.0;
        self.put(2, stamp.wall, true)
    }

    /// Hand the written chunks to the OS (the chunk being filled and a partial scan wait) and
    /// return a handle to sync the file with.
    pub fn flush(&mut self) -> io::Result<File> {
        let Some(o) = self.out.as_mut() else {
            return Err(io::Error::other("the MCAP log is closed"));
        };
        o.w.flush().map_err(err)?;
        o.file.try_clone()
    }

    /// Write the partial scan and the file's summary and footer, and sync it.
    fn finish_file(&mut self) -> io::Result<()> {
        self.put_scan(false)?;
        if let Some(mut o) = self.out.take() {
            o.w.finish().map_err(err)?;
            let mut inner = o.w.into_inner();
            inner.flush()?;
            o.file.sync_data()?;
        }
        self.write_metadata()
    }

    /// rosbag2's `metadata.yaml` (version 5 keys) for the files so far.
    fn write_metadata(&self) -> io::Result<()> {
        let (t0, t1) = self.span.unwrap_or((0, 0));
        let mut y = format!(
            "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n  duration:\n    nanoseconds: {}\n  starting_time:\n    nanoseconds_since_epoch: {t0}\n  message_count: {}\n  topics_with_message_count:\n",
            t1 - t0,
            self.counts.iter().sum::<u64>()
        );
        for (k, (topic, ty)) in [
            (SCAN_TOPIC, "velodyne_msgs/msg/VelodyneScan"),
            (DATAGRAM_TOPIC, DATAGRAM_TYPE),
            (SERIAL_TOPIC, SERIAL_TYPE),
        ]
        .iter()
        .enumerate()
        {
            y.push_str(&format!(
                "    - topic_metadata:\n        name: {topic}\n        type: {ty}\n        serialization_format: cdr\n        offered_qos_profiles: \"\"\n      message_count: {}\n",
                self.counts[k]
            ));
        }
        y.push_str(
            "  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n",
        );
        for f in &self.files {
            if let Some(n) = f.file_name() {
                y.push_str(&format!("    - {}\n", n.to_string_lossy()));
            }
        }
        let path = self.dir.join("metadata.yaml");
        std::fs::write(&path, y)
            .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))
    }

    /// The bag folder.
    pub fn bag(&self) -> &Path {
        &self.dir
    }

    /// End the log: the last scan, the summary and footer, synced. Nothing can be written
    /// after.
    pub fn finish(&mut self) -> io::Result<()> {
        self.finish_file()
    }

    /// The files written so far, in order.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::packet::{PacketSource, Record};
    use crate::rosbag::sources::{ScanPackets, SerialBytes};
    use crate::rosbag::Bag;
    use crate::serial::{ByteSource, ReadOutcome};

    /// 400 data packets, 20 position packets and 100 serial reads over 100-kB files: a bag
    /// folder of several complete MCAP files and its metadata.yaml; read back, every datagram
    /// (data packets gathered into scans of 76, the last one short) and every serial byte with
    /// its stamps.
    #[test]
    fn an_mcap_log_reads_back_as_what_was_received() {
        let dir = std::env::temp_dir().join(format!("spherecal-mcaplog-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mut log = McapLog::create(&dir, "run", 100_000, 2368, 115_200).unwrap();
        let sensor = (Ipv4Addr::new(192, 168, 1, 201), 2368);
        let me = Ipv4Addr::new(192, 168, 1, 77);
        let t0 = 1_700_000_000_000_000_000i64;
        let mut want_udp = Vec::new();
        let mut want_serial = Vec::new();
        for i in 0..400i64 {
            let t = HostTime(t0 + i * 1_327_000);
            let p: Vec<u8> = (0..1206).map(|k| (k as i64 * 7 + i) as u8).collect();
            log.write_datagram(t, sensor, (me, 2368), &p).unwrap();
            want_udp.push((t, 2368u16, p));
            if i % 20 == 0 {
                let q = vec![i as u8; 512];
                log.write_datagram(t, (sensor.0, 8308), (me, 8308), &q)
                    .unwrap();
                want_udp.push((t, 8308, q));
            }
            if i % 4 == 0 {
                let b = vec![(i / 4) as u8; 1 + (i as usize % 300)];
                let s = RxStamp {
                    mono_ns: i as u64,
                    wall: HostTime(t.0 + 5),
                };
                log.write_serial(s, &b).unwrap();
                want_serial.push((s, b));
            }
        }
        log.flush().unwrap();
        log.finish().unwrap();
        assert!(log.files().len() > 3, "{:?}", log.files());
        assert_eq!((log.datagrams, log.reads), (420, 100));
        let bag = Bag::open(log.bag()).unwrap();
        assert!(bag.metadata.is_some());
        assert_eq!(bag.files.len(), log.files().len());
        // The datagrams: data packets come in their scans, so a position packet may come
        // before the data packets received before it; per port, all in order.
        let mut src = ScanPackets::with_datagrams(
            bag.messages(&[SCAN_TOPIC, DATAGRAM_TOPIC]),
            Some(DATAGRAM_TOPIC),
        );
        let mut got = Vec::new();
        while let Some(r) = src.next_record().unwrap() {
            let Record::Udp(d) = r else { panic!("{r:?}") };
            assert_eq!(d.src_addr, sensor.0);
            got.push((d.time, d.dst_port, d.payload.to_vec()));
        }
        // Scans of 76, and a short one wherever a rotation closed a file mid-scan.
        assert!(
            (400u64.div_ceil(76)..=400u64.div_ceil(76) + log.files().len() as u64)
                .contains(&src.scans)
        );
        for port in [2368, 8308] {
            let a: Vec<_> = got.iter().filter(|g| g.1 == port).collect();
            let b: Vec<_> = want_udp.iter().filter(|g| g.1 == port).collect();
            assert_eq!(a, b, "port {port}");
        }
        // The serial reads, byte for byte, each with its stamps.
        let mut ser = SerialBytes::new(bag.messages(&[SERIAL_TOPIC]));
        let mut k = 0;
        let mut buf = [0u8; 4096];
        while let ReadOutcome::Data { len, stamp } = ser.read_chunk(&mut buf).unwrap() {
            assert_eq!(
                (&buf[..len], stamp),
                (&want_serial[k].1[..], Some(want_serial[k].0))
            );
            k += 1;
        }
        assert_eq!((k, ser.reads), (100, (100, Some(115_200))));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

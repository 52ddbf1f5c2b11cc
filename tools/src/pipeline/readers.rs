//! One reader per stream, used by the file pipeline and the rig alike: LiDAR packets from any
//! [`PacketSource`] onto the LiDAR ring; VN-200 bytes framed into gated poses; SBET records
//! into poses.

use super::*;
use spherecal::vn200::Framed;
use spherecal_hal::serial::{ByteSource, FileChain, ReadOutcome, RxStamp};
use std::net::Ipv4Addr;
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// The LiDAR ring end a reader writes to, and what it does when the ring is full.
pub struct LidarRing<'r, 'q> {
    /// The ring's producer end.
    pub ring: &'r mut heapless::spsc::Producer<'q, LidarItem>,
    /// Wait (files) or drop (live).
    pub policy: Overflow,
    /// Counts the full-ring events.
    pub full: &'r AtomicU64,
    /// Counts the items enqueued.
    pub queued: &'r AtomicU64,
}

/// Which datagrams a LiDAR reader hands on: the sensor's two ports and, for live input, its
/// address (the board's `sensor_addr`; `None` accepts any sender).
#[derive(Debug, Clone, Copy, Default)]
pub struct Accept {
    /// The data and position ports.
    pub ports: Ports,
    /// The sensor's address.
    pub sensor: Option<Ipv4Addr>,
    /// The sensor is a Hesai: its data packets (on the data port) instead of a Velodyne's.
    pub hesai: bool,
}

impl Accept {
    /// The ring item for `d`, or why it is skipped.
    pub fn item(&self, d: &Datagram<'_>) -> Result<LidarItem, SkipReason> {
        match self.sensor {
            Some(a) if a != d.src_addr => Err(SkipReason::OtherSender(d.src_addr)),
            _ if self.hesai => match d.dst_port == self.ports.data {
                true => spherecal::hesai::DataPacket::new_checked(d.payload)
                    .map(|p| LidarItem::hesai(&p, Some(d.time)))
                    .map_err(SkipReason::Hesai),
                false
                    if d.dst_port == self.ports.position
                        || d.dst_port == spherecal::hesai::GPS_PORT =>
                {
                    spherecal::hesai::GpsPacket::new_checked(d.payload)
                        .map(|p| LidarItem::hesai_gps(&p, Some(d.time)))
                        .map_err(SkipReason::Hesai)
                }
                false => Err(SkipReason::OtherPort(d.dst_port)),
            },
            _ => LidarItem::classify(d, self.ports),
        }
    }
}

/// Every record of `src` until it ends, fails or `stop` is set: accepted VLP-16 packets onto
/// the ring, the rest counted by reason. The same loop reads a capture file (waiting for room)
/// and a live socket (dropping on a full ring); the caller ends the ring ([`end_lidar`]).
pub fn lidar_reader<S: PacketSource>(
    src: &mut S,
    out: &mut LidarRing<'_, '_>,
    accept: Accept,
    stop: &AtomicBool,
) -> (SkipStats, Result<(), S::Error>) {
    let mut skips = SkipStats::default();
    while !stop.load(Ordering::Relaxed) {
        let rec = match src.next_record() {
            Ok(Some(r)) => r,
            Ok(None) => break,
            Err(e) => return (skips, Err(e)),
        };
        let d = match rec {
            Record::Skipped { offset, reason } => {
                skips.count(offset, &reason);
                continue;
            }
            Record::Idle => continue,
            Record::Udp(d) => d,
        };
        match accept.item(&d) {
            Ok(item) => {
                if enqueue(out.ring, item, out.policy, out.full) {
                    out.queued.fetch_add(1, Ordering::Relaxed);
                }
            }
            Err(reason) => skips.count(d.offset, &reason),
        }
    }
    (skips, Ok(()))
}

/// Every return of a bag's point clouds onto the ring in chunks (a file: waits for room); the
/// cells and clouds not used are counted by reason. A topic whose returns mostly lie off their
/// ring's elevation is not in the LiDAR's own frame: an error naming its frame_id.
pub fn cloud_reader(
    src: &mut spherecal_hal::rosbag::clouds::CloudChunks,
    out: &mut LidarRing<'_, '_>,
) -> (SkipStats, Result<(), String>) {
    let mut chunk = spherecal_hal::rosbag::clouds::Chunk::default();
    let r = loop {
        match src.next_chunk(&mut chunk) {
            Ok(true) => {
                if enqueue(out.ring, LidarItem::points(&chunk), out.policy, out.full) {
                    out.queued.fetch_add(1, Ordering::Relaxed);
                }
            }
            Ok(false) => break Ok(()),
            Err(e) => break Err(e.to_string()),
        }
    };
    let st = &src.stats;
    let r = r.and_then(|()| {
        if st.off_elevation() > 0.5 {
            return Err(format!(
                "{:.0} % of the point clouds' returns are not on their ring's elevation for a {}: the clouds are not in the LiDAR's own frame (frame_id '{}'; record velodyne_pointcloud without a target_frame) or the LiDAR is another model (say --model)",
                100.0 * st.off_elevation(),
                src.model().name(),
                st.frame_id.as_deref().unwrap_or("")
            ));
        }
        Ok(())
    });
    (st.skips.clone(), r)
}

/// End the LiDAR ring: wait for room for the End, unless the aligner is `gone`.
pub fn end_lidar(ring: &mut heapless::spsc::Producer<'_, LidarItem>, gone: &AtomicBool) {
    let mut end = LidarItem::end();
    while let Err(back) = ring.enqueue(end) {
        if gone.load(Ordering::Acquire) {
            return;
        }
        end = back;
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

/// A trajectory file, opened: the VN-200 byte stream (a serial log's records joined), or an
/// SBET reader with the GPS week that dates it.
pub enum InsFile {
    /// VN-200 bytes (raw, or a serial log's records with their stamps), one file or several
    /// (rotated logs) in name order.
    Vn200(FileChain),
    /// SBET files in the order of their first record's time, and their GPS week.
    Sbet(Vec<PathBuf>, u16),
    /// POS MV streams (raw `.000` files or captures of its datagrams) in name order, the week
    /// that dates them until their Group 3 does, and the pose group.
    Posmv(Vec<PathBuf>, Option<u16>, u16),
    /// A ROS 2 bag's VectorNav groups as VN-200 frames.
    Bag(Box<crate::bag::BagIns>),
}

impl InsFile {
    /// Open what `ins` names; an SBET without a week is dated from the capture's RMC.
    pub fn open(ins: &InsInput, pcap: &Files, leap: i64) -> Result<Self, crate::Error> {
        match ins {
            InsInput::Bag(p, topic) => {
                let path = super::as_bag(p).ok_or_else(|| {
                    format!(
                        "{}: not a ROS 2 bag (a .mcap, a .db3 or a bag folder)",
                        p.display()
                    )
                })?;
                let b = crate::bag::open(path, None, topic.as_deref(), false)?;
                Ok(Self::Bag(Box::new(b.ins(leap)?)))
            }
            InsInput::Vn200(p) => {
                if let Some(d) = p.0.iter().find(|p| p.is_dir()) {
                    return Err(format!(
                        "{}: a folder; give the INS file or a pattern (e.g. DIR/*-ins-*.vnlog)",
                        d.display()
                    )
                    .into());
                }
                FileChain::open(p.expand()?)
                    .map(Self::Vn200)
                    .map_err(|e| e.to_string().into())
            }
            InsInput::Posmv(p, week, group) => {
                if ![1, 102, 103].contains(group) {
                    return Err(format!(
                        "POS MV group {group}: poses come from group 1, 102 or 103"
                    )
                    .into());
                }
                let week = week.or_else(|| week_from_capture(pcap, leap));
                Ok(Self::Posmv(p.expand()?, week, *group))
            }
            InsInput::Sbet(p, week) => {
                let week = sbet_week(*week, pcap, leap)?;
                let mut files = Vec::new();
                for f in p.expand()? {
                    files.push((first_tow(&f)?, f));
                }
                // Time order (the week's rollover aside: a file starting late in the week
                // goes first).
                files.sort_by(|a, b| a.0.total_cmp(&b.0));
                Ok(Self::Sbet(files.into_iter().map(|f| f.1).collect(), week))
            }
        }
    }
}

/// The first valid record's time of week of an SBET file (+inf when it has none).
fn first_tow(p: &Path) -> Result<f64, crate::Error> {
    let f = std::fs::File::open(p).map_err(|e| format!("{}: {e}", p.display()))?;
    let mut rd = SbetReader::new(std::io::BufReader::new(f));
    Ok(rd
        .next_record()
        .map_err(|e| format!("{}: {e}", p.display()))?
        .map_or(f64::INFINITY, |r| r.tow_s))
}

/// The GPS week of a POSPac file (SBET, smrmsg: their times are seconds of week): `week` if
/// given, else the capture's RMC date.
pub fn sbet_week(week: Option<u16>, pcap: &Files, leap: i64) -> Result<u16, crate::Error> {
    match week {
        Some(w) => Ok(w),
        None => week_from_capture(pcap, leap).ok_or_else(|| {
            format!(
                "{}: no RMC date in the capture to date the SBET; give --gps-week",
                pcap.display()
            )
            .into()
        }),
    }
}

/// Why an INS reader stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InsEnd {
    /// The source ended (a file's end; a serial port that closed).
    SourceEnded,
    /// `stop` was set.
    Stopped,
}

/// Told the INS clock's steps (GPS s, step s) each time the reader finds another.
pub type OnSteps<'a> = dyn FnMut(&[(f64, f64)]) + 'a;

/// Bytes from any [`ByteSource`] (a file, a serial log, the live port) through the VN-200
/// feed onto the INS ring, in reads of at most `buf.len()`, until the source ends, `stop` is
/// set, or it fails. `on_chunk` sees every read first (the rig logs it); `seen` every framed
/// item. Stamped reads give their poses the receive time.
#[allow(clippy::too_many_arguments)]
pub fn ins_reader<B: ByteSource>(
    src: &mut B,
    buf: &mut [u8],
    feed: &mut Vn200Feed,
    out: &mut InsRing<'_, '_>,
    stop: &AtomicBool,
    on_chunk: &mut dyn FnMut(&[u8], Option<RxStamp>),
    seen: &mut dyn FnMut(&Framed<'_>, &InsOutcome),
    on_steps: &mut OnSteps<'_>,
) -> Result<InsEnd, B::Error> {
    while !stop.load(Ordering::Relaxed) {
        match src.read_chunk(buf)? {
            ReadOutcome::Data { len, stamp } => {
                on_chunk(&buf[..len], stamp);
                let steps = feed.st.clock_steps.len();
                feed.feed(&buf[..len], stamp.map(|s| s.wall), out, seen);
                if feed.st.clock_steps.len() != steps {
                    on_steps(&feed.st.clock_steps);
                }
            }
            ReadOutcome::Idle => {}
            ReadOutcome::End => {
                feed.finish(out);
                return Ok(InsEnd::SourceEnded);
            }
        }
    }
    Ok(InsEnd::Stopped)
}

/// A trajectory file's poses onto the INS ring (the caller ends the ring), with the first 256
/// bytes of a VN-200 stream (to say what a file without poses looks like).
pub fn ins_file_reader(
    src: InsFile,
    frame: LocalFrame,
    keep_untracked: bool,
    max_gap_ns: i64,
    leap_seconds: i64,
    out: &mut InsRing<'_, '_>,
) -> Result<(InsState, Vec<u8>), crate::Error> {
    match src {
        InsFile::Vn200(mut file) => {
            let mut feed = Vn200Feed::new(frame, keep_untracked, max_gap_ns);
            let mut head = Vec::new();
            let mut keep_head = |b: &[u8], _: Option<RxStamp>| {
                let n = (256 - head.len()).min(b.len());
                head.extend_from_slice(&b[..n]);
            };
            ins_reader(
                &mut file,
                &mut [0u8; 4096],
                &mut feed,
                out,
                &AtomicBool::new(false),
                &mut keep_head,
                &mut |_, _| {},
                &mut |_| {},
            )
            .map_err(|e| e.to_string())?;
            Ok((feed.state(), head))
        }
        InsFile::Bag(mut bag) => {
            let mut feed = Vn200Feed::new(frame, keep_untracked, max_gap_ns);
            ins_reader(
                &mut *bag,
                &mut [0u8; 4096],
                &mut feed,
                out,
                &AtomicBool::new(false),
                &mut |_, _| {},
                &mut |_, _| {},
                &mut |_| {},
            )
            .map_err(|e| e.to_string())?;
            let mut st = feed.state();
            let said = bag.describe();
            st.bag = Some(said);
            Ok((st, Vec::new()))
        }
        InsFile::Posmv(files, week, group) => {
            let mut feed = super::posmv::PosmvFeed::new(
                frame,
                group,
                keep_untracked,
                max_gap_ns,
                leap_seconds,
                week,
            );
            let mut head = Vec::new();
            for path in files {
                let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
                let mut f = std::fs::File::open(&path).map_err(|e| err(&e))?;
                let mut magic = [0u8; 4];
                use std::io::{Read as _, Seek as _};
                let n = f.read(&mut magic).map_err(|e| err(&e))?;
                f.rewind().map_err(|e| err(&e))?;
                if head.is_empty() {
                    head.extend_from_slice(&magic[..n]);
                }
                if crate::state::looks_like(&magic[..n]) == "a pcap capture"
                    || magic[..n] == [0x0A, 0x0D, 0x0D, 0x0A]
                {
                    // A capture: every UDP payload that is not the LiDAR's.
                    let mut src = spherecal_hal::pcap::PcapSource::new(std::io::BufReader::new(f))
                        .map_err(|e| err(&e))?;
                    while let Some(rec) = src.next_record().map_err(|e| err(&e))? {
                        if let Record::Udp(d) = rec {
                            if d.dst_port != spherecal::velodyne::DATA_PORT
                                && d.dst_port != spherecal::velodyne::POSITION_PORT
                            {
                                feed.feed(d.payload, Some(d.time), out);
                            }
                        }
                    }
                } else {
                    let mut rd = std::io::BufReader::with_capacity(1 << 16, f);
                    let mut buf = [0u8; 1 << 16];
                    loop {
                        let n = rd.read(&mut buf).map_err(|e| err(&e))?;
                        if n == 0 {
                            break;
                        }
                        feed.feed(&buf[..n], None, out);
                    }
                }
            }
            feed.finish(out);
            Ok((feed.state(), head))
        }
        InsFile::Sbet(files, week) => {
            let mut st = InsState::default();
            // Each file's first bytes, to say what a file that is not an SBET looks like.
            let head_of = |p: &Path| {
                use std::io::Read as _;
                let mut head = Vec::new();
                if let Ok(f) = std::fs::File::open(p) {
                    let _ = f.take(64).read_to_end(&mut head);
                }
                head
            };
            let first_head = files.first().map(|p| head_of(p)).unwrap_or_default();
            for path in files {
                let head = head_of(&path);
                let f =
                    std::fs::File::open(&path).map_err(|e| format!("{}: {e}", path.display()))?;
                let mut rd = SbetReader::new(std::io::BufReader::new(f));
                while let Some(r) = rd.next_record().map_err(|e| match e {
                    spherecal_hal::sbet::PospacError::Io(_) => {
                        format!("{}: {e}", path.display())
                    }
                    _ => format!(
                        "{}: {e}; it looks like {}",
                        path.display(),
                        crate::state::looks_like(&head)
                    ),
                })? {
                    let Some(t) = r.time(week) else {
                        st.without_pose += 1;
                        continue;
                    };
                    let g = Geodetic {
                        lat: r.lat,
                        lon: r.lon,
                        h: r.h,
                    };
                    let local = spherecal::frames::rotation(r.roll, r.pitch, r.heading());
                    // Records of one file follow each other: nothing is lost between them.
                    st.sample(t, rd.records > 1, None);
                    st.used(t, max_gap_ns);
                    let pose = PoseSample::from_geodetic(&frame, t, &g, &local);
                    enqueue(out.ring, InsItem::Pose(pose, None), out.policy, out.full);
                }
                st.bytes += rd.records * spherecal_hal::sbet::RECORD as u64 + rd.trailing as u64;
                st.sbet_records += rd.records;
                st.without_pose += rd.invalid;
            }
            Ok((st, first_head))
        }
    }
}

/// What a framed VN-200 item gives the pipeline.
#[derive(Debug, Clone, Copy)]
pub enum InsOutcome {
    /// A pose in the site frame and the INS status word if the message carried it.
    Pose(PoseSample, Option<u16>),
    /// A binary frame without a complete pose (time, attitude, position).
    NoPose,
    /// A frame or sentence that failed its checksum or could not be parsed.
    Rejected,
    /// Something else (NMEA, other $VN sentences).
    Other,
}

/// The pose a framed VN-200 item carries: a binary frame, or an ASCII $VNINS sentence.
pub fn vn200_pose(item: &Item<'_>, frame: &LocalFrame) -> InsOutcome {
    let pose = match item {
        Item::Binary(f) => match Pose::from_frame(f) {
            Some(p) => p,
            None => return InsOutcome::NoPose,
        },
        Item::Ascii(a) => match a.decode() {
            Ok(spherecal::vn200::ascii::Vn::Ins(i)) => match Pose::from_ins(&i) {
                Some(p) => p,
                None => return InsOutcome::NoPose,
            },
            _ => return InsOutcome::Other,
        },
        Item::Nmea(_) => return InsOutcome::Other,
        Item::Error(_) => return InsOutcome::Rejected,
    };
    match PoseSample::from_vn200(frame, &pose) {
        Some(s) => InsOutcome::Pose(s, pose.ins_status),
        None => InsOutcome::NoPose,
    }
}

/// What a VN-200 states of its errors, in a navigation model's source.
const VN200_STATED: &str = "VN-200 Ins.PosU and Attitude.YprU";

/// The errors a VN-200 item states: a binary frame's Ins.PosU (one number, taken for each
/// axis) with its Attitude.YprU (all above zero), or a $VNINS sentence's PosU and AttU; north, east, down [m],
/// roll, pitch, heading [deg].
fn vn200_stated(item: &Item<'_>) -> Option<([f64; 3], [f64; 3])> {
    match item {
        Item::Binary(f) => {
            // Zero is no statement (a filter not yet converged; a simulator without noise).
            let p = f64::from(f.position_uncertainty_m()?);
            let [y, pi, r] = f.ypr_uncertainty_deg()?.map(f64::from);
            (p > 0.0 && y > 0.0 && pi > 0.0 && r > 0.0).then_some(([p; 3], [r, pi, y]))
        }
        Item::Ascii(a) => match a.decode() {
            Ok(spherecal::vn200::ascii::Vn::Ins(i)) => Some(([i.pos_u; 3], [i.att_u; 3])),
            _ => None,
        },
        _ => None,
    }
}

/// The VN-200 stream into poses, the same for a file and the live port: framing, pose
/// extraction, InsStatus gating (left-out poses counted with their spans unless kept), onto the
/// INS ring with the given overflow policy.
pub struct Vn200Feed {
    framer: Box<Framer>,
    gate: PoseGate,
    st: InsState,
}

/// Where a framed item's pose goes: converted into the site frame, gated by its InsStatus.
struct PoseGate {
    frame: LocalFrame,
    keep_untracked: bool,
    max_gap_ns: i64,
}

/// The INS ring end a feed writes to, and what it does when the ring is full.
pub struct InsRing<'r, 'q> {
    /// The ring's producer end.
    pub ring: &'r mut heapless::spsc::Producer<'q, InsItem>,
    /// Wait (files) or drop (live).
    pub policy: Overflow,
    /// Counts the full-ring events.
    pub full: &'r AtomicU64,
}

impl PoseGate {
    fn handle(
        &self,
        it: &Framed<'_>,
        st: &mut InsState,
        host: Option<HostTime>,
        out: &mut InsRing<'_, '_>,
        seen: &mut dyn FnMut(&Framed<'_>, &InsOutcome),
    ) {
        let got = vn200_pose(&it.item, &self.frame);
        seen(it, &got);
        match got {
            InsOutcome::Pose(s, status) => {
                match &it.item {
                    Item::Binary(f) => {
                        st.sample_frame(s.time, it.offset, f.bytes().len(), f.time_startup())
                    }
                    _ => st.sample(s.time, false, None),
                }
                // Not tracking, aligning, GNSS lost, no fix: left out (counted).
                match status.and_then(crate::state::excluded_by) {
                    Some(k) if !self.keep_untracked => {
                        st.exclude(s.time, k);
                        return;
                    }
                    Some(_) => st.kept_untracked += 1,
                    None => {}
                }
                st.used(s.time, self.max_gap_ns);
                if let Some((ned, rph)) = vn200_stated(&it.item) {
                    st.stated.add(VN200_STATED, ned, rph);
                }
                enqueue(out.ring, InsItem::Pose(s, host), out.policy, out.full);
            }
            InsOutcome::NoPose => st.without_pose += 1,
            InsOutcome::Rejected | InsOutcome::Other => {}
        }
    }
}

impl Vn200Feed {
    /// Poses in the site `frame`; `keep_untracked` uses poses whose InsStatus says not
    /// tracking too; samples further apart than `max_gap_ns` are counted as gaps.
    pub fn new(frame: LocalFrame, keep_untracked: bool, max_gap_ns: i64) -> Self {
        Self {
            framer: Box::default(),
            gate: PoseGate {
                frame,
                keep_untracked,
                max_gap_ns,
            },
            st: InsState::default(),
        }
    }

    /// Bytes received at `host` (if known). Every framed item is shown to
    /// `seen` with what it gave before its pose goes to the ring.
    pub fn feed(
        &mut self,
        bytes: &[u8],
        host: Option<HostTime>,
        out: &mut InsRing<'_, '_>,
        seen: &mut dyn FnMut(&Framed<'_>, &InsOutcome),
    ) {
        self.st.bytes += bytes.len() as u64;
        let Self { framer, gate, st } = self;
        framer.consume(bytes, |it| gate.handle(&it, st, host, out, seen));
    }

    /// The stream has ended: what the framer still holds.
    pub fn finish(&mut self, out: &mut InsRing<'_, '_>) {
        self.framer.finish();
        let Self { framer, gate, st } = self;
        while let Some(it) = framer.next() {
            gate.handle(&it, st, None, out, &mut |_, _| {});
        }
    }

    /// The stream's state so far, with the framer's counts.
    pub fn state(&self) -> InsState {
        let fs = self.framer.stats();
        InsState {
            frames: fs.frames,
            crc_failures: fs.crc_failures,
            skipped_bytes: fs.skipped_bytes,
            ascii: fs.ascii,
            nmea: fs.nmea,
            ..self.st.clone()
        }
    }
}

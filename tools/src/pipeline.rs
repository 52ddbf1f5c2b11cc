//! The threaded pipeline that joins the two sensor streams (DESIGN.md data flow), the same for
//! file replay and live input:
//!
//! ```text
//! LiDAR reader --(packets)--> spsc ring --\
//! INS reader   --(poses)----> spsc ring --> aligner: clock, pose history, georef, windows
//!                                              --> batches over crossbeam-channel --> consumer
//! ```
//! Rings are `heapless::spsc` queues. A full ring never blocks a live producer: it drops the
//! newest item and counts it. A file reader ([`Overflow::Wait`]) instead waits for room, since
//! a file can be read later and must not lose data; the waits are counted too.

use crate::config::site::Site;
use crate::state::InsState;
use heapless::spsc::{Consumer, Queue};
use spherecal::align::{AlignStats, Aligner as CoreAligner, PoseHistory, PoseSample};
use spherecal::frames::{Geodetic, LocalFrame};
use spherecal::georef::Mount;
use spherecal::vlp16::PositionPacket;
use spherecal::vn200::{Framer, Item, Pose};
use spherecal::window::{Batch, GeoPoint, Observation, Target};
use spherecal_hal::clock::{Clock, SystemClock};
use spherecal_hal::packet::{Datagram, SkipReason};
use spherecal_hal::pcap::PcapSource;
use spherecal_hal::sbet::SbetReader;
use spherecal_hal::vlp16::{classify, Ports, SkipStats, Vlp16Packet};
use spherecal_hal::{PacketSource, Record};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

/// LiDAR ring capacity (holds N - 1 packets: ~0.68 s of data packets, 0.6 MB).
pub const LIDAR_RING: usize = 512;
/// INS ring capacity (holds N - 1 poses: ~20 s at 200 Hz).
pub const INS_RING: usize = 4096;
/// Pose history kept by the aligner.
pub const HISTORY: usize = 4096;
/// Observations per batch sent to the consumer.
pub const BATCH: usize = 1024;

/// What a full ring does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overflow {
    /// Live input: drop the newest item and count it.
    Drop,
    /// File replay: wait for room (counted).
    Wait,
}

/// What a LiDAR ring item holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LidarKind {
    /// A data packet.
    Data,
    /// A position packet (its first 512 bytes).
    Position,
    /// The stream ended.
    End,
}

/// An item on the LiDAR ring: the payload held in place, so a packet costs one copy into the
/// ring and no allocation.
#[derive(Clone)]
pub struct LidarItem {
    /// What it is.
    pub kind: LidarKind,
    /// Host receive time [ns since 1970 on the host clock; 0 unknown].
    pub host_ns: i64,
    /// The payload (data: all 1206 bytes; position: the first 512).
    pub bytes: [u8; 1206],
}

impl LidarItem {
    /// An item holding `payload` (at most 1206 bytes) received at `host_ns`.
    pub fn new(kind: LidarKind, host_ns: i64, payload: &[u8]) -> Self {
        let mut bytes = [0u8; 1206];
        let n = payload.len().min(bytes.len());
        bytes[..n].copy_from_slice(&payload[..n]);
        Self {
            kind,
            host_ns,
            bytes,
        }
    }
}

impl LidarItem {
    /// The ring item for a received datagram, or why it is skipped.
    pub fn classify(d: &Datagram<'_>, ports: Ports) -> Result<Self, SkipReason> {
        let host = i64::try_from(d.time.0).unwrap_or(0);
        Ok(match classify(d, ports)? {
            Vlp16Packet::Data { packet, .. } => {
                Self::new(LidarKind::Data, host, packet.into_inner())
            }
            Vlp16Packet::Position { packet, .. } => {
                Self::new(LidarKind::Position, host, packet.into_inner())
            }
        })
    }
}

/// An item on the INS ring.
#[derive(Debug, Clone, Copy)]
pub enum InsItem {
    /// A pose in the site frame and its host receive time [ns since 1970; 0 unknown].
    Pose(PoseSample, i64),
    /// The stream ended.
    End,
}

/// Where the trajectory comes from.
#[derive(Debug, Clone)]
pub enum InsInput {
    /// VN-200 serial bytes (raw or a serial log).
    Vn200(PathBuf),
    /// An SBET file and its GPS week (None: taken from the capture's RMC date).
    Sbet(PathBuf, Option<u16>),
}

/// Inputs of a georeferencing run.
#[derive(Debug, Clone)]
pub struct Inputs {
    /// The VLP-16 capture.
    pub pcap: PathBuf,
    /// The trajectory.
    pub ins: InsInput,
    /// The site.
    pub site: Site,
    /// The mounting to georeference with.
    pub mount: Mount,
    /// Window margin [m].
    pub margin: f64,
    /// Largest INS sample spacing to interpolate over [ns].
    pub max_gap_ns: i64,
    /// The time offset between the clocks [ns]: INS time = LiDAR time + this; each firing's
    /// pose is taken at its LiDAR time plus this (DESIGN.md conventions).
    pub time_offset_ns: i64,
    /// Use VN-200 poses whose InsStatus says not tracking (aligning, GNSS lost, no fix) too.
    pub keep_untracked_ins: bool,
}

impl Inputs {
    /// The trajectory's file.
    pub fn ins_path(&self) -> &std::path::Path {
        match &self.ins {
            InsInput::Vn200(p) | InsInput::Sbet(p, _) => p,
        }
    }

    /// Georeference with the site's a-priori mounting and window margin, 50 ms INS gap limit.
    pub fn apriori(pcap: PathBuf, ins: InsInput, site: Site) -> Self {
        let b0 = spherecal::calib::from_deg_m(&site.apriori_deg_m());
        Self {
            pcap,
            ins,
            mount: Mount::from_params(&b0),
            margin: site.apriori.window_margin_m,
            max_gap_ns: 50_000_000,
            time_offset_ns: 0,
            keep_untracked_ins: false,
            site,
        }
    }
}

/// A batch of one sphere's observations.
#[derive(Debug, Clone)]
pub struct BatchMsg {
    /// Sphere index.
    pub sphere: usize,
    /// Observations.
    pub obs: Vec<Observation>,
    /// The time offset they were aligned at [ns] (INS time = LiDAR time + this).
    pub offset_ns: i64,
}

/// Counts of a run.
#[derive(Debug, Clone, Default)]
pub struct RunStats {
    /// The align stage's counts (packets, LiDAR span, windowing, rollovers, batch overflow).
    pub align: AlignStats,
    /// Capture skips by reason.
    pub skips: SkipStats,
    /// The LiDAR clock as its position packets tell it.
    pub clock: crate::state::ClockState,
    /// The INS stream.
    pub ins: crate::state::InsState,
    /// Ring drops (live) or waits (files): lidar, ins.
    pub ring_full: [u64; 2],
}

impl RunStats {
    /// What the inputs held, for people: the capture, the LiDAR clock, the INS stream, their
    /// overlap and the returns that could not be georeferenced.
    pub fn describe_inputs(&self, pcap: &std::path::Path, ins: &std::path::Path) -> String {
        use std::fmt::Write as _;
        let mut o = String::new();
        let _ = write!(
            o,
            "LiDAR: {}: {} data packets",
            pcap.display(),
            self.align.data_packets
        );
        if let Some((a, b)) = self.align.lidar_span {
            let _ = write!(o, " over {:.1} s", b - a);
        }
        let _ = writeln!(o, ", {} skipped", self.skips.total());
        for l in self.skips.lines() {
            let _ = writeln!(
                o,
                "  skipped {}: {} (first at byte {}: {})",
                l.reason, l.count, l.first_offset, l.first
            );
        }
        let _ = writeln!(o, "clock: {}", self.clock.describe());
        let _ = writeln!(o, "{}: {}", ins.display(), self.ins.describe());
        let w = &self.align.window;
        let missed = w.before_history + w.after_history + w.in_gap;
        if missed + self.align.packets_without_time > 0 {
            let _ = writeln!(
                o,
                "not georeferenced: {} returns before the INS data, {} after it, {} in INS gaps; {} packets without a time",
                w.before_history, w.after_history, w.in_gap, self.align.packets_without_time
            );
        }
        o
    }

    /// The inputs cannot be calibrated or georeferenced at all: why, in a sentence naming the
    /// file and what was found instead.
    pub fn unusable(
        &self,
        pcap: &std::path::Path,
        ins: &std::path::Path,
        ins_head: &[u8],
    ) -> Option<String> {
        if self.align.data_packets == 0 {
            return Some(format!(
                "{}: no VLP-16 data packet could be timed ({} skipped; {} without a time)",
                pcap.display(),
                self.skips.total(),
                self.align.packets_without_time
            ));
        }
        let st = &self.ins;
        if st.poses == 0 {
            if st.excluded_total() > 0 {
                return Some(format!(
                    "{}: every one of its {} poses is left out by its InsStatus ({}); --keep-untracked-ins uses them anyway",
                    ins.display(),
                    st.excluded_total(),
                    st.describe()
                ));
            }
            return Some(format!(
                "{}: no VN-200 or SBET pose in {} bytes ({} binary frames, {} CRC failures, {} $VN sentences, {} NMEA sentences): it looks like {}",
                ins.display(),
                st.bytes,
                st.frames,
                st.crc_failures,
                st.ascii,
                st.nmea,
                crate::state::looks_like(ins_head)
            ));
        }
        let w = &self.align.window;
        if w.points > 0 && w.before_history + w.after_history == w.points {
            let (l, i) = (
                self.align.lidar_span.unwrap_or_default(),
                st.span.unwrap_or_default(),
            );
            return Some(format!(
                "the LiDAR's times (GPS {:.1} .. {:.1} s) and the INS's ({:.1} .. {:.1} s) do not overlap; the LiDAR clock: {}",
                l.0, l.1, i.0, i.1, self.clock.describe()
            ));
        }
        None
    }
}

/// Where the site's spheres are, in the site frame.
pub fn targets(site: &Site) -> (LocalFrame, Vec<Target>) {
    let frame = LocalFrame::new(Geodetic::from_deg(
        site.origin.lat_deg,
        site.origin.lon_deg,
        site.origin.h_m,
    ));
    let t = site
        .sphere
        .iter()
        .map(|s| Target {
            center: frame.to_ned(&Geodetic::from_deg(s.lat_deg, s.lon_deg, s.h_m)),
            radius: s.radius_m,
        })
        .collect();
    (frame, t)
}

/// Enqueue `item`; a full ring counts in `full` and then drops the item ([`Overflow::Drop`])
/// or waits for room ([`Overflow::Wait`]). Returns whether it was enqueued.
pub fn enqueue<T>(
    p: &mut heapless::spsc::Producer<'_, T>,
    mut item: T,
    policy: Overflow,
    full: &AtomicU64,
) -> bool {
    loop {
        match p.enqueue(item) {
            Ok(()) => return true,
            Err(back) => {
                full.fetch_add(1, Ordering::Relaxed);
                if policy == Overflow::Drop {
                    return false;
                }
                item = back;
                std::thread::yield_now();
            }
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
        it: &spherecal::vn200::Framed<'_>,
        st: &mut InsState,
        host_ns: i64,
        out: &mut InsRing<'_, '_>,
        seen: &mut dyn FnMut(&spherecal::vn200::Framed<'_>, &InsOutcome),
    ) {
        let got = vn200_pose(&it.item, &self.frame);
        seen(it, &got);
        match got {
            InsOutcome::Pose(s, status) => {
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
                enqueue(out.ring, InsItem::Pose(s, host_ns), out.policy, out.full);
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

    /// Bytes received at `host_ns` [ns since 1970; 0 unknown]. Every framed item is shown to
    /// `seen` with what it gave before its pose goes to the ring.
    pub fn feed(
        &mut self,
        bytes: &[u8],
        host_ns: i64,
        out: &mut InsRing<'_, '_>,
        seen: &mut dyn FnMut(&spherecal::vn200::Framed<'_>, &InsOutcome),
    ) {
        self.st.bytes += bytes.len() as u64;
        let Self { framer, gate, st } = self;
        framer.consume(bytes, |it| gate.handle(&it, st, host_ns, out, seen));
    }

    /// The stream has ended: what the framer still holds.
    pub fn finish(&mut self, out: &mut InsRing<'_, '_>) {
        self.framer.finish();
        let Self { framer, gate, st } = self;
        while let Some(it) = framer.next() {
            gate.handle(&it, st, 0, out, &mut |_, _| {});
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

/// The GPS week of the first RMC date in a capture (for SBET times).
pub fn week_from_capture(pcap: &std::path::Path, leap: i64) -> Option<u16> {
    let mut src = PcapSource::open(pcap).ok()?;
    while let Ok(Some(rec)) = src.next_record() {
        if let Record::Udp(d) = rec {
            if let Ok(Vlp16Packet::Position { packet, .. }) = classify(&d, Ports::default()) {
                if let Some(utc) = packet.nmea_time().ok().and_then(|t| t.utc()) {
                    let g =
                        spherecal::time::unix_ns_to_gps(utc.unix_seconds() * 1_000_000_000, leap);
                    return u16::try_from(g.week_tow_ns().0).ok();
                }
            }
        }
    }
    None
}

/// How the aligner waits for the INS to cover a LiDAR packet's time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InsWait {
    /// Files: until the INS stream has poses past the packet or has ended.
    UntilEnd,
    /// Live: until this long after the packet's host receive time (wall clock). A late INS
    /// (a starved serial reader) is waited for; a silent one leaves the aligner this far
    /// behind real time, its ring holding the packets meanwhile, never stalled.
    Latency(std::time::Duration),
}

/// The align stage's storage on the host: the pose history and one batch per sphere (the core
/// [`CoreAligner`] borrows them).
pub struct AlignStorage {
    history: Box<PoseHistory<HISTORY>>,
    batches: Vec<Batch<BATCH>>,
}

impl AlignStorage {
    /// Room for `spheres` windows and a history that interpolates across at most `max_gap_ns`.
    pub fn new(spheres: usize, max_gap_ns: i64) -> Self {
        Self {
            history: Box::new(PoseHistory::new(max_gap_ns)),
            batches: (0..spheres).map(|_| Batch::default()).collect(),
        }
    }
}

/// The core aligner fed from the rings, with a waiting policy ([`InsWait`]) and the LiDAR
/// clock's state counted from the position packets.
pub struct Aligner<'a> {
    /// The core stage.
    pub core: CoreAligner<'a, HISTORY, BATCH>,
    wait: InsWait,
    /// What the live deadline is measured and waited on.
    time: &'a dyn Clock,
    ins_done: bool,
    /// The LiDAR clock as its position packets tell it.
    pub clock: crate::state::ClockState,
}

impl<'a> Aligner<'a> {
    /// An aligner for `targets` on `storage`, georeferencing with `mount`.
    pub fn new(
        storage: &'a mut AlignStorage,
        targets: &'a [Target],
        margin: f64,
        mount: Mount,
        leap_seconds: i64,
        wait: InsWait,
        time: &'a dyn Clock,
    ) -> Self {
        // From files, the poses are read on past a packet by the span its returns' velocity and
        // turn rate are taken over (live input does not wait: the span shrinks at the newest).
        let lookahead = match wait {
            InsWait::UntilEnd => spherecal::window::RATE_SPAN_NS,
            InsWait::Latency(_) => 0,
        };
        let core = CoreAligner::new(
            targets,
            &mut storage.batches,
            &mut storage.history,
            margin,
            mount,
            leap_seconds,
            lookahead,
        );
        Self {
            core,
            wait,
            time,
            ins_done: false,
            clock: Default::default(),
        }
    }

    /// Move every pose waiting on the ring into the history (live input between packets).
    pub fn drain_ins(&mut self, ic: &mut Consumer<'_, InsItem>) {
        while let Some(it) = ic.dequeue() {
            self.take(it);
        }
    }

    fn take(&mut self, it: InsItem) {
        match it {
            InsItem::Pose(s, h) => {
                self.core.push_pose(s, h);
            }
            InsItem::End => self.ins_done = true,
        }
    }

    /// Discard the ring until its End (so that its reader can finish).
    pub fn drain_until_end(&mut self, ic: &mut Consumer<'_, InsItem>) {
        while !self.ins_done {
            match ic.dequeue() {
                Some(InsItem::End) => self.ins_done = true,
                Some(_) => {}
                None => std::thread::yield_now(),
            }
        }
    }

    /// A position packet (its first 512 bytes): counted, then to the core.
    pub fn position(&mut self, bytes: &[u8]) {
        if let Ok(p) = PositionPacket::new_checked(bytes) {
            self.clock.count(&p);
        }
        self.core.position(bytes);
    }

    /// A data packet: poses are pulled until the history covers it, the INS ends, or (live)
    /// the latency allowed after its receive time has passed; then the core aligns it.
    pub fn data(
        &mut self,
        item: &LidarItem,
        ic: &mut Consumer<'_, InsItem>,
        each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
        emit: &mut dyn FnMut(usize, &[Observation]),
    ) {
        let deadline = match self.wait {
            InsWait::UntilEnd => None,
            InsWait::Latency(d) => {
                let d = i64::try_from(d.as_nanos()).unwrap_or(i64::MAX);
                let from = if item.host_ns != 0 {
                    item.host_ns
                } else {
                    self.time.wall_ns()
                };
                Some(from.saturating_add(d))
            }
        };
        while !self.ins_done && self.core.wants_poses(&item.bytes) {
            match ic.dequeue() {
                Some(it) => self.take(it),
                None => match deadline {
                    None => std::thread::yield_now(),
                    Some(t) if self.time.wall_ns() >= t => break,
                    Some(_) => self.time.sleep(std::time::Duration::from_millis(1)),
                },
            }
        }
        self.core.data(&item.bytes, item.host_ns, each, emit);
    }

    /// Hand on what the batches still hold.
    pub fn finish(&mut self, emit: &mut dyn FnMut(usize, &[Observation])) {
        self.core.finish(emit);
    }

    /// The LiDAR clock's state, with where its hour came from.
    pub fn clock_state(&self) -> crate::state::ClockState {
        let mut clock = self.clock.clone();
        clock.hour_from = match self.core.stats.hour_from {
            Some(spherecal::align::HourFrom::Rmc) => "RMC".into(),
            Some(spherecal::align::HourFrom::Ins) => "INS".into(),
            None => String::new(),
        };
        clock
    }

    /// The run's counts so far, with the readers' (skips, INS state, ring waits or drops).
    pub fn run_stats(&self, skips: SkipStats, ins: InsState, ring_full: [u64; 2]) -> RunStats {
        RunStats {
            align: self.core.stats,
            skips,
            clock: self.clock_state(),
            ins,
            ring_full,
        }
    }
}

/// Run the pipeline over files. `each`, if given, sees every georeferenced return; batches go
/// to `consumer` on its own thread, which returns its result.
pub fn run<C: Send>(
    inp: &Inputs,
    mut each: Option<&mut dyn FnMut(&GeoPoint)>,
    consumer: impl FnOnce(crossbeam_channel::Receiver<BatchMsg>) -> C + Send,
) -> Result<(RunStats, C), String> {
    let (frame, targets) = targets(&inp.site);
    let leap = inp.site.leap_seconds;
    let mut lq: Box<Queue<LidarItem, LIDAR_RING>> = Box::new(Queue::new());
    let mut iq: Box<Queue<InsItem, INS_RING>> = Box::new(Queue::new());
    let (mut lp, mut lc) = lq.split();
    let (mut ip, mut ic) = iq.split();
    let full = [AtomicU64::new(0), AtomicU64::new(0)];
    let (tx, rx) = crossbeam_channel::bounded::<BatchMsg>(64);
    let pcap = PcapSource::open(&inp.pcap).map_err(|e| format!("{}: {e}", inp.pcap.display()))?;
    let ins_bytes = match &inp.ins {
        InsInput::Vn200(p) => Some(
            spherecal_hal::serial::read_byte_file(p)
                .map_err(|e| format!("{}: {e}", p.display()))?
                .0,
        ),
        InsInput::Sbet(..) => None,
    };
    let ins_head: Vec<u8> = ins_bytes
        .as_ref()
        .map_or_else(Vec::new, |b| b.iter().take(256).copied().collect());
    let sbet = match &inp.ins {
        InsInput::Sbet(p, week) => {
            let week = match week {
                Some(w) => *w,
                None => week_from_capture(&inp.pcap, leap).ok_or_else(|| {
                    format!(
                        "{}: no RMC date in the capture to date the SBET; give --gps-week",
                        inp.pcap.display()
                    )
                })?,
            };
            let f = std::fs::File::open(p).map_err(|e| format!("{}: {e}", p.display()))?;
            Some((SbetReader::new(std::io::BufReader::new(f)), week, p.clone()))
        }
        InsInput::Vn200(_) => None,
    };

    std::thread::scope(|sc| {
        // LiDAR reader.
        let full_ref = &full;
        let lidar = sc.spawn(move || -> Result<SkipStats, String> {
            let mut pcap = pcap;
            let mut skips = SkipStats::default();
            loop {
                let rec = match pcap.next_record() {
                    Ok(Some(r)) => r,
                    Ok(None) => break,
                    Err(e) => {
                        enqueue(
                            &mut lp,
                            LidarItem::new(LidarKind::End, 0, &[]),
                            Overflow::Wait,
                            &full_ref[0],
                        );
                        return Err(e.to_string());
                    }
                };
                let item = match rec {
                    Record::Skipped { offset, reason } => {
                        skips.count(offset, &reason);
                        continue;
                    }
                    Record::Udp(d) => match LidarItem::classify(&d, Ports::default()) {
                        Ok(item) => item,
                        Err(reason) => {
                            skips.count(d.offset, &reason);
                            continue;
                        }
                    },
                };
                enqueue(&mut lp, item, Overflow::Wait, &full_ref[0]);
            }
            enqueue(
                &mut lp,
                LidarItem::new(LidarKind::End, 0, &[]),
                Overflow::Wait,
                &full_ref[0],
            );
            Ok(skips)
        });

        // INS reader.
        let (max_gap, keep_untracked) = (inp.max_gap_ns, inp.keep_untracked_ins);
        let ins = sc.spawn(move || -> Result<InsState, String> {
            // The readers that wait on this one get its end even when it fails (else the
            // aligner would wait for poses forever).
            let read = || -> Result<InsState, String> {
                let mut st = InsState::default();
                if let Some(bytes) = ins_bytes {
                    let mut feed = Vn200Feed::new(frame, keep_untracked, max_gap);
                    let mut out = InsRing {
                        ring: &mut ip,
                        policy: Overflow::Wait,
                        full: &full_ref[1],
                    };
                    for chunk in bytes.chunks(4096) {
                        feed.feed(chunk, 0, &mut out, &mut |_, _| {});
                    }
                    feed.finish(&mut out);
                    st = feed.state();
                } else if let Some((mut rd, week, path)) = sbet {
                    while let Some(r) = rd
                        .next_record()
                        .map_err(|e| format!("{}: {e}", path.display()))?
                    {
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
                        st.used(t, max_gap);
                        enqueue(
                            &mut ip,
                            InsItem::Pose(PoseSample::from_geodetic(&frame, t, &g, &local), 0),
                            Overflow::Wait,
                            &full_ref[1],
                        );
                    }
                    st.bytes = rd.records * spherecal_hal::sbet::RECORD as u64 + rd.trailing as u64;
                    st.without_pose += rd.invalid;
                }
                Ok(st)
            };
            let r = read();
            enqueue(&mut ip, InsItem::End, Overflow::Wait, &full_ref[1]);
            r
        });

        // Consumer.
        let consumer = sc.spawn(move || consumer(rx));

        // Aligner (this thread).
        let mut storage = AlignStorage::new(targets.len(), inp.max_gap_ns);
        let mut al = Aligner::new(
            &mut storage,
            &targets,
            inp.margin,
            inp.mount,
            leap,
            InsWait::UntilEnd,
            &SystemClock,
        );
        al.core.time_offset_ns = inp.time_offset_ns;
        let offset_ns = inp.time_offset_ns;
        let mut emit = |sphere: usize, obs: &[Observation]| {
            let _ = tx.send(BatchMsg {
                sphere,
                obs: obs.to_vec(),
                offset_ns,
            });
        };
        loop {
            let Some(item) = lc.dequeue() else {
                std::thread::yield_now();
                continue;
            };
            match item.kind {
                LidarKind::End => break,
                LidarKind::Position => al.position(&item.bytes[..512]),
                LidarKind::Data => al.data(&item, &mut ic, each.as_deref_mut(), &mut emit),
            }
        }
        al.finish(&mut emit);
        drop(tx);
        // Drain the INS ring so its reader can finish.
        al.drain_until_end(&mut ic);
        let skips = lidar
            .join()
            .map_err(|_| "LiDAR reader panicked".to_string())??;
        let ins = ins
            .join()
            .map_err(|_| "INS reader panicked".to_string())??;
        let ring_full = [
            full[0].load(Ordering::Relaxed),
            full[1].load(Ordering::Relaxed),
        ];
        let stats = al.run_stats(skips, ins, ring_full);
        let c = consumer
            .join()
            .map_err(|_| "consumer panicked".to_string())?;
        if let Some(why) = stats.unusable(&inp.pcap, inp.ins_path(), &ins_head) {
            return Err(why);
        }
        Ok((stats, c))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use spherecal::vlp16::{BlockRepr, DataPacket, DataRepr, ReturnMode};
    use spherecal_hal::clock::MockClock;
    use std::time::Duration;

    /// A data packet with no return.
    fn empty_packet() -> [u8; 1206] {
        let mut buf = [0u8; 1206];
        DataRepr {
            blocks: [BlockRepr {
                azimuth: 0,
                channels: [(0, 0); 32],
            }; 12],
            timestamp_us: 0,
            return_mode: ReturnMode::Strongest,
            product: 0x22,
        }
        .emit(&mut DataPacket::new_unchecked(&mut buf[..]));
        buf
    }

    /// The rig's INS deadline on the mock clock (no sleeping): with no pose on the ring, a packet
    /// received at T is held until T + 300 ms, then aligned (here: counted without a time); a
    /// packet already older than that, or an ended INS stream, is not waited for.
    #[test]
    fn live_ins_deadline_on_the_mock_clock() {
        let t = 1_700_000_000_000_000_000i64;
        let targets = [Target {
            center: nalgebra::Vector3::zeros(),
            radius: 0.1,
        }];
        let packet = empty_packet();
        for (host_ns, end, waited_ms) in
            [(t, false, 300), (t - 500_000_000, false, 0), (t, true, 0)]
        {
            let clock = MockClock::new(t);
            let mut storage = AlignStorage::new(1, 50_000_000);
            let mut al = Aligner::new(
                &mut storage,
                &targets,
                0.5,
                Mount::from_params(&[0.0; 6]),
                18,
                InsWait::Latency(Duration::from_millis(300)),
                &clock,
            );
            let mut q: Queue<InsItem, 4> = Queue::new();
            let (mut p, mut c) = q.split();
            if end {
                assert!(p.enqueue(InsItem::End).is_ok());
            }
            let item = LidarItem::new(LidarKind::Data, host_ns, &packet);
            al.data(&item, &mut c, None, &mut |_, _| {});
            let waited = clock.wall_ns() - t;
            assert_eq!(waited, waited_ms * 1_000_000, "host {host_ns} end {end}");
            assert_eq!(al.core.stats.packets_without_time, 1);
        }
    }
}

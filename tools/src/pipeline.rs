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

use crate::site::Site;
use heapless::spsc::Queue;
use spherecal::align::{PoseHistory, PoseSample};
use spherecal::frames::{Geodetic, LocalFrame};
use spherecal::georef::Mount;
use spherecal::time::{GpsTime, LidarClock};
use spherecal::vlp16::{self, DataPacket, PointBuf, PositionPacket};
use spherecal::vn200::{Framer, Item, Pose};
use spherecal::window::{Batch, GeoPoint, Observation, Target, WindowStats, Windowing};
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
    /// The payload (data: all 1206 bytes; position: the first 512).
    pub bytes: [u8; 1206],
}

impl LidarItem {
    /// An item holding `payload` (at most 1206 bytes).
    pub fn new(kind: LidarKind, payload: &[u8]) -> Self {
        let mut bytes = [0u8; 1206];
        let n = payload.len().min(bytes.len());
        bytes[..n].copy_from_slice(&payload[..n]);
        Self { kind, bytes }
    }
}

/// An item on the INS ring.
#[derive(Debug, Clone, Copy)]
pub enum InsItem {
    /// A pose in the site frame.
    Pose(PoseSample),
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
}

impl Inputs {
    /// Georeference with the site's a-priori mounting and window margin, 50 ms INS gap limit.
    pub fn apriori(pcap: PathBuf, ins: InsInput, site: Site) -> Self {
        let b0 = spherecal::calib::from_deg_m(&site.apriori_deg_m());
        Self {
            pcap,
            ins,
            mount: Mount::from_params(&b0),
            margin: site.apriori.window_margin_m,
            max_gap_ns: 50_000_000,
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
}

/// Counts of a run.
#[derive(Debug, Clone, Default)]
pub struct RunStats {
    /// Data packets aligned.
    pub data_packets: u64,
    /// Position packets seen.
    pub position_packets: u64,
    /// Capture skips by reason.
    pub skips: SkipStats,
    /// Poses received.
    pub poses: u64,
    /// INS frames without a complete pose.
    pub ins_frames_without_pose: u64,
    /// INS CRC failures / rejected items.
    pub ins_rejected: u64,
    /// Windowing counts.
    pub window: WindowStats,
    /// Packets whose time could not be known (no RMC and no INS time yet).
    pub packets_without_time: u64,
    /// Ring drops (live) or waits (files): lidar, ins.
    pub ring_full: [u64; 2],
    /// Hour rollovers unwrapped.
    pub rollovers: u32,
    /// Batch overflow (observations lost because a batch was full).
    pub batch_overflow: u64,
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

fn push_wait<T>(
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
                        push_wait(
                            &mut lp,
                            LidarItem::new(LidarKind::End, &[]),
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
                    Record::Udp(d) => match classify(&d, Ports::default()) {
                        Err(reason) => {
                            skips.count(d.offset, &reason);
                            continue;
                        }
                        Ok(Vlp16Packet::Data { packet, .. }) => {
                            LidarItem::new(LidarKind::Data, packet.into_inner())
                        }
                        Ok(Vlp16Packet::Position { packet, .. }) => {
                            LidarItem::new(LidarKind::Position, packet.into_inner())
                        }
                    },
                };
                push_wait(&mut lp, item, Overflow::Wait, &full_ref[0]);
            }
            push_wait(
                &mut lp,
                LidarItem::new(LidarKind::End, &[]),
                Overflow::Wait,
                &full_ref[0],
            );
            Ok(skips)
        });

        // INS reader.
        let ins = sc.spawn(move || -> Result<(u64, u64, u64), String> {
            let (mut poses, mut without, mut rejected) = (0u64, 0u64, 0u64);
            if let Some(bytes) = ins_bytes {
                let mut framer: Box<Framer> = Box::default();
                let mut handle = |it: spherecal::vn200::Framed<'_>| match it.item {
                    Item::Binary(f) => match Pose::from_frame(&f)
                        .and_then(|p| PoseSample::from_vn200(&frame, &p))
                    {
                        Some(s) => {
                            poses += 1;
                            push_wait(&mut ip, InsItem::Pose(s), Overflow::Wait, &full_ref[1]);
                        }
                        None => without += 1,
                    },
                    Item::Ascii(a) => {
                        if let Ok(spherecal::vn200::ascii::Vn::Ins(i)) = a.decode() {
                            if let Some(s) =
                                Pose::from_ins(&i).and_then(|p| PoseSample::from_vn200(&frame, &p))
                            {
                                poses += 1;
                                push_wait(&mut ip, InsItem::Pose(s), Overflow::Wait, &full_ref[1]);
                            }
                        }
                    }
                    Item::Nmea(_) => {}
                    Item::Error(_) => rejected += 1,
                };
                for chunk in bytes.chunks(4096) {
                    framer.consume(chunk, &mut handle);
                }
                framer.finish();
                while let Some(it) = framer.next() {
                    handle(it);
                }
            } else if let Some((mut rd, week, path)) = sbet {
                while let Some(r) = rd
                    .next_record()
                    .map_err(|e| format!("{}: {e}", path.display()))?
                {
                    let Some(t) = r.time(week) else { continue };
                    let g = Geodetic {
                        lat: r.lat,
                        lon: r.lon,
                        h: r.h,
                    };
                    let rot = frame.from_local_level(g.lat, g.lon)
                        * spherecal::frames::rotation(r.roll, r.pitch, r.heading());
                    poses += 1;
                    push_wait(
                        &mut ip,
                        InsItem::Pose(PoseSample::new(t, frame.to_ned(&g), &rot)),
                        Overflow::Wait,
                        &full_ref[1],
                    );
                }
                rejected += rd.invalid;
            }
            push_wait(&mut ip, InsItem::End, Overflow::Wait, &full_ref[1]);
            Ok((poses, without, rejected))
        });

        // Consumer.
        let consumer = sc.spawn(move || consumer(rx));

        // Aligner (this thread).
        let mut stats = RunStats::default();
        let mut history: Box<PoseHistory<HISTORY>> = Box::new(PoseHistory::new(inp.max_gap_ns));
        let mut clock = LidarClock::new(leap);
        let mut ins_done = false;
        let mut batches: Vec<Batch<BATCH>> = (0..targets.len()).map(|_| Batch::default()).collect();
        let mut win = Windowing {
            targets: &targets,
            margin: inp.margin,
            mount: inp.mount,
            batches: &mut batches,
            stats: WindowStats::default(),
        };
        let mut points = PointBuf::new();
        let mut pull_ins =
            |history: &mut PoseHistory<HISTORY>, until: Option<GpsTime>, ins_done: &mut bool| {
                while !*ins_done {
                    if let (Some(u), Some((_, newest))) = (until, history.span()) {
                        if newest > u {
                            return;
                        }
                    }
                    if until.is_none() && !history.is_empty() {
                        return;
                    }
                    match ic.dequeue() {
                        Some(InsItem::Pose(s)) => {
                            history.push(s);
                        }
                        Some(InsItem::End) => *ins_done = true,
                        None => std::thread::yield_now(),
                    }
                }
            };
        loop {
            let item = match lc.dequeue() {
                Some(i) => i,
                None => {
                    std::thread::yield_now();
                    continue;
                }
            };
            match item.kind {
                LidarKind::End => break,
                LidarKind::Position => {
                    stats.position_packets += 1;
                    let p = PositionPacket::new_unchecked(&item.bytes[..]);
                    if !clock.has_hour() {
                        if let Some(utc) = p.nmea_time().ok().and_then(|t| t.utc()) {
                            clock.set_from_rmc(&utc, p.timestamp_us());
                        }
                    }
                }
                LidarKind::Data => {
                    let p = DataPacket::new_unchecked(&item.bytes[..]);
                    if !clock.has_hour() {
                        pull_ins(&mut history, None, &mut ins_done);
                        match history.span() {
                            Some((_, newest)) => clock.set_from_gps(newest, p.timestamp_us()),
                            None => {
                                stats.packets_without_time += 1;
                                continue;
                            }
                        }
                    }
                    let Some(t0) = clock.to_gps(p.timestamp_us()) else {
                        stats.packets_without_time += 1;
                        continue;
                    };
                    pull_ins(&mut history, Some(GpsTime(t0.0 + 1_400_000)), &mut ins_done);
                    if vlp16::decode(&p, &mut points).is_err() {
                        continue;
                    }
                    stats.data_packets += 1;
                    win.add_packet(t0, &points, &history, each.as_deref_mut());
                    for (i, b) in win.batches.iter_mut().enumerate() {
                        if b.obs.len() >= BATCH / 2 {
                            let _ = tx.send(BatchMsg {
                                sphere: i,
                                obs: b.obs.to_vec(),
                            });
                            b.obs.clear();
                        }
                    }
                }
            }
        }
        for (i, b) in win.batches.iter_mut().enumerate() {
            stats.batch_overflow += b.overflow;
            if !b.obs.is_empty() {
                let _ = tx.send(BatchMsg {
                    sphere: i,
                    obs: b.obs.to_vec(),
                });
                b.obs.clear();
            }
        }
        drop(tx);
        // Drain the INS ring so its reader can finish.
        while !ins_done {
            match ic.dequeue() {
                Some(InsItem::End) => ins_done = true,
                Some(_) => {}
                None => std::thread::yield_now(),
            }
        }
        stats.window = win.stats;
        stats.rollovers = clock.rollovers;
        stats.skips = lidar
            .join()
            .map_err(|_| "LiDAR reader panicked".to_string())??;
        let (poses, without, rejected) = ins
            .join()
            .map_err(|_| "INS reader panicked".to_string())??;
        stats.poses = poses;
        stats.ins_frames_without_pose = without;
        stats.ins_rejected = rejected;
        stats.ring_full = [
            full[0].load(Ordering::Relaxed),
            full[1].load(Ordering::Relaxed),
        ];
        let c = consumer
            .join()
            .map_err(|_| "consumer panicked".to_string())?;
        Ok((stats, c))
    })
}

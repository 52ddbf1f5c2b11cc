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
//!
//! - [`readers`]: one reader per stream (LiDAR packets from any [`PacketSource`], the VN-200
//!   feed and SBET records into poses), shared with the rig;
//! - [`items`]: what the rings carry (LiDAR packets checked once, poses);
//! - [`feed`]: the core aligner fed from the rings, with the file or live waiting policy.

pub mod accuracy;
pub mod bag_decode;
mod feed;
mod files;
mod items;
mod ouster_reader;
pub use ouster_reader::{ouster_clock, ouster_reader};
pub mod posmv;
mod readers;
mod stats;

pub use feed::{AlignStorage, Closest, InsWait, RingAligner};
pub use files::{as_bag, expand_files, open_captures, week_from_capture, Captures, Files};
pub use items::{ColumnsTimed, InsItem, LidarItem, LidarKind, LidarPacket};
pub use readers::{
    cloud_reader, end_lidar, ins_file_reader, ins_reader, lidar_reader, sbet_week, vn200_pose,
    Accept, InsEnd, InsFile, InsOutcome, InsRing, LidarRing, Vn200Feed,
};
pub use stats::RunStats;

use crate::config::site::Site;
use crate::state::InsState;
use heapless::spsc::{Consumer, Queue};
use spherecal::align::window::{Batch, GeoPoint, Observation, Target};
use spherecal::align::{Aligner as CoreAligner, PoseHistory, PoseSample};
use spherecal::frames::{Geodetic, LocalFrame};
use spherecal::georef::Mount;
use spherecal::velodyne::{DataPacket, Model, PositionPacket};
use spherecal::vn200::{Framer, Item, Pose};
use spherecal_hal::clock::{Clock, SystemClock};
use spherecal_hal::packet::{Datagram, HostTime, SkipReason};
use spherecal_hal::sbet::SbetReader;
use spherecal_hal::velodyne::{classify, Ports, SkipStats, Vlp16Packet};
use spherecal_hal::{PacketSource, Record};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

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

/// Where the trajectory comes from.
#[derive(Debug, Clone)]
pub enum InsInput {
    /// VN-200 serial bytes (raw or serial logs), in name order.
    Vn200(Files),
    /// SBET files and their GPS week (None: taken from the capture's RMC date).
    Sbet(Files, Option<u16>),
    /// Applanix POS MV real-time groups: logged `.000` streams, or captures holding its UDP
    /// datagrams; the GPS week (None: from its Group 3, else the capture's RMC date) and the
    /// group the poses come from (1, 102 or 103).
    Posmv(Files, Option<u16>, u16),
    /// A ROS 2 bag's VectorNav groups (`--ins-topic`, else the only `CommonGroup` topic), as
    /// the VN-200 frames they were parsed from.
    Bag(Files, Option<String>),
}

/// Inputs of a georeferencing run.
#[derive(Debug, Clone)]
pub struct Inputs {
    /// The Velodyne capture(s).
    pub pcap: Files,
    /// The LiDAR model (`--model`); None: as the first capture's packets say
    /// ([`resolve_model`]).
    pub model: Option<Model>,
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
    /// The trajectory's accuracy file (POSPac smrmsg), if any: the calibration's noise model
    /// takes each return's INS sigmas from it ([`accuracy`]).
    pub accuracy: Option<PathBuf>,
    /// The UDP ports the capture's LiDAR datagrams went to (a sensor or a rig's board set to
    /// other ports than 2368 / 8308).
    pub ports: Ports,
    /// When `pcap` names a ROS 2 bag: its topic of scans (None: the only one).
    pub lidar_topic: Option<String>,
    /// Spans to leave out of the calibration (`--exclude`): GPS seconds since 1980-01-06, or
    /// of the data's GPS week ([`crate::stretches::in_week_of`]).
    pub exclude: Vec<(f64, f64)>,
    /// The LiDAR is a Hesai with these angle corrections (`--metadata CORRECTIONS.csv`): its
    /// data packets are read instead of a Velodyne's, timed by their UTC date-time.
    pub hesai: Option<spherecal::hesai::Corrections>,
    /// The LiDAR is an Ouster with this metadata (`--metadata META.json`): its lidar packets
    /// decoded by the reader ([`ouster_reader`]).
    pub ouster: Option<Box<crate::ouster::Metadata>>,
}

impl Inputs {
    /// The LiDAR's time between two firings of one laser [ns]: the Hesai's (its model from
    /// its corrections' channel count), else the Velodyne model's; `None` while unknown.
    pub fn laser_period_ns(&self) -> Option<i64> {
        if let Some(m) = &self.ouster {
            return Some(m.column_period_ns());
        }
        match &self.hesai {
            Some(c) => c.laser_period_ns(),
            None => self.model.map(|m| i64::from(m.laser_period_ns())),
        }
    }

    /// What the solver takes from the LiDAR: its laser period, and its beam when the model's
    /// manual gives one (the Velodynes').
    pub fn lidar(&self) -> crate::config::lidar::Lidar {
        match self.model {
            Some(m) if self.ouster.is_none() && self.hesai.is_none() => {
                crate::config::lidar::Lidar::velodyne(m)
            }
            _ => crate::config::lidar::Lidar::other(self.laser_period_ns()),
        }
    }

    /// The trajectory's files.
    pub fn ins_files(&self) -> &Files {
        match &self.ins {
            InsInput::Vn200(p)
            | InsInput::Sbet(p, _)
            | InsInput::Posmv(p, _, _)
            | InsInput::Bag(p, _) => p,
        }
    }

    /// Georeference with the site's a-priori mounting and window margin, 50 ms INS gap limit.
    pub fn apriori(pcap: Files, ins: InsInput, site: Site) -> Self {
        let b0 = site.apriori_deg_m().params();
        Self {
            pcap,
            ins,
            mount: Mount::from_params(&b0),
            margin: site.apriori.window_margin_m,
            max_gap_ns: 50_000_000,
            time_offset_ns: 0,
            keep_untracked_ins: false,
            accuracy: None,
            model: None,
            ports: Ports::default(),
            lidar_topic: None,
            exclude: Vec::new(),
            hesai: None,
            ouster: None,
            site,
        }
    }

    /// The LiDAR's own file beside the capture (`--metadata`, [`SensorFile`]) into `hesai` or
    /// `ouster`.
    pub fn set_metadata(&mut self, path: &std::path::Path) -> Result<(), crate::Error> {
        match SensorFile::load(path)? {
            SensorFile::Ouster(m) => self.ouster = Some(m),
            SensorFile::Hesai(c) => self.hesai = Some(*c),
        }
        Ok(())
    }
}

/// A LiDAR's own file (`--metadata`, a board's `[lidar] metadata`): a Hesai's angle
/// correction CSV or an Ouster's metadata JSON, told apart by their first character.
pub enum SensorFile {
    /// A Hesai's angle corrections.
    Hesai(Box<spherecal::hesai::Corrections>),
    /// An Ouster's metadata.
    Ouster(Box<crate::ouster::Metadata>),
}

impl SensorFile {
    /// Read `path`.
    pub fn load(path: &std::path::Path) -> Result<Self, crate::Error> {
        let head = std::fs::read(path)
            .map_err(|e| crate::Error::bad_input(format!("{}: {e}", path.display())))?;
        Ok(match head.iter().find(|b| !b.is_ascii_whitespace()) {
            Some(b'{') => SensorFile::Ouster(Box::new(crate::ouster::Metadata::load(path)?)),
            _ => SensorFile::Hesai(Box::new(crate::hesai::corrections::load(path)?)),
        })
    }

    /// The time between two firings of one laser [ns] (an Ouster's: a column's period).
    pub fn laser_period_ns(&self) -> Option<i64> {
        match self {
            SensorFile::Hesai(c) => c.laser_period_ns(),
            SensorFile::Ouster(m) => Some(m.column_period_ns()),
        }
    }

    /// What the solver takes from the LiDAR ([`Inputs::lidar`]).
    pub fn lidar(&self) -> crate::config::lidar::Lidar {
        crate::config::lidar::Lidar::other(self.laser_period_ns())
    }
}

/// The model to decode the captures of `inp` as: the one given, else what the first capture's
/// data packets say (product byte checked against period: [`crate::decode::identify_file`]);
/// Err, naming the file, byte and `--model`, when they cannot be trusted. None: no data packet.
pub fn resolve_model(inp: &Inputs) -> Result<Option<(Model, String)>, crate::Error> {
    if inp.hesai.is_some() || inp.ouster.is_some() {
        return Ok(None);
    }
    let Some(m) = inp.model else {
        return identify(inp);
    };
    // A model given is checked against what the packets say when their product byte and
    // period agree, as the rig checks its board's: decoded as another model, every return
    // would be a wrong point (a byte that lies, or too few packets, leave --model to decide).
    match identify(inp) {
        Ok(Some((found, why))) if found != m && why.ends_with(crate::decode::AGREED) => Err(format!(
            "--model {}: {} holds {} data packets ({why}); drop --model, or give the capture of that LiDAR",
            m.key(),
            inp.pcap.display(),
            found.name()
        )
        .into()),
        _ => Ok(Some((m, "given with --model".into()))),
    }
}

/// What the first capture's data packets say of the model ([`resolve_model`] without one).
fn identify(inp: &Inputs) -> Result<Option<(Model, String)>, crate::Error> {
    if crate::pipeline::as_bag(&inp.pcap).is_some() {
        let src = open_captures(&inp.pcap, inp.lidar_topic.as_deref(), None)?;
        if matches!(src, Captures::Clouds(_)) {
            return Ok(Some((
                Model::Vlp16,
                "a point cloud's rings read as a VLP-16's (say --model otherwise)".into(),
            )));
        }
        return crate::decode::identify_source(src, inp.ports)
            .map_err(|e| format!("{}: {e}", inp.pcap.display()).into());
    }
    let files = inp.pcap.expand()?;
    let Some(first) = files.first() else {
        return Ok(None);
    };
    crate::decode::identify_file(first, inp.ports).map_err(|e| e.to_string().into())
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

/// The trajectory's datum: the one declared, else a VN-200's or a POS MV's real-time WGS 84
/// (their GNSS's frame); an SBET says nothing of its own and must be declared. With why.
pub fn trajectory_datum(
    ins: &InsInput,
    declared: Option<&str>,
) -> Result<(crate::config::datum::Datum, &'static str), crate::Error> {
    use crate::config::datum::Datum;
    if let Some(d) = declared {
        return Ok((Datum::parse(d)?, "--trajectory-datum"));
    }
    match ins {
        InsInput::Vn200(_) | InsInput::Bag(..) => Ok((Datum::wgs84(), "the VN-200's")),
        InsInput::Posmv(..) => Ok((
            Datum::wgs84(),
            "a POS MV's real-time output, unless its GNSS corrections come from another datum: --trajectory-datum",
        )),
        InsInput::Sbet(..) => Err(
            "an SBET does not say its datum (POSPac writes the one its processing used): give --trajectory-datum, e.g. WGS84, ITRF2014, NAD83(CSRS), ETRS89".into(),
        ),
    }
}

/// The site with its spheres in the trajectory's datum, and a line saying which transformation
/// did it (a warning when it is good to no better than 5 cm).
pub fn site_in_trajectory_datum(
    site: &Site,
    ins: &InsInput,
    declared: Option<&str>,
) -> Result<(Site, String), crate::Error> {
    let (to, why) = trajectory_datum(ins, declared)?;
    let (s, shift) = site.in_datum(&to)?;
    let mut line = if shift.is_identity() {
        format!(
            "datums: the spheres' survey and the trajectory ({why}) are both {}: no transformation",
            to.label()
        )
    } else {
        format!(
            "datums: the spheres' survey {} -> the trajectory's {} ({why}): {}",
            shift.from.label(),
            to.label(),
            shift.describe()
        )
    };
    if shift.accuracy_m > 0.05 || shift.accuracy_m < 0.0 {
        line.push_str(&format!(
            "\nwarning: that transformation is good to {} only: every sphere may be off by as much, and the mounting with it; survey the spheres in the trajectory's datum (or process the trajectory in the survey's)",
            if shift.accuracy_m < 0.0 {
                "an unknown accuracy".to_string()
            } else {
                format!("{} m", shift.accuracy_m)
            }
        ));
    }
    Ok((s, line))
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

/// Waiting on a ring without burning a core: a few spins, then a few yields, then sleeps of
/// 50 us (a ring holds milliseconds of work, so no throughput is lost). A file pipeline has
/// more threads than this machine's two cores; spinning on `yield_now` alone was ~15 % of a
/// calibration's CPU (perf: `sched_yield` and the context switches).
#[derive(Debug, Default)]
pub struct Backoff(u32);

impl Backoff {
    /// Back to spinning (after progress).
    pub fn reset(&mut self) {
        self.0 = 0;
    }

    /// Wait a little longer than last time.
    pub fn wait(&mut self) {
        match self.0 {
            0..=5 => (0..1u32 << self.0).for_each(|_| std::hint::spin_loop()),
            6..=9 => std::thread::yield_now(),
            _ => std::thread::sleep(std::time::Duration::from_micros(50)),
        }
        self.0 = self.0.saturating_add(1);
    }
}

/// Enqueue `item`; a full ring counts in `full` and then drops the item ([`Overflow::Drop`])
/// or waits for room ([`Overflow::Wait`]). Returns whether it was enqueued.
pub fn enqueue<T>(
    p: &mut heapless::spsc::Producer<'_, T>,
    mut item: T,
    policy: Overflow,
    full: &AtomicU64,
) -> bool {
    let mut backoff = Backoff::default();
    loop {
        match p.enqueue(item) {
            Ok(()) => return true,
            Err(back) => {
                full.fetch_add(1, Ordering::Relaxed);
                if policy == Overflow::Drop {
                    return false;
                }
                item = back;
                backoff.wait();
            }
        }
    }
}

/// Run the pipeline over files. `each`, if given, sees every georeferenced return; batches go
/// to `consumer` on its own thread, which returns its result.
pub fn run<C: Send>(
    inp: &Inputs,
    mut each: Option<&mut dyn FnMut(&GeoPoint)>,
    consumer: impl FnOnce(crossbeam_channel::Receiver<BatchMsg>) -> C + Send,
) -> Result<(RunStats, C), crate::Error> {
    let (frame, targets) = targets(&inp.site);
    let leap = inp.site.leap_seconds;
    let mut lq: Box<Queue<LidarItem, LIDAR_RING>> = Box::new(Queue::new());
    let mut iq: Box<Queue<InsItem, INS_RING>> = Box::new(Queue::new());
    let (mut lp, mut lc) = lq.split();
    let (mut ip, mut ic) = iq.split();
    let full = [AtomicU64::new(0), AtomicU64::new(0)];
    let (tx, rx) = crossbeam_channel::bounded::<BatchMsg>(64);
    let model = resolve_model(inp)?.map(|m| m.0);
    let mut pcap = open_captures(&inp.pcap, inp.lidar_topic.as_deref(), model)?;
    if let Captures::Bag(b) = &pcap {
        if b.is_ouster() != inp.ouster.is_some() {
            return Err(format!(
                "{}: its LiDAR topic {} an Ouster's PacketMsg: --metadata META.json (the sensor's metadata) reads one and only one",
                inp.pcap.display(),
                if b.is_ouster() { "holds" } else { "is not" }
            )
            .into());
        }
        match (b.is_pandar(), inp.hesai.is_some()) {
            (true, false) => return Err(format!(
                "{}: its LiDAR topic holds a Hesai's PandarScan messages: give the unit's angle correction file with --metadata CORRECTIONS.csv",
                inp.pcap.display()
            ).into()),
            (false, true) => return Err(format!(
                "--metadata gives a Hesai's corrections, but {}'s LiDAR topic is not a Hesai's PandarScan (name it with --lidar-topic)",
                inp.pcap.display()
            ).into()),
            _ => {}
        }
    }
    let from_bag = matches!(pcap, Captures::Bag(_) | Captures::Clouds(_));
    let clouds = matches!(pcap, Captures::Clouds(_));
    let ins_src = InsFile::open(&inp.ins, &inp.pcap, leap)?;

    std::thread::scope(|sc| {
        // The readers: each ends its ring with End, even when it fails.
        let full_ref = &full;
        let lidar = sc.spawn(move || {
            let (queued, never) = (AtomicU64::new(0), AtomicBool::new(false));
            let mut out = LidarRing {
                ring: &mut lp,
                policy: Overflow::Wait,
                full: &full_ref[0],
                queued: &queued,
            };
            let accept = Accept {
                ports: inp.ports,
                sensor: None,
                hesai: inp.hesai.is_some(),
            };
            let (mut skips, r) = match (&mut pcap, &inp.ouster) {
                (Captures::Clouds(c), _) => cloud_reader(c, &mut out),
                (src, Some(m)) => {
                    let how = (from_bag, None);
                    let (skips, r) = ouster_reader(src, &mut out, m, leap, how, &never);
                    (skips, r.map_err(|e| e.to_string()))
                }
                (src, None) => {
                    let (skips, r) = lidar_reader(src, &mut out, accept, &never);
                    (skips, r.map_err(|e| e.to_string()))
                }
            };
            // A bag's MCAP cut short: its whole chunks were read; the cut is said.
            for (_, at) in pcap.cut() {
                skips.count(
                    *at,
                    &spherecal_hal::packet::SkipReason::TruncatedFile { left: 0 },
                );
            }
            end_lidar(out.ring, &never);
            r.map(|()| skips)
        });
        let (max_gap, keep_untracked) = (inp.max_gap_ns, inp.keep_untracked_ins);
        let ins = sc.spawn(move || {
            let mut out = InsRing {
                ring: &mut ip,
                policy: Overflow::Wait,
                full: &full_ref[1],
            };
            let r = ins_file_reader(ins_src, frame, keep_untracked, max_gap, leap, &mut out);
            enqueue(out.ring, InsItem::End, Overflow::Wait, out.full);
            r
        });

        // Consumer.
        let consumer = sc.spawn(move || consumer(rx));

        // Aligner (this thread).
        let mut storage = AlignStorage::new(targets.len(), inp.max_gap_ns);
        let mut al = RingAligner::new(
            &mut storage,
            &targets,
            inp.margin,
            inp.mount,
            leap,
            InsWait::UntilEnd,
            &SystemClock,
        );
        if let Some(c) = &inp.hesai {
            al = al.with_hesai(c.clone());
        }
        al.clock.ouster = inp.ouster.as_deref().map(ouster_clock);
        al.core.time_offset_ns = inp.time_offset_ns;
        al.core.set_model(model);
        let offset_ns = inp.time_offset_ns;
        let mut emit = |sphere: usize, obs: &[Observation]| {
            let _ = tx.send(BatchMsg {
                sphere,
                obs: obs.to_vec(),
                offset_ns,
            });
        };
        let mut backoff = Backoff::default();
        let mut stamp_minus_host = crate::state::Spread::default();
        loop {
            // Used where it lies in the ring (an item is 1.3 kB), then let go.
            let Some(item) = lc.peek() else {
                backoff.wait();
                continue;
            };
            backoff.reset();
            let end = matches!(item.packet(), LidarPacket::End);
            match item.packet() {
                LidarPacket::End => {}
                LidarPacket::Position(p) => al.position(&p),
                LidarPacket::Data(p) => {
                    if let (true, Some(h)) = (from_bag, item.host) {
                        stamp_minus_host.add(p.timestamp_us(), h);
                    }
                    al.data(&p, item.host, &mut ic, each.as_deref_mut(), &mut emit)
                }
                LidarPacket::Points(c) => al.points(c, &mut ic, each.as_deref_mut(), &mut emit),
                LidarPacket::Hesai(p) => {
                    al.hesai(&p, item.host, &mut ic, each.as_deref_mut(), &mut emit)
                }
                LidarPacket::HesaiGps(p) => al.hesai_gps(&p),
                LidarPacket::Timed(t0, c, n) => {
                    al.timed(t0, c, n, item.host, &mut ic, each.as_deref_mut(), &mut emit)
                }
            }
            lc.dequeue();
            if end {
                break;
            }
        }
        al.finish(&mut emit);
        drop(tx);
        // Drain the INS ring so its reader can finish.
        al.drain_until_end(&mut ic);
        let skips = lidar
            .join()
            .map_err(|_| crate::Error::internal("the LiDAR reader thread panicked"))??;
        let (ins, ins_head) = ins
            .join()
            .map_err(|_| crate::Error::internal("the INS reader thread panicked"))??;
        let ring_full = [
            full[0].load(Ordering::Relaxed),
            full[1].load(Ordering::Relaxed),
        ];
        let mut stats = al.run_stats(skips, ins, ring_full);
        stats.clock.bag = from_bag;
        stats.clock.clouds = clouds;
        stats.clock.hesai = inp.hesai.is_some();
        stats.ouster = inp.ouster.as_ref().map(|m| m.product.clone());
        stats.clock.stamp_minus_host_s = stamp_minus_host.range();
        let c = consumer
            .join()
            .map_err(|_| crate::Error::internal("the batch consumer thread panicked"))?;
        if let Some(why) = stats.unusable(&inp.pcap, &inp.ins, &ins_head, inp.time_offset_ns) {
            return Err(crate::Error::bad_input(why));
        }
        Ok((stats, c))
    })
}

//! The core's real path on a microcontroller: real bytes held in flash (the vendored MRPT
//! VLP-16 capture and the INSTINCT VN-310 stream, `tests/data`) through the VN-200 framer, the
//! pcap's UDP datagrams into the Velodyne views, the aligner (pose history, LiDAR clock,
//! per-packet georeferencing) and the sphere windows into fixed batches. Each stage's output is
//! folded into a [`Digest`] (counts, and FNV-1a hashes of the bits of every decoded point, pose
//! and windowed return), printed by the chip over semihosting and by the host, and compared bit
//! for bit by `scripts/qemu-check.sh`.
//!
//! No heap, no std: the same code runs on the host (`cargo run -p spherecal-firmware`) and on
//! `thumbv7em-none-eabihf` under QEMU.

#![no_std]
#![forbid(unsafe_code)]

use spherecal::align::aligner::{AlignStats, Aligner};
use spherecal::align::history::{PoseHistory, PoseSample};
use spherecal::align::window::{Batch, Observation, Target};
use spherecal::frames::{Geodetic, LocalFrame};
use spherecal::georef::Mount;
use spherecal::time::{GpsTime, LidarClock};
use spherecal::velodyne::{self, DataPacket, Model, PointBuf, PositionPacket};
use spherecal::vn200::framer::{Framer, Item};
use spherecal::vn200::pose::Pose;

mod batch;
mod pcap;

pub use batch::solve_stored;
use pcap::datagrams;

/// The vendored MRPT VLP-16 capture (BSD-3-Clause, tests/data/vlp16/README.md).
pub static CAPTURE: &[u8] = include_bytes!("../../tests/data/vlp16/mrpt_vlp16_gps.pcap");
/// The vendored INSTINCT VN-310 binary stream (MPL-2.0, tests/data/vn200/README.md): 12 frames
/// at 5 Hz with time, attitude and INS position.
pub static INS: &[u8] = include_bytes!("../../tests/data/vn200/vn310_gnss.bin");

/// The stored batch the simplex stage solves on: table1's returns, 200 on each of its two
/// spheres (`tools/examples/firmware_batch.rs` wrote it; its layout there).
pub static BATCH_FILE: &[u8] = include_bytes!("../data/table1-batch.bin");
/// Returns the stored batch holds at most.
pub const BATCH_RETURNS: usize = 400;
/// The simplex's iterations (a fixed number: no tolerance stops it).
pub const SIMPLEX_ITERATIONS: usize = 300;

/// Poses the history holds.
pub const HISTORY: usize = 64;
/// Returns a batch holds before it is handed on.
pub const BATCH: usize = 64;
/// The VN-310 stream's poses are 0.2 s apart.
const MAX_GAP_NS: i64 = 300_000_000;
/// The capture (0.4 s) is timed to start this long after the first pose.
const START_AFTER_FIRST_POSE_NS: i64 = 800_000_000;

/// FNV-1a, 64 bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fnv(pub u64);

impl Default for Fnv {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    /// Fold in bytes.
    pub fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 = (self.0 ^ u64::from(x)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    /// Fold in an f64's bits.
    pub fn f64(&mut self, v: f64) {
        self.bytes(&v.to_bits().to_le_bytes());
    }
    /// Fold in an f32's bits.
    pub fn f32(&mut self, v: f32) {
        self.bytes(&v.to_bits().to_le_bytes());
    }
    /// Fold in an integer.
    pub fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
}

/// What each stage gave.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Digest {
    /// VN-200 binary frames accepted, and the poses made of them.
    pub frames: u64,
    /// Poses into the history.
    pub poses: u64,
    /// Every pose's time, position and rotation.
    pub poses_hash: u64,
    /// UDP datagrams of the capture: data and position packets.
    pub data_packets: u64,
    /// See `data_packets`.
    pub position_packets: u64,
    /// Position packets with a valid RMC time, and the hash of their times and PPS states.
    pub rmc_valid: u64,
    /// See `rmc_valid`.
    pub rmc_hash: u64,
    /// Points decoded, and the hash of every point (x, y, z, azimuth, time offset, laser).
    pub points: u64,
    /// See `points`.
    pub points_hash: u64,
    /// Returns the aligner georeferenced and windowed per sphere.
    pub georeferenced: u64,
    /// See `georeferenced`.
    pub windowed: [u64; 2],
    /// Every windowed return (time, the return in the LiDAR frame, the pose, rates).
    pub windowed_hash: u64,
    /// Packets the windowing spared decoding.
    pub spared: u64,
    /// The stored batch's returns, and the hash of what was read of them.
    pub batch_returns: u64,
    /// See `batch_returns`.
    pub batch_hash: u64,
    /// The simplex's iterations and evaluations.
    pub simplex_iterations: u64,
    /// See `simplex_iterations`.
    pub simplex_evaluations: u64,
    /// Its best vertex (the six, deg and m) and value, hashed.
    pub simplex_hash: u64,
    /// Its value, eq. 6's L1 sum, in micrometres (to read).
    pub simplex_l1_um: u64,
}

/// Each field of `d` as `name value`, in one order for the chip and the host.
pub fn lines(d: &Digest, mut f: impl FnMut(&str, u64)) {
    f("ins frames", d.frames);
    f("ins poses", d.poses);
    f("ins poses hash", d.poses_hash);
    f("lidar data packets", d.data_packets);
    f("lidar position packets", d.position_packets);
    f("lidar rmc valid", d.rmc_valid);
    f("lidar rmc hash", d.rmc_hash);
    f("decoded points", d.points);
    f("decoded points hash", d.points_hash);
    f("aligner georeferenced", d.georeferenced);
    f("aligner spared packets", d.spared);
    f("windowed sphere 1", d.windowed[0]);
    f("windowed sphere 2", d.windowed[1]);
    f("windowed hash", d.windowed_hash);
    f("batch returns", d.batch_returns);
    f("batch hash", d.batch_hash);
    f("simplex iterations", d.simplex_iterations);
    f("simplex evaluations", d.simplex_evaluations);
    f("simplex l1 um", d.simplex_l1_um);
    f("simplex hash", d.simplex_hash);
}

/// Counts time on the chip (SysTick under QEMU's instruction counting); nothing on the host.
/// [`run`] times the aligner's work per data packet with one meter and the simplex with the
/// other.
pub trait Meter {
    /// Start timing.
    fn start(&mut self) {}
    /// Stop timing (the time since `start` is added to the total).
    fn stop(&mut self) {}
}

impl Meter for () {}

/// Every stage over the embedded bytes; `meter` times the aligner's work on each data packet
/// (decode, timing, georeferencing, windowing).
pub fn run(meter: &mut impl Meter, simplex: &mut impl Meter) -> Digest {
    let mut d = Digest::default();
    // 1. The INS: framed, each frame's pose into the site frame (origin at the first pose).
    let mut framer: Framer<2048> = Framer::new();
    let mut poses: heapless::Vec<PoseSample, HISTORY> = heapless::Vec::new();
    let mut site: Option<LocalFrame> = None;
    let mut ph = Fnv::default();
    framer.consume(INS, |f| {
        let Item::Binary(frame) = f.item else { return };
        d.frames += 1;
        let Some(pose) = Pose::from_frame(&frame) else {
            return;
        };
        let frame = site.get_or_insert_with(|| {
            LocalFrame::new(Geodetic {
                lat: pose.lat,
                lon: pose.lon,
                h: pose.h,
            })
        });
        if let Some(s) = PoseSample::from_vn200(frame, &pose) {
            ph.u64(s.time.0 as u64);
            for v in s.position.iter() {
                ph.f64(*v);
            }
            for v in s.attitude.coords.iter() {
                ph.f64(*v);
            }
            let _ = poses.push(s);
        }
    });
    d.poses = poses.len() as u64;
    d.poses_hash = ph.0;
    let (Some(first), Some(last)) = (poses.first(), poses.last()) else {
        return d;
    };
    let mount = Mount::new([0.0, 0.0, core::f64::consts::FRAC_PI_2], [0.3, 0.0, -0.5]);
    // 2. The spheres: two returns of the scene (an indoor one: every return within 2.9 m)
    // 1.5 to 3 m from the LiDAR and 2 m apart (the 500th such, then the first far enough from
    // it; georeferenced by a first pass), radius 0.1 m, windowed 0.3 m beyond.
    let mid = (first.position + last.position) * 0.5;
    let all = [Target {
        center: mid,
        radius: 30.0,
    }];
    let mut picked: [Option<nalgebra::Vector3<f64>>; 2] = [None; 2];
    let mut far = 0usize;
    align(&poses, &all, 0.0, &mount, &mut (), |_, obs| {
        for o in obs.iter().filter(|o| (1.5..3.0).contains(&o.range)) {
            far += 1;
            let x = o.georef(&mount);
            match picked {
                [None, _] if far == 500 => picked[0] = Some(x),
                [Some(a), None] if (x - a).norm() > 2.0 => picked[1] = Some(x),
                _ => {}
            }
        }
    });
    let picked = picked.map(|p| p.unwrap_or(mid));
    let targets = picked.map(|center| Target {
        center,
        radius: 0.1,
    });
    // 3. The capture: every packet decoded and hashed; then aligned and windowed (timed).
    let (mut pts, mut rmc) = (Fnv::default(), Fnv::default());
    let mut points = PointBuf::default();
    datagrams(CAPTURE, |port, payload| match port {
        velodyne::DATA_PORT => {
            let Ok(p) = DataPacket::new_checked(payload) else {
                return;
            };
            d.data_packets += 1;
            if let Ok(n) = velodyne::decode_as(&p, Model::Vlp16, &mut points) {
                d.points += n as u64;
                for q in points.as_slice() {
                    for v in [q.x, q.y, q.z, q.azimuth] {
                        pts.f32(v);
                    }
                    pts.u64(u64::from(q.offset_ns) << 8 | u64::from(q.laser));
                }
            }
        }
        velodyne::POSITION_PORT => {
            let Ok(p) = PositionPacket::new_checked(payload) else {
                return;
            };
            d.position_packets += 1;
            if let Some(utc) = p.nmea_time().ok().filter(|t| t.valid).and_then(|t| t.utc()) {
                d.rmc_valid += 1;
                rmc.u64(utc.unix_seconds() as u64);
                rmc.u64(u64::from(p.timestamp_us()));
            }
        }
        _ => {}
    });
    d.points_hash = pts.0;
    d.rmc_hash = rmc.0;
    let mut wh = Fnv::default();
    let stats = align(&poses, &targets, 0.3, &mount, meter, |_, obs| {
        for o in obs {
            wh.u64(o.time.0 as u64);
            for v in o.q_l.iter() {
                wh.f32(*v);
            }
            for v in o.position.iter() {
                wh.f64(*v);
            }
            for v in o.r_ig.iter().chain(o.velocity.iter()).chain(o.omega.iter()) {
                wh.f32(*v);
            }
        }
    });
    d.windowed_hash = wh.0;
    d.georeferenced = stats.0.window.georeferenced;
    d.windowed = [stats.1[0], stats.1[1]];
    d.spared = stats.0.spared;
    let _ = batch::solve_stored(&mut d, simplex);
    d
}

/// The capture's data packets through an aligner over `poses`, windowing around `targets`
/// with `margin` [m] and `mount`: each batch to `emit`, the aligner's work on each data packet
/// timed by `meter`. The counts and the returns windowed per target.
fn align(
    poses: &[PoseSample],
    targets: &[Target],
    margin: f64,
    mount: &Mount,
    meter: &mut impl Meter,
    mut emit: impl FnMut(usize, &[Observation]),
) -> (AlignStats, [u64; 2]) {
    let mut history: PoseHistory<HISTORY> = PoseHistory::new(MAX_GAP_NS);
    let mut batches = [Batch::<BATCH>::default(), Batch::<BATCH>::default()];
    let mut al = Aligner::new(targets, &mut batches, &mut history, margin, *mount, 18, 0);
    al.set_model(Some(Model::Vlp16));
    for p in poses {
        al.push_pose(*p, None);
    }
    let (Some(first), Some(last)) = (poses.first(), poses.last()) else {
        return (al.stats, [0; 2]);
    };
    // The capture's first packet is timed in the poses' hour (the hour nearest the newest
    // pose, as the aligner times it); the offset puts it 0.8 s after the first pose.
    let mut offset = None;
    datagrams(CAPTURE, |port, payload| {
        let Some(p) = (port == velodyne::DATA_PORT)
            .then(|| DataPacket::new_checked(payload).ok())
            .flatten()
        else {
            return;
        };
        let o = *offset.get_or_insert_with(|| {
            let mut clock = LidarClock::new(18);
            clock.set_from_gps(last.time, p.timestamp_us());
            clock.to_gps(p.timestamp_us()).map_or(0, |t: GpsTime| {
                first.time.0 + START_AFTER_FIRST_POSE_NS - t.0
            })
        });
        al.time_offset_ns = o;
        meter.start();
        al.data(&p, None, None, &mut emit);
        meter.stop();
    });
    al.finish(&mut emit);
    (al.stats, [al.windowed[0], al.windowed[1]])
}

//! The VLP-16 side of the simulator: the firing schedule (manual appendix B, PROTOCOLS.md),
//! ray tracing of every firing at the time and along the azimuth a decoder reconstructs from
//! the packet (integer-microsecond stamps, block azimuths quantized to 0.01 deg, per-block
//! interpolation), and the packets written through the data/position emit sides.
//!
//! Broad phase: once per packet, each object's bounding sphere gives an azimuth window in the
//! sensor frame (and is dropped if it is beyond range or outside the lasers' +-15 deg); only
//! firings inside a window get the exact pose and the narrow-phase test.

use super::rng::Rng;
use super::World;
use crate::georef::{ray, PlatformPose};
use crate::time::{gps_to_unix_ns, micros_past_hour, unix_ns_to_gps, GpsTime, UtcDateTime};
use crate::vlp16::data::{field, DATA_PACKET_LEN};
use crate::vlp16::firing::{firing_offset_ns, BLOCK_NS};
use crate::vlp16::position::{write_gprmc, POSITION_PACKET_LEN};
use crate::vlp16::{
    DataPacket, PositionPacket, PpsStatus, ReturnMode, DATA_PORT, LASERS, POSITION_PORT,
};
use core::f64::consts::{PI, TAU};
use nalgebra::Vector3;

/// Most target spheres a scene may have.
pub const MAX_TARGETS: usize = 16;
/// Most objects (targets and clutter) a scene may have.
pub const MAX_OBJECTS: usize = 32;

/// LiDAR settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LidarConfig {
    /// Rotation rate, 300..=1200 rpm.
    pub rpm: f64,
    /// Return mode.
    pub mode: ReturnMode,
    /// Azimuth at trajectory time 0 [rad].
    pub start_azimuth: f64,
    /// Range noise, 1 sigma [m].
    pub range_sigma: f64,
    /// Probability that a data packet is lost.
    pub drop_prob: f64,
    /// Nearest range the sensor reports [m].
    pub min_range: f64,
    /// Farthest range [m].
    pub max_range: f64,
    /// Seed of the range noise and drops.
    pub seed: u64,
}

impl Default for LidarConfig {
    fn default() -> Self {
        Self {
            rpm: 600.0,
            mode: ReturnMode::Strongest,
            start_azimuth: 0.0,
            range_sigma: 0.0,
            drop_prob: 0.0,
            min_range: 0.5,
            max_range: 100.0,
            seed: 1,
        }
    }
}

/// What [`LidarSim::next_packet`] wrote.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimPacket {
    /// A data packet (1206 bytes, UDP 2368), sent at `time`, or lost on the way.
    Data {
        /// GPS time of the packet's first firing (= its timestamp).
        time: GpsTime,
        /// The packet was lost: do not write it.
        dropped: bool,
    },
    /// A position packet (512 bytes, UDP 8308).
    Position {
        /// GPS time it was sent.
        time: GpsTime,
    },
}

impl SimPacket {
    /// UDP destination port and payload length.
    pub fn port_len(&self) -> (u16, usize) {
        match self {
            SimPacket::Data { .. } => (DATA_PORT, DATA_PACKET_LEN),
            SimPacket::Position { .. } => (POSITION_PORT, POSITION_PACKET_LEN),
        }
    }
}

/// Counts of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LidarStats {
    /// Data packets made (including lost ones).
    pub data_packets: u64,
    /// Data packets lost.
    pub dropped: u64,
    /// Position packets made.
    pub position_packets: u64,
    /// Firings (rays) traced or culled.
    pub rays: u64,
    /// Rays that passed the broad phase.
    pub candidates: u64,
    /// Returns on each target sphere, in packets that were not lost.
    pub hits: [u64; MAX_TARGETS],
    /// Returns on clutter, in packets that were not lost.
    pub clutter_hits: u64,
}

/// One traced return of the last data packet, before range noise and quantization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Block 0..11.
    pub block: u8,
    /// Channel 0..31.
    pub channel: u8,
    /// Firing time.
    pub time: GpsTime,
    /// Firing azimuth [rad], as the decoder reconstructs it.
    pub azimuth: f64,
    /// Exact range [m].
    pub range: f64,
    /// Index of the object hit.
    pub object: u8,
}

/// The VLP-16 simulator: call [`Self::next_packet`] until it returns `None`.
pub struct LidarSim<'w, 'a> {
    world: &'w World<'a>,
    cfg: LidarConfig,
    period_ns: i64,
    packets: u64,
    k: u64,
    next_position_s: i64,
    rng: Rng,
    omega: f64,
    /// Counts so far.
    pub stats: LidarStats,
    /// The returns of the last data packet, exact (for tests and truth checks).
    pub hits: heapless::Vec<Hit, 384>,
}

/// Packet period [ns]: 12 blocks (single) or 6 pairs (dual) of 110.592 us.
pub fn packet_period_ns(mode: ReturnMode) -> i64 {
    match mode {
        ReturnMode::Dual => 6 * i64::from(BLOCK_NS),
        _ => 12 * i64::from(BLOCK_NS),
    }
}

/// An angle wrapped into [-pi, pi).
fn wrap_pi(a: f64) -> f64 {
    a - TAU * libm::floor((a + PI) / TAU)
}

impl<'w, 'a> LidarSim<'w, 'a> {
    /// A simulator over the whole trajectory.
    pub fn new(world: &'w World<'a>, cfg: LidarConfig) -> Self {
        let period_ns = packet_period_ns(cfg.mode);
        let packets = (world.trajectory.duration() * 1e9 / period_ns as f64) as u64;
        let start_unix = gps_to_unix_ns(world.start, world.leap_seconds);
        Self {
            world,
            cfg,
            period_ns,
            packets,
            k: 0,
            next_position_s: start_unix.div_euclid(1_000_000_000) + 1,
            rng: Rng::new(cfg.seed),
            omega: cfg.rpm / 60.0 * TAU,
            stats: LidarStats::default(),
            hits: heapless::Vec::new(),
        }
    }

    /// Data packets the run will make.
    pub fn packet_count(&self) -> u64 {
        self.packets
    }

    /// GPS time of data packet `k`: the schedule rounded to whole microseconds, as the sensor's
    /// timestamp is (so the decoder's firing times are exactly the traced ones).
    pub fn packet_time(&self, k: u64) -> GpsTime {
        let ns = k as i64 * self.period_ns;
        GpsTime(self.world.start.0 + (ns + 500).div_euclid(1000) * 1000)
    }

    /// Sensor azimuth [rad] at a GPS time.
    pub fn azimuth_at(&self, t: GpsTime) -> f64 {
        self.cfg.start_azimuth + self.omega * self.world.t_of(t)
    }

    fn pose(&self, t: GpsTime) -> PlatformPose {
        let s = self.world.trajectory.state(self.world.t_of(t));
        PlatformPose {
            position: s.position,
            r_ig: s.r_ig(),
        }
    }

    /// Write the next packet into `out` (at least 1206 bytes); `None` at the end.
    pub fn next_packet(&mut self, out: &mut [u8]) -> Option<SimPacket> {
        if self.k >= self.packets || out.len() < DATA_PACKET_LEN {
            return None;
        }
        let t = self.packet_time(self.k);
        let pos_unix = self.next_position_s * 1_000_000_000 + 100_000_000;
        let pos_time = unix_ns_to_gps(pos_unix, self.world.leap_seconds);
        if pos_time <= t {
            self.next_position_s += 1;
            self.stats.position_packets += 1;
            self.write_position(pos_time, out);
            return Some(SimPacket::Position { time: pos_time });
        }
        self.k += 1;
        self.stats.data_packets += 1;
        let dropped = self.rng.chance(self.cfg.drop_prob);
        if dropped {
            self.stats.dropped += 1;
        }
        self.write_data(t, !dropped, &mut out[..DATA_PACKET_LEN]);
        Some(SimPacket::Data { time: t, dropped })
    }

    fn write_position(&self, time: GpsTime, out: &mut [u8]) {
        let buf = &mut out[..POSITION_PACKET_LEN];
        buf.fill(0);
        let utc = UtcDateTime::from_unix_ns(gps_to_unix_ns(time, self.world.leap_seconds));
        let whole = UtcDateTime { nanos: 0, ..utc };
        let g = self.world.site.to_geodetic(&self.pose(time).position);
        let mut s = [0u8; 96];
        let n = write_gprmc(&mut s, &whole, g.lat.to_degrees(), g.lon.to_degrees()).unwrap_or(0);
        let mut p = PositionPacket::new_unchecked(buf);
        p.set_timestamp_us(micros_past_hour(time, self.world.leap_seconds));
        p.set_pps(PpsStatus::Locked);
        p.set_nmea(&s[..n]);
    }

    fn write_data(&mut self, t: GpsTime, trace: bool, buf: &mut [u8]) {
        let mode = self.cfg.mode;
        self.hits.clear();
        buf.fill(0);
        let mut p = DataPacket::new_unchecked(buf);
        let mut az = [0u16; field::BLOCKS];
        for (b, a) in az.iter_mut().enumerate() {
            let tb = GpsTime(t.0 + i64::from(firing_offset_ns(mode, b, 0, 0)));
            let cdeg = libm::round(self.azimuth_at(tb).to_degrees() * 100.0) as i64;
            *a = cdeg.rem_euclid(36_000) as u16;
            p.set_flag(b);
            p.set_azimuth_raw(b, *a);
        }
        p.set_timestamp_us(micros_past_hour(t, self.world.leap_seconds));
        p.set_return_mode(mode);
        p.set_product_raw(0x22);
        let stride = if mode == ReturnMode::Dual { 2 } else { 1 };
        self.stats.rays += (field::BLOCKS / stride * field::CHANNELS) as u64;
        if !trace {
            return;
        }

        // Broad phase at the packet's middle.
        let mid = GpsTime(t.0 + self.period_ns / 2);
        let pose = self.pose(mid);
        let mount = &self.world.mount;
        let origin = pose.position + pose.r_ig * mount.lever;
        let to_l = (pose.r_ig * mount.r_li).transpose();
        let mut windows: heapless::Vec<(usize, f64, f64), MAX_OBJECTS> = heapless::Vec::new();
        for (i, obj) in self.world.objects.iter().enumerate() {
            let (c, r) = obj.bound();
            let v = to_l * (c - origin);
            let dist = v.norm();
            let rr = r + 0.05;
            if dist - rr > self.cfg.max_range {
                continue;
            }
            let full = dist <= rr * 1.05;
            let (center, half) = if full {
                (0.0, 4.0)
            } else {
                let alpha = libm::asin(rr / dist) + 0.01;
                let elev = libm::asin((v.z / dist).clamp(-1.0, 1.0));
                let lim = 16f64.to_radians();
                if elev - alpha > lim || elev + alpha < -lim {
                    continue;
                }
                let ce = libm::cos(elev.abs() + alpha);
                let half = if ce <= 0.05 { 4.0 } else { alpha / ce + 0.01 };
                (libm::atan2(v.x, v.y), half)
            };
            if windows.push((i, center, half)).is_err() {
                break;
            }
        }
        if windows.is_empty() {
            return;
        }

        let mut b = 0;
        while b < field::BLOCKS {
            // The decoder's azimuth step for this block (PROTOCOLS.md): to the next block or
            // pair; the last reuses the previous step.
            let next = b + stride;
            let gap = |i: usize, j: usize| {
                f64::from(((36_000 + u32::from(az[j]) - u32::from(az[i])) % 36_000) as u16)
            };
            let step = if next < field::BLOCKS {
                gap(b, next)
            } else {
                gap(b - stride, b)
            };
            for ch in 0..field::CHANNELS {
                let (seq, laser) = (ch / LASERS, ch % LASERS);
                let n = (seq * 24 + laser) as f64;
                let a = (f64::from(az[b]) + step * n / 48.0).to_radians() / 100.0;
                let mut hit: Option<(f64, usize)> = None;
                let mut pose_ray: Option<(Vector3<f64>, Vector3<f64>)> = None;
                for &(i, center, half) in &windows {
                    if wrap_pi(a - center).abs() > half {
                        continue;
                    }
                    let (o, d) = *pose_ray.get_or_insert_with(|| {
                        self.stats.candidates += 1;
                        let tf = GpsTime(t.0 + i64::from(firing_offset_ns(mode, b, seq, laser)));
                        let pf = self.pose(tf);
                        let (s, c) = libm::sincos(a);
                        ray(&pf, mount, laser, s, c)
                    });
                    if let Some(th) = self.world.objects[i].shape.intersect(&o, &d) {
                        if th >= self.cfg.min_range
                            && th <= self.cfg.max_range
                            && hit.is_none_or(|(h, _)| th < h)
                        {
                            hit = Some((th, i));
                        }
                    }
                }
                if let Some((th, i)) = hit {
                    let tf = GpsTime(t.0 + i64::from(firing_offset_ns(mode, b, seq, laser)));
                    let _ = self.hits.push(Hit {
                        block: b as u8,
                        channel: ch as u8,
                        time: tf,
                        azimuth: a,
                        range: th,
                        object: i as u8,
                    });
                    let d = th + self.rng.gauss(self.cfg.range_sigma);
                    let raw = libm::round(d / 0.002).clamp(1.0, 65_535.0) as u16;
                    let target = self.world.objects[i].target;
                    p.set_channel(b, ch, raw, if target.is_some() { 80 } else { 25 });
                    match target {
                        Some(tg) if usize::from(tg) < MAX_TARGETS => {
                            self.stats.hits[usize::from(tg)] += 1
                        }
                        _ => self.stats.clutter_hits += 1,
                    }
                }
            }
            b += stride;
        }
    }
}

//! The LiDAR side of the simulator, for any [`Scanner`]: the firing schedule (the model's
//! timing, manual appendix B, PROTOCOLS.md),
//! ray tracing of every firing at the time and along the azimuth a decoder reconstructs from
//! the packet (integer-microsecond stamps, block azimuths quantized to 0.01 deg, per-block
//! interpolation), and the packets written through the data/position emit sides.
//!
//! The beam (all optional; off, a firing is one ideal ray as in the paper's simulator):
//! - **Footprint.** The VLP-16's beam diverges 3.0 mrad along the scan and 1.5 mrad across it
//!   (full angles; the Velodyne manuals' "beam divergence" tables). A firing whose footprint
//!   touches a sphere is traced as 81 sub-rays of the Gaussian on a grid; at other edges as
//!   five (centre weight 0.4; four at +-1.83 sigma on the two axes, 0.15 each: the Gaussian's
//!   second moments). What they hit forms echoes.
//! - **Echoes and mixed pixels.** Surfaces less than `merge_distance` apart along the beam
//!   return one merged pulse whose range is the energy-weighted mean (a *mixed pixel*: Hebert
//!   & Krotkov 1992, "3D measurements from imaging laser radars"); farther apart they are
//!   separate echoes (the VLS-128 manual, 6.2.3: both returns are recorded only 1 m or more
//!   apart). An echo's energy is sum(w rho cos(incidence)); its received power that over the
//!   range squared; echoes below the detection threshold are lost. The strongest mode reports
//!   the most powerful echo, the last mode the farthest, the dual mode both (manual 9.3.2: the
//!   even block the last, the odd block the strongest or, when that is the last, the second
//!   strongest; identical when there is one). A beam whose centre misses a sphere but whose
//!   edge touches it returns from the sphere at the tangent range, off the surface ("blooming").
//! - **Range noise** `sigma^2 = sigma_0^2 + (R sigma_b tan(theta))^2`: the range spread of the
//!   footprint (1-sigma beam half-angle `sigma_b`) over a surface at incidence `theta`
//!   (Soudarissanane et al. 2011, "Scanning geometry: influencing factor on the quality of
//!   terrestrial laser scanning points", ISPRS J. 66(4)); tan capped at 10.
//! - **Range walk** (optional): weak returns are timed late, `bias = walk (1 - I/100)` for a
//!   calibrated intensity I (the leading-edge timing walk of a threshold detector).
//! - **Water** absorbs the beam; within `specular` of nadir it may glint back.
//!
//! Broad phase: every [`CACHE_PACKETS`] packets each object's bounding sphere gives an azimuth
//! window in the sensor frame (dropped if beyond range or outside the lasers' +-15 deg),
//! widened by what the platform's motion can change over those packets; per packet only the
//! windows over the packet's azimuth span remain, and per firing only the windows holding its
//! azimuth get the exact pose and the narrow-phase tests.

use super::rng::Rng;
use super::scene::{Frame, Water};
use super::World;
use crate::georef::{beam_origin_l, beam_unit, PlatformPose};
use crate::time::{gps_to_unix_ns, micros_past_hour, unix_ns_to_gps, GpsTime, UtcDateTime};
use crate::velodyne::{Beam as Laser, PpsStatus, ReturnMode};
use core::f64::consts::{PI, TAU};
use nalgebra::{Matrix3, Vector3};
use scanner::{Stamp, Writer, MAX_BLOCKS, SIM_LASERS as MAX_LASERS};
use stencil::{stencil, FIVE, MAX_SUBS};

mod body;
mod receiver;
pub mod scanner;
mod stencil;
mod trace;

pub use scanner::{Ouster, OusterSpec, Scanner};

/// The longest packet any scanner's simulation writes.
pub const MAX_PACKET_LEN: usize = 32 + 16 * (12 + 128 * 12) + 32;

/// Most returns a data packet holds (an Ouster's 16 columns of 128 pixels).
pub const MAX_RETURNS: usize = 2048;
/// Most target spheres a scene may have.
pub const MAX_TARGETS: usize = 16;
/// Most objects (targets, scenery and vessel parts) a scene may have.
pub const MAX_OBJECTS: usize = 1024;
/// The label of a return from the water surface (a glint).
pub const LABEL_WATER: u16 = 0xFFFE;
/// Packets between two computations of the broad-phase windows.
pub const CACHE_PACKETS: u64 = 8;
/// Vessel parts (objects fixed to the body) with a table of the firings that can hit them;
/// more are tested on every firing. (The built-in vessels have 5-9; the tables of 128 lasers
/// take 23.5 kB each.)
pub const MAX_BODY_TABLES: usize = 16;
/// Azimuth bins of those tables (0.25 deg).
const BODY_BINS: usize = 1440;
const BODY_WORDS: usize = BODY_BINS.div_ceil(64);

/// Which (laser, azimuth bin) firings can hit one vessel part, as bits.
type BodyTable = [[u64; BODY_WORDS]; MAX_LASERS];

/// LiDAR settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LidarConfig {
    /// The scanner: its lasers, timing, range unit and packets.
    pub scanner: Scanner,
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
    /// Full-angle beam divergence along the scan and across it [rad]; zero: an ideal ray.
    pub divergence: [f64; 2],
    /// Echoes closer than this along the beam merge into one (mixed pixel) [m].
    pub merge_distance: f64,
    /// Range noise grows at grazing incidence (the footprint's range spread).
    pub incidence_noise: bool,
    /// The footprint rendered as the beam's Gaussian on a grid of 81 sub-rays on every firing
    /// whose footprint touches a sphere (the returns the calibration models, and what mixes
    /// into them: a stand, the grass), five sub-rays at other edges ([`stencil`]); `false`:
    /// five sub-rays at every edge (about `1.8 sigma R` of bloom once the axis misses, a
    /// staircase).
    pub footprint_grid: bool,
    /// Range walk: the bias of a zero-intensity return relative to a full one [m].
    pub range_walk: f64,
    /// The receiver's gain: a return's calibrated intensity is `100 gain E` (E: its echo's
    /// energy, reflectivity x cos(incidence) over the footprint), capped at 100, the top of
    /// the diffuse scale (Velodyne's calibrated reflectivity: 0-100 diffuse, 101-255
    /// retro-reflectors). 1: a white surface at normal incidence reads its reflectivity.
    pub intensity_gain: f64,
    /// Per-return intensity scatter: a log-normal factor of this sigma (speckle and the
    /// receiver's gain control: real neighbours differ by 20 and more); 0: none.
    pub intensity_scatter: f64,
    /// Probability that an arc over a target sphere (one laser's run of returns in one
    /// rotation) starts weak and loses its second firing: the leading edge's partial
    /// footprint returns little, and the receiver recovers only a firing later. 0: never.
    pub edge_dropout: f64,
    /// Probability that a return off anything but a target sphere is reported (1: all; less
    /// thins the scenery uniformly, for clutter-density sweeps).
    pub clutter_keep: f64,
    /// Cull with the broad phase (false: every firing against every object; for tests).
    pub cull: bool,
    /// Trace only the firings that can hit a target sphere (against everything, so that what
    /// hides a sphere still does): the survey planner's geometry, a fraction of the work.
    pub targets_only: bool,
    /// Seed of what the tracing draws (the water's glints): the scene's, not the noise's, so
    /// that one trace serves every noise seed.
    pub trace_seed: u64,
    /// The sensor's clock error [ns]: its timestamps are the true time plus this (a unit
    /// without PPS runs on its own oscillator).
    pub clock_offset_ns: i64,
    /// Its oscillator's rate error [parts per million]: without PPS the clock error grows by
    /// this from the start of the scan (a free-running crystal: tens of ppm).
    pub clock_drift_ppm: f64,
    /// The PPS state its position packets report.
    pub pps: PpsStatus,
    /// Its GPS has a fix: the position packets' `$GPRMC` say A (valid), else V.
    pub rmc_valid: bool,
}

impl Default for LidarConfig {
    fn default() -> Self {
        Self {
            scanner: Scanner::Velodyne(crate::velodyne::Model::Vlp16),
            rpm: 600.0,
            mode: ReturnMode::Strongest,
            start_azimuth: 0.0,
            range_sigma: 0.0,
            drop_prob: 0.0,
            min_range: 0.5,
            max_range: 100.0,
            seed: 1,
            divergence: [0.0, 0.0],
            merge_distance: 1.0,
            incidence_noise: false,
            footprint_grid: false,
            range_walk: 0.0,
            intensity_gain: 1.0,
            intensity_scatter: 0.0,
            edge_dropout: 0.0,
            clutter_keep: 1.0,
            cull: true,
            targets_only: false,
            trace_seed: 0x5CE7E,
            clock_offset_ns: 0,
            clock_drift_ppm: 0.0,
            pps: PpsStatus::Locked,
            rmc_valid: true,
        }
    }
}

/// What [`LidarSim::next_packet`] wrote.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimPacket {
    /// A data packet, sent at `time`, or lost on the way.
    Data {
        /// GPS time of the packet's first firing (= its timestamp).
        time: GpsTime,
        /// The packet was lost: do not write it.
        dropped: bool,
    },
    /// The once-a-second time packet: a Velodyne's position packet (512 bytes, UDP 8308), a
    /// Hesai's GPS packet (512 bytes, UDP 10110).
    Position {
        /// GPS time it was sent.
        time: GpsTime,
    },
}

/// Counts of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LidarStats {
    /// Data packets made (including lost ones).
    pub data_packets: u64,
    /// Data packets lost.
    pub dropped: u64,
    /// Position (Hesai: GPS) packets made.
    pub position_packets: u64,
    /// Firings (rays) traced or culled.
    pub rays: u64,
    /// Rays that passed the broad phase.
    pub candidates: u64,
    /// Narrow-phase ray-object tests (sub-rays included).
    pub tests: u64,
    /// Returns whose echo is mostly from each target sphere, in packets that were not lost.
    pub hits: [u64; MAX_TARGETS],
    /// Returns on everything else (scenery, vessel, water glints).
    pub clutter_hits: u64,
    /// Returns mixed from more than one object (under 90 % from the main one).
    pub mixed: u64,
    /// Echoes too weak to be detected.
    pub too_weak: u64,
    /// Beams absorbed by the water.
    pub water: u64,
    /// Arcs over a target sphere that started weak and lost their second firing.
    pub edge_dropouts: u64,
}

/// One laser's run of returns on a target: where it was last and the firing it will lose.
#[derive(Debug, Clone, Copy)]
struct Arc {
    /// The object of its last return.
    obj: u16,
    /// The firing time of its last return [ns].
    last_ns: i64,
    /// The firing to lose [ns] (`i64::MIN`: none).
    drop_ns: i64,
}

impl Arc {
    const NONE: Self = Self {
        obj: u16::MAX,
        last_ns: i64::MIN,
        drop_ns: i64::MIN,
    };
}

/// One return of the last data packet, before range noise and quantization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Block (an Ouster's column in the packet).
    pub block: u8,
    /// Channel (an Ouster's pixel).
    pub channel: u8,
    /// Firing time.
    pub time: GpsTime,
    /// Firing azimuth [rad], as the decoder reconstructs it.
    pub azimuth: f64,
    /// Range of the echo [m] (an ideal beam: exactly the surface along the ray).
    pub range: f64,
    /// Index of the object the echo's energy mostly came from ([`LABEL_WATER`]: water).
    pub object: u16,
    /// That object's share of the echo's energy, 0..=255.
    pub purity: u8,
}

/// A reported echo of one firing as the tracing found it, before noise: what a trace cache
/// holds so that the same scene can be re-noised with other seeds without tracing it again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Traced {
    /// Range of the echo [m].
    pub range: f64,
    /// Its energy, `sum(w rho cos)`.
    pub energy: f32,
    /// Cosine of its incidence on the main object.
    pub cos: f32,
    /// The main object (or [`LABEL_WATER`]).
    pub obj: u16,
    /// The main object's share of the energy, x 255.
    pub purity: u8,
    /// Block it is written in.
    pub block: u8,
    /// Channel.
    pub channel: u8,
}

/// A broad-phase window: object, azimuth centre and half-width [rad] in the LiDAR frame, and
/// the widest a footprint gets at the object's far side [m].
#[derive(Debug, Clone, Copy)]
struct Window {
    obj: u16,
    center: f64,
    half: f64,
    rho: f64,
    /// Index of the vessel part's table in `body` (`u8::MAX`: none).
    table: u8,
}

/// What one sub-ray hit.
#[derive(Debug, Clone, Copy)]
struct SubHit {
    t: f64,
    /// `w rho cos(incidence)`; 0 for an absorbing surface (water).
    energy: f64,
    obj: u16,
    cos: f64,
}

/// One echo of a firing.
#[derive(Debug, Clone, Copy)]
struct Echo {
    range: f64,
    energy: f64,
    obj: u16,
    purity: f64,
    /// Cosine of the incidence on the main object.
    cos: f64,
}

/// Received power `E (R_REF / R)^2` below which an echo is lost: a 10 % reflective surface
/// filling the beam head-on at 100 m is at the threshold.
const R_REF: f64 = 100.0;
const P_MIN: f64 = 0.1;

/// The LiDAR simulator (any [`Scanner`]): call [`Self::next_packet`] until it returns `None`.
pub struct LidarSim<'w, 'a> {
    world: &'w World<'a>,
    cfg: LidarConfig,
    period_ns: i64,
    packets: u64,
    k: u64,
    next_position_s: i64,
    rng: Rng,
    omega: f64,
    /// Windows of the current cache span, and the packet's own.
    windows: heapless::Vec<Window, MAX_OBJECTS>,
    live: heapless::Vec<Window, MAX_OBJECTS>,
    /// The widest angle of a footprint sub-ray from the beam's centre [rad] (0: ideal beam).
    spread: f64,
    /// The footprint's sub-rays ([`stencil`]).
    stencil: heapless::Vec<(f64, f64, f64), MAX_SUBS>,
    /// Cosine of the water's glint angle.
    glint_cos: f64,
    /// Vessel parts: object index and the firings that can hit it.
    body: heapless::Vec<(u16, BodyTable), MAX_BODY_TABLES>,
    /// Each laser's geometry.
    beams: [Laser; MAX_LASERS],
    /// Each laser's beam origin in the body frame: `a + R_li v_k e_z`.
    origins: [Vector3<f64>; MAX_LASERS],
    /// Counts so far.
    pub stats: LidarStats,
    /// The returns of the last data packet (for labels, tests and truth checks).
    pub hits: heapless::Vec<Hit, MAX_RETURNS>,
    /// The last data packet's echoes before noise (traced, or replayed).
    pub traced: heapless::Vec<Traced, MAX_RETURNS>,
    trace_rng: Rng,
    /// Each laser's arc on a target (the leading-edge dropout).
    arcs: [Arc; MAX_LASERS],
    /// An Ouster's columns per frame and the measurement id of the first column.
    columns_per_frame: u32,
    first_m: u32,
}

/// An angle wrapped into [-pi, pi).
fn wrap_pi(a: f64) -> f64 {
    a - TAU * libm::floor((a + PI) / TAU)
}

/// The rotation angle between two rotation matrices [rad].
fn angle_between(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let m = a.tr_mul(b);
    libm::acos(((m.trace() - 1.0) / 2.0).clamp(-1.0, 1.0))
}

/// A firing's beam in one frame: origin, centre direction and the two footprint axes.
#[derive(Debug, Clone, Copy)]
struct Beam {
    o: Vector3<f64>,
    d: Vector3<f64>,
    along: Vector3<f64>,
    across: Vector3<f64>,
}

impl Beam {
    fn rotated(&self, r: &Matrix3<f64>, shift: &Vector3<f64>) -> Self {
        Self {
            o: shift + r * self.o,
            d: r * self.d,
            along: r * self.along,
            across: r * self.across,
        }
    }

    /// The centre ray only (no footprint axes).
    fn centre(o: Vector3<f64>, d: Vector3<f64>) -> Self {
        Self {
            o,
            d,
            along: Vector3::zeros(),
            across: Vector3::zeros(),
        }
    }

    fn sub(&self, ka: f64, kc: f64) -> Vector3<f64> {
        if ka == 0.0 && kc == 0.0 {
            return self.d;
        }
        let v = self.d + self.along * ka + self.across * kc;
        v / v.norm()
    }
}

impl<'w, 'a> LidarSim<'w, 'a> {
    /// A simulator over the whole trajectory.
    pub fn new(world: &'w World<'a>, cfg: LidarConfig) -> Self {
        let period_ns = cfg.scanner.packet_period_ns(cfg.mode);
        let beams: [Laser; MAX_LASERS] = core::array::from_fn(|k| cfg.scanner.beam(k));
        let packets = (world.trajectory.duration() * 1e9 / period_ns as f64) as u64;
        let start_unix = gps_to_unix_ns(world.start, world.leap_seconds);
        let stencil = stencil(cfg.footprint_grid);
        Self {
            world,
            cfg,
            period_ns,
            packets,
            k: 0,
            next_position_s: start_unix.div_euclid(1_000_000_000) + 1,
            rng: Rng::new(cfg.seed),
            omega: cfg.rpm / 60.0 * TAU,
            windows: heapless::Vec::new(),
            live: heapless::Vec::new(),
            spread: stencil
                .iter()
                .map(|&(ka, kc, _)| {
                    libm::hypot(ka * cfg.divergence[0] / 4.0, kc * cfg.divergence[1] / 4.0)
                })
                .fold(0.0, f64::max),
            stencil,
            glint_cos: world.water.map_or(2.0, |w| libm::cos(w.specular)),
            body: heapless::Vec::new(),
            origins: core::array::from_fn(|k| {
                world.mount.lever + world.mount.r_li * beam_origin_l(&beams[k])
            }),
            beams,
            stats: LidarStats::default(),
            hits: heapless::Vec::new(),
            traced: heapless::Vec::new(),
            trace_rng: Rng::new(cfg.trace_seed),
            arcs: [Arc::NONE; MAX_LASERS],
            columns_per_frame: cfg.scanner.columns_per_frame(cfg.rpm).max(1),
            // The column whose azimuth is the start's: A = 2 pi m / W - pi / 2.
            first_m: {
                let w = f64::from(cfg.scanner.columns_per_frame(cfg.rpm).max(1));
                let turns = (cfg.start_azimuth + PI / 2.0) / TAU;
                (libm::round((turns - libm::floor(turns)) * w) as u32) % w as u32
            },
        }
        .with_body_tables()
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

    /// Run only data packets `first..end` (from the broad phase's cache boundary at or before
    /// `first`): one pass of a survey, or one share of it per thread. The data packets keep
    /// their times, seeds aside (the noise draws start anew).
    pub fn restrict(&mut self, first: u64, end: u64) {
        self.packets = end.min(self.packets);
        self.k = (first - first % CACHE_PACKETS).min(self.packets);
        let unix = gps_to_unix_ns(self.packet_time(self.k), self.world.leap_seconds);
        self.next_position_s = unix.div_euclid(1_000_000_000) + 1;
    }

    /// The first data packet at or after trajectory time `t` [s].
    pub fn packet_at(&self, t: f64) -> u64 {
        (libm::ceil(t * 1e9 / self.period_ns as f64).max(0.0) as u64).min(self.packets)
    }

    /// A true GPS time on the sensor's clock.
    fn on_clock(&self, t: GpsTime) -> GpsTime {
        let drift = (self.cfg.clock_drift_ppm * 1e-6 * (t.0 - self.world.start.0) as f64) as i64;
        GpsTime(
            t.0.saturating_add(self.cfg.clock_offset_ns)
                .saturating_add(drift),
        )
    }

    /// UDP destination port and payload length of a packet this simulator wrote.
    pub fn port_len(&self, p: &SimPacket) -> (u16, usize) {
        match p {
            SimPacket::Data { .. } => self.cfg.scanner.data_port_len(),
            SimPacket::Position { .. } => self.cfg.scanner.time_port_len(),
        }
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

    /// Write the next packet into `out` (at least [`MAX_PACKET_LEN`] bytes); `None` at the end.
    pub fn next_packet(&mut self, out: &mut [u8]) -> Option<SimPacket> {
        self.next(out, None, false)
    }

    /// As [`Self::next_packet`], but a data packet's echoes are `traced` (this packet's
    /// [`Self::traced`] from an earlier run over the same scene) instead of traced again: only
    /// the noise is drawn anew. The schedule is the same, so position packets need nothing.
    pub fn next_packet_replayed(&mut self, out: &mut [u8], traced: &[Traced]) -> Option<SimPacket> {
        self.next(out, Some(traced), false)
    }

    /// The next packet as [`LidarSim::next_packet`] would send it, but a data packet is only
    /// timed, neither traced nor noised nor written (reported lost): a Monte Carlo skips the
    /// packets that hold no windowed return. Position packets are written as ever.
    pub fn skip_packet(&mut self, out: &mut [u8]) -> Option<SimPacket> {
        self.next(out, Some(&[]), true)
    }

    fn next(&mut self, out: &mut [u8], replay: Option<&[Traced]>, skip: bool) -> Option<SimPacket> {
        let (_, len) = self.cfg.scanner.data_port_len();
        if self.k >= self.packets || out.len() < len.max(512) {
            return None;
        }
        let t = self.packet_time(self.k);
        let pos_unix = self.next_position_s * 1_000_000_000 + 100_000_000;
        let pos_time = unix_ns_to_gps(pos_unix, self.world.leap_seconds);
        if pos_time <= t && self.cfg.scanner.time_port_len().1 > 0 {
            self.next_position_s += 1;
            self.stats.position_packets += 1;
            self.write_position(pos_time, out);
            return Some(SimPacket::Position { time: pos_time });
        }
        if replay.is_none() && self.k.is_multiple_of(CACHE_PACKETS) {
            self.cache_windows(t);
        }
        self.k += 1;
        self.stats.data_packets += 1;
        let dropped = self.rng.chance(self.cfg.drop_prob);
        if dropped {
            self.stats.dropped += 1;
        }
        if skip {
            self.hits.clear();
            self.traced.clear();
            return Some(SimPacket::Data {
                time: t,
                dropped: true,
            });
        }
        self.write_data(self.k - 1, t, dropped, replay, &mut out[..len]);
        Some(SimPacket::Data { time: t, dropped })
    }

    fn write_position(&self, time: GpsTime, out: &mut [u8]) {
        let utc = UtcDateTime::from_unix_ns(gps_to_unix_ns(time, self.world.leap_seconds));
        let whole = UtcDateTime { nanos: 0, ..utc };
        let g = self.world.site.to_geodetic(&self.pose(time).position);
        scanner::write_time_packet(
            self.cfg.scanner,
            out,
            &whole,
            (g.lat.to_degrees(), g.lon.to_degrees()),
            self.cfg.rmc_valid,
            micros_past_hour(self.on_clock(time), self.world.leap_seconds),
            self.cfg.pps,
        );
    }

    /// A block's azimuth [rad] from its code: a Velodyne's or Hesai's 0.01 deg, an Ouster's
    /// measurement id (its column at `2 pi m / W - pi / 2`, module docs of `scanner`).
    fn block_azimuth(&self, code: u16) -> f64 {
        match self.cfg.scanner {
            Scanner::Ouster(_) => {
                TAU * f64::from(code) / f64::from(self.columns_per_frame) - PI / 2.0
            }
            _ => f64::from(code).to_radians() / 100.0,
        }
    }

    /// The azimuth [rad] the decoder reconstructs for channel `ch` of block `b`, and the
    /// step from the first block's [rad]. A Velodyne's is interpolated per block (PROTOCOLS.md:
    /// the step to the next block or pair, the last reuses the previous) plus the laser's
    /// azimuth offset; a Hesai's is its block's plus its correction; an Ouster's its column's
    /// plus its beam's azimuth.
    fn firing_azimuth(
        &self,
        az: &[u16; MAX_BLOCKS],
        b: usize,
        stride: usize,
        ch: usize,
    ) -> (f64, f64) {
        let scanner = self.cfg.scanner;
        let laser = scanner.laser_of(ch);
        if let Scanner::Ouster(_) = scanner {
            let w = self.columns_per_frame;
            let off = self.beams[laser % MAX_LASERS].azimuth_offset_rad();
            let steps = (u32::from(az[b]) + w - u32::from(az[0]) % w) % w;
            let rel = TAU * f64::from(steps) / f64::from(w) + off;
            return (self.block_azimuth(az[b]) + off, rel);
        }
        let gap = |i: usize, j: usize| {
            f64::from(((36_000 + u32::from(az[j]) - u32::from(az[i])) % 36_000) as u16)
        };
        let off = self.beams[laser % MAX_LASERS].azimuth_offset_deg * 100.0;
        let interpolated = match scanner {
            Scanner::Velodyne(model) => {
                let step = if b + stride < scanner.blocks() {
                    gap(b, b + stride)
                } else {
                    gap(b - stride, b)
                };
                let c = model.channels()[ch % 32];
                step * f64::from(c.offset_ns) / f64::from(model.block_ns())
            }
            _ => 0.0,
        };
        let a = (f64::from(az[b]) + interpolated + off).to_radians() / 100.0;
        let rel = (gap(0, b) + interpolated + off).to_radians() / 100.0;
        (a, rel)
    }

    /// The code of block `b` of data packet `k` fired at `tb`: its azimuth in 0.01 deg, an
    /// Ouster's measurement id.
    fn block_code(&self, k: u64, b: usize, tb: GpsTime) -> u16 {
        match self.cfg.scanner {
            Scanner::Ouster(_) => {
                let col = k * Scanner::OUSTER_COLUMNS_U64 + b as u64 + u64::from(self.first_m);
                (col % u64::from(self.columns_per_frame)) as u16
            }
            _ => {
                let cdeg = libm::round(self.azimuth_at(tb).to_degrees() * 100.0) as i64;
                cdeg.rem_euclid(36_000) as u16
            }
        }
    }

    fn write_data(
        &mut self,
        k: u64,
        t: GpsTime,
        dropped: bool,
        replay: Option<&[Traced]>,
        buf: &mut [u8],
    ) {
        let (scanner, mode) = (self.cfg.scanner, self.cfg.mode);
        self.hits.clear();
        self.traced.clear();
        let first_col = k * Scanner::OUSTER_COLUMNS_U64 + u64::from(self.first_m);
        let stamp = Stamp {
            first: self.on_clock(t),
            leap_seconds: self.world.leap_seconds,
            sequence: k as u32,
            rpm: libm::round(self.cfg.rpm) as u16,
            frame_id: (first_col / u64::from(self.columns_per_frame)) as u16,
            power_on: (self.cfg.pps != PpsStatus::Locked)
                .then(|| GpsTime(self.world.start.0 - scanner::OUSTER_POWER_ON_S * 1_000_000_000)),
        };
        let mut az = [0u16; MAX_BLOCKS];
        let blocks = scanner.blocks();
        for (b, a) in az.iter_mut().enumerate().take(blocks) {
            let tb = GpsTime(t.0 + scanner.firing_offset_ns(mode, b, 0));
            *a = self.block_code(k, b, tb);
        }
        let stride = if mode == ReturnMode::Dual { 2 } else { 1 };
        self.stats.rays += (blocks / stride * scanner.channels()) as u64;
        // What the firings return: traced now (also for a lost packet, so that a trace does
        // not depend on the noise seed), or as an earlier trace found it.
        match replay {
            Some(list) => {
                let n = list.len().min(self.traced.capacity());
                let _ = self.traced.extend_from_slice(&list[..n]);
            }
            None => self.trace_packet(t, &az, stride),
        }
        if dropped {
            return;
        }
        let Some(mut p) = Writer::new(scanner, mode, buf, stamp) else {
            return;
        };
        for (b, &a) in az.iter().enumerate().take(blocks) {
            p.set_block(
                b,
                a,
                GpsTime(stamp.first.0 + scanner.firing_offset_ns(mode, b, 0)),
            );
        }
        self.emit(&mut p, t, &az, stride);
        p.finish();
    }
}

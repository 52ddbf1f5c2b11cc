//! The VN-200 side of the simulator: binary output frames (Common group: TimeStartup, TimeGps,
//! YawPitchRoll or Quaternion, Position, InsStatus) at a fixed rate, sampled from the truth,
//! with optional noise (white per sample, and correlated: [`super::nav_error`]), a clock
//! offset, clock steps and corrupted bytes, written through the VN-200 emit side.

use super::nav_error::{Correlated, GaussMarkov, NavError};
use super::rng::Rng;
use super::World;
use crate::frames::{roll_pitch_heading, rotation};
use crate::time::GpsTime;
use crate::vn200::binary::{emit, Masks};
use crate::vn200::fields::Group;
use nalgebra::Vector3;

/// INS stream settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InsConfig {
    /// Output rate [Hz] (VN-200: up to 400).
    pub rate_hz: f64,
    /// Attitude noise per angle, 1 sigma [rad].
    pub att_sigma: f64,
    /// Position noise per axis, 1 sigma [m].
    pub pos_sigma: f64,
    /// Errors that wander (first-order Gauss-Markov per axis), on top of the white noise.
    pub correlated: Correlated,
    /// INS clock error: reported time = true time + this [ns].
    pub time_offset_ns: i64,
    /// Probability that a byte on the serial line is corrupted.
    pub corrupt_prob: f64,
    /// Output starts this long before the scan and ends this long after it [s].
    pub margin_s: f64,
    /// Seed.
    pub seed: u64,
    /// The attitude field sent.
    pub attitude: AttitudeOutput,
    /// Steps of the INS clock: from true time `.0` [ns since the GPS epoch] on, the reported
    /// time is off by a further `.1` [ns] (a receiver's clock jump; negative: time goes back).
    pub time_steps: [(i64, i64); 4],
    /// Jumps of the reported position: from true time `.0` [ns since the GPS epoch] on, it is
    /// off by a further `.1` (north, east, down [m]): a GNSS solution that loses its fix and
    /// its filter that follows (a fault beyond any declared noise model).
    pub position_jumps: [(i64, [f64; 3]); 4],
    /// Silent GNSS outages: the INS coasts, its error growing, then snaps back (the status
    /// word unchanged).
    pub outages: [Outage; 4],
    /// The unit states its own accuracy (Attitude.YprU and Ins.PosU in every frame: what
    /// the boards configure; false: the Common group only, an unconfigured unit's output).
    pub stated: bool,
}

/// A silent GNSS outage: from `start` [ns since the GPS epoch, true time] for `duration_ns`
/// the INS's error grows as `(elapsed / duration)^2` to `peak` (north, east, down [m], roll,
/// pitch, heading [rad]: a coasting INS's drift), then is gone when the fix returns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outage {
    /// Start [ns since the GPS epoch].
    pub start: i64,
    /// Length [ns].
    pub duration_ns: i64,
    /// The error at its end.
    pub peak: [f64; 6],
}

impl Outage {
    /// No outage.
    pub const NONE: Outage = Outage {
        start: i64::MAX,
        duration_ns: 0,
        peak: [0.0; 6],
    };

    /// Its error at true time `t`.
    pub fn error_at(&self, t: GpsTime) -> [f64; 6] {
        let e = t.0.saturating_sub(self.start);
        if self.duration_ns <= 0 || e < 0 || e >= self.duration_ns {
            return [0.0; 6];
        }
        let f = e as f64 / self.duration_ns as f64;
        self.peak.map(|p| p * f * f)
    }
}

/// Which attitude field the simulated VN-200 sends (VN-200 manual, Common group bits 3, 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AttitudeOutput {
    /// YawPitchRoll: heading, pitch, roll [deg, f32].
    #[default]
    YawPitchRoll,
    /// Quaternion x, y, z, w (scalar last) of the body -> NED rotation [f32].
    Quaternion,
}

impl Default for InsConfig {
    fn default() -> Self {
        Self {
            rate_hz: 200.0,
            att_sigma: 0.0,
            pos_sigma: 0.0,
            correlated: Correlated::default(),
            time_offset_ns: 0,
            corrupt_prob: 0.0,
            margin_s: 1.0,
            seed: 2,
            attitude: AttitudeOutput::YawPitchRoll,
            time_steps: [(i64::MAX, 0); 4],
            position_jumps: [(i64::MAX, [0.0; 3]); 4],
            outages: [Outage::NONE; 4],
            stated: true,
        }
    }
}

impl InsConfig {
    /// The INS clock's error at true time `t` [ns]: the offset plus every step taken by then.
    pub fn clock_error_ns(&self, t: GpsTime) -> i64 {
        self.time_offset_ns
            + self
                .time_steps
                .iter()
                .filter(|(at, _)| t.0 >= *at)
                .map(|(_, step)| step)
                .sum::<i64>()
    }
}

/// The fields the simulated VN-200 sends: Common group TimeStartup (0), TimeGps (1),
/// YawPitchRoll (3) or Quaternion (4), Position (6), InsStatus (12); with `stated`, the
/// Attitude group's YprU (8) and the INS group's PosU (9): what the boards configure.
pub fn output_masks(attitude: AttitudeOutput, stated: bool) -> Masks {
    let att = match attitude {
        AttitudeOutput::YawPitchRoll => 3,
        AttitudeOutput::Quaternion => 4,
    };
    let m = Masks::default()
        .with(Group::Common, 0)
        .with(Group::Common, 1)
        .with(Group::Common, att)
        .with(Group::Common, 6)
        .with(Group::Common, 12);
    if stated {
        m.with(Group::Attitude, 8).with(Group::Ins, 9)
    } else {
        m
    }
}

/// TimeStartup at the first output [ns]: the unit was powered on 100 s before.
pub const STARTUP_NS: i64 = 100_000_000_000;

/// INS status sent: mode 2 (tracking) and GNSS fix (bit 2).
pub const INS_STATUS: u16 = 0b110;

/// Counts of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InsStats {
    /// Frames made.
    pub frames: u64,
    /// Bytes corrupted on the line.
    pub corrupted_bytes: u64,
}

/// The VN-200 simulator.
pub struct InsSim<'w, 'a> {
    world: &'w World<'a>,
    cfg: InsConfig,
    first: i64,
    period_ns: i64,
    count: u64,
    j: u64,
    rng: Rng,
    nav: GaussMarkov,
    /// The correlated error of the last sample made (the truth of what a solver may estimate).
    pub last_error: NavError,
    /// Counts so far.
    pub stats: InsStats,
}

/// The correlated errors' own random stream: `seed` ^ this.
const NAV_ERROR_STREAM: u64 = 0x6e61_765f_6572_7273;

impl<'w, 'a> InsSim<'w, 'a> {
    /// A simulator covering the trajectory plus the margins.
    pub fn new(world: &'w World<'a>, cfg: InsConfig) -> Self {
        let period_ns = (1e9 / cfg.rate_hz.max(1.0)) as i64;
        let margin = (cfg.margin_s * 1e9) as i64;
        let span = (world.trajectory.duration() * 1e9) as i64 + 2 * margin;
        Self {
            world,
            cfg,
            first: world.start.0 - margin,
            period_ns,
            count: (span / period_ns) as u64 + 1,
            j: 0,
            rng: Rng::new(cfg.seed),
            nav: GaussMarkov::new(
                &cfg.correlated,
                period_ns as f64 * 1e-9,
                cfg.seed ^ NAV_ERROR_STREAM,
            ),
            last_error: NavError::default(),
            stats: InsStats::default(),
        }
    }

    /// The true time of sample `j`.
    pub fn sample_time(&self, j: u64) -> GpsTime {
        GpsTime(self.first + j as i64 * self.period_ns)
    }

    /// The next sample with its noise: true time, reported (stamped) GPS time [ns], roll,
    /// pitch, heading relative to the local level [rad], and the WGS84 position.
    fn next_sample(&mut self) -> Option<(GpsTime, i64, [f64; 3], crate::frames::Geodetic)> {
        if self.j >= self.count {
            return None;
        }
        let t = self.sample_time(self.j);
        self.j += 1;
        let s = self.world.trajectory.state(self.world.t_of(t));
        let e = self.nav.step();
        let [en, ee, ed, psi_n, psi_e, psi_d] = e.0;
        let noise = Vector3::new(
            self.rng.gauss(self.cfg.pos_sigma) + en,
            self.rng.gauss(self.cfg.pos_sigma) + ee,
            self.rng.gauss(self.cfg.pos_sigma) + ed,
        );
        let coast = self.cfg.outages.iter().fold([0.0; 6], |a, o| {
            let e = o.error_at(t);
            core::array::from_fn(|i| a[i] + e[i])
        });
        let jumped: Vector3<f64> = self
            .cfg
            .position_jumps
            .iter()
            .filter(|(at, _)| t.0 >= *at)
            .map(|(_, d)| Vector3::from(*d))
            .sum::<Vector3<f64>>()
            + Vector3::new(coast[0], coast[1], coast[2]);
        let g = self.world.site.to_geodetic(&(s.position + noise + jumped));
        // Attitude relative to the local-level NED at the vessel, as an INS reports it.
        let c = self.world.site.from_local_level(g.lat, g.lon);
        let local = c.transpose() * rotation(s.rph[0], s.rph[1], s.rph[2]);
        // The correlated attitude error is the navigation frame's misalignment (an INS's tilt
        // and heading errors, the psi angles: they stay put in the level frame as the vessel
        // turns): the reported attitude is the true one turned by it; its roll, pitch and
        // heading differences are what the outputs carry.
        let [r0, p0, h0] = roll_pitch_heading(&local);
        let [r1, p1, h1] = roll_pitch_heading(&(rotation(psi_n, psi_e, psi_d) * local));
        let wrap = |a: f64| libm::remainder(a, core::f64::consts::TAU);
        let (er, ep, eh) = (wrap(r1 - r0), p1 - p0, wrap(h1 - h0));
        self.last_error = NavError([en, ee, ed, er, ep, eh]);
        let (r, p, h) = (r0, p0, h0);
        let sig = self.cfg.att_sigma;
        let (h, p, r) = (
            h + self.rng.gauss(sig) + eh + coast[5],
            p + self.rng.gauss(sig) + ep + coast[4],
            r + self.rng.gauss(sig) + er + coast[3],
        );
        let stamp = (t.0 + self.cfg.clock_error_ns(t)).max(0);
        Some((t, stamp, [r, p, h], g))
    }

    /// The next sample as a post-processed trajectory holds it (an SBET record): its GPS time
    /// (true time plus the clock error), roll, pitch, heading [rad] and position, with the
    /// same noise as [`Self::next_frame`] for the same seed.
    pub fn next_pose(&mut self) -> Option<(GpsTime, [f64; 3], crate::frames::Geodetic)> {
        let (_, stamp, rph, g) = self.next_sample()?;
        self.stats.frames += 1;
        Some((GpsTime(stamp), rph, g))
    }

    /// Per axis 1 sigma of everything the samples carry (white and correlated together):
    /// north, east, down [m]; roll, pitch, heading [rad] (a POS MV's Group 2, an smrmsg).
    pub fn stated_sigmas(&self) -> [f64; 6] {
        let c = self.cfg.correlated.sigmas();
        core::array::from_fn(|i| {
            let white = if i < 3 {
                self.cfg.pos_sigma
            } else {
                self.cfg.att_sigma
            };
            libm::sqrt(white * white + c[i] * c[i])
        })
    }

    fn corrupt(&mut self, bytes: &mut [u8]) {
        if self.cfg.corrupt_prob > 0.0 {
            for b in bytes.iter_mut() {
                if self.rng.chance(self.cfg.corrupt_prob) {
                    *b ^= (self.rng.next_u64() % 255 + 1) as u8;
                    self.stats.corrupted_bytes += 1;
                }
            }
        }
    }

    /// Write the next frame into `out` (at least 96 bytes); its true time and length.
    pub fn next_frame(&mut self, out: &mut [u8]) -> Option<(GpsTime, usize)> {
        let (t, stamp, [r, p, h], g) = self.next_sample()?;
        let mut payload = [0u8; 74];
        let mut w = 0;
        let mut put = |b: &[u8]| {
            payload[w..w + b.len()].copy_from_slice(b);
            w += b.len();
        };
        // The unit's free-running clock: powered on STARTUP_NS before its first output; it
        // does not take the GPS clock's steps.
        put(&((t.0 - self.first + STARTUP_NS) as u64).to_le_bytes());
        put(&(stamp as u64).to_le_bytes());
        match self.cfg.attitude {
            AttitudeOutput::YawPitchRoll => {
                for a in [h, p, r] {
                    put(&(a.to_degrees() as f32).to_le_bytes());
                }
            }
            AttitudeOutput::Quaternion => {
                let q = nalgebra::UnitQuaternion::from_rotation_matrix(
                    &nalgebra::Rotation3::from_matrix_unchecked(rotation(r, p, h)),
                );
                // Scalar last, as VectorNav sends it.
                for c in [q.i, q.j, q.k, q.w] {
                    put(&(c as f32).to_le_bytes());
                }
            }
        }
        for v in [g.lat.to_degrees(), g.lon.to_degrees(), g.h] {
            put(&v.to_le_bytes());
        }
        put(&INS_STATUS.to_le_bytes());
        if self.cfg.stated {
            // Attitude.YprU: yaw, pitch, roll 1 sigma [deg]; Ins.PosU: one number [m] (the
            // largest axis: VectorNav's is the position's uncertainty, not per axis).
            let sg = self.stated_sigmas();
            for a in [sg[5], sg[4], sg[3]] {
                put(&(a.to_degrees() as f32).to_le_bytes());
            }
            put(&(sg[0].max(sg[1]).max(sg[2]) as f32).to_le_bytes());
        }
        let n = emit(
            out,
            &output_masks(self.cfg.attitude, self.cfg.stated),
            &payload[..w],
        )
        .ok()?;
        self.stats.frames += 1;
        self.corrupt(&mut out[..n]);
        Some((t, n))
    }

    /// The same samples (the same noise as [`Self::next_frame`] for the same seed) as an
    /// Applanix POS MV's real-time output (ICD groups, time 1 in UTC seconds of the week as
    /// a POS MV sends by default, time 2 POS time): Group 1 per sample, and at each whole
    /// second Group 3 (GPS week, GPS - UTC), Group 7 (PPS, synchronized) and Group 2 (RMS
    /// errors: the white and correlated noise settings together, per axis). Writes into `out`
    /// (at least 512 bytes); the true time and the length.
    pub fn next_posmv(&mut self, out: &mut [u8]) -> Option<(GpsTime, usize)> {
        use crate::posmv::{
            Alignment, GnssStatus, Metrics, Navigation, PpsTime, TimeFields, TimeSync, TimeType,
        };
        let first = self.j == 0;
        let (t, stamp, rph, g) = self.next_sample()?;
        let leap = self.world.leap_seconds;
        let (week, gps_tow_ns) = GpsTime(stamp).week_tow_ns();
        let pos_time = (t.0 - self.first) as f64 * 1e-9 + 100.0;
        let utc_sow = gps_tow_ns as f64 * 1e-9 - leap as f64;
        let time = TimeFields {
            time1: utc_sow,
            time2: pos_time,
            distance: 0.0,
            time1_type: TimeType::Utc,
            time2_type: TimeType::Pos,
            distance_type: 1,
        };
        let mut n = 0;
        let whole_second = first || gps_tow_ns % 1_000_000_000 < self.period_ns;
        if whole_second {
            let second = TimeFields {
                time1: libm::floor(utc_sow),
                ..time
            };
            n += GnssStatus {
                time: second,
                solution: 7,
                satellites: 14,
                channels: 0,
                dop: [0.8, 1.3],
                week: week as u32,
                utc_offset: leap as f64,
                receiver: 17,
            }
            .emit(&mut out[n..])?;
            n += PpsTime {
                time: second,
                pps_count: (pos_time as u32).saturating_sub(90),
                sync: TimeSync::Synchronized,
            }
            .emit(&mut out[n..])?;
            let s = self.stated_sigmas();
            let pos: [f32; 3] = core::array::from_fn(|i| s[i] as f32);
            let att: [f32; 3] = core::array::from_fn(|i| s[i + 3].to_degrees() as f32);
            n += Metrics {
                time,
                position_rms: pos,
                velocity_rms: [0.01; 3],
                attitude_rms: att,
                ellipse: [pos[0].max(pos[1]), pos[0].min(pos[1]), 0.0],
            }
            .emit(&mut out[n..])?;
        }
        let h = rph[2].to_degrees();
        let heading = h - 360.0 * libm::floor(h / 360.0);
        n += Navigation {
            time,
            lla: [g.lat.to_degrees(), g.lon.to_degrees(), g.h],
            velocity: [0.0; 3],
            rph: [rph[0].to_degrees(), rph[1].to_degrees(), heading],
            wander: 0.0,
            track_speed: [0.0; 2],
            rate: [0.0; 3],
            accel: [0.0; 3],
            alignment: Alignment::FullNavigation,
        }
        .emit(&mut out[n..])?;
        self.stats.frames += 1;
        self.corrupt(&mut out[..n]);
        Some((t, n))
    }
}

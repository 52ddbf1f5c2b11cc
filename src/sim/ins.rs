//! The VN-200 side of the simulator: binary output frames (Common group: TimeGps,
//! YawPitchRoll, Position, InsStatus) at a fixed rate, sampled from the truth, with optional
//! noise, a clock offset and corrupted bytes, written through the VN-200 emit side.

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
    /// INS clock error: reported time = true time + this [ns].
    pub time_offset_ns: i64,
    /// Probability that a byte on the serial line is corrupted.
    pub corrupt_prob: f64,
    /// Output starts this long before the scan and ends this long after it [s].
    pub margin_s: f64,
    /// Seed.
    pub seed: u64,
}

impl Default for InsConfig {
    fn default() -> Self {
        Self {
            rate_hz: 200.0,
            att_sigma: 0.0,
            pos_sigma: 0.0,
            time_offset_ns: 0,
            corrupt_prob: 0.0,
            margin_s: 1.0,
            seed: 2,
        }
    }
}

/// The fields the simulated VN-200 sends: Common group TimeGps (1), YawPitchRoll (3),
/// Position (6), InsStatus (12).
pub fn output_masks() -> Masks {
    Masks::default()
        .with(Group::Common, 1)
        .with(Group::Common, 3)
        .with(Group::Common, 6)
        .with(Group::Common, 12)
}

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
    /// Counts so far.
    pub stats: InsStats,
}

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
            stats: InsStats::default(),
        }
    }

    /// The true time of sample `j`.
    pub fn sample_time(&self, j: u64) -> GpsTime {
        GpsTime(self.first + j as i64 * self.period_ns)
    }

    /// Write the next frame into `out` (at least 64 bytes); its true time and length.
    pub fn next_frame(&mut self, out: &mut [u8]) -> Option<(GpsTime, usize)> {
        if self.j >= self.count {
            return None;
        }
        let t = self.sample_time(self.j);
        self.j += 1;
        let s = self.world.trajectory.state(self.world.t_of(t));
        let noise = Vector3::new(
            self.rng.gauss(self.cfg.pos_sigma),
            self.rng.gauss(self.cfg.pos_sigma),
            self.rng.gauss(self.cfg.pos_sigma),
        );
        let g = self.world.site.to_geodetic(&(s.position + noise));
        // Attitude relative to the local-level NED at the vessel, as an INS reports it.
        let c = self.world.site.from_local_level(g.lat, g.lon);
        let local = c.transpose() * rotation(s.rph[0], s.rph[1], s.rph[2]);
        let [r, p, h] = roll_pitch_heading(&local);
        let sig = self.cfg.att_sigma;
        let ypr = [
            h + self.rng.gauss(sig),
            p + self.rng.gauss(sig),
            r + self.rng.gauss(sig),
        ];
        let mut payload = [0u8; 46];
        let stamp = (t.0 + self.cfg.time_offset_ns).max(0) as u64;
        payload[..8].copy_from_slice(&stamp.to_le_bytes());
        for (i, a) in ypr.iter().enumerate() {
            payload[8 + 4 * i..12 + 4 * i].copy_from_slice(&(a.to_degrees() as f32).to_le_bytes());
        }
        for (i, v) in [g.lat.to_degrees(), g.lon.to_degrees(), g.h]
            .iter()
            .enumerate()
        {
            payload[20 + 8 * i..28 + 8 * i].copy_from_slice(&v.to_le_bytes());
        }
        payload[44..46].copy_from_slice(&INS_STATUS.to_le_bytes());
        let n = emit(out, &output_masks(), &payload).ok()?;
        self.stats.frames += 1;
        if self.cfg.corrupt_prob > 0.0 {
            for b in out[..n].iter_mut() {
                if self.rng.chance(self.cfg.corrupt_prob) {
                    *b ^= (self.rng.next_u64() % 255 + 1) as u8;
                    self.stats.corrupted_bytes += 1;
                }
            }
        }
        Some((t, n))
    }
}

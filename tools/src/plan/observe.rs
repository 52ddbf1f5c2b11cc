//! What a planned survey would observe: its stretches (passes and turns), every sphere return
//! traced as the observation the pipeline would make of it, and their geometry for the
//! predictor, per stretch and sphere.

use super::{PlanNoise, RATE_HALF_S};
use crate::config::scenario::Scenario;
use nalgebra::{Rotation3, Vector3};
use serde::{Deserialize, Serialize};
use spherecal::align::window::{Observation, Target};
use spherecal::calib::predict::{Info, Predicted};
use spherecal::georef::{beam_origin_l, beam_unit};
use spherecal::sim::{LidarSim, SimPacket, World};

/// A stretch of the trajectory: a pass, or the turn after one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Segment {
    /// Pass i (0-based).
    Pass(usize),
    /// The turn after pass i.
    Turn(usize),
    /// A recorded trajectory (`trajectory.file`).
    Recorded,
}

/// The segments of a scenario's trajectory, with their trajectory times [s].
pub fn segments(s: &Scenario) -> Vec<(Segment, f64, f64)> {
    if s.trajectory.file.is_some() {
        return vec![(Segment::Recorded, f64::NEG_INFINITY, f64::INFINITY)];
    }
    let mut out = Vec::new();
    let mut t = 0.0;
    let n = s.trajectory.pass.len();
    for (i, p) in s.trajectory.pass.iter().enumerate() {
        out.push((Segment::Pass(i), t, t + p.duration_s));
        t += p.duration_s;
        if i + 1 < n {
            out.push((Segment::Turn(i), t, t + s.trajectory.turn_s));
            t += s.trajectory.turn_s;
        }
    }
    out
}

/// One sphere's returns in one segment: their information and extent.
#[derive(Debug, Clone, Default)]
pub struct Cell {
    /// The information.
    pub info: Info,
    /// Shortest and longest range [m] (infinite, 0 without returns).
    pub range_m: [f64; 2],
}

/// A traced plan: per segment, per sphere.
#[derive(Debug, Clone)]
pub struct Geometry {
    /// The segments.
    pub segments: Vec<(Segment, f64, f64)>,
    /// `cells[segment][sphere]`.
    pub cells: Vec<Vec<Cell>>,
    /// The returns under the scenario's navigation model (`None`: it declares none).
    pub nav: Option<super::nav::NavPlan>,
}

impl Geometry {
    /// All of it.
    pub fn total(&self) -> Info {
        self.sum(|_, _| true)
    }

    /// The prediction from the spheres `keep` says: under the scenario's navigation model its
    /// solver's sigmas (infinite when not determined), else the white information's.
    pub fn predict(&self, keep: impl Fn(usize) -> bool) -> Predicted {
        let mut p = Predicted::of(&self.sum(|_, j| keep(j)));
        if let Some(nav) = &self.nav {
            p.sigma = nav
                .sigma(|_, j| keep(j))
                .unwrap_or([f64::INFINITY; spherecal::georef::P + 1]);
        }
        p
    }

    /// Sphere `j`'s returns over every segment.
    pub fn returns_of(&self, j: usize) -> u32 {
        self.cells.iter().map(|r| r[j].info.n).sum()
    }

    /// The cells `keep(segment, sphere)` says.
    pub fn sum(&self, keep: impl Fn(usize, usize) -> bool) -> Info {
        let mut i = Info::default();
        for (k, row) in self.cells.iter().enumerate() {
            for (j, c) in row.iter().enumerate() {
                if keep(k, j) {
                    i += &c.info;
                }
            }
        }
        i
    }
}

/// The returns of sphere(s) of a scenario as the pipeline would observe them (true poses,
/// rates by central differences over 0.4 s): `(trajectory time, sphere, observation)` in time
/// order. Traced on `threads` threads, each over its share of the packets.
pub fn observe(
    s: &Scenario,
    threads: usize,
) -> Result<Vec<(f64, usize, Observation)>, crate::Error> {
    let cfg = {
        let mut c = s.lidar_config();
        // The geometry: ideal beams, nothing lost (drops scale the information instead).
        c.divergence = [0.0; 2];
        c.drop_prob = 0.0;
        c.clutter_keep = 1.0;
        c.range_sigma = 0.0;
        c.incidence_noise = false;
        c.range_walk = 0.0;
        c.targets_only = true;
        c
    };
    let n_spheres = s.sphere.len();
    s.with_world(|world| {
        let probe = LidarSim::new(world, cfg);
        let (first, end) = (0, probe.packet_at(world.trajectory.duration()));
        let threads = threads.clamp(1, 8);
        let step = (end.saturating_sub(first)).div_ceil(threads as u64).max(1);
        std::thread::scope(|sc| {
            let handles: Vec<_> = (0..threads as u64)
                .map(|k| {
                    let (a, b) = (first + k * step, (first + (k + 1) * step).min(end));
                    // (A simulator is ~0.6 MB: more than a default thread's stack holds
                    // unoptimised.)
                    std::thread::Builder::new()
                        .stack_size(16 << 20)
                        .spawn_scoped(sc, move || observe_packets(world, cfg, a, b, n_spheres))
                })
                .collect();
            let parts: Option<Vec<_>> = handles
                .into_iter()
                .map(|h| h.ok().and_then(|h| h.join().ok()))
                .collect();
            parts
                .map(|p| p.concat())
                .ok_or_else(|| crate::Error::internal("a planner's tracing thread panicked"))
        })
    })?
}

/// The sphere returns of data packets `first..end`.
fn observe_packets(
    world: &World<'_>,
    cfg: spherecal::sim::LidarConfig,
    first: u64,
    end: u64,
    n_spheres: usize,
) -> Vec<(f64, usize, Observation)> {
    let mut out = Vec::new();
    if first >= end {
        return out;
    }
    let mut sim = LidarSim::new(world, cfg);
    sim.restrict(first, end);
    let scanner = cfg.scanner;
    let mut buf = [0u8; spherecal::sim::lidar::MAX_PACKET_LEN];
    let state = |t: f64| world.trajectory.state(t);
    while let Some(p) = sim.next_packet(&mut buf) {
        let SimPacket::Data { time, .. } = p else {
            continue;
        };
        if sim.packet_at(world.t_of(time)) < first {
            continue;
        }
        for h in &sim.hits {
            let j = usize::from(h.object);
            if j >= n_spheres || h.purity < 230 {
                continue;
            }
            let t = world.t_of(h.time);
            let st = state(t);
            let (a, b) = (state(t - RATE_HALF_S), state(t + RATE_HALF_S));
            let velocity = (b.position - a.position) / (2.0 * RATE_HALF_S);
            let turn = Rotation3::from_matrix_unchecked(b.r_ig() * a.r_ig().transpose());
            let omega: Vector3<f64> = turn.scaled_axis() / (2.0 * RATE_HALF_S);
            let laser = scanner.laser_of(usize::from(h.channel));
            let beam = scanner.beam(laser);
            let (sa, ca) = h.azimuth.sin_cos();
            let q = beam_unit(&beam, sa, ca) * h.range + beam_origin_l(&beam);
            let laser = laser as u8;
            out.push((
                t,
                j,
                Observation {
                    q_l: q.cast(),
                    position: st.position,
                    r_ig: st.r_ig().cast(),
                    time: h.time,
                    velocity: velocity.cast(),
                    omega: omega.cast(),
                    range: h.range as f32,
                    block: h.block,
                    channel: h.channel,
                    laser,
                    ..Observation::default()
                },
            ));
        }
    }
    out
}

/// The scenario's spheres as the solver's targets (site NED).
pub fn targets_of_scenario(s: &Scenario) -> Vec<Target> {
    s.sphere
        .iter()
        .map(|sp| Target {
            center: Vector3::from(sp.ned_m),
            radius: sp.radius_m,
        })
        .collect()
}

/// Trace a scenario into per-segment, per-sphere information.
pub fn geometry(s: &Scenario, noise: &PlanNoise, threads: usize) -> Result<Geometry, crate::Error> {
    let obs = observe(s, threads)?;
    Ok(geometry_of(s, noise, &obs, segments(s)))
}

/// Fewest returns of a sphere in a slice of time for the solver to keep them: its
/// detections within the prior need 4 inliers ([`ExtractSettings`]'s `min_inliers_prior`).
/// (8 made table1's time offset 25 % worse than 200 noisy calibrations; 1 made pontoon's
/// 20 % better: its turns see the spheres in slices of 1-3 returns the solver never keeps.)
///
/// [`ExtractSettings`]: spherecal::calib::extract::ExtractSettings
pub const MIN_SLICE_RETURNS: usize = 4;

/// Which returns the solver can keep: those in slices of time (cut as the solver cuts them,
/// [`spherecal::calib::extract::assign_slices`]) holding at least [`MIN_SLICE_RETURNS`] of
/// their sphere's returns. Sparse sightings (a sphere far off in a turn) are left out: the
/// solver detects them in some runs and not in others.
fn detectable(obs: &[(f64, usize, Observation)], spheres: usize) -> Vec<bool> {
    use spherecal::calib::extract::{assign_slices, ExtractSettings};
    let slice_ns = ExtractSettings::default().slice_ns;
    let mut keep = vec![false; obs.len()];
    for j in 0..spheres {
        let idx: Vec<usize> = (0..obs.len()).filter(|&k| obs[k].1 == j).collect();
        let mut mine: Vec<Observation> = idx.iter().map(|&k| obs[k].2).collect();
        assign_slices(&mut mine, slice_ns, usize::MAX);
        let mut count = std::collections::HashMap::<u32, usize>::new();
        for o in &mine {
            *count.entry(o.work.slice).or_default() += 1;
        }
        for (&k, o) in idx.iter().zip(&mine) {
            keep[k] = count[&o.work.slice] >= MIN_SLICE_RETURNS;
        }
    }
    keep
}

/// The information of observations, per segment and sphere.
pub fn geometry_of(
    s: &Scenario,
    noise: &PlanNoise,
    obs: &[(f64, usize, Observation)],
    segs: Vec<(Segment, f64, f64)>,
) -> Geometry {
    let targets = targets_of_scenario(s);
    let model = noise.model(s.scanner().unwrap_or_default().distance_unit_m());
    let b = s.truth_mount().params().0;
    let keep = 1.0 - s.lidar.drop_prob;
    let mut cells = vec![vec![Cell::default(); targets.len()]; segs.len()];
    let detectable = detectable(obs, targets.len());
    let nav = super::nav::NavPlan::of(s, noise, &targets, obs, &detectable);
    // Per segment, its returns in time order (all spheres: they share the INS samples).
    let mut buckets: Vec<Vec<(usize, Observation)>> = vec![Vec::new(); segs.len()];
    for ((t, j, o), _) in obs.iter().zip(&detectable).filter(|(_, d)| **d) {
        let k = segs
            .iter()
            .position(|(_, a, b)| *t >= *a && *t < *b)
            .unwrap_or(segs.len() - 1);
        buckets[k].push((*j, *o));
    }
    for (k, v) in buckets.iter().enumerate() {
        for (j, c) in cells[k].iter_mut().enumerate() {
            c.range_m = [f64::INFINITY, 0.0];
            for (_, o) in v.iter().filter(|(jj, _)| *jj == j) {
                let r = f64::from(o.range);
                c.range_m = [c.range_m[0].min(r), c.range_m[1].max(r)];
            }
            // A sphere's cell holds its information with the INS errors it shares with the
            // others' returns (attributed to the cell of the return).
            let mut only = Info::default();
            only.add_returns(
                &targets,
                v.iter().map(|(jj, o)| (*jj, o)).filter(|(jj, _)| *jj == j),
                &b,
                &model,
            );
            c.info = only;
        }
        // The segment's whole information, shared errors included, minus the cells' sum: the
        // cross terms, given to the segment's first cell so that sums over whole segments are
        // exact (per-sphere sums leave them out: a small share).
        let mut all = Info::default();
        all.add_returns(&targets, v.iter().map(|(jj, o)| (*jj, o)), &b, &model);
        let mut sum = Info::default();
        for c in &cells[k] {
            sum += &c.info;
        }
        if let Some(c0) = cells[k].first_mut() {
            c0.info.m += all.m - sum.m;
        }
        if keep < 1.0 {
            for c in cells[k].iter_mut() {
                c.info = c.info.scaled(keep);
            }
        }
    }
    Geometry {
        segments: segs,
        cells,
        nav,
    }
}

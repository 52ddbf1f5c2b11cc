//! The first round's consensus: which of the sphere-like candidates detected in each slice of
//! time are the spheres (docs/extraction.md, "Consensus").
//!
//! Without a prior a slice can hold the sphere and things that look like it from the scan lines
//! that cross them: a buoy or a fender of the same radius, a bollard's cap or a person seen by one
//! scan line. Each accepted candidate becomes a *centre observation*: its centre carried back into
//! the LiDAR frame with a pose of its slice and the start mounting, so that eq. 3 puts it in the
//! site frame for any mounting. The spheres' candidates agree on one mounting that puts each at
//! its surveyed centre, across passes in different directions and across spheres; a decoy agrees
//! only with itself. RANSAC (Fischler & Bolles 1981): mountings from three candidates of distinct
//! (sphere, pass) groups by Gauss-Newton from the start, within the a-priori bounds, scored by the
//! slices they explain (a slice counts once, by its nearest candidate); the best refined on its
//! inliers. Then, per sphere, the best mounting that explains that sphere *without* the chosen
//! candidates: if it explains nearly as much, the sphere is ambiguous and named.

use super::objective::{rotation_and_derivatives, TimeOffset};
use crate::align::window::{Observation, Target, MAX_TARGETS};
use crate::georef::{Mount, Params, P};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// 6x6.
type Mat6 = SMatrix<f64, P, P>;
/// 6-vector.
type Vec6 = SVector<f64, P>;

/// A candidate sphere centre from one slice's detection.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Candidate {
    /// The centre as an observation: `q_l` its point in the LiDAR frame under the start
    /// mounting, the rest the pose of a return of its slice.
    pub centre: Observation,
    /// Sphere index.
    pub sphere: u8,
    /// (sphere, pass) group: candidates of one group see the sphere from nearly one place.
    pub group: u16,
    /// Slice number (within its sphere's observations).
    pub slice: u32,
    /// Its slice's returns: `at..at + len` of its sphere's (as the first round left them).
    pub at: u32,
    /// See `at`.
    pub len: u32,
    /// Its detection's centre relative to the surveyed one, with the start mounting [m].
    pub detected: [f32; 3],
    /// Its detection's inliers.
    pub inliers: u32,
    /// Chosen by the consensus: the nearest of its slice to the surveyed centre, within the
    /// inlier distance.
    pub chosen: bool,
    /// Left out of a search (the ambiguity test).
    pub excluded: bool,
}

impl Candidate {
    /// The candidate at `detected` (relative to the surveyed centre of `t`) in a slice
    /// georeferenced with `mount` and time offset `time`; `rep` a return of the slice (its pose).
    /// `None` when the pose cannot be inverted.
    pub fn new(
        detected: [f32; 3],
        rep: &Observation,
        t: &Target,
        mount: &Mount,
        time: &TimeOffset,
    ) -> Option<Self> {
        let dt = time.at(rep);
        // Eq. 3 with the offset (Observation::georef_dt): x = P + w + (v + om x w) dt, with
        // w = R (a + R_li q); solved for q.
        let x = t.center + Vector3::new(detected[0], detected[1], detected[2]).cast();
        let (v, om): (Vector3<f64>, Vector3<f64>) = (rep.velocity.cast(), rep.omega.cast());
        let m = Matrix3::identity() + skew(&om) * dt;
        let w = m.try_inverse()? * (x - rep.position - v * dt);
        let q = mount.r_li.transpose() * (rep.rot().transpose() * w - mount.lever);
        if !q.iter().all(|c| c.is_finite()) {
            return None;
        }
        Some(Self {
            centre: Observation {
                q_l: q.cast(),
                ..*rep
            },
            detected,
            ..Self::default()
        })
    }
}

#[inline]
fn skew(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

/// The box the mounting must stay in: the start (the a-priori values) plus or minus what the
/// windows' margin allows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// The start [rad, m].
    pub start: [f64; P],
    /// Largest change of each angle [rad].
    pub angle: f64,
    /// Largest change of each lever-arm component [m].
    pub lever: f64,
}

impl Bounds {
    /// No bound.
    pub fn none(start: &Params) -> Self {
        Self {
            start: start.0,
            angle: f64::INFINITY,
            lever: f64::INFINITY,
        }
    }

    /// `b` within the box (angles compared modulo a turn).
    pub fn contains(&self, b: &[f64; P]) -> bool {
        let turn = core::f64::consts::TAU;
        (0..3).all(|i| {
            let d = b[i] - self.start[i];
            let d = d - turn * libm::round(d / turn);
            d.abs() <= self.angle
        }) && (3..P).all(|i| (b[i] - self.start[i]).abs() <= self.lever)
    }

    /// By how much of its allowance each parameter moved from the start (1: at the bound).
    pub fn usage(&self, b: &[f64; P]) -> [f64; P] {
        let turn = core::f64::consts::TAU;
        core::array::from_fn(|i| {
            let d = b[i] - self.start[i];
            if i < 3 {
                (d - turn * libm::round(d / turn)).abs() / self.angle
            } else {
                d.abs() / self.lever
            }
        })
    }
}

/// Consensus settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConsensusSettings {
    /// Hypotheses at most per search.
    pub max_hypotheses: usize,
    /// Hypotheses at least per search.
    pub min_hypotheses: usize,
    /// A candidate within this of its surveyed centre, beyond the sphere's radius, is explained
    /// [m] (a slice's centre from one scan line is uncertain by up to a radius along the
    /// sphere's axis through the arc).
    pub inlier_m: f64,
    /// A runner-up explaining this share of the best's slices with other candidates for one
    /// sphere makes that sphere ambiguous.
    pub ambiguity: f64,
}

impl Default for ConsensusSettings {
    fn default() -> Self {
        Self {
            max_hypotheses: 500,
            min_hypotheses: 60,
            inlier_m: 0.15,
            ambiguity: 0.8,
        }
    }
}

/// What the consensus found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Consensus {
    /// The mounting that explains the most slices [rad, m].
    pub b: [f64; P],
    /// Slices explained (all spheres).
    pub score: f64,
    /// Slices explained, per sphere.
    pub support: [u32; MAX_TARGETS],
    /// Slices with candidates, per sphere.
    pub slices: [u32; MAX_TARGETS],
    /// RMS distance of the chosen candidates from their surveyed centres [m].
    pub rms: f64,
    /// Hypotheses tried, all searches.
    pub hypotheses: usize,
    /// The first sphere another mounting explains nearly as well with other candidates.
    pub ambiguous: Option<Ambiguity>,
}

/// Two mountings that put different candidates on one sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ambiguity {
    /// Sphere index.
    pub sphere: usize,
    /// Slices of it the best mounting explains, and the runner-up (with other candidates).
    pub support: [u32; 2],
    /// Slices in all each explains.
    pub score: [f64; 2],
    /// Where the runner-up's candidates sit relative to the chosen ones, with the start
    /// mounting (their mean) [m, NED].
    pub offset: [f64; 3],
}

/// A small deterministic generator (xorshift64*).
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (((x >> 32) * n as u64) >> 32) as usize
    }
}

/// The centre observation's site position and its derivatives by the six.
#[inline]
fn position_and_rows(
    o: &Observation,
    r_li: &Matrix3<f64>,
    d_rli: &[Matrix3<f64>; 3],
    a: &Vector3<f64>,
    dt: f64,
) -> (Vector3<f64>, [Vector3<f64>; P]) {
    let rot = o.rot();
    let q = o.q();
    let w = rot * (a + r_li * q);
    let om: Vector3<f64> = o.omega.cast();
    let v: Vector3<f64> = o.velocity.cast();
    let x = o.position + w + (v + om.cross(&w)) * dt;
    let m = (Matrix3::identity() + skew(&om) * dt) * rot;
    let rows = [
        m * (d_rli[0] * q),
        m * (d_rli[1] * q),
        m * (d_rli[2] * q),
        m.column(0).into_owned(),
        m.column(1).into_owned(),
        m.column(2).into_owned(),
    ];
    (x, rows)
}

/// The problem: candidates grouped by (sphere, slice), their targets and the bounds.
pub struct Search<'a> {
    /// The candidates, those of one (sphere, slice) together.
    pub cands: &'a mut [Candidate],
    /// The targets.
    pub targets: &'a [Target],
    /// The time offset the candidates are georeferenced with.
    pub time: TimeOffset,
    /// The box.
    pub bounds: Bounds,
    /// Settings.
    pub settings: ConsensusSettings,
}

impl Search<'_> {
    fn inlier(&self, j: usize) -> f64 {
        self.settings.inlier_m + self.targets.get(j).map_or(0.0, |t| t.radius)
    }

    /// Each candidate's distance from its surveyed centre with `b`, into `out` (same order).
    fn distances(&self, b: &[f64; P], out: &mut impl FnMut(usize, f64)) {
        let m = Params(*b).mount();
        for (k, c) in self.cands.iter().enumerate() {
            let t = &self.targets[usize::from(c.sphere)];
            out(
                k,
                (c.centre.georef_dt(&m, self.time.at(&c.centre)) - t.center).norm(),
            );
        }
    }

    /// Slices explained by `b` (each counts `1 - (d/tau)^2` of its nearest candidate within
    /// the inlier distance; excluded candidates count nothing), in all and per sphere.
    fn score(&self, b: &[f64; P]) -> (f64, [u32; MAX_TARGETS]) {
        let mut total = 0.0;
        let mut per = [0u32; MAX_TARGETS];
        let mut best = 0.0f64;
        let mut key: Option<(u8, u32)> = None;
        let cands = &*self.cands;
        let mut flush = |key: Option<(u8, u32)>, best: f64, total: &mut f64| {
            if let (Some((j, _)), true) = (key, best > 0.0) {
                *total += best;
                per[usize::from(j)] += 1;
            }
        };
        self.distances(b, &mut |k, d| {
            let c = &cands[k];
            let kk = Some((c.sphere, c.slice));
            if kk != key {
                flush(key, best, &mut total);
                key = kk;
                best = 0.0;
            }
            let tau = self.inlier(usize::from(c.sphere));
            if !c.excluded && d < tau {
                best = best.max(1.0 - (d / tau) * (d / tau));
            }
        });
        flush(key, best, &mut total);
        (total, per)
    }

    /// Gauss-Newton on `x_k(b) = c_k` over the candidates `idx` (with robust weights when
    /// `robust`), from `b`; `None` when singular or out of bounds.
    fn fit(&self, idx: &[usize], b: [f64; P], robust: bool) -> Option<[f64; P]> {
        let mut b = b;
        for _ in 0..6 {
            let (r_li, d_rli) = rotation_and_derivatives(&b);
            let a = Vector3::new(b[3], b[4], b[5]);
            let mut jtj = Mat6::zeros();
            let mut jtr = Vec6::zeros();
            for &k in idx {
                let c = &self.cands[k];
                let j = usize::from(c.sphere);
                let (x, rows) =
                    position_and_rows(&c.centre, &r_li, &d_rli, &a, self.time.at(&c.centre));
                let e = x - self.targets[j].center;
                let w = if robust {
                    let u = e.norm() / self.inlier(j);
                    if u >= 1.0 {
                        continue;
                    }
                    (1.0 - u * u) * (1.0 - u * u)
                } else {
                    1.0
                };
                for p in 0..P {
                    jtr[p] += w * rows[p].dot(&e);
                    for q in 0..=p {
                        jtj[(p, q)] += w * rows[p].dot(&rows[q]);
                    }
                }
            }
            for p in 0..P {
                for q in 0..p {
                    jtj[(q, p)] = jtj[(p, q)];
                }
            }
            // A weak prior at the start, one bound wide (a hundred for the refinement on every
            // inlier, which must not bias what they determine): directions the candidates do
            // not determine (one pass cannot separate roll, heading and height) stay where
            // they started instead of running off along the null space.
            let mut damped = jtj;
            for p in 0..P {
                let (wide, d) = if p < 3 {
                    (self.bounds.angle, b[p] - self.bounds.start[p])
                } else {
                    (self.bounds.lever, b[p] - self.bounds.start[p])
                };
                let wide = if robust { 100.0 * wide } else { wide };
                let w = if wide.is_finite() && wide > 0.0 {
                    1.0 / (wide * wide)
                } else {
                    0.0
                };
                damped[(p, p)] += w + 1e-9 * jtj[(p, p)] + 1e-12;
                jtr[p] += w * d;
            }
            let step = damped.cholesky()?.solve(&(-jtr));
            if !step.iter().all(|x| x.is_finite()) {
                return None;
            }
            for p in 0..P {
                b[p] += step[p];
            }
            if step.iter().take(3).all(|x| x.abs() < 1e-7)
                && step.iter().skip(3).all(|x| x.abs() < 1e-6)
            {
                break;
            }
        }
        self.bounds.contains(&b).then_some(b)
    }

    /// Indices of the candidates `b` explains: each slice's nearest within the inlier distance
    /// (excluded ones left out), at most `idx.len()`; returns how many.
    fn assign(&self, b: &[f64; P], idx: &mut [usize]) -> usize {
        let mut n = 0;
        let mut key: Option<(u8, u32)> = None;
        let mut best: Option<(usize, f64)> = None;
        let cands = &*self.cands;
        let mut push = |best: Option<(usize, f64)>, n: &mut usize| {
            if let Some((k, _)) = best {
                if *n < idx.len() {
                    idx[*n] = k;
                    *n += 1;
                }
            }
        };
        self.distances(b, &mut |k, d| {
            let c = &cands[k];
            let kk = Some((c.sphere, c.slice));
            if kk != key {
                push(best, &mut n);
                key = kk;
                best = None;
            }
            if !c.excluded
                && d < self.inlier(usize::from(c.sphere))
                && best.is_none_or(|(_, bd)| d < bd)
            {
                best = Some((k, d));
            }
        });
        push(best, &mut n);
        n
    }

    /// The mean detected centre (with the start mounting) of the candidates of sphere `j` that
    /// `b` explains, among those chosen or not.
    fn mean_detected(
        &self,
        b: &[f64; P],
        j: usize,
        chosen: bool,
        idx: &mut [usize],
    ) -> Vector3<f64> {
        let n = self.assign(b, idx);
        let (mut m, mut c) = (Vector3::<f64>::zeros(), 0.0f64);
        for &k in &idx[..n] {
            let cd = &self.cands[k];
            if usize::from(cd.sphere) == j && cd.chosen == chosen {
                m += Vector3::new(cd.detected[0], cd.detected[1], cd.detected[2]).cast();
                c += 1.0;
            }
        }
        m / c.max(1.0)
    }

    /// RANSAC from `start`: the best mounting found (refined), its score and per-sphere support.
    /// With `must`, every sample holds a candidate of that sphere.
    fn ransac(
        &self,
        start: &[f64; P],
        must: Option<u8>,
        rng: &mut Rng,
        scratch: &mut [usize],
        tried: &mut usize,
    ) -> Option<([f64; P], f64, [u32; MAX_TARGETS])> {
        let n = self.cands.len();
        let live = self.cands.iter().filter(|c| !c.excluded).count();
        if live < 3 {
            return None;
        }
        let spheres = {
            let mut seen = [false; MAX_TARGETS];
            for c in self.cands.iter().filter(|c| !c.excluded) {
                seen[usize::from(c.sphere) % MAX_TARGETS] = true;
            }
            seen.iter().filter(|&&s| s).count()
        };
        let mut best: Option<([f64; P], f64, [u32; MAX_TARGETS])> = None;
        let mut budget = self.settings.max_hypotheses;
        let mut h = 0;
        while h < budget {
            h += 1;
            *tried += 1;
            // Three live candidates apart (two spheres at least when there are).
            let mut pick = [usize::MAX; 3];
            let mut ok = true;
            for s in 0..3 {
                let mut found = false;
                for _ in 0..32 {
                    let k = rng.below(n);
                    let c = &self.cands[k];
                    // Distinct groups, or in one group (a single pass) at least a second
                    // apart: nearby slices see the sphere from one place.
                    let near = |p: usize| {
                        let o = &self.cands[p];
                        o.group == c.group
                            && (o.centre.time.0 - c.centre.time.0).abs() < 1_000_000_000
                    };
                    if c.excluded
                        || pick[..s].iter().any(|&p| near(p))
                        || (s == 0 && must.is_some_and(|m| c.sphere != m))
                        || (s == 2
                            && spheres >= 2
                            && pick[..2].iter().all(|&p| self.cands[p].sphere == c.sphere)
                            && self.cands[pick[0]].sphere == self.cands[pick[1]].sphere)
                    {
                        continue;
                    }
                    pick[s] = k;
                    found = true;
                    break;
                }
                if !found {
                    ok = false;
                    break;
                }
            }
            if !ok {
                continue;
            }
            let Some(b) = self.fit(&pick, *start, false) else {
                continue;
            };
            let (score, per) = self.score(&b);
            if best.is_none_or(|(_, s, _)| score > s) {
                best = Some((b, score, per));
                // Enough hypotheses for 99 % confidence of one all-inlier sample at the
                // share of slices this one explains.
                let w = (score / live as f64).clamp(1e-3, 1.0);
                let need = libm::log(0.01) / libm::log(1.0 - w * w * w).min(-1e-12);
                budget = (need as usize)
                    .clamp(self.settings.min_hypotheses, self.settings.max_hypotheses);
            }
        }
        let (mut b, mut score, mut per) = best?;
        // Refine on the inliers, reassigned each time.
        for _ in 0..4 {
            let m = self.assign(&b, scratch);
            let Some(nb) = self.fit(&scratch[..m], b, true) else {
                break;
            };
            let (s, p) = self.score(&nb);
            if s < score {
                break;
            }
            (b, score, per) = (nb, s, p);
        }
        Some((b, score, per))
    }
}

/// The consensus over `cands` (grouped by (sphere, slice)) from `start`: the mounting, the
/// chosen candidates (marked), per-sphere support and the first ambiguity. `scratch` holds
/// candidate indices (as long as `cands`). `None` without three candidates.
pub fn consensus(
    search: &mut Search<'_>,
    start: &[f64; P],
    scratch: &mut [usize],
) -> Option<Consensus> {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut tried = 0;
    for c in search.cands.iter_mut() {
        c.excluded = false;
        c.chosen = false;
    }
    let (b, score, support) = search.ransac(start, None, &mut rng, scratch, &mut tried)?;
    let m = search.assign(&b, scratch);
    let mut slices = [0u32; MAX_TARGETS];
    let mut last: Option<(u8, u32)> = None;
    for c in search.cands.iter() {
        if last != Some((c.sphere, c.slice)) {
            slices[usize::from(c.sphere) % MAX_TARGETS] += 1;
            last = Some((c.sphere, c.slice));
        }
    }
    let mount = Params(b).mount();
    let mut s2 = 0.0;
    for &k in &scratch[..m] {
        let c = &mut search.cands[k];
        c.chosen = true;
        let t = &search.targets[usize::from(c.sphere)];
        s2 += (c.centre.georef_dt(&mount, search.time.at(&c.centre)) - t.center).norm_squared();
    }
    let mut out = Consensus {
        b,
        score,
        support,
        slices,
        rms: libm::sqrt(s2 / m.max(1) as f64),
        hypotheses: 0,
        ambiguous: None,
    };
    // Per sphere: the best mounting without its chosen candidates.
    for j in 0..search.targets.len().min(MAX_TARGETS) {
        if support[j] < 3 {
            continue;
        }
        for c in search.cands.iter_mut() {
            c.excluded = c.chosen && usize::from(c.sphere) == j;
        }
        let alt = search.ransac(start, Some(j as u8), &mut rng, scratch, &mut tried);
        if let Some((ab, ascore, aper)) = alt {
            let s = &search.settings;
            if ascore >= s.ambiguity * score
                && f64::from(aper[j]) >= s.ambiguity * f64::from(support[j])
            {
                let alt_mean = search.mean_detected(&ab, j, false, scratch);
                for c in search.cands.iter_mut() {
                    c.excluded = false;
                }
                let best_mean = search.mean_detected(&b, j, true, scratch);
                let d = alt_mean - best_mean;
                out.ambiguous = Some(Ambiguity {
                    sphere: j,
                    support: [support[j], aper[j]],
                    score: [score, ascore],
                    offset: [d.x, d.y, d.z],
                });
                break;
            }
        }
    }
    for c in search.cands.iter_mut() {
        c.excluded = false;
    }
    out.hypotheses = tried;
    Some(out)
}

#[cfg(test)]
mod tests;

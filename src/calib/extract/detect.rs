//! One slice's detection: votes, peaks, refinement, scoring and acceptance ([`detect`],
//! [`detect_all`] for the first round's candidates), and the returns kept around it ([`keep`]).

use super::score::{plane_vs_sphere, refine, seen_through, support, Key, Sorted};
use super::vote::{Grid, Peaks};
use super::{dot, norm, sub, Detection, Directions, ExtractSettings, ReturnClass, V3};
use crate::align::window::Observation;
use crate::calib::noise::Noise;

/// Detect the sphere of radius `r` in one slice (observations georeferenced by
/// [`georeference`]). `prior`: the centre must lie within this distance of the surveyed one
/// (`None`: anywhere, with the shape test). `grid` is scratch for the votes (all zero on entry
/// and on return; 64^3 cells are plenty); `keys` is scratch for the votes' cells, then the
/// slice's index by x (at least as long as the slice; a longer slice is searched in its first
/// `keys.len()` returns).
#[allow(clippy::too_many_arguments)]
pub fn detect(
    obs: &[Observation],
    keys: &mut [Key],
    r: f64,
    tau: f64,
    prior: Option<f64>,
    grid: &mut [u16],
    dirs: &Directions,
    st: &ExtractSettings,
) -> Option<Detection> {
    let mut all = Candidates::new();
    detect_all(obs, keys, r, tau, prior, grid, dirs, st, 1, &mut all);
    all.first().copied()
}

/// Most sphere-like candidates [`detect_all`] returns per slice.
pub const MAX_CANDIDATES: usize = 4;

/// A slice's accepted candidates, best first.
pub type Candidates = heapless::Vec<Detection, MAX_CANDIDATES>;

/// As [`detect`], the `most` best acceptable candidates into `out` (best score first, at most
/// [`MAX_CANDIDATES`], centres at least a radius apart): a slice can hold the sphere and things
/// that look like it (a buoy, a fender, a bollard's cap seen by one scan line), which only the
/// consensus across slices, passes and spheres tells apart ([`super::consensus`]).
#[allow(clippy::too_many_arguments)]
pub fn detect_all(
    obs: &[Observation],
    keys: &mut [Key],
    r: f64,
    tau: f64,
    prior: Option<f64>,
    grid: &mut [u16],
    dirs: &Directions,
    st: &ExtractSettings,
    most: usize,
    out: &mut Candidates,
) {
    const K: usize = 16;
    out.clear();
    let most = most.clamp(1, MAX_CANDIDATES);
    let r = r as f32;
    let tau = tau as f32;
    let prior = prior.map(|p| p as f32);
    // Voters: returns on scan-line segments no longer than the sphere (a plane's long
    // segments would bury its peak), within reach of the prior.
    let run_max = 2.0 * r + 2.0 * tau + 0.05;
    let voter = |o: &Observation| {
        o.work.run <= run_max
            && match prior {
                Some(p) => o.work.x.iter().all(|v| v.abs() <= p + 2.0 * r),
                None => true,
            }
    };
    let need = if prior.is_some() {
        st.min_inliers_prior
    } else {
        st.min_inliers
    };
    let Some(g) = region(obs, &voter, r, prior, need, grid.len()) else {
        return;
    };
    // A slice longer than the index is searched in its first `keys.len()` returns.
    let obs = &obs[..obs.len().min(keys.len())];
    let peaks = vote::<K>(obs, &voter, &g, grid, dirs, r, keys);
    // Indexed by x, the returns near a candidate are a contiguous run of the index.
    let sorted = Sorted::new(obs, keys);
    // Refine and score the strongest peaks; keep the best acceptable one.
    let mut order: [usize; K] = core::array::from_fn(|i| i);
    order.sort_unstable_by(|&a, &b| peaks.count[b].cmp(&peaks.count[a]));
    // With a prior, the surveyed centre itself is the first candidate (refined within a
    // narrow band: the stand's returns are near); then the peaks (from a cell's precision).
    let first = prior.map(|_| ([0f32; 3], (2.0 * tau).max(0.01)));
    let cands = first.into_iter().chain(
        order
            .iter()
            .take(st.peaks.min(K))
            .filter(|&&i| peaks.cell[i] != u32::MAX && usize::from(peaks.count[i]) >= need / 2)
            .map(|&i| (g.center(peaks.at[i]), (1.5 * g.h).max(2.0 * tau))),
    );
    for (c0, band) in cands {
        let c1 = refine(&sorted, c0, r, band);
        let c = refine(&sorted, c1, r, tau.max(0.01));
        if let Some(p) = prior {
            if norm(c) > p {
                continue;
            }
        }
        let s = support(&sorted, c, r, tau);
        let score = s.weight
            - st.violation_weight * s.violations as f32
            - st.collar_weight * s.collar as f32;
        // A candidate as good as one already accepted within a radius of it adds nothing.
        let beaten = |c: [f32; 3], score: f32| {
            out.iter()
                .any(|d| norm(sub(d.center, c)) < r && d.score >= score)
        };
        // Only what could still enter the list gets the costlier tests below.
        let full = out.len() >= most && out.last().is_some_and(|w| score <= w.score);
        if (s.inliers as usize) < need
            || s.violations as f32 > 0.25 * s.inliers as f32 + 2.0
            || score <= 0.0
            || full
            || beaten(c, score)
        {
            continue;
        }
        if prior.is_none() {
            // Without a prior the cap must be curved like the sphere: a plane must fit it
            // clearly worse.
            let (sph, pl) = plane_vs_sphere(&sorted, c, r, tau);
            if pl < 1.5 * sph || pl < 0.004 {
                continue;
            }
        }
        // Last, the beams that pass through it to returns behind (a scan of the slice).
        let through = seen_through(obs, c, r, tau);
        let violations = s.violations + through;
        let score = score - st.violation_weight * through as f32;
        if violations as f32 > 0.25 * s.inliers as f32 + 2.0 || score <= 0.0 {
            continue;
        }
        if beaten(c, score) {
            continue;
        }
        out.retain(|d| norm(sub(d.center, c)) >= r);
        let d = Detection {
            center: c,
            inliers: s.inliers,
            score,
            violations,
        };
        let at = out.partition_point(|o| o.score >= score);
        if out.len() >= most {
            if at >= out.len() {
                continue;
            }
            out.pop();
        }
        let _ = out.insert(at, d);
    }
}

/// The voting grid over the region the centre may be in: the voters' reach (and the prior's);
/// `None` without enough voters and no prior, or an empty region.
fn region(
    obs: &[Observation],
    voter: &impl Fn(&Observation) -> bool,
    r: f32,
    prior: Option<f32>,
    need: usize,
    cells: usize,
) -> Option<Grid> {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    let mut voters = 0;
    for o in obs.iter().filter(|o| voter(o)) {
        voters += 1;
        for a in 0..3 {
            lo[a] = lo[a].min(o.work.x[a] - r);
            hi[a] = hi[a].max(o.work.x[a] + r);
        }
    }
    // With a prior the surveyed centre is tested whatever the votes: a sphere resting on
    // the ground joins it in one long scan-line segment and has no voters.
    if voters < need && prior.is_none() {
        return None;
    }
    if let Some(p) = prior {
        for a in 0..3 {
            lo[a] = lo[a].max(-p - r);
            hi[a] = hi[a].min(p + r);
            if voters == 0 {
                (lo[a], hi[a]) = (-p - r, p + r);
            }
        }
    }
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0f32, f32::max);
    if !extent.is_finite() || extent <= 0.0 {
        return None;
    }
    let nmax = (libm::cbrt(cells as f64) as u32).max(1);
    let h = (0.5 * r).max(extent / nmax as f32);
    let mut dims = [1u32; 3];
    for a in 0..3 {
        dims[a] = (((hi[a] - lo[a]) / h) as u32 + 1).min(nmax);
    }
    Some(Grid { lo, h, dims })
}

/// Vote every voter's possible centres (a radius behind it along each direction facing its
/// beam); then, per vote in the same order, read the cell (its first reader sees its full
/// count: the peaks) and take the vote back (the grid is left all zero). The votes' cells are
/// noted in `noted` (scratch) as they are cast, and read back from there when they all fit.
fn vote<const K: usize>(
    obs: &[Observation],
    voter: &impl Fn(&Observation) -> bool,
    g: &Grid,
    grid: &mut [u16],
    dirs: &Directions,
    r: f32,
    noted: &mut [Key],
) -> Peaks<K> {
    let mut peaks = Peaks::<K>::new(g.dims);
    let mut min = 0u16;
    let mut cast = 0usize;
    each_vote(obs, voter, g, dirs, r, |k| {
        let cell = &mut grid[k as usize];
        *cell = cell.wrapping_add(1);
        if let Some(n) = noted.get_mut(cast) {
            n.i = k;
        }
        cast += 1;
    });
    let mut take_back = |k: u32| {
        let cell = &mut grid[k as usize];
        peaks.offer(k, *cell, &mut min);
        *cell = cell.wrapping_sub(1);
    };
    if cast <= noted.len() {
        noted[..cast].iter().for_each(|n| take_back(n.i));
    } else {
        each_vote(obs, voter, g, dirs, r, take_back);
    }
    peaks
}

/// Each vote's cell, voter by voter, direction by direction.
#[inline]
fn each_vote(
    obs: &[Observation],
    voter: &impl Fn(&Observation) -> bool,
    g: &Grid,
    dirs: &Directions,
    r: f32,
    mut cast: impl FnMut(u32),
) {
    for o in obs.iter().filter(|o| voter(o)) {
        let (x, u) = (o.work.x, o.work.u);
        for d in &dirs.0 {
            if dot(*d, u) <= 0.0 {
                continue;
            }
            let c = [x[0] + r * d[0], x[1] + r * d[1], x[2] + r * d[2]];
            if let Some(k) = g.index(c) {
                cast(k);
            }
        }
    }
}

/// Tag the observations of a slice against a sphere of radius `r` centred at `c` (relative):
/// `Kept` within `tau` of its surface on the visible side, `Hidden` within `tau` on the far
/// side, `OutsideShell` otherwise. Returns the number kept. A return whose trajectory is known
/// to be noisier than the noise model's (its own INS sigmas, [`Noise::inflation`]) gets a shell
/// wider by as much.
pub fn keep(obs: &mut [Observation], c: V3, r: f64, tau: f64, noise: &Noise) -> usize {
    let (r, tau0) = (r as f32, tau as f32);
    let mut n = 0;
    for o in obs.iter_mut() {
        let tau = if o.ins_sigma == [0.0; 2] {
            tau0
        } else {
            tau0 * noise.inflation(o) as f32
        };
        let d = sub(o.work.x, c);
        let dist = norm(d);
        let e = dist - r;
        o.work.verdict = if e.abs() <= tau {
            // Grazing returns with noise may sit slightly beyond the silhouette.
            if dot(d, o.work.u) <= tau.max(0.25 * dist) {
                n += 1;
                ReturnClass::Kept
            } else {
                ReturnClass::Hidden
            }
        } else {
            ReturnClass::OutsideShell
        } as u8;
    }
    n
}

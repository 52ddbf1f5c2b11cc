//! The whole solve: the spheres' returns found among the clutter ([`super::extract`]), the
//! detect-and-solve rounds (argmin-shaped, with an [`Observe`] hook), the
//! last extraction and least squares, the checks that refuse what the data cannot support
//! ([`Refusal`]). Parts: `settings`, `outcome` (the results), `passes`, `rounds`, `checks`, `workspace` (the
//! lent scratch and its second worker).
//! The method and its limits: docs/extraction.md, section 2.

use super::consensus::Bounds;
use super::extract::{self, time_order, ExtractSettings, ReturnClass};
use super::footprint::Footprint;
use super::fork::Fork;
use super::noise::Noise;
use super::objective::{Problem, SphereObs, TimeOffset};
use super::room::Room;
use super::sphere_fit::fit_center;
use crate::align::window::{Observation, Target, MAX_TARGETS};
use crate::georef::{Mount, Params, P};
use crate::time::GpsTime;
use core::ops::Range;
use nalgebra::Vector3;

mod checks;
mod consistency;
mod first;
mod last;
mod outcome;
mod passes;
mod restart;
mod rounds;
mod settings;
mod workspace;

use checks::{checks, clock_checks, lost_reasons};
pub use outcome::{
    Lost, PassReport, Refusal, Round, SecondStart, SetAside, Solution, SphereReport, Termination,
    Unfinished, TERMINATIONS,
};
use passes::PassFinder;
pub use rounds::Observe;
use rounds::{run_rounds, Data, Rounds};
pub use settings::{ClockFacts, InsStep, Settings, UntrustedLidar};
#[cfg(test)]
use workspace::TinyScratch;
use workspace::{groups, halves, side_by_side, Lane};
pub use workspace::{Helper, Workspace};

/// Most passes (sightings of a sphere) reported per solve; later ones are added to the last.
pub const MAX_PASSES: usize = 128;

/// Counts of windowed returns by [`ReturnClass`] (indexed by its number).
pub type Tally = [u32; 8];

/// How a problem's residuals are formed: weighted or not, corrected by the footprint's bloom or
/// not ([`Problem::weights`], [`Problem::footprint`]).
#[derive(Debug, Clone, Copy)]
struct Residuals {
    weights: Option<Noise>,
    footprint: Option<Footprint>,
}

impl Residuals {
    /// Unweighted distances from the spheres (the simplex, the shells' medians).
    const PLAIN: Residuals = Residuals {
        weights: None,
        footprint: None,
    };

    /// The least squares' residuals: weighted by `weights`, the settings' footprint out.
    fn fitted(weights: Option<Noise>, s: &Settings) -> Self {
        Self {
            weights,
            footprint: s.footprint,
        }
    }
}

fn with_problem<R>(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    stride: usize,
    time: TimeOffset,
    model: Residuals,
    f: impl FnOnce(&Problem<'_>) -> R,
) -> R {
    let mut spheres: heapless::Vec<SphereObs<'_>, MAX_TARGETS> = heapless::Vec::new();
    for (j, t) in targets.iter().enumerate().take(MAX_TARGETS) {
        let _ = spheres.push(SphereObs {
            target: *t,
            obs: &obs[j][..used[j]],
        });
    }
    f(&Problem {
        spheres: &spheres,
        stride,
        dt: time.dt,
        drift: time.drift,
        t_ref: time.t_ref,
        weights: model.weights,
        footprint: model.footprint,
    })
}

/// Signed residual of one observation.
fn residual(o: &Observation, t: &Target, b: &[f64; P], time: &TimeOffset) -> f64 {
    let m = Mount::from_params(&Params(*b));
    (o.georef_dt(&m, time.at(o)) - t.center).norm() - t.radius
}

/// A sphere's centre fitted (radius fixed) to returns with a mounting and time offset, minus
/// the surveyed one: (offset, `J^T J`, residual RMS, count); `None` with fewer than 10 returns
/// or a singular geometry.
fn fit_with_covariance<'a>(
    obs: impl Iterator<Item = &'a Observation> + Clone,
    mount: &Mount,
    time: &TimeOffset,
    t: &Target,
) -> Option<(Vector3<f64>, nalgebra::Matrix3<f64>, f64, usize)> {
    let pts = obs.map(|o| o.georef_dt(mount, time.at(o)));
    if pts.clone().count() < 10 {
        return None;
    }
    let c = fit_center(pts.clone(), t.radius, t.center)?;
    let (mut jtj, mut e2, mut n) = (nalgebra::Matrix3::zeros(), 0.0, 0usize);
    for x in pts {
        let dv = x - c;
        let norm = dv.norm();
        if norm == 0.0 {
            continue;
        }
        let g = dv / norm;
        jtj += g * g.transpose();
        e2 += (norm - t.radius) * (norm - t.radius);
        n += 1;
    }
    Some((c - t.center, jtj, libm::sqrt(e2 / n.max(1) as f64), n))
}

/// Move the kept observations to the front in time order (the others follow in no particular
/// order); returns how many are kept.
fn partition(v: &mut [Observation]) -> usize {
    let mut k = 0;
    for i in 0..v.len() {
        if v[i].work.verdict == ReturnClass::Kept as u8 {
            v.swap(i, k);
            k += 1;
        }
    }
    v[..k].sort_unstable_by_key(time_order);
    k
}

/// The fingerprint of a kept set.
fn fingerprint(h: u64, v: &[Observation]) -> u64 {
    let mut h = h;
    for o in v {
        h = (h ^ o.time.0 as u64 ^ (u64::from(o.channel) << 56)).wrapping_mul(0x100_0000_01b3);
    }
    (h ^ v.len() as u64).wrapping_mul(0x100_0000_01b3)
}

/// Copy the kept returns of every sphere into `room` (at most what it has, evenly spread when
/// they do not fit); returns the room used and each sphere's range in it.
fn gather<'b>(
    obs: &[&mut [Observation]],
    active: &[usize],
    kept: &[usize],
    room: &'b mut dyn Room<Observation>,
) -> (&'b mut [Observation], [Range<usize>; MAX_TARGETS]) {
    let total: usize = kept.iter().sum();
    let buf = room.room(total);
    let stride = total.div_ceil(buf.len().max(1)).max(1);
    let mut out: [Range<usize>; MAX_TARGETS] = core::array::from_fn(|_| 0..0);
    let mut w = 0;
    for (j, v) in obs.iter().enumerate().take(MAX_TARGETS) {
        let start = w;
        let kept = v[..active[j]]
            .iter()
            .filter(|o| o.work.verdict == ReturnClass::Kept as u8);
        for (k, o) in kept.enumerate() {
            if k.is_multiple_of(stride) && w < buf.len() {
                buf[w] = *o;
                w += 1;
            }
        }
        out[j] = start..w;
    }
    (buf, out)
}

/// The rule for the returns still taking part in the rounds at prior radius `prior` and shell
/// `tau`: within a few prior radii of the sphere's surface, at least half a metre.
fn reach(prior: f64, tau: f64) -> f64 {
    (4.0 * prior).max(0.5) + tau
}

/// Each sphere's windowed returns made ready once ([`extract::prepare`]: in time order, the
/// scan-line segments, whose lengths do not depend on the mounting, and the slices),
/// georeferenced with the start `b0`, unclassified; the passes over each sphere, and the
/// nearest return's range [m]. Two groups of spheres side by side with a helper.
fn prepare(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    b0: &Params,
    st: &ExtractSettings,
    ws: &Workspace<'_>,
) -> (heapless::Vec<PassReport, MAX_PASSES>, f64) {
    let mount0 = Mount::from_params(b0);
    let slices = ws.keys.len();
    // The spheres from `first` on: their passes appended to `out`, the nearest range.
    let group = |first: usize,
                 obs: &mut [&mut [Observation]],
                 out: &mut heapless::Vec<PassReport, MAX_PASSES>| {
        let mut near = f32::INFINITY;
        for (j, (v, t)) in obs
            .iter_mut()
            .zip(targets.get(first..).unwrap_or(&[]))
            .enumerate()
        {
            let mut finder = PassFinder::new(first + j, st.pass_gap_ns, st.pass_min_ns, out);
            near = near.min(extract::prepare(v, t, &mount0, st, slices, |o| {
                finder.see(o)
            }));
            finder.finish();
        }
        near
    };
    let mut passes = heapless::Vec::new();
    let near = match ws.helper.as_ref() {
        None => group(0, obs, &mut passes),
        Some(h) => prepare_beside(h.fork, obs, st, &mut passes, &group),
    };
    (passes, f64::from(near))
}

/// [`prepare`]'s work on the spheres from a first one: their passes appended, the nearest range.
type PrepareGroup<'g> = dyn Fn(usize, &mut [&mut [Observation]], &mut Passes) -> f32 + Sync + 'g;

/// The passes over every sphere.
type Passes = heapless::Vec<PassReport, MAX_PASSES>;

/// [`prepare`]'s `group` over two groups of spheres side by side, the second's passes after
/// the first's (found again after them when both do not fit: as one worker finds them).
#[inline(never)]
fn prepare_beside(
    fork: &dyn Fork,
    obs: &mut [&mut [Observation]],
    st: &ExtractSettings,
    passes: &mut heapless::Vec<PassReport, MAX_PASSES>,
    group: &PrepareGroup<'_>,
) -> f32 {
    let lens: heapless::Vec<usize, MAX_TARGETS> = obs.iter().map(|v| v.len()).collect();
    let k = halves(&lens);
    let (oa, ob) = obs.split_at_mut(k);
    let mut theirs = heapless::Vec::<PassReport, MAX_PASSES>::new();
    let (mut na, mut nb) = (f32::INFINITY, f32::INFINITY);
    fork.join(&mut || na = group(0, oa, passes), &mut || {
        nb = group(k, ob, &mut theirs)
    });
    if passes.len() + theirs.len() <= MAX_PASSES {
        passes.extend(theirs);
    } else {
        for (j, v) in ob.iter().enumerate() {
            let mut finder = PassFinder::new(k + j, st.pass_gap_ns, st.pass_min_ns, passes);
            v.iter().for_each(|o| finder.see(o));
            finder.finish();
        }
    }
    na.min(nb)
}

/// `buf` cut at the ends of consecutive `ranges` (the first starting at 0): one slice each.
fn split_ranges<'b>(
    buf: &'b mut [Observation],
    ranges: &[Range<usize>],
) -> heapless::Vec<&'b mut [Observation], MAX_TARGETS> {
    let mut part = heapless::Vec::new();
    let mut rest = buf;
    let mut pos = 0;
    for r in ranges {
        let (head, tail) = core::mem::take(&mut rest).split_at_mut(r.end - pos);
        let _ = part.push(head);
        rest = tail;
        pos = r.end;
    }
    part
}

/// Solve from `b0` with every sphere's windowed returns (reordered in place: the
/// kept ones first, in time order; each tagged with its [`ReturnClass`]).
pub fn solve(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    b0: &Params,
    s: &Settings,
    ws: &mut Workspace<'_>,
) -> Solution {
    solve_watched(targets, obs, b0, s, ws, &mut ())
}

/// [`solve`], telling `watch` of every round and of how the rounds ended.
pub fn solve_watched(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    b0: &Params,
    s: &Settings,
    ws: &mut Workspace<'_>,
    watch: &mut impl Observe,
) -> Solution {
    let mut sol = solve_data(targets, obs, b0, s, ws, watch);
    sol.refusal = clock_checks(s, &sol, sol.refusal);
    sol
}

/// [`solve_watched`] on the returns alone (the clocks' checks follow).
fn solve_data(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    b0: &Params,
    s: &Settings,
    ws: &mut Workspace<'_>,
    watch: &mut impl Observe,
) -> Solution {
    let n = targets.len().min(obs.len()).min(MAX_TARGETS);
    let targets = &targets[..n];
    let obs = &mut obs[..n];
    let mut windowed = [0usize; MAX_TARGETS];
    for j in 0..n {
        windowed[j] = obs[j].len();
    }
    let (mut passes, near) = prepare(targets, obs, b0, &s.extract, ws);
    let bounds = bounds(near, b0, s.margin);
    if n < 2 {
        let mut sol = Solution::start(b0, s.extract.tau0);
        sol.bounds = bounds;
        sol.refusal = Some(Refusal::TooFewTargets { given: n });
        return sol;
    }
    // 1. Rounds: detect and keep, solve, tighten, until the kept sets stop changing.
    let t_ref = middle_time(obs);
    let mut r = Rounds::init(b0, windowed, s.extract.tau0, bounds, t_ref);
    // `prepare` georeferenced every return at `b0` with no time offset, as the first round
    // would.
    r.placed = true;
    let mut d = Data {
        targets,
        obs,
        s,
        ws,
    };
    run_rounds(&mut d, &passes, &mut r, watch);
    let (mut second, mut unsettled) = (None, None);
    if s.second_start && r.stopped().is_none() && (0..n).any(|j| windowed[j] > 0 && r.kept[j] == 0)
    {
        let (both, why) = restart::second_start(&mut d, &passes, &mut r, b0, windowed, watch);
        (second, unsettled) = (Some(both), why);
    }
    let mut sol = Solution::from_rounds(&r, b0);
    sol.second_start = second;
    if let Some(end) = r.stopped().or(unsettled) {
        // The rounds could not go on (ambiguous spheres or a mounting out of bounds), or
        // neither start settled.
        let none = [0usize; MAX_TARGETS];
        let per = PerSphere {
            windowed: &windowed,
            used: &none,
            rounds_kept: &r.kept,
            tallies: &[[0; 8]; MAX_TARGETS],
            counts: &r.counts,
        };
        sphere_reports(targets, obs, &per, b0, &r.time, &mut sol);
        for (j, sp) in sol.spheres.iter_mut().enumerate() {
            sp.agreed = r
                .consensus
                .map_or(0, |c| c.support.get(j).copied().unwrap_or(0));
            sp.lost = Some(Lost::Stopped);
        }
        sol.passes = passes;
        sol.refusal = Some(end);
        return sol;
    }
    // 2. The last extraction, around the surveyed spheres.
    let (mut used, mut tallies) = r.last_extraction(&mut d, &mut passes);
    let found = (0..n).filter(|&j| used[j] > 0).count();
    // 3. Least squares on the kept returns: the answer and its uncertainty.
    r.final_fit(&mut d, &used[..n], found, &mut sol);
    if found >= 2 {
        let mut k = last::Kept {
            used: &mut used,
            tallies: &mut tallies,
            passes: &mut passes,
            found,
        };
        r.set_aside_misfit_pieces(&mut d, &mut k, &mut sol);
        r.set_aside_influential(&mut d, &mut k, &mut sol);
    }
    sol.passes = passes;
    let obs = &mut *d.obs;
    // 4. Per sphere.
    let per = PerSphere {
        windowed: &windowed,
        used: &used,
        rounds_kept: &r.kept,
        tallies: &tallies,
        counts: &r.counts,
    };
    sphere_reports(targets, obs, &per, b0, &r.time, &mut sol);
    lost_reasons(s, &mut sol);
    // 5. Checks.
    if found < 2 {
        sol.refusal = Some(Refusal::TooFewSpheres { have: found });
        return sol;
    }
    sol.refusal = checks(targets, obs, &used[..n], s, &mut sol);
    sol
}

/// The box the mounting must stay in: each lever-arm component within `margin` of the start
/// (a larger error would leave the spheres outside windows made with that margin), each angle
/// within the angle that moves the nearest windowed return (`near` [m], at least 1 m away) by
/// twice the margin, between 5 and 45 deg.
fn bounds(near: f64, b0: &Params, margin: f64) -> Bounds {
    if !(margin.is_finite() && margin > 0.0) {
        return Bounds::none(b0);
    }
    let near = near.max(1.0);
    let angle = if near.is_finite() {
        libm::atan(2.0 * margin / near)
    } else {
        core::f64::consts::FRAC_PI_4
    };
    Bounds {
        start: b0.0,
        angle: angle.clamp(5f64.to_radians(), 45f64.to_radians()),
        lever: margin,
    }
}

/// The middle of the windowed returns' times (the time offset's reference: its drift then
/// barely correlates with it); each sphere's returns in time order.
fn middle_time(obs: &[&mut [Observation]]) -> GpsTime {
    let (mut lo, mut hi) = (i64::MAX, i64::MIN);
    for v in obs {
        if let (Some(a), Some(b)) = (v.first(), v.last()) {
            lo = lo.min(a.time.0);
            hi = hi.max(b.time.0);
        }
    }
    if lo > hi {
        GpsTime(0)
    } else {
        GpsTime(lo + (hi - lo) / 2)
    }
}

/// Per-sphere counts gathered on the way to the answer.
struct PerSphere<'a> {
    windowed: &'a [usize; MAX_TARGETS],
    used: &'a [usize; MAX_TARGETS],
    rounds_kept: &'a [usize; MAX_TARGETS],
    tallies: &'a [[u32; 8]; MAX_TARGETS],
    counts: &'a [(u32, u32); MAX_TARGETS],
}

/// Each sphere's report (residual RMS at the start and at the answer, its centre fitted with
/// the answer) and the RMS of the centre offsets.
fn sphere_reports(
    targets: &[Target],
    obs: &[&mut [Observation]],
    per: &PerSphere<'_>,
    b0: &Params,
    time: &TimeOffset,
    sol: &mut Solution,
) {
    let mount = sol.b.mount();
    let (mut c2, mut nc) = (0.0, 0);
    for (j, t) in targets.iter().enumerate() {
        let kept = &obs[j][..per.used[j]];
        let rms = |bb: &[f64; P]| {
            let s2: f64 = kept
                .iter()
                .map(|o| libm::pow(residual(o, t, bb, time), 2.0))
                .sum();
            libm::sqrt(s2 / kept.len().max(1) as f64)
        };
        let center = fit_center(
            kept.iter().map(|o| o.georef_dt(&mount, time.at(o))),
            t.radius,
            t.center,
        )
        .map(|c| c - t.center);
        if let Some(d) = center {
            c2 += d.norm_squared();
            nc += 1;
        }
        let _ = sol.spheres.push(SphereReport {
            windowed: per.windowed[j],
            used: per.used[j],
            rounds_kept: per.rounds_kept[j],
            found: per.used[j] > 0,
            slices: per.counts[j].0,
            detected: per.counts[j].1,
            verdicts: per.tallies[j],
            rms_before: rms(&b0.0),
            rms_after: rms(&sol.b.0),
            center_offset: center,
            agreed: 0,
            lost: None,
        });
    }
    sol.center_rms = (nc > 0).then(|| libm::sqrt(c2 / nc as f64));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_split_the_returns_evenly() {
        assert_eq!(halves(&[10, 10]), 1);
        assert_eq!(halves(&[1, 100]), 1);
        assert_eq!(halves(&[100, 1, 1]), 1);
        assert_eq!(halves(&[1, 1, 100]), 2);
        assert_eq!(halves(&[3, 3, 3, 3]), 2);
        assert_eq!(halves(&[5]), 1);
        assert_eq!(halves(&[]), 0);
    }

    /// Returns 30 s apart (each a pass of its own: the gap is over 20 s), from `t0` [s].
    fn sightings(t0: i64) -> [Observation; 100] {
        core::array::from_fn(|i| Observation {
            time: GpsTime((t0 + 30 * i as i64) * 1_000_000_000),
            range: 10.0,
            velocity: nalgebra::Vector3::new(1.0, 0.0, 0.0),
            ..Observation::default()
        })
    }

    /// The passes a helper's two groups find are one worker's, those of the second group found
    /// again when both do not fit (200 passes against 128).
    #[test]
    fn the_passes_of_two_groups_are_one_workers() {
        let t = Target {
            center: Vector3::zeros(),
            radius: 0.2,
        };
        let st = ExtractSettings::default();
        let b0 = Params([0.0; P]);
        for n in [10usize, 100] {
            let run = |helped: bool| {
                let (mut a, mut b) = (sightings(0), sightings(1));
                let mut obs: [&mut [Observation]; 2] = [&mut a[..n], &mut b[..n]];
                let mut scratch = TinyScratch::new();
                let ws = scratch.workspace(helped);
                prepare(&[t, t], &mut obs, &b0, &st, &ws)
            };
            let (one, two) = (run(false), run(true));
            assert_eq!(one, two, "{n} passes a sphere");
            let passes = &one.0;
            assert_eq!(passes.len(), (2 * n).min(MAX_PASSES));
            assert_eq!((passes[n - 1].sphere, passes[n].sphere), (0, 1));
            // Beyond the room the last pass takes the rest.
            let last = GpsTime((1 + 30 * (n as i64 - 1)) * 1_000_000_000);
            assert_eq!(passes.last().map(|p| p.end), Some(last));
        }
    }
}

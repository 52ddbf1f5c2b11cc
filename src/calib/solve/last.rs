//! After the rounds: the last extraction around the surveyed spheres and the final least
//! squares (the answer, its uncertainty, the held offset tested).

use super::checks::weights;
use super::outcome::{PassReport, Solution};
use super::passes::{pass_of, PassCursor};
use super::rounds::{Data, Rounds};
use super::settings::Settings;
use super::{groups, partition, side_by_side, with_problem, Helper, Lane, Residuals};
use crate::align::window::{Observation, Target, MAX_TARGETS};
use crate::calib::extract::{self, Directions, ReturnClass};
use crate::calib::lm::{refine, Clock};
use crate::calib::nav::{cut_in, refine as refine_nav, Piece};
use crate::calib::objective::{Linearised, Problem, TimeOffset};
use crate::calib::room::Room;
use crate::georef::{Mount, Params, P};
use crate::time::GpsTime;

impl Rounds {
    /// The last extraction: around the surveyed spheres, in the slices where the sphere is
    /// detected near them, attachments (a stand, a deck) rejected; spheres with too few returns
    /// are not found. Returns each sphere's kept count (the kept ones first in `obs`) and its
    /// verdict tallies; the passes get theirs.
    pub(super) fn last_extraction(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        passes: &mut [PassReport],
    ) -> ([usize; MAX_TARGETS], [[u32; 8]; MAX_TARGETS]) {
        let (targets, s) = (d.targets, d.s);
        let n = targets.len();
        let dirs = Directions::default();
        let noise = s.noise();
        let tau = self.tau;
        let last = LastExtraction {
            targets,
            s,
            mount: Mount::from_params(&Params(self.b)),
            time: self.time,
            how: extract::Extraction {
                tau,
                prior: Some(self.prior.unwrap_or(3.0 * tau).max(3.0 * tau)),
                surveyed: true,
                dirs: &dirs,
                settings: &s.extract,
                noise: &noise,
            },
        };
        let mut out = [Extracted::default(); MAX_TARGETS];
        let k = groups(d.ws, &self.active[..n]);
        let (oa, ob) = d.obs.split_at_mut(k);
        let (aa, ab) = self.active[..n].split_at(k);
        let (xa, xb) = out[..n].split_at_mut(k);
        let cut = passes.partition_point(|p| usize::from(p.sphere) < k);
        let (pa, pb) = passes.split_at_mut(cut);
        side_by_side(
            d.ws,
            |lane| last.spheres(0, oa, aa, xa, pa, lane),
            |lane| last.spheres(k, ob, ab, xb, pb, lane),
        );
        let mut used = [0usize; MAX_TARGETS];
        let mut tallies = [[0u32; 8]; MAX_TARGETS];
        for (j, x) in out.iter().enumerate().take(n) {
            self.counts[j] = x.counts;
            used[j] = x.used;
            tallies[j] = x.tally;
        }
        (used, tallies)
    }

    /// Least squares on the kept returns (with at least two spheres found); with the offset held,
    /// the same returns with it free test the held value. Sets the answer and eq. 6 at it.
    pub(super) fn final_fit(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        used: &[usize],
        found: usize,
        sol: &mut Solution,
    ) {
        let (targets, s, obs) = (d.targets, d.s, &*d.obs);
        let nav = &mut *d.ws.nav;
        let helper = &mut d.ws.helper;
        // Under the navigation model the weights are the white noise's, absolute (the priors
        // are in metres and radians).
        let w = match s.nav {
            Some(_) => Some(s.noise()),
            None => weights(obs, used, s),
        };
        let fit = |pb: &Problem<'_>,
                   b: &[f64; P],
                   iter: usize,
                   clock: Clock,
                   nav: &mut dyn Room<Piece>,
                   helper: &mut Option<Helper<'_>>| match &s.nav {
            Some(model) => {
                let m = cut_in(pb, model, nav);
                let (l, f) = refine_nav(
                    pb,
                    b,
                    model,
                    &s.centre_sigma,
                    &s.mount_prior,
                    nav.room(m),
                    helper.as_mut().map(Helper::split),
                    iter,
                    s.cluster_ns,
                    clock,
                );
                (l, Some(f))
            }
            None => (refine(pb, b, iter, s.cluster_ns, clock), None),
        };
        let fitted = Residuals::fitted(w, s);
        let lm = (found >= 2).then(|| {
            with_problem(targets, obs, used, 1, self.time, fitted, |pb| {
                fit(pb, &self.b, s.lm_iter, s.clock(), nav, helper)
            })
        });
        let lm = lm.map(|(l, f)| {
            sol.nav = f;
            l
        });
        if let Some(l) = &lm {
            self.b = l.b;
            self.time.dt = l.dt;
            self.time.drift = l.drift;
        }
        if let (false, Some(l)) = (s.estimate_dt, &lm) {
            // Where the data move the offset, and its sigma at the held solution (no iteration:
            // the motion model is first order in the offset, exact at the held value and not far
            // from it). The free fit need not converge: far from the truth it stalls on the way (a
            // 0.3 s error stops after 0.14 s, its own sigma inflated by the misfit), which is
            // evidence enough against the held value.
            let free_clock = Clock {
                dt: true,
                drift: s.estimate_drift,
            };
            let (free, at_held) = with_problem(targets, obs, used, 1, self.time, fitted, |pb| {
                (
                    fit(pb, &l.b, s.lm_iter, free_clock, nav, helper).0,
                    fit(pb, &l.b, 0, free_clock, nav, helper).0,
                )
            });
            let sigma = at_held.sigma_dt;
            if free.dt.is_finite() && sigma.is_finite() && sigma > 0.0 {
                sol.dt_free = Some((free.dt, sigma));
            }
        }
        sol.b = Params(self.b);
        sol.dt = self.time.dt;
        sol.drift = self.time.drift;
        sol.t_ref = self.time.t_ref;
        sol.lm = lm;
        sol.l1 = with_problem(targets, obs, used, 1, self.time, Residuals::PLAIN, |pb| {
            pb.l1(&self.b)
        });
    }

    /// Under the navigation model, a step between consecutive pieces beyond
    /// `max_nav_step_sigmas` that one piece's few returns alone make — a slice whose detection
    /// kept ground returns (from 60 m a grass sphere's slice can hold four that fit a free
    /// centre): that piece's kept returns are set aside and the fit made again, kept when then
    /// every step is within the limit. An INS that jumped moves every piece after the jump, so
    /// no one piece explains it: the step stays and is refused ([`Refusal::NavigationJump`]).
    /// At most three pieces of at most [`MISFIT_RETURNS`] returns each.
    pub(super) fn set_aside_misfit_pieces(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        k: &mut Kept<'_>,
        sol: &mut Solution,
    ) {
        for _ in 0..3 {
            let Some(f) = sol.nav.filter(|f| f.worst_step.0 > d.s.max_nav_step_sigmas) else {
                return;
            };
            let cut = &*d.ws.nav.room(f.pieces);
            let Some(i) = cut.iter().position(|p| p.start == f.worst_step.1) else {
                return;
            };
            let spans = [i.checked_sub(1), Some(i)].map(|i| i.map(|i| (cut[i].start, cut[i].end)));
            let mut done = false;
            for span in spans.into_iter().flatten() {
                let limit = d.s.max_nav_step_sigmas;
                let accepted = self.try_without(d, k, span, MISFIT_RETURNS, sol, |_, new, _| {
                    new.nav.is_some_and(|f| f.worst_step.0 <= limit)
                });
                if let Some(n) = accepted {
                    sol.set_aside.misfit_pieces.0 += n;
                    sol.set_aside.misfit_pieces.1 += 1;
                    done = true;
                    break;
                }
            }
            if !done {
                return;
            }
        }
    }

    /// An isolated stretch of few kept returns (at most [`INFLUENTIAL_RETURNS`], a 20th of
    /// all, with gaps of [`GAP_S`] either side: a turn, a far glimpse of a sphere) that is not
    /// the sphere: without it, its returns lie (median) beyond the shell from the spheres the
    /// rest put them on, and its removal moves a parameter (the six, the time offset) by more
    /// than `max_influence_sigmas` times what its information can move it by (under the model
    /// the change is the difference of two estimates, of variance `sigma_without^2 -
    /// sigma_with^2`; at least half `sigma_without`, the variance factor being found again).
    /// Three ground returns kept in a turn at 60 m made the time offset pay 12 sigma (0.5-0.7
    /// m off without them); a turn's real returns move it as much (5 sigma in a drone survey's
    /// turn: the model's time offset is optimistic there) but lie within the shell. Set aside,
    /// the fit without it kept. At most [`INFLUENCE_TRIES`] stretches refitted.
    pub(super) fn set_aside_influential(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        k: &mut Kept<'_>,
        sol: &mut Solution,
    ) {
        let n = d.targets.len();
        let total: usize = k.used[..n].iter().sum();
        let (mut t, mut tries) = (GpsTime(i64::MIN), 0);
        while tries < INFLUENCE_TRIES {
            // The next stretch: the kept returns (all spheres) from the first after `t` on,
            // until a gap of GAP_S.
            let obs = &*d.obs;
            let next = |after: GpsTime| {
                (0..n)
                    .filter_map(|j| {
                        let v = &obs[j][..k.used[j]];
                        v.get(v.partition_point(|o| o.time <= after))
                            .map(|o| o.time)
                    })
                    .min()
            };
            let Some(a) = next(t) else { return };
            let (mut b, mut count) = (a, 0usize);
            loop {
                count += (0..n)
                    .map(|j| {
                        let v = &obs[j][..k.used[j]];
                        v.partition_point(|o| o.time <= b) - v.partition_point(|o| o.time < b)
                    })
                    .sum::<usize>();
                match next(b) {
                    Some(c) if (c.0 - b.0) as f64 * 1e-9 <= GAP_S => b = c,
                    _ => break,
                }
            }
            t = b;
            if count > INFLUENTIAL_RETURNS || count * 20 > total {
                continue;
            }
            // Kept within the shell of the answer they helped make: the sphere's.
            let kept = ReturnClass::Kept as u8;
            let within =
                |_: usize, o: &Observation| o.work.verdict == kept && o.time >= a && o.time <= b;
            if self.off_sphere(d, within) <= self.tau {
                continue;
            }
            tries += 1;
            let (max, shell) = (d.s.max_influence_sigmas, self.tau);
            let accepted = self.try_without(
                d,
                k,
                (a, b),
                INFLUENTIAL_RETURNS,
                sol,
                |with, without, off| {
                    let (Some(w), Some(wo)) = (with.lm, without.lm) else {
                        return false;
                    };
                    if off <= shell {
                        return false;
                    }
                    let z = |x: f64, y: f64, sw: f64, swo: f64| {
                        let room = libm::sqrt((swo * swo - sw * sw).max(0.0)).max(0.5 * swo);
                        (x - y).abs() / room
                    };
                    let worst = (0..P)
                        .map(|i| z(w.b[i], wo.b[i], w.sigma[i], wo.sigma[i]))
                        .chain(
                            (w.sigma_dt > 0.0)
                                .then(|| z(with.dt, without.dt, w.sigma_dt, wo.sigma_dt)),
                        )
                        .fold(0.0, f64::max);
                    worst > max
                },
            );
            if let Some(m) = accepted {
                sol.set_aside.influential.0 += m;
                sol.set_aside.influential.1 += 1;
            }
        }
    }

    /// The fit again without the kept returns in `span` (all spheres; at most `most`, each
    /// sphere keeping `min_points`), kept when it converged and `better(before, after)`; else
    /// everything as it was. The returns set aside, if kept.
    fn try_without(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        k: &mut Kept<'_>,
        (a, b): (GpsTime, GpsTime),
        most: usize,
        sol: &mut Solution,
        better: impl Fn(&Solution, &Solution, f64) -> bool,
    ) -> Option<u32> {
        let (n, min_points) = (d.targets.len(), d.s.min_points);
        let obs = &mut *d.obs;
        // Each sphere's kept returns in the span: a run of its time-ordered kept ones.
        let runs: [(usize, usize); MAX_TARGETS] = core::array::from_fn(|j| {
            if j >= n {
                return (0, 0);
            }
            let v = &obs[j][..k.used[j]];
            let lo = v.partition_point(|o| o.time < a);
            (lo, lo + v[lo..].partition_point(|o| o.time <= b))
        });
        let total: usize = runs.iter().map(|(lo, hi)| hi - lo).sum();
        let enough = (0..n).all(|j| {
            let left = k.used[j] - (runs[j].1 - runs[j].0);
            k.used[j] == 0 || left >= min_points
        });
        if total == 0 || total > most || !enough {
            return None;
        }
        let mut moved: heapless::Vec<(usize, GpsTime, u8, u8), MOVED> = heapless::Vec::new();
        for j in 0..n {
            for o in &mut obs[j][runs[j].0..runs[j].1] {
                o.work.verdict = ReturnClass::Undetected as u8;
                let _ = moved.push((j, o.time, o.channel, o.block));
            }
            k.used[j] = partition(obs[j]);
        }
        let saved = (self.b, self.time, sol.clone());
        self.final_fit(d, &k.used[..n], k.found, sol);
        let off = self.off_sphere(d, |j, o| moved.contains(&(j, o.time, o.channel, o.block)));
        let ok = sol.lm.is_some_and(|l| l.converged) && better(&saved.2, sol, off);
        if ok {
            for &(j, t, _, _) in &moved {
                let kept = ReturnClass::Kept as usize;
                let undetected = ReturnClass::Undetected as usize;
                k.tallies[j][kept] = k.tallies[j][kept].saturating_sub(1);
                k.tallies[j][undetected] += 1;
                let lo = k.passes.partition_point(|p| usize::from(p.sphere) < j);
                let hi = k.passes.partition_point(|p| usize::from(p.sphere) <= j);
                if let Some(p) = pass_of(&mut k.passes[lo..hi], t) {
                    p.verdicts[kept] = p.verdicts[kept].saturating_sub(1);
                    p.verdicts[undetected] += 1;
                }
            }
            return Some(total as u32);
        }
        for (j, v) in d.obs.iter_mut().enumerate().take(n) {
            for o in v.iter_mut() {
                if moved.contains(&(j, o.time, o.channel, o.block)) {
                    o.work.verdict = ReturnClass::Kept as u8;
                }
            }
            k.used[j] = partition(v);
        }
        (self.b, self.time) = (saved.0, saved.1);
        *sol = saved.2;
        None
    }

    /// The median distance from their sphere of the returns `pick(sphere, return)` chooses
    /// at the current answer (at most [`MOVED`] of them), raw (no navigation correction: the
    /// shell is widened by the navigation's errors).
    fn off_sphere(&self, d: &Data<'_, '_, '_>, pick: impl Fn(usize, &Observation) -> bool) -> f64 {
        let lin = Linearised::at(&self.b).with_footprint(d.s.footprint);
        let mut r: heapless::Vec<f64, MOVED> = heapless::Vec::new();
        for (j, v) in d.obs.iter().enumerate().take(d.targets.len()) {
            for o in v.iter().filter(|o| pick(j, o)) {
                if let Some(row) = lin.row(o, &d.targets[j], self.time.at(o)) {
                    let _ = r.push(row.residual.abs());
                }
            }
        }
        r.sort_unstable_by(f64::total_cmp);
        r.get(r.len() / 2).copied().unwrap_or(0.0)
    }
}

/// The kept returns' bookkeeping the set-asides keep up to date: each sphere's kept count (the
/// kept ones first in its `obs`), its verdict tallies, the passes' and the spheres found.
pub(super) struct Kept<'a> {
    pub(super) used: &'a mut [usize; MAX_TARGETS],
    pub(super) tallies: &'a mut [[u32; 8]; MAX_TARGETS],
    pub(super) passes: &'a mut [PassReport],
    pub(super) found: usize,
}

/// Most returns one piece may hold for [`Rounds::set_aside_misfit_pieces`] to set it aside.
const MISFIT_RETURNS: usize = 8;
/// Most returns a stretch may hold for [`Rounds::set_aside_influential`] to test it.
const INFLUENTIAL_RETURNS: usize = 24;
/// Most stretches [`Rounds::set_aside_influential`] refits without.
const INFLUENCE_TRIES: usize = 8;
/// A stretch of kept returns ends at a gap of this many seconds.
const GAP_S: f64 = 2.0;
/// Room for the keys of the returns one set-aside moves (all of them: they are restored by it).
const MOVED: usize = 24;
const _: () = assert!(MISFIT_RETURNS <= MOVED && INFLUENTIAL_RETURNS <= MOVED);

/// One sphere's last extraction: its slices and detections, its kept returns, its verdicts.
#[derive(Debug, Clone, Copy, Default)]
struct Extracted {
    counts: (u32, u32),
    used: usize,
    tally: [u32; 8],
}

/// How the last extraction extracts each sphere's returns ([`Rounds::last_extraction`]).
struct LastExtraction<'x> {
    targets: &'x [Target],
    s: &'x Settings,
    mount: Mount,
    time: TimeOffset,
    how: extract::Extraction<'x>,
}

impl LastExtraction<'_> {
    /// Spheres `first..` (`obs`, with `active` returns taking part), their passes among
    /// `passes`: each one's outcome into `out`, the kept returns first in `obs`.
    fn spheres(
        &self,
        first: usize,
        obs: &mut [&mut [Observation]],
        active: &[usize],
        out: &mut [Extracted],
        passes: &mut [PassReport],
        lane: &mut Lane<'_>,
    ) {
        let (s, tau, dirs) = (self.s, self.how.tau, self.how.dirs);
        for (i, ((all, &active), x)) in obs.iter_mut().zip(active).zip(out).enumerate() {
            let j = first + i;
            let Some(t) = self.targets.get(j) else {
                continue;
            };
            let v = &mut all[..active];
            extract::georeference(v, t, &self.mount, &self.time);
            let mine = {
                let a = passes.partition_point(|p| usize::from(p.sphere) < j);
                let b = passes.partition_point(|p| usize::from(p.sphere) <= j);
                &mut passes[a..b]
            };
            let (_, sl, det) =
                extract::extract_sphere(v, t, &self.how, lane.grid, lane.keys, |t0, d| {
                    if let Some(p) = pass_of(mine, t0) {
                        p.slices += 1;
                        if let Some(d) = d {
                            p.detected += 1;
                            p.mean_inliers += d.inliers as f32;
                        }
                    }
                });
            x.counts = (sl, det);
            // What meets the sphere (its stand, a deck) is recognised around the surveyed centre.
            let kept = v
                .iter()
                .filter(|o| o.work.verdict == ReturnClass::Kept as u8)
                .count() as u32;
            extract::reject_attachments(v, t.radius, tau, dirs, (kept / 33).max(8));
            extract::reject_touching_plane(v, t.radius, tau, (kept / 10).max(12));
            if s.extract.ground_sweeps {
                let band = 3.5 * s.noise().range + 0.01;
                extract::reject_ground_on_sweeps(v, t.radius, tau, band);
            }
            // Only the returns still taking part can be kept: the rest were set behind them
            // as `OutsideShell` (`extract::place_and_compact`).
            x.used = partition(v);
            if x.used < s.min_points {
                extract::tag(all, ReturnClass::NotFound);
                x.used = 0;
            }
            x.tally = tally(all, mine);
        }
    }
}

/// A sphere's returns (`all`) counted by verdict, into its passes (`mine`) too, with each pass's
/// course over its kept returns and its detections' mean inliers.
fn tally(all: &[Observation], mine: &mut [PassReport]) -> [u32; 8] {
    let mut tally = [0u32; 8];
    let mut at = PassCursor::default();
    for o in all {
        let k = usize::from(o.work.verdict).min(7);
        tally[k] += 1;
        if let Some(p) = at.pass_of(mine, o.time) {
            p.verdicts[k] += 1;
            if k == ReturnClass::Kept as usize {
                p.course[0] += o.velocity.x;
                p.course[1] += o.velocity.y;
            }
        }
    }
    for p in mine.iter_mut() {
        if p.detected > 0 {
            p.mean_inliers /= p.detected as f32;
        }
        let [n, e] = p.course;
        let speed = libm::sqrtf(n * n + e * e);
        p.course = if speed > 0.0 {
            [n / speed, e / speed]
        } else {
            [0.0; 2]
        };
    }
    tally
}

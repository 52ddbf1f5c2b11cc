//! The detect-and-solve rounds, shaped like argmin's executor: the state ([`Rounds`]),
//! [`Rounds::next_iter`] (one extraction, solve and next shell), [`Rounds::terminate`] (a named
//! [`Termination`]) and an [`Observe`] hook told of every round; then the last extraction and
//! the final least squares.

use super::checks::weights;
use super::outcome::{PassReport, Refusal, Round, Solution, Termination};
use super::settings::Settings;
use super::{
    fingerprint, gather, groups, reach, side_by_side, split_ranges, time_order, with_problem, Lane,
    Residuals, Workspace,
};
use crate::align::window::{Observation, Target, MAX_TARGETS};
use crate::calib::consensus::{Bounds, Consensus};
use crate::calib::extract::{self, apparent_offsets, Directions, ReturnClass};
use crate::calib::histogram::Histogram;
use crate::calib::lm::refine;
use crate::calib::nelder_mead::{minimize, NmResult};
use crate::calib::objective::TimeOffset;
use crate::georef::{DegM, Mount, Params, P};
use crate::time::GpsTime;

/// What a solve tells whoever watches it (argmin's `Observe`): every round as it ends and how
/// the rounds ended. Both do nothing by default; `()` watches nothing.
pub trait Observe {
    /// A round ended (`number` from 1) with this log entry.
    fn round(&mut self, _number: usize, _round: &Round) {}
    /// The rounds ended, after `rounds` of them.
    fn ended(&mut self, _how: Termination, _rounds: usize) {}
}

impl Observe for () {}

/// The data the rounds work on: the spheres, their windowed returns (reordered in place), the
/// settings and the lent scratch.
pub(super) struct Data<'d, 'o, 'w> {
    pub(super) targets: &'d [Target],
    pub(super) obs: &'d mut [&'o mut [Observation]],
    pub(super) s: &'d Settings,
    pub(super) ws: &'d mut Workspace<'w>,
}

/// The rounds' state: what each round carries to the next and into the last extraction.
pub(super) struct Rounds {
    /// The parameters [rad, m] (plain numbers for the optimisers).
    pub(super) b: [f64; P],
    /// The time offset model.
    pub(super) time: TimeOffset,
    /// The shell half-width [m].
    pub(super) tau: f64,
    /// The prior radius (`None`: from afar, the whole window) [m].
    pub(super) prior: Option<f64>,
    /// Each sphere's returns still taking part (the others are far from it).
    pub(super) active: [usize; MAX_TARGETS],
    /// Each sphere's slices and detections in the latest extraction.
    pub(super) counts: [(u32, u32); MAX_TARGETS],
    /// The box the mounting must stay in.
    pub(super) bounds: Bounds,
    /// The first round's consensus.
    pub(super) consensus: Option<Consensus>,
    /// Rounds run so far.
    pub(super) round: usize,
    /// Nelder-Mead's work over the rounds from afar.
    pub(super) nm: Option<NmResult<P>>,
    /// The latest rounds' kept-set fingerprints (a repeat is a cycle).
    prints: heapless::Vec<u64, 4>,
    /// The returns kept in the round before.
    last_kept: Option<usize>,
    /// How the rounds ended, once they have (stopped: why they could not go on, and the
    /// solution is refused).
    pub(super) ended: Option<Termination>,
    /// Each sphere's returns kept in the latest round.
    pub(super) kept: [usize; MAX_TARGETS],
    /// The returns are georeferenced at `b` and `time` already (as [`super::prepare`] leaves
    /// them at the start): the first extraction does not do it again.
    pub(super) placed: bool,
    /// What each round did (both starts', in order, once a second start is merged in).
    pub(super) log: heapless::Vec<Round, 32>,
}

impl Rounds {
    /// The state before the first round (argmin's `init`).
    pub(super) fn init(
        b0: &Params,
        windowed: [usize; MAX_TARGETS],
        tau0: f64,
        bounds: Bounds,
        t_ref: GpsTime,
    ) -> Self {
        Self {
            b: b0.0,
            time: TimeOffset {
                dt: 0.0,
                drift: 0.0,
                t_ref,
            },
            tau: tau0,
            prior: None,
            active: windowed,
            counts: [(0, 0); MAX_TARGETS],
            bounds,
            consensus: None,
            round: 0,
            nm: None,
            prints: heapless::Vec::new(),
            last_kept: None,
            ended: None,
            kept: [0; MAX_TARGETS],
            placed: false,
            log: heapless::Vec::new(),
        }
    }

    /// Why the rounds could not go on, when they were stopped.
    pub(super) fn stopped(&self) -> Option<Refusal> {
        self.ended.and_then(Termination::refusal)
    }

    /// Whether the rounds are over, and how (argmin's `terminate`): a round ended them, or
    /// `max_rounds` ran without settling.
    pub(super) fn terminate(&self, s: &Settings) -> Option<Termination> {
        self.ended
            .or((self.round >= s.max_rounds).then_some(Termination::MaxRounds))
    }

    /// One round (argmin's `next_iter`): extract, solve, the next shell; then whether the
    /// kept sets barely changed and the parameters stood still (to a tenth of the 1e-3 deg /
    /// 1e-3 m the method aims for), or the kept sets went round a cycle (a few returns at the
    /// shell's edge in, out). Returns the round's log entry; `None` when the round ended the
    /// rounds without a solve (fewer than two spheres, ambiguous).
    pub(super) fn next_iter(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        passes: &[PassReport],
    ) -> Option<Round> {
        self.round += 1;
        let (b_before, dt_before) = (self.b, self.time.dt);
        let Some((total, print, next_prior, entry)) = self.one_round(d, passes) else {
            self.ended = self.ended.or(Some(Termination::TooFewSpheres));
            return None;
        };
        if let Some(out) = self.out_of_bounds() {
            self.ended = Some(Termination::Stopped(out));
            return Some(entry);
        }
        let moved = Params(self.b)
            .deg_m()
            .0
            .iter()
            .zip(Params(b_before).deg_m().0)
            .map(|(a, c)| (a - c).abs())
            .fold(0.0, f64::max)
            .max((self.time.dt - dt_before).abs() * 20.0);
        let still = self
            .last_kept
            .is_some_and(|k: usize| k.abs_diff(total) * 200 <= total)
            && moved < 2e-3;
        let cycle = self.prints.contains(&print);
        if self.prior.is_some() && (still || cycle) {
            self.ended = Some(if still {
                Termination::Settled
            } else {
                Termination::Cycle
            });
        }
        self.prior = Some(next_prior);
        self.last_kept = Some(total);
        if self.prints.is_full() {
            self.prints.remove(0);
        }
        let _ = self.prints.push(print);
        Some(entry)
    }

    /// The mounting is outside its box: the refusal naming the parameter furthest out.
    pub(super) fn out_of_bounds(&self) -> Option<Refusal> {
        if self.bounds.contains(&self.b) {
            return None;
        }
        let u = self.bounds.usage(&self.b);
        let i = (0..P).max_by(|&a, &b| u[a].total_cmp(&u[b])).unwrap_or(0);
        let limit = if i < 3 {
            self.bounds.angle
        } else {
            self.bounds.lever
        };
        Some(Refusal::OutOfBounds {
            parameter: i,
            change: u[i] * limit,
            limit,
        })
    }
}

/// The rounds from `r`'s state to their end (argmin's executor): each round's entry into the
/// state's log and to `watch`; the state counts the rounds and keeps how they ended.
pub(super) fn run_rounds(
    d: &mut Data<'_, '_, '_>,
    passes: &[PassReport],
    r: &mut Rounds,
    watch: &mut impl Observe,
) {
    let how = loop {
        if let Some(how) = r.terminate(d.s) {
            break how;
        }
        if let Some(entry) = r.next_iter(d, passes) {
            let _ = r.log.push(entry);
            watch.round(r.round, &entry);
        }
    };
    r.ended = Some(how);
    watch.ended(how, r.round);
}

impl Solution {
    /// The answer as the rounds' final state `r` leaves it (argmin's result from its state):
    /// the mounting, the time offset model, the shell, the first round's consensus, the box,
    /// the rounds run with their log, how they ended and Nelder-Mead's work; the rest as
    /// nothing solved yet from `b0`.
    pub(super) fn from_rounds(r: &Rounds, b0: &Params) -> Self {
        let mut sol = Solution::start(b0, r.tau);
        sol.b = Params(r.b);
        sol.dt = r.time.dt;
        sol.drift = r.time.drift;
        sol.t_ref = r.time.t_ref;
        if let Some(nm) = r.nm {
            sol.nm = nm;
        }
        sol.rounds = r.round;
        sol.termination = r.ended.unwrap_or_default();
        sol.log = r.log.clone();
        sol.consensus = r.consensus;
        sol.bounds = r.bounds;
        sol
    }
}

impl Rounds {
    /// One round: extract each sphere's returns, solve on the kept ones, the next shell. Returns
    /// the returns kept, their fingerprint and the next prior radius; `None` when fewer than two
    /// spheres are found.
    fn one_round(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        passes: &[PassReport],
    ) -> Option<(usize, u64, f64, Round)> {
        let targets = d.targets;
        let n = targets.len();
        let round_tau = self.tau;
        let kept = if self.prior.is_none() {
            let kept = self.first_extract(d, passes);
            self.placed = false;
            kept?
        } else {
            self.round_extract(d)?
        };
        let (buf, ranges) = gather(d.obs, &self.active[..n], &kept[..n], d.ws.kept);
        let mut print = 0xcbf2_9ce4_8422_2325u64;
        for rg in ranges.iter().take(n) {
            print = fingerprint(print, &buf[rg.clone()]);
        }
        let mut part = split_ranges(buf, &ranges[..n]);
        let lens: [usize; MAX_TARGETS] =
            core::array::from_fn(|j| part.get(j).map_or(0, |p| p.len()));
        self.round_solve(targets, &mut part, &lens, d.s);
        let next_prior = self.next_shell(targets, &mut part, &lens, d.s);
        let total: usize = kept[..n].iter().sum();
        self.kept = kept;
        let entry = Round {
            tau: round_tau,
            prior: self.prior,
            kept: total,
            detected: self.counts[..n].iter().map(|c| c.1).sum(),
            b: Params(self.b),
            dt: self.time.dt,
        };
        Some((total, print, next_prior, entry))
    }

    /// Each sphere's returns extracted with the current parameters, shell and prior; spheres with
    /// fewer than `min_points` take no part (kept 0, tagged undetected). `None` when fewer than
    /// two are found.
    fn round_extract(&mut self, d: &mut Data<'_, '_, '_>) -> Option<[usize; MAX_TARGETS]> {
        let (targets, s) = (d.targets, d.s);
        let n = targets.len();
        let dirs = Directions::default();
        let noise = s.noise();
        let r = RoundExtraction {
            targets,
            mount: Mount::from_params(&Params(self.b)),
            time: self.time,
            // Returns far from the sphere (a few prior radii beyond its surface, at least half
            // a metre) cannot become its returns any more: they leave the rounds.
            far: self.prior.map(|p| reach(p, self.tau)),
            how: extract::Extraction {
                tau: self.tau,
                prior: self.prior,
                surveyed: false,
                dirs: &dirs,
                settings: &s.extract,
                noise: &noise,
            },
        };
        let mut kept = [0usize; MAX_TARGETS];
        let k = groups(d.ws, &self.active[..n]);
        let (oa, ob) = d.obs.split_at_mut(k);
        let (aa, ab) = self.active[..n].split_at_mut(k);
        let (ca, cb) = self.counts[..n].split_at_mut(k);
        let (ka, kb) = kept[..n].split_at_mut(k);
        side_by_side(
            d.ws,
            |lane| r.spheres(0, oa, aa, ca, ka, lane),
            |lane| r.spheres(k, ob, ab, cb, kb, lane),
        );
        let obs = &mut *d.obs;
        if (0..n).filter(|&j| kept[j] >= s.min_points).count() < 2 {
            return None;
        }
        for (j, v) in obs.iter_mut().enumerate() {
            if kept[j] < s.min_points {
                kept[j] = 0;
            }
            if kept[j] == 0 {
                extract::tag(&mut v[..self.active[j]], ReturnClass::Undetected);
            }
        }
        Some(kept)
    }

    /// The round's solve on the kept returns `part`: from afar (no prior yet) Nelder-Mead on eq. 6
    /// (L1) over at most `nm_points` returns per sphere, evenly spread, with a restart; close,
    /// least squares (time order for its clusters).
    fn round_solve(
        &mut self,
        targets: &[Target],
        part: &mut [&mut [Observation]],
        lens: &[usize; MAX_TARGETS],
        s: &Settings,
    ) {
        let n = targets.len();
        if self.prior.is_none() {
            let most = lens[..n].iter().copied().max().unwrap_or(1);
            let stride = most.div_ceil(s.nm_points.max(1)).max(1);
            let plain = Residuals::PLAIN;
            let mut nm = with_problem(targets, part, lens, stride, self.time, plain, |pb| {
                minimize::<P, 7>(
                    |x| pb.l1(&DegM(*x).params().0),
                    &Params(self.b).deg_m().0,
                    &s.step,
                    &s.nm,
                )
            });
            if let Some(before) = self.nm {
                nm.evaluations += before.evaluations;
                nm.iterations += before.iterations;
            }
            self.nm = Some(nm);
            self.b = DegM(nm.x).params().0;
        } else {
            for p in part.iter_mut().take(n) {
                p.sort_unstable_by_key(time_order);
            }
            let fitted = Residuals::fitted(weights(part, &lens[..n], s), s);
            let lm = with_problem(targets, part, lens, 1, self.time, fitted, |pb| {
                refine(pb, &self.b, s.lm_iter, s.cluster_ns, s.clock())
            });
            self.b = lm.b;
            if lm.dt.is_finite() && lm.drift.is_finite() {
                self.time.dt = lm.dt;
                self.time.drift = lm.drift;
            }
        }
    }

    /// The next shell (from the kept returns' median residual against the surveyed spheres, into
    /// `self.tau`) and the next prior radius (from their apparent offsets), returned.
    fn next_shell(
        &mut self,
        targets: &[Target],
        part: &mut [&mut [Observation]],
        lens: &[usize; MAX_TARGETS],
        s: &Settings,
    ) -> f64 {
        let med = with_problem(targets, part, lens, 1, self.time, Residuals::PLAIN, |pb| {
            let mut h = Histogram::new();
            pb.residuals(&self.b, |_, e| h.add(e.abs()));
            h.median()
        });
        let widest = s
            .extract
            .tau0
            .max(0.5 * targets.iter().map(|t| t.radius).fold(0.0, f64::max));
        self.tau = (s.shell_sigmas * 1.4826 * med).clamp(s.shell_floor, widest);
        let mount = Mount::from_params(&Params(self.b));
        let mut offsets = Histogram::new();
        for j in (0..targets.len()).filter(|&j| lens[j] > 0) {
            part[j].sort_unstable_by_key(|o| o.work.slice);
            extract::georeference(part[j], &targets[j], &mount, &self.time);
            apparent_offsets(part[j], targets[j].radius, &mut offsets);
        }
        let off = if offsets.count() > 0 {
            offsets.median()
        } else {
            1.0
        };
        (4.0 * off).max(3.0 * self.tau).max(0.02)
    }
}

/// How a round extracts each sphere's returns ([`Rounds::round_extract`]).
struct RoundExtraction<'r> {
    targets: &'r [Target],
    mount: Mount,
    time: TimeOffset,
    /// How far from its surface a return still takes part [m].
    far: Option<f64>,
    how: extract::Extraction<'r>,
}

impl RoundExtraction<'_> {
    /// Spheres `first..` (`obs`, with `active` returns taking part, updated): each one placed,
    /// compacted and extracted, its kept count into `kept` and its slices and detections into
    /// `counts`.
    fn spheres(
        &self,
        first: usize,
        obs: &mut [&mut [Observation]],
        active: &mut [usize],
        counts: &mut [(u32, u32)],
        kept: &mut [usize],
        lane: &mut Lane<'_>,
    ) {
        let rows = obs.iter_mut().zip(active).zip(counts).zip(kept);
        for (i, (((v, active), count), kept)) in rows.enumerate() {
            let Some(t) = self.targets.get(first + i) else {
                continue;
            };
            let v = &mut v[..*active];
            *active = extract::place_and_compact(v, t, &self.mount, &self.time, self.far);
            let v = &mut v[..*active];
            let (k, sl, det) =
                extract::extract_sphere(v, t, &self.how, lane.grid, lane.keys, |_, _| {});
            *count = (sl, det);
            *kept = k;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::consensus::Bounds;
    use nalgebra::Vector3;

    /// Counts what it is told.
    #[derive(Default)]
    struct Count {
        rounds: usize,
        ended: Option<(Termination, usize)>,
    }

    impl Observe for Count {
        fn round(&mut self, n: usize, _: &Round) {
            self.rounds = n;
        }
        fn ended(&mut self, how: Termination, rounds: usize) {
            self.ended = Some((how, rounds));
        }
    }

    fn state() -> Rounds {
        let b0 = Params([0.0; P]);
        Rounds::init(&b0, [0; MAX_TARGETS], 0.1, Bounds::none(&b0), GpsTime(0))
    }

    #[test]
    fn the_rounds_end_at_their_limit_or_when_a_round_says() {
        let mut r = state();
        let s = Settings {
            max_rounds: 2,
            ..Settings::default()
        };
        assert_eq!(r.terminate(&s), None);
        r.round = 2;
        assert_eq!(r.terminate(&s), Some(Termination::MaxRounds));
        r.round = 1;
        r.ended = Some(Termination::Settled);
        assert_eq!(r.terminate(&s), Some(Termination::Settled));
    }

    #[test]
    fn a_round_with_nothing_to_find_ends_them_and_the_watcher_hears() {
        // No returns at all: the first round finds fewer than two spheres.
        let t = Target {
            center: Vector3::zeros(),
            radius: 0.2,
        };
        let targets = [t, t];
        let (mut a, mut b): ([Observation; 0], [Observation; 0]) = ([], []);
        let mut obs: [&mut [Observation]; 2] = [&mut a, &mut b];
        let mut scratch = super::super::TinyScratch::new();
        let mut ws = scratch.workspace(false);
        let s = Settings::default();
        let mut d = Data {
            targets: &targets,
            obs: &mut obs,
            s: &s,
            ws: &mut ws,
        };
        let mut r = state();
        let mut watch = Count::default();
        run_rounds(&mut d, &[], &mut r, &mut watch);
        let sol = Solution::from_rounds(&r, &Params([0.0; P]));
        assert_eq!(sol.termination, Termination::TooFewSpheres);
        assert_eq!(sol.rounds, 1);
        assert!(sol.log.is_empty());
        assert_eq!(watch.rounds, 0, "no round finished a solve");
        assert_eq!(watch.ended, Some((Termination::TooFewSpheres, 1)));
        // With no round allowed the limit is the end.
        let s0 = Settings {
            max_rounds: 0,
            ..Settings::default()
        };
        d.s = &s0;
        let mut r = state();
        run_rounds(&mut d, &[], &mut r, &mut watch);
        assert_eq!(watch.ended, Some((Termination::MaxRounds, 0)));
        assert_eq!(r.ended, Some(Termination::MaxRounds));
    }
}

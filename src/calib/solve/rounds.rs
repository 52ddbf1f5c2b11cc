//! The detect-and-solve rounds as state ([`Rounds`]) and steps: the first extraction (the
//! consensus), each round's extraction, solve and next shell, until [`Termination`]; then the
//! last extraction and the final least squares.

#[allow(unused_imports)]
use super::*;

/// What the rounds carry from one to the next and into the last extraction.
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
    /// Why the rounds could not go on (the solution is refused).
    pub(super) end: Option<Refusal>,
}

impl Rounds {
    pub(super) fn start(
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
            end: None,
        }
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

/// Rounds until the kept sets barely change and the parameters stand still (to a tenth of the
/// 1e-3 deg / 1e-3 m the method aims for), the kept sets go round a cycle (a few returns at
/// the shell's edge in, out), fewer than two spheres are found, or `max_rounds`.
pub(super) fn run_rounds(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    passes: &[PassReport],
    r: &mut Rounds,
    sol: &mut Solution,
) {
    let mut prints: heapless::Vec<u64, 4> = heapless::Vec::new();
    let mut last_kept: Option<usize> = None;
    sol.termination = Termination::MaxRounds;
    for round in 0..s.max_rounds {
        sol.rounds = round + 1;
        let (b_before, dt_before) = (r.b, r.time.dt);
        let Some((total, print, next_prior)) = one_round(targets, obs, s, ws, passes, r, sol)
        else {
            sol.termination = if r.end.is_some() {
                Termination::Stopped
            } else {
                Termination::TooFewSpheres
            };
            break;
        };
        if let Some(out) = r.out_of_bounds() {
            r.end = Some(out);
            sol.termination = Termination::Stopped;
            break;
        }
        let moved = Params(r.b)
            .deg_m()
            .0
            .iter()
            .zip(Params(b_before).deg_m().0)
            .map(|(a, c)| (a - c).abs())
            .fold(0.0, f64::max)
            .max((r.time.dt - dt_before).abs() * 20.0);
        let still =
            last_kept.is_some_and(|k: usize| k.abs_diff(total) * 200 <= total) && moved < 2e-3;
        let cycle = prints.contains(&print);
        let settled = r.prior.is_some() && (still || cycle);
        r.prior = Some(next_prior);
        last_kept = Some(total);
        if prints.is_full() {
            prints.remove(0);
        }
        let _ = prints.push(print);
        if settled {
            sol.termination = if still {
                Termination::Settled
            } else {
                Termination::Cycle
            };
            break;
        }
    }
}

/// One round: extract each sphere's returns, solve on the kept ones, the next shell. Returns
/// the returns kept, their fingerprint and the next prior radius; `None` when fewer than two
/// spheres are found.
pub(super) fn one_round(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    passes: &[PassReport],
    r: &mut Rounds,
    sol: &mut Solution,
) -> Option<(usize, u64, f64)> {
    let n = targets.len();
    let round_tau = r.tau;
    let kept = if r.prior.is_none() {
        first_extract(targets, obs, s, ws, passes, r)?
    } else {
        round_extract(targets, obs, s, ws, r)?
    };
    let ranges = gather(obs, &r.active[..n], &kept[..n], ws.kept);
    let buf = &mut *ws.kept;
    let mut print = 0xcbf2_9ce4_8422_2325u64;
    for rg in ranges.iter().take(n) {
        print = fingerprint(print, &buf[rg.clone()]);
    }
    let mut part = split_ranges(buf, &ranges[..n]);
    let lens: [usize; MAX_TARGETS] = core::array::from_fn(|j| part.get(j).map_or(0, |p| p.len()));
    round_solve(targets, &mut part, &lens, s, r, sol);
    let next_prior = next_shell(targets, &mut part, &lens, s, r);
    let total: usize = kept[..n].iter().sum();
    let _ = sol.log.push(Round {
        tau: round_tau,
        prior: r.prior,
        kept: total,
        detected: r.counts[..n].iter().map(|c| c.1).sum(),
        b: Params(r.b),
        dt: r.time.dt,
    });
    Some((total, print, next_prior))
}

/// The first round: every sphere-like candidate of every slice ([`extract::detect_all`]), the
/// consensus over them ([`consensus`]) for the mounting and the candidates that are the spheres,
/// and the returns within `tau` of those kept. The consensus mounting becomes the rounds'
/// parameters; an ambiguous sphere ends the rounds. `None` when fewer than two spheres are
/// agreed on.
pub(super) fn first_extract(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    passes: &[PassReport],
    r: &mut Rounds,
) -> Option<[usize; MAX_TARGETS]> {
    let n = targets.len();
    let dirs = Directions::default();
    let mount = Mount::from_params(&Params(r.b));
    let mut nc = 0;
    let mut found = extract::Candidates::new();
    for j in 0..n {
        let v = &mut obs[j][..r.active[j]];
        extract::georeference(v, &targets[j], &mount, &r.time);
        extract::tag(v, Verdict::Undetected);
        let (mut slices, mut detected) = (0, 0);
        let mut start = 0;
        loop {
            let Some(sl) = extract::slices(&v[start..]).next() else {
                break;
            };
            let sl = start + sl.start..start + sl.end;
            start = sl.end;
            slices += 1;
            let slice = &v[sl.clone()];
            extract::detect_all(
                slice,
                ws.keys,
                targets[j].radius,
                r.tau,
                None,
                ws.grid,
                &dirs,
                &s.extract,
                extract::MAX_CANDIDATES,
                &mut found,
            );
            detected += u32::from(!found.is_empty());
            // The pose of the slice's middle return carries its candidates.
            let rep = &slice[slice.len() / 2];
            let group = passes
                .iter()
                .rposition(|p| usize::from(p.sphere) == j && p.start <= rep.time)
                .unwrap_or(0);
            for d in &found {
                let Some(c) = Candidate::new(d.center, rep, &targets[j], &mount, &r.time) else {
                    continue;
                };
                if let Some(slot) = ws.cands.get_mut(nc) {
                    *slot = Candidate {
                        sphere: j as u8,
                        group: group as u16,
                        slice: rep.work.slice,
                        inliers: d.inliers,
                        ..c
                    };
                    nc += 1;
                }
            }
        }
        r.counts[j] = (slices, detected);
    }
    let mut search = Search {
        cands: &mut ws.cands[..nc],
        targets,
        time: r.time,
        bounds: r.bounds,
        settings: s.consensus,
    };
    let Some(c) = consensus(&mut search, &r.b, ws.idx) else {
        // Not three candidates apart, or no mounting within the bounds explains any.
        r.consensus = Some(Consensus {
            b: r.b,
            score: 0.0,
            support: [0; MAX_TARGETS],
            slices: core::array::from_fn(|j| r.counts[j].1),
            rms: f64::NAN,
            hypotheses: 0,
            ambiguous: None,
        });
        return None;
    };
    r.consensus = Some(c);
    if let Some(a) = c.ambiguous {
        r.end = Some(Refusal::Ambiguous(a));
        return None;
    }
    // Keep the returns of the chosen candidates (slices and candidates are in one order).
    let mut kept = [0usize; MAX_TARGETS];
    let cands = &ws.cands[..nc];
    let mut k = 0;
    for j in 0..n {
        let v = &mut obs[j][..r.active[j]];
        let mut start = 0;
        loop {
            let Some(sl) = extract::slices(&v[start..]).next() else {
                break;
            };
            let sl = start + sl.start..start + sl.end;
            start = sl.end;
            let id = v[sl.start + sl.len() / 2].work.slice;
            while k < nc
                && (usize::from(cands[k].sphere) < j
                    || (usize::from(cands[k].sphere) == j && cands[k].slice < id))
            {
                k += 1;
            }
            let mut chosen = None;
            while k < nc && usize::from(cands[k].sphere) == j && cands[k].slice == id {
                if cands[k].chosen {
                    chosen = Some(cands[k].detected);
                }
                k += 1;
            }
            if let Some(at) = chosen {
                kept[j] += extract::keep(&mut v[sl], at, targets[j].radius, r.tau, &s.noise());
            }
        }
    }
    r.b = c.b;
    if (0..n).filter(|&j| kept[j] >= s.min_points).count() < 2 {
        return None;
    }
    for (j, v) in obs.iter_mut().enumerate() {
        if kept[j] < s.min_points {
            kept[j] = 0;
            extract::tag(&mut v[..r.active[j]], Verdict::Undetected);
        }
    }
    Some(kept)
}

/// Each sphere's returns extracted with the current parameters, shell and prior; spheres with
/// fewer than `min_points` take no part (kept 0, tagged undetected). `None` when fewer than
/// two are found.
pub(super) fn round_extract(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    r: &mut Rounds,
) -> Option<[usize; MAX_TARGETS]> {
    let n = targets.len();
    let dirs = Directions::default();
    let mount = Mount::from_params(&Params(r.b));
    let mut kept = [0usize; MAX_TARGETS];
    for j in 0..n {
        let v = &mut obs[j][..r.active[j]];
        extract::georeference(v, &targets[j], &mount, &r.time);
        if let Some(p) = r.prior {
            // Returns far from the sphere (a few prior radii beyond its surface, at least
            // half a metre) cannot become its returns any more: they leave the rounds.
            r.active[j] = compact(v, targets[j].radius, (4.0 * p).max(0.5) + r.tau);
        }
        let v = &mut obs[j][..r.active[j]];
        let (k, sl, det) = extract_sphere(
            v,
            &targets[j],
            r.tau,
            r.prior,
            false,
            ws.grid,
            ws.keys,
            &dirs,
            &s.extract,
            &s.noise(),
            None,
        );
        r.counts[j] = (sl, det);
        kept[j] = k;
    }
    if (0..n).filter(|&j| kept[j] >= s.min_points).count() < 2 {
        return None;
    }
    for (j, v) in obs.iter_mut().enumerate() {
        if kept[j] < s.min_points {
            kept[j] = 0;
        }
        if kept[j] == 0 {
            extract::tag(&mut v[..r.active[j]], Verdict::Undetected);
        }
    }
    Some(kept)
}

/// The round's solve on the kept returns `part`: from afar (no prior yet) Nelder-Mead on eq. 6
/// (L1) over at most `nm_points` returns per sphere, evenly spread, with a restart; close,
/// least squares (time order for its clusters).
pub(super) fn round_solve(
    targets: &[Target],
    part: &mut [&mut [Observation]],
    lens: &[usize; MAX_TARGETS],
    s: &Settings,
    r: &mut Rounds,
    sol: &mut Solution,
) {
    let n = targets.len();
    if r.prior.is_none() {
        let most = lens[..n].iter().copied().max().unwrap_or(1);
        let stride = most.div_ceil(s.nm_points.max(1)).max(1);
        let mut nm = with_problem(targets, part, lens, stride, r.time, None, |pb| {
            minimize::<P, 7>(
                |x| pb.l1(&DegM(*x).params().0),
                &Params(r.b).deg_m().0,
                &s.step,
                &s.nm,
            )
        });
        nm.evaluations += sol.nm.evaluations;
        nm.iterations += sol.nm.iterations;
        sol.nm = nm;
        r.b = DegM(nm.x).params().0;
    } else {
        for p in part.iter_mut().take(n) {
            p.sort_unstable_by_key(|o| (o.time, o.channel, o.block));
        }
        let w = weights(part, &lens[..n], s);
        let lm = with_problem(targets, part, lens, 1, r.time, w, |pb| {
            refine(pb, &r.b, s.lm_iter, s.cluster_ns, s.clock())
        });
        r.b = lm.b;
        if lm.dt.is_finite() && lm.drift.is_finite() {
            r.time.dt = lm.dt;
            r.time.drift = lm.drift;
        }
    }
}

/// The next shell (from the kept returns' median residual against the surveyed spheres, into
/// `r.tau`) and the next prior radius (from their apparent offsets), returned.
pub(super) fn next_shell(
    targets: &[Target],
    part: &mut [&mut [Observation]],
    lens: &[usize; MAX_TARGETS],
    s: &Settings,
    r: &mut Rounds,
) -> f64 {
    let med = with_problem(targets, part, lens, 1, r.time, None, |pb| {
        let mut h = Histogram::new();
        pb.residuals(&r.b, |_, e| h.add(e.abs()));
        h.median()
    });
    let widest = s
        .extract
        .tau0
        .max(0.5 * targets.iter().map(|t| t.radius).fold(0.0, f64::max));
    r.tau = (s.shell_sigmas * 1.4826 * med).clamp(s.shell_floor, widest);
    let mount = Mount::from_params(&Params(r.b));
    let mut offsets = Histogram::new();
    for j in (0..targets.len()).filter(|&j| lens[j] > 0) {
        part[j].sort_unstable_by_key(|o| o.work.slice);
        extract::georeference(part[j], &targets[j], &mount, &r.time);
        apparent_offsets(part[j], targets[j].radius, &mut offsets);
    }
    let off = if offsets.n > 0 { offsets.median() } else { 1.0 };
    (4.0 * off).max(3.0 * r.tau).max(0.02)
}

/// The last extraction: around the surveyed spheres, in the slices where the sphere is
/// detected near them, attachments (a stand, a deck) rejected; spheres with too few returns
/// are not found. Returns each sphere's kept count (the kept ones first in `obs`) and its
/// verdict tallies; the passes get theirs.
pub(super) fn last_extraction(
    targets: &[Target],
    obs: &mut [&mut [Observation]],
    s: &Settings,
    ws: &mut Workspace<'_>,
    r: &mut Rounds,
    passes: &mut [PassReport],
) -> ([usize; MAX_TARGETS], [[u32; 8]; MAX_TARGETS]) {
    let dirs = Directions::default();
    let tau = r.tau;
    let mount = Mount::from_params(&Params(r.b));
    let mut used = [0usize; MAX_TARGETS];
    let mut tallies = [[0u32; 8]; MAX_TARGETS];
    for j in 0..targets.len() {
        let v = &mut obs[j][..r.active[j]];
        extract::georeference(v, &targets[j], &mount, &r.time);
        let mine = {
            let a = passes.partition_point(|p| usize::from(p.sphere) < j);
            let b = passes.partition_point(|p| usize::from(p.sphere) <= j);
            &mut passes[a..b]
        };
        let (_, sl, det) = extract_sphere(
            v,
            &targets[j],
            tau,
            Some(r.prior.unwrap_or(3.0 * tau).max(3.0 * tau)),
            true,
            ws.grid,
            ws.keys,
            &dirs,
            &s.extract,
            &s.noise(),
            Some(&mut *mine),
        );
        r.counts[j] = (sl, det);
        // What meets the sphere (its stand, a deck) is recognised around the surveyed centre.
        let kept = v
            .iter()
            .filter(|o| o.work.verdict == Verdict::Kept as u8)
            .count() as u32;
        extract::reject_attachments(v, targets[j].radius, tau, &dirs, (kept / 33).max(8));
        used[j] = partition(obs[j]);
        if used[j] < s.min_points {
            extract::tag(obs[j], Verdict::NotFound);
            used[j] = 0;
        }
        for o in obs[j].iter() {
            let k = usize::from(o.work.verdict).min(7);
            tallies[j][k] += 1;
            if let Some(p) = pass_of(mine, o.time) {
                p.verdicts[k] += 1;
            }
        }
        for p in mine.iter_mut() {
            if p.detected > 0 {
                p.mean_inliers /= p.detected as f32;
            }
        }
    }
    (used, tallies)
}

/// Least squares on the kept returns (with at least two spheres found); with the offset held,
/// the same returns with it free test the held value. Sets the answer and eq. 6 at it.
pub(super) fn final_fit(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    found: usize,
    s: &Settings,
    r: &mut Rounds,
    sol: &mut Solution,
) {
    let w = weights(obs, used, s);
    let lm = (found >= 2).then(|| {
        with_problem(targets, obs, used, 1, r.time, w, |pb| {
            refine(pb, &r.b, s.lm_iter, s.cluster_ns, s.clock())
        })
    });
    if let Some(l) = &lm {
        r.b = l.b;
        r.time.dt = l.dt;
        r.time.drift = l.drift;
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
        let (free, at_held) = with_problem(targets, obs, used, 1, r.time, w, |pb| {
            (
                refine(pb, &l.b, s.lm_iter, s.cluster_ns, free_clock),
                refine(pb, &l.b, 0, s.cluster_ns, free_clock),
            )
        });
        let sigma = at_held.sigma_dt;
        if free.dt.is_finite() && sigma.is_finite() && sigma > 0.0 {
            sol.dt_free = Some((free.dt, sigma));
        }
    }
    sol.b = Params(r.b);
    sol.dt = r.time.dt;
    sol.drift = r.time.drift;
    sol.t_ref = r.time.t_ref;
    sol.lm = lm;
    sol.l1 = with_problem(targets, obs, used, 1, r.time, None, |pb| pb.l1(&r.b));
}

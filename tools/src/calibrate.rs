//! `spherecal calibrate`: the pipeline, then the solver, then the report (JSON, a human
//! summary, optionally the calibrated cloud as LAS and the residual plots as SVG).

use crate::config::nav_source::InsKind;
use crate::pipeline::accuracy::Accuracy;
use crate::pipeline::Closest;
use crate::pipeline::{run, targets, BatchMsg, Inputs, RunStats};
use crate::reasons::{empty_windows, refusal_text_clock};
use crate::report::{InputsReport, Report, SearchCandidate};
use crate::session::settings_for;
use spherecal::align::window::{Observation, Target};
use spherecal::calib::solve::{Refusal, Solution};
use spherecal::calib::Params;
use std::fmt::Write as _;

/// A calibration's run counts, windowed returns (with their verdicts), solution and report.
pub type Calibrated = (RunStats, Vec<Vec<Observation>>, Solution, Report);

/// The half-width of the time offset search when the LiDAR clock is not trusted [s].
pub const DEFAULT_SEARCH_S: f64 = 2.0;
/// The search's step [s]: the joint solve pulls in from at least twice this (a 0.4 s error
/// converges from 0 on table1).
pub const SEARCH_STEP_S: f64 = 0.25;

/// A coarse 1-D search of the time offset over `centre +- half` in steps of [`SEARCH_STEP_S`]:
/// at each start the windows are collected and the joint solve run; what each found is
/// returned. The clock error moves the spheres' returns along the track by speed x error, so a
/// wrong start gives fewer sphere returns (detection fails in the slices it smears) and a larger
/// RMS: [`best_candidate`] picks the most compact.
pub fn search_time_offset<E>(
    centre: f64,
    half: f64,
    at_centre: &Solution,
    attempt: &mut impl FnMut(f64) -> Result<Calibrated, E>,
) -> Result<Vec<SearchCandidate>, E> {
    let n = (half / SEARCH_STEP_S).round().clamp(1.0, 400.0) as i64;
    let mut out = Vec::with_capacity(2 * n as usize + 1);
    let bar = crate::progress::bar(2 * n as u64 + 1, "time offset search");
    for k in -n..=n {
        bar.inc(1);
        let start = centre + k as f64 * SEARCH_STEP_S;
        let one = |sol: &Solution| SearchCandidate {
            start_s: start,
            found_s: sol
                .lm
                .filter(|l| l.converged && sol.dt.is_finite())
                .map(|_| start + sol.dt),
            kept: sol.spheres.iter().map(|s| s.used).sum(),
            rms_m: sol.lm.map(|l| l.rms).filter(|r| r.is_finite()),
        };
        if k == 0 {
            out.push(one(at_centre));
        } else {
            // A start where the clocks no longer overlap finds nothing; it does not end the
            // search.
            match attempt(start) {
                Ok((_, _, sol, _)) => out.push(one(&sol)),
                Err(_) => out.push(SearchCandidate {
                    start_s: start,
                    found_s: None,
                    kept: 0,
                    rms_m: None,
                }),
            }
        }
    }
    bar.finish_and_clear();
    Ok(out)
}

/// The widest search around `centre` [s] that keeps at least half the LiDAR data's span
/// (`lidar`, GPS seconds without any offset) within the INS's (`ins`): beyond it the clocks
/// barely overlap and nothing can be found; `half` clipped to it.
pub fn search_half_width(
    centre: f64,
    half: f64,
    lidar: Option<(f64, f64)>,
    ins: Option<(f64, f64)>,
) -> f64 {
    let (Some((l0, l1)), Some((i0, i1))) = (lidar, ins) else {
        return half;
    };
    // Offsets dt with [l0 + dt, l1 + dt] half inside [i0, i1].
    let w = 0.5 * (l1 - l0);
    let (lo, hi) = (i0 - l0 - w, i1 - l1 + w);
    let reach = (centre - lo).min(hi - centre).max(SEARCH_STEP_S);
    half.min(reach)
}

/// The most compact start: among those whose solve converged, the lowest RMS of those that
/// kept at least 80 % of the most sphere returns any kept.
pub fn best_candidate(c: &[SearchCandidate]) -> Option<SearchCandidate> {
    let ok = || {
        c.iter()
            .filter(|c| c.found_s.is_some() && c.rms_m.is_some())
    };
    let most = ok().map(|c| c.kept).max()?;
    ok().filter(|c| c.kept * 5 >= most * 4)
        .min_by(|a, b| a.rms_m.unwrap_or(0.0).total_cmp(&b.rms_m.unwrap_or(0.0)))
        .copied()
}

/// Windowed returns a collection holds before it tries to let go of what cannot be a sphere's
/// ([`collect_bounded`]): ~50 MB of observations.
pub const STORE_CAP: usize = 300_000;

/// Run the pipeline and collect the windowed observations per sphere, in memory bounded in the
/// survey's length (as the rig's store is): once the store holds `cap` returns (`calibrate`:
/// [`STORE_CAP`]; then twice that, ...), a solve from `b0` on them is tried; when it converges,
/// the returns farther than [`crate::session::KEEP_NEAR_M`] from every sphere's surface under
/// it are let go, and so are those that arrive after. A survey that never reaches the cap is
/// collected whole, as [`collect`] does. The stats count what was let go
/// ([`RunStats::pruned`]).
pub fn collect_bounded(
    inp: &Inputs,
    targets: &[Target],
    ids: &[String],
    b0: &Params,
    settings: &spherecal::calib::Settings,
    cap: usize,
) -> Result<(RunStats, Vec<Vec<Observation>>), crate::Error> {
    let n = inp.site.sphere.len();
    let (mut stats, (out, pruned)) = run(
        inp,
        None,
        move |rx: crossbeam_channel::Receiver<BatchMsg>| {
            let mut out: Vec<Vec<Observation>> = vec![Vec::new(); n];
            let (mut held, mut next_try, mut pruned) = (0usize, cap.max(1), 0u64);
            let mut near: Option<(spherecal::georef::Mount, f64)> = None;
            for m in rx {
                let (v, t) = (&mut out[m.sphere], &targets[m.sphere]);
                match &near {
                    Some((mount, dt)) => {
                        let before = v.len();
                        v.extend(
                            m.obs
                                .iter()
                                .filter(|o| crate::session::near(o, t, mount, *dt)),
                        );
                        pruned += (m.obs.len() - (v.len() - before)) as u64;
                        held += v.len() - before;
                    }
                    None => {
                        held += m.obs.len();
                        v.extend(m.obs);
                    }
                }
                if near.is_none() && held >= next_try {
                    next_try = next_try.saturating_mul(2);
                    near = trial_mount(&mut out, targets, ids, b0, settings);
                    if let Some((mount, dt)) = &near {
                        for (v, t) in out.iter_mut().zip(targets) {
                            let before = v.len();
                            v.retain(|o| crate::session::near(o, t, mount, *dt));
                            pruned += (before - v.len()) as u64;
                            v.shrink_to_fit();
                        }
                        held = out.iter().map(Vec::len).sum();
                    }
                }
            }
            (out, pruned)
        },
    )?;
    stats.pruned = pruned;
    Ok((stats, out))
}

/// The mounting and time offset a solve from `b0` finds on the store so far, under white
/// navigation errors; `None` unless it converged and was claimed. (In place: the store is put
/// back in arrival order and unmarked after.)
fn trial_mount(
    obs: &mut [Vec<Observation>],
    targets: &[Target],
    ids: &[String],
    b0: &Params,
    settings: &spherecal::calib::Settings,
) -> Option<(spherecal::georef::Mount, f64)> {
    let s = spherecal::calib::Settings {
        nav: None,
        ..*settings
    };
    let (sol, _) = crate::session::solve_report(targets, ids, obs, b0, &s);
    // The store as it came: in arrival order, unmarked (what the session's solve expects).
    for v in obs.iter_mut() {
        v.sort_unstable_by_key(|o| (o.packet, o.block, o.channel));
        v.iter_mut().for_each(|o| o.work = Default::default());
    }
    (sol.refusal.is_none() && sol.lm.is_some_and(|l| l.converged)).then(|| (sol.b.mount(), sol.dt))
}

/// Run the pipeline and collect the windowed observations per sphere.
pub fn collect(inp: &Inputs) -> Result<(RunStats, Vec<Vec<Observation>>), crate::Error> {
    let n = inp.site.sphere.len();
    run(
        inp,
        None,
        move |rx: crossbeam_channel::Receiver<BatchMsg>| {
            let mut out = vec![Vec::new(); n];
            for m in rx {
                out[m.sphere].extend(m.obs);
            }
            out
        },
    )
}

/// The `--returns` CSV header.
pub const RETURNS_HEADER: &str =
    "sphere,packet,block,channel,time_gps_s,laser,range_m,x_m,y_m,z_m,residual_m,verdict";

/// How `calibrate` treats the clocks and the INS.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockOptions {
    /// Estimate the time offset between the clocks (else hold `start`).
    pub estimate: bool,
    /// The time offset to start from [s] (INS time = LiDAR time + this); `None`: 0, or what
    /// the LiDAR's RMC says when its clock is not PPS-locked.
    pub start: Option<f64>,
    /// Claim a solution although the LiDAR clock is not PPS-locked (when the time offset
    /// found explains its disagreement with the RMC).
    pub allow_unlocked: bool,
    /// Use VN-200 poses whose InsStatus says not tracking.
    pub keep_untracked_ins: bool,
    /// Search the time offset over +- this [s] around the start (`None`: 2 s when the LiDAR
    /// clock is not PPS-locked with a valid RMC, no search otherwise).
    pub search: Option<f64>,
}

impl Default for ClockOptions {
    fn default() -> Self {
        Self {
            estimate: true,
            start: None,
            allow_unlocked: false,
            keep_untracked_ins: false,
            search: None,
        }
    }
}

/// Write every windowed return with its verdict (`--returns`): sphere id, where it is in the
/// capture, its time, laser and range, its place with the solution `b` (site NED), its signed
/// distance from the sphere's surface, and the extraction's verdict.
pub fn write_returns(
    path: &std::path::Path,
    targets: &[Target],
    ids: &[String],
    obs: &[Vec<Observation>],
    b: &Params,
) -> Result<(), crate::Error> {
    use std::io::Write as _;
    let err = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut w = crate::output::Staged::create(path)?;
    writeln!(w, "{}", RETURNS_HEADER).map_err(err)?;
    let mount = spherecal::georef::Mount::from_params(b);
    let mut line = String::new();
    for ((t, id), v) in targets.iter().zip(ids).zip(obs) {
        for o in v {
            let x = o.georef(&mount);
            let e = (x - t.center).norm() - t.radius;
            line.clear();
            let _ = writeln!(
                line,
                "{id},{},{},{},{:.9},{},{:.3},{:.5},{:.5},{:.5},{:.5},{}",
                o.packet,
                o.block,
                o.channel,
                o.time.as_secs_f64(),
                o.laser,
                o.range,
                x.x,
                x.y,
                x.z,
                e,
                spherecal::calib::extract::ReturnClass::from_u8(o.work.verdict).name()
            );
            w.write_all(line.as_bytes()).map_err(err)?;
        }
    }
    w.commit()
}

/// When the collections at the time offsets found do not settle (the last of five, solved at
/// the offset the one before found, still moves it by many of its own sigmas: the returns fix
/// no one offset, and whichever the last collection lands on would be claimed with a sigma
/// that does not hold; drone-noisy seed 1085's trial went 0 -> +18.9 -> +2.4 -> +5.4 -> +3.5
/// -> +19.1 ms, each +- 2-3 ms), the refusal in words. `found`: each collection's offset and
/// sigma [s].
fn unsettled_offset(found: &[(f64, f64)]) -> Option<String> {
    let last = found.len().checked_sub(1)?;
    let (lo, hi) = found
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, f| {
            (a.0.min(f.0), a.1.max(f.0))
        });
    let sigma = found[last].1;
    let moved = (found[last].0 - found[last.checked_sub(1)?].0).abs();
    (sigma.is_finite() && sigma > 0.0 && moved > 3.0 * sigma && hi - lo > 3.0 * sigma).then(|| {
        let list: Vec<String> = found.iter().map(|f| format!("{:+.1}", f.0 * 1e3)).collect();
        format!(
            "the time offset does not settle: solved again at each offset found, the collections give {} ms (each +- {:.1} ms): the returns fix no one offset; hold it (--time-offset S --hold-time-offset) if the clocks are known to agree, or survey with turns and speed changes",
            list.join(", "),
            sigma * 1e3
        )
    })
}

/// The whole calibration of the files of `inp` from `b0` [rad, m]: collect the windows,
/// solve; with the time offset estimated, collect them again at the offset found until it
/// moves by less than 0.5 ms (the solver's estimate is first-order in the offset the poses were
/// taken at; five collections at most, within 2 s of the start). A LiDAR clock that is not
/// PPS-locked with valid RMCs starts from the offset its RMCs give, and is searched around it
/// (`clock.search`, default 2 s: a coarse 1-D search, see [`search_time_offset`]); its solution
/// is refused unless `clock.allow_unlocked` and the offset found explains the RMC
/// disagreement. The report records the inputs' state.
pub fn calibrate(
    inp: &mut Inputs,
    targets: &[Target],
    ids: &[String],
    b0: &Params,
    clock: ClockOptions,
) -> Result<Calibrated, crate::Error> {
    // The model, once: every collection decodes as it, and the extraction's scan lines follow
    // its laser period.
    if let Some((m, _)) = crate::pipeline::resolve_model(inp)? {
        inp.model = Some(m);
    }
    let settings = settings_for(&inp.site, inp.model, clock.estimate, inp.margin);
    // The extraction's settings, for the radii's search on a refusal (the session's own).
    let extract = settings.extract;
    let mut session =
        crate::session::Session::with_settings(targets.to_vec(), ids.to_vec(), settings);
    let accuracy = match (&inp.accuracy, &inp.ins) {
        (Some(p), crate::pipeline::InsInput::Sbet(_, week)) => Some(Accuracy::load(
            p,
            crate::pipeline::sbet_week(*week, &inp.pcap, inp.site.leap_seconds)?,
        )?),
        (Some(p), _) => {
            return Err(crate::Error::bad_input(format!(
                "{}: an accuracy file goes with an SBET trajectory",
                p.display()
            )))
        }
        (None, _) => None,
    };
    let mut used_accuracy = None;
    // The navigation model: the site's, else what the INS stated in the data, else its kind's
    // default (`nav_source`), chosen at the first collection.
    let kind = match &inp.ins {
        crate::pipeline::InsInput::Vn200(_) | crate::pipeline::InsInput::Bag(..) => InsKind::Vn200,
        crate::pipeline::InsInput::Sbet(..) => InsKind::Sbet,
        crate::pipeline::InsInput::Posmv(..) => InsKind::PosmvRealTime,
    };
    let site_spec = inp.site.ins.as_ref().map(|i| i.correlated.clone());
    let mut chosen = false;
    // A LiDAR clock without PPS runs on its own crystal: its drift is estimated too.
    let drift = std::cell::Cell::new(false);
    // The rounds on a spinner (on a terminal only).
    let spinner = crate::progress::spinner("solving");
    let mut attempt = |applied: f64| -> Result<_, crate::Error> {
        inp.time_offset_ns = (applied * 1e9).round() as i64;
        let (stats, mut obs) =
            collect_bounded(inp, targets, ids, b0, session.settings(), STORE_CAP)?;
        if !chosen {
            let stated = accuracy
                .as_ref()
                .map(|a| &a.stated)
                .filter(|s| s.samples > 0)
                .unwrap_or(&stats.ins.stated);
            let c =
                crate::config::nav_source::choose(site_spec.as_ref(), None, Some(stated), kind)?;
            session.set_nav(&c, &inp.site);
            chosen = true;
        }
        // The accuracy file's sigmas weigh each return, unless a navigation model holds them.
        if let Some(a) = &accuracy {
            used_accuracy = Some(match session.nav().filter(|m| !m.is_white()) {
                None => a.apply(&mut obs),
                Some(_) => a.unapplied(),
            });
        }
        session.estimate_drift(drift.get());
        session.replace(obs, inp.time_offset_ns);
        if let (false, Some((t0, _))) = (inp.exclude.is_empty(), stats.align.lidar_span) {
            let week_of = spherecal::time::GpsTime((t0 * 1e9) as i64);
            session.exclude(&crate::stretches::in_week_of(&inp.exclude, week_of));
        }
        let clocks = crate::session::clock_facts(
            &stats.clock,
            &stats.ins.clock_steps,
            stats.align.lidar_span,
            applied,
            clock.allow_unlocked,
        );
        // The report's offset includes the one the windows were made at.
        let (sol, rep) = session.solve(b0, clocks, &mut crate::progress::Rounds(&spinner));
        let obs = session.take_store();
        Ok((stats, obs, sol, rep))
    };
    let mut start = clock.start.unwrap_or(0.0);
    let mut first = attempt(start)?;
    let trusted = first.0.clock.trusted();
    if !trusted && clock.estimate {
        drift.set(true);
        first = attempt(start)?;
    }
    // An untrusted LiDAR clock: start where its RMCs put it (INS time = LiDAR time - its
    // error).
    if clock.start.is_none() && !trusted {
        if let Some(e) = first.0.clock.rmc_offset_s().filter(|e| e.abs() > 0.5) {
            start = -e;
            first = attempt(start)?;
        }
    }
    let search = clock
        .search
        .or((!trusted && clock.estimate).then_some(DEFAULT_SEARCH_S));
    let mut searched = Vec::new();
    let search =
        search.map(|h| search_half_width(start, h, first.0.align.lidar_span, first.0.ins.span));
    if let Some(half) = search.filter(|h| *h > 0.0 && clock.estimate) {
        searched = search_time_offset(start, half, &first.2, &mut attempt)?;
        if let Some(best) = best_candidate(&searched) {
            let found = best.found_s.unwrap_or(best.start_s);
            if (found - (start + first.2.dt)).abs() > 5e-4 {
                start = found;
                first = attempt(start)?;
            }
        }
    }
    let mut applied = start;
    let mut collections = 1;
    // Each collection's time offset [s] (the windows' plus the solve's) and its sigma.
    let mut found: Vec<(f64, f64)> = Vec::new();
    let unsettled;
    let (stats, obs, sol, mut rep) = loop {
        let (stats, obs, sol, rep) = first;
        found.push((applied + sol.dt, sol.lm.map_or(f64::NAN, |l| l.sigma_dt)));
        // Again with the offset found, while it moves enough to matter (the session's one
        // rule), at most five collections.
        let next = crate::session::next_offset(
            applied,
            start,
            clock.estimate,
            sol.dt,
            sol.lm.is_some_and(|l| l.converged),
        );
        let Some(next) = next.filter(|_| collections < 5) else {
            // At the last collection still moving: not settled.
            unsettled = next.is_some();
            break (stats, obs, sol, rep);
        };
        applied = next;
        first = attempt(applied)?;
        collections += 1;
    };
    if let (true, true, Some(why)) = (rep.converged, unsettled, unsettled_offset(&found)) {
        rep.converged = false;
        rep.reason = Some(why);
    }
    // A refusal: the radii first, a wrong one is the cause of whatever else went wrong (a
    // claim passed the passes' consistency, which a wrong radius fails: seen from two sides,
    // a sphere's centre moves by twice the error).
    if !rep.converged {
        crate::radius::name_first(&mut rep, &obs, targets, ids, &inp.mount, &extract);
    }
    spinner.finish_and_clear();
    rep.time_offset_search = searched;
    rep.start.insert("time_offset".to_string(), start);
    rep.batch_overflow = stats.align.batch_overflow;
    let mut inputs = InputsReport::of(inp, &stats);
    inputs.accuracy = used_accuracy;
    rep.inputs = Some(inputs);
    // Windows that caught nothing: how far the trajectory came from those spheres says why.
    if !rep.converged && !matches!(sol.refusal, Some(Refusal::InsClockStep(_))) {
        let reach = inp.model.unwrap_or_default().max_range_m();
        let empty: Vec<(&str, Closest, f64)> = obs
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_empty())
            .filter_map(|(k, _)| {
                let c = *stats.closest.get(k)?;
                Some((ids[k].as_str(), c, targets[k].radius + inp.margin))
            })
            .collect();
        // No window caught anything: the heights are tested before the mounting is blamed.
        // (A probe that cannot read the inputs again says nothing: the refusal stands.)
        let heights = if empty.len() == obs.len() {
            crate::vertical::columns(inp, targets)
                .ok()
                .and_then(|m| crate::vertical::heights_off(&m, targets, ids, inp.margin))
        } else {
            None
        };
        if let Some(why) = heights.or_else(|| empty_windows(&empty, reach)) {
            rep.reason = Some(format!(
                "{why}{}",
                rep.reason.map(|r| format!("; so {r}")).unwrap_or_default()
            ));
        }
    }
    // The clocks' refusals are the core's (`Settings::clocks`); their words name the LiDAR
    // clock's state.
    if let Some(r) = &sol.refusal {
        if matches!(r, Refusal::LidarClockUntrusted { .. }) {
            rep.reason = Some(refusal_text_clock(
                r,
                ids,
                &[],
                Some(&stats.clock.describe()),
                clock.estimate,
            ));
        }
    }
    Ok((stats, obs, sol, rep))
}

/// Site targets and ids.
pub fn site_targets(inp: &Inputs) -> (Vec<Target>, Vec<String>) {
    let (_, t) = targets(&inp.site);
    (t, inp.site.sphere.iter().map(|s| s.id.clone()).collect())
}

//! The rig's solver thread: collects the windowed batches, solves when the windows hold enough, keeps the time offset and the report current.

use super::shared::{SolverHandle, SolverOut};
use super::watch::Steer;
use super::{LIVE_MARGIN_FLOOR_M, LIVE_MARGIN_RMS, MAX_OBS_PER_SPHERE};
use crate::pipeline::BatchMsg;
use crate::report::Report;
use spherecal::align::window::{Observation, Target};
use spherecal::calib::Settings;
use spherecal::georef::Params;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Anything that arrived is solved with at most this long after the last solve [s].
pub(super) const RESOLVE_S: u64 = 5;

/// What the solver thread solves for and how it judges: the run's plan and options.
pub(super) struct SolverPlan<'a> {
    /// The spheres and their names.
    pub(super) targets: &'a [Target],
    /// See `targets`.
    pub(super) ids: &'a [String],
    /// The start (the a-priori mounting).
    pub(super) b0: &'a Params,
    /// The calibration's settings (the site's and the board's).
    pub(super) settings: &'a Settings,
    /// Where the navigation model came from, in words.
    pub(super) nav_source: &'a str,
    /// The INS's output rate [Hz].
    pub(super) ins_rate_hz: f64,
    /// The targets the verdict judges by: the site's [calibration], else the board's, else the
    /// default (as `calibrate` judges).
    pub(super) accuracy: crate::config::goal::TargetChoice,
    /// The LiDAR model.
    pub(super) model: spherecal::velodyne::Model,
    /// The a-priori window margin [m].
    pub(super) apriori_margin: f64,
    /// Where to keep the report current.
    pub(super) report: Option<&'a Path>,
    /// Spans left out by hand (GPS s or seconds of the week).
    pub(super) exclude: &'a [(f64, f64)],
    /// Claim although the LiDAR clock is not PPS-locked (`run --allow-unlocked-clock`).
    pub(super) allow_unlocked: bool,
}

impl<'a> SolverPlan<'a> {
    /// The run's plan and options.
    pub(super) fn of(opts: &'a super::RunOptions, plan: &'a super::inputs::Plan) -> Self {
        let accuracy = crate::config::goal::TargetChoice::of(
            opts.site.as_ref().and_then(|s| s.calibration.as_ref()),
            Some(&opts.board.calibration),
        );
        Self {
            targets: &plan.targets,
            ids: &plan.ids,
            b0: &plan.b0,
            settings: &plan.settings,
            nav_source: &plan.nav_source,
            ins_rate_hz: opts.board.ins.rate_hz,
            accuracy,
            model: opts.board.lidar_model().unwrap_or_default(),
            apriori_margin: plan.margin,
            report: opts.report.as_deref(),
            exclude: &opts.exclude,
            allow_unlocked: opts.allow_unlocked_clock,
        }
    }
}

/// The live calibration: the session, the start and the live planner, solved on demand.
struct LiveSolve<'p> {
    plan: &'p SolverPlan<'p>,
    sh: SolverHandle<'p>,
    session: crate::session::Session,
    start: Params,
    /// The planner on the survey under way (built at the first solve: the LiDAR's rpm is
    /// known by then).
    planner: Option<crate::plan::live::Live>,
    goal: crate::config::goal::Goal,
}

impl<'p> LiveSolve<'p> {
    /// The session with the same settings, workspace and offset rule as `calibrate`.
    fn new(plan: &'p SolverPlan<'p>, sh: SolverHandle<'p>) -> Self {
        let session = crate::session::Session::new(
            plan.targets.to_vec(),
            plan.ids.to_vec(),
            *plan.settings,
            plan.nav_source,
        )
        .with_capacity(MAX_OBS_PER_SPHERE);
        Self {
            plan,
            sh,
            session,
            start: *plan.b0,
            planner: None,
            goal: plan.accuracy.goal(),
        }
    }

    /// One solve on the store: the report (kept current on disk), the verdict published,
    /// and on convergence the windows and the store moved to the solution.
    fn solve(&mut self) -> Report {
        let (plan, sh) = (self.plan, self.sh);
        // The clocks as the position packets and the INS stream told them so far: the live
        // verdict claims and refuses by the same rule as `calibrate`.
        let (clock, first) = sh
            .aligner
            .clock
            .lock()
            .map(|c| c.clone())
            .unwrap_or_default();
        let steps = sh.readers.ins_watch.clock_steps();
        let clocks = crate::session::clock_facts(
            &clock,
            &steps,
            first.map(|t| (t, f64::INFINITY)),
            self.session.offset_ns() as f64 * 1e-9,
            plan.allow_unlocked,
        );
        let (sol, mut rep) = self
            .session
            .solve(&self.start, clocks, &mut StatusRounds(sh.solver));
        rep.targets = Some(crate::report::TargetsReport::of(&rep, &plan.accuracy));
        sh.solver.solves.fetch_add(1, Ordering::Relaxed);
        self.judge(&sol, &rep);
        if rep.converged {
            self.follow(&sol, &rep);
        }
        if let Some(p) = plan.report {
            if let Err(e) = crate::report::write_json_atomically(p, &rep) {
                sh.said.error(e.to_string());
            }
        }
        rep
    }

    /// Enough yet? The verdict (from the kept returns, before the store is pruned) with the
    /// live planner's advice, published.
    fn judge(&mut self, sol: &spherecal::calib::Solution, rep: &Report) {
        let (plan, sh) = (self.plan, self.sh);
        let (targets, settings, rate) = (plan.targets, plan.settings, plan.ins_rate_hz);
        let store = self.session.store();
        let (info, returns) = crate::verdict::data_info(targets, store, sol, settings, rate);
        let predicted = crate::verdict::predicted_sigma(targets, store, sol, settings, rate);
        if self.planner.is_none() {
            let rpm = sh.readers.heard[0]
                .lock()
                .ok()
                .and_then(|h| h.rpm)
                .unwrap_or(600.0);
            let l =
                crate::plan::live::Live::new(targets, plan.ids, plan.model, rpm, rate, settings);
            match l {
                Ok(l) => self.planner = Some(l),
                Err(e) => sh.said.error(format!("the live planner: {e}")),
            }
        }
        let goal = Some(&self.goal);
        let advice = self.planner.as_mut().and_then(|l| {
            if let Err(e) = l.update(sol, store) {
                sh.said.error(format!("the live planner: {e}"));
                return None;
            }
            let nav = crate::verdict::nav_plan(targets, store, sol, settings);
            l.has_candidates()
                .then(|| l.advise(&info, &returns, goal, nav.as_ref()))
        });
        let verdict = self
            .session
            .claim(sol, rep, goal, Some(&predicted), advice.as_ref());
        if let Ok(mut v) = sh.solver.verdict.lock() {
            *v = Some(verdict);
        }
    }

    /// A converged solve: the time offset published, the windows and the store moved to the
    /// offset found (the session's rule, as `calibrate`'s), the aligner's windows around the
    /// solution as tight as its residuals allow, the store pruned, the calibration shown.
    fn follow(&mut self, sol: &spherecal::calib::Solution, rep: &Report) {
        let sh = self.sh;
        if let Ok(mut t) = sh.solver.time_offset.lock() {
            *t = Some((rep.time_offset_s, rep.sigma.time_offset_s));
        }
        let offset = self.session.wants_offset(sol);
        if let Some(to) = offset {
            self.session.rebase(to);
        }
        self.start = sol.b;
        let rms = if rep.rms_m.is_finite() {
            rep.rms_m
        } else {
            0.0
        };
        let margin = (LIVE_MARGIN_RMS * rms)
            .clamp(LIVE_MARGIN_FLOOR_M, crate::session::KEEP_NEAR_M)
            .min(self.plan.apriori_margin);
        sh.solver.steer.send_if(|now| {
            let moved = now.windows.is_none_or(|(b, m)| {
                (m - margin).abs() > 0.05
                    || b.0.iter().zip(sol.b.0).any(|(a, c)| (a - c).abs() > 1e-4)
            });
            (moved || offset.is_some()).then(|| Steer {
                time_offset_ns: offset.unwrap_or(now.time_offset_ns),
                windows: if moved {
                    Some((sol.b, margin))
                } else {
                    now.windows
                },
                windows_moved: now.windows_moved + u64::from(moved),
            })
        });
        let mount = sol.b.mount();
        for (v, t) in self.session.store_mut().iter_mut().zip(self.plan.targets) {
            v.retain(|o| crate::session::near(o, t, &mount, 0.0));
        }
        let d = sol.b.deg_m().0;
        // The sigmas are in the parameters' units.
        let s = sol.lm.map_or([f64::NAN; 6], |l| Params(l.sigma).deg_m().0);
        if let Ok(mut c) = sh.solver.calibration.lock() {
            *c = Some((d, s));
        }
    }
}

/// The solver thread: batches into the session until the channel closes; a solve when every
/// sphere has enough returns, again as the store grows, and at the end.
pub(super) fn solver(
    rx: crossbeam_channel::Receiver<BatchMsg>,
    pool: crossbeam_channel::Sender<Vec<Observation>>,
    plan: &SolverPlan<'_>,
    sh: SolverHandle<'_>,
) -> Option<Report> {
    let n = plan.targets.len();
    let mut live = LiveSolve::new(plan, sh);
    let mut last_total = 0usize;
    let mut excluding = false;
    let mut last_solve: Option<Instant> = None;
    let mut latest: Option<Report> = None;
    loop {
        let closed = match rx.recv_timeout(Duration::from_millis(200)) {
            Ok(m) => {
                // The spans left out by hand, placed in the data's GPS week at the first batch.
                if let (false, Some(o)) = (plan.exclude.is_empty() || excluding, m.obs.first()) {
                    live.session
                        .exclude(&crate::stretches::in_week_of(plan.exclude, o.time));
                    excluding = true;
                }
                // Aligned at an older offset (in flight when it moved): the session moves it
                // to the store's.
                let dropped = live.session.add(m.sphere, &m.obs, m.offset_ns);
                sh.aligner
                    .batch_drops
                    .fetch_add(dropped as u64, Ordering::Relaxed);
                let _ = pool.try_send(m.obs);
                false
            }
            Err(crossbeam_channel::RecvTimeoutError::Timeout) => false,
            Err(crossbeam_channel::RecvTimeoutError::Disconnected) => true,
        };
        if n == 0 {
            if closed {
                return None;
            }
            continue;
        }
        let store = live.session.store();
        let total: usize = store.iter().map(Vec::len).sum();
        let ready = store.iter().all(|s| s.len() >= plan.settings.min_points);
        if closed {
            if ready && total > last_total {
                latest = Some(live.solve());
            }
            return latest;
        }
        // Solve when every sphere has enough returns, then again each time the store has
        // grown by a quarter over what the last solve left in it (a converged solve prunes
        // it), at most once a second, or when anything arrived in the [`RESOLVE_S`] since the
        // last solve (passes at long range add few returns: they must count too); and at the
        // end if anything arrived since.
        let since = last_solve.map(|t| t.elapsed());
        let due = since.is_none_or(|e| e >= Duration::from_secs(1));
        let stale = since.is_none_or(|e| e >= Duration::from_secs(RESOLVE_S));
        if ready && due && total > last_total && (total * 4 >= last_total * 5 || stale) {
            latest = Some(live.solve());
            last_total = live.session.store().iter().map(Vec::len).sum();
            last_solve = Some(Instant::now());
        }
    }
}

/// The solve's rounds on the status line's `solve=` (the core's observer hook).
struct StatusRounds<'a>(&'a SolverOut);

impl spherecal::calib::solve::Observe for StatusRounds<'_> {
    fn round(&mut self, n: usize, _: &spherecal::calib::solve::Round) {
        if let Ok(mut s) = self.0.solve_state.lock() {
            *s = format!("r{n}");
        }
    }
    fn ended(&mut self, how: spherecal::calib::Termination, rounds: usize) {
        if let Ok(mut s) = self.0.solve_state.lock() {
            *s = format!("{}:{rounds}", how.name());
        }
    }
}

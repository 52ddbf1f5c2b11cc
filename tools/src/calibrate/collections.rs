//! The file command's collections: the windows collected at a time offset and solved by the
//! session, again at each offset found until it settles; and the words a refusal gets from
//! what the collections saw.

use super::{best_candidate, collect_bounded, DEFAULT_SEARCH_S, STORE_CAP};
use super::{search_half_width, search_time_offset, unsettled_offset, Calibrated, ClockOptions};
use crate::config::nav_errors::CorrelatedSpec;
use crate::config::nav_source::InsKind;
use crate::pipeline::accuracy::{Accuracy, AccuracyReport};
use crate::pipeline::{Closest, Inputs, InsInput, RunStats};
use crate::reasons::{empty_windows, refusal_text_clock, unknown_offset};
use crate::report::{Report, SearchCandidate};
use crate::session::{settings_for, settings_under, Session};
use spherecal::align::window::{Observation, Target};
use spherecal::calib::solve::{Refusal, Solution};
use spherecal::calib::Settings;
use spherecal::georef::Params;

/// One calibration's collections over the files of `inp`, and what the first decided.
pub(super) struct Collections<'a> {
    pub(super) inp: &'a mut Inputs,
    targets: &'a [Target],
    ids: &'a [String],
    b0: &'a Params,
    clock: ClockOptions,
    /// The settings under the site's own navigation model: the first collection's (before
    /// the model is chosen from what the INS stated).
    base: Settings,
    /// The session, made at the first collection under the navigation model chosen then.
    session: Option<Session>,
    /// The SBET's accuracy file.
    accuracy: Option<Accuracy>,
    /// What the accuracy file gave the returns, for the report.
    pub(super) used_accuracy: Option<AccuracyReport>,
    /// The INS, for its default navigation model.
    kind: InsKind,
    /// The site's navigation model, if it declares one.
    site_spec: Option<CorrelatedSpec>,
    /// The rounds on a spinner (on a terminal only).
    pub(super) spinner: indicatif::ProgressBar,
    /// Called after each collection, before its solve.
    collected: &'a mut dyn FnMut(),
    /// The collections made.
    collections: u32,
}

impl<'a> Collections<'a> {
    /// The collections of `inp` (its model resolved once: every collection decodes as it, and the
    /// extraction's scan lines follow its laser period), its accuracy file read.
    pub(super) fn new(
        inp: &'a mut Inputs,
        targets: &'a [Target],
        ids: &'a [String],
        b0: &'a Params,
        clock: ClockOptions,
        collected: &'a mut dyn FnMut(),
    ) -> Result<Self, crate::Error> {
        if let Some((m, _)) = crate::pipeline::resolve_model(inp)? {
            inp.model = Some(m);
        }
        let settings = settings_for(&inp.site, inp.lidar(), clock.estimate, inp.margin);
        let accuracy = match (&inp.accuracy, &inp.ins) {
            (Some(p), InsInput::Sbet(_, week)) => Some(Accuracy::load(
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
        // The navigation model: the site's, else what the INS stated in the data, else its
        // kind's default (`nav_source`), chosen at the first collection.
        let kind = match &inp.ins {
            InsInput::Vn200(_) | InsInput::Bag(..) => InsKind::Vn200,
            InsInput::Sbet(..) => InsKind::Sbet,
            InsInput::Posmv(..) => InsKind::PosmvRealTime,
        };
        let site_spec = inp.site.ins.as_ref().map(|i| i.correlated.clone());
        Ok(Self {
            targets,
            ids,
            b0,
            clock,
            base: settings,
            session: None,
            accuracy,
            used_accuracy: None,
            kind,
            site_spec,
            spinner: crate::progress::spinner("solving"),
            inp,
            collected,
            collections: 0,
        })
    }

    /// Collect the windows at the time offset `applied` [s] and solve them.
    pub(super) fn attempt(&mut self, applied: f64) -> Result<Calibrated, crate::Error> {
        self.attempt_for(applied, false)
    }

    /// As [`Self::attempt`] for one start of the time-offset search ([`Session::solve_start`]).
    fn attempt_start(&mut self, applied: f64) -> Result<Calibrated, crate::Error> {
        self.attempt_for(applied, true)
    }

    /// [`Self::attempt`], its solve a search start's when `start`.
    fn attempt_for(&mut self, applied: f64, start: bool) -> Result<Calibrated, crate::Error> {
        let inp = &mut *self.inp;
        inp.time_offset_ns = (applied * 1e9).round() as i64;
        let settings = self.session.as_ref().map_or(&self.base, Session::settings);
        let (stats, mut obs) = collect_bounded(inp, self.targets, self.b0, settings, STORE_CAP)?;
        self.collections += 1;
        (self.collected)();
        let session = match &mut self.session {
            Some(s) => s,
            None => {
                // The navigation model, chosen once: the site's, else what the INS stated in
                // the data, else its kind's default; the settings made under it.
                let stated = self
                    .accuracy
                    .as_ref()
                    .map(|a| &a.stated)
                    .filter(|s| s.samples > 0)
                    .unwrap_or(&stats.ins.stated);
                let c = crate::config::nav_source::choose(
                    self.site_spec.as_ref(),
                    None,
                    Some(stated),
                    self.kind,
                )?;
                let (site, est) = (&inp.site, self.clock.estimate);
                let settings = settings_under(site, inp.lidar(), est, inp.margin, c.model);
                let (t, ids) = (self.targets.to_vec(), self.ids.to_vec());
                let session = self
                    .session
                    .insert(Session::new(t, ids, settings, &c.source).on_two_cores());
                // An offset the user gave is known, whatever the clocks say.
                if self.clock.start.is_some() {
                    session.know_offset();
                }
                session
            }
        };
        // The accuracy file's sigmas weigh each return, unless a navigation model holds them.
        if let Some(a) = &self.accuracy {
            self.used_accuracy = Some(match session.nav().filter(|m| !m.is_white()) {
                None => a.apply(&mut obs),
                Some(_) => a.unapplied(),
            });
        }
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
            self.clock.allow_unlocked,
        );
        // The report's offset includes the one the windows were made at.
        let watch = &mut crate::progress::Rounds(&self.spinner);
        let (sol, rep) = if start {
            session.solve_start(self.b0, clocks, watch)
        } else {
            session.solve(self.b0, clocks, watch)
        };
        let obs = session.take_store();
        Ok((stats, obs, sol, rep))
    }

    /// The first collection: at the start offset (for a LiDAR clock that is not trusted, again
    /// from where its RMCs put it), then the coarse search around it when asked or the clock is
    /// untrusted. A solve the search follows is its centre's, solved as a start (its refusal
    /// left as it is); the collection the search picks is solved as any other, and so is the
    /// centre's again when the search found nothing and it was refused. The start, the
    /// collection, the search.
    pub(super) fn first(
        &mut self,
    ) -> Result<(f64, Calibrated, Vec<SearchCandidate>), crate::Error> {
        let clock = self.clock;
        let mut start = clock.start.unwrap_or(0.0);
        // Whether a search of half-width `h` [s] runs: its centre's solve is then a start's.
        let searches = |h: Option<f64>| clock.estimate && h.is_some_and(|h| h > 0.0);
        let mut as_start = searches(clock.search);
        let mut first = self.attempt_for(start, as_start)?;
        let trusted = first.0.clock.trusted();
        let search = clock
            .search
            .or((!trusted && clock.estimate).then_some(DEFAULT_SEARCH_S));
        // An untrusted LiDAR clock: start where its RMCs put it (INS time = LiDAR time - its
        // error).
        if clock.start.is_none() && !trusted {
            if let Some(e) = first.0.clock.rmc_offset_s().filter(|e| e.abs() > 0.5) {
                start = -e;
                as_start = searches(search);
                first = self.attempt_for(start, as_start)?;
            }
        }
        let mut searched = Vec::new();
        let search =
            search.map(|h| search_half_width(start, h, first.0.align.lidar_span, first.0.ins.span));
        if let Some(half) = search.filter(|&h| searches(Some(h))) {
            searched = search_time_offset(start, half, &first.2, &mut |a| self.attempt_start(a))?;
            if let Some(best) = best_candidate(&searched) {
                let found = best.found_s.unwrap_or(best.start_s);
                // Found by the data: a refusal at it is no longer the clock's to explain.
                if let Some(s) = self.session.as_mut() {
                    s.know_offset();
                }
                if (found - (start + first.2.dt)).abs() > 5e-4 || !first.3.converged {
                    start = found;
                    first = self.attempt(start)?;
                    as_start = false;
                }
            }
        }
        if as_start && !first.3.converged {
            first = self.attempt(start)?;
        }
        Ok((start, first, searched))
    }

    /// Collect again at the offset found while it moves enough to matter (the session's one
    /// rule), five collections at most; the last, and why it is refused when the offset never
    /// settled.
    pub(super) fn settle(
        &mut self,
        start: f64,
        mut first: Calibrated,
    ) -> Result<(Calibrated, Option<String>), crate::Error> {
        let mut applied = start;
        let mut collections = 1;
        // Each collection's time offset [s] (the windows' plus the solve's) and its sigma.
        let mut found: Vec<(f64, f64)> = Vec::new();
        loop {
            let sol = &first.2;
            found.push((applied + sol.dt, sol.lm.map_or(f64::NAN, |l| l.sigma_dt)));
            let next = crate::session::next_offset(
                applied,
                start,
                self.clock.estimate,
                sol.dt,
                sol.lm.is_some_and(|l| l.converged),
            );
            // A radius the returns do not show: no offset mends it.
            let radius = self.session.as_ref().is_some_and(Session::radius_named);
            let Some(next) = next.filter(|_| collections < 5 && !radius) else {
                // At the last collection still moving: not settled.
                let why = next.and_then(|_| unsettled_offset(&found));
                return Ok((first, why));
            };
            applied = next;
            // The last collection's returns go before the next is gathered.
            first.1 = Vec::new();
            first = self.attempt(applied)?;
            collections += 1;
        }
    }

    /// What the calibration ran so far.
    pub(super) fn effort(&self) -> crate::report::Effort {
        let (solves, radius_probes) = self.session.as_ref().map_or((0, 0), Session::effort);
        crate::report::Effort {
            collections: self.collections,
            solves,
            radius_probes,
        }
    }

    /// A refusal in the words of what the collections saw: windows that caught nothing (how
    /// far the trajectory came from those spheres, or heights that are off), a LiDAR clock's
    /// state.
    pub(super) fn explain(
        &self,
        rep: &mut Report,
        sol: &Solution,
        obs: &[Vec<Observation>],
        stats: &RunStats,
    ) {
        let (inp, targets, ids) = (&*self.inp, self.targets, self.ids);
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
            // No window caught anything: the heights are tested before the mounting is
            // blamed. (A probe that cannot read the inputs again says nothing: the refusal
            // stands.)
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
                    rep.reason
                        .take()
                        .map(|r| format!("; so {r}"))
                        .unwrap_or_default()
                ));
            }
        }
        // The session's words for an offset nothing tells, with the clock's state.
        if let Some(r) = rep.reason.as_mut() {
            let (general, words) = (
                unknown_offset(None),
                unknown_offset(Some(&stats.clock.describe())),
            );
            *r = r.replacen(&general, &words, 1);
        }
        // The clocks' refusals are the core's (`Settings::clocks`); their words name the LiDAR
        // clock's state.
        if let Some(r @ Refusal::LidarClockUntrusted { .. }) = &sol.refusal {
            rep.reason = Some(refusal_text_clock(
                r,
                ids,
                &[],
                Some(&stats.clock.describe()),
                self.clock.estimate,
            ));
        }
    }
}

//! A refused solve looked into ([`Session::solve`]): the time offset an untrusted LiDAR clock
//! leaves unknown or its RMC belies, else a radius the returns do not show
//! ([`super::radius`]), else a stretch of the survey set aside ([`crate::stretches`]).

use super::{radius, solve_report_in, Session};
use crate::reasons::{belied_offset, unknown_offset};
use crate::report::Report;
use spherecal::calib::solve::Refusal;
use spherecal::calib::{Settings, Solution};
use spherecal::georef::Params;

impl Session {
    /// A refusal looked into. Under a LiDAR clock whose offset nothing tells (no PPS, no RMC
    /// time, neither searched nor given), or applied beyond where its RMC time puts it, the
    /// offset is named first: a second's error smears each sphere metres along the track, which
    /// reads as a larger radius or a bad stretch, so neither is probed. Else the radii first: a
    /// wrong one is the cause of whatever else went wrong (a claim passed the passes'
    /// consistency, which a wrong radius fails: seen from two sides, a sphere's centre moves by
    /// twice the error), and no stretch set aside helps; then a stretch set aside.
    pub(super) fn look_into(
        &mut self,
        b0: &Params,
        s: &Settings,
        mut sol: Solution,
        mut rep: Report,
    ) -> (Solution, Report) {
        let u = s.clocks.lidar_untrusted;
        let untold = u.is_some_and(|u| u.rmc_offset_s.is_none()) && !self.offset_known;
        // The stamps' RMC time puts the offset within half a second (its whole second) of
        // `-e`, and the one applied is beyond (`calibrate` collects again where the RMC puts it,
        // unless one was given).
        let belied = u.and_then(|u| {
            let e = u.rmc_offset_s?;
            ((u.applied_s + e).abs() > 0.55).then_some((u.applied_s, e))
        });
        if untold || belied.is_some() {
            if !matches!(sol.refusal, Some(Refusal::LidarClockUntrusted { .. })) {
                let head = match belied {
                    Some((applied, e)) => belied_offset(applied, e),
                    None => unknown_offset(None),
                };
                let why = rep.reason.take().map(|r| format!("; so: {r}"));
                rep.reason = Some(head + &why.unwrap_or_default());
            }
            return (sol, rep);
        }
        let mount = spherecal::georef::Mount::from_params(b0);
        self.radius_probes += 1;
        let (store, targets, ex) = (&self.store, &self.targets, &s.extract);
        let radii = radius::apparent(store, targets, &mount, ex, &mut self.scratch);
        let wrong = radius::disagreement(&radii, &self.targets, &self.ids);
        if wrong.is_none() {
            if let Some(found) = self.set_aside(b0, s, &sol) {
                (sol, rep) = (found.0, found.1);
                let sp = found.2;
                let span = ((sp.from_gps_s * 1e9) as i64, (sp.to_gps_s * 1e9) as i64);
                self.excluded.push((span, sp.returns, sp.why));
            }
        }
        if !rep.converged {
            self.radius_named = wrong.is_some();
            radius::name_first(&mut rep, &radii, wrong);
        }
        (sol, rep)
    }

    /// When `sol` was refused for a reason one stretch of the survey may explain
    /// ([`crate::stretches`]): the first candidate stretch without which the rest is claimed,
    /// holding at most a third of the kept returns, taken out of the store for good, with the
    /// solve without it; `None` (the store as it was) when none is.
    fn set_aside(
        &mut self,
        b0: &Params,
        s: &Settings,
        sol: &Solution,
    ) -> Option<(Solution, Report, crate::stretches::SetAsideSpan)> {
        use crate::stretches::{candidates, locatable, restore, split, SetAsideSpan, MAX_FRACTION};
        let r = sol.refusal.filter(locatable)?;
        let kept: u32 = sol.passes.iter().map(|p| p.verdicts[1]).sum();
        for span in candidates(&sol.passes, &r) {
            let within: u32 = sol
                .passes
                .iter()
                .filter(|p| p.start.0 >= span.0 && p.end.0 <= span.1)
                .map(|p| p.verdicts[1])
                .sum();
            if f64::from(within) > MAX_FRACTION * f64::from(kept) {
                continue;
            }
            let cut = split(&mut self.store, span);
            self.solves += 1;
            let (sol2, rep2) = solve_report_in(
                &self.targets,
                &self.ids,
                &mut self.store,
                b0,
                s,
                &mut self.scratch,
                &mut (),
            );
            if sol2.refusal.is_none()
                && sol2.lm.is_some_and(|l| l.converged)
                && crate::stretches::clean(&sol2).is_ok()
            {
                let span = SetAsideSpan {
                    from_gps_s: span.0 as f64 * 1e-9,
                    to_gps_s: span.1 as f64 * 1e-9,
                    returns: cut.iter().map(Vec::len).sum(),
                    why: format!(
                        "with it the survey was refused ({}); without it every check passes",
                        crate::reasons::refusal_text(&r, &self.ids, &[], s.estimate_dt)
                    ),
                };
                return Some((sol2, rep2, span));
            }
            restore(&mut self.store, cut);
        }
        None
    }
}

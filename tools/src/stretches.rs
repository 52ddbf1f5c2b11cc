//! Stretches of a survey set aside: by hand (`--exclude GPS_T0..GPS_T1`), and where a refusal
//! is located in time and the rest of the survey passes every check without the stretch
//! (issue 46: one bad stretch, a 4 s multipath jump or a silent GNSS outage, must not refuse a
//! whole day's survey, nor leave a remnant on which a wrong claim stands).
//!
//! A stretch is a sphere visit: the passes over the spheres (the core's [`PassReport`]s),
//! joined where they overlap in time. The candidates for a refusal are the stretches (one, or
//! two in a row: an outage spanning a visit and ending in the next) that hold its time (a
//! navigation jump, an inconsistent pass), or, for a refusal of the whole (a remnant, noise
//! beyond the model), every one, those whose passes kept the least of what their detections
//! saw first. Each candidate is solved without its returns; the first that the rest claims is
//! taken, when it holds at most a third of the kept returns.

use serde::{Deserialize, Serialize};
use spherecal::align::window::Observation;
use spherecal::calib::solve::{PassReport, Refusal};
use spherecal::time::GpsTime;

/// A stretch of the survey whose returns were left out.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SetAsideSpan {
    /// First and last GPS time [s since 1980-01-06].
    pub from_gps_s: f64,
    /// See `from_gps_s`.
    pub to_gps_s: f64,
    /// Windowed returns left out (all spheres).
    pub returns: usize,
    /// Why: `by hand` (`--exclude`) or the refusal the rest of the survey did not repeat.
    pub why: String,
}

impl SetAsideSpan {
    /// The span in words, seconds after `first` (the survey's first return) too.
    pub fn describe(&self, first_gps_s: Option<f64>) -> String {
        let into = first_gps_s.map_or(String::new(), |f| {
            format!(
                " ({:.1}-{:.1} s into the data)",
                self.from_gps_s - f,
                self.to_gps_s - f
            )
        });
        format!(
            "GPS {:.1}..{:.1}{into}, {:.1} s, {} windowed returns: {}",
            self.from_gps_s,
            self.to_gps_s,
            self.to_gps_s - self.from_gps_s,
            self.returns,
            self.why
        )
    }
}

/// A time span given as `T0..T1` [GPS s since 1980-01-06, or seconds of the GPS week when
/// both are below 604,800]: (start, end) [s].
pub fn parse_span(text: &str) -> Result<(f64, f64), crate::Error> {
    let bad = || {
        format!("--exclude {text:?}: expected GPS_T0..GPS_T1 (GPS seconds as the reports print them, or seconds of the GPS week), T0 < T1")
    };
    let (a, b) = text.split_once("..").ok_or_else(bad)?;
    let (a, b): (f64, f64) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    if !(a.is_finite() && b.is_finite() && a >= 0.0 && a < b) {
        return Err(bad().into());
    }
    Ok((a, b))
}

/// Spans given in seconds of the GPS week placed in the week of `t` [GPS ns]: absolute spans
/// are kept.
pub fn in_week_of(spans: &[(f64, f64)], t: GpsTime) -> Vec<(i64, i64)> {
    const WEEK: f64 = 604_800.0;
    let week_start = (t.0 as f64 * 1e-9 / WEEK).floor() * WEEK;
    spans
        .iter()
        .map(|&(a, b)| {
            let shift = if b < WEEK { week_start } else { 0.0 };
            (((a + shift) * 1e9) as i64, ((b + shift) * 1e9) as i64)
        })
        .collect()
}

/// Take the returns within `span` [GPS ns, inclusive] out of each sphere's store; how many.
pub fn remove(store: &mut [Vec<Observation>], span: (i64, i64)) -> usize {
    let mut n = 0;
    for v in store.iter_mut() {
        let before = v.len();
        v.retain(|o| o.time.0 < span.0 || o.time.0 > span.1);
        n += before - v.len();
    }
    n
}

/// Move the returns within `span` to the end of each sphere's store and cut them off: the
/// store without them, and what was cut (to put back with [`restore`]).
pub fn split(store: &mut [Vec<Observation>], span: (i64, i64)) -> Vec<Vec<Observation>> {
    store
        .iter_mut()
        .map(|v| {
            let mut k = 0;
            for i in 0..v.len() {
                let t = v[i].time.0;
                if t < span.0 || t > span.1 {
                    v.swap(i, k);
                    k += 1;
                }
            }
            v.split_off(k)
        })
        .collect()
}

/// Put back what [`split`] cut.
pub fn restore(store: &mut [Vec<Observation>], cut: Vec<Vec<Observation>>) {
    for (v, c) in store.iter_mut().zip(cut) {
        v.extend(c);
    }
}

/// Most candidates solved for one refusal.
pub const MAX_TRIES: usize = 12;
/// A candidate may hold at most this fraction of the kept returns.
pub const MAX_FRACTION: f64 = 1.0 / 3.0;

/// The rest of a survey with a stretch set aside must pass stricter checks than a survey as a
/// whole (the stretch was chosen because the rest then passes, and what is left of a fault
/// beside it must not pass unseen): each pass's centre at most this chi-square (3 degrees of
/// freedom, p = 0.01) ...
pub const CLEAN_PASS_CHI2: f32 = 11.3;
/// ... each pass's own time offset within this many of its sigmas of the rest's (the core
/// refuses beyond 5) ...
pub const CLEAN_DT_SIGMAS: f32 = 3.0;
/// ... the navigation's steps within this many of the model's sigmas (1.7-2.3 in surveys with
/// the declared errors) ...
pub const CLEAN_NAV_STEP_SIGMAS: f64 = 2.8;
/// ... each sphere's last extraction keeping at least this share of what the rounds kept
/// (0.36-1 in the planner's Monte Carlo of drone-noisy, 0.9-0.98 of table1-real; the core
/// refuses below 0.25) ...
pub const CLEAN_KEPT_FRACTION: f64 = 0.5;
/// ... and the white noise found at most this many times the declared (drone-noisy 1.3-1.82,
/// table1-real 0.7-0.97; the core refuses above 2.5).
pub const CLEAN_WHITE_NOISE: f64 = 2.0;

/// Whether a claimed solution passes the stricter checks ([`CLEAN_PASS_CHI2`] ...); the first
/// that fails, in words, when not.
pub fn clean(sol: &spherecal::calib::Solution) -> Result<(), String> {
    if let Some(p) = sol.passes.iter().find(|p| p.chi2 > CLEAN_PASS_CHI2) {
        return Err(format!("a pass's centre chi-square {:.1}", p.chi2));
    }
    // A clock that stepped leaves the passes after it on another time offset.
    if let Some(p) = sol
        .passes
        .iter()
        .find(|p| p.dt_sigma > 0.0 && p.dt_shift.abs() > CLEAN_DT_SIGMAS * p.dt_sigma)
    {
        return Err(format!(
            "a pass's time offset {:.1} ms off the rest ({:.1} sigma)",
            p.dt_shift * 1e3,
            p.dt_shift.abs() / p.dt_sigma
        ));
    }
    if let Some(f) = &sol.nav {
        if f.worst_step.0 > CLEAN_NAV_STEP_SIGMAS {
            return Err(format!("a navigation step of {:.1} sigma", f.worst_step.0));
        }
        if f.variance_factor.sqrt() > CLEAN_WHITE_NOISE {
            return Err(format!(
                "white noise {:.2}x the declared",
                f.variance_factor.sqrt()
            ));
        }
    }
    for sp in &sol.spheres {
        if sp.rounds_kept > 0 && (sp.used as f64) < CLEAN_KEPT_FRACTION * sp.rounds_kept as f64 {
            return Err(format!(
                "a sphere kept {} of the rounds' {}",
                sp.used, sp.rounds_kept
            ));
        }
    }
    Ok(())
}

/// Whether a refusal may be one stretch's: located in time, or of the whole but of a kind a
/// stretch of bad navigation makes. Not the clocks' (a clock that steps or drifts moves every
/// pass after it: setting one stretch aside leaves the rest on two clocks; table1-noisy with a
/// POS MV clock step of 50 ms was claimed 0.5 deg off that way), nor a sphere's survey.
pub fn locatable(r: &Refusal) -> bool {
    matches!(
        r,
        Refusal::NavigationJump { .. }
            | Refusal::Inconsistent { .. }
            | Refusal::OverDispersed { .. }
            | Refusal::Remnant { .. }
            | Refusal::Noisier { .. }
    )
}

/// The passes over the spheres as spans [GPS ns] in order of their start, each with the share
/// it kept of what its detections saw (kept / (detected slices x mean inliers), at most 1).
pub fn visits(passes: &[PassReport]) -> Vec<((i64, i64), f64)> {
    let mut v: Vec<((i64, i64), f64)> = passes
        .iter()
        .filter(|p| p.detected > 0 && p.end.0 > p.start.0)
        .map(|p| {
            let seen = f64::from(p.detected) * f64::from(p.mean_inliers);
            let kept = f64::from(p.verdicts[1]);
            ((p.start.0, p.end.0), (kept / seen.max(1.0)).min(1.0))
        })
        .collect();
    v.sort_by_key(|(s, _)| *s);
    v
}

/// The candidates for the refusal `r` of a solution with these `passes`, best first: the span
/// [GPS ns] of one pass (all spheres' returns in it), or of two or three passes in a row (an
/// outage spanning a sphere visit and ending in the next).
pub fn candidates(passes: &[PassReport], r: &Refusal) -> Vec<(i64, i64)> {
    let vs = visits(passes);
    if vs.len() < 3 {
        // Setting one aside would leave too little to tell by.
        return Vec::new();
    }
    // Runs of one to three passes in a row, each with its worst share kept.
    let mut all: Vec<((i64, i64), f64, usize)> = Vec::new();
    for n in 1..=3 {
        all.extend(vs.windows(n).map(|w| {
            let a = w.iter().map(|x| x.0 .0).min().unwrap_or(0);
            let b = w.iter().map(|x| x.0 .1).max().unwrap_or(0);
            let k = w.iter().map(|x| x.1).fold(1.0, f64::min);
            ((a, b), k, n)
        }));
    }
    let pass_mid = |k: usize| passes.get(k).map(|p| p.start.0 + (p.end.0 - p.start.0) / 2);
    let at: Option<i64> = match r {
        Refusal::NavigationJump { at, .. } => Some(at.0),
        Refusal::Inconsistent { pass, .. } => pass_mid(*pass),
        _ => None,
    };
    if let Some(t) = at {
        // Located: the candidates holding it (a second's slack: a jump is dated by the piece
        // after it).
        all.retain(|(s, _, _)| s.0 - 1_000_000_000 <= t && t <= s.1 + 1_000_000_000);
        all.sort_by(|a, b| a.2.cmp(&b.2).then(a.1.total_cmp(&b.1)));
    } else {
        // Of the whole: the passes that kept least of what they saw first.
        all.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.2.cmp(&b.2)));
    }
    let mut out: Vec<(i64, i64)> = Vec::new();
    for (s, _, _) in all {
        if !out.contains(&s) {
            out.push(s);
        }
    }
    out.truncate(MAX_TRIES);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pass(sphere: u8, a: f64, b: f64, kept: u32) -> PassReport {
        let mut verdicts = [0; 8];
        verdicts[1] = kept;
        PassReport {
            end: GpsTime((b * 1e9) as i64),
            slices: 10,
            detected: 10,
            mean_inliers: 10.0,
            verdicts,
            ..PassReport::starting(sphere, GpsTime((a * 1e9) as i64))
        }
    }

    #[test]
    fn spans_parse_and_bad_ones_are_named() {
        assert_eq!(parse_span("100.5..104").unwrap(), (100.5, 104.0));
        for bad in ["100", "104..100", "a..b", "nan..5", "-1..2"] {
            let e = parse_span(bad).unwrap_err().to_string();
            assert!(e.contains("GPS_T0..GPS_T1"), "{bad}: {e}");
        }
        // Seconds of the week go into the data's week; absolute times stay.
        let t = GpsTime(2318 * 604_800 * 1_000_000_000 + 5_000_000_000);
        let w = 2318.0 * 604_800.0;
        assert_eq!(
            in_week_of(&[(10.0, 20.0), (w + 30.0, w + 40.0)], t),
            vec![
                (((w + 10.0) * 1e9) as i64, ((w + 20.0) * 1e9) as i64),
                (((w + 30.0) * 1e9) as i64, ((w + 40.0) * 1e9) as i64)
            ]
        );
    }

    /// Passes over two spheres in order of their start; a refusal located in time gets the
    /// passes that hold it (one, then two in a row); one of the whole gets the passes that kept
    /// least first.
    #[test]
    fn visits_and_candidates() {
        let passes = [
            pass(0, 0.0, 8.0, 100),
            pass(1, 7.5, 15.0, 100),
            pass(0, 20.0, 30.0, 10),
            pass(1, 40.0, 50.0, 100),
            pass(0, 60.0, 70.0, 60),
        ];
        let v = visits(&passes);
        let s = |a: f64, b: f64| ((a * 1e9) as i64, (b * 1e9) as i64);
        assert_eq!(v.len(), 5);
        assert_eq!(v[1].0, s(7.5, 15.0));
        assert!((v[2].1 - 0.1).abs() < 1e-9);
        let jump = Refusal::NavigationJump {
            at: GpsTime((45.0 * 1e9) as i64),
            step: [0.0; 6],
            sigmas: 9.0,
        };
        assert_eq!(
            candidates(&passes, &jump),
            vec![
                s(40.0, 50.0),
                s(20.0, 50.0),
                s(40.0, 70.0),
                s(7.5, 50.0),
                s(20.0, 70.0)
            ]
        );
        let remnant = Refusal::Remnant {
            sphere: 0,
            kept: 10,
            rounds: 100,
        };
        let c = candidates(&passes, &remnant);
        assert_eq!(c[0], s(20.0, 30.0));
        assert_eq!(c.len(), 12);
    }
}

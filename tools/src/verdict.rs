//! Whether the data so far are enough: each sphere's coverage (returns kept, passes, both
//! directions, the range span) and each parameter's sigma from the solution on the data so far
//! against the board's targets; `ready`, or `collecting` with what is missing in words
//! ("S2: no southbound pass", "heading sigma 0.031 > 0.010 deg: add a pass at 8-15 m").
//! Before a solution is claimed (one pass, one direction) the sigmas are the survey planner's
//! prediction from the geometry of the returns kept so far and the noise model
//! ([`spherecal::calib::predict`]), marked `(predicted)`.

use crate::report::Report;
use serde::{Deserialize, Serialize};
use spherecal::align::window::Observation;
use spherecal::calib::solve::Solution;
use spherecal::georef::{NAMES, P};

/// A pass counts when it holds this many kept returns.
pub const MIN_PASS_RETURNS: usize = 10;

/// One sphere's coverage by the kept returns.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Coverage {
    /// Sphere id.
    pub id: String,
    /// Returns kept.
    pub returns: usize,
    /// Passes: the solver's (split at a turn past 90 deg or a gap, `Solution::passes`) with at
    /// least [`MIN_PASS_RETURNS`] kept returns.
    pub passes: usize,
    /// The compass headings of the passes' mean velocities [deg].
    pub headings_deg: Vec<f64>,
    /// Some two passes go opposite ways (mean velocities more than 120 deg apart).
    pub both_directions: bool,
    /// Shortest and longest range of a kept return [m].
    pub range_m: [f64; 2],
}

/// The verdict on the data so far.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    /// Enough: every sphere seen both ways, every sigma within its target, the solution claimed.
    pub ready: bool,
    /// What is missing, in words.
    pub missing: Vec<String>,
    /// Per sphere.
    pub coverage: Vec<Coverage>,
    /// The sigmas predicted from the geometry of the returns kept so far: the six [deg, m]
    /// and the time offset [s] (null: not determined).
    #[serde(default)]
    pub predicted_sigma: Option<[Option<f64>; 7]>,
    /// Why it is ready, in words.
    #[serde(default)]
    pub ready_because: String,
}

/// Each sphere's coverage by its kept returns (the first `used` of its observations after the
/// solve) in the solver's passes.
pub fn coverage(ids: &[String], obs: &[Vec<Observation>], sol: &Solution) -> Vec<Coverage> {
    ids.iter()
        .enumerate()
        .map(|(j, id)| {
            let used = sol.spheres.get(j).map_or(0, |s| s.used);
            let kept = obs.get(j).map_or(&[][..], |v| &v[..used.min(v.len())]);
            let passes = sol.passes.iter().filter(|p| usize::from(p.sphere) == j);
            one(id, kept, passes)
        })
        .collect()
}

fn one<'a>(
    id: &str,
    kept: &[Observation],
    passes: impl Iterator<Item = &'a spherecal::calib::solve::PassReport>,
) -> Coverage {
    let kept_of = |p: &spherecal::calib::solve::PassReport| {
        p.verdicts[spherecal::calib::extract::ReturnClass::Kept as usize] as usize
    };
    let dirs: Vec<[f64; 2]> = passes
        .filter(|p| kept_of(p) >= MIN_PASS_RETURNS && p.course != [0.0; 2])
        .map(|p| [f64::from(p.course[0]), f64::from(p.course[1])])
        .collect();
    let range_m = kept.iter().fold([f64::INFINITY, 0.0f64], |r, o| {
        let d = f64::from(o.range);
        [r[0].min(d), r[1].max(d)]
    });
    Coverage {
        id: id.to_string(),
        returns: kept.len(),
        passes: dirs.len(),
        headings_deg: dirs
            .iter()
            .map(|d| d[1].atan2(d[0]).to_degrees().rem_euclid(360.0))
            .collect(),
        both_directions: dirs
            .iter()
            .any(|a| dirs.iter().any(|b| a[0] * b[0] + a[1] * b[1] < -0.5)),
        range_m: if kept.is_empty() { [0.0; 2] } else { range_m },
    }
}

/// The information (the planner's predictor) of the returns kept so far ([`coverage`]'s) at
/// the solution, with the solver's noise model (range, INS attitude and position per sample of
/// an INS at `ins_rate_hz`, the 2 mm range step), and the returns per sphere.
pub fn data_info(
    targets: &[spherecal::align::window::Target],
    obs: &[Vec<Observation>],
    sol: &Solution,
    settings: &spherecal::calib::Settings,
    ins_rate_hz: f64,
) -> (spherecal::calib::predict::Info, Vec<i64>) {
    use spherecal::calib::predict::{Info, NoiseModel};
    let noise = NoiseModel {
        range: settings.range_noise,
        beam_sigma: 0.0,
        range_unit: 0.002,
        position: settings.position_noise,
        attitude: settings.attitude_noise,
        ins_period_ns: (1e9 / ins_rate_hz.max(1.0)).round() as i64,
        footprint: settings.footprint,
    };
    let mut kept: Vec<(usize, &Observation)> = Vec::new();
    let mut returns = Vec::new();
    for (j, v) in obs.iter().enumerate().take(targets.len()) {
        let used = sol.spheres.get(j).map_or(0, |s| s.used).min(v.len());
        kept.extend(v[..used].iter().map(|o| (j, o)));
        returns.push(used as i64);
    }
    kept.sort_by_key(|(_, o)| o.time);
    let mut info = Info::default();
    info.add_returns(targets, kept, &sol.b.0, &noise);
    (info, returns)
}

/// The returns kept so far under the solver's navigation model (`None`: it has none), for the
/// planner's predictions on them ([`crate::plan::nav`]), weighed as the solve found: the
/// footprint's spread at grazing incidence at the share its residuals showed (none without a
/// solve under the model).
pub fn nav_plan(
    targets: &[spherecal::align::window::Target],
    obs: &[Vec<Observation>],
    sol: &Solution,
    settings: &spherecal::calib::Settings,
) -> Option<crate::plan::nav::NavPlan> {
    let model = settings.nav?;
    let used: Vec<usize> = sol.spheres.iter().map(|s| s.used).collect();
    let noise = settings
        .noise()
        .with_spread_share(sol.nav.map_or(0.0, |f| f.spread_share));
    Some(crate::plan::nav::NavPlan::of_returns(
        model, noise, targets, obs, &used, sol.b.0,
    ))
}

/// The sigmas the planner's predictor gives the returns kept so far ([`data_info`]): the six
/// [deg, m] and the time offset [s] (infinite where the geometry cannot determine them).
pub fn predicted_sigma(
    targets: &[spherecal::align::window::Target],
    obs: &[Vec<Observation>],
    sol: &Solution,
    settings: &spherecal::calib::Settings,
    ins_rate_hz: f64,
) -> [f64; 7] {
    let (info, _) = data_info(targets, obs, sol, settings, ins_rate_hz);
    let mut p = spherecal::calib::predict::Predicted::of(&info);
    if let Some(n) = nav_plan(targets, obs, sol, settings) {
        p.sigma = n.sigma(|_, _| true).unwrap_or([f64::INFINITY; P + 1]);
    }
    let d = spherecal::georef::Params(core::array::from_fn(|i| p.sigma[i]))
        .deg_m()
        .0;
    core::array::from_fn(|i| if i < 6 { d[i] } else { p.sigma[6] })
}

/// The verdict from the solution's report on the data so far, the coverage, the sigmas
/// predicted from the geometry so far ([`predicted_sigma`]; used where the solution gives
/// none) and the planner's advice on the next pass ([`crate::plan::live`]): with the board's
/// targets, each sigma against its target (the advice: the planner's pass, and whether the
/// targets are out of reach); without, done once another pass would improve no sigma by more
/// than [`crate::plan::live::ENOUGH_GAIN`].
pub fn assess(
    rep: &Report,
    cov: &[Coverage],
    goal: Option<&crate::config::goal::Goal>,
    predicted: Option<&[f64; 7]>,
    advice: Option<&crate::plan::live::LiveAdvice>,
) -> Verdict {
    let mut missing = Vec::new();
    if !rep.converged {
        let why = rep.reason.as_deref().unwrap_or("not converged");
        let short: String = why.chars().take(120).collect();
        missing.push(format!("no calibration claimed yet ({short})"));
    }
    for c in cov {
        if c.passes == 0 {
            missing.push(format!("{}: not seen in a pass yet", c.id));
        } else if !c.both_directions {
            let h = c.headings_deg[0];
            missing.push(format!(
                "{}: no {} pass (all {} so far)",
                c.id,
                crate::plan::bound(h + 180.0),
                crate::plan::bound(h)
            ));
        }
    }
    let next = advice.and_then(|a| a.next.as_ref().map(|n| n.0.clone()));
    match goal {
        Some(goal) => {
            let (lo, hi) = cov.iter().fold((f64::INFINITY, 0.0f64), |(a, b), c| {
                if c.returns > 0 {
                    (a.min(c.range_m[0]), b.max(c.range_m[1]))
                } else {
                    (a, b)
                }
            });
            let band = if lo > 15.0 {
                "at 8-15 m"
            } else if hi < 20.0 {
                "at 20-30 m"
            } else {
                "crossing the spheres at another range"
            };
            let sig = rep.sigma.deg_m();
            // Every sigma short of its target, then one advice for them all.
            let mut short = Vec::new();
            let mut angle_short = false;
            for (i, name) in NAMES.iter().enumerate() {
                let (target, unit) = if i < 3 {
                    (goal.sigma_deg, "deg")
                } else {
                    (goal.sigma_m, "m")
                };
                let (s, how) = match predicted {
                    Some(p) if !(rep.converged && sig[i].is_finite()) => (p[i], " (predicted)"),
                    _ => (sig[i], ""),
                };
                if !(s.is_finite() && s <= target) {
                    angle_short |= i < 3;
                    short.push(format!(
                        "{name} sigma{how} {} > {target} {unit}",
                        if s.is_finite() {
                            format!("{s:.4}")
                        } else {
                            "-".into()
                        }
                    ));
                }
            }
            let short_of_target = !short.is_empty();
            if short_of_target {
                let advice = match &next {
                    Some(w) => format!("{w} (the planner's)"),
                    None if angle_short => {
                        format!("add a pass {band} (ranges so far {lo:.0}-{hi:.0} m)")
                    }
                    None if cov.iter().any(|c| !c.both_directions) => {
                        "add a pass in the other direction".to_string()
                    }
                    None => "add a pass closer to the spheres".to_string(),
                };
                missing.push(format!("{}: {advice}", short.join(", ")));
            }
            // Out of reach matters only while a sigma is short of its target: the data may
            // beat the planner's noise model.
            if let Some(o) = advice.and_then(|a| a.out_of_reach.clone()) {
                if short_of_target {
                    missing.push(o);
                }
            }
        }
        None => match advice {
            Some(a) if a.gain > crate::plan::live::ENOUGH_GAIN => missing.push(format!(
                "another pass would still improve a sigma by {:.0} %: {}",
                a.gain * 100.0,
                next.unwrap_or_else(|| "-".into())
            )),
            Some(_) => {}
            None => missing.push("no advice from the planner yet (no pass flown)".into()),
        },
    }
    let ready_because = match (goal, advice) {
        (Some(_), _) => "every sphere seen both ways, every sigma within the board's targets".into(),
        (None, Some(a)) => format!(
            "every sphere seen both ways; another pass would improve no sigma by more than {:.0} % ({:.0} % at best: {})",
            crate::plan::live::ENOUGH_GAIN * 100.0,
            a.gain * 100.0,
            a.next.as_ref().map_or("-", |n| n.0.as_str())
        ),
        (None, None) => String::new(),
    };
    Verdict {
        ready: missing.is_empty(),
        ready_because,
        missing,
        coverage: cov.to_vec(),
        predicted_sigma: predicted
            .map(|p| core::array::from_fn(|i| p[i].is_finite().then_some(p[i]))),
    }
}

/// The coverage on the status line: `id:returns/passes/directions/min-max` per sphere.
pub fn status_field(cov: &[Coverage]) -> String {
    cov.iter()
        .map(|c| {
            format!(
                "{}:{}/{}/{}/{:.0}-{:.0}",
                c.id,
                c.returns,
                c.passes,
                if c.both_directions {
                    2
                } else {
                    u8::from(c.passes > 0)
                },
                c.range_m[0],
                c.range_m[1]
            )
        })
        .collect::<Vec<_>>()
        .join(",")
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use spherecal::time::GpsTime;

    fn obs(t_s: f64, v: [f32; 2], range: f32) -> Observation {
        Observation {
            time: GpsTime((t_s * 1e9) as i64),
            velocity: Vector3::new(v[0], v[1], 0.0),
            range,
            ..Observation::default()
        }
    }

    fn pass(kept: u32, course: [f32; 2]) -> spherecal::calib::solve::PassReport {
        let mut verdicts = [0; 8];
        verdicts[spherecal::calib::extract::ReturnClass::Kept as usize] = kept;
        spherecal::calib::solve::PassReport {
            sphere: 0,
            start: GpsTime(0),
            end: GpsTime(0),
            slices: 0,
            detected: 0,
            mean_inliers: 0.0,
            verdicts,
            centre_offset: [0.0; 3],
            along_track: 0.0,
            chi2: 0.0,
            dt_shift: 0.0,
            dt_sigma: 0.0,
            course,
        }
    }

    /// Hand case: 30 returns northbound at 9-12 m, then 30 southbound at 21 m, in the solver's
    /// passes; a pass of 5 kept returns and one standing still do not count.
    #[test]
    fn passes_directions_and_span() {
        let mut v: Vec<Observation> = (0..30)
            .map(|k| obs(k as f64 * 0.05, [1.3, 0.0], 9.0 + k as f32 * 0.1))
            .collect();
        let north = [
            pass(30, [1.0, 0.0]),
            pass(5, [-1.0, 0.0]),
            pass(40, [0.0; 2]),
        ];
        let c = one("S1", &v, north.iter());
        assert_eq!((c.passes, c.both_directions), (1, false));
        assert!((c.headings_deg[0] - 0.0).abs() < 1e-9);
        assert_eq!(crate::plan::bound(c.headings_deg[0] + 180.0), "southbound");
        v.extend((0..30).map(|k| obs(6.5 + k as f64 * 0.05, [-1.8, 0.1], 21.0)));
        let s = 1.8f32.hypot(0.1);
        let both = [pass(30, [1.0, 0.0]), pass(30, [-1.8 / s, 0.1 / s])];
        let c = one("S1", &v, both.iter());
        assert_eq!((c.passes, c.both_directions), (2, true));
        assert!(
            (c.headings_deg[1] - 176.82).abs() < 0.01,
            "{:?}",
            c.headings_deg
        );
        assert_eq!(c.range_m, [9.0, 21.0]);
        assert_eq!(status_field(&[c]), "S1:60/2/2/9-21");
        let none = one("S2", &[], [].iter());
        assert_eq!((none.passes, none.range_m), (0, [0.0; 2]));
    }
}

//! The checks a solution must pass before it is claimed: the noise model's predicted RMS and
//! weights, the per-pass checks ([`super::consistency`]: the dispersion and every pass's
//! chi-square, the clocks per pass), the reasons a sphere is lost (see the module [`super`] for
//! the limits).

use super::consistency::{consistency, pass_clocks, Answer};
use super::outcome::{Lost, Refusal, Solution};
use super::settings::Settings;
use crate::align::window::{Observation, Target, MAX_TARGETS};
use crate::calib::noise::Noise;
use crate::georef::P;

/// The residual RMS the noise model predicts over the kept returns ([`Noise::variance`]: range
/// noise, INS attitude noise times the range, INS position noise, the 2 mm range quantisation;
/// each return's own INS sigmas where the trajectory's accuracy file gives them).
pub(super) fn predicted_rms(obs: &[&mut [Observation]], used: &[usize], s: &Settings) -> f64 {
    let noise = s.noise();
    let (mut s2, mut n) = (0.0, 0usize);
    for (v, &u) in obs.iter().zip(used) {
        for o in &v[..u] {
            s2 += noise.variance(o);
            n += 1;
        }
    }
    libm::sqrt(s2 / n.max(1) as f64)
}

/// The least squares are weighted by the noise model when the trajectory's accuracy file gave
/// any kept return its own INS sigmas (the returns' variances then differ along the survey);
/// otherwise every residual counts alike, as in the paper.
pub(super) fn weights(obs: &[&mut [Observation]], used: &[usize], s: &Settings) -> Option<Noise> {
    obs.iter()
        .zip(used)
        .any(|(v, &u)| v[..u.min(v.len())].iter().any(|o| o.ins_sigma != [0.0; 2]))
        .then(|| s.noise())
}

/// Why each sphere not found was lost.
pub(super) fn lost_reasons(s: &Settings, sol: &mut Solution) {
    let c = sol.consensus;
    for (j, sp) in sol.spheres.iter_mut().enumerate() {
        sp.agreed = c.map_or(0, |c| c.support.get(j).copied().unwrap_or(0));
        if sp.lost.is_some() {
            continue;
        }
        sp.lost = if sp.used >= s.min_points {
            None
        } else if sp.windowed == 0 {
            Some(Lost::NoReturns)
        } else if c.is_some_and(|c| c.slices.get(j).copied().unwrap_or(0) == 0) {
            Some(Lost::NotDetected)
        } else if c.is_some_and(|c| c.support.get(j).copied().unwrap_or(0) < 3) {
            Some(Lost::Disagrees)
        } else {
            Some(Lost::TooFewReturns)
        };
    }
}

/// The quality checks on a least-squares answer: the weak parameters, then the first reason
/// to refuse it — a held time offset the data contradict, not converged, ill-conditioned,
/// residuals over-dispersed against the noise model, a pass inconsistent with the others.
pub(super) fn checks(
    targets: &[Target],
    obs: &[&mut [Observation]],
    used: &[usize],
    s: &Settings,
    sol: &mut Solution,
) -> Option<Refusal> {
    let lm = sol.lm?;
    // Every unit vector has components above 0.3: the direction only matters when it is weak.
    let weak_geometry = lm.condition.is_nan() || lm.condition > s.weak_condition;
    for (w, &v) in sol.weak.iter_mut().zip(&lm.weakest) {
        *w = weak_geometry && v.abs() > 0.3;
    }
    let (b, time, dt) = (sol.b.0, sol.time(), sol.dt);
    let predicted = predicted_rms(obs, used, s);
    sol.predicted_rms = predicted;
    let at = Answer {
        targets,
        obs,
        used,
        b: &b,
        time: &time,
    };
    let worst = consistency(&at, s, &mut sol.passes);
    let clock = pass_clocks(&at, s, &mut sol.passes);
    let contradicted = sol
        .dt_free
        .and_then(|(found, sigma)| s.held_contradicted(dt, found, sigma));
    // A held offset the data contradict comes first: it is the cause, and the mounting fitted
    // around it may fail to converge or fit badly only because of it.
    if contradicted.is_some() {
        contradicted
    } else if !lm.converged {
        Some(Refusal::NotConverged {
            iterations: lm.iterations,
        })
    } else if lm.condition.is_nan() || lm.condition > s.max_condition {
        Some(Refusal::IllConditioned {
            condition: lm.condition,
            limit: s.max_condition,
        })
    } else if let Some(r) = prior_check(s, sol) {
        // A measured mounting the data contradict, as a held offset: the fit bent around it
        // makes jumps and inconsistent passes of its own.
        Some(r)
    } else if clock.is_some() {
        // A clock that steps or drifts also spreads the residuals and moves passes' centres:
        // the cause first.
        clock
    } else if let Some(r) = remnant(s, sol) {
        Some(r)
    } else if lm.rms.is_nan() || lm.rms > s.max_dispersion * predicted {
        Some(Refusal::OverDispersed {
            rms: lm.rms,
            predicted,
        })
    } else if let Some(r) = noisier(s, sol) {
        Some(r)
    } else {
        // A jump of the navigation, then a sphere's survey the others contradict, are the
        // causes of the passes' disagreement.
        jump_check(s, sol)
            .or_else(|| survey_check(s, sol, targets.len()))
            .or(worst)
    }
}

/// The sphere whose last extraction kept the smallest fraction of what the rounds kept, when
/// below `min_kept_fraction` (spheres the rounds kept fewer than twice `min_points` of are not
/// judged: a glimpse).
fn remnant(s: &Settings, sol: &Solution) -> Option<Refusal> {
    sol.spheres
        .iter()
        .enumerate()
        .filter(|(_, sp)| sp.rounds_kept >= 2 * s.min_points && sp.used > 0)
        .map(|(j, sp)| (j, sp.used as f64 / sp.rounds_kept as f64))
        .filter(|(_, f)| *f < s.min_kept_fraction)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(j, _)| Refusal::Remnant {
            sphere: j,
            kept: sol.spheres[j].used,
            rounds: sol.spheres[j].rounds_kept,
        })
}

/// The mounting's measured values the data contradict: over the angles and over the lever
/// arm, the chi-square of each one's move from its prior against what the prior leaves
/// unexplained (prior variance less posterior, at least a tenth of the prior, as
/// [`survey_check`]) beyond `max_pass_chi2` (3 degrees of freedom); the parameter moved most
/// named.
fn prior_check(s: &Settings, sol: &Solution) -> Option<Refusal> {
    let lm = sol.lm?;
    let mut worst: Option<(f64, Refusal)> = None;
    for group in [0..3, 3..P] {
        let (mut chi2, mut most) = (0.0, None::<Refusal>);
        for i in group {
            let info = s.mount_prior.info[i];
            if info.is_nan() || info <= 0.0 {
                continue;
            }
            let sp2 = 1.0 / info;
            let post = lm.sigma[i] * lm.sigma[i];
            let moved = sol.b.0[i] - s.mount_prior.centre[i];
            let z = moved.abs() / libm::sqrt((sp2 - post).max(0.1 * sp2));
            chi2 += z * z;
            if most
                .as_ref()
                .is_none_or(|m| matches!(m, Refusal::PriorDisagrees { z: zm, .. } if z > *zm))
            {
                most = Some(Refusal::PriorDisagrees {
                    parameter: i,
                    moved,
                    sigma: libm::sqrt(sp2),
                    z,
                });
            }
        }
        if chi2 > s.max_pass_chi2 && worst.as_ref().is_none_or(|(c, _)| chi2 > *c) {
            worst = most.map(|m| (chi2, m));
        }
    }
    worst.map(|(_, r)| r)
}

/// Under a navigation model that wanders, the white noise found beyond
/// `max_white_noise_factor` times the declared.
fn noisier(s: &Settings, sol: &Solution) -> Option<Refusal> {
    s.nav.filter(|m| !m.is_white())?;
    let factor = libm::sqrt(sol.nav.as_ref()?.variance_factor);
    (factor.is_nan() || factor > s.max_white_noise_factor).then_some(Refusal::Noisier {
        factor,
        limit: s.max_white_noise_factor,
    })
}

/// Under the navigation model, the largest step between consecutive pieces when beyond
/// `max_nav_step_sigmas`.
fn jump_check(s: &Settings, sol: &Solution) -> Option<Refusal> {
    let (sigmas, at, step) = sol.nav.as_ref()?.worst_step;
    (sigmas > s.max_nav_step_sigmas).then_some(Refusal::NavigationJump { at, step, sigmas })
}

/// Under the navigation model, the sphere whose estimated centre moved furthest from its
/// survey, when beyond `max_pass_chi2`: each axis's correction against what its prior leaves
/// unexplained (prior variance less posterior, at least a tenth of the prior: a correction
/// `c ~ N(0, sigma_p^2 - sigma_post^2)` when the survey is right).
fn survey_check(s: &Settings, sol: &Solution, n: usize) -> Option<Refusal> {
    let f = sol.nav.as_ref()?;
    let mut worst: Option<(f64, Refusal)> = None;
    for j in 0..n.min(MAX_TARGETS) {
        let sp = s.centre_sigma[j];
        if sp.is_nan() || sp <= 0.0 {
            continue;
        }
        let chi2: f64 = (0..3)
            .map(|k| {
                let v = (sp * sp - f.centre_sigma[j][k] * f.centre_sigma[j][k]).max(0.1 * sp * sp);
                f.centre[j][k] * f.centre[j][k] / v
            })
            .sum();
        if chi2 > s.max_pass_chi2 && worst.as_ref().is_none_or(|(c, _)| chi2 > *c) {
            worst = Some((
                chi2,
                Refusal::SurveyDisagrees {
                    sphere: j,
                    moved: f.centre[j],
                    chi2,
                    sigma: sp,
                },
            ));
        }
    }
    worst.map(|(_, r)| r)
}

/// The clocks' verdict over the solve's (`found`): an INS clock step within the data is the
/// cause whatever else was found; an untrusted LiDAR clock refuses an otherwise claimed
/// solution unless allowed and its offset explains the stamps' RMC disagreement.
pub(super) fn clock_checks(
    s: &Settings,
    sol: &Solution,
    found: Option<Refusal>,
) -> Option<Refusal> {
    if let Some(step) = s.clocks.ins_step {
        return Some(Refusal::InsClockStep(step));
    }
    if found.is_some() {
        return found;
    }
    let u = s.clocks.lidar_untrusted?;
    let offset_s = u.applied_s + sol.dt;
    let explained = u.rmc_offset_s.map(|e| (offset_s + e).abs() <= 1.5);
    let refused = !u.allowed || explained == Some(false);
    refused.then_some(Refusal::LidarClockUntrusted {
        offset_s,
        explained,
        allowed: u.allowed,
        rmc_offset_s: u.rmc_offset_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::solve::settings::ClockFacts;
    use crate::calib::solve::settings::InsStep;
    use crate::calib::solve::settings::UntrustedLidar;
    use crate::georef::Params;

    fn with(facts: ClockFacts) -> Settings {
        Settings {
            clocks: facts,
            ..Settings::default()
        }
    }

    fn solved(dt: f64) -> Solution {
        let mut sol = Solution::start(&Params([0.0; P]), 0.1);
        sol.dt = dt;
        sol
    }

    fn untrusted(rmc: Option<f64>, applied: f64, allowed: bool) -> ClockFacts {
        ClockFacts {
            lidar_untrusted: Some(UntrustedLidar {
                rmc_offset_s: rmc,
                applied_s: applied,
                allowed,
            }),
            ins_step: None,
        }
    }

    #[test]
    fn trusted_clocks_leave_the_verdict_alone() {
        let s = with(ClockFacts::default());
        assert_eq!(clock_checks(&s, &solved(0.01), None), None);
        let found = Some(Refusal::TooFewSpheres { have: 1 });
        assert_eq!(clock_checks(&s, &solved(0.01), found), found);
    }

    #[test]
    fn an_ins_step_is_the_cause_whatever_else_was_found() {
        let step = InsStep {
            at_s: 1000.5,
            into_s: 31.0,
            step_s: 0.02,
            count: 2,
        };
        let s = with(ClockFacts {
            lidar_untrusted: None,
            ins_step: Some(step),
        });
        let found = Some(Refusal::TooFewSpheres { have: 1 });
        assert_eq!(
            clock_checks(&s, &solved(0.0), found),
            Some(Refusal::InsClockStep(step))
        );
        assert_eq!(
            clock_checks(&s, &solved(0.0), None),
            Some(Refusal::InsClockStep(step))
        );
    }

    #[test]
    fn an_untrusted_lidar_clock_claims_only_when_allowed_and_explained() {
        // Applied 0.25 s + found 0.05 s = 0.30 s; the stamps are 0.30 s behind the RMC.
        let refused = |f, dt| clock_checks(&with(f), &solved(dt), None);
        match refused(untrusted(Some(-0.3), 0.25, false), 0.05) {
            Some(Refusal::LidarClockUntrusted {
                offset_s,
                explained,
                allowed,
                ..
            }) => {
                assert!((offset_s - 0.30).abs() < 1e-12);
                assert_eq!((explained, allowed), (Some(true), false));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(refused(untrusted(Some(-0.3), 0.25, true), 0.05), None);
        assert_eq!(refused(untrusted(None, 0.25, true), 0.05), None);
        // 1.5 s is the limit: 0.30 + 1.21 = 1.51 s unexplained.
        assert!(matches!(
            refused(untrusted(Some(1.21), 0.25, true), 0.05),
            Some(Refusal::LidarClockUntrusted {
                explained: Some(false),
                ..
            })
        ));
        assert_eq!(refused(untrusted(Some(1.19), 0.25, true), 0.05), None);
        // A refusal of the data stands over the clock's.
        let found = Some(Refusal::TooFewSpheres { have: 0 });
        assert_eq!(
            clock_checks(&with(untrusted(None, 0.0, false)), &solved(0.0), found),
            found
        );
    }
}

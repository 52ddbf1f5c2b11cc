//! The plan under navigation errors that wander (`[ins.correlated]`): the covariance the
//! solver's own least squares gives on the plan's exact returns ([`spherecal::calib::nav::predict`]:
//! each piece of the time line shares one INS error, wandering between pieces under the
//! Gauss-Markov prior, the sphere centres free within their survey's sigma). The information
//! of such errors does not add over returns: a pass's thousands of returns see one error, so
//! more passes (new errors) help where more returns in a pass do not; each share is the
//! survey solved again without it.

use super::{PlanNoise, Segment};
use crate::config::scenario::Scenario;
use crate::config::site::DEFAULT_CENTRE_SIGMA_M;
use spherecal::align::window::{Observation, Target};
use spherecal::calib::lm::Clock;
use spherecal::calib::nav::{cut_for, predict, NavModel, Piece};
use spherecal::calib::noise::Noise;
use spherecal::calib::objective::{Problem, SphereObs};
use spherecal::georef::P;

/// How far apart in time candidate passes are driven after the survey [s] (beyond a few
/// correlation times: each brings its own navigation errors).
pub const PASS_APART_S: f64 = 600.0;

/// Most pieces a planned survey is cut into (the file command's [`crate::session::scratch::Scratch`]
/// holds as many).
const PIECES: usize = 1024;

/// A plan's returns and what the solver would weigh them with under the navigation model.
#[derive(Debug, Clone)]
pub struct NavPlan {
    /// The model (the scenario's `[ins.correlated]`).
    pub model: NavModel,
    /// The white noise the solver weighs with (the site's `[noise]` a synthesised survey
    /// writes).
    pub noise: Noise,
    /// Each sphere's survey sigma [m].
    pub centre_sigma: Vec<f64>,
    targets: Vec<Target>,
    /// Per sphere, its returns in time order with their trajectory time [s].
    obs: Vec<Vec<(f64, Observation)>>,
    /// The mounting they are linearised at (the truth's).
    b: [f64; P],
}

impl NavPlan {
    /// The plan of scenario `s` under its navigation model (`None`: it declares none) from its
    /// traced returns `obs` (`(time, sphere, observation)`) the solver can keep (`keep`).
    pub fn of(
        s: &Scenario,
        noise: &PlanNoise,
        targets: &[Target],
        obs: &[(f64, usize, Observation)],
        keep: &[bool],
    ) -> Option<Self> {
        let c = s.ins.correlated.resolve("ins.correlated").ok()?;
        if !c.is_on() {
            return None;
        }
        let mut per = vec![Vec::new(); targets.len()];
        for ((t, j, o), _) in obs.iter().zip(keep).filter(|(_, k)| **k) {
            if let Some(v) = per.get_mut(*j) {
                v.push((*t, *o));
            }
        }
        let b = s.truth_mount().params().0;
        let unit = s.scanner().unwrap_or_default().distance_unit_m();
        Some(Self {
            model: NavModel {
                position_sigma: c.position_sigma,
                attitude_sigma: c.attitude_sigma,
                correlation_s: c.correlation_s,
            },
            noise: Noise {
                // The solver weighs by the declared white noise (times the factor its
                // residuals give) and, where they show it, the footprint's spread at
                // incidence (`spherecal::calib::nav::refine`): the plan weighs as it will.
                range: noise.range_m.max(0.005),
                attitude: noise.attitude_deg.to_radians(),
                position: noise.position_m,
                spread: noise.model(unit).beam_sigma,
            },
            centre_sigma: vec![DEFAULT_CENTRE_SIGMA_M; targets.len()],
            targets: targets.to_vec(),
            obs: per,
            b,
        })
    }

    /// The returns kept so far of a survey under way (the rig: `store`'s first `used` per
    /// sphere) under `model`, weighed with `noise`, linearised at `b`.
    pub fn of_returns(
        model: NavModel,
        noise: Noise,
        targets: &[Target],
        store: &[Vec<Observation>],
        used: &[usize],
        b: [f64; P],
    ) -> Self {
        let obs = targets
            .iter()
            .enumerate()
            .map(|(j, _)| {
                let v = store.get(j).map_or(&[][..], |v| {
                    &v[..used.get(j).copied().unwrap_or(0).min(v.len())]
                });
                let mut v: Vec<(f64, Observation)> = v.iter().map(|o| (0.0, *o)).collect();
                v.sort_by_key(|(_, o)| o.time);
                v
            })
            .collect();
        Self {
            model,
            noise,
            centre_sigma: vec![DEFAULT_CENTRE_SIGMA_M; targets.len()],
            targets: targets.to_vec(),
            obs,
            b,
        }
    }

    /// The model in words.
    pub fn words(&self) -> String {
        let m = &self.model;
        format!(
            "position {:.3} m horizontal, {:.3} m vertical; roll/pitch {:.3} deg, heading {:.3} \
             deg; correlation {:.0} s (sigmas as the solver's under it, the sphere centres free \
             within {:.0} mm)",
            m.position_sigma[0],
            m.position_sigma[1],
            m.attitude_sigma[0].to_degrees(),
            m.attitude_sigma[1].to_degrees(),
            m.correlation_s,
            self.centre_sigma.first().copied().unwrap_or(0.0) * 1e3
        )
    }

    /// The sigmas of the six [rad, m] and the time offset [s] from the returns `keep(time,
    /// sphere)` says (`None`: not determined).
    pub fn sigma(&self, keep: impl Fn(f64, usize) -> bool) -> Option<[f64; P + 1]> {
        let kept: Vec<Vec<Observation>> = self
            .obs
            .iter()
            .enumerate()
            .map(|(j, v)| {
                v.iter()
                    .filter(|(t, _)| keep(*t, j))
                    .map(|(_, o)| *o)
                    .collect()
            })
            .collect();
        self.solve(&self.targets, &kept)
    }

    /// The sigmas with the returns of candidate plans added and the returns within `drop`
    /// spans [s] taken out (a pass driven again slower). A candidate pass (the same spheres)
    /// is driven after this survey, each [`PASS_APART_S`] after the one before (its navigation
    /// errors its own); a candidate sphere's returns are over the same trajectory.
    pub fn sigma_with(&self, adds: &[&NavPlan], drop: &[(f64, f64)]) -> Option<[f64; P + 1]> {
        let end = self.span_ns().map_or(0, |s| s.1);
        let mut passes = 0;
        let adds: Vec<(&NavPlan, i64)> = adds
            .iter()
            .map(|p| {
                if !self.same_spheres(p) {
                    return (*p, 0);
                }
                passes += 1;
                let first = p.span_ns().map_or(0, |s| s.0);
                let after = (PASS_APART_S * f64::from(passes) * 1e9) as i64;
                (*p, end - first + after)
            })
            .collect();
        self.sigma_shifted(&adds, drop)
    }

    /// [`Self::sigma_with`] with each plan's times moved by its shift [ns].
    fn sigma_shifted(&self, adds: &[(&NavPlan, i64)], drop: &[(f64, f64)]) -> Option<[f64; P + 1]> {
        let mut targets = self.targets.clone();
        let mut kept: Vec<Vec<Observation>> = self
            .obs
            .iter()
            .map(|v| {
                v.iter()
                    .filter(|(t, _)| !drop.iter().any(|(a, b)| t >= a && t < b))
                    .map(|(_, o)| *o)
                    .collect()
            })
            .collect();
        for (p, shift) in adds {
            for (tg, v) in p.targets.iter().zip(&p.obs) {
                let j = match targets.iter().position(|t| t == tg) {
                    Some(j) => j,
                    None => {
                        targets.push(*tg);
                        kept.push(Vec::new());
                        targets.len() - 1
                    }
                };
                kept[j].extend(v.iter().map(|(_, o)| {
                    let mut o = *o;
                    o.time.0 += shift;
                    o
                }));
            }
        }
        for v in &mut kept {
            v.sort_by_key(|o| o.time);
        }
        self.solve(&targets, &kept)
    }

    /// The first and last return's time [ns] (`None`: no returns).
    pub fn span_ns(&self) -> Option<(i64, i64)> {
        let t = self.obs.iter().flatten().map(|(_, o)| o.time.0);
        Some((t.clone().min()?, t.max()?))
    }

    /// Whether `other` observes the same spheres (a candidate pass, not a new sphere).
    pub fn same_spheres(&self, other: &NavPlan) -> bool {
        self.targets == other.targets
    }

    fn solve(&self, targets: &[Target], kept: &[Vec<Observation>]) -> Option<[f64; P + 1]> {
        let spheres: Vec<SphereObs<'_>> = targets
            .iter()
            .zip(kept)
            .map(|(t, o)| SphereObs { target: *t, obs: o })
            .collect();
        let t_ref = kept.iter().flatten().map(|o| o.time).min()?;
        let pb = Problem {
            spheres: &spheres,
            stride: 1,
            dt: 0.0,
            drift: 0.0,
            t_ref,
            weights: Some(self.noise),
            // The planner's returns are ideal rays (`observe`): no bloom to take out.
            footprint: None,
        };
        let mut pieces = vec![Piece::EMPTY; PIECES];
        let m = cut_for(&pb, &self.model, &mut pieces);
        let clock = Clock {
            dt: true,
            drift: false,
        };
        let centre_sigma = vec![DEFAULT_CENTRE_SIGMA_M; targets.len()];
        predict(
            &pb,
            &self.b,
            &self.model,
            &centre_sigma,
            &mut pieces[..m],
            clock,
        )
    }

    /// [`Self::sigma`] without segment `k` of `segs` (its time span), or without sphere `j`.
    pub fn sigma_without(
        &self,
        segs: &[(Segment, f64, f64)],
        k: Option<usize>,
        j: Option<usize>,
    ) -> Option<[f64; P + 1]> {
        let span = k.and_then(|k| segs.get(k)).map(|(_, a, b)| (*a, *b));
        self.sigma(|t, jj| Some(jj) != j && !span.is_some_and(|(a, b)| t >= a && t < b))
    }
}

//! The planner on a survey under way (the rig's verdict): the site's spheres and the latest
//! solution as a scenario, the passes flown so far taken from the data, the candidate passes of
//! [`recommend`](super::recommend) traced over the spheres with that solution, and what each
//! would add to the information of the returns kept so far. The verdict's advice is the
//! planner's: the cheapest pass that meets the board's targets, else the one that gains most;
//! without targets from the board, the survey is done when no candidate pass would improve any
//! parameter's sigma by more than [`ENOUGH_GAIN`].

use super::nav::NavPlan;
use super::recommend::{candidate_pass_infos, PassCandidate};
use super::{PlanNoise, Prediction};
use crate::config::goal::Goal;
use crate::config::scenario::{PassSpec, Scenario, SphereSpec};
use spherecal::align::window::{Observation, Target};
use spherecal::calib::predict::{Info, Predicted};
use spherecal::calib::solve::Solution;
use spherecal::georef::{Params, P};

/// Another pass that improves no sigma by more than this share is not worth driving (on
/// table1-noisy the best fifth pass gains 22 %, a sixth 16 %, a seventh 15 %, then 10 %).
pub const ENOUGH_GAIN: f64 = 0.2;
/// The candidates are traced again when the solution moves by more than this [deg, m].
const RETRACE: [f64; 2] = [0.2, 0.05];

/// The planner kept by the rig's solver.
pub struct Live {
    scenario: Scenario,
    noise: PlanNoise,
    cands: Vec<PassCandidate>,
    traced_for: Option<[f64; P]>,
}

/// What the planner says of the data so far.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveAdvice {
    /// The best next pass in words, and the prediction with it.
    pub next: Option<(String, Prediction)>,
    /// The largest share by which any candidate pass reduces a sigma (0: nothing to gain).
    pub gain: f64,
    /// With the board's targets: none of the candidates, even four of them one after the other,
    /// meets them; the best such sequence's prediction in words.
    pub out_of_reach: Option<String>,
}

impl Live {
    /// For the site's spheres (`targets`, `ids`), the LiDAR `model` at `rpm`, an INS at
    /// `ins_rate_hz`, and the solver's noise model.
    pub fn new(
        targets: &[Target],
        ids: &[String],
        model: spherecal::velodyne::Model,
        rpm: f64,
        ins_rate_hz: f64,
        settings: &spherecal::calib::Settings,
    ) -> Result<Self, crate::Error> {
        let mut s = Scenario::load("table1-bare").map_err(|e| e.to_string())?;
        s.name = "the survey under way".into();
        s.sphere = targets
            .iter()
            .zip(ids)
            .map(|(t, id)| SphereSpec {
                id: id.clone(),
                ned_m: [t.center.x, t.center.y, t.center.z],
                radius_m: t.radius,
                stand: "none".into(),
                stand_down_m: None,
                reflectivity: 0.8,
            })
            .collect();
        s.lidar.model = model.key().into();
        s.lidar.rpm = rpm;
        s.ins.rate_hz = ins_rate_hz;
        s.lidar.range_sigma_m = settings.range_noise;
        s.ins.att_sigma_deg = settings.attitude_noise.to_degrees();
        s.ins.pos_sigma_m = settings.position_noise;
        // The solver's navigation model: the candidates' returns are kept for it.
        s.ins.correlated = settings.nav.map_or_else(
            || crate::config::nav_errors::CorrelatedSpec::preset_only("white"),
            |m| crate::config::nav_errors::CorrelatedSpec {
                preset: None,
                position_sigma_m: Some(m.position_sigma),
                attitude_sigma_deg: Some(m.attitude_sigma.map(f64::to_degrees)),
                correlation_s: Some(m.correlation_s),
            },
        );
        s.trajectory.pass.clear();
        s.trajectory.roll = [0.0, 6.0];
        s.trajectory.pitch = [0.0, 4.5];
        s.trajectory.yaw = [0.0, 9.0];
        s.trajectory.heave = [0.0, 5.0];
        let noise = PlanNoise::of(&s);
        Ok(Self {
            scenario: s,
            noise,
            cands: Vec::new(),
            traced_for: None,
        })
    }

    /// The passes flown so far (one per span of the solution's passes, from their kept
    /// returns' platform positions and velocities) and the latest solution into the scenario;
    /// the candidates traced again when the solution moved.
    pub fn update(
        &mut self,
        sol: &Solution,
        store: &[Vec<Observation>],
    ) -> Result<(), crate::Error> {
        let mut flown: Vec<(i64, i64, PassSpec)> = Vec::new();
        for p in &sol.passes {
            let v = match store.get(usize::from(p.sphere)) {
                Some(v) => v,
                None => continue,
            };
            let used = sol.spheres.get(usize::from(p.sphere)).map_or(0, |s| s.used);
            let kept: Vec<&Observation> = v[..used.min(v.len())]
                .iter()
                .filter(|o| o.time >= p.start && o.time <= p.end)
                .collect();
            if kept.len() < 10 || flown.iter().any(|f| f.0 < p.end.0 && p.start.0 < f.1) {
                continue;
            }
            let n = kept.len() as f64;
            let (vn, ve) = kept.iter().fold((0.0, 0.0), |(a, b), o| {
                (
                    a + f64::from(o.velocity.x) / n,
                    b + f64::from(o.velocity.y) / n,
                )
            });
            let speed = vn.hypot(ve);
            if speed < 0.3 {
                continue;
            }
            let first = kept[0];
            flown.push((
                p.start.0,
                p.end.0,
                PassSpec {
                    start_ne_m: [first.position.x, first.position.y],
                    heading_deg: ve.atan2(vn).to_degrees().rem_euclid(360.0),
                    speed_mps: speed,
                    duration_s: ((p.end.0 - p.start.0) as f64 * 1e-9).max(1.0),
                    // The height flown (a drone's passes differ; a vessel's are the same).
                    down_m: Some(
                        kept.iter().map(|k| k.position.z).sum::<f64>() / kept.len() as f64,
                    ),
                },
            ));
        }
        self.scenario.trajectory.pass = flown.into_iter().map(|f| f.2).collect();
        if self.scenario.trajectory.pass.is_empty() {
            return Ok(());
        }
        let d = sol.b.deg_m().0;
        let moved = self.traced_for.is_none_or(|t| {
            (0..P).any(|i| (t[i] - d[i]).abs() > if i < 3 { RETRACE[0] } else { RETRACE[1] })
        });
        if moved {
            let (b, l) = ([d[0], d[1], d[2]], [d[3], d[4], d[5]]);
            self.scenario.mount.truth.boresight_deg = b;
            self.scenario.mount.truth.lever_arm_m = l;
            self.cands = candidate_pass_infos(&self.scenario, &self.noise, 1)?;
            self.traced_for = Some(d);
        }
        Ok(())
    }

    /// The advice for the data's information `data` and returns per sphere `returns`: the best
    /// next pass, how much it gains, and (with `goal`: the board's targets) whether up to four
    /// more passes can meet them.
    pub fn advise(
        &self,
        data: &Info,
        returns: &[i64],
        goal: Option<&Goal>,
        nav: Option<&NavPlan>,
    ) -> LiveAdvice {
        // Under the navigation model the sigmas are its solver's: the data so far, with the
        // candidate passes' returns after them (each its own errors).
        let under = |white: Predicted, adds: &[&PassCandidate]| match nav {
            Some(n) => {
                let plans: Vec<&NavPlan> = adds.iter().filter_map(|c| c.nav.as_ref()).collect();
                let mut p = white;
                p.sigma = n.sigma_with(&plans, &[]).unwrap_or([f64::INFINITY; P + 1]);
                p
            }
            None => white,
        };
        let now = under(Predicted::of(data), &[]);
        let gain_of = |p: &Predicted| {
            (0..P)
                .map(|i| {
                    if now.sigma[i].is_finite() && p.sigma[i].is_finite() && now.sigma[i] > 0.0 {
                        1.0 - p.sigma[i] / now.sigma[i]
                    } else if p.sigma[i].is_finite() {
                        1.0
                    } else {
                        0.0
                    }
                })
                .fold(0.0, f64::max)
        };
        let with = |base: &Info, c: &PassCandidate| {
            let mut i = *base;
            i += &c.info;
            i
        };
        let meets = |p: &Predicted, rs: &[i64], g: &Goal| {
            let pr = Prediction::of(p);
            pr.worst_ratio(g) <= 1.0
                && pr.condition.is_some_and(|c| c <= g.max_condition)
                && rs.iter().all(|&r| r >= i64::from(g.min_returns))
        };
        let plus = |rs: &[i64], c: &PassCandidate| -> Vec<i64> {
            rs.iter()
                .zip(c.returns.iter().chain(std::iter::repeat(&0)))
                .map(|(a, b)| a + b)
                .collect()
        };
        // With a goal, the cheapest single pass that meets it, else the one that gains most
        // per second; without, the one that gains most.
        let scored: Vec<(usize, Predicted, f64)> = self
            .cands
            .iter()
            .enumerate()
            .map(|(k, c)| {
                let p = under(Predicted::of(&with(data, c)), &[c]);
                let g = gain_of(&p);
                (k, p, g)
            })
            .collect();
        let best = match goal {
            Some(g) => scored
                .iter()
                .filter(|(k, p, _)| meets(p, &plus(returns, &self.cands[*k]), g))
                .min_by(|a, b| self.cands[a.0].cost_s.total_cmp(&self.cands[b.0].cost_s))
                .or_else(|| {
                    scored.iter().max_by(|a, b| {
                        (a.2 / self.cands[a.0].cost_s.max(1.0))
                            .total_cmp(&(b.2 / self.cands[b.0].cost_s.max(1.0)))
                    })
                }),
            None => scored.iter().max_by(|a, b| a.2.total_cmp(&b.2)),
        };
        let next = best.map(|(k, p, _)| (self.cands[*k].words.clone(), Prediction::of(p)));
        let gain = scored.iter().map(|c| c.2).fold(0.0, f64::max);
        // Out of reach: four passes, each the best gain, still miss the targets.
        let out_of_reach = goal.and_then(|g| {
            if self.cands.is_empty() || meets(&now, returns, g) {
                return None;
            }
            let (mut info, mut rs) = (*data, returns.to_vec());
            let mut taken: Vec<&PassCandidate> = Vec::new();
            for _ in 0..4 {
                let (k, _) = self
                    .cands
                    .iter()
                    .enumerate()
                    .map(|(k, c)| {
                        let mut t = taken.clone();
                        t.push(c);
                        let p = under(Predicted::of(&with(&info, c)), &t);
                        (k, Prediction::of(&p).worst_ratio(g))
                    })
                    .min_by(|a, b| a.1.total_cmp(&b.1))?;
                info = with(&info, &self.cands[k]);
                rs = plus(&rs, &self.cands[k]);
                taken.push(&self.cands[k]);
                if meets(&under(Predicted::of(&info), &taken), &rs, g) {
                    return None;
                }
            }
            let p = Prediction::of(&under(Predicted::of(&info), &taken));
            let worst = (0..P)
                .max_by(|&a, &b| {
                    let r = |i: usize| {
                        let t = if i < 3 { g.sigma_deg } else { g.sigma_m };
                        p.sigma_deg_m[i].map_or(f64::INFINITY, |s| s / t)
                    };
                    r(a).total_cmp(&r(b))
                })
                .unwrap_or(0);
            let (t, unit) = if worst < 3 {
                (g.sigma_deg, "deg")
            } else {
                (g.sigma_m, "m")
            };
            Some(format!(
                "the board's targets are out of reach: with four more passes the planner predicts {} sigma {} against {t} {unit} (the sensors' noise: range {} m, INS {} deg / {} m); relax [calibration] in the board",
                spherecal::georef::NAMES[worst],
                super::sigma_text(p.sigma_deg_m[worst], worst, true).unwrap_or_else(|| "undetermined".into()),
                self.noise.range_m,
                self.noise.attitude_deg,
                self.noise.position_m
            ))
        });
        LiveAdvice {
            next,
            gain,
            out_of_reach,
        }
    }

    /// Candidate passes are traced (a pass has been flown).
    pub fn has_candidates(&self) -> bool {
        !self.cands.is_empty()
    }

    /// The latest solution's mounting the candidates were traced with.
    pub fn traced_for(&self) -> Option<Params> {
        self.traced_for.map(|d| spherecal::georef::DegM(d).params())
    }
}

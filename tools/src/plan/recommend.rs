//! The cheapest change that makes a plan meet its goal: candidate changes (a new pass along
//! the spheres in either direction at 8-30 m, a pass driven at half speed, another sphere
//! beyond either end of the line or raised above it) each traced once and weighed by the
//! predictor (information adds: a candidate costs only its own returns); the cheapest that
//! meets the goal wins, else the one that gains most per second of survey is taken and the
//! search goes on (at most [`MAX_STEPS`] changes).

use super::nav::NavPlan;
use super::{geometry_of, observe, segments, Geometry, PlanNoise, Prediction, Segment};
use crate::config::goal::Goal;
use crate::config::scenario::{PassSpec, Scenario, SphereSpec};
use serde::{Deserialize, Serialize};
use spherecal::calib::predict::{Info, Predicted};
use spherecal::georef::P;

/// Most changes proposed in a row.
pub const MAX_STEPS: usize = 4;
/// The perpendicular distances of candidate passes from the line of the spheres [m].
pub const OFFSETS_M: [f64; 6] = [8.0, 12.0, 16.0, 20.0, 25.0, 30.0];
/// What setting up and surveying one more sphere costs, in seconds of survey time (a crew's
/// quarter of an hour).
pub const SPHERE_COST_S: f64 = 900.0;

/// One change to a plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Change {
    /// Drive one more pass.
    AddPass(PassSpec),
    /// Drive pass `index` (0-based) at `speed_mps` over the same track.
    SlowPass {
        /// The pass.
        index: usize,
        /// Its new speed [m/s].
        speed_mps: f64,
    },
    /// Set up one more sphere.
    AddSphere(SphereSpec),
}

/// A proposed set of changes and what the predictor says of the plan with them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Recommendation {
    /// In words, each change with its predicted gain.
    pub words: String,
    /// The changes, in order.
    pub changes: Vec<Change>,
    /// Their cost in seconds of survey time.
    pub cost_s: f64,
    /// The prediction with them.
    pub predicted: Prediction,
    /// The plan with them meets the goal.
    pub meets: bool,
}

/// A candidate: the change, its cost, and the information it adds (and takes away: a slowed
/// pass's old returns).
struct Candidate {
    change: Change,
    cost_s: f64,
    add: Info,
    remove: Info,
    /// Returns it adds (or takes away) per sphere; a new sphere's count is one more entry.
    returns: Vec<i64>,
    words: String,
    /// Under the navigation model: its returns, and the span of the survey it replaces [s].
    nav: Option<NavPlan>,
    drop: Option<(f64, f64)>,
}

/// A plan as the search sees it: its information, its returns per sphere and the candidates
/// taken.
#[derive(Clone)]
struct State {
    info: Info,
    returns: Vec<i64>,
    taken: Vec<usize>,
}

/// What scores a state under the navigation model: the plan's returns and the candidates'.
struct NavScore<'a> {
    base: Option<&'a NavPlan>,
    cands: &'a [Candidate],
}

impl NavScore<'_> {
    /// The sigmas of a state under the model (`None`: no model).
    fn sigma(&self, st: &State) -> Option<Option<[f64; P + 1]>> {
        let base = self.base?;
        let taken = st.taken.iter().map(|&k| &self.cands[k]);
        let adds: Vec<&NavPlan> = taken.clone().filter_map(|c| c.nav.as_ref()).collect();
        let drop: Vec<(f64, f64)> = taken.filter_map(|c| c.drop).collect();
        Some(base.sigma_with(&adds, &drop))
    }
}

impl State {
    fn with(&self, k: usize, c: &Candidate) -> Self {
        let mut info = self.info;
        info += &c.add;
        info.a -= c.remove.a;
        info.m -= c.remove.m;
        info.n = info.n.saturating_sub(c.remove.n);
        let mut returns = self.returns.clone();
        returns.resize(returns.len().max(c.returns.len()), 0);
        for (r, d) in returns.iter_mut().zip(&c.returns) {
            *r += d;
        }
        let mut taken = self.taken.clone();
        taken.push(k);
        Self {
            info,
            returns,
            taken,
        }
    }

    /// How far it is from the goal: the worst sigma over its target, the condition number
    /// over its limit, or the returns the solver needs over a sphere's fewest, whichever is
    /// worst (1 or less: met, as [`super::assess`] judges). Under the navigation model the
    /// sigmas are its solver's.
    fn score(&self, goal: &Goal, nav: &NavScore<'_>) -> (f64, Predicted) {
        let mut p = Predicted::of(&self.info);
        if let Some(sigma) = nav.sigma(self) {
            p.sigma = sigma.unwrap_or([f64::INFINITY; P + 1]);
        }
        let pred = Prediction::of(&p);
        let c = pred
            .condition
            .map_or(f64::INFINITY, |c| c / goal.max_condition);
        let fewest = self.returns.iter().copied().min().unwrap_or(0).max(0);
        let r = f64::from(goal.min_returns) / fewest as f64;
        (pred.worst_ratio(goal).max(c).max(r), p)
    }
}

/// The line of the spheres: centroid (N, E), unit direction along it, the unit normal towards
/// the passes, and the spheres' extent along it [m].
pub(super) fn line(s: &Scenario) -> ([f64; 2], [f64; 2], [f64; 2], [f64; 2]) {
    let n = s.sphere.len() as f64;
    let c = s.sphere.iter().fold([0.0, 0.0], |a, sp| {
        [a[0] + sp.ned_m[0] / n, a[1] + sp.ned_m[1] / n]
    });
    // Principal axis of the spheres, else the mean course of the passes.
    let (mut snn, mut see, mut sne) = (0.0, 0.0, 0.0);
    for sp in &s.sphere {
        let (dn, de) = (sp.ned_m[0] - c[0], sp.ned_m[1] - c[1]);
        snn += dn * dn;
        see += de * de;
        sne += dn * de;
    }
    let dir = if snn + see > 1.0 {
        let a = 0.5 * (2.0 * sne).atan2(snn - see);
        [a.cos(), a.sin()]
    } else {
        let (mut n_, mut e_) = (0.0, 0.0);
        for p in &s.trajectory.pass {
            let h = p.heading_deg.to_radians();
            // Courses both ways count alike.
            let (a, b) = ((2.0 * h).cos(), (2.0 * h).sin());
            n_ += a;
            e_ += b;
        }
        let a = 0.5 * e_.atan2(n_);
        [a.cos(), a.sin()]
    };
    let mut normal = [-dir[1], dir[0]];
    let side: f64 = s
        .trajectory
        .pass
        .iter()
        .map(|p| {
            let h = p.heading_deg.to_radians();
            let mid = [
                p.start_ne_m[0] + h.cos() * p.speed_mps * p.duration_s / 2.0,
                p.start_ne_m[1] + h.sin() * p.speed_mps * p.duration_s / 2.0,
            ];
            (mid[0] - c[0]) * normal[0] + (mid[1] - c[1]) * normal[1]
        })
        .sum();
    if side < 0.0 {
        normal = [-normal[0], -normal[1]];
    }
    let along: Vec<f64> = s
        .sphere
        .iter()
        .map(|sp| (sp.ned_m[0] - c[0]) * dir[0] + (sp.ned_m[1] - c[1]) * dir[1])
        .collect();
    let ext = [
        along.iter().copied().fold(f64::INFINITY, f64::min),
        along.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    ];
    (c, dir, normal, ext)
}

fn median_speed(s: &Scenario) -> f64 {
    let mut v: Vec<f64> = s.trajectory.pass.iter().map(|p| p.speed_mps).collect();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(1.5)
}

/// The candidate passes: along the line at each offset, both ways, at the plan's median
/// speed, long enough that every laser sees every sphere.
fn candidate_passes(s: &Scenario) -> Vec<PassSpec> {
    let (c, d, nrm, ext) = line(s);
    let speed = median_speed(s);
    let mut out = Vec::new();
    for &o in &OFFSETS_M {
        let run = 0.6 * o + 5.0;
        let (a, b) = (ext[0] - run, ext[1] + run);
        let at = |t: f64| [c[0] + d[0] * t + nrm[0] * o, c[1] + d[1] * t + nrm[1] * o];
        let course = d[1].atan2(d[0]).to_degrees();
        let duration = (b - a) / speed;
        for (start, heading) in [(at(a), course), (at(b), course + 180.0)] {
            out.push(PassSpec {
                start_ne_m: start.map(|x| (x * 1000.0).round() / 1000.0),
                heading_deg: (heading.rem_euclid(360.0) * 10.0).round() / 10.0,
                speed_mps: speed,
                duration_s: (duration * 10.0).round() / 10.0,
                down_m: None,
            });
        }
    }
    out
}

/// The candidate spheres: beyond either end of the line (by the spheres' spacing, 10 m at
/// least) at the mean height, and one 1.5 m above the others at their centroid, each like the
/// nearest sphere.
fn candidate_spheres(s: &Scenario) -> Vec<SphereSpec> {
    let (c, d, _, ext) = line(s);
    let n = s.sphere.len();
    let spacing = if n > 1 {
        ((ext[1] - ext[0]) / (n - 1) as f64).max(10.0)
    } else {
        10.0
    };
    let down = s.sphere.iter().map(|sp| sp.ned_m[2]).sum::<f64>() / n as f64;
    let like = |ne: [f64; 2], down: f64, k: usize| {
        let near = s
            .sphere
            .iter()
            .min_by(|a, b| {
                let da = (a.ned_m[0] - ne[0]).hypot(a.ned_m[1] - ne[1]);
                let db = (b.ned_m[0] - ne[0]).hypot(b.ned_m[1] - ne[1]);
                da.total_cmp(&db)
            })
            .cloned();
        let mut sp = near.unwrap_or_else(|| s.sphere[0].clone());
        sp.id = format!("NEW{k}");
        let lift = down - sp.ned_m[2];
        sp.ned_m = [ne[0], ne[1], down].map(|x| (x * 1000.0).round() / 1000.0);
        sp.stand_down_m = sp.stand_down_m.map(|f| f + lift.max(0.0));
        sp
    };
    let at = |t: f64| [c[0] + d[0] * t, c[1] + d[1] * t];
    vec![
        like(at(ext[1] + spacing), down, 1),
        like(at(ext[0] - spacing), down, 2),
        like(at(0.0), down - 1.5, 3),
    ]
}

/// A scenario with only these passes (and the same scene).
fn with_passes(s: &Scenario, passes: Vec<PassSpec>) -> Scenario {
    let mut t = s.clone();
    t.trajectory.pass = passes;
    t.trajectory.file = None;
    t
}

/// The information of one pass alone over the scenario's spheres (and its returns under the
/// navigation model).
fn pass_info(
    s: &Scenario,
    noise: &PlanNoise,
    p: &PassSpec,
    threads: usize,
) -> Result<(Info, Vec<i64>, Option<NavPlan>), crate::Error> {
    let t = with_passes(s, vec![p.clone()]);
    let obs = observe(&t, threads)?;
    let g = geometry_of(&t, noise, &obs, segments(&t));
    let returns = returns_per_sphere(&g, |_| true);
    Ok((g.total(), returns, g.nav))
}

/// Each sphere's returns in the segments `keep` says.
fn returns_per_sphere(g: &Geometry, keep: impl Fn(usize) -> bool) -> Vec<i64> {
    let n = g.cells.first().map_or(0, Vec::len);
    (0..n)
        .map(|j| {
            g.cells
                .iter()
                .enumerate()
                .filter(|(k, _)| keep(*k))
                .map(|(_, r)| i64::from(r[j].info.n))
                .sum()
        })
        .collect()
}

/// Apply changes to a scenario.
pub fn apply(s: &Scenario, changes: &[Change]) -> Scenario {
    let mut t = s.clone();
    for c in changes {
        match c {
            Change::AddPass(p) => t.trajectory.pass.push(p.clone()),
            Change::SlowPass { index, speed_mps } => {
                if let Some(p) = t.trajectory.pass.get_mut(*index) {
                    p.duration_s = (p.duration_s * p.speed_mps / speed_mps * 10.0).round() / 10.0;
                    p.speed_mps = *speed_mps;
                }
            }
            Change::AddSphere(sp) => t.sphere.push(sp.clone()),
        }
    }
    t
}

fn sigma_words(before: &Prediction, after: &Prediction, goal: &Goal) -> String {
    // The parameter furthest from its target before, and what it becomes.
    let ratio = |p: &Prediction, i: usize| {
        let t = if i < 3 { goal.sigma_deg } else { goal.sigma_m };
        p.sigma_deg_m[i].map_or(f64::INFINITY, |s| s / t)
    };
    let i = (0..6)
        .max_by(|&a, &b| ratio(before, a).total_cmp(&ratio(before, b)))
        .unwrap_or(0);
    let f = |p: &Prediction| {
        super::sigma_text(p.sigma_deg_m[i], i, true).unwrap_or_else(|| "undetermined".into())
    };
    let cond = |p: &Prediction| p.condition.map_or("inf".into(), |c| format!("{c:.0}"));
    format!(
        "{} sigma {} -> {}, condition {} -> {}",
        spherecal::georef::NAMES[i],
        f(before),
        f(after),
        cond(before),
        cond(after)
    )
}

/// A candidate pass, traced: the pass, in words, its cost (its duration and a turn) [s], and
/// the information and returns per sphere it adds.
pub struct PassCandidate {
    /// The pass.
    pub pass: PassSpec,
    /// In words.
    pub words: String,
    /// Its cost [s].
    pub cost_s: f64,
    /// The information it adds.
    pub info: Info,
    /// Its returns per sphere.
    pub returns: Vec<i64>,
    /// Its returns under the navigation model (`None`: the scenario declares none).
    pub nav: Option<NavPlan>,
}

/// Every candidate pass of a plan ([`candidate_passes`]), traced.
pub fn candidate_pass_infos(
    s: &Scenario,
    noise: &PlanNoise,
    threads: usize,
) -> Result<Vec<PassCandidate>, crate::Error> {
    let turn = s.trajectory.turn_s;
    let mut out = Vec::new();
    for p in candidate_passes(s) {
        let (info, returns, nav) = pass_info(s, noise, &p, threads)?;
        out.push(PassCandidate {
            words: format!(
                "add a {} pass {:.0} m off the spheres' line at {:.1} m/s ({:.0} s, course {:03.0} deg, start {})",
                super::bound(p.heading_deg),
                p_offset(s, &p),
                p.speed_mps,
                p.duration_s,
                p.heading_deg.rem_euclid(360.0),
                super::place(s, p.start_ne_m)
            ),
            cost_s: p.duration_s + turn,
            info,
            returns,
            nav,
            pass: p,
        });
    }
    Ok(out)
}

/// The changes weighed: each candidate pass added, each pass driven at half its speed, each
/// candidate sphere set up (while the scene has room for one).
fn candidates(
    s: &Scenario,
    noise: &PlanNoise,
    g: &Geometry,
    threads: usize,
) -> Result<Vec<Candidate>, crate::Error> {
    let mut cands: Vec<Candidate> = candidate_pass_infos(s, noise, threads)?
        .into_iter()
        .map(|c| Candidate {
            add: c.info,
            remove: Info::default(),
            returns: c.returns,
            cost_s: c.cost_s,
            words: c.words,
            change: Change::AddPass(c.pass),
            nav: c.nav,
            drop: None,
        })
        .collect();
    for (i, p) in s.trajectory.pass.iter().enumerate() {
        let speed = (p.speed_mps / 2.0 * 100.0).round() / 100.0;
        let mut slow = p.clone();
        slow.duration_s = p.duration_s * p.speed_mps / speed;
        let k = g
            .segments
            .iter()
            .position(|(seg, _, _)| *seg == Segment::Pass(i));
        let (add, mut returns, nav) = pass_info(s, noise, &slow, threads)?;
        let old = returns_per_sphere(g, |kk| Some(kk) == k);
        for (r, o) in returns.iter_mut().zip(old) {
            *r -= o;
        }
        cands.push(Candidate {
            add,
            remove: k.map_or(Info::default(), |k| g.sum(|kk, _| kk == k)),
            returns,
            cost_s: slow.duration_s - p.duration_s,
            words: format!(
                "drive pass {} at {speed:.2} m/s instead of {:.2} ({:.0} s more)",
                i + 1,
                p.speed_mps,
                slow.duration_s - p.duration_s
            ),
            change: Change::SlowPass {
                index: i,
                speed_mps: speed,
            },
            nav,
            drop: k.map(|k| (g.segments[k].1, g.segments[k].2)),
        });
    }
    if s.sphere.len() < spherecal::sim::lidar::MAX_TARGETS {
        for sp in candidate_spheres(s) {
            let mut t = s.clone();
            t.sphere = vec![sp.clone()];
            let obs = observe(&t, threads)?;
            let sg = geometry_of(&t, noise, &obs, segments(&t));
            let add = sg.total();
            let mut returns = vec![0; s.sphere.len()];
            returns.push(i64::from(add.n));
            cands.push(Candidate {
                add,
                remove: Info::default(),
                returns,
                cost_s: SPHERE_COST_S,
                words: format!(
                    "set up one more sphere at N {:.1} E {:.1}, {:.1} m up ({})",
                    sp.ned_m[0], sp.ned_m[1], -sp.ned_m[2], sp.id
                ),
                change: Change::AddSphere(sp),
                nav: sg.nav,
                drop: None,
            });
        }
    }
    Ok(cands)
}

/// The changes taken greedily from `base` (the best gain per second first) until the plan
/// meets `goal` or no change helps: one recommendation, or none.
fn greedy(
    cands: &[Candidate],
    base: State,
    goal: &Goal,
    nav: &NavScore<'_>,
    before: Prediction,
) -> Option<Recommendation> {
    let mut state = base;
    let mut taken: Vec<usize> = Vec::new();
    let mut words = Vec::new();
    let mut cost = 0.0;
    let mut now = state.score(goal, nav).0;
    let mut last = before;
    for _ in 0..MAX_STEPS {
        let best = cands
            .iter()
            .enumerate()
            .filter(|(k, c)| {
                let slowed_again = matches!(c.change, Change::SlowPass { .. })
                    && taken.iter().any(|&t| cands[t].change == c.change);
                !taken.contains(k) && !slowed_again
            })
            .map(|(k, c)| {
                let (sc, p) = state.with(k, c).score(goal, nav);
                let gain = (now.max(1e-300).ln() - sc.max(1e-300).ln()) / c.cost_s.max(1.0);
                // A change that meets the goal now beats every partial gain, cheapest first.
                let key = if sc <= 1.0 { 1e9 - c.cost_s } else { gain };
                (k, p, sc, key)
            })
            .filter(|(_, _, sc, _)| sc.is_finite() && *sc < now)
            .max_by(|a, b| a.3.total_cmp(&b.3));
        let Some((k, p, sc, _)) = best else { break };
        state = state.with(k, &cands[k]);
        taken.push(k);
        cost += cands[k].cost_s;
        let after = Prediction::of(&p);
        words.push(format!(
            "{}: {}",
            cands[k].words,
            sigma_words(&last, &after, goal)
        ));
        last = after;
        now = sc;
        if sc <= 1.0 {
            break;
        }
    }
    (!taken.is_empty()).then(|| Recommendation {
        words: words.join("; then "),
        changes: taken.iter().map(|&k| cands[k].change.clone()).collect(),
        cost_s: cost,
        meets: now <= 1.0,
        predicted: last,
    })
}

/// The recommendations for a traced plan that misses its goal.
pub fn recommend(
    s: &Scenario,
    noise: &PlanNoise,
    g: &Geometry,
    goal: &Goal,
    threads: usize,
) -> Result<Vec<Recommendation>, crate::Error> {
    if s.trajectory.file.is_some() {
        return Ok(Vec::new());
    }
    let cands = candidates(s, noise, g, threads)?;
    let base = State {
        info: g.total(),
        returns: returns_per_sphere(g, |_| true),
        taken: Vec::new(),
    };
    let nav = NavScore {
        base: g.nav.as_ref(),
        cands: &cands,
    };
    let before = Prediction::of(&base.score(goal, &nav).1);
    let mut out = Vec::new();
    // Single changes that meet the goal, cheapest first (up to three).
    let mut singles: Vec<(f64, usize, Predicted)> = cands
        .iter()
        .enumerate()
        .map(|(k, c)| (c.cost_s, k, base.with(k, c).score(goal, &nav)))
        .filter(|(_, _, (sc, _))| *sc <= 1.0)
        .map(|(cost, k, (_, p))| (cost, k, p))
        .collect();
    singles.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (cost, k, p) in singles.iter().take(3) {
        let c = &cands[*k];
        let after = Prediction::of(p);
        out.push(Recommendation {
            words: format!("{}: {}", c.words, sigma_words(&before, &after, goal)),
            changes: vec![c.change.clone()],
            cost_s: *cost,
            meets: true,
            predicted: after,
        });
    }
    if !out.is_empty() {
        return Ok(out);
    }
    // Otherwise greedily: the best gain per second, until it meets or no change helps.
    out.extend(greedy(&cands, base, goal, &nav, before));
    Ok(out)
}

/// A candidate pass's distance from the spheres' line [m].
fn p_offset(s: &Scenario, p: &PassSpec) -> f64 {
    let (c, _, nrm, _) = line(s);
    ((p.start_ne_m[0] - c[0]) * nrm[0] + (p.start_ne_m[1] - c[1]) * nrm[1]).abs()
}

//! `plan --design`: the survey a site needs, not only the accuracy of the one described
//! (issue 30). From a scenario's site (its scene, sensor, mounting, INS and its navigation
//! model, the area of its spheres) candidate surveys are built, each traced and predicted as
//! [`super::plan`] predicts one, and the cheapest that meets the goal is proposed:
//!
//! - aerial (the INS flies [`AERIAL_M`] or more above the spheres): the pattern of airborne
//!   boresight practice — two opposing lines over the targets at the working height, a line at
//!   a second, lower height (it separates boresight pitch from the lever arm along the track),
//!   a crossing line — at each of [`HEIGHTS_M`] and [`SPEEDS_MPS`], with 3, 4 or 6 spheres of
//!   each of [`RADII_M`] on tripods across the swath;
//! - a vessel: its own passes kept, 2, 3 or 4 spheres of each of [`RADII_M`] spread along the
//!   line of its spheres (the ends of the reach and between), on tripods.
//!
//! Information adds over spheres (and the navigation model's solver is run on a subset), so
//! one trace per flight and sphere size serves every sphere count. The cost is survey time
//! plus a crew's time per sphere ([`super::recommend::SPHERE_COST_S`], scaled by its size: a
//! larger sphere is harder to carry and set up).

use super::recommend::SPHERE_COST_S;
use super::{geometry, PlanNoise, Prediction};
use crate::config::goal::Goal;
use crate::config::scenario::{PassSpec, Scenario, SphereSpec};
use serde::{Deserialize, Serialize};

/// Above this height over the spheres a scenario is an aerial survey [m].
pub const AERIAL_M: f64 = 10.0;
/// Working heights tried above the ground [m] (VLP-16 drone surveys fly 25-60 m).
pub const HEIGHTS_M: [f64; 3] = [25.0, 40.0, 60.0];
/// Speeds tried [m/s].
pub const SPEEDS_MPS: [f64; 3] = [3.0, 5.0, 8.0];
/// Sphere radii tried [m].
pub const RADII_M: [f64; 3] = [0.15, 0.25, 0.35];
/// Candidates the text shows.
pub const SHOWN: usize = 12;
/// A tripod's height: the sphere's centre this far above the ground [m].
pub const TRIPOD_M: f64 = 1.55;

/// One candidate survey weighed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// In words.
    pub words: String,
    /// Working height above the ground [m] (aerial; `None` for a vessel).
    pub height_m: Option<f64>,
    /// Speed [m/s] (aerial).
    pub speed_mps: Option<f64>,
    /// Spheres and their radius [m].
    pub spheres: usize,
    /// Where the spheres are, in words.
    pub layout: String,
    /// See `spheres`.
    pub radius_m: f64,
    /// Survey time [s] and the cost with the spheres' set-up [s].
    pub survey_s: f64,
    /// See `survey_s`.
    pub cost_s: f64,
    /// The prediction.
    pub predicted: Prediction,
    /// The worst sigma over its target (1 or less: met).
    pub worst_ratio: f64,
    /// It meets the goal (sigmas, conditioning, returns per sphere).
    pub meets: bool,
}

/// The proposal: the chosen candidate (cheapest that meets the goal, else the closest) as a
/// scenario, and every candidate weighed.
#[derive(Debug, Clone)]
pub struct Design {
    /// `aerial` or `vessel`.
    pub kind: &'static str,
    /// The proposed survey.
    pub scenario: Scenario,
    /// Index of it in `candidates`.
    pub chosen: usize,
    /// Every candidate, in the order weighed.
    pub candidates: Vec<Candidate>,
}

/// The ground under the spheres (the floor their stands stand on, NED down) and the area's
/// centre (N, E) [m].
fn ground_and_centre(s: &Scenario) -> (f64, [f64; 2]) {
    let n = s.sphere.len().max(1) as f64;
    let g = s.sphere.iter().map(SphereSpec::floor_down_m).sum::<f64>() / n;
    let c = s.sphere.iter().fold([0.0, 0.0], |a, sp| {
        [a[0] + sp.ned_m[0] / n, a[1] + sp.ned_m[1] / n]
    });
    (g, c)
}

/// The ground under the spheres (NED down of the floor their stands stand on) [m].
pub fn ground(s: &Scenario) -> f64 {
    ground_and_centre(s).0
}

/// An aerial survey whose spheres all rest on the ground: the beam's footprint straddles each
/// sphere's edge with the grass right behind it, and the mixed returns bias the lever arm's
/// height, which the prediction leaves out (docs/history/issue-30-drone.md, session 23).
pub fn every_sphere_grounded(s: &Scenario) -> bool {
    is_aerial(s) && s.sphere.iter().all(|x| x.stand == "none")
}

/// The scenario is an aerial survey: its passes fly [`AERIAL_M`] or more above the spheres.
pub fn is_aerial(s: &Scenario) -> bool {
    let top = s
        .sphere
        .iter()
        .map(|sp| sp.ned_m[2])
        .fold(f64::INFINITY, f64::min);
    let tr = &s.trajectory;
    !tr.pass.is_empty()
        && tr
            .pass
            .iter()
            .all(|p| top - p.down_m.unwrap_or(tr.ins_down_m) >= AERIAL_M)
}

/// The second, lower flight height for a working height `h` above the ground [m].
fn lower_m(h: f64) -> f64 {
    (0.6 * h).max(15.0)
}

/// The aerial pattern over `c` along `heading_deg` at `h` (and 0.6 h) above `ground`, at
/// `speed`: each line reaches `reach` beyond the targets' centre both ways.
pub(super) fn aerial_passes(
    c: [f64; 2],
    heading_deg: f64,
    ground: f64,
    h: f64,
    speed: f64,
    reach: f64,
) -> Vec<PassSpec> {
    let line = |off: f64, heading: f64, down: f64| {
        let a = heading.to_radians();
        let (dir, across) = ([a.cos(), a.sin()], [-a.sin(), a.cos()]);
        PassSpec {
            start_ne_m: [
                c[0] - dir[0] * reach + across[0] * off,
                c[1] - dir[1] * reach + across[1] * off,
            ],
            heading_deg: heading.rem_euclid(360.0),
            speed_mps: speed,
            duration_s: (2.0 * reach / speed).ceil(),
            down_m: Some(down),
        }
    };
    let (hi, lo) = (ground - h, ground - lower_m(h));
    let off = 0.1 * h;
    vec![
        line(-off, heading_deg, hi),
        line(off, heading_deg + 180.0, hi),
        line(0.0, heading_deg, lo),
        line(0.0, heading_deg + 90.0, hi),
    ]
}

/// Sphere positions (N, E) about the centre `c`: the four corners of a rectangle `along` the
/// lines and `across` them, then two further across the middle. A layout of n spheres is the
/// first n (three: a right triangle; four: the rectangle).
fn positions(c: [f64; 2], heading_deg: f64, along: f64, across: f64) -> Vec<[f64; 2]> {
    let a = heading_deg.to_radians();
    let (dir, side) = ([a.cos(), a.sin()], [-a.sin(), a.cos()]);
    let at = |u: f64, v: f64| {
        [
            c[0] + dir[0] * u + side[0] * v,
            c[1] + dir[1] * u + side[1] * v,
        ]
    };
    vec![
        at(-along, -across),
        at(along, -across),
        at(along, across),
        at(-along, across),
        at(0.0, -1.6 * across),
        at(0.0, 1.6 * across),
    ]
}

/// The spheres at `pos`, radius `r`, on tripods on the ground at `ground`.
fn spheres_at(pos: &[[f64; 2]], r: f64, ground: f64) -> Vec<SphereSpec> {
    pos.iter()
        .enumerate()
        .map(|(k, p)| SphereSpec {
            id: format!("T{}", k + 1),
            ned_m: [p[0], p[1], ground - TRIPOD_M],
            radius_m: r,
            stand: "tripod".into(),
            stand_down_m: Some(ground),
            reflectivity: 0.8,
        })
        .collect()
}

/// One traced survey and what its candidates share.
struct Layout<'a> {
    /// The sphere counts to weigh (the first n of the scenario's spheres).
    counts: &'a [usize],
    radius_m: f64,
    survey_s: f64,
    height_m: Option<f64>,
    speed_mps: Option<f64>,
    /// Where the spheres are, in words.
    layout: String,
    /// The candidate of n spheres in words.
    label: &'a dyn Fn(usize) -> String,
}

/// Weigh one traced layout: every sphere count it names (the first `n` of its spheres).
fn weigh(
    s: &Scenario,
    noise: &PlanNoise,
    goal: &Goal,
    l: &Layout<'_>,
    threads: usize,
    out: &mut Vec<(Candidate, Scenario)>,
) -> Result<(), crate::Error> {
    let (r, survey_s) = (l.radius_m, l.survey_s);
    let g = geometry(s, noise, threads)?;
    let all = s.sphere.len();
    for &n in l.counts {
        let keep: Vec<bool> = (0..all).map(|j| j < n).collect();
        let p = g.predict(|j| keep[j]);
        let returns: Vec<u32> = (0..n).map(|j| g.returns_of(j)).collect();
        let pred = Prediction::of(&p);
        let ids: Vec<String> = s.sphere[..n].iter().map(|x| x.id.clone()).collect();
        let meets = super::assess(&pred, &p, &returns, &ids, goal).is_empty();
        let cost_s = survey_s + n as f64 * SPHERE_COST_S * (r / 0.25).max(0.6);
        let mut sc = s.clone();
        sc.sphere.truncate(n);
        out.push((
            Candidate {
                words: (l.label)(n),
                height_m: l.height_m,
                speed_mps: l.speed_mps,
                spheres: n,
                layout: l.layout.clone(),
                radius_m: r,
                survey_s,
                cost_s,
                worst_ratio: pred.worst_ratio(goal),
                predicted: pred,
                meets,
            },
            sc,
        ));
    }
    Ok(())
}

/// Design the survey for the site of `s` (see the module's words).
pub fn design(s: &Scenario, goal: &Goal, threads: usize) -> Result<Design, crate::Error> {
    if s.trajectory.file.is_some() {
        return Err(
            "plan --design: the scenario drives a recorded trajectory; design needs passes \
                    (`[[trajectory.pass]]`) to start from"
                .into(),
        );
    }
    let noise = PlanNoise::of(s);
    let (ground, c) = ground_and_centre(s);
    let heading = s.trajectory.pass.first().map_or(0.0, |p| p.heading_deg);
    let aerial = is_aerial(s);
    let mut weighed: Vec<(Candidate, Scenario)> = Vec::new();
    if aerial {
        for &h in &HEIGHTS_M {
            for &v in &SPEEDS_MPS {
                for &r in &RADII_M {
                    // Targets 0.3 h along and 0.25 h across (the middle of the swath), lines
                    // reaching 25 m beyond the farthest.
                    let (along, across) = ((0.3 * h).max(10.0), (0.25 * h).max(8.0));
                    let reach = along.max(1.6 * across) + 25.0;
                    let mut sc = s.clone();
                    sc.name = format!("{}-design", s.name);
                    sc.trajectory.pass = aerial_passes(c, heading, ground, h, v, reach);
                    sc.trajectory.ins_down_m = ground - h;
                    sc.sphere = spheres_at(&positions(c, heading, along, across), r, ground);
                    sc.validate().map_err(|e| e.to_string())?;
                    let survey_s = sc.duration_s();
                    let label = |n: usize| {
                        format!(
                            "fly {h:.0} m and {:.0} m above the ground at {v:.0} m/s (two opposing \
                             lines, one lower, one crossing: {survey_s:.0} s); {n} spheres of \
                             {r:.2} m on tripods",
                            lower_m(h)
                        )
                    };
                    let l = Layout {
                        counts: &[3, 4, 6],
                        radius_m: r,
                        survey_s,
                        height_m: Some(h),
                        speed_mps: Some(v),
                        layout: format!("{along:.0} m along, {across:.0} m across the centre"),
                        label: &label,
                    };
                    weigh(&sc, &noise, goal, &l, threads, &mut weighed)?;
                }
            }
        }
    } else {
        // Along the line of the spheres, over the reach the passes cover.
        let (c, dir, _, ext) = super::recommend::line(s);
        let half = ((ext[1] - ext[0]) / 2.0).max(10.0);
        let height =
            s.sphere.iter().map(|sp| sp.ned_m[2]).sum::<f64>() / s.sphere.len().max(1) as f64;
        for &r in &RADII_M {
            // The reach of the spheres as planned and twice as long; all at the planned
            // height, or every other sphere raised 1.5 m (height differences separate the
            // angles from the vertical lever arm).
            for (stretch, raise) in [(1.0, 0.0), (1.0, 1.5), (2.0, 0.0), (2.0, 1.5)] {
                let half = half * stretch;
                let mut sc = s.clone();
                sc.name = format!("{}-design", s.name);
                // Ends of the reach, then the middle, then a quarter in: every count spread.
                let along = [-half, half, 0.0, -half / 2.0];
                let pos: Vec<[f64; 2]> = along
                    .iter()
                    .map(|&u| [c[0] + dir[0] * u, c[1] + dir[1] * u])
                    .collect();
                sc.sphere = spheres_at(&pos, r, ground);
                for (k, sp) in sc.sphere.iter_mut().enumerate() {
                    sp.ned_m[2] = height - if k % 2 == 1 { raise } else { 0.0 };
                }
                sc.validate().map_err(|e| e.to_string())?;
                let survey_s = sc.duration_s();
                let label = |n: usize| {
                    format!(
                        "the planned passes ({survey_s:.0} s); {n} spheres of {r:.2} m on tripods \
                         along {:.0} m of the reach{}",
                        2.0 * half,
                        if raise > 0.0 {
                            format!(", every other one raised {raise} m")
                        } else {
                            String::new()
                        }
                    )
                };
                let l = Layout {
                    counts: &[2, 3, 4],
                    radius_m: r,
                    survey_s,
                    height_m: None,
                    speed_mps: None,
                    layout: format!(
                        "along {:.0} m{}",
                        2.0 * half,
                        if raise > 0.0 {
                            ", every other raised"
                        } else {
                            ""
                        }
                    ),
                    label: &label,
                };
                weigh(&sc, &noise, goal, &l, threads, &mut weighed)?;
            }
        }
    }
    let chosen = weighed
        .iter()
        .enumerate()
        .filter(|(_, (c, _))| c.meets)
        .min_by(|a, b| a.1 .0.cost_s.total_cmp(&b.1 .0.cost_s))
        .or_else(|| {
            weighed
                .iter()
                .enumerate()
                .min_by(|a, b| a.1 .0.worst_ratio.total_cmp(&b.1 .0.worst_ratio))
        })
        .map(|(k, _)| k)
        .ok_or("plan --design: no candidate survey")?;
    let scenario = weighed[chosen].1.clone();
    Ok(Design {
        kind: if aerial { "aerial" } else { "vessel" },
        scenario,
        chosen,
        candidates: weighed.into_iter().map(|(c, _)| c).collect(),
    })
}

impl Design {
    /// The candidates to show first: the proposal, the cheapest that meet, then the closest
    /// that do not.
    pub fn order(&self) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.candidates.len()).collect();
        order.sort_by(|&a, &b| {
            let (x, y) = (&self.candidates[a], &self.candidates[b]);
            (b == self.chosen)
                .cmp(&(a == self.chosen))
                .then(y.meets.cmp(&x.meets))
                .then(if x.meets {
                    x.cost_s.total_cmp(&y.cost_s)
                } else {
                    x.worst_ratio.total_cmp(&y.worst_ratio)
                })
        });
        order
    }
}

/// The design in words: the proposal and the table weighed.
pub fn render(d: &Design, goal: &Goal) -> String {
    use std::fmt::Write as _;
    let mut o = String::new();
    let c = &d.candidates[d.chosen];
    let _ = writeln!(
        o,
        "design ({} survey, {} candidates weighed; target {} deg, {} mm):",
        d.kind,
        d.candidates.len(),
        goal.sigma_deg,
        goal.sigma_m * 1e3
    );
    let _ = writeln!(
        o,
        "proposed: {} ({}; cost {:.0} s with the spheres' set-up)",
        c.words,
        if c.meets {
            "meets the targets"
        } else {
            "the closest to the targets: none meets them"
        },
        c.cost_s
    );
    let _ = writeln!(
        o,
        "  {:>6} {:>5} {:>3} {:>5} {:>6} {:>8} {:>8} {:>8} {:>7} {:>7} {:>7}  meets  spheres",
        "height", "m/s", "n", "r m", "cost s", "roll", "pitch", "heading", "x mm", "y mm", "z mm"
    );
    let order = d.order();
    for &k in order.iter().take(SHOWN) {
        let c = &d.candidates[k];
        let s = |i: usize| {
            super::sigma_text(c.predicted.sigma_deg_m[i], i, false).unwrap_or_else(|| "-".into())
        };
        let _ = writeln!(
            o,
            "{} {:>6} {:>5} {:>3} {:>5.2} {:>6.0} {:>8} {:>8} {:>8} {:>7} {:>7} {:>7}  {}  {}",
            if k == d.chosen { '>' } else { ' ' },
            c.height_m.map_or("-".into(), |h| format!("{h:.0}")),
            c.speed_mps.map_or("-".into(), |v| format!("{v:.0}")),
            c.spheres,
            c.radius_m,
            c.cost_s,
            s(0),
            s(1),
            s(2),
            s(3),
            s(4),
            s(5),
            if c.meets { "yes" } else { "no " },
            c.layout
        );
    }
    if d.candidates.len() > SHOWN {
        let _ = writeln!(
            o,
            "  ({} more in `--report OUT.json`)",
            d.candidates.len() - SHOWN
        );
    }
    o
}

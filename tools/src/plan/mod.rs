//! `spherecal plan`: the accuracy a planned calibration survey will give, before anyone goes
//! to the quay. The scenario's passes are traced against its scene (only the firings that can
//! reach a sphere, against everything that may hide it: [`spherecal::sim::LidarConfig`]'s
//! `targets_only`), every sphere return becomes the observation the pipeline would make of it,
//! and the core predictor ([`spherecal::calib::predict`]) turns their geometry and the noise
//! model into each parameter's sigma, the correlations, the conditioning and the weakest
//! direction, without drawing any noise. Information adds over returns, so each pass and
//! sphere's share is known (the sigmas without it), and a candidate change (a pass, a slower
//! pass, a sphere: [`recommend`]) costs only its own tracing.

pub mod design;
pub mod html;
pub mod live;
pub mod nav;
pub mod observe;
pub mod recommend;
pub mod site;

use crate::config::goal::Goal;
pub use observe::{
    geometry, geometry_of, observe, segments, targets_of_scenario, Cell, Geometry, Segment,
};

use crate::config::scenario::Scenario;
use serde::{Deserialize, Serialize};
use spherecal::calib::predict::{NoiseModel, Predicted};
use spherecal::georef::{Params, NAMES, P};

/// Half the span of the central differences that give each return's velocity and turn rate
/// (the pipeline's, [`spherecal::align::history`]) [s].
const RATE_HALF_S: f64 = 0.2;

/// The noise the plan assumes (1 sigma).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlanNoise {
    /// Range noise [m].
    pub range_m: f64,
    /// Beam divergence along the scan [mrad] when the range noise grows at grazing incidence
    /// (0: it does not).
    pub incidence_divergence_mrad: f64,
    /// INS attitude noise per angle [deg] ...
    pub attitude_deg: f64,
    /// ... and position noise per axis [m], per sample ...
    pub position_m: f64,
    /// ... at this rate [Hz].
    pub ins_rate_hz: f64,
    /// The scenario states no noise at all: these are the sensors' specified values
    /// ([`Self::specified`]).
    pub assumed: bool,
}

impl PlanNoise {
    /// The noise a plan assumes when its scenario states none: the scanner's range accuracy
    /// (its datasheet's, [`spherecal::sim::Scanner::range_sigma_m`]; a VLP-16's +-3 cm) and a
    /// VN-200-class INS (0.03 deg, 2 cm).
    pub fn specified(scanner: Option<spherecal::sim::Scanner>) -> [f64; 3] {
        let range = scanner.map_or(0.03, spherecal::sim::Scanner::range_sigma_m);
        [range, 0.03, 0.02]
    }

    /// The scenario's noise, or the specified values when it states none (a noise-free
    /// simulation predicts nothing).
    pub fn of(s: &Scenario) -> Self {
        let none =
            s.lidar.range_sigma_m == 0.0 && s.ins.att_sigma_deg == 0.0 && s.ins.pos_sigma_m == 0.0;
        let [range, att, pos] = if none {
            Self::specified(s.scanner())
        } else {
            [
                s.lidar.range_sigma_m,
                s.ins.att_sigma_deg,
                s.ins.pos_sigma_m,
            ]
        };
        Self {
            range_m: range,
            incidence_divergence_mrad: if s.lidar.incidence_noise {
                s.lidar.beam_divergence_mrad[0]
            } else {
                0.0
            },
            attitude_deg: att,
            position_m: pos,
            ins_rate_hz: s.ins.rate_hz,
            assumed: none,
        }
    }

    /// The core predictor's model, with the model's range quantisation.
    pub fn model(&self, unit_m: f64) -> NoiseModel {
        NoiseModel {
            range: self.range_m,
            beam_sigma: self.incidence_divergence_mrad * 1e-3 / 4.0,
            range_unit: unit_m,
            position: self.position_m,
            attitude: self.attitude_deg.to_radians(),
            ins_period_ns: (1e9 / self.ins_rate_hz.max(1.0)).round() as i64,
            // The plan's returns are ideal rays (`observe`): no bloom in them to model. (Its
            // gradient on ideal rays predicted the time offset's sigma 1.3-1.4x too large on
            // table1-noisy and pontoon-noisy, session 39.)
            footprint: None,
        }
    }
}

/// The scenario with [`PlanNoise::specified`] where it states no noise: what a plan assumes,
/// and what the Monte Carlo that checks it simulates.
pub fn with_planning_noise(s: &Scenario) -> Scenario {
    let mut s = s.clone();
    let n = PlanNoise::of(&s);
    if n.assumed {
        s.lidar.range_sigma_m = n.range_m;
        s.ins.att_sigma_deg = n.attitude_deg;
        s.ins.pos_sigma_m = n.position_m;
    }
    s
}

/// A prediction in the surveyor's units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Prediction {
    /// 1 sigma: roll, pitch, heading [deg], x, y, z [m] (null: not determined).
    pub sigma_deg_m: [Option<f64>; P],
    /// 1 sigma of the time offset [s].
    pub sigma_time_offset_s: Option<f64>,
    /// Condition number of the unit-diagonal normal matrix.
    pub condition: Option<f64>,
    /// Returns.
    pub returns: u32,
}

impl Prediction {
    /// From the core's.
    pub fn of(p: &Predicted) -> Self {
        let fin = |v: f64| v.is_finite().then_some(v);
        let d = Params(core::array::from_fn(|i| p.sigma[i])).deg_m().0;
        Self {
            sigma_deg_m: d.map(fin),
            sigma_time_offset_s: fin(p.sigma[P]),
            condition: fin(p.condition),
            returns: p.n,
        }
    }

    /// The worst sigma over its target (above 1: missed; infinite: not determined).
    pub fn worst_ratio(&self, goal: &Goal) -> f64 {
        (0..P)
            .map(|i| {
                let t = if i < 3 { goal.sigma_deg } else { goal.sigma_m };
                self.sigma_deg_m[i].map_or(f64::INFINITY, |s| s / t)
            })
            .fold(0.0, f64::max)
    }
}

/// What one pass or sphere brings: the prediction without it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Share {
    /// `pass 3 (northbound, 1.3 m/s)`, `turn after pass 1`, or the sphere's id.
    pub what: String,
    /// Its sphere returns.
    pub returns: u32,
    /// The ranges they span [m] (null without returns).
    pub range_m: Option<[f64; 2]>,
    /// The sigmas without it (null: not determined without it).
    pub sigma_without: [Option<f64>; P],
    /// Its share of the information: the mean over the six of 1 - (sigma / sigma without)^2
    /// (0: adds nothing; 1: nothing without it).
    pub share: f64,
}

/// The plan's report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanReport {
    /// Scenario name.
    pub scenario: String,
    /// The noise assumed.
    pub noise: PlanNoise,
    /// The accuracy wanted.
    pub goal: Goal,
    /// The navigation errors that wander the prediction is under (`[ins.correlated]`), in
    /// words (`None`: white per sample).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub navigation: Option<String>,
    /// The prediction.
    pub predicted: Prediction,
    /// Correlations of the six and the time offset (row-major 7x7).
    pub correlation: Vec<Vec<f64>>,
    /// The weakest direction: the six and the time offset (unit vector of the scaled normal
    /// matrix).
    pub weakest: [f64; P + 1],
    /// The plan meets the goal.
    pub meets: bool,
    /// What misses it, in words.
    pub missing: Vec<String>,
    /// Per pass (and turn with sphere returns).
    pub passes: Vec<Share>,
    /// Per sphere.
    pub spheres: Vec<Share>,
    /// What the prediction leaves out, in words (every sphere of an aerial survey on the
    /// ground: [`design::every_sphere_grounded`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Changes that meet the goal, cheapest first (or the best steps towards it).
    pub recommendations: Vec<recommend::Recommendation>,
    /// Time to predict [ms] (tracing included, recommendations not).
    pub ms: f64,
}

/// Words for a segment.
pub fn segment_name(s: &Scenario, seg: Segment) -> String {
    match seg {
        Segment::Pass(i) => {
            let p = &s.trajectory.pass[i];
            format!(
                "pass {} ({}, {:.1} m/s)",
                i + 1,
                bound(p.heading_deg),
                p.speed_mps
            )
        }
        Segment::Turn(i) => format!("turn after pass {}", i + 1),
        Segment::Recorded => "the recorded trajectory".into(),
    }
}

fn share(p: &Predicted, without: &Predicted) -> f64 {
    let mut s = 0.0;
    for i in 0..P {
        s += if without.sigma[i].is_finite() {
            (1.0 - (p.sigma[i] / without.sigma[i]).powi(2)).clamp(0.0, 1.0)
        } else {
            1.0
        };
    }
    s / P as f64
}

/// Whether a prediction meets the goal, and what misses it in words.
pub fn assess(
    pred: &Prediction,
    p: &Predicted,
    per_sphere: &[u32],
    ids: &[String],
    goal: &Goal,
) -> Vec<String> {
    let mut missing = Vec::new();
    for (j, &n) in per_sphere.iter().enumerate() {
        if n < goal.min_returns {
            missing.push(format!(
                "{}: {n} returns predicted, the solver needs {}",
                ids.get(j).map_or("?", |s| s.as_str()),
                goal.min_returns
            ));
        }
    }
    match pred.condition {
        Some(c) if c <= goal.max_condition => {}
        c => missing.push(format!(
            "condition number {} > {:.0e}: the solver would refuse (weakest: {})",
            c.map_or("infinite".into(), |c| format!("{c:.3e}")),
            goal.max_condition,
            weakest_words(&p.weakest)
        )),
    }
    for (i, name) in NAMES.iter().enumerate() {
        let (t, unit) = if i < 3 {
            (goal.sigma_deg, "deg")
        } else {
            (goal.sigma_m, "m")
        };
        match pred.sigma_deg_m[i] {
            Some(s) if s <= t => {}
            Some(s) => missing.push(format!("{} sigma {s:.4} > {t} {unit}", name)),
            None => missing.push(format!("{} not determined", name)),
        }
    }
    missing
}

/// The parameters with a large share of the weakest direction.
pub fn weakest_words(w: &[f64; P + 1]) -> String {
    let names: Vec<&str> = (0..=P)
        .filter(|&i| w[i].abs() > 0.3)
        .map(|i| if i < P { NAMES[i] } else { "time offset" })
        .collect();
    names.join(", ")
}

/// Predict a scenario's accuracy (and, with `recommend`, the changes that meet the goal).
pub fn plan(s: &Scenario, goal: &Goal, recommend: bool) -> Result<PlanReport, crate::Error> {
    let t0 = std::time::Instant::now();
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let noise = PlanNoise::of(s);
    let g = geometry(s, &noise, threads)?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut rep = report_of(s, &noise, &g, goal);
    rep.ms = ms;
    if recommend && !rep.meets {
        rep.recommendations = recommend::recommend(s, &noise, &g, goal, threads)?;
    }
    Ok(rep)
}

/// The report of a traced plan (no recommendations).
pub fn report_of(s: &Scenario, noise: &PlanNoise, g: &Geometry, goal: &Goal) -> PlanReport {
    let total = g.total();
    let white = Predicted::of(&total);
    // Under a navigation model the sigmas are its solver's on the whole survey (information
    // no longer adds: each share is the survey solved again without it).
    let under = |sigma: Option<[f64; P + 1]>| {
        let mut p = white;
        p.sigma = sigma.unwrap_or([f64::INFINITY; P + 1]);
        p
    };
    let without = |k: Option<usize>, j: Option<usize>| match &g.nav {
        Some(nav) => under(nav.sigma_without(&g.segments, k, j)),
        None => Predicted::of(&g.sum(|kk, jj| Some(kk) != k && Some(jj) != j)),
    };
    let p = g.predict(|_| true);
    let pred = Prediction::of(&p);
    let ids: Vec<String> = s.sphere.iter().map(|x| x.id.clone()).collect();
    let per_sphere: Vec<u32> = (0..ids.len()).map(|j| g.returns_of(j)).collect();
    let mut missing = assess(&pred, &p, &per_sphere, &ids, goal);
    // Why a sphere gets too few returns, where the survey's geometry says it.
    for (j, &n) in per_sphere.iter().enumerate() {
        if n < goal.min_returns {
            if let (Some(why), Some(m)) = (
                crate::synth::why_unseen(s, j),
                missing
                    .iter_mut()
                    .find(|m| m.starts_with(&format!("{}: ", ids[j]))),
            ) {
                m.push_str(&format!(
                    " ({})",
                    why.trim_start_matches(&format!("{}: ", ids[j]))
                ));
            }
        }
    }
    let range_of = |cells: &mut dyn Iterator<Item = &Cell>| {
        let r = cells.fold([f64::INFINITY, 0.0f64], |r, c| {
            [r[0].min(c.range_m[0]), r[1].max(c.range_m[1])]
        });
        r[0].is_finite().then_some(r)
    };
    let mut passes = Vec::new();
    for (k, (seg, _, _)) in g.segments.iter().enumerate() {
        let n: u32 = g.cells[k].iter().map(|c| c.info.n).sum();
        if n == 0 && !matches!(seg, Segment::Pass(_)) {
            continue;
        }
        let without = without(Some(k), None);
        passes.push(Share {
            what: segment_name(s, *seg),
            returns: n,
            range_m: range_of(&mut g.cells[k].iter()),
            sigma_without: Prediction::of(&without).sigma_deg_m,
            share: share(&p, &without),
        });
    }
    let spheres = ids
        .iter()
        .enumerate()
        .map(|(j, id)| {
            let without = without(None, Some(j));
            Share {
                what: id.clone(),
                returns: per_sphere[j],
                range_m: range_of(&mut g.cells.iter().map(|r| &r[j])),
                sigma_without: Prediction::of(&without).sigma_deg_m,
                share: share(&p, &without),
            }
        })
        .collect();
    PlanReport {
        scenario: s.name.clone(),
        noise: *noise,
        goal: *goal,
        navigation: g.nav.as_ref().map(|n| n.words()),
        correlation: (0..=P)
            .map(|i| (0..=P).map(|j| p.correlation[(i, j)]).collect())
            .collect(),
        weakest: p.weakest,
        meets: missing.is_empty(),
        missing,
        predicted: pred,
        passes,
        spheres,
        warnings: design::every_sphere_grounded(s)
            .then(|| GROUNDED.to_string())
            .into_iter()
            .collect(),
        recommendations: Vec::new(),
        ms: 0.0,
    }
}

/// [`PlanReport::warnings`]' words for an aerial survey whose spheres all rest on the ground.
const GROUNDED: &str = "every sphere rests on the ground: from the air the beam's footprint \
    straddles each sphere's edge with the grass right behind it, and those returns, mixed, lie \
    beyond the sphere: the prediction leaves out the bias they give the lever arm's height \
    (simulated on the built-in field, all four spheres on the grass: -5 cm, 0.85 sigma; 6 in \
    100 flights refused, none with two on tripods): put two or more on tripods (1.5 m)";

/// Parameter `i`'s sigma as the plan shows it: deg with 4 decimals for the angles, mm with 1
/// for the lever arm (`units`: followed by the unit); `None` when not determined.
pub fn sigma_text(v: Option<f64>, i: usize, units: bool) -> Option<String> {
    let (x, prec, unit) = if i < 3 {
        (v?, 4, " deg")
    } else {
        (v? * 1e3, 1, " mm")
    };
    Some(format!("{x:.prec$}{}", if units { unit } else { "" }))
}

/// The plan in words.
pub fn render(r: &PlanReport) -> String {
    use std::fmt::Write as _;
    let mut o = String::new();
    let n = &r.noise;
    let _ = writeln!(
        o,
        "plan {}: {} sphere returns predicted{}",
        r.scenario,
        r.predicted.returns,
        if r.ms > 0.0 {
            format!(" ({:.0} ms)", r.ms)
        } else {
            String::new()
        }
    );
    let _ =
        writeln!(
        o,
        "noise{}: range {:.3} m{}, INS attitude {:.3} deg, position {:.3} m per sample at {} Hz",
        if n.assumed {
            " (the scenario states none: the sensors' specified values)"
        } else {
            ""
        },
        n.range_m,
        if n.incidence_divergence_mrad > 0.0 {
            format!(" growing at grazing incidence ({} mrad beam)", n.incidence_divergence_mrad)
        } else {
            String::new()
        },
        n.attitude_deg,
        n.position_m,
        n.ins_rate_hz
    );
    if let Some(nav) = &r.navigation {
        let _ = writeln!(o, "navigation errors that wander: {nav}");
    }
    let fmt = |v: Option<f64>, i: usize| sigma_text(v, i, true).unwrap_or_else(|| "-".into());
    let _ = writeln!(
        o,
        "predicted 1 sigma (target {} deg, {} mm):",
        r.goal.sigma_deg,
        r.goal.sigma_m * 1e3
    );
    for (i, name) in NAMES.iter().enumerate() {
        let _ = writeln!(o, "  {:<8} {}", name, fmt(r.predicted.sigma_deg_m[i], i));
    }
    let _ = writeln!(
        o,
        "  time offset {}",
        r.predicted
            .sigma_time_offset_s
            .map_or("-".into(), |v| format!("{:.3} ms", v * 1e3))
    );
    let _ = writeln!(
        o,
        "condition number {} (the solver refuses above {:.0e}); weakest direction: {}",
        r.predicted
            .condition
            .map_or("infinite".into(), |c| format!("{c:.1}")),
        r.goal.max_condition,
        weakest_words(&r.weakest)
    );
    let mut worst = (0.0, 0, 0);
    for i in 0..P {
        for j in 0..i {
            let c = r.correlation[i][j].abs();
            if c > worst.0 {
                worst = (c, i, j);
            }
        }
    }
    let _ = writeln!(
        o,
        "strongest correlation: {} / {} {:+.3}",
        NAMES[worst.1], NAMES[worst.2], r.correlation[worst.1][worst.2]
    );
    let _ = writeln!(
        o,
        "what each pass brings (share of the information; sigmas without it):"
    );
    for s in r.passes.iter().chain(&r.spheres) {
        let _ = writeln!(
            o,
            "  {:<34} {:>6} returns at {:<9} share {:>3.0} %   without: {}",
            s.what,
            s.returns,
            s.range_m
                .map_or("-".into(), |r| format!("{:.0}-{:.0} m", r[0], r[1])),
            s.share * 100.0,
            (0..P)
                .map(|i| fmt(s.sigma_without[i], i))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if r.meets {
        let _ = writeln!(o, "verdict: the plan meets the targets");
    } else {
        let _ = writeln!(
            o,
            "verdict: the plan misses the targets: {}",
            r.missing.join("; ")
        );
    }
    for w in &r.warnings {
        let _ = writeln!(o, "warning: {w}");
    }
    for (k, rec) in r.recommendations.iter().enumerate() {
        let steps: Vec<&str> = rec.words.split("; then ").collect();
        let _ = writeln!(
            o,
            "recommendation {}: {}{}",
            k + 1,
            steps[0],
            if steps.len() > 1 { ";" } else { "" }
        );
        for st in &steps[1..] {
            let _ = writeln!(o, "  then {st}");
        }
        let _ = writeln!(
            o,
            "  ({:.0} s of survey; {})",
            rec.cost_s,
            if rec.meets {
                "the plan then meets the targets"
            } else {
                "the plan is then still short of the targets: no candidate change gains more"
            }
        );
    }
    o
}

/// A point of the site (north, east [m] from its origin) where a helmsman can find it: the
/// site offsets, WGS 84 latitude and longitude, and UTM easting and northing with the zone.
pub fn place(s: &Scenario, ne: [f64; 2]) -> String {
    let g = s
        .site()
        .to_geodetic(&nalgebra::Vector3::new(ne[0], ne[1], 0.0));
    let (lat, lon) = (g.lat.to_degrees(), g.lon.to_degrees());
    let hemi =
        |v: f64, p: char, n: char| format!("{:.6} {}", v.abs(), if v >= 0.0 { p } else { n });
    let zone = (((lon + 180.0) / 6.0).floor() as i32).clamp(0, 59) as u16 + 1;
    let code = if lat >= 0.0 { 32600 } else { 32700 } + zone;
    let utm = crate::config::crs::Crs::epsg(code)
        .and_then(|c| c.from_wgs84(lat, lon, 0.0))
        .map(|(e, n, _)| {
            format!(
                ", UTM {zone}{} E {e:.1} N {n:.1}",
                if lat >= 0.0 { 'N' } else { 'S' }
            )
        })
        .unwrap_or_default();
    format!(
        "N {:.1} E {:.1} m from the site origin = {} {}{utm}",
        ne[0],
        ne[1],
        hemi(lat, 'N', 'S'),
        hemi(lon, 'E', 'W')
    )
}

/// The compass point of a course [deg] ("northbound", "south-westbound" ...).
pub fn bound(h: f64) -> &'static str {
    const P: [&str; 8] = [
        "northbound",
        "north-eastbound",
        "eastbound",
        "south-eastbound",
        "southbound",
        "south-westbound",
        "westbound",
        "north-westbound",
    ];
    P[(((h.rem_euclid(360.0) + 22.5) / 45.0) as usize) % 8]
}

#[cfg(test)]
mod tests {
    /// Against pyproj: the NED offset through EPSG:4978 to latitude and longitude, then
    /// EPSG:32630 (48.380360 N 4.489671 W; E 389698.006 N 5359649.094).
    #[test]
    fn place_in_latitude_longitude_and_utm() {
        let s = crate::config::scenario::Scenario::load("table1").unwrap();
        let p = super::place(&s, [40.0, 24.4]);
        assert!(p.contains("N 40.0 E 24.4 m from the site origin"), "{p}");
        assert!(p.contains("48.380360 N 4.489671 W"), "{p}");
        assert!(p.contains("UTM 30N E 389698.0 N 5359649.1"), "{p}");
    }
}

//! `spherecal calibrate`: the pipeline, then the solver, then the report (JSON, a human
//! summary, optionally the calibrated cloud as LAS and the residual plots as SVG).

use crate::pipeline::{run, targets, BatchMsg, Inputs, RunStats};
use serde::{Deserialize, Serialize};
use spherecal::calib::solve::{Refusal, Settings, Solution, Workspace};
use spherecal::calib::{solve, NAMES, P};
use spherecal::window::{Observation, Target};
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// The report's three-angle / three-axis groups.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Angles {
    /// Roll.
    pub roll: f64,
    /// Pitch.
    pub pitch: f64,
    /// Heading.
    pub heading: f64,
}

/// x, y, z.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Xyz {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// 1-sigma of each parameter.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Sigma {
    /// [deg].
    pub boresight_deg: Angles,
    /// [m].
    pub lever_arm_m: Xyz,
    /// [s] (0 when the time offset is not estimated).
    #[serde(default)]
    pub time_offset_s: f64,
}

/// Windowed returns by the extraction's verdict.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Verdicts {
    /// On the sphere: used.
    pub kept: u32,
    /// In slices of time where the sphere was not detected.
    pub undetected: u32,
    /// Off the sphere's shell.
    pub outside_shell: u32,
    /// On the far side of the sphere as seen from the sensor.
    pub hidden_side: u32,
    /// On a plane that continues beyond the sphere.
    pub plane: u32,
    /// On a pole that continues beyond the sphere.
    pub pole: u32,
    /// The sphere was not found.
    pub sphere_not_found: u32,
}

impl Verdicts {
    fn from_tally(t: &spherecal::calib::solve::Tally) -> Self {
        use spherecal::calib::extract::Verdict as V;
        let g = |v: V| t[v as usize];
        Self {
            kept: g(V::Kept),
            undetected: g(V::Undetected),
            outside_shell: g(V::OutsideShell),
            hidden_side: g(V::Hidden),
            plane: g(V::Plane),
            pole: g(V::Pole),
            sphere_not_found: g(V::NotFound) + g(V::Unclassified),
        }
    }

    /// Returns rejected (everything but the kept ones).
    pub fn rejected(&self) -> u32 {
        self.undetected
            + self.outside_shell
            + self.hidden_side
            + self.plane
            + self.pole
            + self.sphere_not_found
    }
}

/// One pass over one sphere.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PerPass {
    /// Sphere id.
    pub sphere: String,
    /// GPS seconds of its first and last windowed return.
    pub start_gps_s: f64,
    /// ...
    pub end_gps_s: f64,
    /// Slices of time (0.4 s) with windowed returns.
    pub slices: u32,
    /// Slices where the sphere was detected.
    pub detected: u32,
    /// Mean inliers per detection (the detection score).
    pub mean_inliers: f32,
    /// Windowed returns.
    pub windowed: u32,
    /// By verdict.
    pub verdicts: Verdicts,
}

/// Per sphere.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PerSphere {
    /// Sphere id.
    pub id: String,
    /// Found among the clutter (else left out of the solution).
    pub found: bool,
    /// Returns in the a-priori window.
    pub windowed: usize,
    /// Returns used.
    pub points: usize,
    /// Slices of time with windowed returns, and those where the sphere was detected.
    pub slices: u32,
    /// ...
    pub detected: u32,
    /// Windowed returns by verdict.
    pub verdicts: Verdicts,
    /// RMS with the starting values [m].
    pub rms_before_m: f64,
    /// RMS with the solution [m].
    pub rms_after_m: f64,
    /// Fitted minus surveyed centre, NED [m].
    pub centre_offset_m: Option<[f64; 3]>,
}

/// `report.json` (DESIGN.md contract plus the keys).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Report {
    /// [deg].
    pub boresight_deg: Angles,
    /// [m].
    pub lever_arm_m: Xyz,
    /// The time offset between the clocks: INS time = LiDAR time + this [s] (DESIGN.md).
    #[serde(default)]
    pub time_offset_s: f64,
    /// The time offset was estimated (else held at the value the pipeline applied).
    #[serde(default)]
    pub time_offset_estimated: bool,
    /// 1-sigma.
    pub sigma: Sigma,
    /// RMS of the residuals [m].
    pub rms_m: f64,
    /// Eq. 6 over the used returns [m].
    pub objective_l1_m: f64,
    /// Returns used per sphere.
    pub points_per_sphere: Vec<usize>,
    /// Objective evaluations by Nelder-Mead.
    pub evaluations: usize,
    /// Nelder-Mead iterations.
    pub nm_iterations: usize,
    /// LM iterations (last round).
    pub lm_iterations: usize,
    /// Re-windowing rounds.
    pub rounds: usize,
    /// A solution is claimed.
    pub converged: bool,
    /// Why not, if not.
    pub reason: Option<String>,
    /// Correlation matrix, order roll, pitch, heading, x, y, z, time_offset (the last row and
    /// column 0 when the time offset is not estimated).
    pub correlation: Vec<Vec<f64>>,
    /// Condition number of the unit-diagonal normal matrix.
    pub condition_number: f64,
    /// Parameters the data determine poorly.
    pub weak_parameters: Vec<String>,
    /// RMS of fitted minus surveyed centres [m].
    pub sphere_centre_rms_m: Option<f64>,
    /// Per sphere.
    pub per_sphere: Vec<PerSphere>,
    /// Per pass over each sphere.
    pub per_pass: Vec<PerPass>,
    /// The final shell: kept returns are within this of their sphere's surface [m].
    pub shell_m: f64,
    /// Windowed returns rejected as clutter, all spheres.
    pub clutter_rejected: u64,
    /// Windowed returns lost because a fixed-capacity batch was full (never expected; counted
    /// so that a truncated window cannot pass unnoticed).
    #[serde(default)]
    pub batch_overflow: u64,
    /// Time of the solve [ms].
    pub solve_ms: f64,
    /// Starting values.
    pub start: BTreeMap<String, f64>,
}

/// Run the pipeline and collect the windowed observations per sphere.
pub fn collect(inp: &Inputs) -> Result<(RunStats, Vec<Vec<Observation>>), String> {
    let n = inp.site.sphere.len();
    run(
        inp,
        None,
        move |rx: crossbeam_channel::Receiver<BatchMsg>| {
            let mut out = vec![Vec::new(); n];
            for m in rx {
                out[m.sphere].extend(m.obs);
            }
            out
        },
    )
}

/// A refusal in words.
pub fn refusal_text(r: &Refusal, ids: &[String], weak: &[String]) -> String {
    match r {
        Refusal::TooFewSpheres { have } => format!("{have} sphere(s) found: at least two are needed (one sphere cannot fix the rotation about the line to it)"),
        Refusal::TooFewPoints { sphere, have, need } => format!("sphere {}: {have} returns, at least {need} are needed", ids.get(*sphere).map_or("?", |s| s.as_str())),
        Refusal::IllConditioned { condition, limit } => format!(
            "ill-conditioned: condition number {condition:.3e} > {limit:.0e}; the geometry cannot separate {}",
            if weak.is_empty() { "the parameters".to_string() } else { weak.join(", ") }
        ),
        Refusal::NotConverged { iterations } => format!("the least squares did not converge (stalled after {iterations} iterations)"),
        Refusal::RmsTooHigh { rms, limit } => format!("residual RMS {:.1} mm above the {:.1} mm limit", rms * 1e3, limit * 1e3),
    }
}

/// Cells of the detection's vote grid (64^3: 512 KB).
pub const GRID_CELLS: usize = 64 * 64 * 64;
/// Kept returns a detect-and-solve round solves on at most (8.6 MB).
pub const KEPT_CAPACITY: usize = 50_000;
/// Returns in one slice of time at most (longer ones are split).
pub const SLICE_CAPACITY: usize = 32_768;

/// The solver's scratch, owned.
#[derive(Debug, Clone)]
pub struct Scratch {
    grid: Vec<u16>,
    kept: Vec<Observation>,
    keys: Vec<(f32, u32)>,
}

impl Default for Scratch {
    fn default() -> Self {
        Self {
            grid: vec![0; GRID_CELLS],
            kept: vec![Observation::default(); KEPT_CAPACITY],
            keys: vec![(0.0, 0); SLICE_CAPACITY],
        }
    }
}

impl Scratch {
    /// The workspace [`solve`] borrows.
    pub fn workspace(&mut self) -> Workspace<'_> {
        Workspace {
            grid: &mut self.grid,
            kept: &mut self.kept,
            keys: &mut self.keys,
        }
    }
}

/// Solve and build the report from collected observations.
pub fn solve_report(
    targets: &[Target],
    ids: &[String],
    obs: &mut [Vec<Observation>],
    b0: &[f64; P],
    s: &Settings,
) -> (Solution, Report) {
    let mut slices: Vec<&mut [Observation]> = obs.iter_mut().map(|v| v.as_mut_slice()).collect();
    let mut scratch = Scratch::default();
    let t0 = std::time::Instant::now();
    let sol = solve(targets, &mut slices, b0, s, &mut scratch.workspace());
    let solve_ms = t0.elapsed().as_secs_f64() * 1e3;
    let b = sol.b;
    let lm = sol.lm;
    let sigma = lm.map_or([f64::NAN; P], |l| l.sigma);
    let weak: Vec<String> = NAMES
        .iter()
        .chain(&["time_offset"])
        .zip(sol.weak)
        .filter(|(_, w)| *w)
        .map(|(n, _)| n.to_string())
        .collect();
    let report = Report {
        boresight_deg: Angles {
            roll: b[0].to_degrees(),
            pitch: b[1].to_degrees(),
            heading: b[2].to_degrees(),
        },
        lever_arm_m: Xyz {
            x: b[3],
            y: b[4],
            z: b[5],
        },
        sigma: Sigma {
            boresight_deg: Angles {
                roll: sigma[0].to_degrees(),
                pitch: sigma[1].to_degrees(),
                heading: sigma[2].to_degrees(),
            },
            lever_arm_m: Xyz {
                x: sigma[3],
                y: sigma[4],
                z: sigma[5],
            },
            time_offset_s: lm.map_or(f64::NAN, |l| l.sigma_dt),
        },
        time_offset_s: sol.dt,
        time_offset_estimated: s.estimate_dt,
        rms_m: lm.map_or(f64::NAN, |l| l.rms),
        objective_l1_m: sol.l1,
        points_per_sphere: sol.spheres.iter().map(|s| s.used).collect(),
        evaluations: sol.nm.evaluations,
        nm_iterations: sol.nm.iterations,
        lm_iterations: lm.map_or(0, |l| l.iterations),
        rounds: sol.rounds,
        converged: sol.refusal.is_none(),
        reason: sol.refusal.as_ref().map(|r| refusal_text(r, ids, &weak)),
        correlation: (0..=P)
            .map(|i| {
                (0..=P)
                    .map(|j| {
                        lm.map_or(f64::NAN, |l| match (i, j) {
                            (P, P) => f64::from(u8::from(l.estimated_dt)),
                            (P, k) | (k, P) => l.dt_correlation[k],
                            _ => l.correlation[(i, j)],
                        })
                    })
                    .collect()
            })
            .collect(),
        condition_number: lm.map_or(f64::INFINITY, |l| l.condition),
        weak_parameters: weak,
        sphere_centre_rms_m: sol.center_rms,
        per_pass: sol
            .passes
            .iter()
            .map(|p| PerPass {
                sphere: ids.get(usize::from(p.sphere)).cloned().unwrap_or_default(),
                start_gps_s: p.start.as_secs_f64(),
                end_gps_s: p.end.as_secs_f64(),
                slices: p.slices,
                detected: p.detected,
                mean_inliers: p.mean_inliers,
                windowed: p.verdicts.iter().sum(),
                verdicts: Verdicts::from_tally(&p.verdicts),
            })
            .collect(),
        shell_m: sol.shell,
        batch_overflow: 0,
        clutter_rejected: sol
            .spheres
            .iter()
            .map(|s| u64::from(Verdicts::from_tally(&s.verdicts).rejected()))
            .sum(),
        per_sphere: sol
            .spheres
            .iter()
            .zip(ids)
            .map(|(s, id)| PerSphere {
                id: id.clone(),
                found: s.found,
                windowed: s.windowed,
                points: s.used,
                slices: s.slices,
                detected: s.detected,
                verdicts: Verdicts::from_tally(&s.verdicts),
                rms_before_m: s.rms_before,
                rms_after_m: s.rms_after,
                centre_offset_m: s.center_offset.map(|c| [c.x, c.y, c.z]),
            })
            .collect(),
        solve_ms,
        start: NAMES
            .iter()
            .zip(b0)
            .enumerate()
            .map(|(i, (n, v))| (n.to_string(), if i < 3 { v.to_degrees() } else { *v }))
            .collect(),
    };
    (sol, report)
}

/// The human summary.
/// `truth`: roll, pitch, heading [deg], x, y, z [m], time offset [s].
pub fn render(r: &Report, truth: Option<&[f64; P + 1]>) -> String {
    let mut o = String::new();
    let b = [
        r.boresight_deg.roll,
        r.boresight_deg.pitch,
        r.boresight_deg.heading,
        r.lever_arm_m.x,
        r.lever_arm_m.y,
        r.lever_arm_m.z,
    ];
    let s = [
        r.sigma.boresight_deg.roll,
        r.sigma.boresight_deg.pitch,
        r.sigma.boresight_deg.heading,
        r.sigma.lever_arm_m.x,
        r.sigma.lever_arm_m.y,
        r.sigma.lever_arm_m.z,
    ];
    let _ = writeln!(
        o,
        "{:<10}{:>14}{:>12}{:>14}{}",
        "parameter",
        "start",
        "solution",
        "1-sigma",
        if truth.is_some() {
            "         truth      error"
        } else {
            ""
        }
    );
    for i in 0..P {
        let unit = if i < 3 { "deg" } else { "m" };
        let _ = write!(
            o,
            "{:<10}{:>14.4}{:>12.5}{:>10.5} {unit:<3}",
            NAMES[i], r.start[NAMES[i]], b[i], s[i]
        );
        if let Some(t) = truth {
            let _ = write!(o, "{:>14.4}{:>11.2e}", t[i], b[i] - t[i]);
        }
        let _ = writeln!(o);
    }
    // The time offset: INS time = LiDAR time + dt.
    let start = r.start.get("time_offset").copied().unwrap_or(0.0);
    if r.time_offset_estimated {
        let _ = write!(
            o,
            "{:<10}{:>14.4}{:>12.6}{:>10.6} {:<3}",
            "dt", start, r.time_offset_s, r.sigma.time_offset_s, "s"
        );
    } else {
        let _ = write!(
            o,
            "{:<10}{:>14.4}{:>12.6}{:>10} {:<3}",
            "dt", start, r.time_offset_s, "held", "s"
        );
    }
    if let Some(t) = truth {
        let _ = write!(o, "{:>14.4}{:>11.2e}", t[P], r.time_offset_s - t[P]);
    }
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "residual RMS {:.2} mm, L1 {:.4} m, condition number {:.3e}, centre RMS {}",
        r.rms_m * 1e3,
        r.objective_l1_m,
        r.condition_number,
        r.sphere_centre_rms_m
            .map_or("-".into(), |c| format!("{:.2} mm", c * 1e3))
    );
    for p in &r.per_sphere {
        let v = &p.verdicts;
        if !p.found {
            let _ = writeln!(
                o,
                "  {}: NOT FOUND among {} windowed returns (detected in {} of {} slices): left out",
                p.id, p.windowed, p.detected, p.slices
            );
            continue;
        }
        let mut why = format!(
            "{} off the sphere, {} in slices without it",
            v.outside_shell, v.undetected
        );
        for (n, what) in [
            (v.plane, "on a plane"),
            (v.pole, "on a pole or stand"),
            (v.hidden_side, "behind it"),
        ] {
            if n > 0 {
                let _ = write!(why, ", {n} {what}");
            }
        }
        let _ = writeln!(
            o,
            "  {}: kept {} of {} windowed returns, seen in {} of {} slices; rejected {} ({why}); RMS {:.2} mm",
            p.id,
            p.points,
            p.windowed,
            p.detected,
            p.slices,
            v.rejected(),
            p.rms_after_m * 1e3
        );
    }
    let _ = writeln!(
        o,
        "clutter rejected: {} of {} windowed returns; kept: within {:.1} mm of a sphere",
        r.clutter_rejected,
        r.per_sphere.iter().map(|p| p.windowed).sum::<usize>(),
        r.shell_m * 1e3
    );
    if r.batch_overflow > 0 {
        let _ = writeln!(
            o,
            "WARNING: {} windowed returns lost to full batches",
            r.batch_overflow
        );
    }
    let _ = writeln!(o, "Nelder-Mead {} evaluations ({} iterations), {} detect-and-solve rounds, LM {} iterations, {:.1} ms", r.evaluations, r.nm_iterations, r.rounds, r.lm_iterations, r.solve_ms);
    match &r.reason {
        None => {
            let _ = writeln!(o, "converged");
        }
        Some(why) => {
            let _ = writeln!(o, "NOT CONVERGED: {why}");
        }
    }
    o
}

/// Write every windowed return with its verdict (`--returns`): sphere id, where it is in the
/// capture, its time, laser and range, its place with the solution `b` (site NED), its signed
/// distance from the sphere's surface, and the extraction's verdict.
pub fn write_returns(
    path: &std::path::Path,
    targets: &[Target],
    ids: &[String],
    obs: &[Vec<Observation>],
    b: &[f64; P],
) -> Result<(), String> {
    use std::io::Write as _;
    let err = |e: std::io::Error| format!("{}: {e}", path.display());
    let f = std::fs::File::create(path).map_err(err)?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
    writeln!(w, "{}", crate::RETURNS_HEADER).map_err(err)?;
    let mount = spherecal::georef::Mount::from_params(b);
    let mut line = String::new();
    for ((t, id), v) in targets.iter().zip(ids).zip(obs) {
        for o in v {
            let x = o.georef(&mount);
            let e = (x - t.center).norm() - t.radius;
            line.clear();
            let _ = writeln!(
                line,
                "{id},{},{},{},{:.9},{},{:.3},{:.5},{:.5},{:.5},{:.5},{}",
                o.packet,
                o.block,
                o.channel,
                o.time.as_secs_f64(),
                o.laser,
                o.range,
                x.x,
                x.y,
                x.z,
                e,
                spherecal::calib::extract::Verdict::from_u8(o.work.verdict).name()
            );
            w.write_all(line.as_bytes()).map_err(err)?;
        }
    }
    w.flush().map_err(err)
}

/// Site targets and ids.
pub fn site_targets(inp: &Inputs) -> (Vec<Target>, Vec<String>) {
    let (_, t) = targets(&inp.site);
    (t, inp.site.sphere.iter().map(|s| s.id.clone()).collect())
}

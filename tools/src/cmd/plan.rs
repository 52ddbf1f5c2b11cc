//! `spherecal plan --scenario NAME|FILE | --site SITE.toml [--platform vessel|drone]
//! [--target-sigma-deg A --target-sigma-m L] [--report OUT.json|.html] [--geojson OUT.geojson]
//! [--write-plan OUT.toml] [--no-recommend] [--design]`.

use super::{claimed, fail};
use crate::config::goal::Goal;
use crate::plan::{html, plan, recommend, render};
use std::path::PathBuf;
use std::process::ExitCode;

/// Predict the accuracy of a planned calibration survey; propose changes if it misses.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A built-in scenario or a scenario file (the planned spheres, scene, passes, sensors).
    #[arg(long, required_unless_present = "site", conflicts_with = "site")]
    pub scenario: Option<String>,
    /// Plan for your own site file (`site import`'s): its surveyed spheres, a-priori mounting,
    /// noise, navigation model and targets, with the passes of a first survey by `--platform`;
    /// the lines are printed in the site's grid.
    #[arg(long)]
    pub site: Option<PathBuf>,
    /// With --site: a vessel (lines along the spheres at 8, 12, 20, 30 m, both ways) or a drone
    /// (two opposing lines over them, one lower, one crossing).
    #[arg(long, value_enum, default_value = "vessel")]
    pub platform: crate::plan::site::Platform,
    /// With --site: the LiDAR (vlp16, hdl32e, vlp32c, puck-hires, xt16, xt32, os0-128,
    /// os1-64, os1-128, os2-128; default vlp16): its beams, firing times and range unit.
    #[arg(long, value_parser = super::parse_scanner)]
    pub model: Option<spherecal::sim::Scanner>,
    /// With --site: a vessel's INS height above the spheres' mean centre (default -1.5: below
    /// them), or a drone's working height above the ground (default 40) [m].
    #[arg(long, allow_hyphen_values = true, value_parser = super::finite)]
    pub height: Option<f64>,
    /// With --site: speed along the lines [m/s] (vessel 2, drone 5).
    #[arg(long, value_parser = super::positive)]
    pub speed: Option<f64>,
    /// With --site and a vessel: the side of the spheres' line to run on, a compass direction
    /// from the spheres (n, ne, e, ... or degrees; default: the side the prediction favours).
    #[arg(long, value_parser = compass)]
    pub side: Option<f64>,
    /// With --site: write the lines (and the spheres) as GeoJSON (WGS 84).
    #[arg(long)]
    pub geojson: Option<PathBuf>,
    /// Each boresight angle's 1-sigma wanted [deg] (default: the site's [calibration], else
    /// 0.01).
    #[arg(long, allow_hyphen_values = true, value_parser = super::positive)]
    pub target_sigma_deg: Option<f64>,
    /// Each lever-arm component's 1-sigma wanted [m] (default: the site's [calibration], else
    /// 0.005).
    #[arg(long, allow_hyphen_values = true, value_parser = super::positive)]
    pub target_sigma_m: Option<f64>,
    /// Write the report: JSON, or a self-contained HTML page if the name ends in .html.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write the plan with the first recommendation applied, as a scenario file to edit.
    #[arg(long)]
    pub write_plan: Option<PathBuf>,
    /// Predict only: no recommendations.
    #[arg(long)]
    pub no_recommend: bool,
    /// Design the survey for the scenario's site: flight heights, line pattern and speed (aerial)
    /// and the number, size and placement of spheres; the report and --write-plan are then the
    /// proposed survey's.
    #[arg(long)]
    pub design: bool,
}

/// Run it: exit 0 when the plan meets the targets, 1 when it misses them, 2 on bad input.
pub fn run(a: Args) -> ExitCode {
    let (s, site, side) = match planned(&a) {
        Ok(x) => x,
        Err(e) => return fail("plan", e),
    };
    let targets = crate::config::goal::TargetChoice::of(
        site.as_ref().and_then(|x| x.calibration.as_ref()),
        None,
    );
    for (flag, p) in [
        ("--report", &a.report),
        ("--write-plan", &a.write_plan),
        ("--geojson", &a.geojson),
    ] {
        if let Some(p) = p {
            if let Err(e) = crate::survey::check_output(flag, p) {
                return fail("plan", e);
            }
        }
    }
    if let Some(p) = &a.report {
        let ext = p
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        if !matches!(ext.as_deref(), Some("json" | "html" | "htm")) {
            return fail(
                "plan",
                format!(
                    "--report {}: expected a .json or .html file (the report is JSON or one HTML page)",
                    p.display()
                ),
            );
        }
    }
    crate::output::remove_partial_on_interrupt();
    let goal = Goal {
        sigma_deg: a.target_sigma_deg.unwrap_or(targets.sigma_deg),
        sigma_m: a.target_sigma_m.unwrap_or(targets.sigma_m),
        ..Goal::default()
    };
    let design = if a.design {
        let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
        match crate::plan::design::design(&s, &goal, threads) {
            Ok(d) => Some(d),
            Err(e) => return fail("plan", e),
        }
    } else {
        None
    };
    if let Some(d) = &design {
        say!("{}", crate::plan::design::render(d, &goal));
    }
    let s = design.as_ref().map_or(s, |d| d.scenario.clone());
    // The recommendations' candidate passes are a vessel's: not for a designed flight.
    let recommend = !a.no_recommend && design.as_ref().is_none_or(|d| d.kind == "vessel");
    let r = match plan(&s, &goal, recommend) {
        Ok(r) => r,
        Err(e) => return fail("plan", e),
    };
    say!("{}", render(&r));
    let lines = match &site {
        Some(site) => {
            let first = r
                .recommendations
                .first()
                .map_or(&[][..], |x| &x.changes[..]);
            let drone = a.platform == crate::plan::site::Platform::Drone;
            match crate::plan::site::lines(site, &s, side, first, drone) {
                Ok(l) => {
                    say!("{}", crate::plan::site::render(&l, drone));
                    Some(l)
                }
                Err(e) => return fail("plan", e),
            }
        }
        None => None,
    };
    if !r.meets && design.is_none() && crate::plan::design::is_aerial(&s) {
        sayln!(
            "an aerial survey: `plan --design` weighs flight heights, the line pattern, speed and \
             the spheres' number, size and placement (the recommendations above are a vessel's: \
             lines along the spheres at the plan's height, slower lines, one more sphere)"
        );
    }
    if let Some(p) = &a.report {
        if let Err(e) = write_report(p, &s, &r, design.as_ref(), lines.as_ref()) {
            return fail("plan", e);
        }
        sayln!("wrote {}", p.display());
    }
    if let (Some(p), Some(l), Some(site)) = (&a.geojson, &lines, &site) {
        let out = crate::plan::site::geojson(site, l)
            .and_then(|g| crate::report::write_json_atomically(p, &g));
        if let Err(e) = out {
            return fail("plan", e);
        }
        sayln!("wrote {}", p.display());
    }
    if let Some(p) = &a.write_plan {
        let written = if design.is_some() {
            write_scenario(p, &s, "the survey `plan --design` proposes")
        } else {
            let Some(rec) = r.recommendations.first() else {
                return fail(
                    "plan",
                    format!(
                        "--write-plan {}: no change to write (the plan {})",
                        p.display(),
                        if r.meets {
                            "meets the targets"
                        } else {
                            "has no candidate change: it uses a recorded trajectory"
                        }
                    ),
                );
            };
            let mut improved = recommend::apply(&s, &rec.changes);
            improved.name = format!("{}-planned", s.name);
            write_scenario(
                p,
                &improved,
                &format!("{} with the plan's recommendation: {}", s.name, rec.words),
            )
        };
        if let Err(e) = written {
            return fail("plan", e);
        }
        sayln!("wrote {}", p.display());
    }
    claimed(r.meets, true)
}

/// A scenario as a TOML file to edit, under a comment line.
fn write_scenario(
    p: &std::path::Path,
    s: &crate::config::scenario::Scenario,
    what: &str,
) -> Result<(), crate::Error> {
    let t = toml::to_string(s)
        .map_err(|e| crate::Error::internal(format!("the scenario as TOML: {e}")))?;
    crate::report::write_atomically(p, format!("# {what}\n{t}").as_bytes())
}

/// A compass direction: n, ne, e, se, s, sw, w, nw (or the words), or degrees.
fn compass(s: &str) -> Result<f64, String> {
    const P: [&str; 8] = [
        "north",
        "northeast",
        "east",
        "southeast",
        "south",
        "southwest",
        "west",
        "northwest",
    ];
    const A: [&str; 8] = ["n", "ne", "e", "se", "s", "sw", "w", "nw"];
    let t: String = s
        .trim()
        .to_ascii_lowercase()
        .chars()
        .filter(|c| !matches!(c, '-' | ' ' | '_'))
        .collect();
    if let Some(k) = P.iter().zip(A).position(|(p, a)| t == *p || t == a) {
        return Ok(45.0 * k as f64);
    }
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v.rem_euclid(360.0)),
        _ => Err(format!(
            "{s:?}: expected a compass direction (n, ne, e, se, s, sw, w, nw) or degrees"
        )),
    }
}

/// The scenario planned (a scenario file's, or the first survey of `--site`'s), the site, and
/// the side of its spheres' line a vessel runs on.
fn planned(
    a: &Args,
) -> Result<
    (
        crate::config::scenario::Scenario,
        Option<crate::config::site::Site>,
        Option<f64>,
    ),
    crate::Error,
> {
    let Some(path) = &a.site else {
        let given = [
            ("--height", a.height.is_some()),
            ("--speed", a.speed.is_some()),
            ("--side", a.side.is_some()),
            ("--geojson", a.geojson.is_some()),
            (
                "--platform drone",
                a.platform != crate::plan::site::Platform::Vessel,
            ),
            ("--model", a.model.is_some()),
        ];
        if let Some((flag, _)) = given.iter().find(|g| g.1) {
            return Err(format!(
                "{flag} plans for a site file: give --site SITE.toml (a scenario states its own passes and sensors)"
            )
            .into());
        }
        let name = a.scenario.as_deref().ok_or("give --scenario or --site")?;
        return Ok((crate::config::scenario::Scenario::load(name)?, None, None));
    };
    let site = crate::config::site::Site::load(path)?;
    let o = crate::plan::site::Options {
        platform: a.platform,
        model: a.model.unwrap_or_default(),
        height_m: a.height,
        speed_mps: a.speed,
        side_deg: a.side,
    };
    let (s, side) = crate::plan::site::scenario(&site, &o)?;
    Ok((s, Some(site), side))
}

/// The report: one HTML page, or JSON (with the design's candidates, or the site's lines).
fn write_report(
    p: &std::path::Path,
    s: &crate::config::scenario::Scenario,
    r: &crate::plan::PlanReport,
    design: Option<&crate::plan::design::Design>,
    lines: Option<&crate::plan::site::Lines>,
) -> Result<(), crate::Error> {
    if p.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("html") || e.eq_ignore_ascii_case("htm"))
    {
        html::render(s, r, design, lines)
            .and_then(|page| crate::report::write_atomically(p, page.as_bytes()))
    } else if let Some(d) = design {
        crate::report::write_json_atomically(
            p,
            &serde_json::json!({ "design": { "kind": d.kind, "chosen": d.chosen,
                "candidates": d.candidates }, "plan": r }),
        )
    } else if let Some(l) = lines {
        crate::report::write_json_atomically(p, &serde_json::json!({ "lines": l, "plan": r }))
    } else {
        crate::report::write_json_atomically(p, r)
    }
}

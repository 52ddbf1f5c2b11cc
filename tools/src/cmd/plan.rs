//! `spherecal plan --scenario NAME|FILE [--target-sigma-deg A --target-sigma-m L] [--report
//! OUT.json|.html] [--write-plan OUT.toml] [--no-recommend] [--design]`.

use super::{claimed, fail};
use crate::plan::{html, plan, recommend, render, Goal};
use std::path::PathBuf;
use std::process::ExitCode;

/// Predict the accuracy of a planned calibration survey; propose changes if it misses.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A built-in scenario or a scenario file (the planned spheres, scene, passes, sensors).
    #[arg(long)]
    pub scenario: String,
    /// Each boresight angle's 1-sigma wanted [deg].
    #[arg(long, default_value_t = 0.01, allow_hyphen_values = true, value_parser = super::positive)]
    pub target_sigma_deg: f64,
    /// Each lever-arm component's 1-sigma wanted [m].
    #[arg(long, default_value_t = 0.005, allow_hyphen_values = true, value_parser = super::positive)]
    pub target_sigma_m: f64,
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
    let s = match crate::config::scenario::Scenario::load(&a.scenario) {
        Ok(s) => s,
        Err(e) => return fail("plan", e),
    };
    if !(a.target_sigma_deg > 0.0 && a.target_sigma_m > 0.0) {
        return fail(
            "plan",
            "--target-sigma-deg and --target-sigma-m: expected > 0",
        );
    }
    for (flag, p) in [("--report", &a.report), ("--write-plan", &a.write_plan)] {
        if let Some(p) = p {
            if let Err(e) = crate::check_output(flag, p) {
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
        sigma_deg: a.target_sigma_deg,
        sigma_m: a.target_sigma_m,
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
    if !r.meets && design.is_none() && crate::plan::design::is_aerial(&s) {
        sayln!(
            "an aerial survey: `plan --design` weighs flight heights, the line pattern, speed and \
             the spheres' number, size and placement (the recommendations above are a vessel's: \
             lines along the spheres at the plan's height, slower lines, one more sphere)"
        );
    }
    if let Some(p) = &a.report {
        let out = if p
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("html") || e.eq_ignore_ascii_case("htm"))
        {
            html::render(&s, &r, design.as_ref())
                .and_then(|page| crate::report::write_atomically(p, page.as_bytes()))
        } else if let Some(d) = &design {
            crate::report::write_json_atomically(
                p,
                &serde_json::json!({ "design": { "kind": d.kind, "chosen": d.chosen,
                    "candidates": d.candidates }, "plan": r }),
            )
        } else {
            crate::report::write_json_atomically(p, &r)
        };
        if let Err(e) = out {
            return fail("plan", e);
        }
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

//! spherecal-tools: the `spherecal` command's subcommands as library functions, so that tests
//! and benchmarks call exactly what the command runs.
#![forbid(unsafe_code)]

pub mod board;
pub mod calibrate;
pub mod decode;
pub mod fixtures;
pub mod georef;
pub mod ins;
pub mod montecarlo;
pub mod pipeline;
pub mod plot;
pub mod replay;
pub mod rig;
pub mod scenario;
pub mod scene;
pub mod site;
pub mod status;
pub mod synth;

use std::path::PathBuf;

/// `spherecal calibrate` as a function: returns the summary and whether a solution is claimed.
/// `truth` (for the demo) is printed beside the result.
#[allow(clippy::too_many_arguments)]
pub fn run_calibrate(
    pcap: PathBuf,
    ins: Option<PathBuf>,
    sbet: Option<PathBuf>,
    gps_week: Option<u16>,
    site: PathBuf,
    init: Option<[f64; 6]>,
    report: Option<PathBuf>,
    las: Option<PathBuf>,
    plot: Option<PathBuf>,
    truth: Option<[f64; 6]>,
) -> Result<(String, bool), String> {
    use pipeline::{Inputs, InsInput};
    let site = site::Site::load(&site)?;
    let start = init.unwrap_or(site.apriori_deg_m());
    let b0 = spherecal::calib::from_deg_m(&start);
    let ins = match (ins, sbet) {
        (Some(i), _) => InsInput::Vn200(i),
        (None, Some(s)) => InsInput::Sbet(s, gps_week),
        (None, None) => return Err("give --ins or --sbet".into()),
    };
    let mut inp = Inputs::apriori(pcap, ins, site);
    inp.mount = spherecal::georef::Mount::from_params(&b0);
    let (stats, mut obs) = calibrate::collect(&inp)?;
    let (targets, ids) = calibrate::site_targets(&inp);
    let (sol, rep) = calibrate::solve_report(
        &targets,
        &ids,
        &mut obs,
        &b0,
        &spherecal::calib::Settings::default(),
    );
    let mut text = format!(
        "{} data packets, {} poses, {} returns, windows {:?}\n",
        stats.data_packets,
        stats.poses,
        stats.window.points,
        obs.iter().map(Vec::len).collect::<Vec<_>>()
    );
    text.push_str(&calibrate::render(&rep, truth.as_ref()));
    if let Some(p) = &report {
        let json = serde_json::to_string_pretty(&rep).map_err(|e| e.to_string())?;
        std::fs::write(p, json + "\n").map_err(|e| format!("{}: {e}", p.display()))?;
    }
    if let Some(p) = &las {
        let inp2 = pipeline::Inputs {
            mount: spherecal::georef::Mount::from_params(&sol.b),
            ..inp.clone()
        };
        let (_, _, t) = georef::georef(&inp2, Some(p), None)?;
        text.push_str(&t);
    }
    if let Some(p) = &plot {
        plot::plot(p, &targets, &ids, &obs, &sol, &b0)?;
        text.push_str(&format!("plot: {}\n", p.display()));
    }
    Ok((text, rep.converged))
}

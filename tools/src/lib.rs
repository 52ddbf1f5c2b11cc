//! spherecal-tools: the `spherecal` command's subcommands as library functions, so that tests
//! and benchmarks call exactly what the command runs.
#![forbid(unsafe_code)]

pub mod calibrate;
pub mod decode;
pub mod georef;
pub mod ins;
pub mod montecarlo;
pub mod pipeline;
pub mod plot;
pub mod scenario;
pub mod site;
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
    let a = &site.apriori;
    let start = init.unwrap_or([
        a.boresight_deg[0],
        a.boresight_deg[1],
        a.boresight_deg[2],
        a.lever_arm_m[0],
        a.lever_arm_m[1],
        a.lever_arm_m[2],
    ]);
    let b0 = [
        start[0].to_radians(),
        start[1].to_radians(),
        start[2].to_radians(),
        start[3],
        start[4],
        start[5],
    ];
    let ins = match (ins, sbet) {
        (Some(i), _) => InsInput::Vn200(i),
        (None, Some(s)) => InsInput::Sbet(s, gps_week),
        (None, None) => return Err("give --ins or --sbet".into()),
    };
    let inp = Inputs {
        pcap,
        ins,
        mount: spherecal::georef::Mount::from_params(&b0),
        margin: site.apriori.window_margin_m,
        max_gap_ns: 50_000_000,
        site,
    };
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

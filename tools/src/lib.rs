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

/// What `spherecal calibrate` reads.
#[derive(Debug, Clone)]
pub struct Survey {
    /// The VLP-16 capture.
    pub pcap: PathBuf,
    /// VN-200 serial bytes (raw or a serial log) ...
    pub ins: Option<PathBuf>,
    /// ... or an Applanix SBET and its GPS week (None: from the capture's RMC date).
    pub sbet: Option<PathBuf>,
    /// The SBET's GPS week.
    pub gps_week: Option<u16>,
    /// site.toml.
    pub site: PathBuf,
}

impl Survey {
    /// A `synth` folder: `lidar.pcap`, `ins.bin`, `site.toml`.
    pub fn synth_dir(dir: &std::path::Path) -> Self {
        Self {
            pcap: dir.join("lidar.pcap"),
            ins: Some(dir.join("ins.bin")),
            sbet: None,
            gps_week: None,
            site: dir.join("site.toml"),
        }
    }
}

/// What `spherecal calibrate` writes besides its summary.
#[derive(Debug, Clone, Default)]
pub struct Outputs {
    /// The JSON report.
    pub report: Option<PathBuf>,
    /// The cloud georeferenced with the result, as LAS.
    pub las: Option<PathBuf>,
    /// Residual plots (SVG).
    pub plot: Option<PathBuf>,
    /// Every windowed return with its verdict (CSV).
    pub returns: Option<PathBuf>,
}

/// The `--returns` CSV header.
pub const RETURNS_HEADER: &str =
    "sphere,packet,block,channel,time_gps_s,laser,range_m,x_m,y_m,z_m,residual_m,verdict";

/// How `calibrate` treats the clocks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockOptions {
    /// Estimate the time offset between the clocks (else hold `start`).
    pub estimate: bool,
    /// The time offset to start from [s] (INS time = LiDAR time + this).
    pub start: f64,
}

impl Default for ClockOptions {
    fn default() -> Self {
        Self {
            estimate: true,
            start: 0.0,
        }
    }
}

/// `spherecal calibrate` as a function: returns the summary and whether a solution is claimed.
/// `init` overrides the site's a-priori start [deg, m]; `truth` (for the demo: the six and the
/// time offset) is printed beside the result.
///
/// With the time offset estimated, the windows are collected again with the offset found
/// (the solver's estimate is to first order in the offset the poses were taken at) until it
/// changes by less than 0.5 ms (four times at most).
pub fn run_calibrate(
    survey: Survey,
    init: Option<[f64; 6]>,
    clock: ClockOptions,
    out: &Outputs,
    truth: Option<[f64; 7]>,
) -> Result<(String, bool), String> {
    use pipeline::{Inputs, InsInput};
    let site = site::Site::load(&survey.site)?;
    let start = init.unwrap_or(site.apriori_deg_m());
    let b0 = spherecal::calib::from_deg_m(&start);
    let ins = match (survey.ins, survey.sbet) {
        (Some(i), _) => InsInput::Vn200(i),
        (None, Some(s)) => InsInput::Sbet(s, survey.gps_week),
        (None, None) => return Err("give --ins or --sbet".into()),
    };
    let mut inp = Inputs::apriori(survey.pcap, ins, site);
    inp.mount = spherecal::georef::Mount::from_params(&b0);
    let settings = spherecal::calib::Settings {
        estimate_dt: clock.estimate,
        ..Default::default()
    };
    let (targets, ids) = calibrate::site_targets(&inp);
    let mut applied = clock.start;
    let mut collections = 0;
    let (stats, obs, sol, mut rep) = loop {
        inp.time_offset_ns = (applied * 1e9).round() as i64;
        let (stats, mut obs) = calibrate::collect(&inp)?;
        let (sol, rep) = calibrate::solve_report(&targets, &ids, &mut obs, &b0, &settings);
        collections += 1;
        // Again with the offset found, while it moves by more than 0.5 ms (and stays within
        // 2 s of the start: beyond, the first-order estimate is no guide).
        let next = applied + sol.dt;
        let again = clock.estimate
            && collections < 4
            && sol.lm.is_some_and(|l| l.converged)
            && sol.dt.abs() > 5e-4
            && (next - clock.start).abs() <= 2.0;
        if !again {
            break (stats, obs, sol, rep);
        }
        applied = next;
    };
    rep.time_offset_s += applied;
    rep.start.insert("time_offset".to_string(), clock.start);
    rep.batch_overflow = stats.batch_overflow;
    let mut text = format!(
        "{} data packets, {} poses, {} returns, windows {:?}\n",
        stats.data_packets,
        stats.poses,
        stats.window.points,
        obs.iter().map(Vec::len).collect::<Vec<_>>()
    );
    text.push_str(&calibrate::render(&rep, truth.as_ref()));
    if let Some(p) = &out.report {
        let json = serde_json::to_string_pretty(&rep).map_err(|e| e.to_string())?;
        std::fs::write(p, json + "\n").map_err(|e| format!("{}: {e}", p.display()))?;
    }
    if let Some(p) = &out.returns {
        calibrate::write_returns(p, &targets, &ids, &obs, &sol.b)?;
        text.push_str(&format!("returns: {}\n", p.display()));
    }
    if let Some(p) = &out.las {
        let inp2 = pipeline::Inputs {
            mount: spherecal::georef::Mount::from_params(&sol.b),
            time_offset_ns: (rep.time_offset_s * 1e9).round() as i64,
            ..inp.clone()
        };
        let (_, _, t) = georef::georef(&inp2, Some(p), None)?;
        text.push_str(&t);
    }
    if let Some(p) = &out.plot {
        plot::plot(p, &targets, &ids, &obs, &sol, &b0)?;
        text.push_str(&format!("plot: {}\n", p.display()));
    }
    Ok((text, rep.converged))
}

//! `spherecal calibrate --pcap P (--ins I | --sbet S) --site SITE ...`.

use super::{claimed, fail, parse6, SurveyArgs};
use std::path::PathBuf;
use std::process::ExitCode;

/// Calibrate: georeference, window, solve for boresight and lever arm, report.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub survey: SurveyArgs,
    /// Start: roll,pitch,heading [deg],x,y,z [m] (default: the site's a-priori values).
    #[arg(long, value_parser = parse6, allow_hyphen_values = true, conflicts_with = "init_from")]
    pub init: Option<[f64; 6]>,
    /// Start from the boresight, lever arm and time offset of an earlier report.json.
    #[arg(long)]
    pub init_from: Option<PathBuf>,
    /// Write the JSON report here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write the calibrated cloud as LAS.
    #[arg(long)]
    pub las: Option<PathBuf>,
    /// LAS coordinates: `projected` (the site's CRS, or its UTM zone, with the WKT CRS
    /// record) or `local` (east-north-up metres from the site origin).
    #[arg(long, value_enum, default_value_t = crate::georef::LasFrame::Projected)]
    pub las_frame: crate::georef::LasFrame,
    /// Write the figures (residual histograms, residuals against time, 1:1 cross-sections per
    /// sphere) as one SVG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the report as one self-contained HTML page (inline figures, no network).
    #[arg(long)]
    pub html: Option<PathBuf>,
    /// Write every windowed return with its verdict (kept, or why not) as CSV.
    #[arg(long)]
    pub returns: Option<PathBuf>,
    /// Start from this time offset between the clocks [s] (INS time = LiDAR time + this;
    /// default 0, or what the LiDAR's RMC says when its clock is not PPS-locked).
    #[arg(long, allow_hyphen_values = true, value_parser = super::finite)]
    pub time_offset: Option<f64>,
    /// Hold the time offset (at `--time-offset`) instead of estimating it.
    #[arg(long)]
    pub hold_time_offset: bool,
    /// Claim a solution although the LiDAR clock is not PPS-locked with a valid RMC (when
    /// the time offset found explains the stamps' disagreement with the RMC).
    #[arg(long)]
    pub allow_unlocked_clock: bool,
    /// Use VN-200 poses whose InsStatus says not tracking, aligning, GNSS lost or no fix.
    #[arg(long)]
    pub keep_untracked_ins: bool,
    /// Search the time offset over +- this many seconds around the start, in 0.25 s steps
    /// (default: 2 s when the LiDAR clock is not PPS-locked with a valid RMC, else none; 0
    /// turns it off).
    #[arg(long, allow_hyphen_values = true, value_parser = super::non_negative)]
    pub search_time_offset: Option<f64>,
    /// Leave the returns between these GPS times out (`T0..T1`: GPS seconds as the reports
    /// print them, or seconds of the GPS week); repeatable. A stretch whose navigation is bad
    /// (a multipath jump, a GNSS outage the INS did not flag).
    #[arg(long, value_parser = crate::stretches::parse_span)]
    pub exclude: Vec<(f64, f64)>,
    /// The rig's board file: its name, `vessel` and `operator` go on the report's cover sheet,
    /// its `[calibration]` targets apply when the site gives none.
    #[arg(long)]
    pub board: Option<PathBuf>,
    /// Who ran the survey, for the report (else the board's `operator`).
    #[arg(long)]
    pub operator: Option<String>,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    let s = a.survey;
    let ports = s.ports();
    let (pcap, lidar_topic) = s.lidar();
    let bag = s.ins_bag();
    let survey = crate::survey::Survey {
        pcap,
        lidar_topic,
        bag,
        model: s.model,
        metadata: s.metadata,
        ins: (!s.ins.is_empty()).then(|| s.ins.into()),
        sbet: (!s.sbet.is_empty()).then(|| s.sbet.into()),
        posmv: (!s.posmv.is_empty()).then(|| (s.posmv.into(), s.posmv_group)),
        gps_week: s.gps_week,
        smrmsg: s.smrmsg,
        site: s.site,
        trajectory_datum: s.trajectory_datum,
        ports,
        exclude: a.exclude,
        board: a.board,
        operator: a.operator,
    };
    let out = crate::survey::Outputs {
        report: a.report,
        las: a.las,
        las_frame: a.las_frame,
        plot: a.plot,
        html: a.html,
        returns: a.returns,
    };
    let (init, start) = match &a.init_from {
        Some(p) => match crate::report::solved::Solved::load(p) {
            Ok(r) => (Some(r.deg_m), a.time_offset.or(Some(r.time_offset_s))),
            Err(e) => return fail("calibrate", e),
        },
        None => (a.init, a.time_offset),
    };
    let clock = crate::calibrate::ClockOptions {
        estimate: !a.hold_time_offset,
        start,
        allow_unlocked: a.allow_unlocked_clock,
        keep_untracked_ins: a.keep_untracked_ins,
        search: a.search_time_offset,
    };
    crate::output::remove_partial_on_interrupt();
    match crate::survey::run_calibrate(survey, init.map(spherecal::georef::DegM), clock, &out, None)
    {
        Ok(c) => {
            say!("{}", c.text);
            super::outputs_failed("calibrate", &c.output_errors)
                .unwrap_or(claimed(c.converged, c.met))
        }
        Err(e) => super::fail("calibrate", e),
    }
}

//! `spherecal georef --pcap P (--ins I | --sbet S) --site SITE ...`.

use super::{fail, parse3, SurveyArgs};
use crate::pipeline::{Inputs, InsInput};
use std::path::PathBuf;
use std::process::ExitCode;

/// Georeference a survey: align the LiDAR with the trajectory, keep the sphere windows.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub survey: SurveyArgs,
    /// Boresight roll,pitch,heading [deg] (default: the site's a-priori).
    #[arg(long, value_parser = parse3, allow_hyphen_values = true)]
    pub boresight: Option<[f64; 3]>,
    /// Lever arm x,y,z [m] (default: the site's a-priori).
    #[arg(long, value_parser = parse3, allow_hyphen_values = true)]
    pub lever: Option<[f64; 3]>,
    /// Largest INS sample spacing to interpolate over [ms].
    #[arg(long, default_value_t = 50.0, allow_hyphen_values = true, value_parser = super::positive)]
    pub max_gap_ms: f64,
    /// The time offset between the clocks [s]: INS time = LiDAR time + this (what
    /// `calibrate` reports as `time_offset_s`).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = super::finite)]
    pub time_offset: f64,
    /// Write the georeferenced cloud as LAS 1.4 (see --las-frame).
    #[arg(long)]
    pub las: Option<PathBuf>,
    /// LAS coordinates: `projected` (the site's CRS, or its UTM zone, with the WKT CRS
    /// record) or `local` (east-north-up metres from the site origin).
    #[arg(long, value_enum, default_value_t = crate::georef::LasFrame::Projected)]
    pub las_frame: crate::georef::LasFrame,
    /// Write the window points as CSV.
    #[arg(long)]
    pub windows: Option<PathBuf>,
    /// Use VN-200 poses whose InsStatus says not tracking, aligning, GNSS lost or no fix.
    #[arg(long)]
    pub keep_untracked_ins: bool,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    let ports = a.survey.ports();
    let (pcap, lidar_topic) = a.survey.lidar();
    let ins_bag = a.survey.ins_bag();
    let SurveyArgs {
        model,
        ins,
        sbet,
        posmv,
        posmv_group,
        gps_week,
        site,
        trajectory_datum,
        ..
    } = a.survey;
    for (flag, p) in [("--las", &a.las), ("--windows", &a.windows)] {
        if let Some(p) = p {
            if let Err(e) = crate::survey::check_output(flag, p) {
                return fail("georef", e);
            }
        }
    }
    let site = match crate::config::site::Site::load(&site) {
        Ok(s) => s,
        Err(e) => return fail("georef", e),
    };
    let b = a.boresight.unwrap_or(site.apriori.boresight_deg);
    let l = a.lever.unwrap_or(site.apriori.lever_arm_m);
    let ins = match (ins.is_empty(), sbet.is_empty(), posmv.is_empty()) {
        _ if ins_bag.is_some() => {
            let (b, t) = ins_bag.unwrap_or_default();
            InsInput::Bag(b, t)
        }
        (false, _, _) => InsInput::Vn200(ins.into()),
        (true, false, _) => InsInput::Sbet(sbet.into(), gps_week),
        (true, true, false) => InsInput::Posmv(posmv.into(), gps_week, posmv_group),
        (true, true, true) => return fail("georef", "give --ins, --sbet or --posmv"),
    };
    let (site, datums) =
        match crate::pipeline::site_in_trajectory_datum(&site, &ins, trajectory_datum.as_deref()) {
            Ok(s) => s,
            Err(e) => return fail("georef", e),
        };
    sayln!("{datums}");
    let mut inp = Inputs {
        pcap,
        lidar_topic,
        model,
        ins,
        mount: spherecal::georef::Mount::new(b.map(f64::to_radians), l),
        margin: site.apriori.window_margin_m,
        max_gap_ns: (a.max_gap_ms * 1e6) as i64,
        time_offset_ns: (a.time_offset * 1e9).round() as i64,
        keep_untracked_ins: a.keep_untracked_ins,
        accuracy: None,
        ports,
        exclude: Vec::new(),
        hesai: None,
        ouster: None,
        site,
    };
    if let Some(p) = &a.survey.metadata {
        if let Err(e) = inp.set_metadata(p) {
            return fail("georef", e);
        }
    }
    match crate::georef::georef(
        &inp,
        a.las.as_deref().map(|p| (p, a.las_frame)),
        a.windows.as_deref(),
    ) {
        Ok((_, _, text)) => {
            say!("{text}");
            ExitCode::SUCCESS
        }
        Err(e) => fail("georef", e),
    }
}

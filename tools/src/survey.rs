//! A survey as the file commands take it: its files ([`Survey`]), the outputs asked for
//! ([`Outputs`]), the clock options ([`ClockOptions`]) and the whole calibration of the files
//! ([`run_calibrate`]: the pipeline, the session, the outputs).

use crate::calibrate::ClockOptions;
use crate::{calibrate, config, georef, html, output, pipeline, plot, report};
use spherecal::georef::{DegM, NAMES};
use std::path::PathBuf;

/// What `spherecal calibrate` reads.
#[derive(Debug, Clone)]
pub struct Survey {
    /// The Velodyne capture(s), or a ROS 2 bag.
    pub pcap: pipeline::Files,
    /// When `pcap` is a bag: its topic of scans (None: the only one).
    pub lidar_topic: Option<String>,
    /// A ROS 2 bag as the INS and its topic of CommonGroups (None: the only one).
    pub bag: Option<(pipeline::Files, Option<String>)>,
    /// The LiDAR model (None: as the packets say, checked against their period).
    pub model: Option<spherecal::velodyne::Model>,
    /// A Hesai's angle correction file (`--metadata`): the capture is that Hesai's.
    pub metadata: Option<PathBuf>,
    /// VN-200 serial bytes (raw or serial logs) ...
    pub ins: Option<pipeline::Files>,
    /// ... or Applanix SBET files and their GPS week (None: from the capture's RMC date).
    pub sbet: Option<pipeline::Files>,
    /// ... or an Applanix POS MV stream and the group its poses come from.
    pub posmv: Option<(pipeline::Files, u16)>,
    /// The SBET's GPS week.
    pub gps_week: Option<u16>,
    /// The SBET's accuracy file (POSPac smrmsg; None: `smrmsg_NAME` beside `sbet_NAME` if
    /// there).
    pub smrmsg: Option<PathBuf>,
    /// site.toml.
    pub site: PathBuf,
    /// The trajectory's datum (`--trajectory-datum`; None: a VN-200's or POS MV's WGS 84; an
    /// SBET must say).
    pub trajectory_datum: Option<String>,
    /// The LiDAR's UDP ports in the capture (`--lidar-ports`; default 2368, 8308).
    pub ports: spherecal_hal::velodyne::Ports,
    /// Spans to leave out (`--exclude`) [GPS s, or seconds of the week].
    pub exclude: Vec<(f64, f64)>,
    /// The rig's board file (`calibrate --board`): its name, vessel and operator on the
    /// report, its `[calibration]` targets when the site gives none.
    pub board: Option<PathBuf>,
    /// Who ran the survey (`calibrate --operator`; else the board's).
    pub operator: Option<String>,
}

impl Survey {
    /// A `synth` folder: `lidar.pcap`, `ins.bin`, `site.toml`.
    pub fn synth_dir(dir: &std::path::Path) -> Self {
        Self {
            pcap: dir.join("lidar.pcap").into(),
            lidar_topic: None,
            bag: None,
            model: None,
            metadata: [crate::synth::CORRECTIONS, crate::synth::OUSTER_METADATA]
                .iter()
                .map(|f| dir.join(f))
                .find(|p| p.exists()),
            ins: Some(dir.join("ins.bin").into()),
            sbet: None,
            posmv: None,
            gps_week: None,
            smrmsg: None,
            site: dir.join("site.toml"),
            trajectory_datum: None,
            ports: Default::default(),
            exclude: Vec::new(),
            board: None,
            operator: None,
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
    /// The report as one self-contained HTML page.
    pub html: Option<PathBuf>,
    /// Every windowed return with its verdict (CSV).
    pub returns: Option<PathBuf>,
    /// Where the LAS coordinates are.
    pub las_frame: georef::LasFrame,
}

/// An output file can be created where it is asked for ([`output::check`]: its folder exists
/// and takes a new file, it is not a folder), checked before a long run so that it does not
/// fail at the end. `flag` names the option in the message.
pub fn check_output(flag: &str, p: &std::path::Path) -> Result<(), crate::Error> {
    output::check(flag, p)
}

impl Outputs {
    /// Every output can be written ([`check_output`]).
    pub fn check(&self) -> Result<(), crate::Error> {
        for (flag, p) in [
            ("--report", &self.report),
            ("--las", &self.las),
            ("--plot", &self.plot),
            ("--html", &self.html),
            ("--returns", &self.returns),
        ] {
            if let Some(p) = p {
                check_output(flag, p)?;
            }
        }
        Ok(())
    }
}

/// What a calibration's outputs are made from besides its report.
struct Written<'a> {
    targets: &'a [spherecal::align::window::Target],
    ids: &'a [String],
    obs: &'a [Vec<spherecal::align::window::Observation>],
    sol: &'a spherecal::calib::Solution,
    b0: &'a spherecal::georef::Params,
    inp: &'a pipeline::Inputs,
}

/// Every output asked for (report.json, the returns CSV, the LAS, the plots, the HTML page):
/// the lines naming those written, and the errors of those that failed.
fn write_outputs(out: &Outputs, rep: &report::Report, w: &Written<'_>) -> (String, Vec<String>) {
    let mut wrote = String::new();
    let mut output_errors = Vec::new();
    let mut put = |r: Result<Option<String>, crate::Error>| match r {
        Ok(Some(line)) => wrote.push_str(&line),
        Ok(None) => {}
        Err(e) => output_errors.push(e.to_string()),
    };
    if let Some(p) = &out.report {
        put(report::write_json_atomically(p, rep).map(|()| None));
    }
    if let Some(p) = &out.returns {
        put(
            calibrate::write_returns(p, w.targets, w.ids, w.obs, &w.sol.b)
                .map(|()| Some(format!("returns: {}\n", p.display()))),
        );
    }
    if let Some(p) = &out.las {
        let inp2 = pipeline::Inputs {
            mount: w.sol.b.mount(),
            time_offset_ns: (rep.time_offset_s * 1e9).round() as i64,
            ..w.inp.clone()
        };
        put(
            georef::georef(&inp2, Some((p, out.las_frame)), None).map(|(st, _, _)| {
                Some(format!(
                    "LAS: {} ({} returns with the calibrated mount, {} coordinates)\n",
                    p.display(),
                    st.align.window.georeferenced,
                    match out.las_frame {
                        georef::LasFrame::Projected => "map",
                        georef::LasFrame::Local => "local east-north-up",
                    }
                ))
            }),
        );
    }
    if out.plot.is_some() || out.html.is_some() {
        let figs = plot::Figures::new(w.targets, w.ids, w.obs, w.sol, w.b0, rep);
        if let Some(p) = &out.plot {
            put(plot::plot(p, &figs).map(|()| Some(format!("plot: {}\n", p.display()))));
        }
        if let Some(p) = &out.html {
            put(html::render(rep, &figs, w.inp.site.leap_seconds)
                .and_then(|page| output::write(p, page.as_bytes()))
                .map(|()| Some(format!("report (HTML): {}\n", p.display()))));
        }
    }
    (wrote, output_errors)
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
    init: Option<DegM>,
    clock: ClockOptions,
    out: &Outputs,
    truth: Option<[f64; 7]>,
) -> Result<Calibrated, crate::Error> {
    use crate::pipeline::{Inputs, InsInput};
    out.check()?;
    let site = config::site::Site::load(&survey.site)?;
    let board = match &survey.board {
        Some(p) => Some((p.clone(), config::board::Board::load(p)?)),
        None => None,
    };
    let start = init.unwrap_or(site.apriori_deg_m());
    let b0 = start.params();
    let (ins, accuracy) = match (survey.ins, survey.sbet, survey.posmv) {
        _ if survey.bag.is_some() => {
            let (b, t) = survey.bag.unwrap_or_default();
            (InsInput::Bag(b, t), None)
        }
        (Some(i), _, _) => (InsInput::Vn200(i), None),
        (None, None, Some((f, g))) => (InsInput::Posmv(f, survey.gps_week, g), None),
        (None, Some(s), _) => {
            // Beside a single SBET file, its smrmsg.
            let acc = survey.smrmsg.or_else(|| match s.0.as_slice() {
                [one] => pipeline::accuracy::beside_sbet(one),
                _ => None,
            });
            (InsInput::Sbet(s, survey.gps_week), acc)
        }
        (None, None, None) => return Err("give --ins, --sbet or --posmv".into()),
    };
    let surveyed = site.clone();
    let (site, datums) =
        pipeline::site_in_trajectory_datum(&site, &ins, survey.trajectory_datum.as_deref())?;
    if out.las.is_some() {
        georef::LasOut::check(&site, out.las_frame)?;
    }
    let mut inp = Inputs::apriori(survey.pcap, ins, site);
    inp.model = survey.model;
    if let Some(p) = &survey.metadata {
        inp.set_metadata(p)?;
    }
    inp.ports = survey.ports;
    inp.lidar_topic = survey.lidar_topic;
    inp.accuracy = accuracy;
    inp.mount = b0.mount();
    inp.keep_untracked_ins = clock.keep_untracked_ins;
    inp.exclude = survey.exclude.clone();
    let (targets, ids) = calibrate::site_targets(&inp);
    // Hashed for the provenance on the other core once the data are in (the solve uses one).
    let mut hashing = report::provenance::Hashing::new(input_files(&inp)?);
    let (mut stats, mut obs, mut sol, mut rep) =
        calibrate::calibrate(&mut inp, &targets, &ids, &b0, clock, &mut || {
            hashing.start()
        })?;
    // A parameter the data cannot determine: held at its a-priori value, the rest calibrated.
    let candidates = crate::undetermined::candidates(&sol, &inp.site);
    let mut held = String::new();
    if !candidates.is_empty() {
        let mut again = inp.clone();
        again.site = crate::undetermined::holding(&inp.site, &candidates);
        let second = calibrate::calibrate(&mut again, &targets, &ids, &b0, clock, &mut || {})?;
        let weak = crate::undetermined::undetermined(&candidates, &second.3.sigma.deg_m());
        if second.3.converged && !weak.is_empty() {
            let why = rep
                .reason
                .clone()
                .unwrap_or_else(|| crate::undetermined::alone(&sol, &weak));
            held = crate::undetermined::words(&weak, &inp.site, &why);
            (stats, obs, sol, rep) = second;
            rep.held = weak.iter().map(|&i| NAMES[i].into()).collect();
            inp = again;
        }
    }
    let mut text = format!("{datums}\n{held}");
    // A bag's own account of itself (no metadata.yaml, messages it promises but lacks).
    if let Some(b) = pipeline::as_bag(&inp.pcap) {
        if let Ok(o) = crate::bag::open(b, inp.lidar_topic.as_deref(), None, false) {
            for n in o.notes() {
                text.push_str(&n);
                text.push('\n');
            }
        }
    }
    text.push_str(&stats.describe_inputs(&inp.pcap, inp.ins_files()));
    text.push_str(&format!(
        "{} returns, windows {:?}\n",
        stats.align.window.points,
        obs.iter().map(Vec::len).collect::<Vec<_>>()
    ));
    if stats.pruned > 0 {
        text.push_str(&format!(
            "memory: {} windowed returns farther than {:.1} m from every sphere were let go as \
             they came (a solve of the first {} had placed the spheres)\n",
            stats.pruned,
            crate::session::KEEP_NEAR_M,
            crate::calibrate::STORE_CAP
        ));
    }
    let goal = crate::config::goal::TargetChoice::of(
        inp.site.calibration.as_ref(),
        board.as_ref().map(|b| &b.1.calibration),
    );
    rep.targets = Some(report::TargetsReport::of(&rep, &goal));
    rep.conventions = Some(report::conventions::Conventions::of(&sol.b.0));
    // What the site measured (not the holds).
    rep.mounting_prior = report::prior::of(&surveyed.apriori, &rep);
    let mut prov = provenance(&inp, hashing, &survey.site, &surveyed, &datums, &stats)?;
    prov.platform = report::provenance::Platform::of(board.as_ref(), survey.operator.as_deref())?;
    rep.provenance = Some(prov);
    text.push_str(&report::render(&rep, truth.as_ref()));
    // The result is printed whatever happens to the files: an output that fails now (a disk
    // full, a mount gone) is said after it, not instead of it.
    let written = Written {
        targets: &targets,
        ids: &ids,
        obs: &obs,
        sol: &sol,
        b0: &b0,
        inp: &inp,
    };
    let (wrote, output_errors) = write_outputs(out, &rep, &written);
    text.push_str(&wrote);
    // Every output is written (or failed and said): an interrupt now removes none of them.
    output::finished();
    Ok(Calibrated {
        text,
        converged: rep.converged,
        met: rep.targets.as_ref().is_some_and(|t| t.met),
        output_errors,
    })
}

/// What [`run_calibrate`] gives: the printed result, whether a solution is claimed, and the
/// outputs that could not be written (said after the result).
#[derive(Debug, Clone)]
pub struct Calibrated {
    /// The inputs, the datums, the table and the verdict, as printed.
    pub text: String,
    /// A solution is claimed (every check passed).
    pub converged: bool,
    /// ... and every sigma is within its target (`report.json` `targets`).
    pub met: bool,
    /// Outputs that failed, each naming its file.
    pub output_errors: Vec<String>,
}

/// The input files of `inp` for the provenance, `(role, path)`: each capture and INS file once
/// (a bag as one input: its folder's files hashed together), then the accuracy file.
fn input_files(inp: &pipeline::Inputs) -> Result<Vec<(String, std::path::PathBuf)>, crate::Error> {
    let mut out: Vec<(String, std::path::PathBuf)> = Vec::new();
    for (role, files) in [("lidar", &inp.pcap), ("ins", inp.ins_files())] {
        let paths = match pipeline::as_bag(files) {
            Some(b) => vec![b.to_path_buf()],
            None => files.expand()?,
        };
        for f in paths {
            if !out.iter().any(|(_, p)| *p == f) {
                out.push((role.into(), f));
            }
        }
    }
    if let Some(a) = &inp.accuracy {
        out.push(("accuracy".into(), a.clone()));
    }
    Ok(out)
}

/// Where this calibration came from: the command line, the build, each input file with its
/// hash and the span its data cover, the site as surveyed and the datums' transformation.
fn provenance(
    inp: &pipeline::Inputs,
    hashed: report::provenance::Hashing,
    site_path: &std::path::Path,
    surveyed: &config::site::Site,
    datums: &str,
    stats: &pipeline::RunStats,
) -> Result<report::provenance::Provenance, crate::Error> {
    use report::provenance::{Provenance, SiteProvenance};
    let mut inputs = hashed.finish()?;
    for i in &mut inputs {
        i.gps_span_s = match i.role.as_str() {
            "lidar" => stats.align.lidar_span,
            "ins" => stats.ins.span,
            _ => None,
        };
    }
    Ok(Provenance {
        command: std::env::args().collect(),
        version: report::provenance::version(),
        made_utc: chrono::Utc::now().format("%Y-%m-%dT%H:%M:%SZ").to_string(),
        inputs,
        site: SiteProvenance::of(site_path, surveyed, &inp.site, datums)?,
        platform: None,
    })
}

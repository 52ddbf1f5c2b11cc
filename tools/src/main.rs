//! `spherecal`: the command (see README.md and ../shared/DESIGN.md for the contract).
//! Exit codes: 0 success; 1 calibration failed; 2 bad arguments or unreadable input.

use clap::{Parser, Subcommand};
use std::io::BufWriter;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "spherecal",
    version,
    about = "LiDAR boresight / lever-arm calibration on spheres"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Option<Cmd>,
}

/// The recorded survey: capture, trajectory and site.
#[derive(clap::Args)]
struct Survey {
    /// The VLP-16 capture.
    #[arg(long)]
    pcap: PathBuf,
    /// VN-200 serial bytes (raw or a serial log).
    #[arg(long, required_unless_present = "sbet", conflicts_with = "sbet")]
    ins: Option<PathBuf>,
    /// An Applanix SBET trajectory instead of the VN-200.
    #[arg(long)]
    sbet: Option<PathBuf>,
    /// GPS week of the SBET (default: from the capture's RMC date).
    #[arg(long)]
    gps_week: Option<u16>,
    /// site.toml: spheres, origin, a-priori values.
    #[arg(long)]
    site: PathBuf,
}

#[derive(Subcommand)]
enum Cmd {
    /// Decode VLP-16 packets from a pcap/pcapng capture; print counts, optionally list points.
    Decode {
        /// Capture file (classic pcap or pcapng).
        file: PathBuf,
        /// Write one row per returned point to this CSV file.
        #[arg(long)]
        csv: Option<PathBuf>,
    },
    /// Simulate a survey: write lidar.pcap, ins.bin, site.toml and truth.json.
    Synth {
        /// A built-in scenario name (table1, table1-noisy) or a scenario TOML file.
        #[arg(long, required_unless_present = "print_scenario")]
        scenario: Option<String>,
        /// Output folder.
        #[arg(long, required_unless_present = "print_scenario")]
        out: Option<PathBuf>,
        /// Print a built-in scenario as TOML (to edit) and exit.
        #[arg(long, value_name = "NAME", conflicts_with_all = ["scenario", "out"])]
        print_scenario: Option<String>,
    },
    /// Georeference a survey: align the LiDAR with the trajectory, keep the sphere windows.
    Georef {
        #[command(flatten)]
        survey: Survey,
        /// Boresight roll,pitch,heading [deg] (default: the site's a-priori).
        #[arg(long, value_parser = parse3, allow_hyphen_values = true)]
        boresight: Option<[f64; 3]>,
        /// Lever arm x,y,z [m] (default: the site's a-priori).
        #[arg(long, value_parser = parse3, allow_hyphen_values = true)]
        lever: Option<[f64; 3]>,
        /// Largest INS sample spacing to interpolate over [ms].
        #[arg(long, default_value_t = 50.0)]
        max_gap_ms: f64,
        /// The time offset between the clocks [s]: INS time = LiDAR time + this (what
        /// `calibrate` reports as `time_offset_s`).
        #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
        time_offset: f64,
        /// Write the georeferenced cloud as LAS 1.4 (local east-north-up from the origin).
        #[arg(long)]
        las: Option<PathBuf>,
        /// Write the window points as CSV.
        #[arg(long)]
        windows: Option<PathBuf>,
    },
    /// Calibrate: georeference, window, solve for boresight and lever arm, report.
    Calibrate {
        #[command(flatten)]
        survey: Survey,
        /// Start: roll,pitch,heading [deg],x,y,z [m] (default: the site's a-priori values).
        #[arg(long, value_parser = parse6, allow_hyphen_values = true)]
        init: Option<[f64; 6]>,
        /// Write the JSON report here.
        #[arg(long)]
        report: Option<PathBuf>,
        /// Write the calibrated cloud as LAS.
        #[arg(long)]
        las: Option<PathBuf>,
        /// Write residual plots (SVG).
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Write every windowed return with its verdict (kept, or why not) as CSV.
        #[arg(long)]
        returns: Option<PathBuf>,
        /// Start from this time offset between the clocks [s] (INS time = LiDAR time + this;
        /// default 0, or what the LiDAR's RMC says when its clock is not PPS-locked).
        #[arg(long, allow_hyphen_values = true)]
        time_offset: Option<f64>,
        /// Hold the time offset (at `--time-offset`) instead of estimating it.
        #[arg(long)]
        hold_time_offset: bool,
        /// Claim a solution although the LiDAR clock is not PPS-locked with a valid RMC (when
        /// the time offset found explains the stamps' disagreement with the RMC).
        #[arg(long)]
        allow_unlocked_clock: bool,
        /// Use VN-200 poses whose InsStatus says not tracking, aligning, GNSS lost or no fix.
        #[arg(long)]
        keep_untracked_ins: bool,
        /// Search the time offset over +- this many seconds around the start, in 0.25 s steps
        /// (default: 2 s when the LiDAR clock is not PPS-locked with a valid RMC, else none; 0
        /// turns it off).
        #[arg(long)]
        search_time_offset: Option<f64>,
    },
    /// Calibrate one synthetic survey from many perturbed starts, on all cores.
    Montecarlo {
        /// A built-in scenario or a scenario file.
        #[arg(long)]
        scenario: String,
        /// Number of starts.
        #[arg(long, default_value_t = 200)]
        trials: usize,
        /// Starts within +- this of the true angles [deg].
        #[arg(long, default_value_t = 5.0)]
        angle_noise_deg: f64,
        /// Starts within +- this of the true lever arm [m].
        #[arg(long, default_value_t = 0.5)]
        lever_noise_m: f64,
        /// Seed of the starts.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Write the JSON report here.
        #[arg(long)]
        report: Option<PathBuf>,
    },
    /// Play recorded files back: UDP datagrams to their ports, serial bytes to a device.
    Replay {
        /// A folder with lidar.pcap and ins.vnlog or ins.bin (as `synth` writes).
        dir: Option<PathBuf>,
        /// The capture (instead of DIR).
        #[arg(long)]
        pcap: Option<PathBuf>,
        /// The serial bytes or log (instead of DIR).
        #[arg(long)]
        ins: Option<PathBuf>,
        /// Host to send the datagrams to.
        #[arg(long, default_value = "127.0.0.1")]
        udp: std::net::Ipv4Addr,
        /// Send the capture's data (2368) and position (8308) packets to these ports instead.
        #[arg(long, value_name = "DATA,POSITION", value_parser = parse_ports)]
        ports: Option<[u16; 2]>,
        /// Serial device to write the INS bytes to (none: the bytes are not replayed).
        #[arg(long)]
        serial: Option<String>,
        /// Baud rate of the serial device.
        #[arg(long, default_value_t = 921_600)]
        baud: u32,
        /// Speed: a factor of the recorded pacing (1 = real time) or max.
        #[arg(long, default_value = "1")]
        speed: spherecal_tools::replay::Speed,
    },
    /// The rig: listen to the VLP-16 and the VN-200, log everything raw, show a status line every
    /// second, calibrate once every sphere has been seen well enough. Stops on SIGINT/SIGTERM
    /// or after --duration, exit 0.
    Run {
        /// The board file (boards/*.toml).
        #[arg(long)]
        board: PathBuf,
        /// Serial device of the INS (overrides the board's).
        #[arg(long)]
        serial: Option<String>,
        /// site.toml: without it the rig only acquires and logs.
        #[arg(long)]
        site: Option<PathBuf>,
        /// Raw log folder (overrides the board's).
        #[arg(long)]
        log_dir: Option<PathBuf>,
        /// Rotate raw log files at this size [MB] (overrides the board's).
        #[arg(long)]
        rotate_mb: Option<f64>,
        /// Stop after this many seconds.
        #[arg(long)]
        duration: Option<f64>,
        /// Write the calibration report here after every solve.
        #[arg(long)]
        report: Option<PathBuf>,
        /// Use VN-200 poses whose InsStatus says not tracking, aligning, GNSS lost or no fix.
        #[arg(long)]
        keep_untracked_ins: bool,
    },
    /// Synthesise table1, calibrate from the paper's erroneous start, show the result beside the
    /// truth (what a bare `cargo run --release` does).
    Demo,
    /// Frame a VN-200 serial capture (raw bytes or a spherecal serial log); print counts,
    /// optionally list the binary frames' fields.
    Ins {
        /// Raw serial bytes, or a timestamped serial log (magic SCSERLOG).
        file: PathBuf,
        /// Write one row per valid binary frame to this CSV file.
        #[arg(long)]
        csv: Option<PathBuf>,
    },
}

/// Print to stdout; a closed pipe (`spherecal ... | head`) is not an error worth a panic.
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout(), $($t)*);
    }};
}

macro_rules! sayln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::from(2)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    let Some(cmd) = cli.cmd else {
        return demo();
    };
    match cmd {
        Cmd::Demo => demo(),
        Cmd::Run {
            board,
            serial,
            site,
            log_dir,
            rotate_mb,
            duration,
            report,
            keep_untracked_ins,
        } => run(
            board,
            serial,
            site,
            log_dir,
            rotate_mb,
            duration,
            report,
            keep_untracked_ins,
        ),
        Cmd::Replay {
            dir,
            pcap,
            ins,
            udp,
            ports,
            serial,
            baud,
            speed,
        } => replay(dir, pcap, ins, udp, ports, serial, baud, speed),
        Cmd::Montecarlo {
            scenario,
            trials,
            angle_noise_deg,
            lever_noise_m,
            seed,
            report,
        } => {
            let s = match spherecal_tools::scenario::Scenario::load(&scenario) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("spherecal montecarlo: {e}");
                    return ExitCode::from(2);
                }
            };
            match spherecal_tools::montecarlo::montecarlo(
                &s,
                trials,
                angle_noise_deg,
                lever_noise_m,
                seed,
                true,
            ) {
                Ok(r) => {
                    say!("{}", spherecal_tools::montecarlo::render(&r));
                    if let Some(p) = report {
                        let json = serde_json::to_string_pretty(&r).unwrap_or_default();
                        if let Err(e) = std::fs::write(&p, json + "\n") {
                            eprintln!("spherecal montecarlo: {}: {e}", p.display());
                            return ExitCode::from(2);
                        }
                    }
                    if r.fraction_within == 1.0 {
                        ExitCode::SUCCESS
                    } else {
                        ExitCode::from(1)
                    }
                }
                Err(e) => {
                    eprintln!("spherecal montecarlo: {e}");
                    ExitCode::from(2)
                }
            }
        }
        Cmd::Calibrate {
            survey,
            init,
            report,
            las,
            plot,
            returns,
            time_offset,
            hold_time_offset,
            allow_unlocked_clock,
            keep_untracked_ins,
            search_time_offset,
        } => {
            let survey = spherecal_tools::Survey {
                pcap: survey.pcap,
                ins: survey.ins,
                sbet: survey.sbet,
                gps_week: survey.gps_week,
                site: survey.site,
            };
            let out = spherecal_tools::Outputs {
                report,
                las,
                plot,
                returns,
            };
            let clock = spherecal_tools::ClockOptions {
                estimate: !hold_time_offset,
                start: time_offset,
                allow_unlocked: allow_unlocked_clock,
                keep_untracked_ins,
                search: search_time_offset,
            };
            match spherecal_tools::run_calibrate(survey, init, clock, &out, None) {
                Ok((text, ok)) => {
                    say!("{text}");
                    if ok {
                        ExitCode::SUCCESS
                    } else {
                        ExitCode::from(1)
                    }
                }
                Err(e) => {
                    eprintln!("spherecal calibrate: {e}");
                    ExitCode::from(2)
                }
            }
        }
        Cmd::Decode { file, csv } => decode(file, csv),
        Cmd::Ins { file, csv } => ins(file, csv),
        Cmd::Synth {
            scenario,
            out,
            print_scenario,
        } => synth(scenario, out, print_scenario),
        Cmd::Georef {
            survey,
            boresight,
            lever,
            max_gap_ms,
            time_offset,
            las,
            windows,
        } => georef(
            survey,
            boresight,
            lever,
            (max_gap_ms, time_offset),
            las,
            windows,
        ),
    }
}

fn synth(scenario: Option<String>, out: Option<PathBuf>, print: Option<String>) -> ExitCode {
    use spherecal_tools::scenario::{Scenario, BUILTIN};
    if let Some(name) = print {
        return match BUILTIN.iter().find(|b| b.0 == name) {
            Some((_, text)) => {
                say!("{text}");
                ExitCode::SUCCESS
            }
            None => {
                let names: Vec<&str> = BUILTIN.iter().map(|b| b.0).collect();
                eprintln!(
                    "spherecal synth: no built-in scenario {name:?} (have: {})",
                    names.join(", ")
                );
                ExitCode::from(2)
            }
        };
    }
    let (Some(scenario), Some(out)) = (scenario, out) else {
        eprintln!("spherecal synth: --scenario and --out are required");
        return ExitCode::from(2);
    };
    let s = match Scenario::load(&scenario) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("spherecal synth: {e}");
            return ExitCode::from(2);
        }
    };
    let t0 = std::time::Instant::now();
    match spherecal_tools::synth::synth(&s, &out) {
        Ok(t) => {
            sayln!(
                "{}: {:.1} s of scanning, {} data + {} position packets, {} VN-200 frames, {} rays in {:.2} s",
                s.name,
                s.duration_s(),
                t.data_packets,
                t.position_packets,
                t.ins_frames,
                t.rays_traced,
                t0.elapsed().as_secs_f64()
            );
            sayln!(
                "points per sphere: {:?} (clutter: {})",
                t.points_per_sphere,
                t.clutter_points
            );
            sayln!(
                "wrote {}/{{lidar.pcap, ins.bin, site.toml, truth.json}}",
                out.display()
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("spherecal synth: {e}");
            ExitCode::from(2)
        }
    }
}

fn demo() -> ExitCode {
    let dir = std::env::temp_dir().join(format!("spherecal-demo-{}", std::process::id()));
    let s = match spherecal_tools::scenario::Scenario::load("table1") {
        Ok(s) => s,
        Err(e) => {
            eprintln!("spherecal demo: {e}");
            return ExitCode::from(2);
        }
    };
    sayln!(
        "spherecal demo: the paper's Table 1 survey, synthesised into {}",
        dir.display()
    );
    let t0 = std::time::Instant::now();
    let truth = match spherecal_tools::synth::synth(&s, &dir) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("spherecal demo: {e}");
            return ExitCode::from(2);
        }
    };
    sayln!(
        "synthesised {:.1} s of scanning ({} packets, {} VN-200 frames, {:?} sphere returns) in {:.2} s",
        s.duration_s(),
        truth.data_packets,
        truth.ins_frames,
        truth.points_per_sphere,
        t0.elapsed().as_secs_f64()
    );
    sayln!("calibrating from the paper's erroneous a-priori values ...");
    let t6 = spherecal_tools::site::deg_m(s.mount.truth.boresight_deg, s.mount.truth.lever_arm_m);
    let truth7 = [
        t6[0],
        t6[1],
        t6[2],
        t6[3],
        t6[4],
        t6[5],
        s.true_time_offset_s(),
    ];
    let out = spherecal_tools::Outputs {
        report: Some(dir.join("report.json")),
        ..Default::default()
    };
    let res = spherecal_tools::run_calibrate(
        spherecal_tools::Survey::synth_dir(&dir),
        None,
        Default::default(),
        &out,
        Some(truth7),
    );
    let code = match res {
        Ok((text, ok)) => {
            say!("{text}");
            sayln!("report: {}", dir.join("report.json").display());
            if ok {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(1)
            }
        }
        Err(e) => {
            eprintln!("spherecal demo: {e}");
            ExitCode::from(2)
        }
    };
    for f in ["lidar.pcap", "ins.bin"] {
        let _ = std::fs::remove_file(dir.join(f));
    }
    code
}

#[allow(clippy::too_many_arguments)]
fn run(
    board: PathBuf,
    serial: Option<String>,
    site: Option<PathBuf>,
    log_dir: Option<PathBuf>,
    rotate_mb: Option<f64>,
    duration: Option<f64>,
    report: Option<PathBuf>,
    keep_untracked_ins: bool,
) -> ExitCode {
    use spherecal_tools::rig::{run, RunOptions};
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;
    let fail = |e: String| {
        eprintln!("spherecal run: {e}");
        ExitCode::from(2)
    };
    let board = match spherecal_tools::board::Board::load(&board) {
        Ok(b) => b,
        Err(e) => return fail(e),
    };
    let site = match site
        .map(|s| spherecal_tools::site::Site::load(&s))
        .transpose()
    {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    if let Some(d) = duration.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return fail(format!(
            "--duration {d}: expected a positive number of seconds"
        ));
    }
    if let Some(r) = rotate_mb.filter(|r| !(r.is_finite() && *r > 0.0)) {
        return fail(format!("--rotate-mb {r}: expected a positive size"));
    }
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(e) = signal_hook::flag::register(sig, Arc::clone(&stop)) {
            return fail(format!("signal {sig}: {e}"));
        }
    }
    let mut console =
        match spherecal_hal::console::Console::open(&board.console.device, board.console.baud) {
            Ok(c) => c,
            Err(e) => return fail(e),
        };
    let opts = RunOptions {
        board,
        serial,
        site,
        log_dir,
        rotate_bytes: rotate_mb.map(|m| (m * 1_048_576.0) as u64),
        duration: duration.map(std::time::Duration::from_secs_f64),
        report,
        settings: spherecal::calib::Settings::default(),
        keep_untracked_ins,
    };
    match run(&opts, &mut console, &stop) {
        Ok(s) => {
            // A closed stderr is no reason to fail a finished run.
            let _ = std::io::Write::write_all(
                &mut std::io::stderr(),
                spherecal_tools::rig::render(&s).as_bytes(),
            );
            ExitCode::SUCCESS
        }
        Err(e) => fail(e),
    }
}

#[allow(clippy::too_many_arguments)]
fn replay(
    dir: Option<PathBuf>,
    pcap: Option<PathBuf>,
    ins: Option<PathBuf>,
    udp: std::net::Ipv4Addr,
    ports: Option<[u16; 2]>,
    serial: Option<String>,
    baud: u32,
    speed: spherecal_tools::replay::Speed,
) -> ExitCode {
    use spherecal_tools::replay::{replay_both, Target};
    let pcap = pcap.or_else(|| dir.as_ref().map(|d| d.join("lidar.pcap")));
    // A serial log (with receive times) keeps the two streams in step; raw bytes go at the
    // baud rate's pace.
    let ins = ins.or_else(|| {
        dir.as_ref().map(|d| {
            let log = d.join("ins.vnlog");
            if log.exists() {
                log
            } else {
                d.join("ins.bin")
            }
        })
    });
    let Some(pcap) = pcap else {
        eprintln!("spherecal replay: give DIR or --pcap");
        return ExitCode::from(2);
    };
    let mut to = Target::host(udp);
    if let Some([d, p]) = ports {
        to.ports = [(2368, d), (8308, p)];
    }
    let mut port = match &serial {
        Some(dev) => match serialport::new(dev.as_str(), baud).open() {
            Ok(p) => Some(p),
            Err(e) => {
                eprintln!("spherecal replay: {dev}: {e}");
                return ExitCode::from(2);
            }
        },
        None => None,
    };
    let serial_job = match (&mut port, &ins) {
        (Some(p), Some(i)) => Some((i.as_path(), p as &mut (dyn std::io::Write + Send), baud)),
        _ => None,
    };
    match replay_both(&pcap, to, serial_job, speed) {
        Ok((u, s)) => {
            sayln!(
                "sent {} datagrams to {udp} ({} records skipped)",
                u.sent,
                u.skipped
            );
            if let Some(n) = s {
                sayln!("wrote {n} bytes to {}", serial.unwrap_or_default());
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("spherecal replay: {e}");
            ExitCode::from(2)
        }
    }
}

/// Two comma-separated ports.
fn parse_ports(s: &str) -> Result<[u16; 2], String> {
    match s.split_once(',') {
        Some((a, b)) => match (a.trim().parse::<u16>(), b.trim().parse::<u16>()) {
            (Ok(a), Ok(b)) if a > 0 && b > 0 => Ok([a, b]),
            _ => Err(format!("{s:?}: expected two ports DATA,POSITION")),
        },
        None => Err(format!("{s:?}: expected two ports DATA,POSITION")),
    }
}

/// Six comma-separated numbers.
fn parse6(s: &str) -> Result<[f64; 6], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s:?}: {e}"))?;
    <[f64; 6]>::try_from(v.as_slice())
        .ok()
        .filter(|a| a.iter().all(|x| x.is_finite()))
        .ok_or_else(|| format!("{s:?}: expected six finite numbers r,p,h,x,y,z"))
}

/// `a,b,c` as three numbers.
fn parse3(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s:?}: {e}"))?;
    match v.as_slice() {
        [a, b, c] if v.iter().all(|x| x.is_finite()) => Ok([*a, *b, *c]),
        _ => Err(format!("{s:?}: expected three finite numbers a,b,c")),
    }
}

fn georef(
    survey: Survey,
    boresight: Option<[f64; 3]>,
    lever: Option<[f64; 3]>,
    (max_gap_ms, time_offset): (f64, f64),
    las: Option<PathBuf>,
    windows: Option<PathBuf>,
) -> ExitCode {
    use spherecal_tools::pipeline::{Inputs, InsInput};
    let Survey {
        pcap,
        ins,
        sbet,
        gps_week,
        site,
    } = survey;
    let site = match spherecal_tools::site::Site::load(&site) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("spherecal georef: {e}");
            return ExitCode::from(2);
        }
    };
    let b = boresight.unwrap_or(site.apriori.boresight_deg);
    let l = lever.unwrap_or(site.apriori.lever_arm_m);
    let ins = match (ins, sbet) {
        (Some(i), _) => InsInput::Vn200(i),
        (None, Some(s)) => InsInput::Sbet(s, gps_week),
        (None, None) => {
            eprintln!("spherecal georef: give --ins or --sbet");
            return ExitCode::from(2);
        }
    };
    let inp = Inputs {
        pcap,
        ins,
        mount: spherecal::georef::Mount::new(b.map(f64::to_radians), l),
        margin: site.apriori.window_margin_m,
        max_gap_ns: (max_gap_ms * 1e6) as i64,
        time_offset_ns: (time_offset * 1e9).round() as i64,
        keep_untracked_ins: false,
        site,
    };
    match spherecal_tools::georef::georef(&inp, las.as_deref(), windows.as_deref()) {
        Ok((_, _, text)) => {
            say!("{text}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("spherecal georef: {e}");
            ExitCode::from(2)
        }
    }
}

fn create_csv(
    cmd: &str,
    csv: Option<&PathBuf>,
) -> Result<Option<BufWriter<std::fs::File>>, ExitCode> {
    match csv.map(std::fs::File::create).transpose() {
        Ok(f) => Ok(f.map(|f| BufWriter::with_capacity(1 << 20, f))),
        Err(e) => {
            eprintln!(
                "spherecal {cmd}: {}: cannot create: {e}",
                csv.map(|p| p.display().to_string()).unwrap_or_default()
            );
            Err(ExitCode::from(2))
        }
    }
}

fn ins(file: PathBuf, csv: Option<PathBuf>) -> ExitCode {
    let (bytes, _stamps) = match spherecal_hal::serial::read_byte_file(&file) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("spherecal ins: {}: {e}", file.display());
            return ExitCode::from(2);
        }
    };
    let mut out = match create_csv("ins", csv.as_ref()) {
        Ok(o) => o,
        Err(code) => return code,
    };
    let w = out.as_mut().map(|w| w as &mut dyn std::io::Write);
    match spherecal_tools::ins::frame_bytes(&bytes, w) {
        Ok(s) => {
            say!("{}", s.render(&file.display().to_string()));
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("spherecal ins: {}: writing CSV: {e}", file.display());
            ExitCode::from(2)
        }
    }
}

fn decode(file: PathBuf, csv: Option<PathBuf>) -> ExitCode {
    let mut out = match create_csv("decode", csv.as_ref()) {
        Ok(o) => o,
        Err(code) => return code,
    };
    let w = out.as_mut().map(|w| w as &mut dyn std::io::Write);
    match spherecal_tools::decode::decode_file(&file, w) {
        Ok(s) => {
            say!("{}", s.render(&file.display().to_string()));
            if let Some(stop) = &s.stopped {
                eprintln!("spherecal decode: {}: {stop}", file.display());
                return ExitCode::from(2);
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("spherecal decode: {e}");
            ExitCode::from(2)
        }
    }
}

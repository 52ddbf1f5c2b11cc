//! The `spherecal` subcommands: each module owns its clap `Args` and its `run`, which reads the
//! arguments, calls the library and maps the outcome to the exit code of the command contract
//! ([`EXIT_CODES`]: 0 success; 1 calibration refused; 2 bad arguments or unreadable input; 3
//! converged but the sigmas miss the targets; 4 an internal fault: [`crate::Error`]).

use std::path::PathBuf;
use std::process::ExitCode;

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

pub mod bag;
pub mod board;
pub mod calibrate;
pub mod decode;
pub mod demo;
pub mod georef;
pub mod ins;
pub mod montecarlo;
pub mod plan;
pub mod replay;
pub mod run;
pub mod site;
pub mod synth;
pub mod vn200;

/// `spherecal CMD: error` on stderr and the exit code of its kind: a plain message is bad
/// input (exit 2), a [`crate::Error`] keeps its kind.
pub(crate) fn fail(cmd: &str, why: impl Into<crate::Error>) -> ExitCode {
    let e = why.into();
    eprintln!("spherecal {cmd}: {e}");
    e.exit_code()
}

/// Outputs that failed after the result was printed: each said, exit 2 (`None` when all
/// were written).
fn outputs_failed(cmd: &str, errors: &[String]) -> Option<ExitCode> {
    for e in errors {
        eprintln!("spherecal {cmd}: the result above stands, but an output was not written: {e}");
    }
    (!errors.is_empty()).then(|| ExitCode::from(crate::ErrorKind::BadInput.exit_code()))
}

/// Print the text and exit 0, or fail (exit 2) with the error.
fn print_or_fail(cmd: &str, r: Result<String, crate::Error>) -> ExitCode {
    match r {
        Ok(text) => {
            say!("{text}");
            ExitCode::SUCCESS
        }
        Err(e) => fail(cmd, e),
    }
}

/// The exit code of a calibration (the command contract): 0 claimed and every sigma within
/// its target, 3 claimed but some sigma misses its target, 1 refused.
fn claimed(converged: bool, met: bool) -> ExitCode {
    match (converged, met) {
        (true, true) => ExitCode::SUCCESS,
        (true, false) => ExitCode::from(MISSES_TARGETS),
        _ => ExitCode::from(crate::ErrorKind::Refused.exit_code()),
    }
}

/// Exit code of a calibration that converged but whose sigmas miss the targets.
pub const MISSES_TARGETS: u8 = 3;

/// The exit codes, for `--help`.
pub const EXIT_CODES: &str = "Exit codes: 0 converged and every sigma within its target; 1 refused (the reason first); 2 bad input (the file, offset and reason); 3 converged, but the sigmas miss the targets ([calibration] target_sigma_deg / target_sigma_m in the site, else the board's, else 0.01 deg and 5 mm); 4 an internal fault of spherecal (a bug to report).";

/// The recorded survey: capture, trajectory and site.
#[derive(clap::Args, Debug, Clone)]
pub struct SurveyArgs {
    /// The Velodyne capture: files, folders of captures or patterns
    /// (`'logs/*-lidar-*.pcap'`), one or several, taken in the order of their first datagram.
    #[arg(long, num_args = 1.., required_unless_present = "bag")]
    pub pcap: Vec<PathBuf>,
    /// A ROS 2 bag (a rosbag2 folder, a `.mcap` or a `.db3`): the LiDAR from its
    /// velodyne_msgs/VelodyneScan topic unless --pcap is given, the INS from its
    /// vectornav_msgs/CommonGroup topic unless --ins, --sbet or --posmv is (`spherecal bag
    /// info` shows what is read).
    #[arg(long)]
    pub bag: Option<PathBuf>,
    /// The bag's topic of VelodyneScan messages (default: the only one).
    #[arg(long, requires = "bag")]
    pub lidar_topic: Option<String>,
    /// The bag's topic of CommonGroup messages (default: the only one).
    #[arg(long, requires = "bag")]
    pub ins_topic: Option<String>,
    /// The LiDAR model (vlp16, puck-hires, hdl32e, vlp32c); by default the packets' product
    /// byte, checked against their period.
    #[arg(long, value_parser = parse_model)]
    pub model: Option<spherecal::velodyne::Model>,
    /// A Hesai unit's angle correction CSV: the capture holds that Hesai's data packets
    /// (PandarXT16 / XT32 / QT64 / QT128, UDP 2368) and GPS packets (UDP 10110), each return
    /// timed by its packet's date-time and microseconds as UTC.
    #[arg(long, conflicts_with = "model")]
    pub metadata: Option<PathBuf>,
    /// VN-200 serial bytes (raw or serial logs): files or patterns, in name order.
    #[arg(
        long,
        num_args = 1..,
        required_unless_present_any = ["sbet", "posmv", "bag"],
        conflicts_with_all = ["sbet", "posmv"]
    )]
    pub ins: Vec<PathBuf>,
    /// An Applanix SBET trajectory instead of the VN-200: files or patterns, in time order.
    #[arg(long, num_args = 1.., conflicts_with = "posmv")]
    pub sbet: Vec<PathBuf>,
    /// An Applanix POS MV's real-time groups instead: logged `.000` streams, or captures of its
    /// UDP datagrams (the LiDAR's own capture when both were recorded on one network).
    #[arg(long, num_args = 1..)]
    pub posmv: Vec<PathBuf>,
    /// The POS MV group the poses come from: 1 (vessel reference point, default), 102 or 103
    /// (sensor 1 or 2).
    #[arg(long, default_value_t = 1, requires = "posmv")]
    pub posmv_group: u16,
    /// GPS week of the SBET or POS MV stream (default: the POS MV's Group 3, else the
    /// capture's RMC date).
    #[arg(long)]
    pub gps_week: Option<u16>,
    /// The SBET's accuracy file (POSPac smrmsg): the calibration weighs each return by the
    /// trajectory's own position and attitude sigma at its time (default: `smrmsg_NAME.out`
    /// beside `sbet_NAME.out`, when there).
    #[arg(long, requires = "sbet")]
    pub smrmsg: Option<PathBuf>,
    /// site.toml: spheres, origin, a-priori values.
    #[arg(long)]
    pub site: PathBuf,
    /// The datum of the trajectory's positions: WGS84, ITRF2014, NAD83(CSRS), ETRS89, ...,
    /// `EPSG:<CRS>` or `datum:<EPSG datum code>` (default: WGS 84 for a VN-200 or a POS MV's
    /// real-time output; an SBET must say). The site's coordinates are transformed into it,
    /// and the transformation named.
    #[arg(long)]
    pub trajectory_datum: Option<String>,
    /// The UDP ports the capture's LiDAR datagrams went to, DATA,POSITION (default 2368,8308;
    /// a sensor or a rig's board set to others: the board's `[lidar]` ports).
    #[arg(long, value_name = "DATA,POSITION", value_parser = parse_ports)]
    pub lidar_ports: Option<[u16; 2]>,
}

impl SurveyArgs {
    /// The LiDAR's files and, for a bag, its topic: `--pcap`, else `--bag`.
    fn lidar(&self) -> (crate::pipeline::Files, Option<String>) {
        match (&self.bag, self.pcap.is_empty()) {
            (Some(b), true) => (b.into(), self.lidar_topic.clone()),
            _ => (self.pcap.clone().into(), None),
        }
    }

    /// The bag as the INS, when no other trajectory is given.
    fn ins_bag(&self) -> Option<(crate::pipeline::Files, Option<String>)> {
        let other = !(self.ins.is_empty() && self.sbet.is_empty() && self.posmv.is_empty());
        match &self.bag {
            Some(b) if !other => Some((b.into(), self.ins_topic.clone())),
            _ => None,
        }
    }

    /// The ports as the pipeline takes them.
    fn ports(&self) -> spherecal_hal::velodyne::Ports {
        self.lidar_ports
            .map_or_else(Default::default, |[data, position]| {
                spherecal_hal::velodyne::Ports { data, position }
            })
    }
}

/// Comma-separated finite numbers, exactly `N` of them (`what` names them in the error).
fn parse_n<const N: usize>(s: &str, what: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s:?}: {e}"))?;
    <[f64; N]>::try_from(v.as_slice())
        .ok()
        .filter(|a| a.iter().all(|x| x.is_finite()))
        .ok_or_else(|| format!("{s:?}: expected {what}"))
}

/// A finite number (`nan` and `inf` are refused).
pub(crate) fn finite(s: &str) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|e| format!("{s:?}: {e}"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{s:?}: expected a finite number"))
    }
}

/// A finite number at least 0.
pub(crate) fn non_negative(s: &str) -> Result<f64, String> {
    let v = finite(s)?;
    if v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{s:?}: expected a number >= 0"))
    }
}

/// A finite number above 0.
pub(crate) fn positive(s: &str) -> Result<f64, String> {
    let v = finite(s)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{s:?}: expected a number > 0"))
    }
}

/// A count of at least 1.
pub(crate) fn count(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        Ok(_) => Err(format!("{s:?}: expected at least 1")),
        Err(e) => Err(format!("{s:?}: {e}")),
    }
}

/// `r,p,h,x,y,z`.
fn parse6(s: &str) -> Result<[f64; 6], String> {
    parse_n(s, "six finite numbers r,p,h,x,y,z")
}

/// `a,b,c`.
fn parse3(s: &str) -> Result<[f64; 3], String> {
    parse_n(s, "three finite numbers a,b,c")
}

/// A LiDAR model by name (`--model`).
pub(crate) fn parse_model(s: &str) -> Result<spherecal::velodyne::Model, String> {
    spherecal::velodyne::Model::parse(s).ok_or_else(|| {
        format!(
            "unknown LiDAR model {s:?}: expected {}",
            crate::decode::model_keys()
        )
    })
}

/// A simulated scanner's key (a Velodyne's, `xt16`, `xt32`).
pub(crate) fn parse_scanner(s: &str) -> Result<spherecal::sim::Scanner, String> {
    spherecal::sim::Scanner::parse(s).ok_or_else(|| {
        let keys: Vec<&str> = spherecal::sim::Scanner::ALL
            .iter()
            .map(|m| m.key())
            .collect();
        format!("unknown LiDAR model {s:?}: expected {}", keys.join(", "))
    })
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

/// The CSV file `--csv` names, buffered, or the exit code of a file that cannot be created.
fn create_csv(cmd: &str, csv: Option<&PathBuf>) -> Result<Option<crate::output::Staged>, ExitCode> {
    csv.map(|p| crate::output::Staged::create(p))
        .transpose()
        .map_err(|e| fail(cmd, e))
}

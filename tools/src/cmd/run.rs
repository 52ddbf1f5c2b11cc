//! `spherecal run --board FILE ...`: the rig.

use super::fail;
use crate::rig::RunOptions;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// The rig: listen to the VLP-16 and the VN-200, log everything raw, show a status line every
/// second, calibrate once every sphere has been seen well enough. Stops on SIGINT/SIGTERM or
/// after --duration, exit 0.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The board file (boards/*.toml).
    #[arg(long)]
    pub board: PathBuf,
    /// Serial device of the INS (overrides the board's).
    #[arg(long)]
    pub serial: Option<String>,
    /// site.toml: without it the rig only acquires and logs.
    #[arg(long)]
    pub site: Option<PathBuf>,
    /// Raw log folder (overrides the board's).
    #[arg(long)]
    pub log_dir: Option<PathBuf>,
    /// Rotate raw log files at this size [MB] (overrides the board's).
    #[arg(long, allow_hyphen_values = true, value_parser = super::positive)]
    pub rotate_mb: Option<f64>,
    /// Stop after this many seconds.
    #[arg(long, allow_hyphen_values = true, value_parser = super::positive)]
    pub duration: Option<f64>,
    /// Write the calibration report here after every solve.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Use VN-200 poses whose InsStatus says not tracking, aligning, GNSS lost or no fix.
    #[arg(long)]
    pub keep_untracked_ins: bool,
    /// Claim a solution although the LiDAR clock is not PPS-locked with a valid RMC (as
    /// `calibrate --allow-unlocked-clock`: the time offset found must explain the stamps).
    #[arg(long)]
    pub allow_unlocked_clock: bool,
    /// Leave the returns between these GPS times out of the calibration (`T0..T1`: GPS
    /// seconds, or seconds of the GPS week); repeatable. Everything is still logged.
    #[arg(long, value_parser = crate::stretches::parse_span)]
    pub exclude: Vec<(f64, f64)>,
    /// Check that the rig can start (board, UDP ports free, serial device, log folder,
    /// console) and exit: 0 when every check passes, 2 otherwise.
    #[arg(long)]
    pub check: bool,
    /// The LiDAR model (vlp16, puck-hires, hdl32e, vlp32c), instead of the board's
    /// `[lidar] model` (default: from the packets' product byte, checked against their period).
    #[arg(long, value_parser = super::parse_model)]
    pub model: Option<spherecal::velodyne::Model>,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    let mut board = match crate::config::board::Board::load(&a.board) {
        Ok(b) => b,
        Err(e) => return fail("run", e),
    };
    if let Some(m) = a.model {
        board.lidar.model = Some(m.key().into());
    }
    let site = match a
        .site
        .map(|s| crate::config::site::Site::load(&s))
        .transpose()
    {
        Ok(s) => s,
        Err(e) => return fail("run", e),
    };
    // The site in the INS's datum, the transformation said once.
    let site = match site
        .map(|s| {
            let to = match &board.ins.datum {
                Some(d) => crate::config::datum::Datum::parse(d)?,
                None => crate::config::datum::Datum::wgs84(),
            };
            let (s, shift) = s.in_datum(&to)?;
            if !shift.is_identity() {
                sayln!("datums: {}", shift.describe());
            }
            Ok::<_, String>(s)
        })
        .transpose()
    {
        Ok(s) => s,
        Err(e) => return fail("run", e),
    };
    if let Some(d) = a.duration.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return fail(
            "run",
            format!("--duration {d}: expected a positive number of seconds"),
        );
    }
    if let Some(r) = a.rotate_mb.filter(|r| !(r.is_finite() && *r > 0.0)) {
        return fail("run", format!("--rotate-mb {r}: expected a positive size"));
    }
    if a.check {
        let opts = RunOptions {
            board,
            serial: a.serial,
            site,
            log_dir: a.log_dir,
            rotate_bytes: None,
            duration: None,
            report: None,
            keep_untracked_ins: false,
            allow_unlocked_clock: false,
            exclude: Vec::new(),
        };
        let results = crate::rig::check::check(&opts);
        for r in &results {
            match r {
                Ok(l) => sayln!("check: ok: {l}"),
                Err(l) => sayln!("check: PROBLEM: {l}"),
            }
        }
        let bad = results.iter().filter(|r| r.is_err()).count();
        return if bad == 0 {
            ExitCode::SUCCESS
        } else {
            fail(
                "run --check",
                format!("{bad} problem(s): the rig cannot start as it is"),
            )
        };
    }
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(e) = signal_hook::flag::register(sig, Arc::clone(&stop)) {
            return fail("run", format!("signal {sig}: {e}"));
        }
    }
    let mut console =
        match spherecal_hal::console::Console::open(&board.console.device, board.console.baud) {
            Ok(c) => c,
            Err(e) => return fail("run", e),
        };
    let opts = RunOptions {
        board,
        serial: a.serial,
        site,
        log_dir: a.log_dir,
        rotate_bytes: a.rotate_mb.map(|m| (m * 1_048_576.0) as u64),
        duration: a.duration.map(std::time::Duration::from_secs_f64),
        report: a.report,
        keep_untracked_ins: a.keep_untracked_ins,
        allow_unlocked_clock: a.allow_unlocked_clock,
        exclude: a.exclude,
    };
    match crate::rig::run(&opts, &mut console, &stop) {
        Ok(s) => {
            // A closed stderr is no reason to fail a finished run.
            let _ = std::io::Write::write_all(
                &mut std::io::stderr(),
                crate::rig::render(&s).as_bytes(),
            );
            ExitCode::SUCCESS
        }
        Err(e) => super::fail("run", e),
    }
}

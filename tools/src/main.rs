//! `spherecal`: the command (README.md; docs/DESIGN.md for the contract). Each subcommand
//! lives in `spherecal_tools::cmd`. Exit codes ([`cmd::EXIT_CODES`]): 0 converged and within
//! its targets; 1 refused; 2 bad input; 3 converged but the sigmas miss the targets; 4 an
//! internal fault.

use clap::{Parser, Subcommand};
use spherecal_tools::cmd;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "spherecal",
    version,
    about = "LiDAR boresight / lever-arm calibration on spheres",
    after_help = cmd::EXIT_CODES
)]
struct Cli {
    #[command(subcommand)]
    cmd: Option<Cmd>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Decode VLP-16 packets from a pcap/pcapng capture; print counts, optionally list points.
    Decode(cmd::decode::Args),
    /// Simulate a survey: write lidar.pcap, ins.bin, site.toml and truth.json.
    Synth(cmd::synth::Args),
    /// Georeference a survey: align the LiDAR with the trajectory, keep the sphere windows.
    Georef(cmd::georef::Args),
    /// Calibrate: georeference, window, solve for boresight and lever arm, report.
    #[command(after_help = cmd::EXIT_CODES)]
    Calibrate(cmd::calibrate::Args),
    /// Calibrate one synthetic survey from many perturbed starts, on all cores.
    Montecarlo(cmd::montecarlo::Args),
    /// Predict the accuracy of a planned calibration survey (each parameter's sigma, what each
    /// pass and sphere brings) and propose the cheapest change that meets the targets.
    Plan(cmd::plan::Args),
    /// Play recorded files back: UDP datagrams to their ports, serial bytes to a device.
    Replay(cmd::replay::Args),
    /// The rig: listen to the VLP-16 and the VN-200, log everything raw, show a status line every
    /// second, calibrate once every sphere has been seen well enough. Stops on SIGINT/SIGTERM
    /// or after --duration, exit 0.
    Run(cmd::run::Args),
    /// Synthesise table1, calibrate from the paper's erroneous start, show the result beside the
    /// truth (what a bare `cargo run --release` does).
    Demo(cmd::demo::Args),
    /// Board files: `board set-mount BOARD --from report.json` writes a calibration into
    /// `[mount]`, keeping the rest of the file.
    Board(cmd::board::Args),
    /// Site files from survey data: `site import SURVEY.csv --crs EPSG:n -o site.toml`.
    Site(cmd::site::Args),
    /// ROS 2 bags: `bag info BAG` lists the topics and what spherecal reads of them.
    Bag(cmd::bag::Args),
    /// Frame a VN-200 serial capture (raw bytes or a spherecal serial log); print counts,
    /// optionally list the binary frames' fields.
    Ins(cmd::ins::Args),
    /// The VN-200 on a serial port: `vn200 configure --board FILE` sets it up for the board
    /// (and checks every write); `vn200 emulate --serial DEV` is one, to try the rig.
    Vn200(cmd::vn200::Args),
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
    match cli.cmd {
        None => cmd::demo::run(cmd::demo::Args::default()),
        Some(Cmd::Demo(a)) => cmd::demo::run(a),
        Some(Cmd::Decode(a)) => cmd::decode::run(a),
        Some(Cmd::Synth(a)) => cmd::synth::run(a),
        Some(Cmd::Georef(a)) => cmd::georef::run(a),
        Some(Cmd::Calibrate(a)) => cmd::calibrate::run(a),
        Some(Cmd::Montecarlo(a)) => cmd::montecarlo::run(a),
        Some(Cmd::Plan(a)) => cmd::plan::run(a),
        Some(Cmd::Replay(a)) => cmd::replay::run(a),
        Some(Cmd::Run(a)) => cmd::run::run(a),
        Some(Cmd::Ins(a)) => cmd::ins::run(a),
        Some(Cmd::Site(a)) => cmd::site::run(a),
        Some(Cmd::Bag(a)) => cmd::bag::run(a),
        Some(Cmd::Board(a)) => cmd::board::run(a),
        Some(Cmd::Vn200(a)) => cmd::vn200::run(a),
    }
}

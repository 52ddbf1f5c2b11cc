//! `spherecal`: the command (README.md; docs/DESIGN.md for the contract; docs/CLI.md for every
//! option, generated from [`spherecal_tools::cli`]). Exit codes ([`cmd::EXIT_CODES`]): 0
//! converged and within its targets; 1 refused; 2 bad input; 3 converged but the sigmas miss
//! the targets; 4 an internal fault.

use clap::Parser;
use spherecal_tools::cli::{Cli, Cmd};
use spherecal_tools::cmd;
use std::process::ExitCode;

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
        Some(Cmd::Reference(a)) => spherecal_tools::cli::reference::run(a),
    }
}

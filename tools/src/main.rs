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
    cmd: Cmd,
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
        Cmd::Decode { file, csv } => decode(file, csv),
    }
}

fn decode(file: PathBuf, csv: Option<PathBuf>) -> ExitCode {
    let mut out = match csv.as_ref().map(std::fs::File::create).transpose() {
        Ok(f) => f.map(|f| BufWriter::with_capacity(1 << 20, f)),
        Err(e) => {
            eprintln!(
                "spherecal decode: {}: cannot create: {e}",
                csv.unwrap_or_default().display()
            );
            return ExitCode::from(2);
        }
    };
    let w = out.as_mut().map(|w| w as &mut dyn std::io::Write);
    match spherecal_tools::decode::decode_file(&file, w) {
        Ok(s) => {
            print!("{}", s.render(&file.display().to_string()));
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

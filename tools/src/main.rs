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
        Cmd::Ins { file, csv } => ins(file, csv),
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
            print!("{}", s.render(&file.display().to_string()));
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

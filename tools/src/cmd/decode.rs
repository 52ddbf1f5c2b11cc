//! `spherecal decode FILE [--csv OUT]`.

use super::{create_csv, fail};
use std::path::PathBuf;
use std::process::ExitCode;

/// Decode Velodyne packets (VLP-16, Puck Hi-Res, HDL-32E, VLP-32C) from a pcap/pcapng
/// capture; print counts, optionally list points.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Capture file (classic pcap or pcapng).
    pub file: PathBuf,
    /// Write one row per returned point to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// The LiDAR model (vlp16, puck-hires, hdl32e, vlp32c); by default the packets' product
    /// byte, checked against their period.
    #[arg(long, value_parser = super::parse_model)]
    pub model: Option<spherecal::velodyne::Model>,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    let mut out = match create_csv("decode", a.csv.as_ref()) {
        Ok(o) => o,
        Err(code) => return code,
    };
    crate::output::remove_partial_on_interrupt();
    let w = out.as_mut().map(|w| w as &mut dyn std::io::Write);
    match crate::decode::decode_file(&a.file, w, a.model) {
        Ok(s) => {
            let path = a.file.display().to_string();
            say!("{}", s.render(&path));
            if let Some(Err(e)) = out.map(crate::output::Staged::commit) {
                return fail("decode", e);
            }
            match (&s.stopped, s.truncation(&path)) {
                (Some(stop), _) => fail("decode", format!("{path}: {stop}")),
                (None, Some(w)) => fail("decode", w),
                (None, None) => ExitCode::SUCCESS,
            }
        }
        Err(e) => fail("decode", e),
    }
}

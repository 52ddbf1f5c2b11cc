//! `spherecal ins FILE [--csv OUT]`.

use super::{create_csv, fail};
use std::path::PathBuf;
use std::process::ExitCode;

/// Frame a VN-200 serial capture (raw bytes or a spherecal serial log); print counts,
/// optionally list the binary frames' fields.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Raw serial bytes, or a timestamped serial log (magic SCSERLOG).
    pub file: PathBuf,
    /// Write one row per valid binary frame to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    let (bytes, _stamps) = match spherecal_hal::serial::read_byte_file(&a.file) {
        Ok(b) => b,
        Err(e) => return fail("ins", format!("{}: {e}", a.file.display())),
    };
    let kind = crate::state::looks_like(&bytes[..bytes.len().min(64)]);
    if kind.contains("pcap") {
        return fail(
            "ins",
            format!(
                "{}: {kind}, not a VN-200 byte stream: `spherecal decode` reads a LiDAR capture, `--posmv` a POS MV's captured datagrams",
                a.file.display()
            ),
        );
    }
    let mut out = match create_csv("ins", a.csv.as_ref()) {
        Ok(o) => o,
        Err(code) => return code,
    };
    let w = out.as_mut().map(|w| w as &mut dyn std::io::Write);
    match crate::ins::frame_bytes(&bytes, w) {
        Ok(s) => {
            say!("{}", s.render(&a.file.display().to_string()));
            let st = &s.stats;
            if st.frames == 0 && st.crc_failures > 0 {
                return fail(
                    "ins",
                    format!(
                        "{}: {} frame headers, every one failing its CRC: not a VN-200 binary stream (another baud rate, another device, or corrupted bytes)",
                        a.file.display(),
                        st.crc_failures
                    ),
                );
            }
            if st.frames + st.ascii + st.nmea == 0 {
                // Nothing a VN-200 sends: say what the file looks like instead.
                let head = &bytes[..bytes.len().min(64)];
                return fail(
                    "ins",
                    format!(
                        "{}: no VN-200 binary frame or sentence in {} bytes: it looks like {}",
                        a.file.display(),
                        bytes.len(),
                        crate::state::looks_like(head)
                    ),
                );
            }
            if let Some(Err(e)) = out.map(crate::output::Staged::commit) {
                return fail("ins", e);
            }
            ExitCode::SUCCESS
        }
        Err(e) => fail("ins", format!("{}: writing CSV: {e}", a.file.display())),
    }
}

//! `spherecal board set-mount BOARD --from REPORT.json`.

use super::print_or_fail;
use crate::config::board::Board;
use crate::config::MountDegM;
use crate::report::solved::Solved;
use std::path::PathBuf;
use std::process::ExitCode;

/// Board files.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

/// What to do.
#[derive(clap::Subcommand, Debug)]
pub enum What {
    /// Write a calibration's boresight and lever arm into the board's `[mount]`, keeping the
    /// rest of the file and its comments.
    SetMount(SetMountArgs),
}

/// `board set-mount`.
#[derive(clap::Args, Debug)]
pub struct SetMountArgs {
    /// The board file (rewritten in place).
    pub board: PathBuf,
    /// The calibration's report.json.
    #[arg(long)]
    pub from: PathBuf,
    /// Write it even though the calibration was refused.
    #[arg(long)]
    pub even_if_refused: bool,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    match a.what {
        What::SetMount(a) => print_or_fail("board set-mount", set_mount(&a)),
    }
}

fn set_mount(a: &SetMountArgs) -> Result<String, crate::Error> {
    let r = Solved::load(&a.from)?;
    if !r.converged && !a.even_if_refused {
        return Err(format!(
            "{}: the calibration was refused ({}); give --even-if-refused to write it anyway",
            a.from.display(),
            r.reason.as_deref().unwrap_or("no reason recorded")
        )
        .into());
    }
    let old = Board::load(&a.board)?.mount;
    let d = r.deg_m;
    let m = MountDegM {
        boresight_deg: [d[0], d[1], d[2]],
        lever_arm_m: [d[3], d[4], d[5]],
    };
    let text =
        std::fs::read_to_string(&a.board).map_err(|e| format!("{}: {e}", a.board.display()))?;
    let out = Board::with_mount(&text, &m, &provenance(&a.from, &r))
        .map_err(|e| format!("{}: {e}", a.board.display()))?;
    crate::output::write(&a.board, out.as_bytes())?;
    Ok(format!(
        "{}: [mount] boresight_deg {:?} -> {:?}, lever_arm_m {:?} -> {:?} (from {}{})\n",
        a.board.display(),
        old.boresight_deg,
        m.boresight_deg,
        old.lever_arm_m,
        m.lever_arm_m,
        a.from.display(),
        if r.converged {
            ""
        } else {
            ", a REFUSED calibration"
        }
    ))
}

/// The comment lines kept with the mount: where it came from and when, how well it is known,
/// and the time offset between the clocks found with it.
fn provenance(from: &std::path::Path, r: &Solved) -> Vec<String> {
    let now = spherecal::time::UtcDateTime::from_unix_ns(spherecal_hal::clock::wall().0);
    let sig = |k: usize, unit: &str, scale: f64, prec: usize| {
        let v = r.sigma[k] * scale;
        if v.is_finite() {
            format!("{:.prec$} {unit}", v)
        } else {
            "-".into()
        }
    };
    let source = std::fs::canonicalize(from).unwrap_or_else(|_| from.to_path_buf());
    vec![
        format!(
            "from {} ({}), written {:04}-{:02}-{:02} {:02}:{:02} UTC{}",
            source.display(),
            if r.version.is_empty() {
                "spherecal"
            } else {
                &r.version
            },
            now.year,
            now.month,
            now.day,
            now.hour,
            now.minute,
            if r.converged {
                ""
            } else {
                ": a REFUSED calibration, written with --even-if-refused"
            }
        ),
        format!(
            "1-sigma: roll {}, pitch {}, heading {}, x {}, y {}, z {}",
            sig(0, "deg", 1.0, 4),
            sig(1, "deg", 1.0, 4),
            sig(2, "deg", 1.0, 4),
            sig(3, "mm", 1e3, 2),
            sig(4, "mm", 1e3, 2),
            sig(5, "mm", 1e3, 2)
        ),
        format!(
            "time offset (INS time = LiDAR time + this): {:+.6} s{}",
            r.time_offset_s,
            if r.time_offset_sigma_s.is_finite() && r.time_offset_sigma_s > 0.0 {
                format!(" +- {:.6} s", r.time_offset_sigma_s)
            } else {
                String::new()
            }
        ),
    ]
}

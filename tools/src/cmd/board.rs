//! `spherecal board set-mount BOARD --from REPORT.json`.

use super::print_or_fail;
use crate::config::board::Board;
use crate::config::MountDegM;
use crate::report::Report;
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

fn set_mount(a: &SetMountArgs) -> Result<String, String> {
    let r = Report::load(&a.from)?;
    if !r.converged && !a.even_if_refused {
        return Err(format!(
            "{}: the calibration was refused ({}); give --even-if-refused to write it anyway",
            a.from.display(),
            r.reason.as_deref().unwrap_or("no reason recorded")
        ));
    }
    let old = Board::load(&a.board)?.mount;
    let d = r.deg_m();
    let m = MountDegM {
        boresight_deg: [d[0], d[1], d[2]],
        lever_arm_m: [d[3], d[4], d[5]],
    };
    let text =
        std::fs::read_to_string(&a.board).map_err(|e| format!("{}: {e}", a.board.display()))?;
    let out = Board::with_mount(&text, &m).map_err(|e| format!("{}: {e}", a.board.display()))?;
    let tmp = a.board.with_extension("toml.new");
    std::fs::write(&tmp, out).map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, &a.board).map_err(|e| format!("{}: {e}", a.board.display()))?;
    Ok(format!(
        "{}: [mount] boresight_deg {:?} -> {:?}, lever_arm_m {:?} -> {:?} (from {})\n",
        a.board.display(),
        old.boresight_deg,
        m.boresight_deg,
        old.lever_arm_m,
        m.lever_arm_m,
        a.from.display()
    ))
}

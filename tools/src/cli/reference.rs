//! `spherecal reference [--markdown FILE] [--man DIR] [--completions SHELL]`: the command's own
//! reference, generated from its clap definitions ([`super`]) so that it cannot drift:
//! docs/CLI.md (checked against the definitions by `cli::tests`), a man page per subcommand
//! (clap_mangen), the shell completions (clap_complete).

use crate::cmd::fail;
use clap::CommandFactory;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

/// Write the reference.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Write the Markdown reference of every subcommand here (the repository's docs/CLI.md).
    #[arg(long)]
    pub markdown: Option<PathBuf>,
    /// Write a man page per subcommand into this folder (spherecal.1, spherecal-calibrate.1,
    /// ...; `man -l spherecal-calibrate.1`).
    #[arg(long)]
    pub man: Option<PathBuf>,
    /// Print the completion script for this shell (e.g. `spherecal reference --completions
    /// bash > ~/.local/share/bash-completion/completions/spherecal`).
    #[arg(long, value_enum)]
    pub completions: Option<clap_complete::Shell>,
}

/// Run it: exit 0, or 2 when a file cannot be written or nothing was asked.
pub fn run(a: Args) -> ExitCode {
    if a.markdown.is_none() && a.man.is_none() && a.completions.is_none() {
        return fail(
            "reference",
            "give --markdown FILE, --man DIR or --completions SHELL",
        );
    }
    if let Some(p) = &a.markdown {
        if let Err(e) = crate::report::write_atomically(p, crate::cli::markdown().as_bytes()) {
            return fail("reference", e);
        }
        let _ = writeln!(std::io::stdout(), "wrote {}", p.display());
    }
    if let Some(d) = &a.man {
        let written = std::fs::create_dir_all(d)
            .and_then(|()| clap_mangen::generate_to(crate::cli::Cli::command(), d));
        if let Err(e) = written {
            return fail("reference", format!("--man {}: {e}", d.display()));
        }
        let _ = writeln!(
            std::io::stdout(),
            "wrote the man pages into {}",
            d.display()
        );
    }
    if let Some(shell) = a.completions {
        let mut cmd = crate::cli::Cli::command();
        clap_complete::generate(shell, &mut cmd, "spherecal", &mut std::io::stdout());
    }
    ExitCode::SUCCESS
}

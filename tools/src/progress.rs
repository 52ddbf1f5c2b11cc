//! Progress bars on standard error for the commands that take more than a few seconds
//! (indicatif; drawn only when standard error is a terminal, so logs and pipes stay clean).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A bar of `len` steps named `what`.
pub fn bar(len: u64, what: &str) -> ProgressBar {
    let b = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) =
        ProgressStyle::with_template("{prefix} [{bar:40}] {pos}/{len} ({elapsed}, {eta} left)")
    {
        b.set_style(style.progress_chars("#>-"));
    }
    b.set_prefix(what.to_string());
    b
}

/// A counter without a known end (records of a capture being read).
pub fn counter(what: &str) -> ProgressBar {
    let b = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    if let Ok(style) =
        ProgressStyle::with_template("{prefix} {spinner} {pos} ({per_sec}, {elapsed})")
    {
        b.set_style(style);
    }
    b.set_prefix(what.to_string());
    b
}

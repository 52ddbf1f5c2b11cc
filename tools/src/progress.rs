//! Progress bars on standard error for the commands that take more than a few seconds
//! (indicatif; drawn only when standard error is a terminal, so logs and pipes stay clean).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use spherecal::calib::solve::{Observe, Round};
use spherecal::calib::Termination;

/// A bar of `len` steps named `what`.
pub fn bar(len: u64, what: &str) -> ProgressBar {
    let b = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(
        "{prefix} [{bar:40}] {pos}/{len} ({elapsed}, {eta} left) {msg}",
    ) {
        b.set_style(style.progress_chars("#>-"));
    }
    b.set_prefix(what.to_string());
    b
}

/// A counter without a known end (records of a capture being read).
pub fn counter(what: &str) -> ProgressBar {
    let b = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    if let Ok(style) =
        ProgressStyle::with_template("{prefix} {spinner} {pos} ({per_sec}, {elapsed}) {msg}")
    {
        b.set_style(style);
    }
    b.set_prefix(what.to_string());
    b
}

/// A spinner with a message and no count (a solve's rounds).
pub fn spinner(what: &str) -> ProgressBar {
    let b = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template("{prefix} {spinner} {msg} ({elapsed})") {
        b.set_style(style);
    }
    b.set_prefix(what.to_string());
    b
}

/// The solver's rounds as a bar's message (the core's [`Observe`] hook): `round N: K returns
/// kept, shell T mm`, then how the rounds ended.
pub struct Rounds<'a>(pub &'a ProgressBar);

impl Observe for Rounds<'_> {
    fn round(&mut self, n: usize, r: &Round) {
        self.0.set_message(round_words(n, r));
    }
    fn ended(&mut self, how: Termination, rounds: usize) {
        self.0
            .set_message(format!("{rounds} rounds, ended: {}", how.words()));
    }
}

/// One round in words (the bars' message, the rig's status).
pub fn round_words(n: usize, r: &Round) -> String {
    format!(
        "round {n}: {} returns kept, shell {:.1} mm",
        r.kept,
        r.tau * 1e3
    )
}

//! `spherecal montecarlo --scenario NAME|FILE ...`.

use super::{claimed, fail};
use std::path::PathBuf;
use std::process::ExitCode;

/// Calibrate one synthetic survey from many perturbed starts, on all cores.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A built-in scenario or a scenario file.
    #[arg(long)]
    pub scenario: String,
    /// Number of starts.
    #[arg(long, default_value_t = 200, allow_hyphen_values = true, value_parser = super::count)]
    pub trials: usize,
    /// Starts within +- this of the true angles [deg].
    #[arg(long, default_value_t = 5.0, allow_hyphen_values = true, value_parser = super::non_negative)]
    pub angle_noise_deg: f64,
    /// Starts within +- this of the true lever arm [m].
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true, value_parser = super::non_negative)]
    pub lever_noise_m: f64,
    /// Seed of the starts.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the JSON report here.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// Run it: exit 1 unless every trial is within the bounds.
pub fn run(a: Args) -> ExitCode {
    let s = match crate::config::scenario::Scenario::load(&a.scenario) {
        Ok(s) => s,
        Err(e) => return fail("montecarlo", e),
    };
    if let Some(p) = &a.report {
        if let Err(e) = crate::survey::check_output("--report", p) {
            return fail("montecarlo", e);
        }
    }
    crate::output::remove_partial_on_interrupt();
    let r = match crate::montecarlo::montecarlo(
        &s,
        None,
        a.trials,
        a.angle_noise_deg,
        a.lever_noise_m,
        a.seed,
        true,
    ) {
        Ok(r) => r,
        Err(e) => return fail("montecarlo", e),
    };
    say!("{}", crate::report::render_montecarlo(&r));
    if let Some(p) = a.report {
        if let Err(e) = crate::report::write_json_atomically(&p, &r) {
            return fail("montecarlo", e);
        }
    }
    claimed(r.fraction_within == 1.0, true)
}

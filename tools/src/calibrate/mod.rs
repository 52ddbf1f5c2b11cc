//! `spherecal calibrate`: the pipeline, then the solver, then the report (JSON, a human
//! summary, optionally the calibrated cloud as LAS and the residual plots as SVG).

use crate::pipeline::{targets, Inputs, RunStats};
use crate::report::{InputsReport, Report};
use spherecal::align::window::{Observation, Target};
use spherecal::calib::solve::Solution;
use spherecal::georef::Params;
use std::fmt::Write as _;

mod collect;
mod collections;
mod search;

pub use collect::{collect, collect_bounded, STORE_CAP};
use collections::Collections;
pub use search::{
    best_candidate, search_half_width, search_time_offset, DEFAULT_SEARCH_S, SEARCH_STEP_S,
};

/// A calibration's run counts, windowed returns (with their verdicts), solution and report.
pub type Calibrated = (RunStats, Vec<Vec<Observation>>, Solution, Report);

/// The `--returns` CSV header.
pub const RETURNS_HEADER: &str =
    "sphere,packet,block,channel,time_gps_s,laser,range_m,x_m,y_m,z_m,residual_m,verdict";

/// How `calibrate` treats the clocks and the INS.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockOptions {
    /// Estimate the time offset between the clocks (else hold `start`).
    pub estimate: bool,
    /// The time offset to start from [s] (INS time = LiDAR time + this); `None`: 0, or what
    /// the LiDAR's RMC says when its clock is not PPS-locked.
    pub start: Option<f64>,
    /// Claim a solution although the LiDAR clock is not PPS-locked (when the time offset
    /// found explains its disagreement with the RMC).
    pub allow_unlocked: bool,
    /// Use VN-200 poses whose InsStatus says not tracking.
    pub keep_untracked_ins: bool,
    /// Search the time offset over +- this [s] around the start (`None`: 2 s when the LiDAR
    /// clock is not PPS-locked with a valid RMC, no search otherwise).
    pub search: Option<f64>,
}

impl Default for ClockOptions {
    fn default() -> Self {
        Self {
            estimate: true,
            start: None,
            allow_unlocked: false,
            keep_untracked_ins: false,
            search: None,
        }
    }
}

/// Write every windowed return with its verdict (`--returns`): sphere id, where it is in the
/// capture, its time, laser and range, its place with the solution `b` (site NED), its signed
/// distance from the sphere's surface, and the extraction's verdict.
pub fn write_returns(
    path: &std::path::Path,
    targets: &[Target],
    ids: &[String],
    obs: &[Vec<Observation>],
    b: &Params,
) -> Result<(), crate::Error> {
    use std::io::Write as _;
    let err = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut w = crate::output::Staged::create(path)?;
    writeln!(w, "{}", RETURNS_HEADER).map_err(err)?;
    let mount = spherecal::georef::Mount::from_params(b);
    let mut line = String::new();
    for ((t, id), v) in targets.iter().zip(ids).zip(obs) {
        for o in v {
            let x = o.georef(&mount);
            let e = (x - t.center).norm() - t.radius;
            line.clear();
            let _ = writeln!(
                line,
                "{id},{},{},{},{:.9},{},{:.3},{:.5},{:.5},{:.5},{:.5},{}",
                o.packet,
                o.block,
                o.channel,
                o.time.as_secs_f64(),
                o.laser,
                o.range,
                x.x,
                x.y,
                x.z,
                e,
                spherecal::calib::extract::ReturnClass::from_u8(o.work.verdict).name()
            );
            w.write_all(line.as_bytes()).map_err(err)?;
        }
    }
    w.commit()
}

/// When the collections at the time offsets found do not settle (the last of five, solved at
/// the offset the one before found, still moves it by many of its own sigmas: the returns fix
/// no one offset, and whichever the last collection lands on would be claimed with a sigma
/// that does not hold; drone-noisy seed 1085's trial went 0 -> +18.9 -> +2.4 -> +5.4 -> +3.5
/// -> +19.1 ms, each +- 2-3 ms), the refusal in words. `found`: each collection's offset and
/// sigma [s].
fn unsettled_offset(found: &[(f64, f64)]) -> Option<String> {
    let last = found.len().checked_sub(1)?;
    let (lo, hi) = found
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, f| {
            (a.0.min(f.0), a.1.max(f.0))
        });
    let sigma = found[last].1;
    let moved = (found[last].0 - found[last.checked_sub(1)?].0).abs();
    (sigma.is_finite() && sigma > 0.0 && moved > 3.0 * sigma && hi - lo > 3.0 * sigma).then(|| {
        let list: Vec<String> = found.iter().map(|f| format!("{:+.1}", f.0 * 1e3)).collect();
        format!(
            "the time offset does not settle: solved again at each offset found, the collections give {} ms (each +- {:.1} ms): the returns fix no one offset; hold it (--time-offset S --hold-time-offset) if the clocks are known to agree, or survey with turns and speed changes",
            list.join(", "),
            sigma * 1e3
        )
    })
}

/// The whole calibration of the files of `inp` from `b0` [rad, m]: collect the windows,
/// solve; with the time offset estimated, collect them again at the offset found until it
/// moves by less than 0.5 ms (the solver's estimate is first-order in the offset the poses were
/// taken at; five collections at most, within 2 s of the start). A LiDAR clock that is not
/// PPS-locked with valid RMCs starts from the offset its RMCs give, and is searched around it
/// (`clock.search`, default 2 s: a coarse 1-D search, see [`search_time_offset`]); its solution
/// is refused unless `clock.allow_unlocked` and the offset found explains the RMC
/// disagreement. The report records the inputs' state. `collected` is called after each
/// collection (the solve that follows uses one core: the caller's work for the other).
pub fn calibrate(
    inp: &mut Inputs,
    targets: &[Target],
    ids: &[String],
    b0: &Params,
    clock: ClockOptions,
    collected: &mut dyn FnMut(),
) -> Result<Calibrated, crate::Error> {
    let mut c = Collections::new(inp, targets, ids, b0, clock, collected)?;
    let (start, first, searched) = c.first()?;
    let ((stats, obs, sol, mut rep), unsettled) = c.settle(start, first)?;
    if let (true, Some(why)) = (rep.converged, unsettled) {
        rep.converged = false;
        rep.reason = Some(why);
    }
    c.spinner.finish_and_clear();
    rep.time_offset_search = searched;
    rep.effort = Some(c.effort());
    rep.start.insert("time_offset".to_string(), start);
    rep.batch_overflow = stats.align.batch_overflow;
    let mut inputs = InputsReport::of(c.inp, &stats);
    inputs.accuracy = c.used_accuracy.take();
    rep.inputs = Some(inputs);
    c.explain(&mut rep, &sol, &obs, &stats);
    Ok((stats, obs, sol, rep))
}

/// Site targets and ids.
pub fn site_targets(inp: &Inputs) -> (Vec<Target>, Vec<String>) {
    let (_, t) = targets(&inp.site);
    (t, inp.site.sphere.iter().map(|s| s.id.clone()).collect())
}

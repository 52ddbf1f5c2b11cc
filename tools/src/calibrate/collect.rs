//! One collection: the pipeline over the files into each sphere's windowed returns, its memory
//! bounded in the survey's length.

use crate::pipeline::{run, BatchMsg, Inputs, RunStats};
use spherecal::align::window::{Observation, Target};
use spherecal::georef::Params;

/// Windowed returns a collection holds before it tries to let go of what cannot be a sphere's
/// ([`collect_bounded`]): ~50 MB of observations.
pub const STORE_CAP: usize = 300_000;

/// Run the pipeline and collect the windowed observations per sphere, in memory bounded in the
/// survey's length (as the rig's store is): once the store holds `cap` returns (`calibrate`:
/// [`STORE_CAP`]; then twice that, ...), a solve from `b0` on them is tried; when it converges,
/// the returns farther than [`crate::session::KEEP_NEAR_M`] from every sphere's surface under
/// it are let go, and so are those that arrive after. A survey that never reaches the cap is
/// collected whole, as [`collect`] does. The stats count what was let go
/// ([`RunStats::pruned`]).
pub fn collect_bounded(
    inp: &Inputs,
    targets: &[Target],
    b0: &Params,
    settings: &spherecal::calib::Settings,
    cap: usize,
) -> Result<(RunStats, Vec<Vec<Observation>>), crate::Error> {
    let n = inp.site.sphere.len();
    let (mut stats, (out, pruned)) = run(
        inp,
        None,
        move |rx: crossbeam_channel::Receiver<BatchMsg>| {
            let mut out: Vec<Vec<Observation>> = vec![Vec::new(); n];
            let (mut held, mut next_try, mut pruned) = (0usize, cap.max(1), 0u64);
            let mut near: Option<(spherecal::georef::Mount, f64)> = None;
            for m in rx {
                let (v, t) = (&mut out[m.sphere], &targets[m.sphere]);
                match &near {
                    Some((mount, dt)) => {
                        let before = v.len();
                        v.extend(
                            m.obs
                                .iter()
                                .filter(|o| crate::session::near(o, t, mount, *dt)),
                        );
                        pruned += (m.obs.len() - (v.len() - before)) as u64;
                        held += v.len() - before;
                    }
                    None => {
                        held += m.obs.len();
                        v.extend(m.obs);
                    }
                }
                if near.is_none() && held >= next_try {
                    next_try = next_try.saturating_mul(2);
                    near = trial_mount(&mut out, targets, b0, settings);
                    if let Some((mount, dt)) = &near {
                        for (v, t) in out.iter_mut().zip(targets) {
                            let before = v.len();
                            v.retain(|o| crate::session::near(o, t, mount, *dt));
                            pruned += (before - v.len()) as u64;
                            v.shrink_to_fit();
                        }
                        held = out.iter().map(Vec::len).sum();
                    }
                }
            }
            (out, pruned)
        },
    )?;
    stats.pruned = pruned;
    Ok((stats, out))
}

/// The mounting and time offset a solve from `b0` finds on the store so far, under white
/// navigation errors; `None` unless it converged and was claimed. In place: every solve puts
/// the store in time order and marks its returns afresh (`calib::solve`'s preparation).
fn trial_mount(
    obs: &mut [Vec<Observation>],
    targets: &[Target],
    b0: &Params,
    settings: &spherecal::calib::Settings,
) -> Option<(spherecal::georef::Mount, f64)> {
    let s = spherecal::calib::Settings {
        nav: None,
        ..*settings
    };
    let mut slices: Vec<&mut [Observation]> = obs.iter_mut().map(|v| v.as_mut_slice()).collect();
    let mut scratch = crate::session::scratch::Scratch::for_settings(&s);
    let sol =
        spherecal::calib::solve::solve(targets, &mut slices, b0, &s, &mut scratch.workspace());
    (sol.refusal.is_none() && sol.lm.is_some_and(|l| l.converged)).then(|| (sol.b.mount(), sol.dt))
}

/// Run the pipeline and collect the windowed observations per sphere.
pub fn collect(inp: &Inputs) -> Result<(RunStats, Vec<Vec<Observation>>), crate::Error> {
    let n = inp.site.sphere.len();
    run(
        inp,
        None,
        move |rx: crossbeam_channel::Receiver<BatchMsg>| {
            let mut out = vec![Vec::new(); n];
            for m in rx {
                out[m.sphere].extend(m.obs);
            }
            out
        },
    )
}

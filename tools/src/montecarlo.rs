//! `spherecal montecarlo`: synthesise once, then calibrate from N starts drawn uniformly within
//! +-A deg and +-L m of the truth, on all cores.

use crate::calibrate::collect;
use crate::config::scenario::Scenario;
use crate::pipeline::{targets, Inputs, InsInput};
use crate::report::{McReport, Trial};
use spherecal::calib::solve::solve_watched;
use spherecal::georef::P;
use spherecal::sim::Rng;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// Run a Monte Carlo on `files`, a synthesis of `scenario` already made (`site.toml`,
/// `lidar.pcap`, `ins.bin`), or without them on one made for it in a temporary folder.
pub fn montecarlo(
    scenario: &Scenario,
    files: Option<&std::path::Path>,
    trials: usize,
    angle_deg: f64,
    lever_m: f64,
    seed: u64,
    progress: bool,
) -> Result<McReport, crate::Error> {
    let Some(dir) = files else {
        let dir =
            std::env::temp_dir().join(format!("spherecal-mc-{}-{}", std::process::id(), seed));
        crate::synth::synth(scenario, &dir)?;
        let r = montecarlo(
            scenario,
            Some(&dir),
            trials,
            angle_deg,
            lever_m,
            seed,
            progress,
        );
        let _ = std::fs::remove_dir_all(&dir);
        return r;
    };
    let site = crate::config::site::Site::load(&dir.join("site.toml"))?;
    let inp = Inputs::apriori(
        dir.join("lidar.pcap").into(),
        InsInput::Vn200(dir.join("ins.bin").into()),
        site.clone(),
    );
    let (_, obs) = collect(&inp)?;
    let (_, tg) = targets(&site);
    // As `calibrate` would (the mounting held to the clock: the simulated one has PPS).
    let settings = crate::session::settings_for(
        &site,
        scenario
            .scanner()
            .map_or_else(Default::default, crate::config::lidar::Lidar::of_scanner),
        false,
        site.apriori.window_margin_m,
    );
    let t = &scenario.mount.truth;
    let truth = t.deg_m().0;
    let mut rng = Rng::new(seed);
    let starts: Vec<[f64; P]> = (0..trials)
        .map(|_| {
            let mut s = truth;
            for (i, v) in s.iter_mut().enumerate() {
                *v += if i < 3 {
                    rng.range(-angle_deg, angle_deg)
                } else {
                    rng.range(-lever_m, lever_m)
                };
            }
            s
        })
        .collect();
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Trial>>> = Mutex::new(vec![None; trials]);
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let bar = if progress {
        crate::progress::bar(trials as u64, "trials")
    } else {
        indicatif::ProgressBar::hidden()
    };
    std::thread::scope(|sc| {
        for _ in 0..threads {
            sc.spawn(|| {
                let mut work = obs.clone();
                let mut scratch = crate::session::scratch::Scratch::default();
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    if k >= trials {
                        break;
                    }
                    let st = starts[k];
                    let b0 = spherecal::georef::DegM(st).params();
                    for (w, o) in work.iter_mut().zip(&obs) {
                        w.copy_from_slice(o);
                    }
                    let mut slices: Vec<&mut [spherecal::align::window::Observation]> =
                        work.iter_mut().map(|v| v.as_mut_slice()).collect();
                    let t0 = std::time::Instant::now();
                    let sol = solve_watched(
                        &tg,
                        &mut slices,
                        &b0,
                        &settings,
                        &mut scratch.workspace(),
                        &mut crate::progress::Rounds(&bar),
                    );
                    let ms = t0.elapsed().as_secs_f64() * 1e3;
                    let solution = sol.b.deg_m().0;
                    let mut error = [0.0; P];
                    for i in 0..P {
                        error[i] = solution[i] - truth[i];
                    }
                    let within = error.iter().all(|e| e.abs() < 1e-3);
                    if let Ok(mut r) = results.lock() {
                        r[k] = Some(Trial {
                            start: st,
                            solution,
                            error,
                            converged: sol.refusal.is_none(),
                            within,
                            ms,
                        });
                    }
                    done.fetch_add(1, Ordering::Relaxed);
                    bar.inc(1);
                }
            });
        }
    });
    bar.finish_and_clear();
    let runs: Vec<Trial> = results
        .into_inner()
        .map_err(|_| crate::Error::internal("a trial thread panicked"))?
        .into_iter()
        .flatten()
        .collect();
    let n = runs.len().max(1) as f64;
    let mut worst = [0.0f64; P];
    for r in &runs {
        for (w, e) in worst.iter_mut().zip(&r.error) {
            *w = w.max(e.abs());
        }
    }
    Ok(McReport {
        scenario: scenario.name.clone(),
        trials,
        angle_noise_deg: angle_deg,
        lever_noise_m: lever_m,
        seed,
        fraction_within: runs.iter().filter(|r| r.within).count() as f64 / n,
        fraction_converged: runs.iter().filter(|r| r.converged).count() as f64 / n,
        worst_error: worst,
        ms_per_trial: runs.iter().map(|r| r.ms).sum::<f64>() / n,
        runs,
    })
}

/// The data packets of a traced survey that hold a windowed return, for trials that simulate
/// only those ([`crate::synth::TraceCache::keep_only`]): `s` synthesised once in full and
/// collected with windows `extra` [m] wider than the site's (range and INS noise move a
/// return by centimetres, not by `extra`), each packet marked with its `neighbours` either
/// side. Skipping the rest changes nothing a calibration sees: it only reads the windows.
/// Returns the mask and how many packets it keeps.
pub fn windowed_packets(
    s: &Scenario,
    cache: &crate::synth::TraceCache,
    extra: f64,
    neighbours: usize,
) -> Result<(Vec<bool>, usize), crate::Error> {
    let dir = std::env::temp_dir().join(format!(
        "spherecal-windowed-{}-{}-{}",
        std::process::id(),
        s.name,
        s.seed
    ));
    let (_, written) = crate::synth::synth_traced_written(s, &dir, cache)?;
    let site = crate::config::site::Site::load(&dir.join("site.toml"))?;
    let mut inp = Inputs::apriori(
        dir.join("lidar.pcap").into(),
        InsInput::Vn200(dir.join("ins.bin").into()),
        site,
    );
    inp.margin += extra;
    let collected = collect(&inp);
    let _ = std::fs::remove_dir_all(&dir);
    let (_, obs) = collected?;
    let mut keep = vec![false; cache.packets()];
    for o in obs.iter().flatten() {
        let Some(&k) = written.get(o.packet as usize) else {
            return Err(format!(
                "windowed return in data packet {} of {} written",
                o.packet,
                written.len()
            )
            .into());
        };
        let k = k as usize;
        let lo = k.saturating_sub(neighbours);
        let hi = (k + neighbours).min(keep.len().saturating_sub(1));
        for m in keep.iter_mut().take(hi + 1).skip(lo) {
            *m = true;
        }
    }
    let n = keep.iter().filter(|&&m| m).count();
    Ok((keep, n))
}

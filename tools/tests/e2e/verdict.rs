//! The live verdict on synthetic table1-noisy (the quay, 3 cm range noise, VN-200-like INS
//! noise), calibrating the data as they would have arrived, with targets of 0.045 deg and
//! 5 mm: after the first (northbound) pass the verdict is `collecting` (ill-conditioned, no
//! southbound pass); after the second, one parameter short; it turns `ready` only once the
//! third pass adds the longer ranges that pin pitch down.

use crate::common;

use spherecal::calib::Settings;
use spherecal_tools::calibrate::{collect, site_targets};
use spherecal_tools::config::goal::Targets;
use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::pipeline::{Inputs, InsInput};
use spherecal_tools::session::solve_report;
use spherecal_tools::verdict::{assess, coverage, data_info, predicted_sigma};

/// Scenario `s` synthesised into `dir`: the inputs of its capture and VN-200 stream with its
/// site.
fn synthesised(s: &Scenario, dir: &std::path::Path) -> Inputs {
    spherecal_tools::synth::synth(s, dir).unwrap();
    let site = spherecal_tools::config::site::Site::load(&dir.join("site.toml")).unwrap();
    Inputs::apriori(
        dir.join("lidar.pcap").into(),
        InsInput::Vn200(dir.join("ins.bin").into()),
        site,
    )
}

#[test]
fn verdict_turns_ready_with_the_passes_that_make_it() {
    let dir = common::tmp("verdict", "table1-noisy");
    let s = Scenario::load("table1-noisy").unwrap();
    let inp = synthesised(&s, &dir);
    let (targets, ids) = site_targets(&inp);
    let (_, all) = collect(&inp).unwrap();
    let t0 = s.start().0;
    let b0 = inp.site.apriori_deg_m().params();
    let noise = inp.site.noise.unwrap_or_default();
    let settings = Settings {
        range_noise: noise.range_m,
        attitude_noise: noise.attitude_deg.to_radians(),
        position_noise: noise.position_m,
        ..Default::default()
    };
    let goal = Targets {
        target_sigma_deg: Some(0.045),
        target_sigma_m: Some(0.005),
    };
    // The data so far after pass 1 (0-20 s), pass 2 (to 38 s), pass 3 (to 50.5 s), all.
    let mut verdicts = Vec::new();
    for until in [21.0, 39.0, 51.5, 70.0] {
        let mut obs: Vec<Vec<_>> = all
            .iter()
            .map(|v| {
                v.iter()
                    .filter(|o| ((o.time.0 - t0) as f64) * 1e-9 < until)
                    .copied()
                    .collect()
            })
            .collect();
        let (sol, rep) = solve_report(&targets, &ids, &mut obs, &b0, &settings);
        let cov = coverage(&ids, &obs, &sol);
        // The prediction with the simulation's own noise (the site states none: the solver's
        // defaults, 0.05 deg and 3 cm, are conservative for this INS).
        let sim_noise = Settings {
            range_noise: s.lidar.range_sigma_m,
            attitude_noise: s.ins.att_sigma_deg.to_radians(),
            position_noise: s.ins.pos_sigma_m,
            ..settings
        };
        let predicted = predicted_sigma(&targets, &obs, &sol, &sim_noise, s.ins.rate_hz);
        let v = assess(&rep, &cov, goal.goal().as_ref(), Some(&predicted), None);
        // Once claimed, the prediction from the kept returns' geometry agrees with the
        // solution's own (cluster-robust) sigma: the noise model is the site's, the data's
        // scatter the simulator's.
        if rep.converged {
            let reported = rep.sigma.deg_m();
            for i in 0..6 {
                let r = predicted[i] / reported[i];
                eprintln!(
                    "until {until} s: {} predicted / reported {r:.2}",
                    spherecal::georef::NAMES[i]
                );
                assert!(
                    (0.7..1.4).contains(&r),
                    "until {until} s: parameter {i}: {r}"
                );
            }
        }
        eprintln!(
            "until {until} s: ready {} sigma {:?}: {:?}",
            v.ready,
            rep.sigma.deg_m(),
            v.missing
        );
        verdicts.push(v);
    }
    let has = |k: usize, what: &str| verdicts[k].missing.iter().any(|m| m.contains(what));
    // Pass 1 (northbound): ill-conditioned, and each sphere lacks a southbound pass.
    assert!(!verdicts[0].ready);
    assert!(
        has(0, "no calibration claimed yet (ill-conditioned"),
        "{:?}",
        verdicts[0]
    );
    assert!(has(0, "S1: no southbound pass") && has(0, "S2: no southbound pass"));
    // After pass 2 (southbound) every sphere is seen both ways, but pitch, with ranges of
    // 7-25 m only, is not yet as good as asked (0.053 deg measured): collecting, and it says
    // which parameter and what pass would help.
    assert!(!verdicts[1].ready, "{:?}", verdicts[1]);
    assert!(verdicts[1].coverage.iter().all(|c| c.both_directions));
    assert_eq!(verdicts[1].missing.len(), 1, "{:?}", verdicts[1]);
    assert!(
        has(1, "pitch sigma") && has(1, "another range"),
        "{:?}",
        verdicts[1]
    );
    // Pass 3 (northbound at 20 m, ranges to 33 m) brings pitch to 0.041 deg: ready, and stays.
    for k in [2, 3] {
        assert!(verdicts[k].ready, "{:?}", verdicts[k]);
        assert!(verdicts[k].missing.is_empty());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The planner on the survey under way (the rig's advice): after table1-noisy's first two
/// passes it proposes a pass; with targets the sensors cannot reach (0.002 deg, 0.5 mm) it says
/// they are out of reach, naming the parameter; with none, the survey is done once another
/// pass would improve no sigma by more than 20 %, and each pass flown shrinks what the next
/// could gain.
#[test]
fn the_live_planner_advises_and_says_what_is_out_of_reach() {
    let dir = common::tmp("verdict", "live");
    let s = Scenario::load("table1-noisy").unwrap();
    let inp = synthesised(&s, &dir);
    let (targets, ids) = site_targets(&inp);
    let (_, all) = collect(&inp).unwrap();
    let t0 = s.start().0;
    let b0 = inp.site.apriori_deg_m().params();
    let settings = Settings {
        range_noise: s.lidar.range_sigma_m,
        attitude_noise: s.ins.att_sigma_deg.to_radians(),
        position_noise: s.ins.pos_sigma_m,
        ..Default::default()
    };
    let mut live = spherecal_tools::plan::live::Live::new(
        &targets,
        &ids,
        spherecal::velodyne::Model::Vlp16,
        600.0,
        s.ins.rate_hz,
        &settings,
    )
    .unwrap();
    let none = Targets::default();
    let tight = Targets {
        target_sigma_deg: Some(0.002),
        target_sigma_m: Some(0.0005),
    };
    let mut gains = Vec::new();
    for until in [39.0, 70.0] {
        let mut obs: Vec<Vec<_>> = all
            .iter()
            .map(|v| {
                v.iter()
                    .filter(|o| ((o.time.0 - t0) as f64) * 1e-9 < until)
                    .copied()
                    .collect()
            })
            .collect();
        let (sol, rep) = solve_report(&targets, &ids, &mut obs, &b0, &settings);
        assert!(rep.converged, "{:?}", rep.reason);
        let cov = coverage(&ids, &obs, &sol);
        let (info, returns) = data_info(&targets, &obs, &sol, &settings, s.ins.rate_hz);
        live.update(&sol, &obs).unwrap();
        assert!(live.has_candidates());
        let a = live.advise(&info, &returns, None, None);
        let next = a.next.clone().unwrap().0;
        assert!(
            next.starts_with("add a ") && next.contains("m off the spheres' line"),
            "{next}"
        );
        let v = assess(&rep, &cov, none.goal().as_ref(), None, Some(&a));
        eprintln!(
            "until {until}: gain {:.3}: {next}; ready {}: {:?} {}",
            a.gain, v.ready, v.missing, v.ready_because
        );
        assert_eq!(
            v.ready,
            a.gain <= spherecal_tools::plan::live::ENOUGH_GAIN,
            "{v:?}"
        );
        gains.push(a.gain);
        // Out of reach: the targets, the parameter, the sensors' noise.
        let g = tight.goal();
        let a = live.advise(&info, &returns, g.as_ref(), None);
        let o = a.out_of_reach.clone().expect("0.002 deg is out of reach");
        assert!(
            o.starts_with(
                "the board's targets are out of reach: with four more passes the planner predicts "
            ),
            "{o}"
        );
        let v = assess(&rep, &cov, tight.goal().as_ref(), None, Some(&a));
        assert!(
            !v.ready && v.missing.iter().any(|m| m.contains("(the planner's)")),
            "{v:?}"
        );
    }
    assert!(gains[1] < gains[0], "{gains:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The rig under navigation errors that wander (table1-real, the site's `[ins.correlated]`):
/// its predicted sigma on the data so far is the solver's covariance under the model (not
/// the per-sample white prediction, ~10 times smaller), the live planner advises under it
/// (each candidate pass brings its own navigation errors), and the verdict says `ready` only
/// on targets the model's sigmas meet.
#[test]
fn under_the_navigation_model_the_rig_predicts_and_advises_with_it() {
    let dir = common::tmp("verdict", "table1-real");
    let s = Scenario::load("table1-real").unwrap();
    let inp = synthesised(&s, &dir);
    let (targets, ids) = site_targets(&inp);
    let (_, mut obs) = collect(&inp).unwrap();
    let b0 = inp.site.apriori_deg_m().params();
    let settings = spherecal_tools::session::settings_for(
        &inp.site,
        spherecal_tools::config::lidar::Lidar::velodyne(spherecal::velodyne::Model::Vlp16),
        true,
        inp.margin,
    );
    assert!(settings.nav.is_some());
    let (sol, rep) = solve_report(&targets, &ids, &mut obs, &b0, &settings);
    assert!(rep.converged, "{:?}", rep.reason);
    let solver = rep.sigma.deg_m();
    let predicted = predicted_sigma(&targets, &obs, &sol, &settings, s.ins.rate_hz);
    let white = {
        let mut w = settings;
        w.nav = None;
        predicted_sigma(&targets, &obs, &sol, &w, s.ins.rate_hz)
    };
    for i in 0..6 {
        let r = predicted[i] / solver[i];
        eprintln!(
            "{i}: predicted {:.3e}, the solver's {:.3e} (ratio {r:.2}), white {:.3e}",
            predicted[i], solver[i], white[i]
        );
        assert!((0.75..1.25).contains(&r), "{i}: {r}");
    }
    // The white prediction is the idealisation the model replaces: far smaller on z.
    assert!(white[5] < 0.3 * predicted[5], "{white:?} {predicted:?}");
    // The live planner under the model: a next pass, predicted to improve on now.
    let mut live = spherecal_tools::plan::live::Live::new(
        &targets,
        &ids,
        spherecal::velodyne::Model::Vlp16,
        600.0,
        s.ins.rate_hz,
        &settings,
    )
    .unwrap();
    live.update(&sol, &obs).unwrap();
    assert!(live.has_candidates());
    let (info, returns) = data_info(&targets, &obs, &sol, &settings, s.ins.rate_hz);
    let nav = spherecal_tools::verdict::nav_plan(&targets, &obs, &sol, &settings);
    assert!(nav.is_some());
    let a = live.advise(&info, &returns, None, nav.as_ref());
    let (next, with) = a.next.clone().unwrap();
    eprintln!("gain {:.3}: {next}: {:?}", a.gain, with.sigma_deg_m);
    assert!(a.gain > 0.0 && a.gain < 1.0, "{}", a.gain);
    let best = (0..6)
        .map(|i| 1.0 - with.sigma_deg_m[i].unwrap() / predicted[i])
        .fold(0.0, f64::max);
    assert!((best - a.gain).abs() < 1e-6, "{best} vs {}", a.gain);
    // Ready only on what the model's sigmas meet.
    let cov = coverage(&ids, &obs, &sol);
    let loose = Targets {
        target_sigma_deg: Some(0.1),
        target_sigma_m: Some(0.07),
    };
    let tight = Targets {
        target_sigma_deg: Some(0.01),
        target_sigma_m: Some(0.005),
    };
    let v = assess(
        &rep,
        &cov,
        loose.goal().as_ref(),
        Some(&predicted),
        Some(&a),
    );
    assert!(v.ready, "{v:?}");
    let v = assess(
        &rep,
        &cov,
        tight.goal().as_ref(),
        Some(&predicted),
        Some(&a),
    );
    assert!(
        !v.ready && v.missing.iter().any(|m| m.contains("heading")),
        "{v:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

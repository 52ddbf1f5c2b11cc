//! Calibration end to end: table1 from the paper's erroneous start, a 200-start Monte Carlo,
//! honest uncertainties on table1-noisy over 100 noise seeds, refusals.

mod common;

use spherecal::calib::solve::Refusal;
use spherecal::calib::{solve, Settings};
use spherecal_tools::calibrate::{collect, site_targets, solve_report};
use spherecal_tools::pipeline::{Inputs, InsInput};
use spherecal_tools::scenario::{Scenario, BUILTIN};
use spherecal_tools::site::Site;
use std::path::{Path, PathBuf};

const TRUTH: [f64; 6] = [179.5, -44.9, 1.2, 1.5, -1.24, -1.36];

fn tmp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("spherecal-calib-{}-{name}", std::process::id()))
}

fn inputs(dir: &Path) -> Inputs {
    Inputs::apriori(
        dir.join("lidar.pcap"),
        InsInput::Vn200(dir.join("ins.bin")),
        Site::load(&dir.join("site.toml")).unwrap(),
    )
}

fn scenario_text(name: &str) -> String {
    BUILTIN.iter().find(|b| b.0 == name).unwrap().1.to_string()
}

#[test]
fn table1_from_the_papers_erroneous_start() {
    let dir = tmp("table1");
    let s = Scenario::load("table1").unwrap();
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let report = dir.join("report.json");
    common::stdout_of(
        common::spherecal()
            .arg("calibrate")
            .args(common::survey_args(&dir))
            .arg("--report")
            .arg(&report)
            .arg("--plot")
            .arg(dir.join("plot.svg")),
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let got = [
        r["boresight_deg"]["roll"].as_f64().unwrap(),
        r["boresight_deg"]["pitch"].as_f64().unwrap(),
        r["boresight_deg"]["heading"].as_f64().unwrap(),
        r["lever_arm_m"]["x"].as_f64().unwrap(),
        r["lever_arm_m"]["y"].as_f64().unwrap(),
        r["lever_arm_m"]["z"].as_f64().unwrap(),
    ];
    for i in 0..6 {
        assert!(
            (got[i] - TRUTH[i]).abs() < 1e-3,
            "parameter {i}: {} vs {}",
            got[i],
            TRUTH[i]
        );
    }
    assert_eq!(r["converged"], true);
    // The re-windowing drops the tripod: the kept returns are the sphere returns.
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    assert_eq!(r["points_per_sphere"], truth["points_per_sphere"]);
    for key in [
        "sigma",
        "rms_m",
        "objective_l1_m",
        "evaluations",
        "correlation",
        "condition_number",
        "sphere_centre_rms_m",
        "per_sphere",
        "solve_ms",
    ] {
        assert!(!r[key].is_null(), "report key {key}");
    }
    assert!(r["sphere_centre_rms_m"].as_f64().unwrap() < 1e-3);
    assert!(std::fs::read_to_string(dir.join("plot.svg"))
        .unwrap()
        .starts_with("<svg"));
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn monte_carlo_200_starts_all_converge() {
    let s = Scenario::load("table1").unwrap();
    let r = spherecal_tools::montecarlo::montecarlo(&s, 200, 5.0, 0.5, 11, false).unwrap();
    assert_eq!(r.runs.len(), 200);
    assert_eq!(r.fraction_within, 1.0, "worst errors {:?}", r.worst_error);
}

/// 100 noise seeds of table1-noisy: each parameter's error within 3 reported sigma in at least
/// 95 % of the runs. (Before the grazing-inflation term of the least squares, y was 94/100 with
/// a mean z-score of -0.9: errors in variables at the spheres' limbs.)
#[test]
fn table1_noisy_sigmas_are_honest() {
    let text = scenario_text("table1-noisy");
    let seeds: Vec<u64> = (1000..1100).collect();
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|sc| {
        for chunk in seeds.chunks(50) {
            let (text, results) = (&text, &results);
            sc.spawn(move || {
                for &seed in chunk {
                    let s =
                        Scenario::from_toml(&text.replace("seed = 7", &format!("seed = {seed}")))
                            .unwrap();
                    let dir = tmp(&format!("noisy-{seed}"));
                    spherecal_tools::synth::synth(&s, &dir).unwrap();
                    let inp = inputs(&dir);
                    let (_, mut obs) = collect(&inp).unwrap();
                    let (t, ids) = site_targets(&inp);
                    let b0 = inp.mount.params();
                    let (sol, _) = solve_report(&t, &ids, &mut obs, &b0, &Settings::default());
                    let lm = sol.lm.expect("a least-squares solution");
                    let mut z = [0.0; 6];
                    for i in 0..6 {
                        let truth = if i < 3 {
                            TRUTH[i].to_radians()
                        } else {
                            TRUTH[i]
                        };
                        z[i] = (sol.b[i] - truth) / lm.sigma[i];
                    }
                    results.lock().unwrap().push((seed, z, sol.refusal));
                    std::fs::remove_dir_all(&dir).unwrap();
                }
            });
        }
    });
    let results = results.into_inner().unwrap();
    assert_eq!(results.len(), 100);
    assert!(
        results.iter().all(|r| r.2.is_none()),
        "every noisy run converges"
    );
    for i in 0..6 {
        let inside = results.iter().filter(|r| r.1[i].abs() <= 3.0).count();
        let rms = (results.iter().map(|r| r.1[i] * r.1[i]).sum::<f64>() / 100.0).sqrt();
        eprintln!(
            "{}: {inside}/100 within 3 sigma, rms z {rms:.2}",
            spherecal::calib::NAMES[i]
        );
        assert!(
            inside >= 95,
            "{}: only {inside} of 100 within 3 sigma",
            spherecal::calib::NAMES[i]
        );
    }
}

#[test]
fn one_sphere_is_refused() {
    let s = Scenario::from_toml(&scenario_text("table1").replace(
        "[[sphere]]\nid = \"S2\"\nned_m = [20.0, -0.6, -1.55]\nradius_m = 0.19\ntripod = true\n",
        "",
    ))
    .unwrap();
    assert_eq!(s.sphere.len(), 1);
    let dir = tmp("one-sphere");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let inp = inputs(&dir);
    let (_, mut obs) = collect(&inp).unwrap();
    let (t, _) = site_targets(&inp);
    let mut slices: Vec<&mut [spherecal::window::Observation]> =
        obs.iter_mut().map(|v| v.as_mut_slice()).collect();
    let mut scratch = spherecal_tools::calibrate::Scratch::default();
    let sol = solve(
        &t,
        &mut slices,
        &inp.mount.params(),
        &Settings::default(),
        &mut scratch.workspace(),
    );
    assert_eq!(sol.refusal, Some(Refusal::TooFewSpheres { have: 1 }));
    // The command says so and exits 1.
    let out = common::spherecal()
        .arg("calibrate")
        .args(common::survey_args(&dir))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout)
        .contains("NOT CONVERGED: 1 sphere(s): at least two are needed"));
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_single_pass_is_flagged_naming_the_weak_parameters() {
    let text = scenario_text("table1");
    let i = text.find("[[trajectory.pass]]").unwrap();
    let one = format!("{}[[trajectory.pass]]\nstart_ne_m = [-3.5, 8.0]\nheading_deg = 0.0\nspeed_mps = 1.3\nduration_s = 20.0\n", &text[..i]);
    let s = Scenario::from_toml(&one).unwrap();
    let dir = tmp("one-pass");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let inp = inputs(&dir);
    let (_, mut obs) = collect(&inp).unwrap();
    let (t, ids) = site_targets(&inp);
    let (sol, rep) = solve_report(
        &t,
        &ids,
        &mut obs,
        &inp.mount.params(),
        &Settings::default(),
    );
    assert!(
        matches!(sol.refusal, Some(Refusal::IllConditioned { .. })),
        "{:?}",
        sol.refusal
    );
    assert!(!rep.converged);
    let why = rep.reason.unwrap();
    assert!(
        why.contains("roll") && why.contains("heading") && why.contains('z'),
        "{why}"
    );
    assert!(rep.weak_parameters.contains(&"roll".to_string()));
    std::fs::remove_dir_all(dir).unwrap();
}

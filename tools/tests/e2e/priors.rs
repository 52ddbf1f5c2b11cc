//! Priors from outside the data (issue 46 item 4, issue 47 item 3): the spheres' survey sigmas
//! and a measured lever arm (`[apriori] lever_arm_sigma_m`) weighed with the returns under
//! white INS errors, their sigmas honest against Monte Carlo (each trial's survey and lever arm
//! drawn with the declared errors), a measured lever arm the data contradict refused by name.

use crate::common;
use crate::common::text;
use crate::plan::{calibrate, run_trials, tmp};
use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::report::Report;
use std::path::Path;

/// A draw of N(0, 1) per call (SplitMix64 and Box-Muller: the test's own generator).
struct Normal(u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn next(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * self.uniform()).cos()
    }
}

/// The site `synth` wrote to `dir`, each sphere surveyed with an error (north, east, up [m])
/// `survey(j)` and declaring `sigma_m` (none: the spheres left as written), the a-priori lever arm `lever_m` declared to
/// `lever_sigma_m` (none: left as written).
fn edit_site(
    dir: &Path,
    mut survey: impl FnMut(usize) -> [f64; 3],
    sigma_m: Option<f64>,
    lever: Option<([f64; 3], f64)>,
) {
    let p = dir.join("site.toml");
    let mut v: toml::Table = toml::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    let spheres = v["sphere"].as_array_mut().unwrap();
    for (j, sp) in spheres.iter_mut().enumerate() {
        let Some(sigma_m) = sigma_m else { break };
        let sp = sp.as_table_mut().unwrap();
        let [n, e, u] = survey(j);
        let lat = sp["lat_deg"].as_float().unwrap();
        // WGS 84's radii of curvature (the meridian's and the prime vertical's).
        let e2 = 6.694_379_990_14e-3;
        let w = 1.0 - e2 * lat.to_radians().sin().powi(2);
        let rn = 6_378_137.0 / w.sqrt();
        let rm = rn * (1.0 - e2) / w;
        let lon = sp["lon_deg"].as_float().unwrap();
        let h = sp["h_m"].as_float().unwrap();
        sp.insert("lat_deg".into(), (lat + (n / rm).to_degrees()).into());
        sp.insert(
            "lon_deg".into(),
            (lon + (e / (rn * lat.to_radians().cos())).to_degrees()).into(),
        );
        sp.insert("h_m".into(), (h + u).into());
        sp.insert("sigma_m".into(), sigma_m.into());
    }
    if let Some((arm, sigma)) = lever {
        let a = v["apriori"].as_table_mut().unwrap();
        a.insert(
            "lever_arm_m".into(),
            arm.map(toml::Value::from).to_vec().into(),
        );
        a.insert(
            "lever_arm_sigma_m".into(),
            [sigma; 3].map(toml::Value::from).to_vec().into(),
        );
    }
    std::fs::write(&p, toml::to_string(&v).unwrap()).unwrap();
}

const NAMES: [&str; 7] = ["roll", "pitch", "heading", "x", "y", "z", "time offset"];

/// table1-noisy (white INS errors) over 60 seeds, each trial's spheres surveyed with errors
/// drawn at 1 cm and declared so, its lever arm measured with 3 mm errors and declared so,
/// calibrated as a user runs it: every parameter's RMS z-score 0.7-1.4 (too large a sigma is
/// as wrong as too small; the sample's own relative error at 60 trials is ~9 %), at most one
/// refused; the lever arm's sigmas below the measurement's.
#[test]
fn survey_and_lever_arm_priors_are_honest_under_white_errors() {
    const TRIALS: u64 = 60;
    const SURVEY_M: f64 = 0.01;
    const LEVER_M: f64 = 0.003;
    let s = Scenario::load("table1-noisy").unwrap();
    let truth = s.mount.truth.deg_m().0;
    let (cache, _, _) = common::trial_cache(&s);
    let seeds: Vec<u64> = (3000..3000 + TRIALS).collect();
    let results = run_trials(&s, &seeds, &cache, "priors", |sd, dir| {
        let mut g = Normal(sd.seed);
        let arm = [3, 4, 5].map(|i| truth[i] + LEVER_M * g.next());
        let mut g2 = Normal(sd.seed ^ 0xABCD);
        edit_site(
            dir,
            |_| [0; 3].map(|_| SURVEY_M * g2.next()),
            Some(SURVEY_M),
            Some((arm, LEVER_M)),
        );
        calibrate(sd, dir)
    });
    let refused: Vec<_> = results
        .iter()
        .filter_map(|(seed, r)| r.2.as_ref().map(|w| (seed, w)))
        .collect();
    assert!(refused.len() <= 1, "refused: {refused:?}");
    let claimed: Vec<_> = results.iter().filter(|r| r.1 .2.is_none()).collect();
    let n = claimed.len() as f64;
    let mut bad = Vec::new();
    for (i, name) in NAMES.iter().enumerate() {
        let rms_z = (claimed
            .iter()
            .map(|r| (r.1 .0[i] / r.1 .1[i]).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let sigma = claimed.iter().map(|r| r.1 .1[i]).sum::<f64>() / n;
        eprintln!("{name:<11} RMS z {rms_z:.2}, mean reported sigma {sigma:.3e}");
        if !(0.7..=1.4).contains(&rms_z) {
            bad.push(format!("{name}: RMS z {rms_z:.2}"));
        }
        if (3..6).contains(&i) && sigma >= LEVER_M {
            bad.push(format!(
                "{name}: sigma {sigma:.4} not below the measurement's"
            ));
        }
    }
    assert!(bad.is_empty(), "{bad:?}");
}

/// `spherecal calibrate` of the trial in `dir`: its output and report.
fn calibrate_cli(dir: &Path) -> (std::process::Output, Report) {
    let report = dir.join("report.json");
    let out = common::calibrate_survey(dir, &dir.join("site.toml"), &report);
    let r = std::fs::read_to_string(&report).unwrap_or_else(|_| panic!("{}", text(&out)));
    (out, serde_json::from_str(&r).unwrap())
}

/// A lever arm measured to 3 mm: at the truth it is claimed within 3 sigma, the lever arm's
/// sigmas below 3 mm and below the data's alone, the measurement shown beside the result;
/// measured 5 cm off in x it is refused (exit 1), naming x and the measurement.
#[test]
fn a_measured_lever_arm_is_weighed_and_a_wrong_one_refused() {
    let s = Scenario::load("table1-noisy").unwrap();
    let truth = s.mount.truth.deg_m().0;
    let (cache, _, _) = common::trial_cache(&s);
    let dir = tmp("lever-arm");
    spherecal_tools::synth::synth_traced(&s, &dir, &cache).unwrap();
    let site = std::fs::read_to_string(dir.join("site.toml")).unwrap();
    let arm = [truth[3], truth[4], truth[5]];
    // Without a measured lever arm: the data's own sigmas.
    let (_, alone, why) = calibrate(&s, &dir);
    assert_eq!(why, None);
    edit_site(&dir, |_| [0.0; 3], None, Some((arm, 0.003)));
    let (o, r) = calibrate_cli(&dir);
    let t = text(&o);
    assert!(common::claimed(&o), "{t}");
    let (got, sigma) = (r.deg_m(), r.sigma.deg_m());
    for i in 0..6 {
        assert!(
            (got[i] - truth[i]).abs() < 3.0 * sigma[i],
            "{}: {got:?} {sigma:?}",
            NAMES[i]
        );
    }
    for i in 3..6 {
        assert!(
            sigma[i] < 0.003 && sigma[i] < alone[i],
            "{}: {sigma:?} vs alone {alone:?}",
            NAMES[i]
        );
    }
    assert_eq!(r.mounting_prior.len(), 3, "{:?}", r.mounting_prior);
    for (m, i) in r.mounting_prior.iter().zip(3..6) {
        assert_eq!(m.parameter, NAMES[i]);
        assert!((m.measured - truth[i]).abs() < 1e-9 && m.sigma == 0.003);
        assert!(m.z.abs() < 3.0, "{m:?}");
    }
    assert!(t.contains("measured mounting: x measured"), "{t}");
    std::fs::write(dir.join("site.toml"), &site).unwrap();
    edit_site(
        &dir,
        |_| [0.0; 3],
        None,
        Some(([arm[0] + 0.05, arm[1], arm[2]], 0.003)),
    );
    let (o, r) = calibrate_cli(&dir);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let why = r.reason.expect("a lever arm measured 5 cm off is refused");
    assert!(
        why.starts_with("the data move the x") && why.contains("[apriori]"),
        "{why}"
    );
    assert!(r.mounting_prior[0].z.abs() > 3.0, "{:?}", r.mounting_prior);
    std::fs::remove_dir_all(&dir).unwrap();
}

//! The drone (issue 30, first step): the built-in `drone` survey — a multirotor at 40 m and
//! 25 m above a field, its VLP-16 scanning across the track, spheres on tripods and resting
//! on the grass among a shed, cars, trees and bushes — is extracted from above and calibrates within 1e-3
//! of the truth from a-priori values 0.5 deg / 3 cm off.

use crate::common;

/// `calibrate` on the survey in `d` (exit 0, claimed): its JSON report and what it printed.
fn calibrated(d: &std::path::Path) -> (serde_json::Value, String) {
    let report = d.join("report.json");
    let o = common::spherecal()
        .arg("calibrate")
        .args(common::survey_args(d))
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "{text}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["converged"], true, "{text}");
    (r, text)
}

#[test]
fn the_drone_survey_calibrates_from_above_within_1e_3() {
    let s = spherecal_tools::config::scenario::Scenario::load("drone").unwrap();
    // Two flight heights, from the passes' own down.
    let downs: Vec<f64> = s
        .trajectory
        .pass
        .iter()
        .map(|p| p.down_m.unwrap_or(s.trajectory.ins_down_m))
        .collect();
    assert!(
        downs.contains(&-40.0) && downs.contains(&-25.0),
        "{downs:?}"
    );
    let d = common::tmp("drone", "clean");
    let _ = std::fs::remove_dir_all(&d);
    let truth = spherecal_tools::synth::synth(&s, &d).unwrap();
    // Every sphere is seen from the air (the simulator's own labels).
    assert!(
        truth.points_per_sphere.iter().all(|&n| n > 150),
        "{:?}",
        truth.points_per_sphere
    );
    let (r, _) = calibrated(&d);
    common::assert_within(
        &common::report_deg_m(&r),
        &s.mount.truth.deg_m().0,
        1e-3,
        "the drone survey",
    );
    // Every sphere's kept returns are most of what the simulator put on it: on a tripod and
    // on the grass alike (71-79 % and 68-77 % when this was written; a sphere on the grass
    // kept 43 % before its ground was set aside per slice: the scan lines run on from the
    // grass over it).
    for (k, p) in r["per_sphere"].as_array().unwrap().iter().enumerate() {
        let kept = p["points"].as_u64().unwrap_or(0);
        assert!(
            kept * 10 >= truth.points_per_sphere[k] * 6,
            "sphere {k}: kept {kept} of {}: {p}",
            truth.points_per_sphere[k]
        );
    }
    assert!(s.sphere.iter().any(|x| x.stand == "none"));
    let _ = std::fs::remove_dir_all(&d);
}

/// `drone-noisy` (an APX-15-class INS whose errors wander, the VLP-16's measured noise):
/// synthesised as the VN-200 stream (`--ins vn200`, as for the vessel), calibrated through the
/// command line under the site's navigation model, converged with every error within 3 of its
/// reported sigmas, and those sigmas at the INS's own level (the plan's within a factor 2:
/// 0.03-0.06 deg, 2-6 cm), not the white model's millimetres. The 100-seed check is
/// `plan::drone_noisy_prediction_agrees_with_monte_carlo` (open).
#[test]
fn the_noisy_drone_survey_calibrates_within_its_sigmas() {
    let d = common::tmp("drone", "noisy");
    let _ = std::fs::remove_dir_all(&d);
    let o = common::spherecal()
        .args([
            "synth",
            "--scenario",
            "drone-noisy",
            "--ins",
            "vn200",
            "--out",
        ])
        .arg(&d)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(d.join("ins.bin").exists() && !d.join("ins.posmv").exists());
    let s = spherecal_tools::config::scenario::Scenario::load("drone-noisy").unwrap();
    let (r, text) = calibrated(&d);
    assert!(text.contains("preset \"apx15\""), "{text}");
    let got = common::report_deg_m(&r);
    let truth = s.mount.truth.deg_m().0;
    let sig = &r["sigma"];
    let sigma: Vec<f64> = ["roll", "pitch", "heading", "x", "y", "z"]
        .iter()
        .enumerate()
        .map(|(i, k)| {
            let group = if i < 3 {
                "boresight_deg"
            } else {
                "lever_arm_m"
            };
            sig[group][k].as_f64().unwrap()
        })
        .collect();
    let planned = [0.032, 0.012, 0.056, 0.024, 0.015, 0.060];
    for i in 0..6 {
        assert!(
            (got[i] - truth[i]).abs() <= 3.0 * sigma[i],
            "{i}: error {} sigma {}",
            got[i] - truth[i],
            sigma[i]
        );
        assert!(
            (0.5..=2.0).contains(&(sigma[i] / planned[i])),
            "{i}: sigma {} against the plan's {}",
            sigma[i],
            planned[i]
        );
    }
    let _ = std::fs::remove_dir_all(&d);
}

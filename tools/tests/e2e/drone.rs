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
    assert!(common::claimed(&o), "{text}");
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
/// `plan::drone_noisy_prediction_agrees_with_monte_carlo` (passes; ignored for its 55 s).
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
    assert!(
        common::claimed(&o),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
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
    let planned = [0.039, 0.015, 0.058, 0.028, 0.016, 0.063];
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

/// `drone-noisy` Monte Carlo trials (the plan's trials: the scenario's planning noise, the
/// windowed packets only) of `seeds`, its lidar effects switched off when `ideal`: each solved
/// as the file command does with the settings changed by each of `edits`; per seed and edit
/// the solution, the returns with their verdicts and the trial's labels (object, purity) by
/// (packet, block, channel).
type Labels = std::collections::HashMap<(u32, u8, u8), (u16, u8)>;
/// A solution, the returns with their verdicts, the labels.
type Solved = (
    spherecal::calib::Solution,
    Vec<Vec<spherecal::align::window::Observation>>,
    Labels,
);

fn trial(
    ideal: bool,
    seeds: &[u64],
    edits: &[&dyn Fn(&mut spherecal::calib::Settings)],
) -> Vec<Vec<Solved>> {
    let name = if ideal { "ideal" } else { "noisy" };
    trial_of(
        name,
        &|s| {
            if ideal {
                ideal_lidar(s)
            }
        },
        seeds,
        edits,
    )
}

/// The LiDAR without its effects: range noise alone.
fn ideal_lidar(s: &mut spherecal_tools::config::scenario::Scenario) {
    let l = &mut s.lidar;
    l.beam_divergence_mrad = [0.0, 0.0];
    l.incidence_noise = false;
    l.intensity_scatter = 0.0;
    l.edge_dropout = 0.0;
    l.range_walk_m = 0.0;
}

/// [`trial`] of drone-noisy edited by `scene` (named `name` in the trials' folders), in the
/// simulator's world the faults were found in: the footprint as five sub-rays at edges (the
/// Gaussian grid of session 39 moves every seed's returns, so the seeds here would no longer
/// hold their faults), the site then stating no beam to model.
fn trial_of(
    name: &str,
    scene: &dyn Fn(&mut spherecal_tools::config::scenario::Scenario),
    seeds: &[u64],
    edits: &[&dyn Fn(&mut spherecal::calib::Settings)],
) -> Vec<Vec<Solved>> {
    use spherecal_tools::calibrate::{collect, site_targets};
    use spherecal_tools::config::lidar::Lidar;
    use spherecal_tools::config::scenario::Scenario;
    use spherecal_tools::session::settings_for;
    use spherecal_tools::session::solve_report_in;
    let mut s = spherecal_tools::plan::with_planning_noise(&Scenario::load("drone-noisy").unwrap());
    s.lidar.footprint_grid = false;
    scene(&mut s);
    let (cache, _, _) = common::trial_cache(&s);
    seeds
        .iter()
        .map(|&seed| {
            s.seed = seed;
            let d = common::tmp("drone", &format!("trial-{name}-{seed}"));
            let _ = std::fs::remove_dir_all(&d);
            spherecal_tools::synth::synth_traced(&s, &d, &cache).unwrap();
            let inp = common::survey_inputs(&d);
            let labels: Labels = spherecal_tools::synth::read_labels(&d.join("labels.bin"))
                .unwrap()
                .into_iter()
                .map(|l| ((l.packet, l.block, l.channel), (l.object, l.purity)))
                .collect();
            let (_, obs) = collect(&inp).unwrap();
            let (tg, ids) = site_targets(&inp);
            let out = edits
                .iter()
                .map(|edit| {
                    let mut settings = settings_for(
                        &inp.site,
                        s.scanner().map_or_else(Default::default, Lidar::of_scanner),
                        true,
                        inp.margin,
                    );
                    edit(&mut settings);
                    let mut o = obs.clone();
                    let (sol, _) = solve_report_in(
                        &tg,
                        &ids,
                        &mut o,
                        &inp.mount.params(),
                        &settings,
                        &mut spherecal_tools::session::scratch::Scratch::default(),
                        &mut (),
                    );
                    (sol, o, labels.clone())
                })
                .collect();
            let _ = std::fs::remove_dir_all(&d);
            out
        })
        .collect()
}

/// The kept returns of `a` that `b` does not keep.
fn kept_only_in(
    a: &[Vec<spherecal::align::window::Observation>],
    b: &[Vec<spherecal::align::window::Observation>],
) -> Vec<(usize, spherecal::align::window::Observation)> {
    let kept = spherecal::calib::extract::ReturnClass::Kept as u8;
    let key = |o: &spherecal::align::window::Observation| (o.packet, o.block, o.channel);
    a.iter()
        .enumerate()
        .flat_map(|(j, v)| {
            let theirs: std::collections::HashSet<_> = b[j]
                .iter()
                .filter(|o| o.work.verdict == kept)
                .map(key)
                .collect();
            v.iter()
                .filter(move |o| o.work.verdict == kept && !theirs.contains(&key(o)))
                .map(move |o| (j, *o))
        })
        .collect()
}

/// What the final fit sets aside, on real faults of the drone's Monte Carlo trials (seeds the
/// 100-seed check found; a change to the simulator's random streams moves them: look for new
/// ones with `SPHERECAL_MC_KEEP` and `calibrate --returns` against the trial's labels.bin, as
/// docs/history/issue-30-drone.md says). The labels, not the solver, say what the returns were:
/// - seed 1085: in a turn 60 m from a grass sphere, a slice kept three grass returns; the
///   time offset paid for them (12 sigma). The isolated stretch is set aside (they lie
///   0.5-0.7 m off the sphere without it), the offset comes within 3 sigma;
/// - seed 1037 with an ideal LiDAR: a slice kept grass returns that a navigation piece took
///   in, a 7-sigma step refused as an INS jump; that piece is set aside and the survey claimed;
/// - seed 1043 with an ideal LiDAR: a pass's first pieces (1-3 returns on one side of a
///   sphere) sat in a second minimum 25 cm below the truth, an 8.3-sigma step refused as an
///   INS jump; started from the other side's pieces, the fit finds the lower cost, claimed.
///
/// The faults were found before the last extraction rejected the grass along the laser's
/// sweeps (`ExtractSettings::ground_sweeps`): the set-asides are shown with it off; with it
/// on seed 1085 is claimed within 3 sigma too (its turn's three grass returns, far from any
/// sweep's ground line, still set aside by the influence test).
#[test]
fn the_final_fit_sets_aside_what_is_not_the_sphere() {
    let sweeps_off = |s: &mut spherecal::calib::Settings| s.extract.ground_sweeps = false;
    // Claimed; the returns the second run keeps and the first not are `counted`, none the
    // sphere's by the labels.
    let claimed_without_spheres =
        |runs: &[(spherecal::calib::Solution, Vec<Vec<_>>, Labels)],
         counted: fn(&spherecal::calib::Solution) -> (u32, u32)| {
            let ((with, kept, labels), (_, all, _)) = (&runs[0], &runs[1]);
            assert_eq!(with.refusal, None, "{:?}", with.refusal);
            assert_eq!(counted(with).1, 1, "{:?}", with.set_aside);
            let aside = kept_only_in(all, kept);
            assert_eq!(aside.len() as u32, counted(with).0);
            let sphere = |j: usize, o: &spherecal::align::window::Observation| {
                labels
                    .get(&(o.packet, o.block, o.channel))
                    .is_some_and(|&(ob, purity)| usize::from(ob) == j && purity >= 230)
            };
            assert!(
                aside.iter().all(|(j, o)| !sphere(*j, o)),
                "set aside sphere returns: {aside:?}"
            );
        };
    // Seed 1085: the influence test on and off; then the grass rejected along the sweeps.
    let runs = &trial(
        false,
        &[1085],
        &[
            &sweeps_off,
            &|s| {
                sweeps_off(s);
                s.max_influence_sigmas = f64::INFINITY
            },
            &|_| {},
        ],
    )[0];
    claimed_without_spheres(runs, |s| s.set_aside.influential);
    let z = |s: &spherecal::calib::Solution| s.dt / s.lm.unwrap().sigma_dt;
    assert!(z(&runs[1].0).abs() > 5.0, "the fault: {}", z(&runs[1].0));
    assert!(z(&runs[0].0).abs() < 3.0, "{}", z(&runs[0].0));
    let swept = &runs[2].0;
    assert_eq!(swept.refusal, None, "{:?}", swept.refusal);
    assert!(z(swept).abs() < 3.0, "{}", z(swept));
    // An ideal LiDAR: seed 1037, the misfit piece on and off (no jump test); seed 1043, the
    // second minimum escaped (refused before, an 8.3-sigma step), nothing set aside.
    let ideal = trial(
        true,
        &[1037, 1043],
        &[&sweeps_off, &|s| {
            sweeps_off(s);
            s.max_nav_step_sigmas = f64::INFINITY
        }],
    );
    claimed_without_spheres(&ideal[0], |s| s.set_aside.misfit_pieces);
    assert!(ideal[0][1].0.nav.unwrap().worst_step.0 > 5.0);
    let escaped = &ideal[1][0].0;
    assert_eq!(escaped.refusal, None, "{:?}", escaped.refusal);
    assert_eq!(escaped.set_aside, Default::default());
    assert!(escaped.nav.unwrap().worst_step.0 < 5.0);
}

/// A first round's consensus resting on a handful of slices, on a real fault of the Monte
/// Carlo (seed 1057 of drone-noisy without the range walk: the consensus on 4 + 4 + 2 slices
/// put pitch +1.7 deg and y -0.8 m off and the rounds kept only what fits it, two spheres
/// lost, the answer 5-7 sigma off and claimed). A lost sphere starts the rounds again from
/// the a-priori, close: they explain more and the answer is the truth's within 3 sigma;
/// without the second start the fault is back (the test can fail).
#[test]
fn a_lost_sphere_starts_the_rounds_again_from_the_apriori() {
    let truth = noisy_truth();
    let runs = &trial_of(
        "walkless",
        &|s| s.lidar.range_walk_m = 0.0,
        &[1057],
        &[&|_| {}, &|s| s.second_start = false],
    )[0];
    let worst_z = |sol: &spherecal::calib::Solution| {
        let l = sol.lm.unwrap();
        (0..6)
            .map(|i| ((sol.b.0[i] - truth[i]) / l.sigma[i]).abs())
            .fold(0.0, f64::max)
    };
    let (with, without) = (&runs[0].0, &runs[1].0);
    assert_eq!(with.refusal, None, "{:?}", with.refusal);
    let again = with.second_start.expect("a second start");
    assert!(again.taken && again.second >= 2 * again.first, "{again:?}");
    assert!(worst_z(with) < 3.0, "{}", worst_z(with));
    assert!(
        with.spheres.iter().all(|s| s.used > 0),
        "{:?}",
        with.spheres
    );
    // Without it: claimed, two spheres lost, beyond 5 sigma.
    assert_eq!(without.second_start, None);
    assert!(worst_z(without) > 5.0, "{}", worst_z(without));
}

/// All four spheres resting on the grass (a surveyor without tripods), seen from 40 m: a
/// round's consensus on a handful of slices and a mounting off by tenths lift the grass into
/// the spheres' shells. On a real fault of that Monte Carlo (seed 1045): the first start lost
/// two spheres and ended with a round that found fewer than two, the second start from the
/// a-priori left the bounds, and the last extraction around the first start's mounting
/// claimed pitch 12.6 and y 9.1 sigma off (before the rule). Neither start settled: refused
/// as `Unsettled`. A seed whose second start settles (1000) is claimed, every error within 3
/// sigma (the rule does not refuse what the rounds confirmed).
#[test]
fn spheres_all_on_the_grass_are_refused_when_neither_start_settles() {
    use spherecal::calib::solve::{Refusal, Unfinished};
    let truth = noisy_truth();
    let runs = trial_of(
        "grounded",
        &every_sphere_on_the_grass,
        &[1045, 1000],
        &[&|_| {}],
    );
    let (fault, fine) = (&runs[0][0].0, &runs[1][0].0);
    assert!(
        matches!(
            fault.refusal,
            Some(Refusal::Unsettled {
                first: Unfinished::TooFewSpheres,
                ..
            })
        ),
        "{:?} {:?}",
        fault.refusal,
        fault.second_start
    );
    let again = fault.second_start.expect("a second start");
    assert!(!again.taken && again.second > 4 * again.first, "{again:?}");
    assert_eq!(fine.refusal, None, "{:?}", fine.refusal);
    assert!(fine.second_start.is_some_and(|s| s.taken));
    let l = fine.lm.unwrap();
    for (i, t) in truth.iter().enumerate() {
        let z = (fine.b.0[i] - t) / l.sigma[i];
        assert!(z.abs() < 3.0, "{i}: z {z}");
    }
}

/// The mounting `drone-noisy`'s trials are made with [rad, m].
fn noisy_truth() -> [f64; 6] {
    use spherecal_tools::config::scenario::Scenario;
    spherecal_tools::plan::with_planning_noise(&Scenario::load("drone-noisy").unwrap())
        .mount
        .truth
        .deg_m()
        .params()
        .0
}

/// `plan` on an aerial survey whose spheres all rest on the ground says what its prediction
/// leaves out (the footprint's mixed returns against the grass bias the lever arm's height)
/// and to put spheres on tripods, in its text and its report (`warnings`); on the built-in
/// `drone` (two on tripods) it does not.
#[test]
fn plan_warns_when_every_sphere_rests_on_the_ground() {
    use spherecal_tools::config::scenario::Scenario;
    let d = common::tmp("drone", "grounded-plan");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let mut s = Scenario::load("drone").unwrap();
    every_sphere_on_the_grass(&mut s);
    let f = d.join("grounded.toml");
    std::fs::write(&f, toml::to_string(&s).unwrap()).unwrap();
    let said = |scenario: &std::ffi::OsStr| {
        let o = common::spherecal()
            .args(["plan", "--no-recommend", "--scenario"])
            .arg(scenario)
            .arg("--report")
            .arg(d.join("plan.json"))
            .output()
            .unwrap();
        // Exit 1: the plan misses the default targets (0.01 deg, 5 mm); not an error.
        assert!(
            matches!(o.status.code(), Some(0 | 1)),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let grounded = said(f.as_os_str());
    assert!(
        grounded.contains("warning: every sphere rests on the ground")
            && grounded.contains("tripods"),
        "{grounded}"
    );
    // In the report too.
    let report = |d: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("plan.json")).unwrap()).unwrap()
    };
    let w = &report(&d)["warnings"];
    assert!(
        w[0].as_str().unwrap().contains("rests on the ground"),
        "{w}"
    );
    assert!(!said("drone".as_ref()).contains("rests on the ground"));
    assert!(report(&d).get("warnings").is_none());
    let _ = std::fs::remove_dir_all(&d);
}

/// Every sphere of `s` taken off its stand and laid on the grass (the ground at d = 0): its
/// centre one radius up.
fn every_sphere_on_the_grass(s: &mut spherecal_tools::config::scenario::Scenario) {
    for sp in s.sphere.iter_mut().filter(|sp| sp.stand != "none") {
        sp.ned_m[2] = -sp.radius_m;
        sp.stand = "none".into();
        sp.stand_down_m = None;
    }
}

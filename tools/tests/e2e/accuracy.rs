//! The trajectory's accuracy file (POSPac smrmsg) in the calibration's stochastic model, end to
//! end: table1 with an SBET whose noise is 4x larger in the second half of the survey (a GNSS
//! degradation over the last two passes) and an smrmsg that says so, as POSPac writes it beside
//! the SBET.
//!
//! Without the smrmsg, the site's noise model (the good half's) applies to every return and the
//! shell cuts most of the degraded passes' returns away as outliers. With it, each return has
//! its own sigma: the degraded returns are kept in a wider shell and weighted down, the
//! predicted RMS follows the mix (the dispersion test stays near 1), and the solution lies
//! within its sigmas of the truth.

use crate::common;

use common::spherecal;
use spherecal::frames::{roll_pitch_heading, rotation};
use spherecal::sim::Rng;
use spherecal_hal::sbet::{SbetRecord, SmrmsgRecord};
use spherecal_tools::config::scenario::Scenario;
use std::path::Path;

const TRUTH: [f64; 6] = [179.5, -44.9, 1.2, 1.5, -1.24, -1.36];
/// Per-axis 1-sigma of the SBET: position [m], attitude [deg]; good, then degraded.
const GOOD: (f64, f64) = (0.004, 0.004);
const BAD: (f64, f64) = (0.015, 0.015);
/// The degradation starts this long after the survey's start [s] (passes 3 and 4).
const DEGRADED_AFTER_S: f64 = 40.0;

/// Write `sbet_t.out` with the noise above and `smrmsg_t.out` (1 Hz) declaring it.
fn write_trajectory(s: &Scenario, dir: &Path) {
    let (passes, objects) = (s.passes(), s.objects());
    let w = s.world(&[], &passes, &objects);
    let mut rng = Rng::new(11);
    let (mut sbet, mut rms) = (Vec::new(), Vec::new());
    let sigma = |since: f64| if since > DEGRADED_AFTER_S { BAD } else { GOOD };
    for j in 0..(70 * 200) {
        let t = spherecal::time::GpsTime(s.start().0 - 1_000_000_000 + j * 5_000_000);
        let since = (t.0 - s.start().0) as f64 * 1e-9;
        let (sp, sa) = sigma(since);
        let st = w.trajectory.state(w.t_of(t));
        let noisy =
            st.position + nalgebra::Vector3::new(rng.normal(), rng.normal(), rng.normal()) * sp;
        let g = w.site.to_geodetic(&noisy);
        let rph: [f64; 3] = core::array::from_fn(|k| st.rph[k] + rng.normal() * sa.to_radians());
        let local =
            w.site.from_local_level(g.lat, g.lon).transpose() * rotation(rph[0], rph[1], rph[2]);
        let [roll, pitch, heading] = roll_pitch_heading(&local);
        let tow = t.week_tow_ns().1 as f64 * 1e-9;
        sbet.extend_from_slice(
            &SbetRecord {
                tow_s: tow,
                lat: g.lat,
                lon: g.lon,
                h: g.h,
                roll,
                pitch,
                platform_heading: heading,
                wander: 0.0,
            }
            .emit(),
        );
        if j % 200 == 0 {
            rms.extend_from_slice(
                &SmrmsgRecord {
                    tow_s: tow,
                    position_m: [sp; 3],
                    velocity_mps: [0.01; 3],
                    attitude_arcmin: [sa * 60.0; 3],
                }
                .emit(),
            );
        }
    }
    std::fs::write(dir.join("sbet_t.out"), &sbet).unwrap();
    std::fs::write(dir.join("smrmsg_t.out"), &rms).unwrap();
    // The same SBET under a name with no accuracy file beside it.
    std::fs::write(dir.join("trajectory.out"), &sbet).unwrap();
}

/// The site with the noise model `(position [m], attitude [deg])` (range noise 1 mm: the
/// scenario's LiDAR is noiseless).
fn site(dir: &Path, name: &str, noise: (f64, f64)) -> std::path::PathBuf {
    let base = std::fs::read_to_string(dir.join("site.toml")).unwrap();
    let p = dir.join(name);
    std::fs::write(
        &p,
        format!(
            "{base}\n[noise]\nrange_m = 0.001\nattitude_deg = {}\nposition_m = {}\n",
            noise.1, noise.0
        ),
    )
    .unwrap();
    p
}

fn calibrate(dir: &Path, sbet: &str, site: &Path, report: &str) -> serde_json::Value {
    let r = dir.join(report);
    let out = spherecal()
        .arg("calibrate")
        .arg("--pcap")
        .arg(dir.join("lidar.pcap"))
        .arg("--sbet")
        .arg(dir.join(sbet))
        .args(["--trajectory-datum", "WGS84"])
        .arg("--site")
        .arg(site)
        .arg("--hold-time-offset")
        .arg("--report")
        .arg(&r)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    let v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(&r).unwrap_or_else(|e| panic!("{e}: {text}")),
    )
    .unwrap();
    eprintln!(
        "{report}: converged {} rms {} dispersion {} predicted {} shell {} kept {} reason {}",
        v["converged"],
        v["rms_m"],
        v["consistency"]["dispersion"],
        v["consistency"]["predicted_rms_m"],
        v["shell_m"],
        v["points_per_sphere"],
        v["reason"]
    );
    v
}

fn six(v: &serde_json::Value) -> [f64; 6] {
    let f = |a: &str, b: &str| v[a][b].as_f64().unwrap();
    [
        f("boresight_deg", "roll"),
        f("boresight_deg", "pitch"),
        f("boresight_deg", "heading"),
        f("lever_arm_m", "x"),
        f("lever_arm_m", "y"),
        f("lever_arm_m", "z"),
    ]
}

#[test]
fn smrmsg_sigmas_weigh_the_returns() {
    let dir = common::tmp("accuracy", "table1");
    let s = Scenario::load("table1-bare").unwrap();
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    write_trajectory(&s, &dir);
    let good = site(&dir, "site-good.toml", GOOD);

    // Without the accuracy file: the good half's noise model cannot explain the residuals.
    let plain = calibrate(&dir, "trajectory.out", &good, "plain.json");
    assert!(plain["inputs"]["accuracy"].is_null());

    // With it (found beside sbet_t.out): claimed, consistent, within its sigmas.
    let weighted = calibrate(&dir, "sbet_t.out", &good, "weighted.json");
    let acc = &weighted["inputs"]["accuracy"];
    assert!(
        acc["file"].as_str().unwrap().ends_with("smrmsg_t.out"),
        "{acc}"
    );
    assert_eq!(acc["returns_outside"], 0);
    assert!(acc["returns_given"].as_u64().unwrap() > 1000);
    // Per-axis 4 mm and 4 cm are also the one-axis sigmas (the RMS of three equal axes).
    let [lo, hi] = [0, 1].map(|k| acc["position_sigma_m"][k].as_f64().unwrap());
    assert!(
        (lo - GOOD.0).abs() < 1e-6 && (hi - BAD.0).abs() < 1e-6,
        "{acc}"
    );
    assert_eq!(weighted["converged"], true);
    let dispersion = weighted["consistency"]["dispersion"].as_f64().unwrap();
    assert!((0.6..1.4).contains(&dispersion), "dispersion {dispersion}");
    let (got, sig) = (six(&weighted), six(&weighted["sigma"]));
    for i in 0..6 {
        let e = (got[i] - TRUTH[i]).abs();
        assert!(
            e < 4.0 * sig[i],
            "parameter {i}: error {e} > 4 sigma {}",
            sig[i]
        );
    }

    // The degraded passes: their returns, known to be noisier, are kept in a shell widened by
    // as much (and weighted down), not cut away as by the plain run's shell.
    let kept_late = |v: &serde_json::Value| -> u64 {
        let t0 = v["per_pass"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["start_gps_s"].as_f64().unwrap())
            .fold(f64::INFINITY, f64::min);
        v["per_pass"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|p| p["start_gps_s"].as_f64().unwrap() > t0 + DEGRADED_AFTER_S - 5.0)
            .map(|p| p["verdicts"]["kept"].as_u64().unwrap())
            .sum()
    };
    let (late_plain, late_weighted) = (kept_late(&plain), kept_late(&weighted));
    assert!(
        late_weighted * 4 > late_plain * 5,
        "degraded passes: {late_weighted} kept weighted vs {late_plain} plain"
    );
    // The plain run predicts the good half's noise for all its returns; the weighted run the
    // mix the smrmsg gives, which its residuals follow.
    let predicted = |v: &serde_json::Value| v["consistency"]["predicted_rms_m"].as_f64().unwrap();
    assert!(predicted(&weighted) > 1.3 * predicted(&plain));

    // The SBET in two files named against their time order, given one by one with the
    // smrmsg: the same calibration.
    let sbet = std::fs::read(dir.join("sbet_t.out")).unwrap();
    let half = sbet.len() / 136 / 2 * 136;
    std::fs::write(dir.join("part-b.out"), &sbet[..half]).unwrap();
    std::fs::write(dir.join("part-a.out"), &sbet[half..]).unwrap();
    let r = dir.join("parts.json");
    common::stdout_of(
        spherecal()
            .arg("calibrate")
            .arg("--pcap")
            .arg(dir.join("lidar.pcap"))
            .arg("--sbet")
            .arg(dir.join("part-a.out"))
            .arg(dir.join("part-b.out"))
            .arg("--smrmsg")
            .arg(dir.join("smrmsg_t.out"))
            .args(["--trajectory-datum", "WGS84"])
            .arg("--site")
            .arg(&good)
            .arg("--hold-time-offset")
            .arg("--report")
            .arg(&r),
    );
    let parts: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&r).unwrap()).unwrap();
    for key in ["boresight_deg", "lever_arm_m", "sigma", "points_per_sphere"] {
        assert_eq!(parts[key], weighted[key], "{key}");
    }
}

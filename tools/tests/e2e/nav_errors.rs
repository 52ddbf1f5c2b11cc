//! Navigation errors that wander (`[ins.correlated]`, issue 28): the simulated INS outputs carry
//! them, sample by sample, on top of the same white noise.

use crate::common;

use spherecal::posmv::{self, Item};
use spherecal_tools::config::nav_errors::CorrelatedSpec;
use spherecal_tools::config::scenario::Scenario;
use std::path::Path;

/// WGS84 meridian and prime-vertical radii at `lat` [m].
fn radii(lat: f64) -> (f64, f64) {
    let (a, e2) = (6_378_137.0, 6.694_379_990_14e-3);
    let w = (1.0 - e2 * lat.sin().powi(2)).sqrt();
    (a * (1.0 - e2) / (w * w * w), a / w)
}

/// One sample as decoded: GPS time [ns], lat, lon [rad], h [m], roll, pitch, heading [deg].
type Sample = (i64, [f64; 3], [f64; 3]);

fn vn200_samples(file: &Path) -> Vec<Sample> {
    let bytes = std::fs::read(file).unwrap();
    let mut out = Vec::new();
    spherecal_tools::ins::for_each_item(&bytes, |it| {
        if let spherecal::vn200::Item::Binary(f) = it.item {
            let p = spherecal::vn200::Pose::from_frame(&f).unwrap();
            let spherecal::vn200::Attitude::YawPitchRoll([y, pi, r]) = p.attitude else {
                panic!("yaw, pitch, roll expected")
            };
            out.push((
                p.time.0,
                [p.lat, p.lon, p.h],
                [r.to_degrees(), pi.to_degrees(), y.to_degrees()],
            ));
        }
    });
    out
}

/// A Group 2's position (N, E, D [m]) and attitude (roll, pitch, heading [deg]) RMS.
type Rms = ([f32; 3], [f32; 3]);

/// The POS MV's Group 1 samples, and its Group 2s' RMS.
fn posmv_samples(file: &Path) -> (Vec<Sample>, Vec<Rms>) {
    let bytes = std::fs::read(file).unwrap();
    let mut f: posmv::Framer = posmv::Framer::new();
    let (mut nav, mut rms) = (Vec::new(), Vec::new());
    let mut take = |g: &posmv::Group<&[u8]>| match g.id() {
        1 => {
            let n = posmv::Navigation::parse(g).unwrap();
            let [lat, lon, h] = n.lla;
            // Time 1 (UTC seconds of the week) as it is: both files share it.
            nav.push((
                (n.time.time1 * 1e9).round() as i64,
                [lat.to_radians(), lon.to_radians(), h],
                n.rph,
            ));
        }
        2 => {
            let m = posmv::Metrics::parse(g).unwrap();
            rms.push((m.position_rms, m.attitude_rms));
        }
        _ => {}
    };
    f.consume(&bytes, |it| {
        if let Item::Group(g) = it.item {
            take(&g);
        }
    });
    f.finish();
    while let Some(it) = f.next() {
        if let Item::Group(g) = it.item {
            take(&g);
        }
    }
    (nav, rms)
}

/// Reported minus twin, as north, east, down [m] and roll, pitch, heading [deg].
fn difference(a: &Sample, b: &Sample) -> [f64; 6] {
    let (m, n) = radii(a.1[0]);
    let wrap = |d: f64| d - 360.0 * (d / 360.0).round();
    [
        (b.1[0] - a.1[0]) * m,
        (b.1[1] - a.1[1]) * n * a.1[0].cos(),
        -(b.1[2] - a.1[2]),
        wrap(b.2[0] - a.2[0]),
        wrap(b.2[1] - a.2[1]),
        wrap(b.2[2] - a.2[2]),
    ]
}

/// table1 as a POS MV survey with white noise (2 cm, 0.03 deg) and the POS MV RTK preset
/// (3/6 cm, 0.01/0.02 deg, 30 s) on top, against the same scenario and seed without it: each
/// VN-200 frame and each POS MV Group 1 differs from its twin by exactly the error that
/// `nav-errors.csv` records for that sample (positions to 1 mm, the VN-200's f32 attitude to
/// 5e-5 deg); the errors are of the declared size and wander (one 5 ms step moves them by a
/// few % of their sigma); Group 2 states the white and correlated sigmas together.
#[test]
fn the_ins_outputs_carry_the_correlated_errors() {
    let mut plain = Scenario::load("table1").unwrap();
    plain.ins.kind = "posmv".into();
    plain.ins.pos_sigma_m = 0.02;
    plain.ins.att_sigma_deg = 0.03;
    let mut wander = plain.clone();
    wander.ins.correlated = CorrelatedSpec {
        preset: Some("posmv-rtk".into()),
        ..Default::default()
    };
    let (a, b) = (
        common::tmp("nav-errors", "plain"),
        common::tmp("nav-errors", "wander"),
    );
    spherecal_tools::synth::synth_ins(&plain, &a).unwrap();
    spherecal_tools::synth::synth_ins(&wander, &b).unwrap();
    assert!(!a.join("nav-errors.csv").exists());
    let text = std::fs::read_to_string(b.join("nav-errors.csv")).unwrap();
    let truth: Vec<[f64; 6]> = text
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            core::array::from_fn(|i| v[i + 1])
        })
        .collect();
    let tol = [1e-3, 1e-3, 1e-3, 5e-5, 5e-5, 5e-5];
    let (va, vb) = (
        vn200_samples(&a.join("ins.bin")),
        vn200_samples(&b.join("ins.bin")),
    );
    assert_eq!((va.len(), vb.len()), (truth.len(), truth.len()));
    let (pa, ra) = posmv_samples(&a.join("ins.posmv"));
    let (pb, rb) = posmv_samples(&b.join("ins.posmv"));
    assert_eq!((pa.len(), pb.len()), (truth.len(), truth.len()));
    for (what, xa, xb) in [("VN-200", &va, &vb), ("POS MV", &pa, &pb)] {
        for (k, ((sa, sb), t)) in xa.iter().zip(xb).zip(&truth).enumerate() {
            assert_eq!(sa.0, sb.0, "{what} sample {k}: the same time");
            let d = difference(sa, sb);
            for i in 0..6 {
                assert!(
                    (d[i] - t[i]).abs() < tol[i],
                    "{what} sample {k} axis {i}: {} vs {}",
                    d[i],
                    t[i]
                );
            }
        }
    }
    // Of the declared size (one realisation over ~70 s with tau = 30 s: only loosely), and
    // slow: a 5 ms step moves each by ~sigma sqrt(2 dt / tau) = 1.8 % of sigma.
    let sig = [0.03, 0.03, 0.06, 0.01, 0.01, 0.02];
    for i in 0..6 {
        let rms = (truth.iter().map(|t| t[i] * t[i]).sum::<f64>() / truth.len() as f64).sqrt();
        let step = (truth
            .windows(2)
            .map(|w| (w[1][i] - w[0][i]).powi(2))
            .sum::<f64>()
            / (truth.len() - 1) as f64)
            .sqrt();
        eprintln!(
            "axis {i}: RMS {rms:.4}, RMS step {step:.2e} (sigma {})",
            sig[i]
        );
        assert!(
            rms > 0.1 * sig[i] && rms < 3.0 * sig[i],
            "axis {i}: RMS {rms}"
        );
        let want = sig[i] * (2.0 * 0.005 / 30.0f64).sqrt();
        assert!(
            step > 0.8 * want && step < 1.25 * want,
            "axis {i}: RMS step {step} vs {want}"
        );
    }
    // Group 2: sqrt(white^2 + correlated^2) per axis.
    let (pos_rms, att_rms) = rb[0];
    let h = (0.02f64.powi(2) + 0.03f64.powi(2)).sqrt();
    let v = (0.02f64.powi(2) + 0.06f64.powi(2)).sqrt();
    let want = [h, h, v];
    for i in 0..3 {
        assert!(
            (f64::from(pos_rms[i]) - want[i]).abs() < 1e-6,
            "{pos_rms:?}"
        );
    }
    let rp = (0.03f64.powi(2) + 0.01f64.powi(2)).sqrt();
    let hd = (0.03f64.powi(2) + 0.02f64.powi(2)).sqrt();
    for (i, w) in [rp, rp, hd].iter().enumerate() {
        assert!((f64::from(att_rms[i]) - w).abs() < 1e-6, "{att_rms:?}");
    }
    assert!(ra
        .iter()
        .all(|(p, _)| (f64::from(p[0]) - 0.02).abs() < 1e-6));
    // The SBET holds the same samples as the real-time groups, errors and all; its smrmsg
    // states what Group 2 states, each second.
    let sbet = std::fs::read(b.join("sbet_ins.out")).unwrap();
    let recs: Vec<_> = sbet
        .chunks_exact(spherecal_hal::sbet::RECORD)
        .map(|c| spherecal_hal::sbet::SbetRecord::parse(c.try_into().unwrap()))
        .collect();
    assert_eq!(recs.len(), pb.len());
    let wrap = |d: f64| d - 360.0 * (d / 360.0).round();
    for (r, g) in recs.iter().zip(&pb) {
        assert!((r.lat - g.1[0]).abs() < 1e-12 && (r.lon - g.1[1]).abs() < 1e-12);
        assert!((r.h - g.1[2]).abs() < 1e-9);
        let rph = [r.roll, r.pitch, r.heading()].map(f64::to_degrees);
        for i in 0..3 {
            assert!(wrap(rph[i] - g.2[i]).abs() < 1e-9, "{rph:?} {:?}", g.2);
        }
    }
    let rms = std::fs::read(b.join("smrmsg_ins.out")).unwrap();
    let n = rms.len() / spherecal_hal::sbet::SMRMSG_RECORD;
    assert!(
        (n as f64 - truth.len() as f64 / 200.0).abs() <= 2.0,
        "{n} records"
    );
    let pos0 = f64::from_le_bytes(rms[8..16].try_into().unwrap());
    let hd0 = f64::from_le_bytes(rms[72..80].try_into().unwrap());
    assert!((pos0 - h).abs() < 1e-12 && (hd0 - hd * 60.0).abs() < 1e-9);
    std::fs::remove_dir_all(a).unwrap();
    std::fs::remove_dir_all(b).unwrap();
}

/// The synthesised SBET (and its smrmsg, found beside it) calibrates like the streams: table1
/// as a POS MV survey with white INS noise, `calibrate --sbet` converges within 3 sigma of
/// the truth, weighting by the smrmsg.
#[test]
fn the_synthesised_sbet_calibrates() {
    let mut s = Scenario::load("table1").unwrap();
    s.ins.kind = "posmv".into();
    s.ins.pos_sigma_m = 0.01;
    s.ins.att_sigma_deg = 0.01;
    let dir = common::tmp("nav-errors", "sbet");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let report = dir.join("report.json");
    let out = common::stdout_of(
        common::spherecal()
            .arg("calibrate")
            .arg("--pcap")
            .arg(dir.join("lidar.pcap"))
            .arg("--sbet")
            .arg(dir.join("sbet_ins.out"))
            // The simulator's positions are WGS 84 (an SBET does not say its datum).
            .args(["--trajectory-datum", "WGS84"])
            .arg("--site")
            .arg(dir.join("site.toml"))
            .arg("--report")
            .arg(&report),
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["converged"], true, "{out}");
    assert!(
        r["inputs"]["accuracy"]["file"]
            .as_str()
            .is_some_and(|f| f.ends_with("smrmsg_ins.out")),
        "{}",
        r["inputs"]
    );
    let (got, sigma) = six_and_sigmas(&r);
    let t = s.mount.truth.deg_m().0;
    for i in 0..6 {
        assert!(
            (got[i] - t[i]).abs() < 3.0 * sigma[i] + 1e-4,
            "{i}: {} vs {} (sigma {})",
            got[i],
            t[i],
            sigma[i]
        );
    }
    std::fs::remove_dir_all(dir).unwrap();
}

/// The report's six with their sigmas.
fn six_and_sigmas(r: &serde_json::Value) -> ([f64; 6], [f64; 6]) {
    let sig = &r["sigma"];
    let s: Vec<f64> = ["roll", "pitch", "heading"]
        .iter()
        .map(|k| sig["boresight_deg"][k].as_f64().unwrap())
        .chain(
            ["x", "y", "z"]
                .iter()
                .map(|k| sig["lever_arm_m"][k].as_f64().unwrap()),
        )
        .collect();
    (common::report_deg_m(r), s.try_into().unwrap())
}

/// The paper's real survey as table1-real simulates it (POS MV errors at the smrmsg's levels,
/// wandering over 30 s): the site declares them (`[ins.correlated]`), the calibration
/// estimates them with the mounting and claims a solution within 3 sigma of the truth, names
/// the model in its report; the same survey without the declaration (the white-noise model)
/// is refused by its own consistency tests; a sphere surveyed 20 cm off is refused, named.
#[test]
fn table1_real_calibrates_under_the_navigation_model() {
    let s = Scenario::load("table1-real").unwrap();
    let dir = common::tmp("nav-errors", "table1-real");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let site = std::fs::read_to_string(dir.join("site.toml")).unwrap();
    assert!(site.contains("[ins.correlated]"), "{site}");
    // `calibrate` with `site`, its report to `report`: exit code and printed result.
    let calibrate_from = |ins: &[&str], site: &Path, report: &Path| {
        let out = common::spherecal()
            .arg("calibrate")
            .arg("--pcap")
            .arg(dir.join("lidar.pcap"))
            .args(ins)
            .arg("--site")
            .arg(site)
            .arg("--report")
            .arg(report)
            .arg("--html")
            .arg(report.with_extension("html"))
            .output()
            .unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
        )
    };
    // On two cores (each evaluation's rows in two halves side by side) the solve is one core's.
    let inp = common::survey_inputs(&dir);
    let settings =
        spherecal_tools::session::settings_for(&inp.site, inp.lidar(), false, inp.margin);
    assert!(settings.nav.is_some());
    common::same_on_two_cores(&inp, &settings);
    let ins_bin = dir.join("ins.bin");
    let stream = ["--ins", ins_bin.to_str().unwrap()];
    let calibrate = |site: &Path, report: &Path| calibrate_from(&stream, site, report);
    let report = dir.join("report.json");
    let (code, out) = calibrate(&dir.join("site.toml"), &report);
    assert!(matches!(code, Some(0 | 3)), "{out}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["converged"], true, "{out}");
    assert!(
        r["navigation"]["source"]
            .as_str()
            .is_some_and(|s| s.starts_with("site [ins.correlated]")),
        "{}",
        r["navigation"]["source"]
    );
    assert!(out.contains("navigation errors:"), "{out}");
    let html = std::fs::read_to_string(report.with_extension("html")).unwrap();
    assert!(
        html.contains("<h2>Navigation errors</h2>") && html.contains("centre moved N, E, D"),
        "the HTML page has no navigation section"
    );
    // The corrections are an output: every piece with a finite sigma, within 1-25 mm.
    let c = r["navigation"]["corrections"].as_array().unwrap();
    assert!(c.len() > 20, "{} pieces", c.len());
    for p in c {
        for s in p["position_sigma_m"].as_array().unwrap() {
            let s = s.as_f64().unwrap();
            assert!((0.001..0.025).contains(&s), "{p}");
        }
    }
    let (got, sigma) = six_and_sigmas(&r);
    let t = s.mount.truth.deg_m().0;
    for i in 0..6 {
        assert!(
            (got[i] - t[i]).abs() < 3.0 * sigma[i],
            "{i}: {} vs {} (sigma {})",
            got[i],
            t[i],
            sigma[i]
        );
    }
    // The site declares nothing: the model is what the INS states of itself, the POS MV's
    // Group 2 in its stream, the SBET's smrmsg beside it (claimed within 3 sigma either way),
    // else the INS kind's default.
    let plain = site.split("\n[noise]").next().unwrap();
    let undeclared = dir.join("site-undeclared.toml");
    std::fs::write(&undeclared, plain).unwrap();
    let sbet = dir.join("sbet_ins.out");
    let posmv = dir.join("ins.posmv");
    // The same stream from a unit whose boards configured the Common group only (no TimeStartup,
    // no YprU / PosU): it states nothing.
    let bytes = std::fs::read(&ins_bin).unwrap();
    let unstated = dir.join("ins-common-only.bin");
    std::fs::write(
        &unstated,
        common::vn200::without_startup(&bytes, &common::vn200::frames(&bytes)),
    )
    .unwrap();
    let unstated = ["--ins", unstated.to_str().unwrap()];
    for (ins, from) in [
        (&["--posmv", posmv.to_str().unwrap()][..], "POS MV Group 2"),
        (
            &[
                "--sbet",
                sbet.to_str().unwrap(),
                "--trajectory-datum",
                "WGS84",
            ][..],
            "POSPac smrmsg",
        ),
        (&stream[..], "VN-200 Ins.PosU and Attitude.YprU"),
        (&unstated[..], "preset \"vn200-gnss\""),
    ] {
        let report = dir.join("report-undeclared.json");
        let (code, out) = calibrate_from(ins, &undeclared, &report);
        assert!(matches!(code, Some(0 | 3)), "{from}: {out}");
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        let source = r["navigation"]["source"].as_str().unwrap_or_default();
        assert!(source.contains(from), "{source}");
        // The stated sigmas are the survey's (1.6/1.5/3.3 cm with the white 2 mm on top);
        // the Common-only VN-200 stream states none: its kind's default (metre level), sigmas
        // to match.
        let p = &r["navigation"]["position_sigma_m"];
        if from.contains("vn200-gnss") {
            assert_eq!(p[0], 2.5, "{p}");
            assert!(
                r["sigma"]["lever_arm_m"]["z"].as_f64().unwrap() > 0.1,
                "{}",
                r["sigma"]
            );
            continue;
        }
        // A VN-200's PosU is one number: the simulator states the largest axis's.
        let h = if from.contains("PosU") {
            0.030..0.036
        } else {
            0.014..0.019
        };
        assert!(
            h.contains(&p[0].as_f64().unwrap()) && (0.030..0.036).contains(&p[1].as_f64().unwrap()),
            "{from}: {p}"
        );
        let (got, sigma) = six_and_sigmas(&r);
        for i in 0..6 {
            assert!(
                (got[i] - t[i]).abs() < 3.0 * sigma[i],
                "{from} {i}: {} vs {} (sigma {})",
                got[i],
                t[i],
                sigma[i]
            );
        }
    }
    // The white-noise model declared on the same survey: refused (the passes disagree beyond
    // it).
    let white = dir.join("site-white.toml");
    std::fs::write(
        &white,
        format!("{plain}\n[ins.correlated]\npreset = \"white\"\n"),
    )
    .unwrap();
    let report = dir.join("report-white.json");
    let (code, out) = calibrate(&white, &report);
    assert_eq!(code, Some(1), "a refusal exits 1: {out}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["converged"], false, "{}", r["reason"]);
    assert!(r["navigation"].is_null(), "{}", r["navigation"]);
    // S1 surveyed 20 cm north of where it stands: refused, S1 named with its disagreement.
    let lat = |t: &str| -> f64 {
        let after = t.split("id = \"S1\"").nth(1).unwrap();
        let l = after.lines().find(|l| l.starts_with("lat_deg")).unwrap();
        l.split('=').nth(1).unwrap().trim().parse().unwrap()
    };
    let moved = site.replacen(
        &format!("lat_deg = {}", lat(&site)),
        &format!("lat_deg = {}", lat(&site) + 0.2 / 111_200.0),
        1,
    );
    assert_ne!(moved, site);
    let off = dir.join("site-off.toml");
    std::fs::write(&off, moved).unwrap();
    let (code, text) = calibrate(&off, &dir.join("report-off.json"));
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("sphere S1's surveyed centre disagrees"),
        "{text}"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

/// A fault beyond the declared model: table1-real's INS jumps 20 cm down 3.5 s into the scan
/// (during the first pass, spheres in view) and stays there: refused, the jump named with
/// its time and size, instead of a lever arm bent by 10 cm.
#[test]
fn an_ins_jump_beyond_the_model_is_refused() {
    let mut s = Scenario::load("table1-real").unwrap();
    s.ins.position_jumps = vec![[3.5, 0.0, 0.0, 0.2]];
    let dir = common::tmp("nav-errors", "jump");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let out = common::spherecal()
        .arg("calibrate")
        .args(common::survey_args(&dir))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("the navigation jumps at GPS"), "{text}");
    std::fs::remove_dir_all(dir).unwrap();
}

/// A held clock offset the data contradict is refused under the navigation model too (the
/// INS 20 ms late on table1-real); free, the offset is found within 3 sigma. (The held run's
/// own extraction keeps what agrees with the held value: on this survey the free fit on its
/// returns moves the offset by 4.2 +- 2.0 ms only, so the held value is tested against a free
/// solve, `Session::free_offset`.)
#[test]
fn a_held_clock_the_data_contradict_is_refused_under_the_model() {
    let mut s = Scenario::load("table1-real").unwrap();
    s.ins.time_offset_s = 0.02;
    let dir = common::tmp("nav-errors", "held-clock");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let run = |hold: bool| {
        let report = dir.join(format!("r-{hold}.json"));
        let mut c = common::spherecal();
        c.arg("calibrate")
            .args(common::survey_args(&dir))
            .arg("--report")
            .arg(&report);
        if hold {
            c.arg("--hold-time-offset");
        }
        let out = c.output().unwrap();
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            r,
        )
    };
    let (code, text, _) = run(true);
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("the time offset held is contradicted"),
        "{text}"
    );
    let (code, text, r) = run(false);
    assert!(matches!(code, Some(0 | 3)), "{text}");
    let dt = r["time_offset_s"].as_f64().unwrap();
    let sigma = r["sigma"]["time_offset_s"].as_f64().unwrap();
    assert!((dt - 0.02).abs() < 3.0 * sigma, "{dt} +- {sigma}");
    std::fs::remove_dir_all(dir).unwrap();
}

//! Faults found from outside (issue 46), each rebuilt here from its description, not from the
//! files it was found on: INS data lost (whole frames cut, dropped, a silent port, a bag's
//! dropped and unparsable messages) is a gap, never a clock step.

use crate::common;
use crate::common::text;
use crate::common::vn200::{frame_time_s, frames, without_startup};

use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::report::Report;
use std::path::{Path, PathBuf};
use std::process::Output;

fn synth(base: &str, name: &str, edit: impl FnOnce(&mut Scenario)) -> (PathBuf, Scenario) {
    let mut s = Scenario::load(base).unwrap();
    edit(&mut s);
    let d = common::tmp("faults", name);
    spherecal_tools::synth::synth(&s, &d).unwrap();
    (d, s)
}

/// `calibrate` of the survey in `d` with the INS given by `ins` (`--ins FILE` or `--posmv
/// FILE`), writing its report to `report`: its output and report.
fn calibrate_as(
    d: &Path,
    ins: [&std::ffi::OsStr; 2],
    report: &Path,
    extra: &[&str],
) -> (Output, Report) {
    let _ = std::fs::remove_file(report);
    let out = common::spherecal()
        .arg("calibrate")
        .arg("--pcap")
        .arg(d.join("lidar.pcap"))
        .args(ins)
        .arg("--site")
        .arg(d.join("site.toml"))
        .arg("--report")
        .arg(report)
        .args(extra)
        .output()
        .unwrap();
    let r = std::fs::read_to_string(report).unwrap_or_else(|_| panic!("no report: {}", text(&out)));
    (out, serde_json::from_str(&r).unwrap())
}

/// `calibrate` of the survey in `d` with the VN-200 stream `ins`.
fn calibrate(d: &Path, ins: &Path, extra: &[&str]) -> (Output, Report) {
    let report = ins.with_extension("report.json");
    calibrate_as(d, ["--ins".as_ref(), ins.as_os_str()], &report, extra)
}

/// Every parameter within `k` of its reported sigma of the truth.
fn within_sigmas(r: &Report, s: &Scenario, k: f64, what: &str) {
    let (got, want, sg) = (r.deg_m(), s.mount.truth.deg_m().0, r.sigma.deg_m());
    for i in 0..6 {
        assert!(
            (got[i] - want[i]).abs() < k * sg[i],
            "{what}: parameter {i}: {} vs {} (sigma {})",
            got[i],
            want[i],
            sg[i]
        );
    }
}

/// The frames at `at` whose index `keep` accepts, back to back (whole frames left out).
fn keep_frames(ins: &[u8], at: &[usize], keep: impl Fn(usize, f64) -> bool) -> Vec<u8> {
    let t0 = frame_time_s(ins, at[0]);
    let mut out = Vec::with_capacity(ins.len());
    for (k, &i) in at.iter().enumerate() {
        if keep(k, frame_time_s(ins, i) - t0) {
            out.extend_from_slice(&ins[i..i + common::vn200::FRAME]);
        }
    }
    out
}

/// A 2 s hole of whole frames 30 s in (the port silent), and 25 frames dropped one by one (a
/// VN-200 whose output outruns its baud drops whole messages), in the stream as the boards
/// configure it (with TimeStartup) and as older ones sent it (TimeGps alone): each is data lost,
/// counted, not a clock step, and the survey calibrates within 3 sigma. The same stream with its
/// GPS time stepped by +23 ms (not a whole number of periods) is still refused as a step.
#[test]
fn whole_frames_lost_are_gaps_not_clock_steps() {
    let (d, s) = synth("table1-noisy", "lost-frames", |_| {});
    let ins = std::fs::read(d.join("ins.bin")).unwrap();
    let at = frames(&ins);
    assert_eq!(at.len() * common::vn200::FRAME, ins.len());
    // 25 frames spread over the stream, none next to another (a xorshift: the test's own).
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let mut dropped = std::collections::BTreeSet::new();
    while dropped.len() < 25 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let k = 100 + (x % (at.len() as u64 - 200)) as usize;
        if !dropped.contains(&(k - 1)) && !dropped.contains(&(k + 1)) {
            dropped.insert(k);
        }
    }
    let hole = keep_frames(&ins, &at, |_, t| !(30.0..32.0).contains(&t));
    let drops = keep_frames(&ins, &at, |k, _| !dropped.contains(&k));
    let all: Vec<usize> = (0..hole.len() / common::vn200::FRAME)
        .map(|k| k * common::vn200::FRAME)
        .collect();
    let hole_old = without_startup(&hole, &all);
    let all: Vec<usize> = (0..drops.len() / common::vn200::FRAME)
        .map(|k| k * common::vn200::FRAME)
        .collect();
    let drops_old = without_startup(&drops, &all);
    for (name, bytes, lost) in [
        ("hole", hole, 400),
        ("drops", drops, 25),
        ("hole-gps-only", hole_old, 400),
        ("drops-gps-only", drops_old, 25),
    ] {
        let path = d.join(format!("{name}.bin"));
        std::fs::write(&path, bytes).unwrap();
        let (o, r) = calibrate(&d, &path, &[]);
        let t = text(&o);
        assert!(common::claimed(&o), "{name}: {t}");
        let st = &r.inputs.as_ref().unwrap().ins_state;
        assert_eq!(st.clock_step_count, 0, "{name}: {:?}", st.clock_steps);
        assert_eq!(st.lost_samples, lost, "{name}");
        assert!(
            t.contains(&format!(
                "{lost} samples missing (lost data, not clock steps)"
            )),
            "{name}: {t}"
        );
        within_sigmas(&r, &s, 3.0, name);
    }
    std::fs::remove_dir_all(d).unwrap();

    // A real step of the GPS time, 23 ms, in the older output: found and refused.
    let (d, _) = synth("table1-noisy", "step-gps-only", |s| {
        s.ins.clock_steps = vec![[31.0, 0.023]];
    });
    let ins = std::fs::read(d.join("ins.bin")).unwrap();
    let old = d.join("gps-only.bin");
    std::fs::write(&old, without_startup(&ins, &frames(&ins))).unwrap();
    let (o, r) = calibrate(&d, &old, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let reason = r.reason.unwrap();
    assert!(
        reason.starts_with("the INS clock stepped by +23.0 ms 31.0 s into the LiDAR data"),
        "{reason}"
    );
    std::fs::remove_dir_all(d).unwrap();
}

/// A ROS 2 bag whose recorder dropped 0.2 % of the CommonGroup messages and holds others cut
/// short (the reader counts them "not parsed"): data lost, not clock steps; it calibrates as
/// the whole bag does.
#[test]
fn a_bag_with_dropped_and_unparsable_ins_messages_calibrates() {
    let (d, s) = synth("table1", "bag-drops", |_| {});
    let bag = d.join("rec");
    let o = std::process::Command::new("python3")
        .arg(common::repo_root().join("scripts/ros2-bag.py"))
        .arg(&d)
        .arg(&bag)
        .args(["--drop-ins-every", "500", "--garble-ins-every", "700"])
        .output()
        .expect("python3");
    assert!(
        common::claimed(&o),
        "scripts/ros2-bag.py needs python3 with rosbags==0.11.9 and mcap (scripts/test.sh installs them): {}",
        text(&o)
    );
    let report = d.join("bag.json");
    let o = common::spherecal()
        .arg("calibrate")
        .arg("--bag")
        .arg(&bag)
        .arg("--site")
        .arg(d.join("site.toml"))
        .args(["--allow-unlocked-clock", "--search-time-offset", "0.5"])
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    let t = text(&o);
    assert!(common::claimed(&o), "{t}");
    // 12901 frames: every 500th left out (25), and the 1st, 701st ... cut short (19); the
    // first one lost has no sample before it, so 43 are missing between those read.
    assert!(t.contains("12857 CommonGroup messages"), "{t}");
    assert!(t.contains("19 messages not parsed"), "{t}");
    assert!(
        t.contains("43 samples missing (lost data, not clock steps)"),
        "{t}"
    );
    let r = Report::parse(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r.inputs.as_ref().unwrap().ins_state.clock_step_count, 0);
    common::assert_within(&r.deg_m(), &s.mount.truth.deg_m().0, 1e-3, "bag with drops");
    std::fs::remove_dir_all(d).unwrap();
}

/// `site` with sphere `id` moved `east_m` east and declaring `sigma_m`.
fn resurveyed(site: &str, id: &str, east_m: f64, sigma_m: f64) -> String {
    let mut v: toml::Table = toml::from_str(site).unwrap();
    let sp = v
        .get_mut("sphere")
        .and_then(|s| s.as_array_mut())
        .unwrap()
        .iter_mut()
        .find(|s| s["id"].as_str() == Some(id))
        .unwrap();
    let lat = sp["lat_deg"].as_float().unwrap().to_radians();
    // WGS 84 prime vertical radius: a metre east in degrees of longitude.
    let n = 6_378_137.0 / (1.0 - 6.694_379_990_14e-3 * lat.sin().powi(2)).sqrt();
    let lon = sp["lon_deg"].as_float().unwrap() + (east_m / (n * lat.cos())).to_degrees();
    let sp = sp.as_table_mut().unwrap();
    sp.insert("lon_deg".into(), toml::Value::Float(lon));
    sp.insert("sigma_m".into(), toml::Value::Float(sigma_m));
    toml::to_string(&v).unwrap()
}

/// A survey prior under white INS errors (table1-noisy's site: `preset = "white"`): S1
/// surveyed 2 cm off, declared to 3 cm, is claimed within 3 sigma (it was claimed 5.2 sigma
/// off with the centre held); 10 cm off declared to 1 cm is refused naming S1's survey.
#[test]
fn a_survey_sigma_applies_under_white_ins_errors() {
    let (d, s) = synth("table1-noisy", "white-survey", |_| {});
    let site = std::fs::read_to_string(d.join("site.toml")).unwrap();
    assert!(site.contains("preset = \"white\""), "{site}");
    let off = d.join("off.toml");
    std::fs::write(&off, resurveyed(&site, "S1", 0.02, 0.03)).unwrap();
    let report = d.join("off.json");
    let run = |site: &Path| common::calibrate_survey(&d, site, &report);
    let o = run(&off);
    let t = text(&o);
    assert!(common::claimed(&o), "{t}");
    assert!(
        t.contains("S1: centre moved") && t.contains("S2: centre held at its survey"),
        "{t}"
    );
    let r = Report::parse(&std::fs::read_to_string(&report).unwrap()).unwrap();
    within_sigmas(&r, &s, 3.0, "S1 2 cm off, declared 3 cm");
    // The centre's estimate moved towards the truth (2 cm west of the survey).
    let c = &r.navigation.as_ref().unwrap().centres[0];
    assert!(c.correction_m[1] < -0.005, "{c:?}");

    let bad = d.join("bad.toml");
    std::fs::write(&bad, resurveyed(&site, "S1", 0.10, 0.01)).unwrap();
    let o = run(&bad);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let r = Report::parse(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let reason = r.reason.unwrap();
    assert!(
        reason.starts_with("sphere S1's surveyed centre disagrees"),
        "{reason}"
    );
    std::fs::remove_dir_all(d).unwrap();
}

/// table1-real (a POS MV under its correlated model) on seed `seed` with `edit` made to its
/// INS, calibrated as a user runs it (`--posmv`), with `extra` options: output, report.
fn real_with(
    name: &str,
    seed: u64,
    edit: impl FnOnce(&mut Scenario),
    extra: &[&str],
) -> (PathBuf, Scenario, Output, Report) {
    let (d, s) = synth("table1-real", name, |s| {
        s.seed = seed;
        edit(s);
    });
    let (o, r) = calibrate_posmv(&d, extra);
    (d, s, o, r)
}

/// `calibrate` of the survey in `d` with its POS MV stream.
fn calibrate_posmv(d: &Path, extra: &[&str]) -> (Output, Report) {
    let report = d.join(format!("r{}.json", extra.len()));
    let posmv = d.join("ins.posmv");
    calibrate_as(d, ["--posmv".as_ref(), posmv.as_os_str()], &report, extra)
}

/// GPS seconds of the scenario's start plus `s`.
fn gps_at(sc: &Scenario, s: f64) -> f64 {
    sc.start().0 as f64 * 1e-9 + s
}

/// A 4 s multipath jump of 15 cm (north and east 10 cm, up 5 cm) in one pass of table1-real,
/// 33-37 s in: the survey with it is refused (a navigation jump); the stretch is located,
/// set aside by its time span and size (summary and report), and the rest claimed within 3
/// sigma. The same stretch excluded by hand gives the same claim, said as by hand.
#[test]
fn a_located_multipath_jump_is_set_aside_and_the_rest_claimed() {
    // In the simulator's world of five footprint sub-rays (in the Gaussian one, the rest is
    // claimed with pitch 3.03 sigma off: NOTES "Issue 46", session 39, open).
    let jump = |s: &mut Scenario| {
        s.ins.position_jumps = vec![[33.0, 0.1, 0.1, -0.05], [37.0, -0.1, -0.1, 0.05]];
        s.lidar.footprint_grid = false;
    };
    let (d, s, o, r) = real_with("multipath", 2, jump, &[]);
    let t = text(&o);
    assert!(common::claimed(&o), "{t}");
    assert_eq!(r.set_aside.len(), 1, "{:?}", r.set_aside);
    let sa = &r.set_aside[0];
    let (a, b) = (gps_at(&s, 33.0), gps_at(&s, 37.0));
    assert!(sa.from_gps_s <= a + 1.0 && sa.to_gps_s >= b - 1.0, "{sa:?}");
    assert!(sa.to_gps_s - sa.from_gps_s < 25.0, "{sa:?}");
    assert!(sa.why.contains("the navigation jumps"), "{sa:?}");
    assert!(t.contains("SET ASIDE: GPS "), "{t}");
    within_sigmas(&r, &s, 3.0, "jump set aside");
    // By hand: the span the user reads off the refusal, a few seconds wide.
    let span = format!("{:.1}..{:.1}", a - 1.0, b + 1.0);
    let (o, r) = calibrate_posmv(&d, &["--exclude", &span]);
    assert!(common::claimed(&o), "{}", text(&o));
    let hand = &r.set_aside[0];
    assert!(
        hand.why.contains("by hand") && hand.returns > 1000,
        "{hand:?}"
    );
    within_sigmas(&r, &s, 3.0, "jump excluded by hand");
    std::fs::remove_dir_all(d).unwrap();
}

/// A silent GNSS outage (the status unchanged, the error growing as a coasting INS's to 0.25 m
/// north, 0.3 m west, 0.1 m down and 0.1-0.15 deg, then snapping back) over 20-32 s of
/// table1-real (a sphere visit and into the next) on three seeds other than the scenario's,
/// and over 5-45 s (most of the survey) on one: each either claimed within 3 sigma, any
/// stretch set aside overlapping the outage, or refused; never a claim off by more.
#[test]
fn a_silent_gnss_outage_is_set_aside_or_refused_never_claimed_wrong() {
    // In the simulator's world of five footprint sub-rays (in the Gaussian one, seed 1's
    // 40 s outage is claimed with y 3.3 sigma off, S2's RMS 46 mm: NOTES "Issue 46", session
    // 39, open).
    let outage = |at: f64, dur: f64| {
        move |s: &mut Scenario| {
            s.ins.outages = vec![[at, dur, 0.25, -0.3, 0.1, 0.15, 0.1, -0.15]];
            s.lidar.footprint_grid = false;
        }
    };
    let runs: Vec<_> = std::thread::scope(|sc| {
        [
            (1u64, 20.0, 12.0),
            (3, 20.0, 12.0),
            (5, 20.0, 12.0),
            (1, 5.0, 40.0),
        ]
        .map(|(seed, at, dur)| {
            sc.spawn(move || {
                let name = format!("outage{seed}-{at}");
                (at, dur, real_with(&name, seed, outage(at, dur), &[]))
            })
        })
        .map(|h| h.join().unwrap())
    })
    .into_iter()
    .collect();
    for (at, dur, (d, s, o, r)) in runs {
        let t = text(&o);
        let what = format!("seed {}, {dur} s outage", s.seed);
        match o.status.code() {
            Some(0 | 3) => {
                within_sigmas(&r, &s, 3.0, &what);
                for sa in &r.set_aside {
                    assert!(
                        sa.to_gps_s > gps_at(&s, at) && sa.from_gps_s < gps_at(&s, at + dur),
                        "{what}: {sa:?}"
                    );
                }
            }
            Some(1) => assert!(r.reason.is_some(), "{what}: {t}"),
            c => panic!("{what}: {c:?}: {t}"),
        }
        std::fs::remove_dir_all(d).unwrap();
    }
}

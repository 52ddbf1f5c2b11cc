//! A Hesai PandarXT32 simulated (`synth --model xt32`: its data packets, GPS packets and angle
//! correction file from the same scenes as the Velodynes'): `decode` lists every return the
//! simulator labelled and no other; `calibrate --metadata` finds table1's and the drone's
//! mounting within 1e-3 of the truth with its GPS packets' PPS lock trusted; without the lock
//! the clock is refused unless `--allow-unlocked-clock`, and then its offset is searched.

use crate::common;
use spherecal_tools::config::scenario::Scenario;
use std::path::Path;

/// `spherecal calibrate` of a synth folder with its corrections, the report to `dir`.
fn calibrate(dir: &Path, extra: &[&str]) -> (std::process::Output, serde_json::Value) {
    let report = dir.join("report.json");
    let _ = std::fs::remove_file(&report);
    let out = common::spherecal()
        .arg("calibrate")
        .args(common::survey_args(dir))
        .arg("--metadata")
        .arg(dir.join("corrections.csv"))
        .arg("--report")
        .arg(&report)
        .args(extra)
        .output()
        .unwrap();
    let r = std::fs::read_to_string(&report)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or(serde_json::Value::Null);
    (out, r)
}

fn text(o: &std::process::Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The number after `key` in `out`.
fn count_after(out: &str, key: &str) -> u64 {
    let at = out
        .find(key)
        .unwrap_or_else(|| panic!("no {key:?} in {out}"))
        + key.len();
    out[at..]
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no number after {key:?} in {out}"))
}

#[test]
fn table1_and_the_drone_scanned_by_an_xt32_calibrate_to_the_truth() {
    for name in ["table1", "drone"] {
        let mut s = Scenario::load(name).unwrap();
        s.lidar.model = "xt32".into();
        let dir = common::tmp("hesai-sim", name);
        let truth = spherecal_tools::synth::synth(&s, &dir).unwrap();
        // The correction file is the manual's nominal XT32 table.
        let csv = std::fs::read_to_string(dir.join("corrections.csv")).unwrap();
        assert!(
            csv.starts_with("Channel,Elevation,Azimuth\n1,15,0\n2,14,0\n"),
            "{csv}"
        );
        assert!(csv.ends_with("32,-16,0\n"), "{csv}");
        // `decode` reads every packet and lists each labelled return once.
        let out = common::stdout_of(
            common::spherecal()
                .arg("decode")
                .arg(dir.join("lidar.pcap"))
                .arg("--metadata")
                .arg(dir.join("corrections.csv")),
        );
        assert!(out.contains("sensor: Hesai PandarXT32 (32 channels, 8 blocks per packet), return mode strongest, 600 rpm"), "{out}");
        let labels = spherecal_tools::synth::read_labels(&dir.join("labels.bin")).unwrap();
        assert_eq!(count_after(&out, "points: "), labels.len() as u64, "{out}");
        assert_eq!(
            count_after(&out, "data packets: "),
            truth.data_packets - truth.dropped_packets
        );
        let gps = count_after(&out, "GPS packets: ");
        assert_eq!(gps, truth.position_packets);
        assert!(
            out.contains(&format!("({gps} with the PPS locked)")),
            "{out}"
        );
        assert_eq!(count_after(&out, "skipped: "), 0);
        // `calibrate`: the truth, the clock trusted, the model named.
        let (o, r) = calibrate(&dir, &[]);
        assert_eq!(o.status.code(), Some(0), "{name}: {}", text(&o));
        assert!(
            text(&o).contains(&format!("clock: Hesai, {gps} GPS packets: {gps} with the PPS locked, {gps} with a valid $GPRMC (synchronised to GPS time)")),
            "{}",
            text(&o)
        );
        assert_eq!(r["inputs"]["lidar_model"], "PandarXT32");
        let got = common::report_deg_m(&r);
        eprintln!("{name} (XT32): {got:?}");
        common::assert_within(&got, &s.mount.truth.deg_m().0, 1e-3, name);
        assert!(r["time_offset_s"].as_f64().unwrap().abs() < 1e-3);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// An XT32 whose GPS packets say the PPS is not locked and whose clock runs 0.3 s ahead:
/// refused (exit 1) naming the clock; with `--allow-unlocked-clock` the offset is found within
/// 1 ms and the mounting within 1e-3.
#[test]
fn an_xt32_without_its_pps_lock_is_refused_unless_allowed() {
    let mut s = Scenario::load("table1").unwrap();
    s.lidar.model = "xt32".into();
    s.lidar.pps = "absent".into();
    s.lidar.clock_offset_s = 0.3;
    let dir = common::tmp("hesai-sim", "unlocked");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let (o, r) = calibrate(&dir, &["--search-time-offset", "0"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let reason = r["reason"].as_str().unwrap_or_default();
    assert!(
        reason.contains("not PPS-locked") && reason.contains("0 with the PPS locked"),
        "{reason}"
    );
    assert_eq!(r["inputs"]["clock_trusted"], false);
    // (A search of +-0.5 s: 5 starts, not the default 17.)
    let (o, r) = calibrate(
        &dir,
        &["--allow-unlocked-clock", "--search-time-offset", "0.5"],
    );
    assert!(common::claimed(&o), "{}", text(&o));
    let dt = r["time_offset_s"].as_f64().unwrap();
    assert!(
        (dt - s.true_time_offset_s()).abs() < 1e-3,
        "{dt} vs {}",
        s.true_time_offset_s()
    );
    common::assert_within(
        &common::report_deg_m(&r),
        &s.mount.truth.deg_m().0,
        1e-3,
        "unlocked XT32",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

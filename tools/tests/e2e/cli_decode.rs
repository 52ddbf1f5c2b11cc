//! `spherecal decode` as a user runs it: summary, CSV contract, and bad files.

use crate::common;

use std::collections::HashMap;

fn tmp(name: &str) -> std::path::PathBuf {
    common::tmp("cli-decode", name)
}

#[test]
fn decode_mrpt_summary_and_csv() {
    let pcap = common::test_data("vlp16/mrpt_vlp16_gps.pcap");
    let csv = tmp("mrpt.csv");
    let stdout = common::stdout_of(
        common::spherecal()
            .arg("decode")
            .arg(&pcap)
            .arg("--csv")
            .arg(&csv),
    );
    assert!(
        stdout.contains("data packets: 293 (strongest: 293)"),
        "{stdout}"
    );
    assert!(
        stdout.contains("position packets: 57 (PPS locked: 57)"),
        "{stdout}"
    );
    assert!(stdout.contains("points: 73486"), "{stdout}");
    assert!(
        stdout.contains("RMC times: 57 from 2016-01-21T08:18:02.00Z"),
        "{stdout}"
    );
    assert!(stdout.contains("skipped: 0"), "{stdout}");

    // The CSV against the independent decoding: same points, same raw values and times.
    let reference =
        std::fs::read_to_string(common::test_data("vlp16/mrpt_vlp16_gps.reference.csv")).unwrap();
    let mut want: HashMap<String, (String, String, String)> = HashMap::new();
    for l in reference.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        // time_us = packet time + offset, to the nanosecond; distance_m = raw * 0.002.
        let (us, frac) = f[5].split_once('.').unwrap();
        let t_ns = f[4].parse::<u64>().unwrap() * 1000
            + us.parse::<u64>().unwrap() * 1000
            + frac.parse::<u64>().unwrap();
        let mm = f[7].parse::<u64>().unwrap() * 2;
        want.insert(
            format!("{},{},{},{}", f[0], f[1], f[2], f[3]),
            (
                format!("{}.{:03}", t_ns / 1000, t_ns % 1000),
                format!("{}.{:03}", mm / 1000, mm % 1000),
                f[8].to_string(),
            ),
        );
    }
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "packet,block,sequence,laser,return,time_us,azimuth_deg,elevation_deg,distance_m,intensity,x_m,y_m,z_m"
    );
    let mut n = 0;
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        assert_eq!(f.len(), 13);
        let key = format!("{},{},{},{}", f[0], f[1], f[2], f[3]);
        let (t, d, i) = want
            .get(&key)
            .unwrap_or_else(|| panic!("row {key} not in the reference"));
        assert_eq!(
            (f[5], f[8], f[9]),
            (t.as_str(), d.as_str(), i.as_str()),
            "row {key}"
        );
        assert_eq!(f[4], "strongest");
        // Elevation from the manual's table for the laser id.
        let laser: usize = f[3].parse().unwrap();
        assert_eq!(
            f[7],
            [
                "-15", "1", "-13", "3", "-11", "5", "-9", "7", "-7", "9", "-5", "11", "-3", "13",
                "-1", "15"
            ][laser]
        );
        n += 1;
    }
    assert_eq!(n, want.len());
}

#[test]
fn missing_file_exits_2_with_the_path() {
    let out = common::spherecal()
        .args(["decode", "/nonexistent/capture.pcap"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/capture.pcap"), "{err}");
}

#[test]
fn wrong_magic_and_random_bytes_exit_2() {
    let p = tmp("notpcap.bin");
    std::fs::write(&p, b"this is not a capture file at all, just text\n").unwrap();
    let out = common::spherecal().arg("decode").arg(&p).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("notpcap.bin") && err.contains("offset 0: not a pcap or pcapng file"),
        "{err}"
    );

    // Random bytes (a fixed xorshift stream) behind a valid pcap magic.
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    let mut bytes = vec![
        0xD4, 0xC3, 0xB2, 0xA1, 2, 0, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xFF, 0xFF, 0, 0, 1, 0, 0, 0,
    ];
    for _ in 0..4096 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        bytes.push(x as u8);
    }
    let p = tmp("random.pcap");
    std::fs::write(&p, &bytes).unwrap();
    let out = common::spherecal().arg("decode").arg(&p).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    // Either a corrupt record stops it (exit 2, with an offset) or every record is a counted skip.
    match out.status.code() {
        Some(2) => assert!(err.contains("random.pcap: offset 24"), "{err}"),
        Some(0) => assert!(stdout.contains("data packets: 0"), "{stdout}"),
        c => panic!("exit {c:?}: {err}"),
    }
}

#[test]
fn truncated_capture_is_a_counted_skip() {
    let full = std::fs::read(common::test_data("vlp16/mrpt_vlp16_gps.pcap")).unwrap();
    let p = tmp("cut.pcap");
    // Cut inside the 11th record.
    std::fs::write(&p, &full[..24 + 10 * (16 + 1248) + 700]).unwrap();
    let out = common::spherecal().arg("decode").arg(&p).output().unwrap();
    // Said loudly, on both streams, with exit 2: the counts of what was read, then why not all.
    assert_eq!(out.status.code(), Some(2));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    // The record that is cut: where the counted skip says it starts.
    let at: u64 = stdout
        .split("truncated file: 1 (first at byte ")
        .nth(1)
        .and_then(|r| r.split(':').next())
        .and_then(|n| n.parse().ok())
        .expect("the skip's byte");
    assert!(at > 24 + 9 * 600 && at < 24 + 11 * (16 + 1248), "{at}");
    for text in [&stdout, &stderr] {
        assert!(
            text.contains(&format!(
                "is truncated: it ends inside the record at byte {at}"
            )),
            "{text}"
        );
        assert!(text.contains("cut short"), "{text}");
    }
    assert!(stdout.contains("skipped: 1"), "{stdout}");
    assert!(
        stdout.contains("truncated file: 1 (first at byte"),
        "{stdout}"
    );
}

/// `spherecal decode` of the real MRPT capture into `csv`.
fn decode_mrpt_capture_to(csv: &std::path::Path) {
    common::stdout_of(
        common::spherecal()
            .arg("decode")
            .arg(common::test_data("vlp16/mrpt_vlp16_gps.pcap"))
            .arg("--csv")
            .arg(csv),
    );
}

/// `spherecal decode --bag BAG --csv CSV`: its summary.
fn decode_bag_to(bag: &std::path::Path, csv: &std::path::Path) -> String {
    common::stdout_of(
        common::spherecal()
            .args(["decode", "--bag"])
            .arg(bag)
            .arg("--csv")
            .arg(csv),
    )
}

/// The real MRPT capture's data packets as a ROS 2 bag (written by rosbags from the capture:
/// tests/data/ros2/README.md): `decode --bag` writes the very CSV the capture gives (the
/// capture's is checked against an independent decoding above); a cut bag stops with the file
/// named, exit 2.
#[test]
fn a_bag_of_the_mrpt_capture_decodes_as_the_capture() {
    let bag = common::test_data("ros2/bags/mrpt_vlp16");
    let (from_bag, from_pcap) = (tmp("mrpt-bag.csv"), tmp("mrpt-pcap.csv"));
    let out = decode_bag_to(&bag, &from_bag);
    assert!(out.contains("data packets: 293 (strongest: 293)"), "{out}");
    assert!(
        out.contains("product byte 0x22, packet period agrees"),
        "{out}"
    );
    assert!(out.contains("points: 73486"), "{out}");
    decode_mrpt_capture_to(&from_pcap);
    assert!(std::fs::read(&from_bag).unwrap() == std::fs::read(&from_pcap).unwrap());
    let whole = std::fs::read(bag.join("mrpt_vlp16.mcap")).unwrap();
    let cut = tmp("cut.mcap");
    std::fs::write(&cut, &whole[..whole.len() / 2]).unwrap();
    let o = common::spherecal()
        .arg("decode")
        .arg(&cut)
        .output()
        .unwrap();
    // Cut short: what comes before the cut is decoded and the cut said (exit 2, as a truncated
    // capture).
    let err = String::from_utf8_lossy(&o.stderr);
    let printed = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cut.mcap is truncated") && printed.contains("points: "),
        "{printed}{err}"
    );
}

/// velodyne_pointcloud's clouds of the MRPT capture (written by scripts/ros2-bag.py --clouds,
/// which decodes the packets itself with the driver's conventions): every return is one the
/// capture's decoding has (same laser and distance), where the capture puts it up to the
/// driver's 0.01 deg azimuth rounding; the returns inside its 0.9 m min_range are the only
/// ones missing.
#[test]
fn a_bag_of_point_clouds_decodes_to_the_captures_returns() {
    let bag = common::test_data("ros2/bags/mrpt_vlp16_clouds.mcap");
    let (from_bag, from_pcap) = (tmp("mrpt-clouds.csv"), tmp("mrpt-pcap-2.csv"));
    let out = decode_bag_to(&bag, &from_bag);
    assert!(out.contains("point clouds: 2"), "{out}");
    assert!(out.contains("skipped: 0"), "{out}");
    decode_mrpt_capture_to(&from_pcap);
    let rows = |p: &std::path::Path| -> Vec<Vec<String>> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(String::from).collect())
            .collect()
    };
    let f = |r: &[String], i: usize| r[i].parse::<f64>().unwrap();
    // Columns: packet, block, sequence, laser, return, time, azimuth, elevation, distance,
    // intensity, x, y, z. The two clouds hold the first 2 x 76 packets.
    let pcap: Vec<Vec<String>> = rows(&from_pcap)
        .into_iter()
        .filter(|r| f(r, 0) < 152.0)
        .collect();
    let mut by_key: std::collections::HashMap<(String, String), Vec<&Vec<String>>> =
        Default::default();
    for r in &pcap {
        by_key
            .entry((r[3].clone(), r[8].clone()))
            .or_default()
            .push(r);
    }
    let clouds = rows(&from_bag);
    let in_range = pcap
        .iter()
        .filter(|r| (0.9..=130.0).contains(&f(r, 8)))
        .count();
    assert_eq!(clouds.len(), in_range, "returns within the driver's range");
    assert!(out.contains(&format!("points: {in_range}")), "{out}");
    let mut worst = 0f64;
    for c in &clouds {
        let d = f(c, 8);
        let bound = d * 0.005f64.to_radians() + 2e-6 * d + 1e-6;
        let near = by_key
            .get(&(c[3].clone(), c[8].clone()))
            .into_iter()
            .flatten()
            .map(|p| {
                let da = (f(p, 6) - f(c, 6)).abs();
                let da = da.min(360.0 - da);
                let e = ((f(p, 10) - f(c, 10)).powi(2)
                    + (f(p, 11) - f(c, 11)).powi(2)
                    + (f(p, 12) - f(c, 12)).powi(2))
                .sqrt();
                (da, e)
            })
            .filter(|(da, _)| *da <= 0.0051)
            .map(|(_, e)| e / bound)
            .fold(f64::INFINITY, f64::min);
        assert!(
            near <= 1.0,
            "cloud return {c:?}: nearest capture return {near} x the bound"
        );
        worst = worst.max(near);
    }
    assert!(worst > 0.5, "the rounding shows ({worst})");
}

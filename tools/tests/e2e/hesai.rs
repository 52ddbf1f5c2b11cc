//! `spherecal decode BAG --metadata CORRECTIONS.csv` on real Hesai packets (tests/data/hesai:
//! tier4/nebula's decoder test bags of `pandar_msgs/msg/PandarScan`) against the point clouds
//! nebula's decoder produced from the same bags (its `.pcd` ground truth).

use crate::common;
use std::collections::HashMap;
use std::path::PathBuf;

/// A vendored bag: folder, correction file, and nebula's test settings for it (the sensor's
/// and the test's range limits [m]).
struct Case {
    dir: &'static str,
    corrections: &'static str,
    range: (f64, f64),
    /// The return mode the bag's packets carry.
    mode: &'static str,
}

const CASES: [Case; 4] = [
    Case {
        dir: "xt16",
        corrections: "PandarXT16.csv",
        range: (0.05, 120.0),
        mode: "dual (last, strongest)",
    },
    Case {
        dir: "xt32",
        corrections: "PandarXT32.csv",
        range: (0.05, 120.0),
        mode: "dual (last, strongest)",
    },
    Case {
        dir: "qt64",
        corrections: "PandarQT64.csv",
        range: (0.1, 60.0),
        mode: "dual (first, last)",
    },
    Case {
        dir: "qt128",
        corrections: "PandarQT128.csv",
        range: (0.3, 50.0),
        mode: "dual (last, strongest)",
    },
];

/// nebula's `dual_return_distance_threshold` in its decoder test: of a firing's two returns
/// closer than this, only the second block's is kept [m].
const DUAL_THRESHOLD_M: f64 = 0.1;

fn paths(c: &Case) -> (PathBuf, PathBuf, PathBuf) {
    let dir = common::test_data(&format!("hesai/{}", c.dir));
    let mut bag = None;
    let mut pcd = None;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            bag = Some(p);
        } else if p.extension().is_some_and(|x| x == "pcd") {
            pcd = Some(p);
        }
    }
    (
        bag.unwrap(),
        pcd.unwrap(),
        common::test_data(&format!("hesai/{}", c.corrections)),
    )
}

/// A `.pcd` of `FIELDS x y z`, binary float32.
fn read_pcd(p: &PathBuf) -> Vec<[f64; 3]> {
    let b = std::fs::read(p).unwrap();
    let tag = b"DATA binary\n";
    let at = b.windows(tag.len()).position(|w| w == tag).unwrap() + tag.len();
    let head = String::from_utf8_lossy(&b[..at]);
    assert!(
        head.contains("FIELDS x y z\n") && head.contains("SIZE 4 4 4\n"),
        "{head}"
    );
    b[at..]
        .chunks_exact(12)
        .map(|c| {
            let f = |i: usize| f64::from(f32::from_le_bytes(c[i..i + 4].try_into().unwrap()));
            [f(0), f(4), f(8)]
        })
        .collect()
}

/// One CSV row as the test needs it.
struct Row {
    packet: u64,
    block: u64,
    channel: usize,
    distance: f64,
    xyz: [f64; 3],
    /// The rotation it belongs to, cut where its corrected azimuth passes 0 deg (nebula's
    /// `cut_angle` 0: a rotation holds (0, 360] deg).
    scan: i64,
}

/// The azimuth offsets of a correction file [deg].
fn offsets(p: &PathBuf) -> Vec<f64> {
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap().trim().parse().unwrap())
        .collect()
}

/// The CSV's rows, each with its rotation: the block azimuth (the row's azimuth less its
/// channel's offset) counts the rotations where it falls back; a corrected azimuth past 360 deg
/// (or at or below 0) is in the next (the previous) one.
fn rows(text: &str, off: &[f64]) -> Vec<Row> {
    let mut out = Vec::new();
    let (mut wraps, mut prev) = (0i64, None::<i64>);
    for l in text.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        let p = |i: usize| f[i].parse::<f64>().unwrap();
        let ch: usize = f[3].parse().unwrap();
        let block_az = ((p(6) - off[ch]) * 100.0).round().rem_euclid(36000.0) as i64;
        if prev.is_some_and(|q| block_az < q - 18000) {
            wraps += 1;
        }
        prev = Some(block_az);
        let corrected = block_az as f64 / 100.0 + off[ch];
        out.push(Row {
            packet: f[0].parse().unwrap(),
            block: f[1].parse().unwrap(),
            channel: ch,
            distance: p(8),
            xyz: [p(10), p(11), p(12)],
            scan: wraps + i64::from(corrected > 360.0) - i64::from(corrected <= 0.0),
        });
    }
    out
}

/// The rows nebula's test keeps: within the range limits, and of a firing's two returns
/// closer than the threshold only the second block's.
fn as_nebula_keeps(rows: &[Row], range: (f64, f64)) -> Vec<&Row> {
    let mut second: HashMap<(u64, u64, usize), f64> = HashMap::new();
    for r in rows.iter().filter(|r| r.block % 2 == 1) {
        second.insert((r.packet, r.block / 2, r.channel), r.distance);
    }
    rows.iter()
        .filter(|r| r.distance >= range.0 && r.distance <= range.1)
        .filter(|r| {
            r.block % 2 == 1
                || second
                    .get(&(r.packet, r.block / 2, r.channel))
                    .is_none_or(|d| (d - r.distance).abs() >= DUAL_THRESHOLD_M)
        })
        .collect()
}

/// Pair every reference point with a distinct row within 1 mm; the unpaired on both sides.
fn pair(want: &[[f64; 3]], got: &[&Row]) -> (usize, usize, f64) {
    let key = |p: &[f64; 3]| p.map(|v| (v * 1000.0).round() as i64);
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, r) in got.iter().enumerate() {
        grid.entry(key(&r.xyz)).or_default().push(i);
    }
    let mut used = vec![false; got.len()];
    let (mut missing, mut worst) = (0, 0.0f64);
    for w in want {
        let k = key(w);
        let mut best: Option<(f64, usize)> = None;
        for d in 0..27 {
            let c = [k[0] + d % 3 - 1, k[1] + d / 3 % 3 - 1, k[2] + d / 9 - 1];
            for &i in grid.get(&c).into_iter().flatten() {
                let e = (0..3)
                    .map(|a| (got[i].xyz[a] - w[a]).abs())
                    .fold(0.0, f64::max);
                if !used[i] && e <= 1e-3 && best.is_none_or(|b| e < b.0) {
                    best = Some((e, i));
                }
            }
        }
        match best {
            Some((e, i)) => {
                used[i] = true;
                worst = worst.max(e);
            }
            None => missing += 1,
        }
    }
    (missing, used.iter().filter(|u| !**u).count(), worst)
}

/// Every return of the rotation nebula's decoder wrote out, from each vendored bag: the same
/// points (none missing, none extra once nebula's range and dual-return filters are applied)
/// within 1 mm; the summary names the model and its return mode.
#[test]
fn every_bag_decodes_as_nebulas_ground_truth() {
    for c in &CASES {
        let (bag, pcd, corr) = paths(c);
        let csv = common::tmp("hesai", &format!("{}.csv", c.dir));
        let stdout = common::stdout_of(
            common::spherecal()
                .arg("decode")
                .arg(&bag)
                .arg("--metadata")
                .arg(&corr)
                .arg("--csv")
                .arg(&csv),
        );
        assert!(
            stdout.contains(&format!("return mode {},", c.mode)),
            "{stdout}"
        );
        let text = std::fs::read_to_string(&csv).unwrap();
        assert!(text.starts_with(
            "packet,block,sequence,laser,return,time_us,azimuth_deg,elevation_deg,distance_m,intensity,x_m,y_m,z_m\n"
        ));
        let all = rows(&text, &offsets(&corr));
        let kept = as_nebula_keeps(&all, c.range);
        let want = read_pcd(&pcd);
        // The rotation whose rows pair with every reference point, and none left over.
        let scans: std::collections::BTreeSet<i64> = kept.iter().map(|r| r.scan).collect();
        let found = scans.iter().find_map(|&s| {
            let of: Vec<&Row> = kept.iter().copied().filter(|r| r.scan == s).collect();
            let (missing, extra, worst) = pair(&want, &of);
            (missing == 0).then_some((s, of.len(), extra, worst))
        });
        let Some((scan, n, extra, worst)) = found else {
            panic!(
                "{}: no rotation holds all {} reference points",
                c.dir,
                want.len()
            );
        };
        assert_eq!(
            (n, extra),
            (want.len(), 0),
            "{}: rotation {scan} has {n} returns against nebula's {}",
            c.dir,
            want.len()
        );
        assert!(worst < 1e-4, "{}: {worst} m off nebula", c.dir);
    }
}

/// The packets of a bag, as a recorder on the sensor's link writes them: a classic pcap of
/// Ethernet + IPv4 + UDP frames to `port` (2368), `damage(i, payload)` applied first; with
/// `gps`, one GPS packet (UDP 10110) before the data.
fn as_pcap(
    bag: &std::path::Path,
    gps: Option<&[u8]>,
    mut damage: impl FnMut(usize, &mut Vec<u8>),
) -> Vec<u8> {
    use spherecal_hal::PacketSource;
    let b = spherecal_hal::rosbag::Bag::open(bag).unwrap();
    let mut src =
        spherecal_hal::rosbag::sources::ScanPackets::pandar(b.messages(&["/pandar_packets"]));
    let mut out = Vec::new();
    out.extend_from_slice(&0xa1b2_c3d4u32.to_le_bytes());
    out.extend_from_slice(&[2, 0, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    out.extend_from_slice(&65_535u32.to_le_bytes());
    out.extend_from_slice(&1u32.to_le_bytes());
    let frame = |out: &mut Vec<u8>, port: u16, payload: &[u8], t: u32| {
        let mut f = vec![0xff; 6];
        f.extend_from_slice(&[0x00, 0x50, 0x43, 0x00, 0x00, 0x01, 0x08, 0x00]);
        let ip_len = (20 + 8 + payload.len()) as u16;
        let mut ip = vec![
            0x45, 0, 0, 0, 0, 0, 0x40, 0, 64, 17, 0, 0, 192, 168, 1, 201, 255, 255, 255, 255,
        ];
        ip[2..4].copy_from_slice(&ip_len.to_be_bytes());
        f.extend_from_slice(&ip);
        f.extend_from_slice(&10_000u16.to_be_bytes());
        f.extend_from_slice(&port.to_be_bytes());
        f.extend_from_slice(&((8 + payload.len()) as u16).to_be_bytes());
        f.extend_from_slice(&[0, 0]);
        f.extend_from_slice(payload);
        out.extend_from_slice(&t.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&(f.len() as u32).to_le_bytes());
        out.extend_from_slice(&(f.len() as u32).to_le_bytes());
        out.extend_from_slice(&f);
    };
    if let Some(g) = gps {
        frame(&mut out, 10_110, g, 1_700_000_000);
    }
    let mut i = 0;
    while let Some(rec) = src.next_record().unwrap() {
        if let spherecal_hal::Record::Udp(d) = rec {
            let mut p = d.payload.to_vec();
            damage(i, &mut p);
            frame(&mut out, 2368, &p, 1_700_000_000 + i as u32);
            i += 1;
        }
    }
    out
}

/// The XT32 bag's packets as a pcap in the scratch folder of `group`, after one GPS packet
/// (the PandarQT manual's example date and time, position valid, PPS locked).
fn xt32_pcap(group: &str) -> PathBuf {
    let (bag, _, _) = paths(&CASES[1]);
    let mut gps = vec![0xDFu8; 512];
    gps[..14].copy_from_slice(b"\xff\xee912062354511");
    gps[14..18].fill(0);
    gps[506] = b'A';
    gps[507] = 1;
    let pcap = common::tmp(group, "xt32.pcap");
    std::fs::write(&pcap, as_pcap(&bag, Some(&gps), |_, _| {})).unwrap();
    pcap
}

/// The XT32's packets recorded from the link (a pcap, with the unit's GPS packet: the PandarQT
/// manual's example, PPS locked) decode row for row as from the bag; a QT128 packet damaged on
/// the way is skipped by its CRC-32; another unit's corrections, none, or a broken file are
/// refused (exit 2) naming what is wrong.
#[test]
fn a_capture_decodes_as_its_bag_and_damage_or_other_corrections_are_named() {
    let (bag, _, corr) = paths(&CASES[1]);
    let pcap = xt32_pcap("hesai");
    let listing = |input: &std::path::Path, name: &str| {
        let csv = common::tmp("hesai", name);
        let out = common::stdout_of(
            common::spherecal()
                .arg("decode")
                .arg(input)
                .arg("--metadata")
                .arg(&corr)
                .arg("--csv")
                .arg(&csv),
        );
        (out, std::fs::read_to_string(&csv).unwrap())
    };
    let (from_bag, bag_rows) = listing(&bag, "xt32-bag.csv");
    let (from_pcap, pcap_rows) = listing(&pcap, "xt32-pcap.csv");
    assert!(bag_rows == pcap_rows, "the listings differ");
    assert!(from_bag.contains("GPS packets: 0 "), "{from_bag}");
    assert!(
        from_pcap.contains("GPS packets: 1 (1 with the PPS locked)")
            && from_pcap.contains("the first at 2019-02-26T11:54:53Z"),
        "{from_pcap}"
    );

    // One QT128 packet with a body byte flipped.
    let (qbag, _, qcorr) = paths(&CASES[3]);
    let qpcap = common::tmp("hesai", "qt128-damaged.pcap");
    std::fs::write(
        &qpcap,
        as_pcap(&qbag, None, |i, p| {
            if i == 100 {
                p[500] ^= 0x10;
            }
        }),
    )
    .unwrap();
    let out = common::stdout_of(
        common::spherecal()
            .arg("decode")
            .arg(&qpcap)
            .arg("--metadata")
            .arg(&qcorr),
    );
    assert!(
        out.contains("data packets: 1799;")
            && out.contains("CRC-32: 1799 packets agree")
            && out.contains("Hesai CRC-32 mismatch"),
        "{out}"
    );

    let refused = |c: &mut std::process::Command| {
        let o = c.output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{o:?}");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let xt16 = common::test_data("hesai/PandarXT16.csv");
    let e = refused(
        common::spherecal()
            .arg("decode")
            .arg(&pcap)
            .arg("--metadata")
            .arg(&xt16),
    );
    assert!(
        e.contains("PandarXT32's (32 channels), the angle correction file lists 16"),
        "{e}"
    );
    let e = refused(common::spherecal().arg("decode").arg(&pcap));
    assert!(
        e.contains("PandarXT32 data packets") && e.contains("--metadata CORRECTIONS.csv"),
        "{e}"
    );
    let broken = common::tmp("hesai", "broken.csv");
    std::fs::write(&broken, "Channel,Elevation,Azimuth\n1,15,0\n2,thirteen,0\n").unwrap();
    let e = refused(
        common::spherecal()
            .arg("decode")
            .arg(&pcap)
            .arg("--metadata")
            .arg(&broken),
    );
    assert!(
        e.contains("line 3: channel 2's elevation is not a number"),
        "{e}"
    );
}

/// `georef` of a Hesai's capture (`--metadata CORRECTIONS.csv`): the XT32's real packets, its
/// clock taken as UTC (the GPS packet says the PPS is locked), against a trajectory moving
/// north at 2 m/s (an SBET, level, the mounting zero): every point of the LAS is a decoded
/// return (the same capture's `decode` listing, checked against nebula) at its firing time
/// (UTC + the 18 leap seconds) placed at the trajectory's position then, within 1 mm.
#[test]
fn georef_of_a_hesai_capture_puts_each_return_at_its_firing_time() {
    let (_, _, corr) = paths(&CASES[1]);
    let pcap = xt32_pcap("hesai-georef");
    let csv = common::tmp("hesai-georef", "xt32.csv");
    common::stdout_of(
        common::spherecal()
            .arg("decode")
            .arg(&pcap)
            .arg("--metadata")
            .arg(&corr)
            .arg("--csv")
            .arg(&csv),
    );
    // Each decoded return: UTC [ns since 1970] and x y z [m] in the sensor frame.
    let rows: Vec<(i64, [f64; 3])> = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let (us, frac) = f[5].split_once('.').unwrap();
            let ns = us.parse::<i64>().unwrap() * 1000 + frac.parse::<i64>().unwrap();
            let p = |i: usize| f[i].parse::<f64>().unwrap();
            (ns, [p(10), p(11), p(12)])
        })
        .collect();
    let (first, last) = (
        rows.iter().map(|r| r.0).min().unwrap(),
        rows.iter().map(|r| r.0).max().unwrap(),
    );
    // GPS time = UTC + 18 s (2017-2026) from the GPS epoch 1980-01-06.
    const GPS_UNIX_S: i64 = 315_964_800;
    let gps_s = |unix_ns: i64| (unix_ns as f64) * 1e-9 - GPS_UNIX_S as f64 + 18.0;
    let t_ref = gps_s(first);
    let week = (t_ref / 604_800.0).floor();
    // The trajectory: from the site's origin, north at 2 m/s, 200 Hz, a second either side.
    let (lat0, lon0, h0) = (48.38f64, -4.49f64, 52.0f64);
    let (a, e2) = (6_378_137.0f64, 6.694_379_990_14e-3f64);
    let s2 = lat0.to_radians().sin().powi(2);
    let m_radius = a * (1.0 - e2) / (1.0 - e2 * s2).powf(1.5) + h0;
    let v = 2.0;
    let mut sbet = Vec::new();
    let n = ((gps_s(last) - t_ref + 2.0) * 200.0) as i64;
    for k in 0..=n {
        let t = t_ref - 1.0 + k as f64 / 200.0;
        let north = v * (t - t_ref);
        let lat = lat0.to_radians() + north / m_radius;
        let rec = spherecal_hal::sbet::SbetRecord {
            tow_s: t - week * 604_800.0,
            lat,
            lon: lon0.to_radians(),
            h: h0,
            roll: 0.0,
            pitch: 0.0,
            platform_heading: 0.0,
            wander: 0.0,
        };
        sbet.extend_from_slice(&rec.emit());
    }
    let sbet_path = common::tmp("hesai-georef", "sbet.out");
    std::fs::write(&sbet_path, sbet).unwrap();
    let site = common::tmp("hesai-georef", "site.toml");
    std::fs::write(
        &site,
        format!(
            "leap_seconds = 18\n\n[origin]\nlat_deg = {lat0}\nlon_deg = {lon0}\nh_m = {h0}\n\n[[sphere]]\nid = \"S1\"\nlat_deg = 48.38009\nlon_deg = -4.49\nh_m = 53.0\nradius_m = 0.2\n\n[[sphere]]\nid = \"S2\"\nlat_deg = 48.37991\nlon_deg = -4.49\nh_m = 53.0\nradius_m = 0.2\n\n[apriori]\nboresight_deg = [0.0, 0.0, 0.0]\nlever_arm_m = [0.0, 0.0, 0.0]\nwindow_margin_m = 3.0\n"
        ),
    )
    .unwrap();
    let las = common::tmp("hesai-georef", "cloud.las");
    // `spherecal COMMAND` on the capture and the trajectory.
    let survey = |command: &str| {
        let mut c = common::spherecal();
        c.arg(command)
            .arg("--pcap")
            .arg(&pcap)
            .arg("--sbet")
            .arg(&sbet_path)
            .arg("--gps-week")
            .arg(format!("{week}"))
            .arg("--site")
            .arg(&site)
            .args(["--trajectory-datum", "WGS84"]);
        c
    };
    let out = common::stdout_of(
        survey("georef")
            .arg("--metadata")
            .arg(&corr)
            .args(["--las-frame", "local", "--las"])
            .arg(&las),
    );
    let mut r = las::Reader::from_path(&las).unwrap();
    let n = r.header().number_of_points();
    let data = r.read_points(n).unwrap();
    let pts: Vec<las::Point> = data.points().map(|p| p.unwrap()).collect();
    assert_eq!(pts.len(), rows.len(), "{out}");
    // The decoded returns by firing time (1 us bins: LAS holds GPS time - 1e9 s as an f64,
    // to some 30 ns).
    let mut by_time: HashMap<i64, Vec<[f64; 3]>> = HashMap::new();
    for (ns, q) in &rows {
        by_time.entry(ns.div_euclid(1000)).or_default().push(*q);
    }
    let mut worst = 0.0f64;
    for p in &pts {
        let t = p.gps_time.unwrap() + 1e9;
        let unix_ns = (p.gps_time.unwrap() * 1e9).round() as i64
            + (1_000_000_000 + GPS_UNIX_S - 18) * 1_000_000_000;
        // The sensor-frame point the LAS implies: NED = P(t) + q (the mounting zero, level).
        let q = [p.y - v * (t - t_ref), p.x, -p.z];
        let bin = unix_ns.div_euclid(1000);
        let best = (bin - 1..=bin + 1)
            .filter_map(|b| by_time.get(&b))
            .flatten()
            .map(|c| (0..3).map(|i| (c[i] - q[i]).abs()).fold(0.0, f64::max))
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(best);
    }
    assert!(
        worst < 1e-3,
        "a LAS point {worst} m from its decoded return at its time"
    );
    // The GPS packet read: PPS locked, but no sentence in its NMEA field (0xDF bytes), so no
    // valid RMC and the clock is not trusted.
    assert!(
        out.contains(
            "clock: Hesai, 1 GPS packets: 1 with the PPS locked, 0 with a valid $GPRMC; each"
        ),
        "{out}"
    );
    // The bag the capture was written from: the same LAS, point for point (the packets' own
    // times; the bag records no GPS packet).
    let (bag, _, _) = paths(&CASES[1]);
    let bag_las = common::tmp("hesai-georef", "bag.las");
    let by_bag = |extra: &[&std::ffi::OsStr]| {
        let mut c = common::spherecal();
        c.arg("georef")
            .arg("--bag")
            .arg(&bag)
            .arg("--sbet")
            .arg(&sbet_path)
            .arg("--gps-week")
            .arg(format!("{week}"))
            .arg("--site")
            .arg(&site)
            .args([
                "--trajectory-datum",
                "WGS84",
                "--las-frame",
                "local",
                "--las",
            ])
            .arg(&bag_las)
            .args(extra);
        c
    };
    let out = common::stdout_of(&mut by_bag(&["--metadata".as_ref(), corr.as_os_str()]));
    assert!(out.contains("clock: Hesai, no GPS packet"), "{out}");
    let mut r = las::Reader::from_path(&bag_las).unwrap();
    let n = r.header().number_of_points();
    let from_bag: Vec<las::Point> = r
        .read_points(n)
        .unwrap()
        .points()
        .map(|p| p.unwrap())
        .collect();
    assert_eq!(from_bag.len(), pts.len());
    for (a, b) in from_bag.iter().zip(&pts) {
        assert_eq!((a.x, a.y, a.z, a.gps_time), (b.x, b.y, b.z, b.gps_time));
    }
    // ... and without the corrections, refused naming them.
    let o = by_bag(&[]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("PandarScan messages: give the unit's angle correction file with --metadata"),
        "{err}"
    );
    // Without the corrections: refused, saying what the capture holds and what reads it.
    let o = survey("calibrate").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("PandarXT32 data packets") && err.contains("--metadata CORRECTIONS.csv"),
        "{err}"
    );
}

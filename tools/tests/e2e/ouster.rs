//! `spherecal decode CAPTURE --metadata META.json` on real Ouster captures (tests/data/ouster),
//! against Ouster's own SDK (PyPI `ouster-sdk`, `scripts/ouster_xyz.py`) on the same files.

use crate::common;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The vendored captures: every profile spherecal reads, both metadata layouts, both headers.
const CAPTURES: [&str; 5] = [
    "OS-1-32-G_v2.1.1_1024x10",
    "OS-0-32-U1_v2.2.0_1024x10",
    "shot_limiting_test",
    "windowed_frame1",
    "OS-1-128_767798045_1024x10_20230712_120049",
];

fn files(name: &str) -> (PathBuf, PathBuf) {
    (
        common::test_data(&format!("ouster/{name}.pcap")),
        common::test_data(&format!("ouster/{name}.json")),
    )
}

/// `spherecal decode PCAP --metadata META` (with more arguments to add).
fn decode(pcap: &Path, meta: &Path) -> std::process::Command {
    let mut c = common::spherecal();
    c.arg("decode").arg(pcap).arg("--metadata").arg(meta);
    c
}

/// A refusal (exit 2): its stderr.
fn refused(c: &mut std::process::Command) -> String {
    let out = c.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{err}");
    err
}

/// (frame id, measurement id, channel, return) -> x y z [m].
pub(crate) type Returns = HashMap<(u32, u32, u32, String), [f64; 3]>;

/// The rows of a `decode --csv` listing (its header skipped) by their Ouster keys; a row
/// twice fails.
pub(crate) fn listed<'a>(lines: impl Iterator<Item = &'a str>) -> Returns {
    let mut got = Returns::new();
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        let p = |i: usize| f[i].parse::<f64>().unwrap();
        let key = (
            f[13].parse().unwrap(),
            f[14].parse().unwrap(),
            f[15].parse().unwrap(),
            f[4].to_string(),
        );
        assert!(
            got.insert(key, [p(10), p(11), p(12)]).is_none(),
            "a row twice: {l}"
        );
    }
    got
}

/// What Ouster's SDK decodes from the capture.
pub(crate) fn reference(pcap: &PathBuf, meta: &PathBuf) -> Returns {
    let script = common::repo_root().join("scripts/ouster_xyz.py");
    // scripts/test.sh installs the SDK in a folder of its own (its pins are not the other
    // reference packages').
    let own = common::repo_root().join("target/py-ouster");
    let mut cmd = std::process::Command::new("python3");
    if own.is_dir() {
        cmd.env("PYTHONPATH", &own);
    }
    let out = cmd
        .arg(&script)
        .arg(pcap)
        .arg(meta)
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "ouster-sdk must be installed (scripts/test.sh does it): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut r = Returns::new();
    for l in String::from_utf8(out.stdout).unwrap().lines() {
        let f: Vec<&str> = l.split_whitespace().collect();
        let p = |i: usize| f[i].parse::<f64>().unwrap();
        let key = (
            f[0].parse().unwrap(),
            f[1].parse().unwrap(),
            f[2].parse().unwrap(),
            f[3].to_string(),
        );
        assert!(
            r.insert(key, [p(4), p(5), p(6)]).is_none(),
            "a return twice: {l}"
        );
    }
    r
}

/// Every return of every vendored capture as Ouster's SDK decodes it: none missing, none
/// extra, x y z in the sensor frame within 1 mm; the summary counts them; the CSV's columns.
#[test]
fn every_capture_decodes_as_ousters_sdk_does() {
    for name in CAPTURES {
        let (pcap, meta) = files(name);
        let csv = common::tmp("ouster", &format!("{name}.csv"));
        let stdout = common::stdout_of(decode(&pcap, &meta).arg("--csv").arg(&csv));
        let want = reference(&pcap, &meta);
        assert!(!want.is_empty(), "{name}: the SDK decoded nothing");
        let text = std::fs::read_to_string(&csv).unwrap();
        let mut lines = text.lines();
        let header = lines.next().unwrap();
        assert_eq!(
            header,
            "packet,block,sequence,laser,return,time_us,azimuth_deg,elevation_deg,distance_m,intensity,x_m,y_m,z_m,frame_id,measurement_id,channel"
        );
        let got = listed(lines);
        let missing = want.keys().filter(|k| !got.contains_key(*k)).count();
        let extra = got.keys().filter(|k| !want.contains_key(*k)).count();
        assert_eq!(
            (missing, extra),
            (0, 0),
            "{name}: {} returns against the SDK's {}",
            got.len(),
            want.len()
        );
        let worst = want
            .iter()
            .map(|(k, w)| (0..3).map(|i| (w[i] - got[k][i]).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
        assert!(worst <= 1e-3, "{name}: {worst} m off the SDK");
        let seconds = want.keys().filter(|k| k.3 == "second").count();
        assert!(
            stdout.contains(&format!(
                "points: {} (first returns {}, second {seconds})",
                want.len(),
                want.len() - seconds
            )),
            "{name}: {stdout}"
        );
        // None of these sensors' clocks was synchronised (the PTP one never locked).
        assert!(
            stdout.contains("\nclock: ") && stdout.contains("unlocked clock"),
            "{name}: {stdout}"
        );
        eprintln!(
            "{name}: {} returns ({seconds} second), worst {worst:.1e} m",
            want.len()
        );
    }
}

/// A capture decoded with another sensor's metadata is refused naming the mismatch, and
/// writes no listing; metadata that is not a sensor's names the key.
#[test]
fn a_capture_with_other_metadata_is_refused_by_name() {
    let (pcap, _) = files("OS-1-32-G_v2.1.1_1024x10");
    let (_, other) = files("OS-0-32-U1_v2.2.0_1024x10");
    let csv = common::tmp("ouster", "mismatch.csv");
    let err = refused(decode(&pcap, &other).arg("--csv").arg(&csv));
    assert!(
        err.contains("(64 of 6464 bytes) are not the metadata's format: RNG19_RFL8_SIG16_NIR16_DUAL of 32 pixels x 16 columns is 8448 bytes"),
        "{err}"
    );
    assert!(!csv.exists());
    // Without metadata: no Velodyne packet, and the way on said.
    let err = refused(common::spherecal().arg("decode").arg(&pcap));
    assert!(
        err.contains("an Ouster's lidar and IMU ports: decode it with the sensor's metadata JSON (--metadata META.json)"),
        "{err}"
    );
    // The same format, another unit's metadata (its serial number): its beam angles are not
    // this sensor's.
    let (pcap2, meta2) = files("windowed_frame1");
    let text = std::fs::read_to_string(&meta2).unwrap();
    assert!(text.contains("\"992108000265\""));
    let other = common::tmp("ouster", "other-unit.json");
    std::fs::write(&other, text.replace("\"992108000265\"", "\"992108000999\"")).unwrap();
    let err = refused(&mut decode(&pcap2, &other));
    assert!(
        err.contains("17 lidar packets come from the sensor with serial number 992108000265, the metadata describes 992108000999"),
        "{err}"
    );
    let bad = common::tmp("ouster", "bad.json");
    for (text, says) in [
        ("{\"data_format\": {\"pixels_per_column\": 32}}", "`columns_per_packet` missing"),
        ("[1, 2]", "not an Ouster sensor's metadata"),
        ("{\"lidar_data_format\": {\"pixels_per_column\": 32, \"columns_per_packet\": 16, \"columns_per_frame\": 1024, \"udp_profile_lidar\": \"FIVE_WORD_PIXEL\"}}", "FIVE_WORD_PIXEL: spherecal reads"),
        ("not json", "not JSON"),
    ] {
        std::fs::write(&bad, text).unwrap();
        let err = refused(&mut decode(&pcap, &bad));
        assert!(err.contains(says), "{text}: {err}");
    }
}

/// Firmware 3.x ends each packet with a CRC-64 of it (shot_limiting_test's agrees): once a
/// packet's agreed, a damaged one (one bit flipped in a copy of the real packet) is skipped
/// and counted by name, not decoded into wrong points.
#[test]
fn a_damaged_packet_of_a_crc_firmware_is_skipped_by_name() {
    let (pcap, meta) = files("shot_limiting_test");
    let b = std::fs::read(&pcap).unwrap();
    // The capture: a 24-byte header and one record (16-byte header + frame).
    let record = &b[24..];
    let mut two = b.clone();
    let mut damaged = record.to_vec();
    damaged[16 + 42 + 1000] ^= 0x10;
    two.extend_from_slice(&damaged);
    let path = common::tmp("ouster", "damaged.pcap");
    std::fs::write(&path, &two).unwrap();
    let run = |p: &PathBuf| common::stdout_of(&mut decode(p, &meta));
    let one = run(&pcap);
    assert!(
        one.contains("footer CRC-64 (firmware 3.x): 1 packets agree"),
        "{one}"
    );
    let out = run(&path);
    assert!(out.contains("lidar packets: 1 "), "{out}");
    assert!(
        out.contains("skipped: 1\n  Ouster CRC-64 mismatch: 1 (first at byte"),
        "{out}"
    );
    assert!(out.contains("points: 2048 "), "{out}");
}

/// The capture recorded as a 1500-byte link delivers it: every lidar packet (6,464 bytes) in
/// five IPv4 fragments, one packet's in reverse order, one stray fragment that never
/// completes. The reader puts the datagrams back together: the listing is the whole capture's,
/// row for row.
#[test]
fn a_capture_of_ip_fragments_decodes_as_the_whole_one() {
    let (pcap, meta) = files("OS-1-32-G_v2.1.1_1024x10");
    let b = std::fs::read(&pcap).unwrap();
    let mut out = b[..24].to_vec();
    let (mut off, mut n) = (24, 0);
    let checksum = |h: &[u8]| {
        let mut sum = 0u32;
        for w in h.chunks(2) {
            sum += u32::from(u16::from_be_bytes([w[0], w[1]]));
        }
        while sum > 0xFFFF {
            sum = (sum & 0xFFFF) + (sum >> 16);
        }
        !(sum as u16)
    };
    let record = |out: &mut Vec<u8>, ts: &[u8], frame: &[u8]| {
        out.extend_from_slice(ts);
        out.extend_from_slice(&(frame.len() as u32).to_le_bytes());
        out.extend_from_slice(&(frame.len() as u32).to_le_bytes());
        out.extend_from_slice(frame);
    };
    while off + 16 <= b.len() {
        let incl = u32::from_le_bytes(b[off + 8..off + 12].try_into().unwrap()) as usize;
        let (ts, frame) = (&b[off..off + 8], &b[off + 16..off + 16 + incl]);
        off += 16 + incl;
        let (eth, ip, body) = (&frame[..14], &frame[14..34], &frame[34..]);
        let mut frags: Vec<Vec<u8>> = body
            .chunks(1480)
            .enumerate()
            .map(|(i, chunk)| {
                let more = (i + 1) * 1480 < body.len();
                let mut h = ip.to_vec();
                h[2..4].copy_from_slice(&(20 + chunk.len() as u16).to_be_bytes());
                let word = (u16::from(more) << 13) | (i * 1480 / 8) as u16;
                h[6..8].copy_from_slice(&word.to_be_bytes());
                h[10..12].copy_from_slice(&[0, 0]);
                let c = checksum(&h);
                h[10..12].copy_from_slice(&c.to_be_bytes());
                [eth, &h[..], chunk].concat()
            })
            .collect();
        assert_eq!(frags.len(), 5);
        if n == 3 {
            frags.reverse();
            // A stray first fragment of a datagram whose rest never comes.
            let mut stray = frags[4].clone();
            stray[14 + 4] ^= 0x55;
            frags.push(stray);
        }
        for f in &frags {
            record(&mut out, ts, f);
        }
        n += 1;
    }
    let fragmented = common::tmp("ouster", "fragmented.pcap");
    std::fs::write(&fragmented, &out).unwrap();
    let csv = |p: &PathBuf, name: &str| {
        let c = common::tmp("ouster", name);
        let s = common::stdout_of(decode(p, &meta).arg("--csv").arg(&c));
        (s, std::fs::read_to_string(&c).unwrap())
    };
    let (whole_sum, whole) = csv(&pcap, "whole.csv");
    let (frag_sum, frag) = csv(&fragmented, "fragments.csv");
    assert!(frag_sum.contains("lidar packets: 64 "), "{frag_sum}");
    assert!(whole_sum.contains("points: 27310 "), "{whole_sum}");
    assert_eq!(whole.lines().count(), frag.lines().count());
    assert!(whole == frag, "the listings differ");
}

/// Every vendored capture as ouster-ros records it (`ouster_sensor_msgs/msg/PacketMsg`, written
/// by PyPI `rosbags` through scripts/ouster-bag.py: each packet with ouster-ros's one byte
/// more; one bag in MCAP with the packets exact): the bag decodes row for row as the capture,
/// its IMU topic counted.
#[test]
fn an_ouster_ros_bag_decodes_as_its_capture() {
    for (k, name) in CAPTURES.iter().enumerate() {
        let (pcap, meta) = files(name);
        let listing = |input: &Path, csv: &str| {
            let c = common::tmp("ouster-bag", csv);
            let s = common::stdout_of(decode(input, &meta).arg("--csv").arg(&c));
            (s, std::fs::read_to_string(&c).unwrap())
        };
        let (from_pcap, rows) = listing(&pcap, &format!("{name}.csv"));
        let port = |line: &str| {
            let at = line.find("(UDP ").unwrap() + 5;
            line[at..].split(')').next().unwrap().to_string()
        };
        let lidar_port = port(
            from_pcap
                .lines()
                .find(|l| l.starts_with("lidar packets"))
                .unwrap(),
        );
        let bag = common::tmp("ouster-bag", &format!("{name}.bag"));
        let _ = std::fs::remove_dir_all(&bag);
        let mcap = k == 1;
        let o = std::process::Command::new("python3")
            .arg(common::repo_root().join("scripts/ouster-bag.py"))
            .arg(&pcap)
            .arg(&bag)
            .args(["--lidar-port", &lidar_port])
            .args(if mcap {
                &["--storage", "mcap", "--exact"][..]
            } else {
                &[][..]
            })
            .output()
            .expect("python3");
        assert!(
            o.status.success(),
            "scripts/ouster-bag.py needs python3 with rosbags (scripts/test.sh installs it): {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let (from_bag, bag_rows) = listing(&bag, &format!("{name}-bag.csv"));
        assert!(
            rows == bag_rows,
            "{name}: the bag's listing differs from the capture's"
        );
        let counts = |s: &str| {
            s.lines()
                .filter(|l| l.starts_with("lidar packets") || l.starts_with("points"))
                .map(str::to_string)
                .collect::<Vec<_>>()
        };
        assert_eq!(counts(&from_bag), counts(&from_pcap), "{name}");
    }
}

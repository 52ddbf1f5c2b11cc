//! The POS MV's real-time groups: our framer against groups packed by an independent encoder
//! (Python's struct, from the ICD's tables), and calibration end to end from a POS MV stream
//! (its datagrams in the capture, or its logged stream), with its faults: corrupted bytes,
//! an alignment that is not full navigation yet, no Group 3 to date the stream.

use crate::common;

use spherecal::posmv::{self, Alignment, Framer, GnssStatus, Group, Item, Navigation, PpsTime};
use spherecal_tools::config::scenario::Scenario;
use std::path::Path;

/// Groups packed by Python's `struct` from the ICD tables (not by our emit side): Group 1,
/// Group 3 with two channel blocks, Group 7; between them garbage, a group with one flipped
/// byte, a "$GRP" with an impossible byte count, and a cut-off group at the end.
const PACK: &str = r#"
import struct, sys
def group(gid, body):
    n = 8 + len(body) + 4
    pad = (-n) % 4
    raw = b"$GRP" + struct.pack("<HH", gid, n + pad - 8) + body + b"\0" * pad
    s = sum(struct.unpack("<%dH" % (len(raw) // 2), raw)) + struct.unpack("<H", b"$#")[0]
    return raw + struct.pack("<H", (-s) & 0xFFFF) + b"$#"
t = struct.pack("<dddBB", 302412.25, 1234.5, 77.0, 0x02, 1)
g1 = group(1, t + struct.pack("<ddd3fdddd2f3f3fB", 48.3812345678, -4.4912345678, 52.125,
    0.5, -0.25, 0.01, 1.5, -2.25, 359.75, 0.0, 12.0, 2.5, 0.1, 0.2, 0.3, 0.01, 0.02, 9.81, 0))
chan = struct.pack("<HH4f", 5, 11, 123.0, 45.0, 44.0, 40.0) * 2
g3 = group(3, t + struct.pack("<bBH", 7, 14, len(chan)) + chan +
    struct.pack("<3fHIdffHI", 0.8, 1.3, 1.0, 7, 2290, 18.0, 0.05, 47.5, 17, 0))
g7 = group(7, t + struct.pack("<IB", 1234, 2))
bad = bytearray(g1); bad[50] ^= 0xFF
stream = b"junk$GR" + g1 + b"\x00\x01$GRP\x01\x00\x03\x00" + bytes(bad) + g3 + b"$" + g7 + g1[:60]
sys.stdout.write(stream.hex())
"#;

#[test]
fn groups_packed_independently_are_framed_and_parsed() {
    let bytes: Vec<u8> = {
        let hex = common::python(PACK, "python3");
        (0..hex.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
            .collect()
    };
    let mut f: Framer = Framer::new();
    let mut ids = Vec::new();
    let mut errors = 0;
    let (mut nav, mut gnss, mut pps) = (None, None, None);
    // Byte by byte: the same as whole (the proptests check that at large).
    for b in &bytes {
        f.consume(std::slice::from_ref(b), |it| match it.item {
            Item::Group(g) => {
                ids.push(g.id());
                match g.id() {
                    1 => nav = Some(Navigation::parse(&g).unwrap()),
                    3 => gnss = Some(GnssStatus::parse(&g).unwrap()),
                    7 => pps = Some(PpsTime::parse(&g).unwrap()),
                    _ => {}
                }
            }
            Item::Error(_) => errors += 1,
            Item::Message(_) => {}
        });
    }
    f.finish();
    while f.next().is_some() {}
    assert_eq!(ids, [1, 3, 7]);
    assert_eq!(errors, 1, "the flipped group");
    let st = f.stats();
    assert_eq!((st.checksum_failures, st.bad_lengths), (1, 1));
    let n = nav.unwrap();
    assert_eq!(n.lla, [48.3812345678, -4.4912345678, 52.125]);
    assert_eq!(n.rph, [1.5, -2.25, 359.75]);
    assert_eq!(n.velocity, [0.5, -0.25, 0.01]);
    assert_eq!(n.accel, [0.01, 0.02, 9.81]);
    assert_eq!(n.alignment, Alignment::FullNavigation);
    assert_eq!(n.time.time1, 302412.25);
    assert_eq!(n.time.time1_type, posmv::TimeType::Utc);
    let g = gnss.unwrap();
    assert_eq!(
        (g.channels, g.week, g.utc_offset, g.solution),
        (2, 2290, 18.0, 7)
    );
    assert_eq!(g.dop, [0.8, 1.3]);
    assert_eq!(pps.unwrap().sync, posmv::TimeSync::Synchronized);
    // The pose: UTC seconds of week 2290 + the 18 s Group 3 gives.
    let p = posmv::Pose::from_navigation(&n, g.week as u16, g.utc_offset as i64).unwrap();
    assert_eq!(
        p.time,
        spherecal::time::GpsTime::from_week_tow_s(2290, 302430.25).unwrap()
    );
}

fn synth_posmv(name: &str, edit: impl FnOnce(&mut Scenario)) -> std::path::PathBuf {
    let mut s = Scenario::load("table1").unwrap();
    s.ins.kind = "posmv".into();
    edit(&mut s);
    let dir = common::tmp("posmv", name);
    let _ = std::fs::remove_dir_all(&dir);
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    dir
}

fn calibrate(dir: &Path, posmv: &Path, extra: &[&str]) -> (serde_json::Value, String) {
    let report = dir.join("report.json");
    let out = common::spherecal()
        .arg("calibrate")
        .arg("--pcap")
        .arg(dir.join("lidar.pcap"))
        .arg("--posmv")
        .arg(posmv)
        .arg("--site")
        .arg(dir.join("site.toml"))
        .arg("--report")
        .arg(&report)
        .args(extra)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let r = serde_json::from_str(&std::fs::read_to_string(&report).unwrap_or_default())
        .unwrap_or(serde_json::Value::Null);
    (r, text)
}

fn assert_truth(r: &serde_json::Value, text: &str, dt: f64) {
    assert_eq!(r["converged"], true, "{text}");
    let got = common::report_deg_m(r);
    common::assert_within(
        &got,
        &[179.5, -44.9, 1.2, 1.5, -1.24, -1.36],
        1e-3,
        "table1 from a POS MV",
    );
    let got_dt = r["time_offset_s"].as_f64().unwrap();
    assert!((got_dt - dt).abs() < 1e-3, "time offset {got_dt} vs {dt}");
}

/// table1 with a POS MV whose clock is 20 ms late and whose line corrupts 1 byte in 20,000:
/// from its datagrams in the capture and from its logged stream, the same truth and offset;
/// the corrupted groups are counted, not used.
#[test]
fn calibration_from_a_posmv_stream() {
    let dir = synth_posmv("late", |s| {
        s.ins.time_offset_s = 0.02;
        s.ins.corrupt_prob = 5e-5;
    });
    for src in [dir.join("lidar.pcap"), dir.join("ins.posmv")] {
        let (r, text) = calibrate(&dir, &src, &[]);
        assert_truth(&r, &text, 0.02);
        let pm = &r["inputs"]["ins_state"]["posmv"];
        let rejected = pm["rejected"].as_u64().unwrap();
        assert!(rejected > 10, "corrupted groups counted: {pm}");
        assert_eq!(pm["week"], 2318, "{pm}");
        assert!(text.contains("POS MV groups"), "{text}");
    }
}

/// Rewrite a logged stream group by group with `f` (None drops the group).
fn rewrite(src: &Path, dst: &Path, mut f: impl FnMut(&Group<&[u8]>, &mut Vec<u8>) -> bool) {
    let bytes = std::fs::read(src).unwrap();
    let mut out = Vec::new();
    let mut fr: Framer = Framer::new();
    fr.consume(&bytes, |it| {
        if let Item::Group(g) = it.item {
            let mut b = g.as_bytes().to_vec();
            if f(&g, &mut b) {
                out.extend_from_slice(&b);
            }
        }
    });
    std::fs::write(dst, out).unwrap();
}

/// The POS MV still aligning for the first 15 s (Group 1's status "fine alignment", then
/// full navigation), and no Group 3 at all: the aligning poses are left out and counted, the
/// stream is dated from the LiDAR's RMC instead, and the calibration still finds the truth.
/// With the stream on POS time only (never a GNSS time), no pose is usable: refused, saying so.
#[test]
fn posmv_faults_are_counted_and_named() {
    let dir = synth_posmv("faults", |_| {});
    let aligning = dir.join("aligning.posmv");
    let mut first: Option<f64> = None;
    rewrite(&dir.join("ins.posmv"), &aligning, |g, b| match g.id() {
        GnssStatus::ID => false,
        Navigation::ID => {
            let mut n = Navigation::parse(g).unwrap();
            let t0 = *first.get_or_insert(n.time.time1);
            if n.time.time1 - t0 < 15.0 {
                n.alignment = Alignment::FineAlign;
                b.resize(140, 0);
                n.emit(b).unwrap();
            }
            true
        }
        _ => true,
    });
    let (r, text) = calibrate(&dir, &aligning, &[]);
    assert_truth(&r, &text, 0.0);
    let st = &r["inputs"]["ins_state"];
    let left_out = st["excluded"][1].as_u64().unwrap();
    assert!((2990..=3010).contains(&left_out), "15 s at 200 Hz: {st}");
    assert_eq!(st["posmv"]["groups"]["3"], serde_json::Value::Null);
    assert_eq!(st["posmv"]["week"], 2318);

    let pos_time = dir.join("pos-time.posmv");
    rewrite(&dir.join("ins.posmv"), &pos_time, |g, b| {
        if g.id() == Navigation::ID {
            let mut n = Navigation::parse(g).unwrap();
            n.time.time1_type = posmv::TimeType::Pos;
            n.emit(b).unwrap();
        }
        true
    });
    let (_, text) = calibrate(&dir, &pos_time, &[]);
    assert!(
        text.contains("12901 poses on the POS clock (no GNSS time)"),
        "{text}"
    );
}

//! The VN-200 framer and decoder against real and vendor files and their independent decodings
//! (tests/data/vn200/*.expected.csv, from a Python decoder checked against VectorNav's SDK).

use crate::common;

use spherecal::vn200::binary::Value;
use spherecal::vn200::{Framer, Item};
use spherecal_tools::ins::frame_columns;
use std::collections::BTreeMap;

/// One decoded binary frame: offset, bytes (hex), and column -> value.
#[derive(Debug, Clone, PartialEq)]
struct Got {
    offset: u64,
    hex: String,
    values: Vec<(String, Value)>,
}

/// ASCII sentence: offset, name, fields.
#[derive(Debug, Clone, PartialEq)]
struct GotAscii {
    offset: u64,
    name: String,
    fields: Vec<String>,
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// Frame `bytes` delivered in the given chunk sizes (cycled).
fn frame(bytes: &[u8], chunks: &[usize]) -> (Vec<Got>, Vec<GotAscii>, spherecal::vn200::Stats) {
    let mut framer: Box<Framer> = Box::default();
    let (mut bin, mut asc) = (Vec::new(), Vec::new());
    let mut handle = |it: spherecal::vn200::Framed<'_>| match it.item {
        Item::Binary(f) => bin.push(Got {
            offset: it.offset,
            hex: hex(f.bytes()),
            values: frame_columns(&f)
                .into_iter()
                .map(|(_, n, v)| (n, v))
                .collect(),
        }),
        Item::Ascii(s) | Item::Nmea(s) => asc.push(GotAscii {
            offset: it.offset,
            name: s.name().to_string(),
            fields: s.fields().map(str::to_string).collect(),
        }),
        Item::Error(e) => panic!("unexpected rejected item at {}: {e}", it.offset),
    };
    let mut rest = bytes;
    let mut i = 0;
    while !rest.is_empty() {
        let n = chunks[i % chunks.len()].min(rest.len());
        i += 1;
        framer.consume(&rest[..n], &mut handle);
        rest = &rest[n..];
    }
    framer.finish();
    while let Some(it) = framer.next() {
        handle(it);
    }
    let stats = *framer.stats();
    (bin, asc, stats)
}

/// Byte-by-byte, whole buffer and uneven chunks must agree; returns the whole-buffer result.
fn frame_every_way(bytes: &[u8]) -> (Vec<Got>, Vec<GotAscii>, spherecal::vn200::Stats) {
    let whole = frame(bytes, &[bytes.len().max(1)]);
    for chunks in [
        &[1usize][..],
        &[7, 1, 300, 2, 64],
        &[4096, 3],
        &[123, 5000, 17],
    ] {
        let other = frame(bytes, chunks);
        assert_eq!(
            whole.0, other.0,
            "binary frames differ with chunks {chunks:?}"
        );
        assert_eq!(whole.1, other.1, "sentences differ with chunks {chunks:?}");
        assert_eq!(whole.2, other.2, "stats differ with chunks {chunks:?}");
    }
    whole
}

/// Is our value exactly the one the expected file prints (round-trip exact)?
fn same(v: &Value, expected: &str) -> bool {
    match v {
        Value::F32(x) => expected
            .parse::<f32>()
            .map(|e| e == *x || (e.is_nan() && x.is_nan()))
            .unwrap_or(false),
        Value::F64(x) => expected
            .parse::<f64>()
            .map(|e| e == *x || (e.is_nan() && x.is_nan()))
            .unwrap_or(false),
        Value::U(x) => expected.parse::<u64>() == Ok(*x),
        Value::I(x) => expected.parse::<i64>() == Ok(*x),
    }
}

fn check_wide(bin: &str, expected: &str, frames: usize) {
    let bytes = std::fs::read(common::test_data(bin)).unwrap();
    let text = std::fs::read_to_string(common::test_data(expected)).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(&header[..4], ["offset", "header", "len", "hex"]);
    let (got, _, stats) = frame_every_way(&bytes);
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), frames);
    assert_eq!(got.len(), rows.len(), "frame count; stats {stats:?}");
    assert_eq!(stats.crc_failures, 0);
    let mut compared = 0;
    for (g, row) in got.iter().zip(&rows) {
        assert_eq!(g.offset.to_string(), row[0], "frame offsets");
        assert_eq!(g.hex.len() / 2, row[2].parse::<usize>().unwrap());
        assert_eq!(g.hex, row[3]);
        let ours: BTreeMap<&str, &Value> = g.values.iter().map(|(n, v)| (n.as_str(), v)).collect();
        for (name, want) in header.iter().zip(row).skip(4) {
            if want.is_empty() {
                continue;
            }
            let v = ours
                .get(name)
                .unwrap_or_else(|| panic!("frame at {}: no column {name}", g.offset));
            assert!(
                same(v, want),
                "frame at {}: {name} = {v} but expected {want}",
                g.offset
            );
            compared += 1;
        }
        // And no column of ours that the expected file does not name.
        for (n, _) in &g.values {
            assert!(
                header.contains(&n.as_str()),
                "frame at {}: extra column {n}",
                g.offset
            );
        }
    }
    eprintln!("{bin}: {} frames, {compared} values equal", got.len());
}

#[test]
fn vn100_logger_file() {
    check_wide(
        "vn200/vn100_F00294.raw",
        "vn200/vn100_F00294.expected.csv",
        99,
    );
    // The back-to-back pair at offset 11754: the earlier frame's last CRC byte is 0xFA.
    let bytes = std::fs::read(common::test_data("vn200/vn100_F00294.raw")).unwrap();
    let (got, nmea, stats) = frame(&bytes, &[bytes.len()]);
    assert_eq!(bytes[11_753], 0xFA, "the earlier frame's last CRC byte");
    assert!(
        got.iter().any(|g| g.offset == 11_630),
        "the frame ending in 0xFA"
    );
    assert!(
        got.iter().any(|g| g.offset == 11_754),
        "the frame right after it"
    );
    // The logger's own $GPRMC / $GPGGA lines are NMEA, checksums valid, decoded by the nmea crate.
    assert!(nmea.iter().all(|s| s.name == "GPRMC" || s.name == "GPGGA"));
    assert_eq!(stats.nmea, nmea.len() as u64);
    assert_eq!(stats.nmea_decoded, stats.nmea);
}

#[test]
fn vn310_gnss_file() {
    check_wide("vn200/vn310_gnss.bin", "vn200/vn310_gnss.expected.csv", 12);
}

#[test]
fn vn310_imu_file() {
    check_wide("vn200/vn310_imu.bin", "vn200/vn310_imu.expected.csv", 18);
}

/// Long-form expected files: `offset,kind,field,value`.
fn long_form(expected: &str) -> BTreeMap<u64, Vec<(String, String)>> {
    let text = std::fs::read_to_string(common::test_data(expected)).unwrap();
    let mut out: BTreeMap<u64, Vec<(String, String)>> = BTreeMap::new();
    for l in text.lines() {
        let f: Vec<&str> = l.splitn(4, ',').collect();
        out.entry(f[0].parse().unwrap())
            .or_default()
            .push((f[2].to_string(), f[3].to_string()));
    }
    out
}

#[test]
fn vnproglib_mock_binary_file() {
    let bytes = std::fs::read(common::test_data("vn200/vnproglib_mock_binary.bin")).unwrap();
    let want = long_form("vn200/vnproglib_mock_binary.expected.csv");
    let (got, _, _) = frame_every_way(&bytes);
    assert_eq!(got.len(), want.len());
    for g in &got {
        let w = &want[&g.offset];
        for (name, value) in w {
            match name.as_str() {
                "_header" => assert_eq!(&g.hex[2..2 + value.len()], value),
                "_len" => assert_eq!((g.hex.len() / 2).to_string(), *value),
                _ => {
                    let v = g
                        .values
                        .iter()
                        .find(|(n, _)| n == name)
                        .unwrap_or_else(|| panic!("no {name}"))
                        .1;
                    assert!(same(&v, value), "{name} = {v}, expected {value}");
                }
            }
        }
    }
}

fn check_ascii(txt: &str, expected: &str) {
    let bytes = std::fs::read(common::test_data(txt)).unwrap();
    let want = long_form(expected);
    let (bin, got, stats) = frame_every_way(&bytes);
    assert!(bin.is_empty());
    assert_eq!(stats.ascii_bad_checksum, 0);
    assert_eq!(got.len(), want.len(), "sentence count");
    for g in &got {
        let w = want
            .get(&g.offset)
            .unwrap_or_else(|| panic!("unexpected sentence at {}", g.offset));
        assert_eq!(w[0], ("_name".to_string(), g.name.clone()));
        assert_eq!(w[1], ("_checksum_ok".to_string(), "1".to_string()));
        let values: Vec<&String> = w[2..].iter().map(|(_, v)| v).collect();
        assert_eq!(
            g.fields.iter().collect::<Vec<_>>(),
            values,
            "fields of {} at {}",
            g.name,
            g.offset
        );
    }
}

#[test]
fn vnproglib_mock_ascii_file() {
    check_ascii(
        "vn200/vnproglib_mock_ascii.txt",
        "vn200/vnproglib_mock_ascii.expected.csv",
    );
}

#[test]
fn thirdparty_quoted_ascii_file() {
    check_ascii(
        "vn200/thirdparty_quoted_ascii.txt",
        "vn200/thirdparty_quoted_ascii.expected.csv",
    );
    // Typed decoding of the first $VNINS, against its printed fields.
    let line =
        std::fs::read_to_string(common::test_data("vn200/thirdparty_quoted_ascii.txt")).unwrap();
    let first = line.lines().next().unwrap();
    let s = spherecal::vn200::ascii::parse(first.as_bytes()).unwrap();
    let spherecal::vn200::ascii::Vn::Ins(ins) = s.decode().unwrap() else {
        panic!("not INS")
    };
    assert_eq!((ins.week, ins.status), (2048, 0x8085));
    assert_eq!(ins.ypr_deg, [-149.042, 13.639, 10.915]);
    assert_eq!(ins.lla, [40.09623362, -88.20139124, 204.179]);
    let pose = spherecal::vn200::Pose::from_ins(&ins).unwrap();
    // 2048 weeks + 224159.474991 s.
    assert_eq!(
        pose.time.0,
        2048 * 604_800_000_000_000 + 224_159_474_991_000
    );
}

/// The two attitude fields of the real VN-310 files (each frame carries YawPitchRoll and
/// Quaternion, as the device computed them) give one body -> NED rotation through
/// `align::history::body_to_ned`: the quaternion path must agree with the Euler angles. With
/// the quaternion's transpose (NED -> body) the two disagree by up to 2.0.
#[test]
fn vn310_quaternion_and_yaw_pitch_roll_give_one_attitude() {
    use spherecal::align::history::body_to_ned;
    use spherecal::vn200::pose::Attitude;
    for file in ["vn200/vn310_gnss.bin", "vn200/vn310_imu.bin"] {
        let bytes = std::fs::read(common::test_data(file)).unwrap();
        let mut framer: Box<Framer> = Box::default();
        let (mut checked, mut worst, mut worst_transposed) = (0, 0f64, 0f64);
        let mut handle = |it: spherecal::vn200::Framed<'_>| {
            let Item::Binary(f) = it.item else { return };
            let (Some(ypr), Some(q)) = (f.yaw_pitch_roll_deg(), f.quaternion()) else {
                return;
            };
            let ypr = Attitude::YawPitchRoll(ypr.map(|d| f64::from(d).to_radians()));
            let q = Attitude::Quaternion(q.map(f64::from));
            let (a, b) = (body_to_ned(&ypr).unwrap(), body_to_ned(&q).unwrap());
            worst = worst.max((a - b).abs().max());
            worst_transposed = worst_transposed.max((a - b.transpose()).abs().max());
            checked += 1;
        };
        framer.consume(&bytes, &mut handle);
        framer.finish();
        while let Some(it) = framer.next() {
            handle(it);
        }
        assert!(
            checked >= 10,
            "{file}: {checked} frames with both attitudes"
        );
        assert!(worst < 1e-5, "{file}: R(q) vs Euler {worst:e}");
        assert!(
            worst_transposed > 0.5,
            "{file}: the attitudes are not a test ({worst_transposed})"
        );
    }
}

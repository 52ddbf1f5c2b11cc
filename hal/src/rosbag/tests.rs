//! Against bags written by independent writers (PyPI `rosbags` 0.11.9: MCAP and sqlite3 bag
//! folders, the sqlite3 one also rewritten to Humble's schema; PyPI `mcap` 1.6: zstd and lz4
//! chunks) from a synthetic survey by `scripts/ros2-bag.py`; what was put in is in
//! tests/data/ros2/bags/expected.json (computed by the script from the capture and the VN-200
//! stream, not by spherecal).

use super::sources::{ScanPackets, Vn200Bytes};
use super::*;
use crate::packet::{PacketSource, Record};
use crate::serial::{ByteSource, ReadOutcome};

fn data(rel: &str) -> PathBuf {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data/ros2/bags")
        .join(rel);
    assert!(p.exists(), "missing test data {}", p.display());
    p
}

/// A pose read back has the host stamp, GPS time and position the script put in (`w`).
fn same_stamp_time_and_place(
    what: &str,
    w: &serde_json::Value,
    stamp: Option<crate::serial::RxStamp>,
    p: &spherecal::vn200::pose::Pose,
) {
    assert_eq!(stamp.unwrap().wall.0, w["host"].as_i64().unwrap(), "{what}");
    assert_eq!(p.time.0 as u64, w["timegps"].as_u64().unwrap(), "{what}");
    let lla = [p.lat.to_degrees(), p.lon.to_degrees(), p.h];
    for (g, x) in lla.iter().zip(w["lla"].as_array().unwrap()) {
        assert!((g - x.as_f64().unwrap()).abs() < 1e-9, "{what}: {lla:?}");
    }
}

fn expected() -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(data("expected.json")).unwrap()).unwrap()
}

const BAGS: [(&str, &str); 5] = [
    ("small_mcap", "mcap"),
    ("small_jazzy", "sqlite3"),
    ("small_humble", "sqlite3"),
    ("small_zstd.mcap", "mcap"),
    ("small_lz4.mcap", "mcap"),
];

#[test]
fn every_storage_lists_its_topics() {
    let e = expected();
    let ins = e["ins_messages"].as_u64().unwrap();
    for (name, storage) in BAGS {
        let bag = Bag::open(&data(name)).unwrap();
        assert_eq!(bag.storage(), storage, "{name}");
        assert_eq!(bag.metadata.is_some(), !name.ends_with(".mcap"), "{name}");
        for topics in [bag.topics().unwrap(), bag.topic_list().unwrap()] {
            let count = |n: &str, ty: &str| {
                let t = topics
                    .iter()
                    .find(|t| t.topic.name == n)
                    .unwrap_or_else(|| panic!("{name}: {n}"));
                assert_eq!(t.topic.type_name, ty, "{name} {n}");
                assert_eq!(t.topic.encoding, "cdr");
                t.count
            };
            assert_eq!(topics.len(), 5, "{name}: {topics:?}");
            assert_eq!(
                count("/velodyne_packets", "velodyne_msgs/msg/VelodyneScan"),
                e["scans"].as_u64().unwrap()
            );
            assert_eq!(
                count("/vectornav/raw/common", "vectornav_msgs/msg/CommonGroup"),
                ins
            );
            assert_eq!(
                count("/vectornav/raw/ins", "vectornav_msgs/msg/InsGroup"),
                ins
            );
            assert_eq!(
                count(
                    "/vectornav/raw/attitude",
                    "vectornav_msgs/msg/AttitudeGroup"
                ),
                ins
            );
            assert_eq!(count("/chatter", "std_msgs/msg/String"), 50);
        }
        // The full count knows each topic's span.
        let full = bag.topics().unwrap();
        assert!(
            full.iter().all(|t| t.span.is_some_and(|s| s.1 >= s.0)),
            "{name}"
        );
    }
}

#[test]
fn the_scans_packets_are_the_captures() {
    let e = expected();
    let want = e["packets"].as_array().unwrap();
    for (name, _) in BAGS {
        let bag = Bag::open(&data(name)).unwrap();
        let mut src = ScanPackets::new(bag.messages(&["/velodyne_packets"]));
        let mut n = 0;
        while let Some(r) = src.next_record().unwrap() {
            let Record::Udp(d) = r else {
                panic!("{name}: a skip")
            };
            let w = &want[n];
            assert_eq!(d.time.0, w[0].as_i64().unwrap(), "{name} packet {n}");
            let sum = d.payload.iter().map(|&b| u64::from(b)).sum::<u64>() % (1 << 32);
            assert_eq!(sum, w[1].as_u64().unwrap(), "{name} packet {n}");
            let head: String = d.payload[..8].iter().map(|b| format!("{b:02x}")).collect();
            assert_eq!(head, w[2].as_str().unwrap());
            assert_eq!((d.dst_port, d.payload.len()), (2368, 1206));
            n += 1;
        }
        assert_eq!(n, want.len(), "{name}");
        assert_eq!(src.scans, 3);
    }
}

#[test]
fn the_vectornav_groups_become_the_vn200_frames() {
    use spherecal::vn200::binary::Frame;
    use spherecal::vn200::pose::{Attitude, Pose};
    let e = expected();
    let want = e["ins"].as_array().unwrap();
    for (name, _) in BAGS {
        let bag = Bag::open(&data(name)).unwrap();
        let topics = [
            "/vectornav/raw/common",
            "/vectornav/raw/ins",
            "/vectornav/raw/attitude",
        ];
        let mut src = Vn200Bytes::new(
            bag.messages(&topics),
            topics[0],
            Some(topics[1]),
            Some(topics[2]),
        );
        let mut buf = [0u8; 4096];
        let mut k = 0;
        loop {
            match src.read_chunk(&mut buf).unwrap() {
                ReadOutcome::End => break,
                ReadOutcome::Idle => panic!("a file is never idle"),
                ReadOutcome::Data { len, stamp } => {
                    let f = Frame::parse(&buf[..len]).unwrap();
                    if let Some(w) = want.get(k) {
                        let p = Pose::from_frame(&f).unwrap();
                        same_stamp_time_and_place(&format!("{name} {k}"), w, stamp, &p);
                        let Attitude::YawPitchRoll(y) = p.attitude else {
                            panic!()
                        };
                        for (g, x) in y.iter().zip(w["ypr"].as_array().unwrap()) {
                            // f32 degrees as sent: the same number, to the last bits of radians.
                            assert!(
                                (g - x.as_f64().unwrap().to_radians()).abs() < 1e-15,
                                "{name} {k}"
                            );
                        }
                        assert_eq!(
                            u64::from(p.ins_status.unwrap() & 3),
                            w["status"].as_u64().unwrap()
                        );
                    }
                    // The script states PosU 0.03 m, YprU 0.2 / 0.02 / 0.02 deg after the first.
                    if k > 0 {
                        assert_eq!(f.position_uncertainty_m(), Some(0.03), "{name} {k}");
                        assert_eq!(f.ypr_uncertainty_deg(), Some([0.2, 0.02, 0.02]));
                    }
                    k += 1;
                }
            }
        }
        assert_eq!(k as u64, e["ins_messages"].as_u64().unwrap(), "{name}");
        assert_eq!(src.stats.frames, k as u64);
        assert_eq!(src.stats.bad, 0);
        assert!(
            src.stats.with_sigmas >= k as u64 - 1,
            "{name}: {:?}",
            src.stats
        );
    }
}

/// A copy of `bytes` as a file in the temporary folder.
fn scratch(name: &str, bytes: &[u8]) -> PathBuf {
    let d = std::env::temp_dir().join(format!("spherecal-rosbag-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn a_cut_or_foreign_file_is_an_error_naming_it() {
    let whole = std::fs::read(data("small_zstd.mcap")).unwrap();
    for cut in [
        9,
        100,
        whole.len() / 3,
        whole.len() / 2,
        whole.len() - 20,
        whole.len() - 1,
    ] {
        // A file cut short (a recorder killed): its whole chunks read, the cut said with
        // where it is (issue 46: it was refused whole).
        let p = scratch("cut.mcap", &whole[..cut]);
        let bag = Bag::open(&p).unwrap();
        let mut m = bag.messages(&[]);
        let mut n = 0;
        while m.next().unwrap().is_some() {
            n += 1;
        }
        assert_eq!(m.cut().len(), 1, "cut at {cut}: {n} messages, no cut said");
        let (f, at) = &m.cut()[0];
        assert!(
            f.ends_with("cut.mcap") && *at <= cut as u64,
            "{cut}: {f:?} {at}"
        );
        // Its topics cannot be had from a summary: counted from what is there.
        let tl = bag.topic_list();
        assert!(tl.is_ok(), "{cut}: {:?}", tl.err());
    }
    let db = std::fs::read(data("small_jazzy/small_jazzy.db3")).unwrap();
    let p = scratch("cut.db3", &db[..db.len() / 2]);
    let bag = Bag::open(&p).unwrap();
    let mut m = bag.messages(&[]);
    let mut r = Ok(None);
    for _ in 0..10_000 {
        r = m.next().map(|o| o.map(|_| ()));
        if !matches!(r, Ok(Some(()))) {
            break;
        }
    }
    assert!(
        r.is_err() || bag.topics().is_err(),
        "a half sqlite file read as whole"
    );
    for (name, bytes) in [("empty.mcap", &b""[..]), ("text.db3", b"hello, world\n")] {
        let e = Bag::open(&scratch(name, bytes)).unwrap_err();
        assert!(e.what.contains("neither MCAP nor SQLite 3"), "{e}");
    }
    let d = std::env::temp_dir().join(format!("spherecal-rosbag-empty-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    assert!(Bag::open(&d).unwrap_err().what.contains("no bag file"));
}

/// Found by the fuzz target `rosbag_mcap`: a record length of ~1e15 bytes in a 1 kB file made
/// the reader reserve it (an abort). Now an error.
/// And a damaged chunk whose reader asked for 2.3 GB at once, and one whose reader kept asking
/// for more past the end of the bytes (a hang: mcap 0.24; 0.26 says the decompressor made no
/// progress), and an attachment shorter than its CRC (a panic in mcap 0.26's parser).
#[test]
fn a_huge_record_length_is_an_error_not_an_allocation() {
    for f in [
        "regression-huge-record-length.mcap",
        "regression-huge-read-request.mcap",
        "regression-endless-read-requests.mcap",
        "regression-short-attachment.mcap",
    ] {
        let b = std::fs::read(
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../fuzz/seeds/rosbag_mcap")
                .join(f),
        )
        .unwrap();
        let e = mcap_messages_in(&b, |_, _, _, _| {}).unwrap_err();
        assert!(e.what.contains("not a complete MCAP file"), "{f}: {e}");
    }
}

/// rosbag2's own test bags (ros2/rosbag2, rosbag2_py/test/resources, Apache-2.0): `talker`
/// (std_msgs/String and rcl_interfaces/Log, metadata version 4) and `wbag` (eight topics split
/// over five files), each in MCAP and sqlite3. Every topic's count is what rosbag2's own
/// metadata.yaml states; the first messages are what PyPI `rosbags` and Python's sqlite3 read.
#[test]
fn rosbag2s_own_test_bags() {
    let dir = |rel: &str| {
        let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../tests/data/ros2/rosbag2")
            .join(rel);
        assert!(p.exists(), "missing test data {}", p.display());
        p
    };
    // (name, count) per topic from a metadata.yaml's topics_with_message_count.
    let stated = |p: &Path| {
        let text = std::fs::read_to_string(p.join("metadata.yaml")).unwrap();
        let list = &text[text.find("topics_with_message_count:").unwrap()..];
        let mut out: Vec<(String, u64)> = Vec::new();
        let (mut name, mut count) = (None, None);
        for line in list.lines().skip(1) {
            let t = line.trim();
            let indent = line.len() - line.trim_start().len();
            if indent <= 2 && !t.starts_with('-') && !t.is_empty() {
                break;
            }
            if t.starts_with("- ") {
                if let (Some(n), Some(c)) = (name.take(), count.take()) {
                    out.push((n, c));
                }
            }
            let t = t.trim_start_matches("- ");
            if let Some(v) = t.strip_prefix("name: ") {
                name = Some(v.trim().to_string());
            } else if let Some(v) = t.strip_prefix("message_count: ") {
                count = Some(v.trim().parse::<u64>().unwrap());
            }
        }
        if let (Some(n), Some(c)) = (name, count) {
            out.push((n, c));
        }
        out.sort();
        out
    };
    let string = |data: &[u8]| {
        let mut r = spherecal::ros2::cdr::Reader::new(data).unwrap();
        r.string("data").unwrap().to_string()
    };
    for storage in ["mcap", "sqlite3"] {
        for (name, files, first_topic, first) in [
            ("talker", 1, "/topic", "Hello, world! 0"),
            ("wbag", 5, "AAA", "Hello, world! 1 - 1"),
        ] {
            let p = dir(&format!("{storage}/{name}"));
            let bag = Bag::open(&p).unwrap();
            assert_eq!(
                (bag.storage(), bag.files.len()),
                (storage.to_string(), files)
            );
            let want = stated(&p);
            assert!(want.len() >= 3, "{want:?}");
            for topics in [bag.topics().unwrap(), bag.topic_list().unwrap()] {
                let mut got: Vec<(String, u64)> = topics
                    .iter()
                    .map(|t| (t.topic.name.clone(), t.count))
                    .collect();
                got.sort();
                assert_eq!(got, want, "{storage}/{name}");
            }
            let mut m = bag.messages(&[first_topic]);
            let msg = m.next().unwrap().unwrap();
            assert_eq!(msg.topic.type_name, "std_msgs/msg/String");
            assert_eq!(string(msg.data), first, "{storage}/{name}");
            // The split bag in the metadata's order: each topic's times never go back.
            let mut last = i64::MIN;
            let mut n = 1;
            while let Some(msg) = m.next().unwrap() {
                assert!(
                    msg.log_time_ns >= last,
                    "{storage}/{name}: {} < {last}",
                    msg.log_time_ns
                );
                last = msg.log_time_ns;
                n += 1;
            }
            assert_eq!(n, want.iter().find(|w| w.0 == first_topic).unwrap().1);
        }
    }
    // talker's spans, as Python's sqlite3 reads them.
    let bag = Bag::open(&dir("sqlite3/talker")).unwrap();
    let t = bag.topics().unwrap();
    let span = |n: &str| t.iter().find(|t| t.topic.name == n).unwrap().span;
    assert_eq!(
        span("/rosout"),
        Some((1_585_866_235_112_411_371, 1_585_866_239_612_761_798))
    );
    assert_eq!(
        span("/topic"),
        Some((1_585_866_235_112_609_068, 1_585_866_239_643_508_139))
    );
    assert_eq!(span("/parameter_events"), None);
}

/// A reader's buffer smaller than one VN-200 frame is an error naming the sizes, not an end.
#[test]
fn a_buffer_smaller_than_a_frame_is_an_error() {
    let bag = Bag::open(&data("small_zstd.mcap")).unwrap();
    let mut src = Vn200Bytes::new(
        bag.messages(&["/vectornav/raw/common"]),
        "/vectornav/raw/common",
        None,
        None,
    );
    let e = src.read_chunk(&mut [0u8; 10]).unwrap_err();
    assert!(
        e.what.contains("does not fit the reader's 10-byte buffer"),
        "{e}"
    );
}

/// The MRPT capture's first two clouds (velodyne_pointcloud's XYZIRT, by scripts/ros2-bag.py
/// --clouds, zstd MCAP): every return in chunks of at most CHUNK, each at its cloud's stamp
/// plus its own time (read here through the view, independently of the chunking).
#[test]
fn clouds_come_in_chunks_at_their_points_times() {
    use super::clouds::{Chunk, CloudChunks, CHUNK};
    use spherecal::ros2::cloud::PointCloud2;
    let bag = Bag::open(&data("mrpt_vlp16_clouds.mcap")).unwrap();
    // Every return's absolute time [host ns], in order, straight from the messages.
    let (mut times, mut want_chunks) = (Vec::new(), 0);
    let mut msgs = bag.messages(&["/velodyne_points"]);
    while let Some(m) = msgs.next().unwrap() {
        let c = PointCloud2::parse(m.data).unwrap();
        let stamp = c.header.stamp.ns();
        let before = times.len();
        times.extend(
            (0..c.len())
                .filter_map(|i| c.point(i))
                .map(|p| stamp + p.time_ns),
        );
        want_chunks += (times.len() - before).div_ceil(CHUNK);
    }
    assert_eq!(times.len(), 28_556);
    let mut src = CloudChunks::new(
        bag.messages(&["/velodyne_points"]),
        spherecal::velodyne::Model::Vlp16,
    );
    let mut chunk = Chunk::default();
    let (mut n, mut chunks) = (0usize, 0);
    while src.next_chunk(&mut chunk).unwrap() {
        chunks += 1;
        assert!(!chunk.points().is_empty() && chunk.points().len() <= CHUNK);
        for p in chunk.points() {
            assert_eq!(chunk.t0.0 + i64::from(p.offset_ns), times[n], "return {n}");
            n += 1;
        }
    }
    assert_eq!(
        (n, src.stats.returns, src.stats.clouds),
        (28_556, 28_556, 2)
    );
    assert_eq!(chunks, want_chunks, "a chunk ends with its cloud");
    assert_eq!(src.stats.skips.total(), 0);
    assert_eq!(src.stats.frame_id.as_deref(), Some("velodyne"));
    // Read as a 32-laser model's rings, the VLP-16's points are off their rings' elevations.
    let mut src = CloudChunks::new(
        bag.messages(&["/velodyne_points"]),
        spherecal::velodyne::Model::Hdl32e,
    );
    while src.next_chunk(&mut chunk).unwrap() {}
    assert!(
        src.stats.off_elevation() > 0.5,
        "{}",
        src.stats.off_elevation()
    );
}

/// The VectorNav driver's `sensor_msgs` topics (Imu, NavSatFix, TimeReference time_gps of one
/// stamp; written by scripts/ros2-bag.py --ins-as-imu --time-ref as vn_sensor_msgs publishes
/// them, with its default use_enu and without) become frames with the groups' GPS time,
/// position and attitude: the quaternion turned back from RFU/ENU gives the yaw, pitch and
/// roll the group had (expected.json), to float32 precision.
#[test]
fn imu_navsatfix_and_time_reference_become_the_vn200_frames() {
    use super::nav::NavBytes;
    use spherecal::align::history::body_to_ned;
    use spherecal::vn200::binary::Frame;
    use spherecal::vn200::pose::{Attitude, Pose};
    let e = expected();
    let want = e["ins"].as_array().unwrap();
    for (name, enu) in [
        ("small_imu_time_ref.mcap", true),
        ("small_imu_ned_time_ref.mcap", false),
    ] {
        let bag = Bag::open(&data(name)).unwrap();
        let t = ["/vectornav/imu", "/vectornav/gnss", "/vectornav/time_gps"];
        let mut src = NavBytes::new(bag.messages(&t), t[0], t[1], t[2], 18);
        let mut buf = [0u8; 4096];
        let mut k = 0;
        while let ReadOutcome::Data { len, stamp } = src.read_chunk(&mut buf).unwrap() {
            let p = Pose::from_frame(&Frame::parse(&buf[..len]).unwrap()).unwrap();
            if let Some(w) = want.get(k) {
                same_stamp_time_and_place(&format!("{name} {k}"), w, stamp, &p);
                assert!(matches!(p.attitude, Attitude::Quaternion(_)));
                let ypr: Vec<f64> = w["ypr"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap().to_radians())
                    .collect();
                let from_ypr =
                    body_to_ned(&Attitude::YawPitchRoll([ypr[0], ypr[1], ypr[2]])).unwrap();
                let from_q = body_to_ned(&p.attitude).unwrap();
                assert!(
                    (from_q - from_ypr).abs().max() < 2e-6,
                    "{name} {k}: {from_q} vs {from_ypr}"
                );
                assert_eq!(
                    p.ins_status.map(|s| s & 7),
                    Some(2 | 4),
                    "tracking with a fix"
                );
            }
            k += 1;
        }
        let s = &src.stats;
        assert_eq!(k as u64, s.frames);
        assert_eq!(s.messages, [s.frames; 3], "{name}");
        assert_eq!(
            s.frames_enu_ned,
            if enu { [s.frames, 0] } else { [0, s.frames] }
        );
        assert_eq!(
            (s.other_reference, s.no_time, s.incomplete, s.bad),
            (0, 0, 0, 0)
        );
    }
    // Without the time reference: nothing can be timed.
    let bag = Bag::open(&data("small_imu.mcap")).unwrap();
    let t = ["/vectornav/imu", "/vectornav/gnss", "/vectornav/time_gps"];
    let mut src = NavBytes::new(bag.messages(&t), t[0], t[1], t[2], 18);
    assert!(matches!(
        src.read_chunk(&mut [0u8; 256]).unwrap(),
        ReadOutcome::End
    ));
    assert!(src.stats.no_time > 0 && src.stats.frames == 0);
}

/// A time reference read as GPS time (the VectorNav driver's) or UTC (an NMEA driver's), by
/// which lies near the host's clock; neither: refused.
#[test]
fn a_time_reference_is_gps_or_utc_by_the_hosts_clock() {
    use spherecal::ros2::nav::TimeReference;
    use spherecal::ros2::{Header, Time};
    let host = Time {
        sec: 1_718_189_965,
        nanosec: 0,
    };
    let r = |sec: i32| TimeReference {
        header: Header {
            stamp: host,
            frame_id: "",
        },
        time_ref: Time { sec, nanosec: 500 },
        source: "gps",
    };
    // GPS time 18 s ahead of UTC: Unix = GPS + 315964800 - 18.
    let gps = 1_718_189_965 - 315_964_800 + 18 + 2;
    assert_eq!(
        r(gps).gps_minus_host_ns(18),
        Some((gps as i64 - 1_718_189_965) * 1_000_000_000 + 500)
    );
    let utc = 1_718_189_965 + 2;
    assert_eq!(
        r(utc).gps_minus_host_ns(18),
        Some((utc as i64 - 315_964_800 + 18 - 1_718_189_965) * 1_000_000_000 + 500)
    );
    assert_eq!(r(12_345).gps_minus_host_ns(18), None);
}

/// A folder of unrelated recordings without a metadata.yaml (issue 46/47: six test bags read as
/// one recording of 8.4 years) is refused naming each with its span; files of one recording,
/// or overlapping in time, open.
#[test]
fn a_folder_of_unrelated_recordings_is_refused_naming_them() {
    let d = std::env::temp_dir().join(format!("spherecal-rosbag-folder-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    for f in ["mrpt_vlp16_clouds.mcap", "small_zstd.mcap"] {
        std::fs::copy(data(f), d.join(f)).unwrap();
    }
    let e = Bag::open(&d).unwrap_err().to_string();
    assert!(
        e.contains("holds 2 recordings whose times do not follow one another")
            && e.contains("mrpt_vlp16_clouds.mcap (0.1 s from 2016-01-21 08:18:02 UTC)")
            && e.contains("small_zstd.mcap"),
        "{e}"
    );
    std::fs::remove_file(d.join("mrpt_vlp16_clouds.mcap")).unwrap();
    std::fs::copy(data("small_lz4.mcap"), d.join("small_lz4.mcap")).unwrap();
    assert!(Bag::open(&d).is_ok());
    std::fs::remove_dir_all(&d).unwrap();
}

/// A Hesai's bag as tier4/nebula's driver records it (tests/data/hesai/qt64): every
/// `PandarScan` parses, its packets are the QT64's 1,072 bytes, the source hands them on in
/// order; a message cut anywhere is an error, not a panic.
#[test]
fn a_hesai_bags_pandar_scans_are_its_packets() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data/hesai/qt64/1673401195788312575");
    let bag = Bag::open(&dir).unwrap();
    let mut msgs = bag.messages(&["/pandar_packets"]);
    let mut first = None;
    let mut n = 0;
    while let Some(m) = msgs.next().unwrap() {
        let s = spherecal::ros2::PandarScan::parse(m.data).unwrap();
        for (_, p) in s.packets() {
            assert_eq!((p.len(), &p[..2]), (1072, &[0xEE, 0xFF][..]));
            n += 1;
        }
        first.get_or_insert_with(|| m.data.to_vec());
    }
    assert_eq!(n, 1200);
    let first = first.unwrap();
    for cut in (0..first.len()).step_by(97) {
        assert!(
            spherecal::ros2::PandarScan::parse(&first[..cut]).is_err(),
            "{cut}"
        );
    }
    let mut src = ScanPackets::pandar(bag.messages(&["/pandar_packets"]));
    let mut k = 0;
    while let Some(rec) = src.next_record().unwrap() {
        if let Record::Udp(d) = rec {
            assert_eq!((d.dst_port, d.payload.len()), (2368, 1072));
            k += 1;
        }
    }
    assert_eq!(k, 1200);
}

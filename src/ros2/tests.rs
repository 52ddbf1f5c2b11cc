//! Against messages serialised by an independent writer (PyPI `rosbags` 0.11.9, from the
//! drivers' message definitions: `scripts/ros2-vectors.py`; the values put in are in
//! `tests/data/ros2/expected.json`).

use super::*;

const SCAN: &[u8] = include_bytes!("../../tests/data/ros2/velodyne_scan.cdr");
const EMPTY: &[u8] = include_bytes!("../../tests/data/ros2/velodyne_scan_empty.cdr");
const COMMON: &[u8] = include_bytes!("../../tests/data/ros2/common_group.cdr");
const INS: &[u8] = include_bytes!("../../tests/data/ros2/ins_group.cdr");
const TIME: &[u8] = include_bytes!("../../tests/data/ros2/time_group.cdr");
const ATT: &[u8] = include_bytes!("../../tests/data/ros2/attitude_group.cdr");

#[test]
fn a_velodyne_scan_and_its_packets() {
    let s = VelodyneScan::parse(SCAN).unwrap();
    assert_eq!(
        s.header,
        Header {
            stamp: Time {
                sec: 1_700_000_002,
                nanosec: 5
            },
            frame_id: "velodyne"
        }
    );
    assert_eq!(s.count, 3);
    let p: std::vec::Vec<_> = s.packets().collect();
    assert_eq!(p.len(), 3);
    for (k, (t, d)) in p.iter().enumerate() {
        let k = k as u32;
        assert_eq!(t.sec, 1_700_000_000 + k as i32);
        assert_eq!(t.nanosec, 123_456_789 + k);
        // The pattern the writer put in: (k * 31 + i * 7) % 256.
        for (i, b) in d.iter().enumerate() {
            assert_eq!(
                u32::from(*b),
                (k * 31 + i as u32 * 7) % 256,
                "packet {k} byte {i}"
            );
        }
    }
    let e = VelodyneScan::parse(EMPTY).unwrap();
    assert_eq!((e.count, e.header.frame_id), (0, ""));
    assert_eq!(e.packets().count(), 0);
}

#[test]
fn a_common_group() {
    let c = CommonGroup::parse(COMMON).unwrap();
    assert_eq!(c.header.stamp.ns(), 1_700_000_003_250_000_000);
    assert_eq!(c.header.frame_id, "vectornav");
    assert_eq!(c.group_fields, 0x104A);
    assert!(c.has(CommonGroup::TIMEGPS | CommonGroup::YAWPITCHROLL | CommonGroup::POSITION));
    assert!(c.has(CommonGroup::INSSTATUS) && !c.has(CommonGroup::QUATERNION));
    assert_eq!(c.timegps, 1_384_000_000_123_456_789);
    assert_eq!(c.yawpitchroll, [12.5, -1.25, 0.75]);
    assert_eq!(c.position, [48.38, -4.49, 52.25]);
    assert_eq!(c.velocity, [1.5, -0.25, 0.0]);
    assert_eq!(c.insstatus.mode, 2);
    assert!(c.insstatus.gps_fix && c.insstatus.gps_heading_ins);
    // Mode 2 with a fix, the GNSS heading flag: as the VN-200 sends it.
    assert_eq!(c.insstatus.word(), 0b1_0000_0110);
    assert_eq!((c.syncincnt, c.timegpspps), (42, 7));
}

#[test]
fn an_ins_group() {
    let g = InsGroup::parse(INS).unwrap();
    assert!(g.has(InsGroup::POSU | InsGroup::POSLLA | InsGroup::INSSTATUS));
    assert_eq!(g.insstatus.mode, 3);
    assert!(!g.insstatus.gps_fix && g.insstatus.errors[3]);
    assert_eq!(g.poslla, [48.38, -4.49, 52.25]);
    assert_eq!(g.posu, 0.021);
}

#[test]
fn an_attitude_group() {
    let a = AttitudeGroup::parse(ATT).unwrap();
    assert_eq!(a.header.stamp.ns(), 1_700_000_006_000_000_007);
    assert_eq!(a.group_fields, 0x0102);
    assert!(a.has(AttitudeGroup::YPRU | AttitudeGroup::YAWPITCHROLL));
    assert_eq!(a.yawpitchroll, [271.5, 2.25, -3.5]);
    assert_eq!(a.ypru, [0.35, 0.04, 0.045]);
    for n in 0..ATT.len() {
        assert!(AttitudeGroup::parse(&ATT[..n]).is_err(), "{n}");
    }
}

#[test]
fn a_time_group() {
    let t = TimeGroup::parse(TIME).unwrap();
    assert_eq!(t.group_fields, 0x022E);
    assert!(t.has(TimeGroup::TIMEGPS | TimeGroup::GPSWEEK | TimeGroup::TIMESTATUS));
    assert_eq!(t.timegps, 1_384_000_000_123_456_789);
    assert_eq!((t.gpstow, t.gpsweek), (345_600_123_456_789, 2288));
    assert_eq!(t.timegpspps, 250_000_000);
    assert_eq!(t.timeutc, ([23, 11, 14, 22, 13, 20], 123));
    assert_eq!(t.timestatus, [true, true, false]);
    for n in 0..TIME.len() {
        assert!(TimeGroup::parse(&TIME[..n]).is_err(), "{n}");
    }
}

#[test]
fn every_cut_of_a_message_is_an_error_not_a_panic() {
    for n in 0..SCAN.len() {
        assert!(VelodyneScan::parse(&SCAN[..n]).is_err(), "{n}");
    }
    for n in 0..COMMON.len() {
        assert!(CommonGroup::parse(&COMMON[..n]).is_err(), "{n}");
    }
    for n in 0..INS.len() {
        assert!(InsGroup::parse(&INS[..n]).is_err(), "{n}");
    }
    // Any bytes: no panic.
    for msg in [SCAN, COMMON, INS] {
        for skip in 0..16 {
            let b = &msg[skip.min(msg.len())..];
            let _ = VelodyneScan::parse(b).map(|s| s.packets().count());
            let _ = CommonGroup::parse(b);
            let _ = InsGroup::parse(b);
        }
    }
    // Cut anywhere, a scan is refused with the offset where it ends.
    let e = VelodyneScan::parse(&SCAN[..SCAN.len() - 1]).unwrap_err();
    assert!(
        matches!(
            e,
            cdr::Error::Truncated {
                expected: "packet data",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(CommonGroup::parse(&COMMON[..COMMON.len() - 1]).is_err());
    assert!(InsGroup::parse(&INS[..INS.len() - 1]).is_err());
}

#[test]
fn a_common_group_back_into_the_vn200_frame() {
    use crate::vn200::binary::Frame;
    use crate::vn200::pose::{Attitude, Pose};
    let c = CommonGroup::parse(COMMON).unwrap();
    let mut out = [0u8; VN200_FRAME_MAX];
    let n = c
        .vn200_frame(Some([0.35, 0.04, 0.045]), Some(0.021), &mut out)
        .unwrap();
    let f = Frame::parse(&out[..n]).unwrap();
    assert_eq!(f.bytes().len(), n);
    // The values rosbags put in, as the VN-200 sends them (f32 attitudes).
    let p = Pose::from_frame(&f).unwrap();
    assert_eq!(p.time.0, 1_384_000_000_123_456_789);
    assert_eq!(
        (p.lat.to_degrees(), p.lon.to_degrees(), p.h),
        (48.38, -4.49, 52.25)
    );
    let Attitude::YawPitchRoll(y) = p.attitude else {
        panic!("{:?}", p.attitude)
    };
    for (got, want) in y.iter().zip([12.5f32, -1.25, 0.75]) {
        assert_eq!(*got, f64::from(want).to_radians());
    }
    assert_eq!(p.ins_status, Some(0b1_0000_0110));
    assert_eq!(f.position_uncertainty_m(), Some(0.021));
    assert_eq!(f.ypr_uncertainty_deg(), Some([0.35, 0.04, 0.045]));
    // Without the sigmas, and a group with none of the fields: nothing.
    let n2 = c.vn200_frame(None, None, &mut out).unwrap();
    assert_eq!(n2, n - 2 * 2 - 12 - 4);
    let mut none = c;
    none.group_fields = 0x0001;
    assert_eq!(none.vn200_frame(None, None, &mut out), None);
}

const CLOUD: &[u8] = include_bytes!("../../tests/data/ros2/cloud_xyzirt.cdr");
const CLOUD_BIG: &[u8] = include_bytes!("../../tests/data/ros2/cloud_xyzirt_big_organised.cdr");

#[test]
fn a_velodyne_pointcloud_cloud_little_and_big_endian_organised_or_not() {
    use cloud::*;
    // Written by rosbags (scripts/ros2-vectors.py): x, y, z, intensity, ring, time [s].
    let want = [
        (10.0, 0.0, -2.679492, 7.0, 0, -0.05),
        (0.0, -5.0, 0.0874887, 100.0, 8, -0.0251),
        (f32::NAN, f32::NAN, f32::NAN, 0.0, 3, 0.0),
        (-3.0, 4.0, 1.339746, 255.0, 15, 0.001234),
    ];
    for (b, height, width) in [(CLOUD, 1, 4), (CLOUD_BIG, 2, 2)] {
        let c = PointCloud2::parse(b).unwrap();
        assert_eq!(
            c.header.stamp,
            Time {
                sec: 1_700_000_010,
                nanosec: 500_000_000
            }
        );
        assert_eq!(c.header.frame_id, "velodyne");
        assert_eq!((c.height, c.layout.width, c.len()), (height, width, 4));
        assert_eq!(c.layout.big, height == 2);
        for (i, w) in want.iter().enumerate() {
            let Some(p) = c.point(i) else {
                assert!(w.0.is_nan(), "point {i} is a return");
                continue;
            };
            assert_eq!((p.x, p.y, p.z), (w.0, w.1, w.2), "point {i}");
            assert_eq!((p.intensity, p.ring), (w.3, w.4));
            // float32 time (the little-endian cloud) is within a nanosecond of the float64.
            let t = (w.5 * 1e9_f64).round() as i64;
            assert!(
                (p.time_ns - t).abs() <= 1,
                "point {i}: {} ns, want {t}",
                p.time_ns
            );
        }
        assert_eq!(c.point(4), None);
    }
}

#[test]
fn a_clouds_points_in_the_lidar_frame_with_the_laser_ids() {
    use crate::velodyne::Model;
    use cloud::*;
    let c = PointCloud2::parse(CLOUD).unwrap();
    let l = Lasers::new(Model::Vlp16);
    // VLP-16 (manual table 9-1): ring r is laser 2r below the horizon, 2(r - 8) + 1 above.
    let ids: std::vec::Vec<u8> = (0..16).map(|r| l.laser(r).unwrap()).collect();
    assert_eq!(ids, [0, 2, 4, 6, 8, 10, 12, 14, 1, 3, 5, 7, 9, 11, 13, 15]);
    assert_eq!(l.laser(16), None);
    let p0 = l.point(&c.point(0).unwrap(), 7).unwrap();
    // 10 m ahead on the -15 deg laser (beam-origin offset 11.2 mm, manual table 9-1): the
    // LiDAR's y (forward), azimuth 0; the driver's offset across the beam (horizontal
    // d cos v - o sin v, z d sin v + o cos v) back to the manual's (z + o).
    let (v, o) = ((-15f64).to_radians(), 0.0112);
    let (h, z) = (10.0 + o * v.sin(), -2.679492 + o * (1.0 - v.cos()));
    let d = (h * h + (z - o) * (z - o)).sqrt();
    assert_eq!((p0.x, p0.laser, p0.offset_ns), (0.0, 0, 7));
    assert!((f64::from(p0.y) - h).abs() < 2e-6, "{}", p0.y);
    assert!((f64::from(p0.z) - z).abs() < 2e-6, "{}", p0.z);
    assert!((f64::from(p0.range) - d).abs() < 2e-6 && p0.azimuth.abs() < 1e-6);
    assert_eq!(p0.distance_raw, (d / 0.002).round() as u16);
    let p1 = l.point(&c.point(1).unwrap(), 0).unwrap();
    // 5 m to the right (ROS y = -5): LiDAR x = 5, azimuth 90 deg clockwise from forward.
    assert_eq!((p1.y, p1.laser, p1.intensity), (0.0, 1, 100));
    assert!((p1.x - 5.0).abs() < 1e-4, "{}", p1.x);
    assert!((p1.azimuth - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
    let p3 = l.point(&c.point(3).unwrap(), 0).unwrap();
    assert!(
        (p3.azimuth.to_degrees() - 233.130_1).abs() < 1e-3,
        "{}",
        p3.azimuth.to_degrees()
    );
    // A point off its ring's cone (a cloud in another frame), a ring the model has not.
    let mut off = c.point(0).unwrap();
    off.z = 0.0;
    assert_eq!(l.point(&off, 0), Err(PointSkip::Elevation));
    off.ring = 16;
    assert_eq!(l.point(&off, 0), Err(PointSkip::Ring));
    // 32-laser models: the rings are in order of elevation too.
    for m in [Model::Hdl32e, Model::Vlp32c, Model::PuckHiRes] {
        let l = Lasers::new(m);
        let e: std::vec::Vec<f64> = (0..m.lasers() as u16)
            .map(|r| m.beam(usize::from(l.laser(r).unwrap())).elevation_deg)
            .collect();
        assert!(e.windows(2).all(|w| w[0] <= w[1]), "{m:?}: {e:?}");
    }
}

#[test]
fn clouds_spherecal_cannot_read_say_why() {
    use cloud::*;
    // The field named "ring" renamed: the layout names what is missing.
    let mut b = CLOUD.to_vec();
    let at = b.windows(5).position(|w| w == b"ring\0").unwrap();
    b[at + 3] = b'x';
    assert_eq!(
        PointCloud2::parse(&b).unwrap_err(),
        CloudError::Layout(LayoutError::Missing("ring"))
    );
    assert!(PointCloud2::parse(&b)
        .unwrap_err()
        .to_string()
        .contains("no 'ring' field"));
    // Cut anywhere: a CDR error with the offset, never a panic.
    for n in 0..CLOUD.len() {
        assert!(PointCloud2::parse(&CLOUD[..n]).is_err(), "cut at {n}");
    }
    // width claimed larger than the data.
    let mut b = CLOUD.to_vec();
    let c = PointCloud2::parse(CLOUD).unwrap();
    let _ = c;
    let at = 4 + 8 + 4 + 9 + 3 + 4; // encapsulation, stamp, frame_id (len + "velodyne\0" + pad), height
    assert_eq!(
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap()),
        4,
        "width's offset"
    );
    b[at] = 40;
    assert!(matches!(
        PointCloud2::parse(&b).unwrap_err(),
        CloudError::Layout(LayoutError::Size {
            data: 88,
            needed: 880
        })
    ));
}

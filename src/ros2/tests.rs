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

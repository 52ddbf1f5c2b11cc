//! POS MV group tests: a Group 7 written out byte by byte from the ICD's tables, emit/parse
//! round trips (proptest), framing in any chunking, resync after garbage, checksum failures
//! counted, arbitrary bytes.

use super::*;
use proptest::prelude::*;

/// Group 7 (Table 15) written out by hand: 44 bytes, byte count 36, pad 1. Its words must sum
/// to zero; the checksum is worked out here from the ICD's rule, not by `emit_group`.
#[test]
fn hand_written_group_7() {
    let mut b = Vec::new();
    b.extend_from_slice(b"$GRP");
    b.extend_from_slice(&7u16.to_le_bytes());
    b.extend_from_slice(&36u16.to_le_bytes());
    b.extend_from_slice(&345_600.5f64.to_le_bytes()); // time 1: GPS seconds of week
    b.extend_from_slice(&1234.25f64.to_le_bytes()); // time 2: POS time
    b.extend_from_slice(&0f64.to_le_bytes()); // distance
    b.push(0x01); // time 1 GPS, time 2 POS
    b.push(1); // POS distance
    b.extend_from_slice(&77u32.to_le_bytes()); // PPS count
    b.push(2); // fully synchronized
    b.push(0); // pad
               // Checksum: minus the sum of every other 16-bit LE word, "$#" included.
    let mut sum: u32 = 0;
    let words: Vec<u16> = b
        .chunks(2)
        .map(|w| u16::from_le_bytes([w[0], w[1]]))
        .chain([u16::from_le_bytes(*b"$#")])
        .collect();
    for w in words {
        sum = (sum + u32::from(w)) & 0xFFFF;
    }
    let ck = ((0x1_0000 - sum) & 0xFFFF) as u16;
    b.extend_from_slice(&ck.to_le_bytes());
    b.extend_from_slice(b"$#");
    assert_eq!(b.len(), 44);

    let g = Group::new_checked(&b[..]).unwrap();
    assert_eq!((g.id(), g.byte_count(), g.len()), (7, 36, 44));
    let p = PpsTime::parse(&g).unwrap();
    assert_eq!(p.pps_count, 77);
    assert_eq!(p.sync, TimeSync::Synchronized);
    assert_eq!(p.time.time1, 345_600.5);
    assert_eq!(p.time.time1_type, TimeType::Gps);
    assert_eq!(p.time.time2_type, TimeType::Pos);
    // Our emit side writes the same bytes.
    let mut out = [0u8; 64];
    assert_eq!(p.emit(&mut out), Some(44));
    assert_eq!(&out[..44], &b[..]);
    // One flipped bit: refused with the sum found.
    let mut bad = b.clone();
    bad[40] ^= 0x10;
    assert!(matches!(
        Group::new_checked(&bad[..]),
        Err(Error::Checksum { .. })
    ));
    // A group asked for as another is refused, naming it.
    assert_eq!(Navigation::parse(&g), Err(Error::WrongGroup { found: 7 }));
}

#[test]
fn group_lengths_follow_the_tables() {
    let mut out = [0u8; 256];
    let n = Navigation {
        time: TimeFields::default(),
        lla: [48.0, -4.0, 50.0],
        velocity: [1.0, 2.0, 3.0],
        rph: [1.0, 2.0, 3.0],
        wander: 0.0,
        track_speed: [0.0, 0.0],
        rate: [0.0; 3],
        accel: [0.0; 3],
        alignment: Alignment::FullNavigation,
    };
    assert_eq!(n.emit(&mut out), Some(140));
    assert_eq!(u16::from_le_bytes([out[6], out[7]]), 132);
    let s = SensorNavigation {
        id: 102,
        time: TimeFields::default(),
        lla: [0.0; 3],
        velocity: [0.0; 3],
        rph: [0.0; 3],
        wander: 0.0,
        heave: 0.1,
        rate: [0.0; 3],
        accel: [0.0; 3],
    };
    assert_eq!(s.emit(&mut out), Some(136));
    let m = Metrics {
        time: TimeFields::default(),
        position_rms: [0.02; 3],
        velocity_rms: [0.01; 3],
        attitude_rms: [0.01; 3],
        ellipse: [0.0; 3],
    };
    assert_eq!(m.emit(&mut out), Some(88));
    assert_eq!(n.emit(&mut out[..139]), None);
    let g = GnssStatus {
        time: TimeFields::default(),
        solution: 7,
        satellites: 14,
        channels: 0,
        dop: [0.8, 1.2],
        week: 2290,
        utc_offset: 18.0,
        receiver: 16,
    };
    assert_eq!(g.emit(&mut out), Some(84));
    assert_eq!(u16::from_le_bytes([out[6], out[7]]), 76);
    assert_eq!(
        GnssStatus::parse(&Group::new_checked(&out[..84]).unwrap()),
        Ok(g)
    );
}

fn f64s() -> impl Strategy<Value = f64> {
    prop_oneof![-1e6f64..1e6, Just(f64::NAN)]
}

fn f32s() -> impl Strategy<Value = f32> {
    -1e4f32..1e4
}

fn time_fields() -> impl Strategy<Value = TimeFields> {
    (
        0.0f64..700_000.0,
        0.0f64..1e6,
        0.0f64..1e6,
        0u8..4,
        0u8..4,
        0u8..3,
    )
        .prop_map(|(time1, time2, distance, a, b, distance_type)| TimeFields {
            time1,
            time2,
            distance,
            time1_type: TimeType::from_code(a),
            time2_type: TimeType::from_code(b),
            distance_type,
        })
}

fn navigation() -> impl Strategy<Value = Navigation> {
    (
        time_fields(),
        [f64s(), f64s(), f64s()],
        [f32s(), f32s(), f32s()],
        [f64s(), f64s(), f64s()],
        f64s(),
        [f32s(), f32s()],
        [f32s(), f32s(), f32s()],
        [f32s(), f32s(), f32s()],
        any::<u8>(),
    )
        .prop_map(
            |(time, lla, velocity, rph, wander, track_speed, rate, accel, a)| Navigation {
                time,
                lla,
                velocity,
                rph,
                wander,
                track_speed,
                rate,
                accel,
                alignment: Alignment::from_byte(a),
            },
        )
}

/// Bitwise equality (NaN fields included).
fn same_nav(a: &Navigation, b: &Navigation) -> bool {
    let mut x = [0u8; 140];
    let mut y = [0u8; 140];
    a.emit(&mut x) == b.emit(&mut y) && x == y
}

proptest! {
    /// emit -> frame -> parse gives back the same group, for every group kind.
    #[test]
    fn round_trips(nav in navigation(), heave in f32s(), id in 102u16..104, count in any::<u32>(), sync in any::<u8>()) {
        let mut buf = [0u8; 512];
        let n = nav.emit(&mut buf).unwrap();
        let back = Navigation::parse(&Group::new_checked(&buf[..n]).unwrap()).unwrap();
        prop_assert!(same_nav(&back, &nav));

        let s = SensorNavigation { id, time: nav.time, lla: nav.lla, velocity: nav.velocity, rph: nav.rph, wander: nav.wander, heave, rate: nav.rate, accel: nav.accel };
        let n = s.emit(&mut buf).unwrap();
        let back = SensorNavigation::parse(&Group::new_checked(&buf[..n]).unwrap()).unwrap();
        let mut again = [0u8; 136];
        prop_assert_eq!(back.emit(&mut again), Some(136));
        prop_assert_eq!(&again[..], &buf[..136]);

        let p = PpsTime { time: nav.time, pps_count: count, sync: TimeSync::from_byte(sync) };
        let n = p.emit(&mut buf).unwrap();
        prop_assert_eq!(PpsTime::parse(&Group::new_checked(&buf[..n]).unwrap()).unwrap(), p);

        let m = Metrics { time: nav.time, position_rms: nav.velocity, velocity_rms: nav.rate, attitude_rms: nav.accel, ellipse: [heave, 1.0, 2.0] };
        let n = m.emit(&mut buf).unwrap();
        prop_assert_eq!(Metrics::parse(&Group::new_checked(&buf[..n]).unwrap()).unwrap(), m);
    }

    /// A stream of groups with garbage between them, framed whole and in random chunks: the
    /// same groups at the same offsets; a corrupted group is reported and counted, and the
    /// next one still found.
    #[test]
    fn framing_any_chunking(navs in prop::collection::vec(navigation(), 1..8),
                            garbage in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..40), 8),
                            corrupt in any::<prop::sample::Index>(),
                            chunks in prop::collection::vec(1usize..64, 1..50)) {
        let mut stream = Vec::new();
        let mut expect = Vec::new();
        let bad = corrupt.index(navs.len());
        for (i, n) in navs.iter().enumerate() {
            // Garbage without a '$' cannot hold a group by chance.
            stream.extend(garbage[i].iter().map(|&b| if b == b'$' { b'#' } else { b }));
            let mut g = [0u8; 140];
            n.emit(&mut g).unwrap();
            if i == bad {
                g[60] ^= 0x01;
            } else {
                expect.push(stream.len() as u64);
            }
            stream.extend_from_slice(&g);
        }
        let run = |chunking: &[usize]| {
            let mut f: Framer<1024> = Framer::new();
            let (mut got, mut errors) = (Vec::new(), 0);
            let mut rest = &stream[..];
            let mut k = 0;
            while !rest.is_empty() {
                let take = chunking.get(k % chunking.len().max(1)).copied().unwrap_or(rest.len()).min(rest.len());
                k += 1;
                f.consume(&rest[..take], |it| match it.item {
                    Item::Group(g) => got.push((it.offset, g.id())),
                    Item::Error(_) => errors += 1,
                    Item::Message(_) => {}
                });
                rest = &rest[take..];
            }
            f.finish();
            while let Some(it) = f.next() {
                if let Item::Group(g) = it.item { got.push((it.offset, g.id())); }
            }
            (got, errors, *f.stats())
        };
        let (whole, e1, s1) = run(&[stream.len()]);
        let (chunked, e2, s2) = run(&chunks);
        let (bytewise, e3, _) = run(&[1]);
        prop_assert_eq!(whole.iter().map(|g| g.0).collect::<Vec<_>>(), expect);
        prop_assert_eq!(&whole, &chunked);
        prop_assert_eq!(&whole, &bytewise);
        prop_assert_eq!((e1, e2, e3), (1, 1, 1));
        prop_assert_eq!(s1.checksum_failures, 1);
        prop_assert_eq!(s1, s2);
        prop_assert_eq!(s1.groups as usize, navs.len() - 1);
    }

    /// Arbitrary bytes never panic, and whatever is accepted checks.
    #[test]
    fn arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..2000)) {
        let mut f: Framer<512> = Framer::new();
        f.consume(&bytes, |it| {
            if let Item::Group(g) = it.item {
                let _ = Navigation::parse(&g);
                let _ = SensorNavigation::parse(&g);
                let _ = PpsTime::parse(&g);
                let _ = Metrics::parse(&g);
                let _ = g.time_fields();
            }
        });
        let _ = Group::new_checked(&bytes[..]);
    }
}

#[test]
fn pose_time_and_validity() {
    let mut n = Navigation {
        time: TimeFields {
            time1: 345_600.0,
            time1_type: TimeType::Utc,
            ..TimeFields::default()
        },
        lla: [48.38, -4.49, 52.0],
        velocity: [0.0; 3],
        rph: [1.0, -2.0, 350.0],
        wander: 0.0,
        track_speed: [0.0; 2],
        rate: [0.0; 3],
        accel: [0.0; 3],
        alignment: Alignment::FullNavigation,
    };
    // UTC seconds of week + 18 leap seconds, week 2290.
    let p = Pose::from_navigation(&n, 2290, 18).unwrap();
    assert_eq!(
        p.time,
        crate::time::GpsTime::from_week_tow_s(2290, 345_618.0).unwrap()
    );
    assert!((p.rph[2] - 350f64.to_radians()).abs() < 1e-15);
    // GPS seconds of week: no leap seconds.
    n.time.time1_type = TimeType::Gps;
    let p = Pose::from_navigation(&n, 2290, 18).unwrap();
    assert_eq!(
        p.time,
        crate::time::GpsTime::from_week_tow_s(2290, 345_600.0).unwrap()
    );
    // POS time in both: no GNSS time yet.
    n.time.time1_type = TimeType::Pos;
    assert_eq!(
        Pose::from_navigation(&n, 2290, 18),
        Err(PoseError::NoGnssTime)
    );
    // Time 2 in GPS time is used when time 1 is not.
    n.time.time2_type = TimeType::Gps;
    n.time.time2 = 1000.0;
    let p = Pose::from_navigation(&n, 2290, 18).unwrap();
    assert_eq!(
        p.time,
        crate::time::GpsTime::from_week_tow_s(2290, 1000.0).unwrap()
    );
    // The ICD's invalid double (all ones: a NaN) in the latitude.
    n.lla[0] = f64::from_bits(u64::MAX);
    assert_eq!(Pose::from_navigation(&n, 2290, 18), Err(PoseError::Invalid));
}

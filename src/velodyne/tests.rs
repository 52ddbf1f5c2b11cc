//! Packet-level tests: hand-worked dual-return packets, emit/parse round trips (proptest) and
//! arbitrary bytes.

use super::data::{field, DATA_PACKET_LEN};
use super::*;
use proptest::prelude::*;

fn set_all_flags(buf: &mut [u8]) {
    let mut p = DataPacket::new_unchecked(buf);
    for b in 0..12 {
        p.set_flag(b);
    }
}

/// Expected point, worked out from the manual's rules in f64.
fn manual_point(distance_raw: u16, laser: usize, azimuth_deg: f64) -> [f64; 3] {
    let elev = [
        -15., 1., -13., 3., -11., 5., -9., 7., -7., 9., -5., 11., -3., 13., -1., 15.,
    ][laser];
    let voff = [
        11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7, -11.2,
    ][laser];
    let d = f64::from(distance_raw) * 0.002;
    let (w, t): (f64, f64) = (f64::to_radians(elev), azimuth_deg.to_radians());
    [
        d * w.cos() * t.sin(),
        d * w.cos() * t.cos(),
        d * w.sin() + voff * 1e-3,
    ]
}

fn close(p: &Point, e: [f64; 3], tol: f64) -> bool {
    (f64::from(p.x) - e[0]).abs() < tol
        && (f64::from(p.y) - e[1]).abs() < tol
        && (f64::from(p.z) - e[2]).abs() < tol
}

/// A hand-written dual-return packet: pairs at 10.00, 10.40, ... deg (0.40 deg per pair).
#[test]
fn hand_written_dual_return_packet() {
    let mut buf = [0u8; DATA_PACKET_LEN];
    set_all_flags(&mut buf);
    let mut p = DataPacket::new_unchecked(&mut buf[..]);
    for b in 0..12 {
        p.set_azimuth_raw(b, 1000 + 40 * (b as u16 / 2));
    }
    p.set_channel(0, 5, 5000, 10); // pair 0, last return: 10 m, laser 5
    p.set_channel(1, 5, 4000, 200); // pair 0, strongest: 8 m
    p.set_channel(10, 31, 1000, 7); // pair 5, last, sequence 1, laser 15
    p.set_channel(11, 31, 1500, 9); // pair 5, strongest
    p.set_timestamp_us(123_456);
    p.set_return_mode(ReturnMode::Dual);
    p.set_product_raw(0x22);

    let p = DataPacket::new_checked(&buf[..]).unwrap();
    let mut out = PointBuf::new();
    assert_eq!(decode(&p, &mut out), Ok(4));
    let pts = out.as_slice();

    // Pair 0, laser 5 of sequence 0: fires 5 * 2.304 = 11.52 us after the stamp, at
    // 10.00 + 0.40 * 11.52 / 110.592 deg = 10.041666.. deg.
    let az0 = 10.0 + 0.40 * 11.52 / 110.592;
    assert_eq!(
        (pts[0].block, pts[0].channel, pts[0].ret),
        (0, 5, Return::DualLast)
    );
    assert_eq!(pts[0].offset_ns, 11_520);
    assert!((f64::from(pts[0].azimuth).to_degrees() - az0).abs() < 1e-4);
    assert!(
        close(&pts[0], manual_point(5000, 5, az0), 2e-5),
        "{:?}",
        pts[0]
    );
    assert_eq!(pts[0].intensity, 10);
    assert_eq!(
        (pts[1].block, pts[1].ret, pts[1].offset_ns),
        (1, Return::DualStrongest, 11_520)
    );
    assert!((pts[1].azimuth - pts[0].azimuth).abs() < 1e-7);
    assert!(close(&pts[1], manual_point(4000, 5, az0), 2e-5));
    assert_eq!(pts[1].intensity, 200);

    // Pair 5 (blocks 10, 11), sequence 1, laser 15: 5 * 110.592 + 55.296 + 15 * 2.304
    // = 642.816 us; the last pair reuses the previous pair's 0.40 deg step:
    // 12.00 + 0.40 * (55.296 + 34.56) / 110.592 = 12.325 deg.
    let az5 = 12.0 + 0.40 * (55.296 + 34.56) / 110.592;
    for (pt, raw, ret) in [
        (&pts[2], 1000, Return::DualLast),
        (&pts[3], 1500, Return::DualStrongest),
    ] {
        assert_eq!((pt.sequence(), pt.laser(), pt.ret), (1, 15, ret));
        assert_eq!(pt.offset_ns, 642_816);
        assert!(
            (f64::from(pt.azimuth).to_degrees() - az5).abs() < 1e-4,
            "{}",
            pt.azimuth.to_degrees()
        );
        assert!(close(pt, manual_point(raw, 15, az5), 2e-5));
    }
}

/// Azimuth wraps from 359.9x to 0: the step is taken mod 360 and the result wrapped.
#[test]
fn azimuth_wraps_through_north() {
    let mut buf = [0u8; DATA_PACKET_LEN];
    set_all_flags(&mut buf);
    let mut p = DataPacket::new_unchecked(&mut buf[..]);
    for b in 0..12u16 {
        p.set_azimuth_raw(usize::from(b), (35_900 + 20 * b) % 36_000);
        p.set_channel(usize::from(b), 31, 500, 1);
    }
    p.set_return_mode(ReturnMode::Strongest);
    p.set_product_raw(0x22);
    let p = DataPacket::new_checked(&buf[..]).unwrap();
    let mut out = PointBuf::new();
    decode(&p, &mut out).unwrap();
    for (b, pt) in out.as_slice().iter().enumerate() {
        // 0.20 deg per block; channel 31 is n = 39 of 48 steps.
        let want = (359.0 + 0.2 * b as f64 + 0.2 * 39.0 / 48.0).rem_euclid(360.0);
        let got = f64::from(pt.azimuth).to_degrees();
        assert!((0.0..360.0).contains(&got));
        assert!((got - want).abs() < 1e-3, "block {b}: {got} vs {want}");
        assert!(close(pt, manual_point(500, 15, want), 2e-5));
    }
}

/// Real units send 36000 for north (velodyne_decoder and the ROS driver read it as 0): the
/// packet decodes exactly as with 0 there; 36001 is refused naming the block.
#[test]
fn azimuth_36000_is_north() {
    let packet = |north: u16| {
        let mut buf = [0u8; DATA_PACKET_LEN];
        set_all_flags(&mut buf);
        let mut p = DataPacket::new_unchecked(&mut buf[..]);
        for b in 0..12u16 {
            let a = (35_960 + 20 * b) % 36_000;
            p.set_azimuth_raw(usize::from(b), if a == 0 { north } else { a });
            p.set_channel(usize::from(b), 7, 700, 9);
        }
        p.set_return_mode(ReturnMode::Strongest);
        p.set_product_raw(0x22);
        buf
    };
    let (a, b) = (packet(0), packet(36_000));
    let (mut pa, mut pb) = (PointBuf::new(), PointBuf::new());
    decode(&DataPacket::new_checked(&a[..]).unwrap(), &mut pa).unwrap();
    decode(&DataPacket::new_checked(&b[..]).unwrap(), &mut pb).unwrap();
    assert_eq!(pa.as_slice(), pb.as_slice());
    // Block 2 sits at north: 0 deg + 7/48 of the 0.2 deg step for channel 7.
    let got = f64::from(pb.as_slice()[2].azimuth).to_degrees();
    assert!((got - 0.2 * 7.0 / 48.0).abs() < 1e-4, "{got}");
    let c = packet(36_001);
    assert_eq!(
        decode(&DataPacket::new_checked(&c[..]).unwrap(), &mut pa),
        Err(Error::BadAzimuth {
            block: 2,
            found: 36_001
        })
    );
}

fn block_strategy() -> impl Strategy<Value = BlockRepr> {
    (
        0u16..36_000,
        prop::array::uniform32((any::<u16>(), any::<u8>())),
    )
        .prop_map(|(azimuth, channels)| BlockRepr { azimuth, channels })
}

fn mode_strategy() -> impl Strategy<Value = ReturnMode> {
    prop_oneof![
        Just(ReturnMode::Strongest),
        Just(ReturnMode::Last),
        Just(ReturnMode::Dual)
    ]
}

fn repr_strategy() -> impl Strategy<Value = DataRepr> {
    (
        prop::array::uniform12(block_strategy()),
        any::<u32>(),
        mode_strategy(),
        prop_oneof![
            Just(0x22u8),
            Just(0x24),
            Just(0x21),
            Just(0x28),
            any::<u8>()
        ],
    )
        .prop_map(|(blocks, timestamp_us, return_mode, product)| DataRepr {
            blocks,
            timestamp_us,
            return_mode,
            product,
        })
}

proptest! {
    /// emit -> parse gives back the same packet, and decode finds exactly the non-zero channels
    /// with the schedule's offsets.
    #[test]
    fn data_emit_parse_round_trip(repr in repr_strategy()) {
        let mut buf = [0u8; DATA_PACKET_LEN];
        repr.emit(&mut DataPacket::new_unchecked(&mut buf[..]));
        let p = DataPacket::new_checked(&buf[..]).unwrap();
        prop_assert_eq!(DataRepr::parse(&p).unwrap(), repr);

        let mut out = PointBuf::new();
        let Some(model) = Model::from_product(repr.product) else {
            prop_assert_eq!(decode(&p, &mut out), Err(Error::UnknownProduct { found: repr.product }));
            prop_assert!(out.is_empty());
            return Ok(());
        };
        let n = decode(&p, &mut out).unwrap();
        let nonzero = repr.blocks.iter().flat_map(|b| b.channels.iter()).filter(|c| c.0 != 0).count();
        prop_assert_eq!(n, nonzero);
        for pt in out.as_slice() {
            let b = usize::from(pt.block);
            let (d, r) = repr.blocks[b].channels[usize::from(pt.channel)];
            prop_assert_eq!((pt.distance_raw, pt.intensity), (d, r));
            prop_assert_eq!(pt.ret, Return::of_block(repr.return_mode, b));
            prop_assert_eq!(pt.laser, model.channels()[usize::from(pt.channel)].laser);
            prop_assert_eq!(pt.offset_ns, firing::firing_offset_ns(model, repr.return_mode, b, usize::from(pt.channel)));
            let beam = model.beam(pt.laser());
            let range = f64::from(pt.x).hypot(f64::from(pt.y)).hypot(f64::from(pt.z) - beam.vertical_offset_m);
            let expect = f64::from(d) * model.distance_unit_m();
            prop_assert!((range - expect).abs() < 1e-5 * (1.0 + range));
            // The elevation is the laser's.
            let el = (f64::from(pt.z) - beam.vertical_offset_m).atan2(f64::from(pt.x).hypot(f64::from(pt.y)));
            prop_assert!(range < 1.0 || (el.to_degrees() - beam.elevation_deg).abs() < 1e-3);
            prop_assert!((0.0..core::f32::consts::TAU).contains(&pt.azimuth));
        }
    }

    /// Any 1206 bytes: views and decode never panic, and either refuse or give consistent points.
    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..1400), flags in any::<bool>()) {
        let mut bytes = bytes;
        if flags && bytes.len() >= 1200 {
            set_all_flags(&mut bytes);
        }
        if let Ok(p) = DataPacket::new_checked(&bytes[..]) {
            let mut out = PointBuf::new();
            let _ = DataRepr::parse(&p);
            if let Ok(n) = decode(&p, &mut out) {
                prop_assert_eq!(n, out.len());
                prop_assert!(n <= POINTS_PER_PACKET);
            }
        }
        if let Ok(p) = PositionPacket::new_checked(&bytes[..]) {
            let _ = p.nmea_time();
            let _ = p.pps();
        }
    }

    /// Position packets: emit -> parse.
    #[test]
    fn position_emit_parse_round_trip(stamp in any::<u32>(), pps in 0u8..4, nmea in "[$A-Z0-9,.*]{0,126}") {
        let mut buf = [0u8; position::POSITION_PACKET_LEN];
        let repr = PositionRepr { timestamp_us: stamp, pps: PpsStatus::from(pps), nmea: nmea.as_bytes() };
        prop_assert!(repr.emit(&mut PositionPacket::new_unchecked(&mut buf[..])));
        let view = PositionPacket::new_checked(&buf[..]).unwrap();
        prop_assert_eq!(PositionRepr::parse(&view).unwrap(), repr);
    }
}

#[test]
fn layout_constants_add_up() {
    assert_eq!(field::BLOCKS * field::BLOCK_LEN + 6, DATA_PACKET_LEN);
    assert_eq!(
        field::CHANNEL0 + field::CHANNELS * field::CHANNEL_LEN,
        field::BLOCK_LEN
    );
}

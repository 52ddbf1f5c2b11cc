//! Packets written byte by byte from the manuals' tables (not through the views), and the
//! manuals' own examples.

use super::*;

/// An XT32 packet (manual 3.1.2): block `b`'s azimuth `100 b + 1000` [0.01 deg], channel `c`'s
/// distance `10 b + c + 1` and reflectivity `c`; tail: return mode, 600 rpm, 2023-01-11
/// 01:31:17, 802 009 us; UDP sequence 77 when `seq`.
fn xt32(mode: u8, seq: bool) -> std::vec::Vec<u8> {
    let mut p = std::vec![0xEE, 0xFF, 6, 1, 0, 0, 32, 8, 0, 4, 2, u8::from(seq)];
    for b in 0..8u16 {
        p.extend_from_slice(&(100 * b + 1000).to_le_bytes());
        for c in 0..32u16 {
            p.extend_from_slice(&(10 * b + c + 1).to_le_bytes());
            p.push(c as u8);
            p.push(0);
        }
    }
    p.extend_from_slice(&[0; 10]);
    p.push(mode);
    p.extend_from_slice(&600u16.to_le_bytes());
    p.extend_from_slice(&[123, 1, 11, 1, 31, 17]);
    p.extend_from_slice(&802_009u32.to_le_bytes());
    p.push(0x42);
    if seq {
        p.extend_from_slice(&77u32.to_le_bytes());
    }
    p
}

#[test]
fn an_xt32_packet_reads_as_the_manual_lays_it_out() {
    let b = xt32(0x39, true);
    assert_eq!(b.len(), 1080, "the manual's UDP data: 1080 bytes");
    let p = DataPacket::new_checked(&b[..]).unwrap();
    assert_eq!(p.model(), Model::Xt32);
    assert_eq!(p.return_mode().returns(), 2);
    assert_eq!(p.distance_unit_mm(), 4);
    assert_eq!(p.azimuth(3), 1300);
    assert_eq!(p.unit(3, 31), (62, 31));
    assert_eq!(p.motor_rpm(), 600);
    assert_eq!(p.udp_sequence(), Some(77));
    // 2023-01-11T01:31:17.802009Z
    assert_eq!(p.unix_ns(), Some(1_673_400_677_802_009_000));
    // Without the sequence flag the packet is 4 bytes shorter.
    let short = xt32(0x37, false);
    let p = DataPacket::new_checked(&short[..]).unwrap();
    assert_eq!((p.udp_sequence(), p.return_mode().returns()), (None, 1));
}

#[test]
fn damaged_packets_are_refused_by_what_is_wrong() {
    let b = xt32(0x39, true);
    assert_eq!(
        DataPacket::new_checked(&b[..1079]).unwrap_err(),
        Error::Length {
            expected: 1080,
            got: 1079
        }
    );
    let mut v = b.clone();
    v[0] = 0xFF;
    v[1] = 0xEE;
    assert!(matches!(
        DataPacket::new_checked(&v[..]),
        Err(Error::Start { .. })
    ));
    let mut v = b.clone();
    v[6] = 40;
    assert!(matches!(
        DataPacket::new_checked(&v[..]),
        Err(Error::Layout { channels: 40, .. })
    ));
    let mut v = b.clone();
    v[1080 - 4 - 24 + 10] = 0x20;
    assert_eq!(
        DataPacket::new_checked(&v[..]).unwrap_err(),
        Error::ReturnMode { found: 0x20 }
    );
    // A date that is not one: no time, not a wrong one.
    let mut v = b.clone();
    v[1080 - 4 - 24 + 14] = 13;
    assert_eq!(DataPacket::new_checked(&v[..]).unwrap().unix_ns(), None);
    for n in 0..b.len() {
        let _ = DataPacket::new_checked(&b[..n]);
    }
}

#[test]
fn a_qt64_tail_is_laid_out_as_its_manual_says() {
    let mut p = std::vec![0xEE, 0xFF, 3, 1, 0, 0, 64, 4, 1, 4, 2, 1];
    for b in 0..4u16 {
        p.extend_from_slice(&(b * 60).to_le_bytes());
        for c in 0..64u16 {
            p.extend_from_slice(&(c + 7).to_le_bytes());
            p.extend_from_slice(&[9, 0]);
        }
    }
    p.extend_from_slice(&[0; 10]);
    p.extend_from_slice(&1200u16.to_le_bytes());
    p.extend_from_slice(&999_999u32.to_le_bytes());
    p.push(0x37);
    p.push(0x42);
    p.extend_from_slice(&[123, 1, 11, 1, 39, 55]);
    p.extend_from_slice(&5u32.to_le_bytes());
    assert_eq!(p.len(), 1072, "the manual's UDP data: 1072 bytes");
    let q = DataPacket::new_checked(&p[..]).unwrap();
    assert_eq!(q.model(), Model::Qt64);
    assert_eq!(
        (q.motor_rpm(), q.micros(), q.return_mode().returns()),
        (1200, 999_999, 1)
    );
    assert_eq!(q.date_time(), [123, 1, 11, 1, 39, 55]);
    assert_eq!(q.unit(3, 63), (70, 9));
    assert_eq!(q.udp_sequence(), Some(5));
}

/// The manuals' firing times: an XT's absolute time is the trigger of the firing in block 8
/// (blocks 7 and 8 in dual mode), firings 50 us apart; a QT64's blocks 166.67 us apart from
/// 25.71 us, channel 1 at 12.31 us and channel 64 at 146.45 us after its block's start.
#[test]
fn firing_times_follow_the_manuals_appendix() {
    assert_eq!(Model::Xt32.firing_offset_ns(7, 0, 1, 1), 6000);
    assert_eq!(Model::Xt32.firing_offset_ns(0, 0, 1, 1), 6000 - 7 * 50_000);
    assert_eq!(Model::Xt32.firing_offset_ns(6, 31, 2, 1), 6000 + 31 * 1512);
    assert_eq!(Model::Xt32.firing_offset_ns(0, 0, 2, 1), 6000 - 3 * 50_000);
    assert_eq!(Model::Xt16.firing_offset_ns(7, 15, 1, 1), 6000 + 15 * 3024);
    assert_eq!(Model::Qt64.firing_offset_ns(0, 0, 1, 1), 25_710 + 12_310);
    assert_eq!(
        Model::Qt64.firing_offset_ns(3, 63, 1, 1),
        25_710 + 500_000 + 146_450
    );
    assert_eq!(
        Model::Qt64.firing_offset_ns(3, 63, 2, 1),
        25_710 + 166_666 + 146_450
    );
    // QT128 single return: block 1 fires sequence 1 111.11 us after block 2's sequence 2.
    assert_eq!(
        Model::Qt128.firing_offset_ns(0, 32, 1, 1),
        9000 + 111_110 + 27_656
    );
    assert_eq!(Model::Qt128.firing_offset_ns(1, 0, 1, 2), 9000 + 2312);
    // Every channel fires after the one before it.
    for ch in 1..64 {
        assert!(
            Model::Qt64.firing_offset_ns(0, ch, 1, 1)
                > Model::Qt64.firing_offset_ns(0, ch - 1, 1, 1)
        );
    }
}

/// The PandarQT manual's GPS example (3.2.3): date '9','1' '2','0' '6','2' = 2019-02-26, time
/// '3','5' '4','5' '1','1' = 11:54:53; PPS locked, position valid.
#[test]
fn the_manuals_gps_example_reads_as_its_date_and_time() {
    let mut g = std::vec![0xDFu8; 512];
    g[0] = 0xFF;
    g[1] = 0xEE;
    g[2..14].copy_from_slice(b"912062354511");
    g[14..18].copy_from_slice(&0u32.to_le_bytes());
    let nmea = b"$GPRMC,115453.00,A,3101.7,N,12112.1,E,0.0,0.0,260219,,,A*6A";
    g[18..18 + nmea.len()].copy_from_slice(nmea);
    g[18 + nmea.len()..102].fill(0);
    g[506] = b'A';
    g[507] = 1;
    let p = GpsPacket::new_checked(&g[..]).unwrap();
    let t = p.utc().unwrap();
    assert_eq!(
        (t.year, t.month, t.day, t.hour, t.minute, t.second),
        (2019, 2, 26, 11, 54, 53)
    );
    assert_eq!(p.nmea(), &nmea[..]);
    assert!(p.pps_locked());
    assert_eq!(p.positioning(), b'A');
    g[507] = 0;
    g[3] = b'x';
    let p = GpsPacket::new_checked(&g[..]).unwrap();
    assert!(!p.pps_locked());
    assert_eq!(p.utc(), None);
    assert!(GpsPacket::new_checked(&g[..511]).is_err());
}

/// The emit side writes the manual's example byte for byte.
#[test]
fn an_emitted_gps_packet_is_the_manuals_example() {
    let mut g = std::vec![0xDFu8; 512];
    g[..2].copy_from_slice(&[0xFF, 0xEE]);
    g[2..14].copy_from_slice(b"912062354511");
    g[14..102].fill(0);
    let nmea = b"$GPRMC,115453.00,A,3101.7,N,12112.1,E,0.0,0.0,260219,,,A*6A";
    g[18..18 + nmea.len()].copy_from_slice(nmea);
    (g[506], g[507]) = (b'A', 1);
    let utc = crate::time::UtcDateTime {
        year: 2019,
        month: 2,
        day: 26,
        hour: 11,
        minute: 54,
        second: 53,
        nanos: 0,
    };
    let mut out = [0u8; 512];
    assert!(GpsPacket::emit(&mut out[..], &utc, nmea, b'A', true).is_some());
    assert_eq!(out[..], g[..]);
    assert!(GpsPacket::emit(&mut out[..511], &utc, nmea, b'A', true).is_none());
}

/// The emit side writes the manual's layout: the hand-built XT32 packet (its factory byte
/// aside, which a unit writes and the emit side leaves 0) and a QT128 whose CRCs agree.
#[test]
fn an_emitted_packet_is_the_manuals_layout() {
    let mut want = xt32(0x39, true);
    want[8] = 1; // the first block's return, as real units send it
    want[1075] = 0; // the factory byte
    let mut out = std::vec![0u8; Model::Xt32.emitted_len()];
    let mut p = DataPacket::emit(&mut out[..], Model::Xt32, ReturnMode::Dual(0x39), 77).unwrap();
    for b in 0..8u16 {
        p.set_azimuth(usize::from(b), 100 * b + 1000);
        for c in 0..32u16 {
            p.set_unit(usize::from(b), usize::from(c), 10 * b + c + 1, c as u8);
        }
    }
    p.set_time(600, [123, 1, 11, 1, 31, 17], 802_009);
    p.seal();
    assert_eq!(out, want);
    let mut q = std::vec![0u8; Model::Qt128.emitted_len()];
    let mut p = DataPacket::emit(&mut q[..], Model::Qt128, ReturnMode::Single(0x37), 9).unwrap();
    p.set_unit(1, 5, 1234, 7);
    p.seal();
    let p = DataPacket::new_checked(&q[..]).unwrap();
    let [(s0, c0), (s1, c1)] = p.crc().unwrap();
    assert_eq!((s0, s1, p.udp_sequence()), (c0, c1, Some(9)));
    assert_eq!(p.unit(1, 5), (1234, 7));
    assert!(DataPacket::emit(&mut q[..10], Model::Qt128, ReturnMode::Single(0x37), 9).is_none());
}

/// A channel with no offsets points along the block's azimuth; the angle-sum tables agree with
/// direct trigonometry at every offset.
#[test]
fn a_points_direction_is_the_block_azimuth_plus_the_channels_offset() {
    let el = [0.0, 15.0, -16.0];
    let az = [0.0, 1.042, -3.125];
    let c = Corrections::new(&el, &az).unwrap();
    let g = c.block(9000); // 90 deg: along +x
    let p = g.xyz(0, 10.0);
    assert!((p[0] - 10.0).abs() < 1e-12 && p[1].abs() < 1e-12 && p[2].abs() < 1e-12);
    for cz in [0u16, 4500, 17_999, 35_999] {
        let g = c.block(cz);
        for ch in 0..3 {
            let a = (f64::from(cz) * 0.01 + az[ch]).to_radians();
            let e = el[ch].to_radians();
            let want = [
                e.cos() * a.sin() * 7.5,
                e.cos() * a.cos() * 7.5,
                e.sin() * 7.5,
            ];
            let got = g.xyz(ch, 7.5);
            for k in 0..3 {
                assert!((got[k] - want[k]).abs() < 1e-12);
            }
        }
    }
    assert!((c.block(35_999).angles_deg(1).0 - 1.032).abs() < 1e-9);
    assert!((c.block(0).angles_deg(2).0 - 356.875).abs() < 1e-9);
    assert!(Corrections::new(&[0.0, f64::NAN], &[0.0, 0.0]).is_none());
    assert!(Corrections::new(&[0.0], &[0.0, 0.0]).is_none());
}

/// A QT128C2X packet (its manual 3.1.2): 2 blocks of 128 channels, the body's CRC-32/MPEG-2,
/// functional safety, the 34-byte tail with the UDP sequence and the tail's CRC, the
/// signature. The CRCs are the catalogue's CRC-32/MPEG-2 (check value 0x0376E6E7 of
/// "123456789"): a packet with a byte flipped disagrees.
#[test]
fn a_qt128_packet_carries_its_crcs_and_sequence_in_the_tail() {
    let crc = |b: &[u8]| {
        // CRC-32/MPEG-2 bit by bit: poly 0x04C11DB7, init all ones, no reflection, no xor.
        let mut c = 0xFFFF_FFFFu32;
        for &x in b {
            c ^= u32::from(x) << 24;
            for _ in 0..8 {
                c = if c & 0x8000_0000 != 0 {
                    (c << 1) ^ 0x04C1_1DB7
                } else {
                    c << 1
                };
            }
        }
        c
    };
    assert_eq!(crc(b"123456789"), 0x0376_E6E7);
    let mut p = std::vec![0xEE, 0xFF, 3, 2, 3, 0, 128, 2, 1, 4, 2, 0x1D];
    for b in 0..2u16 {
        p.extend_from_slice(&(b * 40 + 100).to_le_bytes());
        for c in 0..128u16 {
            p.extend_from_slice(&(c + 3 * b).to_le_bytes());
            p.extend_from_slice(&[c as u8, 0]);
        }
    }
    let body = crc(&p[12..]);
    p.extend_from_slice(&body.to_le_bytes());
    p.extend_from_slice(&[0; 17]);
    let mut tail = std::vec![0u8; 30];
    tail[5] = 1; // firing sequence 1
    tail[12] = 0x39;
    tail[13..15].copy_from_slice(&600u16.to_le_bytes());
    tail[15..21].copy_from_slice(&[120, 10, 9, 12, 3, 29]);
    tail[21..25].copy_from_slice(&403_019u32.to_le_bytes());
    tail[25] = 0x42;
    tail[26..30].copy_from_slice(&6_394_573u32.to_le_bytes());
    let t = crc(&tail);
    p.extend_from_slice(&tail);
    p.extend_from_slice(&t.to_le_bytes());
    assert_eq!(p.len(), 1095);
    p.extend_from_slice(&[0; 32]);
    let q = DataPacket::new_checked(&p[..]).unwrap();
    assert_eq!(q.model(), Model::Qt128);
    assert_eq!(q.udp_sequence(), Some(6_394_573));
    assert_eq!((q.motor_rpm(), q.micros()), (600, 403_019));
    assert_eq!(q.unit(1, 127), (130, 127));
    assert_eq!(q.crc(), Some([(body, body), (t, t)]));
    // 2020-10-09T12:03:29.403019Z
    assert_eq!(q.unix_ns(), Some(1_602_245_009_403_019_000));
    // Dual return, mode flag 1: sequence 1, both blocks at 9 us.
    assert_eq!(q.firing_offset_ns(0, 32), 9000 + 27_656);
    assert_eq!(q.firing_offset_ns(1, 32), 9000 + 27_656);
    assert!(DataPacket::new_checked(&p[..1095]).is_ok());
    assert!(DataPacket::new_checked(&p[..1100]).is_err());
    p[40] ^= 1;
    let [(s, c), _] = DataPacket::new_checked(&p[..]).unwrap().crc().unwrap();
    assert_ne!(s, c);
}

//! The aligner against hand-computed returns, clocks and counts.

use super::*;
use crate::time::{unix_ns_to_gps, UtcDateTime};
use crate::velodyne::position::write_gprmc;
use crate::velodyne::{BlockRepr, DataRepr, Model, PositionRepr, ReturnMode};
use nalgebra::{Matrix3, Vector3};
use std::vec::Vec;

/// 2023-11-14 23:00:00 UTC; the packets are stamped 30 minutes past it.
const HOUR_UNIX_S: i64 = 1_700_002_800;
const STAMP_US: u32 = 1_800_000_000;
const LEAP: i64 = 18;

fn t_packet() -> GpsTime {
    unix_ns_to_gps((HOUR_UNIX_S + 1800) * 1_000_000_000, LEAP)
}

/// One return: block 0, channel 1 (laser 1, +1 deg), 10.000 m, every azimuth 0.
fn data_packet() -> [u8; 1206] {
    let mut blocks = [BlockRepr {
        azimuth: 0,
        channels: [(0, 0); 32],
    }; 12];
    blocks[0].channels[1] = (5000, 100);
    let mut buf = [0u8; 1206];
    DataRepr {
        blocks,
        timestamp_us: STAMP_US,
        return_mode: ReturnMode::Strongest,
        product: 0x22,
    }
    .emit(&mut DataPacket::new_unchecked(&mut buf[..]));
    buf
}

/// A stationary platform at (10, 0, 0) NED, level, facing north: poses every 5 ms.
fn poses(from_s: f64, to_s: f64) -> impl Iterator<Item = PoseSample> {
    let t = t_packet().0;
    let n = ((to_s - from_s) / 0.005).round() as i64;
    (0..=n).map(move |i| {
        let ns = t + (from_s * 1e9) as i64 + i * 5_000_000;
        PoseSample::new(
            GpsTime(ns),
            Vector3::new(10.0, 0.0, 0.0),
            &Matrix3::identity(),
        )
    })
}

/// Hand-computed: zero mounting and a level pose put the return at P + (0, d cos 1, d sin 1
/// + v_1) (x right, y forward, z up; R_li = R_ig = I).
fn expected() -> Vector3<f64> {
    let e = 1f64.to_radians();
    Vector3::new(
        10.0,
        10.0 * e.cos(),
        10.0 * e.sin() + Model::Vlp16.beam(1).vertical_offset_m,
    )
}

/// An aligner with the zero mounting, a 0.5 m margin and no look-ahead.
fn level_aligner<'a, const H: usize, const B: usize>(
    targets: &'a [Target],
    batches: &'a mut [Batch<B>],
    history: &'a mut PoseHistory<H>,
) -> Aligner<'a, H, B> {
    Aligner::new(
        targets,
        batches,
        history,
        0.5,
        Mount::from_params(&crate::georef::Params([0.0; 6])),
        LEAP,
        0,
    )
}

type Seen = Vec<(usize, Vec<Observation>)>;

fn run(offset_ns: i64, rmc: bool) -> (Vec<GeoPoint>, Seen, AlignStats) {
    let targets = [
        Target {
            center: expected() + Vector3::new(0.0, 0.05, 0.0),
            radius: 0.1,
        },
        Target {
            center: Vector3::new(-50.0, 0.0, 0.0),
            radius: 0.1,
        },
    ];
    let mut batches = [Batch::<8>::default(), Batch::default()];
    let mut history = PoseHistory::<1024>::new(50_000_000);
    let mut al = level_aligner(&targets, &mut batches, &mut history);
    al.time_offset_ns = offset_ns;
    let packet = data_packet();
    // An empty history is waited for (garbage cannot get here: the packet is checked).
    assert!(DataPacket::new_checked(&packet[..100]).is_err());
    let packet = DataPacket::new_checked(&packet[..]).unwrap();
    assert!(al.wants_poses(&packet));
    if rmc {
        let utc = UtcDateTime {
            year: 2023,
            month: 11,
            day: 14,
            hour: 23,
            minute: 30,
            second: 0,
            nanos: 0,
        };
        let mut nmea = [0u8; 80];
        let n = write_gprmc(&mut nmea, &utc, 48.38, -4.49, true).unwrap();
        let mut pos = [0u8; 512];
        PositionRepr {
            timestamp_us: STAMP_US,
            pps: PpsStatus::Locked,
            nmea: &nmea[..n],
        }
        .emit(&mut PositionPacket::new_unchecked(&mut pos[..]));
        al.position(&PositionPacket::new_checked(&pos[..]).unwrap());
        assert_eq!(al.pps, Some(PpsStatus::Locked));
    }
    // Poses up to the packet's first firing (plus the offset) do not cover it...
    // With an offset, the host receives each pose 40 ms after its time and the packet
    // 10 ms after its stamp (on the INS clock): the LiDAR leads by 30 ms.
    let host = |t: i64, after: i64| (offset_ns != 0).then_some(HostTime(t + after));
    for p in poses(-1.0, offset_ns as f64 * 1e-9) {
        assert!(al.push_pose(p, host(p.time.0, 40_000_000)));
    }
    assert!(al.wants_poses(&packet));
    // ... 1.4 ms more do.
    for p in poses(offset_ns as f64 * 1e-9 + 0.005, 1.0) {
        assert!(al.push_pose(p, host(p.time.0, 40_000_000)));
    }
    assert!(!al.wants_poses(&packet));
    let mut points = Vec::new();
    let mut each = |g: &GeoPoint| points.push(*g);
    let mut seen: Seen = Vec::new();
    let mut emit = |i: usize, o: &[Observation]| seen.push((i, o.to_vec()));
    al.data(
        &packet,
        host(t_packet().0 + offset_ns, 10_000_000),
        Some(&mut each),
        &mut emit,
    );
    let lag = if offset_ns != 0 {
        Some(30_000_000)
    } else {
        None
    };
    assert_eq!(al.lag_ns, lag);
    assert_eq!(al.windowed_now(0), 1);
    assert_eq!(al.windowed_now(1), 0);
    al.finish(&mut emit);
    assert_eq!(al.windowed[..2], [1, 0]);
    (points, seen, al.stats)
}

#[test]
fn one_return_georeferenced_timed_and_windowed_by_hand() {
    for (offset_ns, rmc) in [
        (0, false),
        (0, true),
        (5_000_000, false),
        (-3_000_000, true),
    ] {
        let (points, seen, stats) = run(offset_ns, rmc);
        assert_eq!(points.len(), 1);
        let g = points[0];
        assert!((g.ned - expected()).norm() < 1e-5, "{:?}", g.ned);
        // The firing 2.304 us after the packet stamp (laser 1), on the INS clock.
        assert_eq!(g.time.0, t_packet().0 + 2_304 + offset_ns);
        assert_eq!(g.window, Some(0));
        assert_eq!(seen.len(), 1);
        let (sphere, obs) = &seen[0];
        assert_eq!((*sphere, obs.len()), (0, 1));
        assert_eq!((obs[0].packet, obs[0].block, obs[0].channel), (0, 0, 1));
        assert_eq!(obs[0].time, g.time);
        assert!((f64::from(obs[0].range) - 10.0).abs() < 1e-6);
        let from = if rmc { HourFrom::Rmc } else { HourFrom::Ins };
        assert_eq!(stats.hour_from, Some(from));
        assert_eq!((stats.data_packets, stats.packets_without_time), (1, 0));
        assert_eq!(stats.position_packets, u64::from(rmc));
        let s = t_packet().as_secs_f64();
        assert_eq!(stats.lidar_span, Some((s, s)));
    }
}

/// A point cloud's returns on the host's clock: GPS time is the host's plus the upper
/// envelope of the poses' GPS minus host stamps (the least-delayed pose), not their mean;
/// the bound follows a drifting host clock; without host-stamped poses nothing is timed.
#[test]
fn host_timed_returns_are_mapped_by_the_least_delayed_pose() {
    let targets = [Target {
        center: expected(),
        radius: 0.1,
    }];
    let mut batches = [Batch::<8>::default()];
    let mut history = PoseHistory::<1024>::new(50_000_000);
    let mut al = level_aligner(&targets, &mut batches, &mut history);
    let mut buf = PointBuf::new();
    velodyne::decode_as(
        &DataPacket::new_checked(data_packet()).unwrap(),
        Model::Vlp16,
        &mut buf,
    )
    .unwrap();
    let t0 = t_packet().0;
    al.points(HostTime(t0), buf.as_slice(), None, &mut |_, _| {});
    assert_eq!(
        (al.stats.packets_without_time, al.stats.data_packets),
        (1, 0)
    );
    // Received 2 ms after their time plus 0 to 1.5 ms of jitter.
    let jitter = [700_000, 0, 300_000, 1_500_000];
    for (i, p) in poses(-1.0, 1.0).enumerate() {
        assert!(al.push_pose(p, Some(HostTime(p.time.0 + 2_000_000 + jitter[i % 4]))));
    }
    // The least-delayed pose (3 poses back: the bound has leaked 3 x 5 ms x 100 ppm).
    let b = al.host_to_gps_ns().unwrap();
    assert_eq!(b, -2_000_000 - 1_500);
    assert!(!al.wants_poses_at_host(HostTime(t0 + 2_000_000), 0));
    let mut seen = Vec::new();
    al.points(
        HostTime(t0 + 2_000_000),
        buf.as_slice(),
        Some(&mut |g: &GeoPoint| seen.push(*g)),
        &mut |_, _| {},
    );
    assert_eq!(seen.len(), 1);
    // The firing 2.304 us after the first, on the GPS clock.
    assert_eq!(seen[0].time.0, t0 + 2_000_000 + b + 2_304);
    assert!(
        (seen[0].ned - expected()).norm() < 1e-5,
        "{:?}",
        seen[0].ned
    );
    assert_eq!(al.stats.data_packets, 1);

    // A host clock gaining 50 ppm (less than the 100 ppm the bound may fall) over 100 s:
    // the bound keeps within the jitter-free offset's 100 us.
    let mut history = PoseHistory::<1024>::new(200_000_000);
    let mut batches = [Batch::<8>::default()];
    let mut al = level_aligner(&targets, &mut batches, &mut history);
    for k in 0..1000i64 {
        let t = t0 + k * 100_000_000;
        let host = t + 2_000_000 + (k * 100_000_000) / 20_000 + jitter[k as usize % 4];
        let s = PoseSample::new(GpsTime(t), Vector3::zeros(), &Matrix3::identity());
        assert!(al.push_pose(s, Some(HostTime(host))));
        let exact = -2_000_000 - (k * 100_000_000) / 20_000;
        let b = al.host_to_gps_ns().unwrap();
        if k >= 4 {
            assert!(
                b <= exact && exact - b <= 100_000,
                "pose {k}: {b} vs {exact}"
            );
        }
    }
}

#[test]
fn a_packet_without_hour_or_pose_is_counted() {
    let targets = [Target {
        center: Vector3::zeros(),
        radius: 0.1,
    }];
    let mut batches = [Batch::<8>::default()];
    let mut history = PoseHistory::<16>::new(50_000_000);
    let mut al = level_aligner(&targets, &mut batches, &mut history);
    al.data(
        &DataPacket::new_checked(data_packet()).unwrap(),
        None,
        None,
        &mut |_, _| {},
    );
    assert_eq!(al.stats.packets_without_time, 1);
    assert_eq!(al.stats.data_packets, 0);
    assert_eq!(al.stats.hour_from, None);
}

/// The product byte decides the model: an unknown one (or one the period contradicts) is
/// never decoded as a VLP-16, and every refused packet is counted; a given model decodes
/// them. Packets 1327 us apart with the HDL-32E's byte: the VLP-16's period.
#[test]
fn refused_models_are_counted_and_a_given_model_decodes() {
    let targets = [Target {
        center: expected(),
        radius: 0.5,
    }];
    for (product, given, refused, identity) in [
        (0x99, None, 40, Some(Identity::Unknown { product: 0x99 })),
        (0x99, Some(Model::Vlp16), 0, None),
        (
            0x21,
            None,
            40 - 16,
            Some(Identity::Disagrees {
                product: 0x21,
                period_us: 1327,
                fits: Some(Model::Vlp16),
            }),
        ),
        (0x22, None, 0, Some(Identity::Agreed(Model::Vlp16))),
    ] {
        let mut batches = [Batch::<64>::default()];
        let mut history = PoseHistory::<1024>::new(50_000_000);
        let mut al = level_aligner(&targets, &mut batches, &mut history);
        al.set_model(given);
        for s in poses(-0.1, 0.2) {
            al.push_pose(s, None);
        }
        for k in 0..40u32 {
            let mut p = data_packet();
            p[1205] = product;
            p[1200..1204].copy_from_slice(&(STAMP_US + 1327 * k).to_le_bytes());
            al.data(
                &DataPacket::new_checked(&p[..]).unwrap(),
                None,
                None,
                &mut |_, _| {},
            );
        }
        assert_eq!(al.stats.model_refused, refused, "0x{product:02X}");
        assert_eq!(al.stats.identity, identity, "0x{product:02X}");
        assert_eq!(al.stats.data_packets, 40 - refused, "0x{product:02X}");
    }
}

/// Packets whose firings miss every window are counted, not decoded ([`Reach`]): over a
/// platform driving at 5 m/s and turning at 0.8 rad/s, with a tilted mounting, three spheres
/// around it and a 10 Hz scan of random ranges, the aligner hands on exactly the returns and
/// counts it does when it decodes every packet (a point cloud wanted), and spares most packets.
#[test]
fn packets_beyond_every_window_are_counted_alike_without_decoding() {
    use crate::sim::rng::Rng;
    let targets = [
        Target {
            center: Vector3::new(8.0, 3.0, -1.0),
            radius: 0.2,
        },
        Target {
            center: Vector3::new(-4.0, -9.0, 0.5),
            radius: 0.3,
        },
        Target {
            center: Vector3::new(20.0, -2.0, -2.0),
            radius: 0.2,
        },
    ];
    let mount = Mount::new(
        [2f64.to_radians(), -1f64.to_radians(), 30f64.to_radians()],
        [0.4, -0.2, -0.6],
    );
    let t = t_packet().0;
    let pose = |i: i64| {
        let s = i as f64 * 0.005;
        let heading = 0.8 * s;
        let r = nalgebra::Rotation3::from_euler_angles(0.02, -0.01, heading);
        PoseSample::new(
            GpsTime(t - 1_000_000_000 + i * 5_000_000),
            Vector3::new(-5.0 + 5.0 * s, 0.0, 0.0),
            r.matrix(),
        )
    };
    // 2 s of a VLP-16 at 10 Hz: a packet every 1.327 ms, 0.4 deg a block.
    let mut rng = Rng::new(11);
    let packets: Vec<[u8; 1206]> = (0..1500u32)
        .map(|k| {
            let mut blocks = [BlockRepr {
                azimuth: 0,
                channels: [(0, 0); 32],
            }; 12];
            for (b, bl) in blocks.iter_mut().enumerate() {
                bl.azimuth = ((k * 12 + b as u32) * 40 % 36_000) as u16;
                for c in bl.channels.iter_mut() {
                    if rng.chance(0.7) {
                        *c = (rng.range(500.0, 15_000.0) as u16, 50);
                    }
                }
            }
            let mut buf = [0u8; 1206];
            DataRepr {
                blocks,
                timestamp_us: STAMP_US + k * 1327,
                return_mode: ReturnMode::Strongest,
                product: 0x22,
            }
            .emit(&mut DataPacket::new_unchecked(&mut buf[..]));
            buf
        })
        .collect();
    let run = |cloud: bool| {
        let mut batches = [Batch::<64>::default(), Batch::default(), Batch::default()];
        let mut history = PoseHistory::<2048>::new(50_000_000);
        let mut al = Aligner::new(&targets, &mut batches, &mut history, 1.0, mount, LEAP, 0);
        al.set_model(Some(Model::Vlp16));
        for i in 0..1000 {
            assert!(al.push_pose(pose(i), None));
        }
        let mut seen: Seen = Vec::new();
        let mut emit = |i: usize, o: &[Observation]| seen.push((i, o.to_vec()));
        let mut each = |_: &GeoPoint| {};
        for p in &packets {
            let p = DataPacket::new_checked(&p[..]).unwrap();
            let cloud = cloud.then_some(&mut each as &mut dyn FnMut(&GeoPoint));
            al.data(&p, None, cloud, &mut emit);
        }
        al.finish(&mut emit);
        (seen, al.stats)
    };
    let (all, all_stats) = run(true);
    let (spared, spared_stats) = run(false);
    assert_eq!(all_stats.spared, 0);
    assert!(
        spared_stats.spared > 500,
        "spared {} of {}",
        spared_stats.spared,
        spared_stats.data_packets
    );
    assert_eq!(
        AlignStats {
            spared: 0,
            ..spared_stats
        },
        all_stats
    );
    for j in 0..3 {
        assert!(all_stats.window.windowed[j] > 20, "{:?}", all_stats.window);
    }
    assert!(all == spared, "the windows' returns differ");
}

//! A fixed amount of core-path work (decode -> align -> georef -> window over the MRPT capture,
//! 20 times) for deterministic instruction counts: `valgrind --tool=callgrind
//! target/release/examples/core_path_count` (criterion timings on a shared machine swing +-15 %).

use nalgebra::Vector3;
use spherecal::align::{PoseHistory, PoseSample};
use spherecal::frames::rotation;
use spherecal::georef::Mount;
use spherecal::time::{GpsTime, LidarClock};
use spherecal::vlp16::{decode, DataPacket, PointBuf, PositionPacket};
use spherecal::window::{Batch, Target, WindowStats, Windowing};
use std::hint::black_box;

fn main() {
    let path = format!(
        "{}/../../shared/data/vlp16/mrpt_vlp16_gps.pcap",
        env!("CARGO_MANIFEST_DIR")
    );
    let b = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let (mut data, mut pos) = (Vec::new(), None);
    let mut off = 24;
    while off + 16 <= b.len() {
        let incl = u32::from_le_bytes(b[off + 8..off + 12].try_into().unwrap()) as usize;
        let payload = &b[off + 16 + 42..off + 16 + incl];
        match payload.len() {
            1206 => data.push(payload.to_vec()),
            512 if pos.is_none() => pos = Some(payload.to_vec()),
            _ => {}
        }
        off += 16 + incl;
    }
    let pos = pos.unwrap();
    let pp = PositionPacket::new_checked(&pos[..]).unwrap();
    let mut clock = LidarClock::new(17);
    clock.set_from_rmc(&pp.nmea_time().unwrap().utc().unwrap(), pp.timestamp_us());
    let t_first = clock
        .to_gps(
            DataPacket::new_checked(&data[0][..])
                .unwrap()
                .timestamp_us(),
        )
        .unwrap();
    // A vessel going north at 2 m/s, rolling 2 deg over 5 s, sampled at 200 Hz.
    let mut history: Box<PoseHistory<4096>> = Box::new(PoseHistory::new(50_000_000));
    for j in 0..1000 {
        let t = t_first.0 - 1_000_000_000 + j * 5_000_000;
        let s = (t - t_first.0) as f64 * 1e-9;
        let r = rotation(0.035 * (s * 1.26).sin(), 0.0, 0.1);
        history.push(PoseSample::new(
            GpsTime(t),
            Vector3::new(2.0 * s, 0.0, 0.0),
            &r,
        ));
    }
    let targets = [
        Target {
            center: Vector3::new(3.0, -4.0, 0.5),
            radius: 0.19,
        },
        Target {
            center: Vector3::new(-2.0, 5.0, 0.0),
            radius: 0.19,
        },
    ];
    let mut batches: Vec<Batch<1024>> = (0..2).map(|_| Batch::default()).collect();
    let mount = Mount::new([0.0, 0.0, 0.0], [0.5, 0.0, -1.0]);
    let mut points = PointBuf::new();
    let total: usize = data
        .iter()
        .map(|d| decode(&DataPacket::new_checked(&d[..]).unwrap(), &mut points).unwrap())
        .sum();
    let _ = total;
    let mut sum = 0;
    for _ in 0..20 {
        let mut clock = clock;
        let mut win = Windowing {
            targets: &targets,
            margin: 0.5,
            mount,
            batches: &mut batches,
            stats: WindowStats::default(),
        };
        for d in &data {
            let p = DataPacket::new_checked(black_box(&d[..])).unwrap();
            let t0 = clock.to_gps(p.timestamp_us()).unwrap();
            decode(&p, &mut points).unwrap();
            win.add_packet(t0, &points, &history, None);
        }
        for bt in win.batches.iter_mut() {
            bt.obs.clear();
        }
        sum += win.stats.georeferenced;
    }
    println!("{sum} returns");
}

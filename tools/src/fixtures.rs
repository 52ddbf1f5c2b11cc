//! A fixed workload for benchmarks and profiling: the real MRPT capture's data packets, a clock
//! set from its first RMC, and a 200 Hz pose history (a vessel going north at 2 m/s, rolling
//! 2 deg over 5 s) around it, two sphere targets, and the pass over it all.

use nalgebra::Vector3;
use spherecal::align::window::{Batch, Target, WindowStats, Windowing};
use spherecal::align::{PoseHistory, PoseSample};
use spherecal::frames::rotation;
use spherecal::georef::Mount;
use spherecal::time::{GpsTime, LidarClock};
use spherecal::velodyne::{decode, DataPacket, PointBuf, PositionPacket};
use std::hint::black_box;

/// The workload.
pub struct CorePath {
    /// Data packet payloads.
    pub data: Vec<Vec<u8>>,
    /// The clock, hour known.
    pub clock: LidarClock,
    /// Poses around the capture.
    pub history: Box<PoseHistory<4096>>,
    /// Two spheres.
    pub targets: [Target; 2],
    /// A mounting.
    pub mount: Mount,
    /// Returns in the capture.
    pub returns: usize,
}

impl CorePath {
    /// Load `tests/data/vlp16/mrpt_vlp16_gps.pcap` (relative to the repository root).
    pub fn load() -> Self {
        let path = format!(
            "{}/../tests/data/vlp16/mrpt_vlp16_gps.pcap",
            env!("CARGO_MANIFEST_DIR")
        );
        let b = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let (mut data, mut pos) = (Vec::new(), None);
        let mut off = 24;
        while off + 16 <= b.len() {
            let incl =
                u32::from_le_bytes([b[off + 8], b[off + 9], b[off + 10], b[off + 11]]) as usize;
            let payload = &b[off + 16 + 42..off + 16 + incl];
            match payload.len() {
                1206 => data.push(payload.to_vec()),
                512 if pos.is_none() => pos = Some(payload.to_vec()),
                _ => {}
            }
            off += 16 + incl;
        }
        let pos = pos.expect("the MRPT capture has position packets");
        let pp = PositionPacket::new_checked(&pos[..]).expect("512 bytes");
        let mut clock = LidarClock::new(17);
        clock.set_from_rmc(
            &pp.nmea_time()
                .ok()
                .and_then(|t| t.utc())
                .expect("an RMC date"),
            pp.timestamp_us(),
        );
        let first = DataPacket::new_checked(&data[0][..])
            .expect("1206 bytes")
            .timestamp_us();
        let t_first = clock.clone().to_gps(first).expect("hour known");
        let mut history: Box<PoseHistory<4096>> = Box::new(PoseHistory::new(50_000_000));
        for j in 0..1000 {
            let t = t_first.0 - 1_000_000_000 + j * 5_000_000;
            let s = (t - t_first.0) as f64 * 1e-9;
            history.push(PoseSample::new(
                GpsTime(t),
                Vector3::new(2.0 * s, 0.0, 0.0),
                &rotation(0.035 * (s * 1.26).sin(), 0.0, 0.1),
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
        let mut points = PointBuf::new();
        let returns = data
            .iter()
            .filter_map(|d| decode(&DataPacket::new_checked(&d[..]).ok()?, &mut points).ok())
            .sum();
        Self {
            data,
            clock,
            history,
            targets,
            mount: Mount::new([0.0, 0.0, 0.0], [0.5, 0.0, -1.0]),
            returns,
        }
    }

    /// One pass over the capture: decode, align, georeference, window. Returns the returns
    /// georeferenced.
    pub fn run(&self, points: &mut PointBuf, batches: &mut [Batch<1024>]) -> u64 {
        let mut clock = self.clock;
        let mut win = Windowing {
            targets: &self.targets,
            margin: 0.5,
            mount: self.mount,
            batches,
            stats: WindowStats::default(),
        };
        for d in &self.data {
            let Ok(p) = DataPacket::new_checked(black_box(&d[..])) else {
                continue;
            };
            let Some(t0) = clock.to_gps(p.timestamp_us()) else {
                continue;
            };
            if decode(&p, points).is_ok() {
                win.add_packet(0, t0, points.as_slice(), &self.history, None);
            }
        }
        for b in win.batches.iter_mut() {
            b.obs.clear();
        }
        win.stats.georeferenced
    }
}

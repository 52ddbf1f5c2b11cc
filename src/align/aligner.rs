//! The aligner: the LiDAR clock (the hour from a valid RMC, else from the INS), the pose
//! history, each data packet's returns georeferenced with the a-priori mounting at their
//! firing's pose (plus the clocks' time offset) and windowed around the spheres.
//!
//! No heap and no waiting: the caller lends the history and one batch per sphere, pushes poses
//! with [`Aligner::push_pose`] until [`Aligner::wants_poses`] is false for a packet (or the INS
//! has ended, or its own deadline passed), then hands the packet to [`Aligner::data`].

use super::history::{PoseHistory, PoseSample};
use crate::georef::Mount;
use crate::time::{GpsTime, HostTime, LidarClock};
use crate::velodyne::{
    self, DataPacket, Identity, Model, Point, PointBuf, PositionPacket, PpsStatus,
};
use crate::window::{Batch, GeoPoint, Observation, Target, WindowStats, Windowing, MAX_TARGETS};

/// A packet's 24 firing sequences span 1.33 ms: the history must reach this far past its
/// first firing.
const PACKET_SPAN_NS: i64 = 1_400_000;
/// How fast the host-to-GPS bound of [`Aligner::points`] may fall [ns per s of GPS time]: a
/// host clock 100 ppm slow (NTP-disciplined clocks stay within tens of ppm).
pub const HOST_DRIFT_NS_PER_S: i64 = 100_000;

/// Where the LiDAR clock's hour came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HourFrom {
    /// A position packet's valid `$GPRMC`.
    Rmc,
    /// The nearest hour to the newest INS time (no valid RMC before the first data packet).
    Ins,
}

/// Counts of the align stage.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AlignStats {
    /// Data packets timed, decoded and windowed.
    pub data_packets: u64,
    /// Position packets seen.
    pub position_packets: u64,
    /// Data packets whose time could not be known (no RMC and no INS time yet).
    pub packets_without_time: u64,
    /// GPS seconds of the first and last data packet timed (on the LiDAR clock).
    pub lidar_span: Option<(f64, f64)>,
    /// Windowing counts.
    pub window: WindowStats,
    /// Hour rollovers unwrapped.
    pub rollovers: u32,
    /// Observations lost because a batch was full.
    pub batch_overflow: u64,
    /// Where the hour came from (None: not yet).
    pub hour_from: Option<HourFrom>,
    /// What the data packets say of the LiDAR model (None: no packet yet, or the model was
    /// given).
    pub identity: Option<Identity>,
    /// Data packets not decoded because their model is unknown or their product byte
    /// disagrees with their period ([`Identity`]); a run with any is not to be trusted.
    pub model_refused: u64,
}

/// The align stage over a history of `H` poses and batches of `B` observations.
pub struct Aligner<'a, const H: usize, const B: usize> {
    targets: &'a [Target],
    batches: &'a mut [Batch<B>],
    history: &'a mut PoseHistory<H>,
    margin: f64,
    mount: Mount,
    clock: LidarClock,
    points: PointBuf,
    lookahead_ns: i64,
    /// Newest pose's GPS time minus its host receive time [ns], if that time is known.
    ins_offset_ns: Option<i64>,
    /// The upper envelope of the poses' GPS time minus host time [ns], leaking
    /// [`HOST_DRIFT_NS_PER_S`], and the GPS time it was last raised or leaked at: host time to
    /// GPS time for returns timed by the host ([`Aligner::points`]).
    host_to_gps: Option<(i64, GpsTime)>,
    data_seen: u32,
    model: Option<Model>,
    detector: velodyne::Detector,
    /// Counts.
    pub stats: AlignStats,
    /// PPS state of the last position packet.
    pub pps: Option<PpsStatus>,
    /// LiDAR clock minus INS time, each against the host receive clock, at the last aligned
    /// packet [ns]: `(T_lidar - H_lidar) - (T_ins - H_ins)`.
    pub lag_ns: Option<i64>,
    /// Returns handed on per sphere so far.
    pub windowed: [u64; MAX_TARGETS],
    /// INS time minus LiDAR time [ns] (DESIGN.md conventions): a firing's pose is taken this
    /// much later. Call [`Self::finish`] before changing it, so a batch holds one offset.
    pub time_offset_ns: i64,
}

impl<'a, const H: usize, const B: usize> Aligner<'a, H, B> {
    /// An aligner windowing around `targets` (at most [`MAX_TARGETS`]; one batch each from
    /// `batches`, extra ones unused) with `mount` and a window `margin` [m]. `lookahead_ns`: how
    /// far past a packet the history should reach before it is aligned (files: the span the
    /// returns' velocity and turn rate are taken over; live: 0).
    pub fn new(
        targets: &'a [Target],
        batches: &'a mut [Batch<B>],
        history: &'a mut PoseHistory<H>,
        margin: f64,
        mount: Mount,
        leap_seconds: i64,
        lookahead_ns: i64,
    ) -> Self {
        let n = targets.len().min(batches.len()).min(MAX_TARGETS);
        Self {
            targets: &targets[..n],
            batches: &mut batches[..n],
            history,
            margin,
            mount,
            clock: LidarClock::new(leap_seconds),
            points: PointBuf::new(),
            lookahead_ns,
            ins_offset_ns: None,
            host_to_gps: None,
            data_seen: 0,
            model: None,
            detector: velodyne::Detector::new(),
            stats: AlignStats::default(),
            pps: None,
            lag_ns: None,
            windowed: [0; MAX_TARGETS],
            time_offset_ns: 0,
        }
    }

    /// Decode every data packet as `model` (the user's `--model`, or what a file's first
    /// packets showed), or (None, the default) as the model the packets' product byte names,
    /// checked against their period ([`velodyne::Detector`]; until it has seen enough packets
    /// the byte's model is used, and a disagreement stops the decoding: [`AlignStats`]).
    pub fn set_model(&mut self, model: Option<Model>) {
        self.model = model;
    }

    /// The model packets are decoded as, once known.
    pub fn model(&self) -> Option<Model> {
        self.model.or(match self.detector.identity() {
            Identity::Agreed(m) | Identity::Pending(Some(m)) => Some(m),
            _ => None,
        })
    }

    /// The spheres windowed.
    pub fn targets(&self) -> &[Target] {
        self.targets
    }

    /// The oldest and newest pose held.
    pub fn history_span(&self) -> Option<(GpsTime, GpsTime)> {
        self.history.span()
    }

    /// Returns windowed for sphere `i` so far, including those not yet handed on.
    pub fn windowed_now(&self, i: usize) -> u64 {
        self.windowed.get(i).copied().unwrap_or(0)
            + self.batches.get(i).map_or(0, |b| b.obs.len() as u64)
    }

    /// Add a pose received at `host` (if known). Returns false if it was refused (not newer
    /// than the newest).
    pub fn push_pose(&mut self, s: PoseSample, host: Option<HostTime>) -> bool {
        let ok = self.history.push(s);
        if ok {
            self.ins_offset_ns = host.map(|h| s.time.0.saturating_sub(h.0));
            if let Some(o) = self.ins_offset_ns {
                // The least-delayed pose bounds the host clock's offset; a host clock that
                // drifts is followed by letting the bound leak.
                let e = match self.host_to_gps {
                    Some((e, at)) => {
                        let dt = (s.time.0 - at.0).max(0);
                        o.max(
                            e - (i128::from(dt) * i128::from(HOST_DRIFT_NS_PER_S) / 1_000_000_000)
                                as i64,
                        )
                    }
                    None => o,
                };
                self.host_to_gps = Some((e, s.time));
            }
        }
        ok
    }

    /// A position packet: the PPS state, and the hour from its RMC when it is valid (a void
    /// one may carry a stale time; the INS gives the hour otherwise).
    pub fn position<T: AsRef<[u8]>>(&mut self, p: &PositionPacket<T>) {
        self.stats.position_packets += 1;
        self.pps = Some(p.pps());
        if !self.clock.has_hour() {
            if let Some(utc) = p.nmea_time().ok().filter(|t| t.valid).and_then(|t| t.utc()) {
                self.clock.set_from_rmc(&utc, p.timestamp_us());
                self.stats.hour_from = Some(HourFrom::Rmc);
            }
        }
    }

    /// The packet's first firing on the INS clock, as [`Self::data`] will time it (without
    /// changing the clock), given the history so far.
    fn first_firing<T: AsRef<[u8]>>(&self, p: &DataPacket<T>) -> Option<GpsTime> {
        let mut clock = self.clock;
        if !clock.has_hour() {
            let (_, newest) = self.history.span()?;
            clock.set_from_gps(newest, p.timestamp_us());
        }
        let t0 = clock.to_gps(p.timestamp_us())?;
        Some(GpsTime(t0.0.saturating_add(self.time_offset_ns)))
    }

    /// Whether more poses are needed before data packet `p` can be aligned: the history
    /// must hold a pose (for the hour) and reach past the packet's last firing plus the
    /// look-ahead. A caller that cannot wait (the INS ended, a live deadline) aligns it anyway;
    /// what the history does not cover is counted.
    pub fn wants_poses<T: AsRef<[u8]>>(&self, p: &DataPacket<T>) -> bool {
        let Some((_, newest)) = self.history.span() else {
            return true;
        };
        match self.first_firing(p) {
            Some(t0) => newest.0 <= t0.0.saturating_add(PACKET_SPAN_NS + self.lookahead_ns),
            None => false,
        }
    }

    /// A checked data packet received at `host` (if known): time it, georeference and window
    /// its returns; `each`, if given, sees every georeferenced return; a batch that is half
    /// full goes to `emit(sphere, observations)`.
    pub fn data<T: AsRef<[u8]>>(
        &mut self,
        p: &DataPacket<T>,
        host: Option<HostTime>,
        each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
        emit: &mut dyn FnMut(usize, &[Observation]),
    ) {
        let index = self.data_seen;
        self.data_seen = self.data_seen.wrapping_add(1);
        if !self.clock.has_hour() {
            let Some((_, newest)) = self.history.span() else {
                self.stats.packets_without_time += 1;
                return;
            };
            self.clock.set_from_gps(newest, p.timestamp_us());
            self.stats.hour_from = Some(HourFrom::Ins);
        }
        let Some(t0) = self.clock.to_gps(p.timestamp_us()) else {
            self.stats.packets_without_time += 1;
            return;
        };
        let s = t0.as_secs_f64();
        self.stats.lidar_span = Some(self.stats.lidar_span.map_or((s, s), |(a, _)| (a, s)));
        // On the INS clock (the poses' times).
        let t0 = GpsTime(t0.0.saturating_add(self.time_offset_ns));
        let model = match self.model {
            Some(m) => m,
            None => {
                let id = self
                    .detector
                    .push(p.timestamp_us(), p.return_mode_raw(), p.product_raw());
                self.stats.identity = Some(id);
                match id {
                    Identity::Agreed(m) | Identity::Pending(Some(m)) => m,
                    _ => {
                        self.stats.model_refused += 1;
                        return;
                    }
                }
            }
        };
        if velodyne::decode_as(p, model, &mut self.points).is_err() {
            return;
        }
        self.window(index, t0, None, host, each, emit);
    }

    /// GPS time minus host time as the poses' host stamps bound it [ns] (see [`Self::points`]).
    pub fn host_to_gps_ns(&self) -> Option<i64> {
        self.host_to_gps.map(|h| h.0)
    }

    /// Whether more poses are needed before returns timed `t0_host` + `span_ns` on the host's
    /// clock can be aligned (see [`Self::wants_poses`]).
    pub fn wants_poses_at_host(&self, t0_host: HostTime, span_ns: i64) -> bool {
        let Some((_, newest)) = self.history.span() else {
            return true;
        };
        match self.host_to_gps {
            Some((o, _)) => newest.0 <= t0_host.0.saturating_add(o + span_ns + self.lookahead_ns),
            None => true,
        }
    }

    /// Returns already decoded and timed on the host's clock (a ROS 2 `PointCloud2`): `points`
    /// fired their `offset_ns` after `t0_host`. The INS poses' host stamps map host time to GPS
    /// time (the upper envelope of GPS minus host time: the least-delayed pose); without them
    /// the returns are counted as without time.
    pub fn points(
        &mut self,
        t0_host: HostTime,
        points: &[Point],
        each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
        emit: &mut dyn FnMut(usize, &[Observation]),
    ) {
        let index = self.data_seen;
        self.data_seen = self.data_seen.wrapping_add(1);
        let Some((o, _)) = self.host_to_gps else {
            self.stats.packets_without_time += 1;
            return;
        };
        let t0 = GpsTime(t0_host.0.saturating_add(o));
        let s = t0.as_secs_f64();
        self.stats.lidar_span = Some(self.stats.lidar_span.map_or((s, s), |(a, _)| (a, s)));
        let t0 = GpsTime(t0.0.saturating_add(self.time_offset_ns));
        self.window(index, t0, Some(points), Some(t0_host), each, emit);
    }

    /// Georeference and window `points` (None: the packet just decoded) fired after `t0` (INS
    /// clock), received at `host`.
    fn window(
        &mut self,
        index: u32,
        t0: GpsTime,
        points: Option<&[Point]>,
        host: Option<HostTime>,
        each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
        emit: &mut dyn FnMut(usize, &[Observation]),
    ) {
        let points = points.unwrap_or(self.points.as_slice());
        self.stats.data_packets += 1;
        if let (Some(o), Some(h)) = (self.ins_offset_ns, host) {
            self.lag_ns = Some(t0.0.saturating_sub(h.0).saturating_sub(o));
        }
        let mut win = Windowing {
            targets: self.targets,
            margin: self.margin,
            mount: self.mount,
            batches: self.batches,
            stats: self.stats.window,
        };
        win.add_packet(index, t0, points, self.history, each);
        self.stats.window = win.stats;
        self.stats.rollovers = self.clock.rollovers;
        for (i, b) in self.batches.iter_mut().enumerate() {
            if b.obs.len() >= B / 2 {
                self.windowed[i] += b.obs.len() as u64;
                emit(i, &b.obs);
                b.obs.clear();
            }
        }
    }

    /// Window around the spheres with another mounting and margin from now on (the live rig,
    /// once calibrated: tighter windows, less clutter). Call [`Self::finish`] first, so a batch
    /// holds returns of one windowing.
    pub fn set_windows(&mut self, mount: Mount, margin: f64) {
        self.mount = mount;
        self.margin = margin;
    }

    /// The window margin in use [m].
    pub fn margin(&self) -> f64 {
        self.margin
    }

    /// Hand on what the batches still hold.
    pub fn finish(&mut self, emit: &mut dyn FnMut(usize, &[Observation])) {
        for (i, b) in self.batches.iter_mut().enumerate() {
            self.stats.batch_overflow += b.overflow;
            b.overflow = 0;
            if !b.obs.is_empty() {
                self.windowed[i] += b.obs.len() as u64;
                emit(i, &b.obs);
                b.obs.clear();
            }
        }
    }
}

#[cfg(test)]
mod tests {
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
}

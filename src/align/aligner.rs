//! The aligner: the LiDAR clock (the hour from a valid RMC, else from the INS), the pose
//! history, each data packet's returns georeferenced with the a-priori mounting at their
//! firing's pose (plus the clocks' time offset) and windowed around the spheres.
//!
//! No heap and no waiting: the caller lends the history and one batch per sphere, pushes poses
//! with [`Aligner::push_pose`] until [`Aligner::wants_poses`] is false for a packet (or the INS
//! has ended, or its own deadline passed), then hands the packet to [`Aligner::data`].

use super::history::{PoseHistory, PoseSample};
use crate::align::window::{
    Batch, GeoPoint, Observation, Reach, Target, WindowStats, Windowing, MAX_TARGETS,
};
use crate::georef::Mount;
use crate::time::{GpsTime, HostTime, LidarClock};
use crate::velodyne::{
    self, DataPacket, Identity, Model, Point, PointBuf, PositionPacket, PpsStatus,
};

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
    /// Data packets (of `data_packets`) whose firings all miss every window: their returns
    /// counted, not decoded ([`Reach`]).
    pub spared: u64,
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
    /// The azimuths that reach a window over the last INS segment a packet fell in.
    reach: Option<Reach>,
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
            reach: None,
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

    /// The index the next data packet's returns will carry ([`Observation::packet`]): the data
    /// packets seen so far, timed or not.
    pub fn next_packet(&self) -> u32 {
        self.data_seen
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
        // Without a point cloud to make, a packet whose azimuths miss every window is counted,
        // not decoded (calibration keeps a few percent of a scan).
        if each.is_none() && self.counted_beyond_reach(p, model, t0, host) {
            return;
        }
        if velodyne::decode_as(p, model, &mut self.points).is_err() {
            return;
        }
        self.window(index, t0, None, host, each, emit);
    }

    /// When no return of `p` (as `model`, first firing at `t0` on the INS clock) can reach a
    /// window ([`Reach`], made once per INS segment): the packet counted as [`Self::window`]
    /// would count it.
    fn counted_beyond_reach<T: AsRef<[u8]>>(
        &mut self,
        p: &DataPacket<T>,
        model: Model,
        t0: GpsTime,
        host: Option<HostTime>,
    ) -> bool {
        let Ok(e) = velodyne::extent(p, model) else {
            return false;
        };
        let end =
            GpsTime(t0.0.saturating_add(i64::from(model.block_ns()) * e.azimuth.len() as i64));
        if !self
            .reach
            .as_ref()
            .is_some_and(|r| r.holds(t0, end, self.history))
        {
            let (targets, mount) = (self.targets, &self.mount);
            self.reach = Reach::at(targets, self.margin, mount, t0, self.history);
        }
        let reach = self.reach.as_ref();
        if !reach.is_some_and(|r| r.holds(t0, end, self.history) && r.misses(&e.azimuth)) {
            return false;
        }
        self.seen(t0, host);
        self.stats.spared += 1;
        let n = e.returns as u64;
        self.stats.window.points += n;
        self.stats.window.georeferenced += n;
        true
    }

    /// A data packet aligned at `t0`: counted, and the clocks' lag and rollovers taken.
    fn seen(&mut self, t0: GpsTime, host: Option<HostTime>) {
        self.stats.data_packets += 1;
        self.stats.rollovers = self.clock.rollovers;
        if let (Some(o), Some(h)) = (self.ins_offset_ns, host) {
            self.lag_ns = Some(t0.0.saturating_sub(h.0).saturating_sub(o));
        }
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

    /// Whether more poses are needed before returns fired from `t0` (LiDAR clock) to `span_ns`
    /// later can be aligned (see [`Self::wants_poses`]).
    pub fn wants_poses_at(&self, t0: GpsTime, span_ns: i64) -> bool {
        let Some((_, newest)) = self.history.span() else {
            return true;
        };
        newest.0
            <= t0
                .0
                .saturating_add(self.time_offset_ns + span_ns + self.lookahead_ns)
    }

    /// Returns already decoded and timed by a LiDAR whose clock is on GPS time (a Hesai's or an
    /// Ouster's, synchronised): `points` fired their `offset_ns` after `t0` (LiDAR clock),
    /// received at `host`.
    pub fn timed(
        &mut self,
        t0: GpsTime,
        points: &[Point],
        host: Option<HostTime>,
        each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
        emit: &mut dyn FnMut(usize, &[Observation]),
    ) {
        let index = self.data_seen;
        self.data_seen = self.data_seen.wrapping_add(1);
        let s = t0.as_secs_f64();
        self.stats.lidar_span = Some(self.stats.lidar_span.map_or((s, s), |(a, _)| (a, s)));
        let t0 = GpsTime(t0.0.saturating_add(self.time_offset_ns));
        self.window(index, t0, Some(points), host, each, emit);
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
        self.seen(t0, host);
        let points = points.unwrap_or(self.points.as_slice());
        let mut win = Windowing {
            targets: self.targets,
            margin: self.margin,
            mount: self.mount,
            batches: self.batches,
            stats: self.stats.window,
        };
        win.add_packet(index, t0, points, self.history, each);
        self.stats.window = win.stats;
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
        self.reach = None;
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
mod tests;

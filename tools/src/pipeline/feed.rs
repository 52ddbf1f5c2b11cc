//! The core aligner fed from the rings: the file pipeline waits for the INS to cover each
//! packet until the INS ends; the rig waits until a deadline after the packet arrived, on a
//! [`Clock`] (a mock one in the tests).

use super::*;

/// How the aligner waits for the INS to cover a LiDAR packet's time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InsWait {
    /// Files: until the INS stream has poses past the packet or has ended.
    UntilEnd,
    /// Live: until this long after the packet's host receive time (wall clock). A late INS
    /// (a starved serial reader) is waited for; a silent one leaves the aligner this far
    /// behind real time, its ring holding the packets meanwhile, never stalled.
    Latency(std::time::Duration),
}

/// The align stage's storage on the host: the pose history and one batch per sphere (the core
/// [`CoreAligner`] borrows them).
pub struct AlignStorage {
    history: Box<PoseHistory<HISTORY>>,
    batches: Vec<Batch<BATCH>>,
}

impl AlignStorage {
    /// Room for `spheres` windows and a history that interpolates across at most `max_gap_ns`.
    pub fn new(spheres: usize, max_gap_ns: i64) -> Self {
        Self {
            history: Box::new(PoseHistory::new(max_gap_ns)),
            batches: (0..spheres).map(|_| Batch::default()).collect(),
        }
    }
}

/// The core aligner fed from the rings, with a waiting policy ([`InsWait`]) and the LiDAR
/// clock's state counted from the position packets.
pub struct RingAligner<'a> {
    /// The core stage.
    pub core: CoreAligner<'a, HISTORY, BATCH>,
    wait: InsWait,
    /// What the live deadline is measured and waited on.
    time: &'a dyn Clock,
    ins_done: bool,
    /// The LiDAR clock as its position packets tell it.
    pub clock: crate::state::ClockState,
    /// Each sphere's centre, and how close the INS came to it (for a window that catches
    /// nothing: [`Closest`]).
    centres: Vec<nalgebra::Vector3<f64>>,
    closest: Vec<Closest>,
    /// A Hesai's angle corrections (its packets are decoded here), and the points of the last.
    hesai: Option<(
        spherecal::hesai::Corrections,
        Box<spherecal::velodyne::PointBuf>,
    )>,
    /// The Hesai model the data packets said.
    hesai_model: Option<spherecal::hesai::Model>,
    leap_seconds: i64,
}

/// How close the trajectory (the INS's reference point) came to a sphere's centre, and when.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Closest {
    /// Distance [m] (infinite when no pose was seen).
    pub distance_m: f64,
    /// GPS time of the closest pose [s].
    pub time_s: f64,
}

impl<'a> RingAligner<'a> {
    /// An aligner for `targets` on `storage`, georeferencing with `mount`.
    pub fn new(
        storage: &'a mut AlignStorage,
        targets: &'a [Target],
        margin: f64,
        mount: Mount,
        leap_seconds: i64,
        wait: InsWait,
        time: &'a dyn Clock,
    ) -> Self {
        // From files, the poses are read on past a packet by the span its returns' velocity and
        // turn rate are taken over (live input does not wait: the span shrinks at the newest).
        let lookahead = match wait {
            InsWait::UntilEnd => spherecal::align::window::RATE_SPAN_NS,
            InsWait::Latency(_) => 0,
        };
        let core = CoreAligner::new(
            targets,
            &mut storage.batches,
            &mut storage.history,
            margin,
            mount,
            leap_seconds,
            lookahead,
        );
        Self {
            core,
            wait,
            time,
            ins_done: false,
            clock: Default::default(),
            centres: targets.iter().map(|t| t.center).collect(),
            closest: vec![
                Closest {
                    distance_m: f64::INFINITY,
                    time_s: 0.0,
                };
                targets.len()
            ],
            hesai: None,
            hesai_model: None,
            leap_seconds,
        }
    }

    /// Decode Hesai data packets with the unit's corrections `c`.
    pub fn with_hesai(mut self, c: spherecal::hesai::Corrections) -> Self {
        self.hesai = Some((c, Box::default()));
        self
    }

    /// Move every pose waiting on the ring into the history (live input between packets).
    pub fn drain_ins(&mut self, ic: &mut Consumer<'_, InsItem>) {
        while let Some(it) = ic.dequeue() {
            self.take(it);
        }
    }

    fn take(&mut self, it: InsItem) {
        match it {
            InsItem::Pose(s, h) => {
                for (c, best) in self.centres.iter().zip(&mut self.closest) {
                    let d = (s.position - c).norm();
                    if d < best.distance_m {
                        *best = Closest {
                            distance_m: d,
                            time_s: s.time.as_secs_f64(),
                        };
                    }
                }
                self.core.push_pose(s, h);
            }
            InsItem::End => self.ins_done = true,
        }
    }

    /// Discard the ring until its End (so that its reader can finish).
    pub fn drain_until_end(&mut self, ic: &mut Consumer<'_, InsItem>) {
        let mut backoff = super::Backoff::default();
        while !self.ins_done {
            match ic.dequeue() {
                Some(InsItem::End) => self.ins_done = true,
                Some(_) => backoff.reset(),
                None => backoff.wait(),
            }
        }
    }

    /// A position packet: counted, then to the core.
    pub fn position(&mut self, p: &PositionPacket<&[u8]>) {
        self.clock.count(p);
        self.core.position(p);
    }

    /// A Hesai GPS packet: its PPS lock and RMC counted.
    pub fn hesai_gps(&mut self, p: &spherecal::hesai::GpsPacket<&[u8]>) {
        self.clock.count_hesai(p);
    }

    /// A data packet received at `host`: poses are pulled until the history covers it, the
    /// INS ends, or (live) the latency allowed after its receive time has passed; then the core
    /// aligns it.
    pub fn data(
        &mut self,
        p: &DataPacket<&[u8]>,
        host: Option<HostTime>,
        ic: &mut Consumer<'_, InsItem>,
        each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
        emit: &mut dyn FnMut(usize, &[Observation]),
    ) {
        self.pull_poses(host, ic, |core| core.wants_poses(p));
        self.core.data(p, host, each, emit);
    }

    /// A Hesai data packet received at `host`, its date-time and microseconds taken as UTC
    /// (a clock synchronised by GPS or PTP): its returns decoded and timed, poses pulled as for
    /// [`Self::data`], then the core aligns them ([`CoreAligner::timed`]). Without corrections,
    /// or with a date-time that is no date, the packet is counted as without time.
    pub fn hesai(
        &mut self,
        p: &spherecal::hesai::DataPacket<&[u8]>,
        host: Option<HostTime>,
        ic: &mut Consumer<'_, InsItem>,
        each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
        emit: &mut dyn FnMut(usize, &[Observation]),
    ) {
        let (Some((c, points)), Some(unix)) = (&mut self.hesai, p.unix_ns()) else {
            self.core.stats.packets_without_time += 1;
            return;
        };
        self.hesai_model = Some(p.model());
        let first = spherecal::hesai::points(p, c, points);
        let t0 = spherecal::time::unix_ns_to_gps(unix + first, self.leap_seconds);
        let span = points
            .as_slice()
            .iter()
            .map(|q| i64::from(q.offset_ns))
            .max()
            .unwrap_or(0);
        self.pull_poses(host, ic, |core| core.wants_poses_at(t0, span));
        if let Some((_, points)) = &self.hesai {
            self.core.timed(t0, points.as_slice(), host, each, emit);
        }
    }

    /// Returns the reader decoded and timed (an Ouster's), fired after `t0` (GPS time): poses
    /// are pulled as for [`Self::data`], then the core aligns them ([`CoreAligner::timed`]);
    /// `columns` counted into the Ouster's clock.
    #[allow(clippy::too_many_arguments)]
    pub fn timed(
        &mut self,
        t0: spherecal::time::GpsTime,
        c: &spherecal_hal::rosbag::clouds::Chunk,
        columns: super::ColumnsTimed,
        host: Option<HostTime>,
        ic: &mut Consumer<'_, InsItem>,
        each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
        emit: &mut dyn FnMut(usize, &[Observation]),
    ) {
        let o = self.clock.ouster.get_or_insert_with(Default::default);
        o.synchronised += u64::from(columns.synchronised);
        o.free_running += u64::from(columns.free_running);
        let span = c.span_ns();
        self.pull_poses(host, ic, |core| core.wants_poses_at(t0, span));
        self.core.timed(t0, c.points(), host, each, emit);
    }

    /// Returns of a point cloud, timed on the host's clock: poses are pulled as for
    /// [`Self::data`], then the core aligns them ([`CoreAligner::points`]).
    pub fn points(
        &mut self,
        c: &spherecal_hal::rosbag::clouds::Chunk,
        ic: &mut Consumer<'_, InsItem>,
        each: Option<&mut (dyn FnMut(&GeoPoint) + '_)>,
        emit: &mut dyn FnMut(usize, &[Observation]),
    ) {
        let span = c.span_ns();
        self.pull_poses(Some(c.t0), ic, |core| core.wants_poses_at_host(c.t0, span));
        self.core.points(c.t0, c.points(), each, emit);
    }

    /// Pull poses while `wants` says so, the INS has not ended and (live) the deadline after
    /// `host` has not passed.
    fn pull_poses(
        &mut self,
        host: Option<HostTime>,
        ic: &mut Consumer<'_, InsItem>,
        wants: impl Fn(&CoreAligner<'a, HISTORY, BATCH>) -> bool,
    ) {
        let deadline = match self.wait {
            InsWait::UntilEnd => None,
            InsWait::Latency(d) => {
                let d = i64::try_from(d.as_nanos()).unwrap_or(i64::MAX);
                let from = host.unwrap_or_else(|| self.time.wall());
                Some(HostTime(from.0.saturating_add(d)))
            }
        };
        let mut backoff = super::Backoff::default();
        while !self.ins_done && wants(&self.core) {
            match ic.dequeue() {
                Some(it) => {
                    self.take(it);
                    backoff.reset();
                }
                None => match deadline {
                    None => backoff.wait(),
                    Some(t) if self.time.wall() >= t => break,
                    Some(_) => self.time.sleep(std::time::Duration::from_millis(1)),
                },
            }
        }
    }

    /// Hand on what the batches still hold.
    pub fn finish(&mut self, emit: &mut dyn FnMut(usize, &[Observation])) {
        self.core.finish(emit);
    }

    /// The LiDAR clock's state, with where its hour came from.
    pub fn clock_state(&self) -> crate::state::ClockState {
        let mut clock = self.clock.clone();
        clock.hour_from = match self.core.stats.hour_from {
            Some(spherecal::align::HourFrom::Rmc) => "RMC".into(),
            Some(spherecal::align::HourFrom::Ins) => "INS".into(),
            None => String::new(),
        };
        clock
    }

    /// The run's counts so far, with the readers' (skips, INS state, ring waits or drops).
    pub fn run_stats(&self, skips: SkipStats, ins: InsState, ring_full: [u64; 2]) -> RunStats {
        RunStats {
            align: self.core.stats,
            skips,
            clock: self.clock_state(),
            ins,
            ring_full,
            model: self.core.model(),
            hesai: self.hesai_model,
            ouster: None,
            closest: self.closest.clone(),
            pruned: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spherecal::velodyne::{BlockRepr, DataPacket, DataRepr, ReturnMode};
    use spherecal_hal::clock::MockClock;
    use std::time::Duration;

    /// A data packet with no return.
    fn empty_packet() -> [u8; 1206] {
        let mut buf = [0u8; 1206];
        DataRepr {
            blocks: [BlockRepr {
                azimuth: 0,
                channels: [(0, 0); 32],
            }; 12],
            timestamp_us: 0,
            return_mode: ReturnMode::Strongest,
            product: 0x22,
        }
        .emit(&mut DataPacket::new_unchecked(&mut buf[..]));
        buf
    }

    /// The rig's INS deadline on the mock clock (no sleeping): with no pose on the ring, a packet
    /// received at T is held until T + 300 ms, then aligned (here: counted without a time); a
    /// packet already older than that, or an ended INS stream, is not waited for.
    #[test]
    fn live_ins_deadline_on_the_mock_clock() {
        let t = 1_700_000_000_000_000_000i64;
        let targets = [Target {
            center: nalgebra::Vector3::zeros(),
            radius: 0.1,
        }];
        let packet = empty_packet();
        for (host_ns, end, waited_ms) in
            [(t, false, 300), (t - 500_000_000, false, 0), (t, true, 0)]
        {
            let clock = MockClock::new(HostTime(t));
            let mut storage = AlignStorage::new(1, 50_000_000);
            let mut al = RingAligner::new(
                &mut storage,
                &targets,
                0.5,
                Mount::from_params(&spherecal::georef::Params([0.0; 6])),
                18,
                InsWait::Latency(Duration::from_millis(300)),
                &clock,
            );
            let mut q: Queue<InsItem, 4> = Queue::new();
            let (mut p, mut c) = q.split();
            if end {
                assert!(p.enqueue(InsItem::End).is_ok());
            }
            let p = DataPacket::new_checked(&packet[..]).unwrap();
            al.data(&p, Some(HostTime(host_ns)), &mut c, None, &mut |_, _| {});
            let waited = clock.wall().0 - t;
            assert_eq!(waited, waited_ms * 1_000_000, "host {host_ns} end {end}");
            assert_eq!(al.core.stats.packets_without_time, 1);
        }
    }
}

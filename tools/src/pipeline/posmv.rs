//! The POS MV stream into poses, the same for a file (a logged `.000` stream, or the UDP
//! datagrams of a capture) and the live Real-Time Data Port: framing, Group 3's GPS week and
//! GPS - UTC offset, Group 7's time synchronization, Group 1's alignment status, and the pose
//! of Group 1 (or 102/103) gated by them, onto the INS ring.

use super::*;
use crate::state::PosmvState;
use spherecal::posmv::{
    self, Alignment, GnssStatus, Metrics, Navigation, PoseError, PpsTime, SensorNavigation,
    TimeSync,
};

/// The group a pose comes from.
enum Carried {
    Vessel(Navigation),
    Sensor(SensorNavigation),
}

/// The POS MV stream into poses (see the module's documentation).
pub struct PosmvFeed {
    framer: Box<posmv::Framer>,
    frame: LocalFrame,
    keep_unaligned: bool,
    max_gap_ns: i64,
    leap_seconds: i64,
    /// A week given from outside, used until a Group 3 gives one.
    fallback_week: Option<u16>,
    gnss_week: Option<u16>,
    alignment: Option<Alignment>,
    sync: Option<TimeSync>,
    st: InsState,
    pm: PosmvState,
}

impl PosmvFeed {
    /// Poses from group `pose_group` (1, 102 or 103) in the site `frame`; UTC times take
    /// `leap_seconds` until a Group 3 gives GPS - UTC; `week` dates the stream until a Group 3
    /// does; `keep_unaligned` uses poses whose alignment is not full navigation too.
    pub fn new(
        frame: LocalFrame,
        pose_group: u16,
        keep_unaligned: bool,
        max_gap_ns: i64,
        leap_seconds: i64,
        week: Option<u16>,
    ) -> Self {
        Self {
            framer: Box::default(),
            frame,
            keep_unaligned,
            max_gap_ns,
            leap_seconds,
            fallback_week: week,
            gnss_week: None,
            alignment: None,
            sync: None,
            st: InsState::default(),
            pm: PosmvState {
                pose_group,
                ..Default::default()
            },
        }
    }

    /// Bytes received at `host` (if known).
    pub fn feed(&mut self, bytes: &[u8], host: Option<HostTime>, out: &mut InsRing<'_, '_>) {
        self.st.bytes += bytes.len() as u64;
        let mut framer = std::mem::take(&mut self.framer);
        framer.consume(bytes, |it| self.handle(&it.item, host, out));
        self.framer = framer;
    }

    /// The stream has ended: what the framer still holds.
    pub fn finish(&mut self, out: &mut InsRing<'_, '_>) {
        let mut framer = std::mem::take(&mut self.framer);
        framer.finish();
        while let Some(it) = framer.next() {
            self.handle(&it.item, None, out);
        }
        self.framer = framer;
    }

    fn handle(
        &mut self,
        item: &posmv::Item<'_>,
        host: Option<HostTime>,
        out: &mut InsRing<'_, '_>,
    ) {
        let g = match item {
            posmv::Item::Group(g) => g,
            posmv::Item::Message(_) => {
                self.pm.messages += 1;
                return;
            }
            posmv::Item::Error(_) => {
                self.pm.rejected += 1;
                return;
            }
        };
        *self.pm.groups.entry(g.id()).or_default() += 1;
        let pose = match g.id() {
            GnssStatus::ID => {
                if let Ok(s) = GnssStatus::parse(g) {
                    if let Ok(w) = u16::try_from(s.week) {
                        if w > 0 && w < 9999 {
                            self.gnss_week = Some(w);
                        }
                    }
                    if s.utc_offset.is_finite() && (10.0..40.0).contains(&s.utc_offset) {
                        self.leap_seconds = s.utc_offset.round() as i64;
                        self.pm.utc_offset_s = Some(s.utc_offset);
                    }
                }
                return;
            }
            Metrics::ID => {
                if let Ok(m) = Metrics::parse(g) {
                    self.st.stated.add(
                        "POS MV Group 2",
                        m.position_rms.map(f64::from),
                        m.attitude_rms.map(f64::from),
                    );
                }
                return;
            }
            PpsTime::ID => {
                if let Ok(p) = PpsTime::parse(g) {
                    self.sync = Some(p.sync);
                    self.pm.time_sync = Some(p.sync.to_byte());
                }
                return;
            }
            Navigation::ID => {
                let Ok(n) = Navigation::parse(g) else {
                    self.st.without_pose += 1;
                    return;
                };
                self.alignment = Some(n.alignment);
                self.pm.alignment = Some(n.alignment.name().to_string());
                if self.pm.pose_group != Navigation::ID {
                    return;
                }
                Carried::Vessel(n)
            }
            id @ (102 | 103) if id == self.pm.pose_group => {
                let Ok(s) = SensorNavigation::parse(g) else {
                    self.st.without_pose += 1;
                    return;
                };
                Carried::Sensor(s)
            }
            _ => return,
        };
        let Some(week) = self.gnss_week.or(self.fallback_week) else {
            self.pm.no_week += 1;
            self.st.without_pose += 1;
            return;
        };
        self.pm.week = Some(week);
        let alignment = self.alignment.unwrap_or(Alignment::FullNavigation);
        let p = match pose {
            Carried::Vessel(n) => posmv::Pose::from_navigation(&n, week, self.leap_seconds),
            Carried::Sensor(s) => posmv::Pose::from_sensor(&s, week, self.leap_seconds, alignment),
        };
        let p = match p {
            Ok(p) => p,
            Err(PoseError::NoGnssTime) => {
                self.pm.pos_time += 1;
                self.st.without_pose += 1;
                return;
            }
            Err(PoseError::Invalid) => {
                self.st.without_pose += 1;
                return;
            }
        };
        if self.sync.is_some_and(|s| !s.is_trusted()) {
            self.pm.unsynchronized += 1;
            self.st.exclude(p.time, 1);
            return;
        }
        self.st.sample(p.time, false, None);
        if !p.alignment.is_navigating() {
            let k = if p.alignment == Alignment::NoSolution {
                0
            } else {
                1
            };
            if !self.keep_unaligned {
                self.st.exclude(p.time, k);
                return;
            }
            self.st.kept_untracked += 1;
        }
        let g = Geodetic {
            lat: p.lat,
            lon: p.lon,
            h: p.h,
        };
        let local = spherecal::frames::rotation(p.rph[0], p.rph[1], p.rph[2]);
        let sample = PoseSample::from_geodetic(&self.frame, p.time, &g, &local);
        self.st.used(p.time, self.max_gap_ns);
        enqueue(out.ring, InsItem::Pose(sample, host), out.policy, out.full);
    }

    /// Poses used so far.
    pub fn poses_used(&self) -> u64 {
        self.st.poses
    }

    /// The last alignment status a Group 1 gave.
    pub fn alignment(&self) -> Option<Alignment> {
        self.alignment
    }

    /// The stream's state so far.
    pub fn state(&self) -> InsState {
        let fs = self.framer.stats();
        InsState {
            frames: fs.groups,
            crc_failures: fs.checksum_failures + fs.bad_ends,
            skipped_bytes: fs.skipped_bytes,
            posmv: Some(self.pm.clone()),
            ..self.st.clone()
        }
    }
}

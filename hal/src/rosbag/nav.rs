//! A bag's `sensor_msgs` navigation topics as the VN-200 frames they were published from
//! ([`NavBytes`], a [`ByteSource`]): the VectorNav driver's `Imu`, `NavSatFix` and
//! `TimeReference` (GPS time) of one header stamp make one frame (Common TimeGps, Quaternion,
//! Position, InsStatus), so they go through the same framing, pose and gating as a serial
//! stream. They carry no INS mode: a frame is "tracking" when the GNSS has a fix. Without a
//! time reference there is no GPS time, and nothing is made.

use super::{BagError, Messages};
use crate::packet::HostTime;
use crate::serial::{ByteSource, ReadOutcome, RxStamp};
use spherecal::ros2::nav::{Imu, NavFrame, NavSatFix, TimeReference};
use spherecal::ros2::{Header, Time, VN200_FRAME_MAX};
use std::collections::VecDeque;

/// What a [`NavBytes`] met.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct NavBagStats {
    /// Imu, NavSatFix and TimeReference messages.
    pub messages: [u64; 3],
    /// Frames made.
    pub frames: u64,
    /// ... of which timed by a reference of another stamp (the same stamp's was not recorded).
    pub other_reference: u64,
    /// Imu + NavSatFix pairs left out: no time reference within [`REFERENCE_AGE_NS`].
    pub no_time: u64,
    /// Stamps with an Imu or a NavSatFix but not both.
    pub incomplete: u64,
    /// Time references that are neither GPS nor UTC time near the host's clock.
    pub bad_reference: u64,
    /// Messages that did not parse: count, and the first (topic, where, why).
    pub bad: u64,
    /// The first bad message.
    pub first_bad: Option<String>,
    /// Imu messages in the ROS frames (RFU/ENU) and in the sensor's (FRD/NED).
    pub frames_enu_ned: [u64; 2],
}

/// How long an Imu or NavSatFix waits for the rest of its stamp [ns].
pub const PAIR_WAIT_NS: i64 = 500_000_000;
/// How old a time reference of another stamp may be to time a frame [ns].
pub const REFERENCE_AGE_NS: i64 = 10_000_000_000;

/// A message, read.
enum Got {
    Imu(i64, [f64; 4], Option<bool>),
    Fix(i64, i8, [f64; 3]),
    Ref(i64, Option<i64>),
    Bad(String),
    Other,
}

#[derive(Debug, Clone, Copy, Default)]
struct Partial {
    stamp: i64,
    q: Option<([f64; 4], Option<bool>)>,
    fix: Option<(i8, [f64; 3])>,
    gps_minus_host: Option<i64>,
}

/// The VN-200 frames of a bag's Imu + NavSatFix + TimeReference topics.
pub struct NavBytes {
    msgs: Messages,
    topics: [String; 3],
    leap_seconds: i64,
    pending: VecDeque<Partial>,
    ready: VecDeque<(i64, [u8; VN200_FRAME_MAX], usize)>,
    /// The latest reference: its stamp and GPS minus host time.
    latest: Option<(i64, i64)>,
    /// The file the latest message came from (for errors).
    file: std::path::PathBuf,
    /// The last frame decision (RFU/ENU unless the specific force says FRD/NED).
    enu: bool,
    /// What was met.
    pub stats: NavBagStats,
}

impl NavBytes {
    /// Over `msgs`, holding the topics `imu`, `fix` and `time_ref`; `leap_seconds` turns a UTC
    /// reference into GPS time.
    pub fn new(msgs: Messages, imu: &str, fix: &str, time_ref: &str, leap_seconds: i64) -> Self {
        Self {
            msgs,
            topics: [imu.into(), fix.into(), time_ref.into()],
            leap_seconds,
            pending: VecDeque::new(),
            ready: VecDeque::new(),
            latest: None,
            file: std::path::PathBuf::new(),
            enu: true,
            stats: NavBagStats::default(),
        }
    }

    fn slot(&mut self, stamp: i64) -> &mut Partial {
        let i = match self.pending.iter().position(|p| p.stamp == stamp) {
            Some(i) => i,
            None => {
                self.pending.push_back(Partial {
                    stamp,
                    ..Default::default()
                });
                self.pending.len() - 1
            }
        };
        &mut self.pending[i]
    }

    /// Make the frames of the stamps that are complete, or waited for long enough (`now`: the
    /// newest stamp seen; `end`: no more messages).
    fn settle(&mut self, now: i64, end: bool) {
        let mut k = 0;
        while k < self.pending.len() {
            let p = self.pending[k];
            let (Some((q, enu)), Some((status, lla))) = (p.q, p.fix) else {
                if end || now - p.stamp > PAIR_WAIT_NS {
                    self.stats.incomplete += 1;
                    self.pending.remove(k);
                } else {
                    k += 1;
                }
                continue;
            };
            let offset = match (p.gps_minus_host, self.latest) {
                (Some(o), _) => Some(o),
                _ if !end && now - p.stamp <= PAIR_WAIT_NS => {
                    k += 1;
                    continue;
                }
                (None, Some((at, o))) if (p.stamp - at).abs() <= REFERENCE_AGE_NS => {
                    self.stats.other_reference += 1;
                    Some(o)
                }
                _ => None,
            };
            self.pending.remove(k);
            let Some(offset) = offset else {
                self.stats.no_time += 1;
                continue;
            };
            if let Some(e) = enu {
                self.enu = e;
            }
            self.stats.frames_enu_ned[usize::from(!self.enu)] += 1;
            let frame = NavFrame {
                gps_ns: p.stamp + offset,
                quaternion: Imu::quaternion_from(q, self.enu),
                lla,
                fix: status >= 0,
            };
            let header = Header {
                stamp: Time {
                    sec: p.stamp.div_euclid(1_000_000_000) as i32,
                    nanosec: p.stamp.rem_euclid(1_000_000_000) as u32,
                },
                frame_id: "",
            };
            let mut out = [0u8; VN200_FRAME_MAX];
            if let Some(n) = frame
                .common(header)
                .and_then(|c| c.vn200_frame(None, None, &mut out))
            {
                self.stats.frames += 1;
                self.ready.push_back((p.stamp, out, n));
            }
        }
    }
}

impl ByteSource for NavBytes {
    type Error = BagError;

    fn read_chunk(&mut self, buf: &mut [u8]) -> Result<ReadOutcome, BagError> {
        loop {
            if let Some((t, frame, n)) = self.ready.pop_front() {
                if n > buf.len() {
                    return Err(BagError::new(
                        &self.file,
                        format!(
                            "a {n}-byte VN-200 frame does not fit the reader's {}-byte buffer",
                            buf.len()
                        ),
                    ));
                }
                buf[..n].copy_from_slice(&frame[..n]);
                return Ok(ReadOutcome::Data {
                    len: n,
                    stamp: Some(RxStamp {
                        mono_ns: t.max(0) as u64,
                        wall: HostTime(t),
                    }),
                });
            }
            let got = {
                let Some(m) = self.msgs.next()? else {
                    self.settle(i64::MAX, true);
                    if self.ready.is_empty() {
                        return Ok(ReadOutcome::End);
                    }
                    continue;
                };
                // No copy per message: `m` borrows only `self.msgs` (the file's name only
                // when it changes).
                if m.file != self.file.as_path() {
                    self.file = m.file.to_path_buf();
                }
                let bad = |e: &dyn std::fmt::Display| {
                    Got::Bad(format!(
                        "{} in {} at {}: {e}",
                        m.topic.name,
                        m.file.display(),
                        m.at
                    ))
                };
                match self.topics.iter().position(|t| *t == m.topic.name) {
                    Some(0) => match Imu::parse(m.data) {
                        Ok(i) => Got::Imu(i.header.stamp.ns(), i.orientation, i.enu()),
                        Err(e) => bad(&e),
                    },
                    Some(1) => match NavSatFix::parse(m.data) {
                        Ok(f) => Got::Fix(f.header.stamp.ns(), f.status, f.lla),
                        Err(e) => bad(&e),
                    },
                    Some(2) => match TimeReference::parse(m.data) {
                        Ok(r) => {
                            Got::Ref(r.header.stamp.ns(), r.gps_minus_host_ns(self.leap_seconds))
                        }
                        Err(e) => bad(&e),
                    },
                    _ => Got::Other,
                }
            };
            let stamp = match got {
                Got::Imu(s, q, enu) => {
                    self.stats.messages[0] += 1;
                    self.slot(s).q = Some((q, enu));
                    s
                }
                Got::Fix(s, status, lla) => {
                    self.stats.messages[1] += 1;
                    self.slot(s).fix = Some((status, lla));
                    s
                }
                Got::Ref(s, o) => {
                    self.stats.messages[2] += 1;
                    match o {
                        Some(o) => {
                            self.latest = Some((s, o));
                            self.slot(s).gps_minus_host = Some(o);
                        }
                        None => self.stats.bad_reference += 1,
                    }
                    s
                }
                Got::Bad(why) => {
                    self.stats.bad += 1;
                    self.stats.first_bad.get_or_insert(why);
                    continue;
                }
                Got::Other => continue,
            };
            self.settle(stamp, false);
        }
    }
}

impl NavBytes {
    /// The MCAP files found cut short so far ([`super::Messages::cut`]).
    pub fn cut(&self) -> &[(std::path::PathBuf, u64)] {
        self.msgs.cut()
    }
}

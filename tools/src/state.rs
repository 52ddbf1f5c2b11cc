//! What the inputs held: the LiDAR clock as its position packets tell it (PPS, `$GPRMC`), the
//! INS stream's state (frames, CRC failures, poses kept and excluded by their InsStatus, gaps),
//! and the time spans of both. Every command prints it and every report records it: a
//! calibration is only as good as its inputs, and a surveyor must see them.

use serde::{Deserialize, Serialize};
use spherecal::time::GpsTime;
use spherecal::velodyne::{PositionPacket, PpsStatus};
use std::fmt::Write as _;

/// Seconds of a GPS time (for reports).
fn secs(t: GpsTime) -> f64 {
    t.as_secs_f64()
}

/// How an Ouster's column times were read.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct OusterClock {
    /// The metadata's `timestamp_mode` (empty: none).
    pub mode: String,
    /// Columns whose time was a synchronised clock's.
    pub synchronised: u64,
    /// Columns of a clock counting from power-on, placed by the capture's receive times.
    pub free_running: u64,
}

impl OusterClock {
    /// Every column's time was a synchronised clock's.
    pub fn trusted(&self) -> bool {
        self.synchronised > 0 && self.free_running == 0
    }
}

/// The LiDAR clock as its position packets tell it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ClockState {
    /// Position packets by PPS state: absent, synchronizing, locked, error, other.
    pub pps: [u64; 5],
    /// Position packets whose `$GPRMC` says A (valid).
    pub rmc_valid: u64,
    /// ... V (void: no fix; its time may be stale).
    pub rmc_void: u64,
    /// ... none, or unreadable.
    pub rmc_none: u64,
    /// The packet's stamp minus its valid RMC's time [s], wrapped into the hour (the RMC names
    /// the last whole second, so 0..1 s on a locked clock): the smallest and largest.
    pub stamp_minus_rmc_s: Option<(f64, f64)>,
    /// Where the LiDAR's hour came from: `RMC` (a valid one) or `INS` (the nearest hour to the
    /// INS time); empty if never.
    pub hour_from: String,
    /// The packets came from a ROS 2 bag: its driver records no position packet, so the PPS
    /// state is unknown rather than absent.
    #[serde(default)]
    pub bag: bool,
    /// The bag's LiDAR topic holds point clouds: returns timed on the host's clock.
    #[serde(default)]
    pub clouds: bool,
    /// The LiDAR is a Hesai (`--metadata`): its packets' date-time and microseconds taken as
    /// UTC; its GPS packets counted as position packets.
    #[serde(default)]
    pub hesai: bool,
    /// The LiDAR is an Ouster (`--metadata META.json`): how its column times were read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ouster: Option<OusterClock>,
    /// A bag's data packets: their stamp (time past the hour) minus the recorder's stamp of
    /// them, wrapped into the hour [s], the smallest and largest. A PPS-synchronised LiDAR and
    /// an NTP-synchronised recorder keep it at minus a few ms, constant; a free-running LiDAR
    /// clock is anywhere in the hour and drifts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stamp_minus_host_s: Option<(f64, f64)>,
}

/// The range of a LiDAR packet's stamp minus its host time, wrapped into the hour
/// ([`ClockState::stamp_minus_host_s`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Spread(Option<(f64, f64)>);

impl Spread {
    /// A packet stamped `toh_us` past the hour, received at `host`.
    pub fn add(&mut self, toh_us: u32, host: spherecal::time::HostTime) {
        let host_s = host.0.rem_euclid(3_600_000_000_000) as f64 * 1e-9;
        let d = (f64::from(toh_us) * 1e-6 - host_s + 1800.0).rem_euclid(3600.0) - 1800.0;
        self.0 = Some(self.0.map_or((d, d), |(a, b)| (a.min(d), b.max(d))));
    }

    /// Smallest and largest.
    pub fn range(&self) -> Option<(f64, f64)> {
        self.0
    }
}

/// PPS state names, in [`ClockState::pps`] order.
pub const PPS_NAMES: [&str; 5] = ["absent", "synchronizing", "locked", "error", "other"];

impl ClockState {
    /// Count a position packet.
    pub fn count(&mut self, p: &PositionPacket<&[u8]>) {
        let k = match p.pps() {
            PpsStatus::Absent => 0,
            PpsStatus::Synchronizing => 1,
            PpsStatus::Locked => 2,
            PpsStatus::Error => 3,
            PpsStatus::Unknown(_) => 4,
        };
        self.pps[k] += 1;
        let stamp = f64::from(p.timestamp_us()) * 1e-6;
        self.count_rmc(p.nmea_time().ok(), Some(stamp));
    }

    /// Count a Hesai's GPS packet (its PPS lock: locked or absent; its NMEA sentence). Its
    /// date-time is the unit's PPS second, named by the same RMC: the difference is counted
    /// at the middle of that second, as a position packet's stamp would be, so that a clock
    /// that agrees shows an offset of 0 ([`Self::rmc_offset_s`]).
    pub fn count_hesai(&mut self, p: &spherecal::hesai::GpsPacket<&[u8]>) {
        self.pps[if p.pps_locked() { 2 } else { 0 }] += 1;
        let stamp = p
            .utc()
            .map(|u| f64::from(u32::from(u.minute) * 60 + u32::from(u.second)) + 0.5);
        self.count_rmc(p.nmea_time(), stamp);
    }

    /// Count a time packet's NMEA time against its stamp `stamp` [s past the hour].
    fn count_rmc(&mut self, t: Option<spherecal::velodyne::NmeaTime>, stamp: Option<f64>) {
        match t {
            Some(t) if t.is_rmc && t.valid => {
                self.rmc_valid += 1;
                let rmc = f64::from(u32::from(t.minute) * 60 + u32::from(t.second))
                    + f64::from(t.nanos) * 1e-9;
                let Some(stamp) = stamp else { return };
                let d = (stamp - rmc + 1800.0).rem_euclid(3600.0) - 1800.0;
                self.stamp_minus_rmc_s = Some(match self.stamp_minus_rmc_s {
                    Some((a, b)) => (a.min(d), b.max(d)),
                    None => (d, d),
                });
            }
            Some(t) if t.is_rmc => self.rmc_void += 1,
            _ => self.rmc_none += 1,
        }
    }

    /// Position packets seen.
    pub fn packets(&self) -> u64 {
        self.pps.iter().sum()
    }

    /// The clock can be trusted: position packets seen, every one PPS-locked with a valid RMC
    /// that agrees with its stamp (within 1.5 s: the RMC names a whole second).
    pub fn trusted(&self) -> bool {
        if let Some(o) = &self.ouster {
            return o.trusted();
        }
        let n = self.packets();
        n > 0
            && self.pps[2] == n
            && self.rmc_valid == n
            && self
                .stamp_minus_rmc_s
                .is_some_and(|(a, b)| a > -1.5 && b < 1.5)
    }

    /// The LiDAR clock's error against the valid RMCs [s]: the middle of what the stamps
    /// minus the RMC times span, less the half second the RMC's whole second hides.
    pub fn rmc_offset_s(&self) -> Option<f64> {
        self.stamp_minus_rmc_s.map(|(a, b)| (a + b) / 2.0 - 0.5)
    }

    /// One line for people.
    pub fn describe(&self) -> String {
        let n = self.packets();
        if let Some(o) = &self.ouster {
            let mode = if o.mode.is_empty() {
                "no timestamp_mode"
            } else {
                o.mode.as_str()
            };
            return match o.trusted() {
                true => format!("Ouster, {mode}: {} columns timed by the synchronised clock (PTP: GPS = TAI - 19 s; sync pulse: UTC + the leap seconds)", o.synchronised),
                false => format!("Ouster, {mode}: {} of {} columns timed by a clock counting from power-on (free-running: unlocked), placed by the capture's receive time of its first packet", o.free_running, o.free_running + o.synchronised),
            };
        }
        if self.hesai && n == 0 {
            return "Hesai, no GPS packet (UDP 10110): the data packets' date-time is the unit's own (PTP, or free-running from power-on) and cannot be checked".into();
        }
        if self.hesai {
            return format!(
                "Hesai, {n} GPS packets: {} with the PPS locked, {} with a valid $GPRMC{}; each return timed by its packet's date-time and microseconds as UTC",
                self.pps[2],
                self.rmc_valid,
                match self.trusted() {
                    true => " (synchronised to GPS time)",
                    false => "",
                }
            );
        }
        if self.clouds {
            return "host clock (ROS 2 point clouds: each return at its cloud's stamp plus its time; no LiDAR clock or PPS is recorded), mapped to GPS time by the INS messages' stamps (the least-delayed); the rest is the estimated time offset".into();
        }
        if n == 0 && self.bag {
            let mut o = String::from(
                "PPS unknown (ROS 2 bag: the driver records no position packet, so the LiDAR clock cannot be checked)",
            );
            if let Some((a, b)) = self.stamp_minus_host_s {
                let _ = write!(
                    o,
                    "; packet stamps minus the recorder's {:+.4} .. {:+.4} s ({})",
                    a,
                    b,
                    if a > -1.0 && b < 1.0 && b - a < 0.1 {
                        "within a second and steady: consistent with a PPS-synchronised LiDAR and a synchronised recorder"
                    } else {
                        "not within a second of each other, or not steady: the LiDAR clock or the recorder's is not synchronised"
                    }
                );
            }
            if !self.hour_from.is_empty() {
                let _ = write!(o, "; hour from {}", self.hour_from);
            }
            return o;
        }
        if n == 0 {
            return "no position packets (no PPS, no RMC: the LiDAR clock cannot be checked)"
                .into();
        }
        let mut o = format!("{n} position packets: PPS");
        for (k, c) in self.pps.iter().enumerate().filter(|(_, &c)| c > 0) {
            let _ = write!(o, " {} {c}", PPS_NAMES[k]);
        }
        let rmc: Vec<String> = [
            ("valid", self.rmc_valid),
            ("void", self.rmc_void),
            ("none", self.rmc_none),
        ]
        .iter()
        .filter(|(_, c)| *c > 0)
        .map(|(k, c)| format!("{k} {c}"))
        .collect();
        let _ = write!(o, "; RMC {}", rmc.join(", "));
        if let Some((a, b)) = self.stamp_minus_rmc_s {
            let _ = write!(o, "; stamp - RMC {a:+.3} .. {b:+.3} s");
        }
        if !self.hour_from.is_empty() {
            let _ = write!(o, "; hour from {}", self.hour_from);
        }
        o
    }
}

/// Why a pose was left out.
pub const EXCLUDED_NAMES: [&str; 4] = ["not tracking", "aligning", "GNSS lost", "no GNSS fix"];

/// The INS stream's state.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct InsState {
    /// Bytes read.
    pub bytes: u64,
    /// SBET records read (0 for a VN-200 stream).
    #[serde(default)]
    pub sbet_records: u64,
    /// Binary frames accepted (VN-200).
    pub frames: u64,
    /// Binary candidates whose CRC failed.
    pub crc_failures: u64,
    /// Bytes that were part of no accepted item.
    pub skipped_bytes: u64,
    /// `$VN` sentences.
    pub ascii: u64,
    /// Other NMEA sentences.
    pub nmea: u64,
    /// Frames or records without a complete, valid pose (or time).
    pub without_pose: u64,
    /// Poses used.
    pub poses: u64,
    /// Poses left out by their InsStatus: not tracking, aligning, GNSS lost, no GNSS fix.
    pub excluded: [u64; 4],
    /// When they were left out: GPS seconds, first and last of each run (at most 32 runs; the
    /// rest are counted in `excluded`).
    pub excluded_spans: Vec<(f64, f64)>,
    /// GPS seconds of the first and last pose used.
    pub span: Option<(f64, f64)>,
    /// Gaps between consecutive poses used longer than the interpolation limit.
    pub gaps: u64,
    /// The longest gap between consecutive poses used [s].
    pub longest_gap_s: f64,
    /// Poses kept although their status says not tracking (the user asked).
    pub kept_untracked: u64,
    /// Samples whose time was not after the sample before (the INS clock went back).
    #[serde(default)]
    pub backward: u64,
    /// Steps of the INS clock: a sample right after another (nothing lost between them) whose
    /// time is not one output period later, or time going back: GPS seconds of the later
    /// sample and the step [s] (at most 16 listed; [`Self::clock_step_count`] counts all).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub clock_steps: Vec<(f64, f64)>,
    /// Clock steps in all.
    #[serde(default)]
    pub clock_step_count: u64,
    /// Samples missing between those read (forward jumps of whole output periods, or where the
    /// reader saw data lost): lost data, not clock steps.
    #[serde(default)]
    pub lost_samples: u64,
    /// What the clock check remembers between samples.
    #[serde(skip)]
    pub watch: ClockWatch,
    /// What the INS stated of its own errors (VN-200 PosU/YprU, POS MV Group 2): a navigation
    /// model's source when the site declares none (`nav_source`).
    #[serde(skip)]
    pub stated: crate::config::nav_source::Stated,
    /// What a POS MV stream gave (None: not a POS MV stream).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub posmv: Option<PosmvState>,
    /// What a ROS 2 bag's VectorNav groups gave, in words (None: not a bag).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bag: Option<String>,
}

/// The INS clock between samples: the last sample's time, the output period learnt from the
/// first contiguous intervals (their median).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ClockWatch {
    last: Option<i64>,
    own: Option<i64>,
    end: Option<u64>,
    period: Option<i64>,
    learn: Vec<i64>,
}

/// Intervals the output period is learnt from.
const LEARN: usize = 15;

/// The reason a VN-200 InsStatus leaves a pose out (PROTOCOLS.md: bits 0-1 mode, 0 not
/// tracking, 1 aligning, 2 tracking, 3 loss of GNSS; bit 2 GNSS fix), as an index into
/// [`EXCLUDED_NAMES`].
pub fn excluded_by(status: u16) -> Option<usize> {
    match status & 3 {
        0 => Some(0),
        1 => Some(1),
        3 => Some(2),
        _ if status & 4 == 0 => Some(3),
        _ => None,
    }
}

impl InsState {
    /// Every sample with a time, used or not, in stream order. `contiguous`: it came right after
    /// the sample before with nothing lost between (consecutive binary frames, consecutive
    /// records); `own`: the INS's free-running clock at the sample when the stream carries it
    /// (VN-200 TimeStartup) [ns].
    ///
    /// Time going back is always a step. A forward jump is lost data, not a step, when the
    /// reader saw data lost (not contiguous), when the free-running clock advanced by as much
    /// (within a quarter period, 2 ms at least), or, without that clock, when it is a whole
    /// number of output periods (within a tenth of one, 0.1 ms at least): a VN-200 whose output
    /// outruns its line, a recorder dropping messages and a silent port all lose whole samples.
    /// What is left is a step: a time jump with the data continuous around it. A second message
    /// of the same sample (the same time) is neither.
    pub fn sample(&mut self, t: GpsTime, contiguous: bool, own: Option<i64>) {
        let w = &mut self.watch;
        if w.last == Some(t.0) {
            // The same sample again (a second message of it).
            return;
        }
        let last_own = core::mem::replace(&mut w.own, own);
        let Some(last) = w.last.replace(t.0) else {
            return;
        };
        let d = t.0 - last;
        // What the free-running clock counted meanwhile (None: not carried, or it restarted).
        let d_own = match (last_own, own) {
            (Some(a), Some(b)) if b > a => Some(b - a),
            _ => None,
        };
        let step = if d < 0 {
            self.backward += 1;
            Some(d - d_own.or(w.period).unwrap_or(0))
        } else if let Some(p) = w.period {
            let tol = (p / 4).max(2_000_000);
            let whole = (d + p / 2) / p.max(1);
            let step = match d_own {
                _ if !contiguous => None,
                Some(o) => ((d - o).abs() > tol).then_some(d - o),
                None if (d - p).abs() <= tol => None,
                None if whole >= 2 && (d - whole * p).abs() <= (p / 10).max(100_000) => None,
                None => Some(d - p),
            };
            if step.is_none() && whole >= 2 {
                self.lost_samples += (whole - 1) as u64;
            }
            step
        } else {
            if contiguous {
                w.learn.push(d);
                if w.learn.len() == LEARN {
                    let mut v = w.learn.clone();
                    v.sort_unstable();
                    w.period = Some(v[LEARN / 2]);
                }
            }
            None
        };
        if let Some(d) = step {
            self.clock_step_count += 1;
            if self.clock_steps.len() < 16 {
                self.clock_steps.push((secs(t), d as f64 * 1e-9));
            }
        }
    }

    /// A sample from the frame at byte `offset` of `len` bytes: contiguous when the sample
    /// before ended where it starts; `own` as for [`Self::sample`].
    pub fn sample_frame(&mut self, t: GpsTime, offset: u64, len: usize, own: Option<i64>) {
        let contiguous = self.watch.end == Some(offset);
        self.watch.end = Some(offset + len as u64);
        self.sample(t, contiguous, own);
    }

    /// A pose used at `t`; `max_gap_ns`: the interpolation limit.
    pub fn used(&mut self, t: GpsTime, max_gap_ns: i64) {
        self.poses += 1;
        let s = secs(t);
        if let Some((_, last)) = self.span {
            let gap = s - last;
            if gap > max_gap_ns as f64 * 1e-9 {
                self.gaps += 1;
            }
            self.longest_gap_s = self.longest_gap_s.max(gap);
        }
        self.span = Some(self.span.map_or((s, s), |(a, _)| (a, s)));
    }

    /// A pose left out at `t` for reason `k` ([`EXCLUDED_NAMES`]).
    pub fn exclude(&mut self, t: GpsTime, k: usize) {
        self.excluded[k.min(3)] += 1;
        let s = secs(t);
        let n = self.excluded_spans.len();
        match self.excluded_spans.last_mut() {
            Some(l) if s - l.1 <= 1.0 => l.1 = s,
            _ if n < 32 => self.excluded_spans.push((s, s)),
            _ => {}
        }
    }

    /// Poses left out in all.
    pub fn excluded_total(&self) -> u64 {
        self.excluded.iter().sum()
    }

    /// Lines for people.
    pub fn describe(&self) -> String {
        let mut o = if let Some(p) = &self.posmv {
            format!(
                "{}: {} bytes, {} bytes skipped; {} poses used",
                p.describe(),
                self.bytes,
                self.skipped_bytes,
                self.poses
            )
        } else if let Some(b) = &self.bag {
            format!("{b}; {} poses used", self.poses)
        } else if self.sbet_records > 0 {
            format!(
                "SBET: {} bytes, {} records; {} poses used",
                self.bytes, self.sbet_records, self.poses
            )
        } else {
            format!(
                "INS: {} bytes, {} binary frames, {} CRC failures, {} bytes skipped, {} $VN, {} NMEA; {} poses used",
                self.bytes, self.frames, self.crc_failures, self.skipped_bytes, self.ascii, self.nmea, self.poses
            )
        };
        if let Some((a, b)) = self.span {
            let _ = write!(o, " ({:.1} s)", b - a);
        }
        if self.without_pose > 0 {
            let _ = write!(o, ", {} without a valid pose", self.without_pose);
        }
        if self.excluded_total() > 0 {
            let _ = write!(o, "; left out by InsStatus:");
            for (k, &c) in self.excluded.iter().enumerate().filter(|(_, &c)| c > 0) {
                let _ = write!(o, " {} {c}", EXCLUDED_NAMES[k]);
            }
            if let (Some(f), Some(l)) = (self.excluded_spans.first(), self.excluded_spans.last()) {
                let _ = write!(
                    o,
                    " ({} spans, {:.1}..{:.1} s into the stream)",
                    self.excluded_spans.len(),
                    f.0 - self.span.map_or(f.0, |s| s.0.min(f.0)),
                    l.1 - self.span.map_or(f.0, |s| s.0.min(f.0))
                );
            }
        }
        if self.kept_untracked > 0 {
            let _ = write!(
                o,
                "; {} poses kept although not tracking (asked)",
                self.kept_untracked
            );
        }
        if self.gaps > 0 {
            let _ = write!(
                o,
                "; {} gaps, the longest {:.3} s",
                self.gaps, self.longest_gap_s
            );
        }
        if self.lost_samples > 0 {
            let _ = write!(
                o,
                "; {} samples missing (lost data, not clock steps)",
                self.lost_samples
            );
        }
        if self.clock_step_count > 0 {
            let first = self.span.map_or(0.0, |s| s.0);
            let listed: Vec<String> = self
                .clock_steps
                .iter()
                .take(4)
                .map(|(t, d)| format!("{:+.4} s at {:.1} s", d, t - first))
                .collect();
            let _ = write!(
                o,
                "; CLOCK STEPS: {} ({}{}){}",
                self.clock_step_count,
                listed.join(", "),
                if self.clock_step_count > 4 {
                    ", ..."
                } else {
                    ""
                },
                if self.backward > 0 {
                    format!(", time went back {} times", self.backward)
                } else {
                    String::new()
                }
            );
        }
        o
    }
}

/// The first bytes of a file, named if they are a known format (for an error message).
pub fn looks_like(bytes: &[u8]) -> &'static str {
    match bytes {
        [0xD4, 0xC3, 0xB2, 0xA1, ..] | [0xA1, 0xB2, 0xC3, 0xD4, ..] => "a pcap capture",
        [0x4D, 0x3C, 0xB2, 0xA1, ..] | [0xA1, 0xB2, 0x3C, 0x4D, ..] => "a pcap capture (ns)",
        [0x0A, 0x0D, 0x0D, 0x0A, ..] => "a pcapng capture",
        [] => "an empty file",
        b if b.iter().take(256).all(|c| c.is_ascii()) => "text",
        _ => "unknown bytes",
    }
}

/// What a POS MV stream gave, besides the poses ([`InsState::posmv`]).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PosmvState {
    /// Groups accepted, by ID.
    pub groups: std::collections::BTreeMap<u16, u64>,
    /// Control messages seen.
    pub messages: u64,
    /// Groups whose checksum (or end) failed.
    pub rejected: u64,
    /// The group poses are taken from (1, 102 or 103).
    pub pose_group: u16,
    /// Poses on the POS clock (no GNSS time yet).
    pub pos_time: u64,
    /// Poses before any GPS week was known (no Group 3 yet and none given).
    pub no_week: u64,
    /// Poses while Group 7 said the POS was not synchronized to GPS time.
    pub unsynchronized: u64,
    /// The GPS week used (from Group 3, or given).
    pub week: Option<u16>,
    /// GPS - UTC from Group 3 [s].
    pub utc_offset_s: Option<f64>,
    /// The last alignment status (Group 1).
    pub alignment: Option<String>,
    /// The last time synchronization status (Group 7).
    pub time_sync: Option<u8>,
}

impl PosmvState {
    /// A line for people.
    pub fn describe(&self) -> String {
        let groups: Vec<String> = self
            .groups
            .iter()
            .map(|(id, n)| format!("{n} x {id}"))
            .collect();
        let mut o = format!(
            "POS MV groups {} ({} rejected), poses from group {}",
            if groups.is_empty() {
                "none".to_string()
            } else {
                groups.join(", ")
            },
            self.rejected,
            self.pose_group
        );
        if let Some(w) = self.week {
            let _ = write!(o, ", GPS week {w}");
        }
        if let Some(a) = &self.alignment {
            let _ = write!(o, ", alignment: {a}");
        }
        if let Some(s) = self.time_sync {
            let _ = write!(
                o,
                ", time sync {}",
                sync_name(spherecal::posmv::TimeSync::from_byte(s))
            );
        }
        for (n, what) in [
            (self.pos_time, "on the POS clock (no GNSS time)"),
            (
                self.no_week,
                "before a GPS week was known (no Group 3; give --gps-week)",
            ),
            (
                self.unsynchronized,
                "while not synchronized to GPS time (Group 7)",
            ),
        ] {
            if n > 0 {
                let _ = write!(o, "; {n} poses {what}");
            }
        }
        o
    }
}

fn sync_name(s: spherecal::posmv::TimeSync) -> &'static str {
    match s {
        spherecal::posmv::TimeSync::NotSynchronized => "not synchronized",
        spherecal::posmv::TimeSync::Synchronizing => "synchronizing",
        spherecal::posmv::TimeSync::Synchronized => "synchronized",
        spherecal::posmv::TimeSync::OldOffset => "using old offset",
        spherecal::posmv::TimeSync::Other(_) => "unknown",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ins_status_gate() {
        assert_eq!(excluded_by(0x0006), None); // tracking, GNSS fix
        assert_eq!(excluded_by(0x0002), Some(3)); // tracking, no fix
        assert_eq!(excluded_by(0x0004), Some(0)); // not tracking
        assert_eq!(excluded_by(0x0005), Some(1)); // aligning
        assert_eq!(excluded_by(0x0007), Some(2)); // GNSS lost
    }

    /// 200 Hz samples of the GPS time alone: whole output periods missing (one frame cut from
    /// the bytes, 25 frames dropped whole, a 2 s silence) are lost data, not steps; a
    /// contiguous +23 ms and a -50 ms are steps, the latter also time going back.
    #[test]
    fn clock_steps_and_time_going_back() {
        let mut s = InsState::default();
        let mut t = 0i64;
        let mut next = |s: &mut InsState, d: i64, contiguous: bool| {
            t += d;
            s.sample(GpsTime(t), contiguous, None);
        };
        for _ in 0..40 {
            next(&mut s, 5_000_000, true);
        }
        next(&mut s, 10_000_000, false); // a frame cut
        next(&mut s, 130_000_000, true); // 25 frames dropped whole
        next(&mut s, 2_000_000_000, true); // the port silent for 2 s
        next(&mut s, 28_000_000, true); // +23 ms
        next(&mut s, 5_000_000, true);
        next(&mut s, -45_000_000, true); // -50 ms
        for _ in 0..5 {
            next(&mut s, 5_000_000, true);
        }
        next(&mut s, 5_400_000, true); // jitter
        assert_eq!(s.clock_step_count, 2, "{:?}", s.clock_steps);
        assert_eq!(s.backward, 1);
        assert!((s.clock_steps[0].1 - 0.023).abs() < 1e-9);
        assert!((s.clock_steps[1].1 + 0.050).abs() < 1e-9);
        assert_eq!(s.lost_samples, 1 + 25 + 399);
    }

    /// With the unit's free-running clock (TimeStartup) a step of whole periods is told from
    /// lost frames; a restart of that clock (a power cycle) falls back to the periods.
    #[test]
    fn the_free_running_clock_tells_a_step_of_whole_periods_from_lost_frames() {
        let mut s = InsState::default();
        let (mut t, mut own) = (0i64, 7_000_000_000i64);
        let mut next = |s: &mut InsState, d: i64, d_own: i64| {
            t += d;
            own += d_own;
            s.sample(GpsTime(t), true, Some(own));
        };
        for _ in 0..40 {
            next(&mut s, 5_000_000, 5_000_000);
        }
        next(&mut s, 2_000_000_000, 2_000_000_000); // 2 s of frames lost
        next(&mut s, 25_000_000, 5_000_000); // +20 ms: a step of four whole periods
        next(&mut s, 5_000_000, 5_000_000);
        next(&mut s, 600_000_000, -6_000_000_000); // restarted, 0.6 s later
        next(&mut s, 5_000_000, 5_000_000);
        assert_eq!(s.clock_step_count, 1, "{:?}", s.clock_steps);
        assert!((s.clock_steps[0].1 - 0.020).abs() < 1e-9);
        assert_eq!(s.lost_samples, 399 + 119);
    }

    #[test]
    fn spans_and_gaps() {
        let mut s = InsState::default();
        for k in 0..10 {
            s.used(GpsTime(k * 5_000_000), 50_000_000);
        }
        s.used(GpsTime(1_000_000_000), 50_000_000);
        assert_eq!(s.gaps, 1);
        assert!((s.longest_gap_s - 0.955).abs() < 1e-9);
        s.exclude(GpsTime(2_000_000_000), 1);
        s.exclude(GpsTime(2_500_000_000), 1);
        s.exclude(GpsTime(9_000_000_000), 2);
        assert_eq!(s.excluded_spans, vec![(2.0, 2.5), (9.0, 9.0)]);
        assert_eq!(s.excluded_total(), 3);
    }
}

//! What a run of the pipeline counted ([`RunStats`]): the capture, the LiDAR clock, the INS
//! stream, the rings, and in words what the inputs held and why they cannot be used.

use super::{Closest, Files, InsInput};
use spherecal::align::AlignStats;
use spherecal::velodyne::{Identity, Model};
use spherecal_hal::velodyne::SkipStats;

/// Counts of a run.
#[derive(Debug, Clone, Default)]
pub struct RunStats {
    /// The align stage's counts (packets, LiDAR span, windowing, rollovers, batch overflow).
    pub align: AlignStats,
    /// Capture skips by reason.
    pub skips: SkipStats,
    /// The LiDAR clock as its position packets tell it.
    pub clock: crate::state::ClockState,
    /// The INS stream.
    pub ins: crate::state::InsState,
    /// Ring drops (live) or waits (files): lidar, ins.
    pub ring_full: [u64; 2],
    /// The model the data packets were decoded as.
    pub model: Option<Model>,
    /// The Hesai model the data packets said (`--metadata`).
    pub hesai: Option<spherecal::hesai::Model>,
    /// The Ouster's product line its metadata names (`--metadata`).
    pub ouster: Option<String>,
    /// How close the trajectory came to each sphere.
    pub closest: Vec<Closest>,
    /// Windowed returns let go because they were farther than `session::KEEP_NEAR_M` from
    /// every sphere under a converged solve of those before (`calibrate::collect_bounded`).
    pub pruned: u64,
}

impl RunStats {
    /// The LiDAR's model as its maker names it, once its data packets said.
    pub fn lidar_name(&self) -> Option<&str> {
        self.model
            .map(Model::name)
            .or(self.hesai.map(spherecal::hesai::Model::name))
            .or(self.ouster.as_deref())
    }

    /// What the inputs held, for people: the capture, the LiDAR clock, the INS stream, their
    /// overlap and the returns that could not be georeferenced.
    pub fn describe_inputs(&self, pcap: &Files, ins: &Files) -> String {
        use std::fmt::Write as _;
        let mut o = String::new();
        let _ = write!(
            o,
            "LiDAR: {}: {} {}",
            pcap.display(),
            self.align.data_packets,
            if self.clock.clouds {
                "chunks of point-cloud returns"
            } else if self.clock.ouster.is_some() {
                "chunks of returns of lidar packets"
            } else {
                "data packets"
            }
        );
        if let Some(m) = self.lidar_name() {
            let _ = write!(o, " ({m})");
        }
        if let Some((a, b)) = self.align.lidar_span {
            let _ = write!(o, " over {:.1} s", b - a);
        }
        let _ = writeln!(o, ", {} skipped", self.skips.total());
        if let Some((at, what)) = self.skips.truncated_file() {
            let _ = writeln!(
                o,
                "WARNING: a capture is truncated: it ends inside the record at byte {at} ({what}): \
                 cut short (a recording interrupted, a copy not finished); what follows is missing"
            );
        }
        for l in self.skips.lines() {
            let _ = writeln!(
                o,
                "  skipped {}: {} (first at byte {}: {})",
                l.reason, l.count, l.first_offset, l.first
            );
        }
        let _ = writeln!(o, "clock: {}", self.clock.describe());
        let _ = writeln!(o, "{}: {}", ins.display(), self.ins.describe());
        let w = &self.align.window;
        let missed = w.before_history + w.after_history + w.in_gap;
        if missed + self.align.packets_without_time > 0 {
            let _ = writeln!(
                o,
                "not georeferenced: {} returns before the INS data, {} after it, {} in INS gaps; {} packets without a time",
                w.before_history, w.after_history, w.in_gap, self.align.packets_without_time
            );
        }
        o
    }

    /// Data packets were refused because the LiDAR model is unknown or its product byte
    /// disagrees with the packet period: why, in words.
    pub fn model_problem(&self) -> Option<String> {
        if self.align.model_refused == 0 {
            return None;
        }
        let n = self.align.model_refused;
        Some(match self.align.identity {
            Some(identity @ (Identity::Unknown { .. } | Identity::Disagrees { .. })) => format!(
                "{n} data packets refused: {}",
                crate::decode::ModelError {
                    identity,
                    offset: 0
                }
                .to_string()
                .trim_start_matches("data packet at byte 0: ")
                .trim_start_matches("data packets from byte 0: ")
            ),
            _ => format!("{n} data packets refused: their LiDAR model is not known"),
        })
    }

    /// The inputs cannot be calibrated or georeferenced at all: why, in a sentence naming the
    /// file and what was found instead.
    pub fn unusable(
        &self,
        pcap: &Files,
        ins: &InsInput,
        ins_head: &[u8],
        offset_ns: i64,
    ) -> Option<String> {
        let (sbet, ins) = match ins {
            InsInput::Vn200(f) | InsInput::Posmv(f, _, _) | InsInput::Bag(f, _) => (false, f),
            InsInput::Sbet(f, _) => (true, f),
        };
        if let Some(why) = self.model_problem() {
            return Some(format!("{}: {why}", pcap.display()));
        }
        if self.align.data_packets == 0 && self.clock.clouds {
            return Some(format!(
                "{}: no point-cloud return could be timed ({} chunks without a time): a cloud's returns are timed on the recording host's clock, and only an INS recorded in the same bag (its messages' stamps) maps that clock to GPS time; {} gives none",
                pcap.display(),
                self.align.packets_without_time,
                ins.display()
            ));
        }
        if self.align.data_packets == 0 && self.clock.hesai {
            return Some(format!(
                "{}: no Hesai data packet could be timed ({} skipped; {} whose date-time is no date)",
                pcap.display(),
                self.skips.total(),
                self.align.packets_without_time
            ));
        }
        if self.align.data_packets == 0 {
            let first = pcap.expand().ok().and_then(|f| f.first().cloned());
            if let Some(m) = first.and_then(|f| crate::hesai::decode::sniff(&f)) {
                return Some(format!(
                    "{}: no Velodyne data packet, but {} data packets: give the unit's angle correction file with --metadata CORRECTIONS.csv to read them",
                    pcap.display(),
                    m.name()
                ));
            }
            return Some(format!(
                "{}: no Velodyne data packet could be timed ({} skipped; {} without a time)",
                pcap.display(),
                self.skips.total(),
                self.align.packets_without_time
            ));
        }
        let st = &self.ins;
        if st.poses == 0 {
            if st.excluded_total() > 0 {
                return Some(format!(
                    "{}: every one of its {} poses is left out by its InsStatus ({}); --keep-untracked-ins uses them anyway",
                    ins.display(),
                    st.excluded_total(),
                    st.describe()
                ));
            }
            if let Some(p) = &st.posmv {
                return Some(format!(
                    "{}: no usable POS MV pose in {} bytes ({})",
                    ins.display(),
                    st.bytes,
                    p.describe()
                ));
            }
            if sbet {
                return Some(format!(
                    "{}: no valid SBET record in {} bytes ({} records of 136 bytes, {} of them out of range or not finite): it looks like {}",
                    ins.display(),
                    st.bytes,
                    st.sbet_records,
                    st.without_pose,
                    crate::state::looks_like(ins_head)
                ));
            }
            return Some(format!(
                "{}: no VN-200 pose in {} bytes ({} binary frames, {} CRC failures, {} $VN sentences, {} NMEA sentences): it looks like {}",
                ins.display(),
                st.bytes,
                st.frames,
                st.crc_failures,
                st.ascii,
                st.nmea,
                crate::state::looks_like(ins_head)
            ));
        }
        // Time going back by more than a second is no glitch of one stream: the same time is
        // in the input twice (a file given twice or under two names, or two recordings).
        if let Some(&(at, step)) = st.clock_steps.iter().find(|s| s.1 < -1.0) {
            return Some(format!(
                "{}: the INS time goes back {:.3} s (to GPS {at:.3} s): the trajectory holds the same time twice — a file given twice or under two names, or two recordings of one survey; give the files of one recording",
                ins.display(),
                -step
            ));
        }
        let w = &self.align.window;
        if w.points > 0 && w.before_history + w.after_history == w.points {
            let (l, i) = (
                self.align.lidar_span.unwrap_or_default(),
                st.span.unwrap_or_default(),
            );
            let dt = offset_ns as f64 * 1e-9;
            return Some(format!(
                "the LiDAR's times (GPS {:.1} .. {:.1} s{}) and the INS's ({:.1} .. {:.1} s) do not overlap; the LiDAR clock: {}",
                l.0 + dt,
                l.1 + dt,
                if offset_ns == 0 {
                    String::new()
                } else {
                    format!(", with the time offset {dt:+.3} s applied")
                },
                i.0,
                i.1,
                self.clock.describe()
            ));
        }
        None
    }
}

//! The INS of a bag, as VN-200 bytes: the VectorNav driver's groups (`CommonGroup` with the
//! INS and Attitude groups' sigmas), or its `sensor_msgs` topics (`Imu` + `NavSatFix` + a
//! `TimeReference` of GPS time), whichever was recorded.

use spherecal_hal::rosbag::nav::NavBytes;
use spherecal_hal::rosbag::sources::{SerialBytes, Vn200Bytes};
use spherecal_hal::rosbag::BagError;
use spherecal_hal::serial::{ByteSource, ReadOutcome};

/// A bag's INS topics as the VN-200 frames they were made from.
pub enum BagIns {
    /// `vectornav_msgs` groups.
    Groups(Vn200Bytes),
    /// `sensor_msgs` Imu + NavSatFix + TimeReference.
    Nav(NavBytes),
    /// An MCAP raw log's serial reads.
    Serial(SerialBytes),
}

impl ByteSource for BagIns {
    type Error = BagError;

    fn read_chunk(&mut self, buf: &mut [u8]) -> Result<ReadOutcome, BagError> {
        match self {
            BagIns::Groups(g) => g.read_chunk(buf),
            BagIns::Nav(n) => n.read_chunk(buf),
            BagIns::Serial(s) => s.read_chunk(buf),
        }
    }
}

impl BagIns {
    /// What was read, for people (after the run).
    pub fn describe(&self) -> String {
        match self {
            BagIns::Groups(g) => {
                let b = &g.stats;
                let mut said = format!(
                    "ROS 2 bag: {} CommonGroup messages -> {} VN-200 frames ({} with the filter's PosU and YprU)",
                    b.common, b.frames, b.with_sigmas
                );
                if b.empty > 0 {
                    said.push_str(&format!(", {} without any pose field", b.empty));
                }
                if let Some(first) = &b.first_bad {
                    said.push_str(&format!(", {} messages not parsed (first: {first})", b.bad));
                }
                said.push_str(&spherecal_hal::rosbag::cut_words(g.cut()));
                said
            }
            BagIns::Serial(s) => {
                let mut said = format!(
                    "MCAP raw log: {} serial reads{}",
                    s.reads.0,
                    s.reads
                        .1
                        .map(|b| format!(" at {b} baud"))
                        .unwrap_or_default()
                );
                if let (n, Some(first)) = &s.bad {
                    said.push_str(&format!(", {n} not parsed (first: {first})"));
                }
                said.push_str(&spherecal_hal::rosbag::cut_words(s.cut()));
                said
            }
            BagIns::Nav(n) => {
                let b = &n.stats;
                let mut said = format!(
                    "ROS 2 bag: {} Imu + {} NavSatFix + {} TimeReference messages -> {} VN-200 frames (quaternion, position, GPS time; orientation in RFU/ENU {}, FRD/NED {}; no INS mode: tracking taken as the GNSS fix)",
                    b.messages[0], b.messages[1], b.messages[2], b.frames, b.frames_enu_ned[0], b.frames_enu_ned[1]
                );
                for (n, what) in [
                    (
                        b.other_reference,
                        "timed by a time reference of another stamp",
                    ),
                    (b.no_time, "left out: no time reference within 10 s"),
                    (b.incomplete, "stamps without both an Imu and a NavSatFix"),
                    (
                        b.bad_reference,
                        "time references neither GPS nor UTC time near the host's clock",
                    ),
                ] {
                    if n > 0 {
                        said.push_str(&format!(", {n} {what}"));
                    }
                }
                if let Some(first) = &b.first_bad {
                    said.push_str(&format!(", {} messages not parsed (first: {first})", b.bad));
                }
                said.push_str(&spherecal_hal::rosbag::cut_words(n.cut()));
                said
            }
        }
    }
}

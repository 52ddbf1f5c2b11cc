//! `spherecal decode FILE [--csv OUT]`, `spherecal decode --bag BAG [--lidar-topic T]`.

use super::{create_csv, fail};
use std::path::PathBuf;
use std::process::ExitCode;

/// Decode Velodyne packets (VLP-16, Puck Hi-Res, HDL-32E, VLP-32C) from a pcap/pcapng
/// capture or a ROS 2 bag's VelodyneScan topic, an Ouster's (OS0/OS1/OS2) lidar packets with
/// the sensor's metadata JSON, or a Hesai's (PandarXT16/XT32/QT64/QT128) data packets from a capture
/// or a bag's PandarScan topic with the unit's angle correction CSV; print counts, optionally
/// list points.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Capture file (classic pcap or pcapng).
    #[arg(required_unless_present = "bag", conflicts_with = "bag")]
    pub file: Option<PathBuf>,
    /// A ROS 2 bag (a rosbag2 folder, a `.mcap` or a `.db3`): its VelodyneScan packets.
    #[arg(long)]
    pub bag: Option<PathBuf>,
    /// The bag's topic of VelodyneScan (or, with a Hesai's corrections, PandarScan) messages
    /// (default: the only one).
    #[arg(long)]
    pub lidar_topic: Option<String>,
    /// Write one row per returned point to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// The LiDAR model (vlp16, puck-hires, hdl32e, vlp32c); by default the packets' product
    /// byte, checked against their period.
    #[arg(long, value_parser = super::parse_model)]
    pub model: Option<spherecal::velodyne::Model>,
    /// The sensor's own description: an Ouster's metadata JSON (its packet format, beams and
    /// ports; the CSV then adds `frame_id,measurement_id,channel`, a dual profile's second
    /// return as its own row, `return` = second), or a Hesai unit's angle correction CSV
    /// (`Channel,Elevation,Azimuth`; `laser` is the channel from 0, a dual mode's block as its
    /// `return`). x y z in the sensor frame.
    #[arg(long, conflicts_with = "model")]
    pub metadata: Option<PathBuf>,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    let mut out = match create_csv("decode", a.csv.as_ref()) {
        Ok(o) => o,
        Err(code) => return code,
    };
    crate::output::remove_partial_on_interrupt();
    if let (Some(meta), Some(f)) = (&a.metadata, a.file.as_ref().or(a.bag.as_ref())) {
        if meta
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
        {
            return hesai(f, a.lidar_topic.as_deref(), meta, out);
        }
        return ouster(f, a.lidar_topic.as_deref(), meta, out);
    }
    let w = out.as_mut().map(|w| w as &mut dyn std::io::Write);
    let (path, decoded) = match (&a.bag, &a.file) {
        (Some(b), _) => (
            b,
            crate::pipeline::bag_decode::decode_bag(b, a.lidar_topic.as_deref(), w, a.model),
        ),
        (None, Some(f)) if spherecal_hal::rosbag::is_bag(f) => (
            f,
            crate::pipeline::bag_decode::decode_bag(f, None, w, a.model),
        ),
        (None, Some(f)) => (f, crate::decode::decode_file(f, w, a.model)),
        (None, None) => return fail("decode", "give a capture file or --bag"),
    };
    match decoded {
        Ok(s) => {
            let hesai = (s.data_packets == 0 && !spherecal_hal::rosbag::is_bag(path))
                .then(|| crate::hesai::decode::sniff(path))
                .flatten();
            let path = path.display().to_string();
            say!("{}", s.render(&path));
            if let Some(Err(e)) = out.map(crate::output::Staged::commit) {
                return fail("decode", e);
            }
            match (&s.stopped, s.truncation(&path)) {
                (Some(stop), _) => fail("decode", format!("{path}: {stop}")),
                (None, Some(w)) => fail("decode", w),
                (None, None) if s.data_packets == 0 && hesai.is_some() => fail(
                    "decode",
                    format!(
                        "{path}: no Velodyne packet, but {} data packets: decode them with the unit's angle correction file (--metadata CORRECTIONS.csv)",
                        hesai.map_or("Hesai", spherecal::hesai::Model::name)
                    ),
                ),
                (None, None) if looks_ouster(&s) => fail(
                    "decode",
                    format!(
                        "{path}: no Velodyne packet, and its first other datagram went to UDP {} or {}, an Ouster's lidar and IMU ports: decode it with the sensor's metadata JSON (--metadata META.json)",
                        spherecal::ouster::LIDAR_PORT,
                        spherecal::ouster::IMU_PORT
                    ),
                ),
                (None, None) => ExitCode::SUCCESS,
            }
        }
        Err(e) => fail("decode", e),
    }
}

/// An Ouster capture with its metadata.
fn ouster(
    f: &std::path::Path,
    topic: Option<&str>,
    meta: &std::path::Path,
    mut out: Option<crate::output::Staged>,
) -> ExitCode {
    let w = out.as_mut().map(|w| w as &mut dyn std::io::Write);
    let m = match crate::ouster::Metadata::load(meta) {
        Ok(m) => m,
        Err(e) => return fail("decode", e),
    };
    let s = match crate::ouster::decode::decode_file(f, topic, &m, w) {
        Ok(s) => s,
        Err(e) => return fail("decode", e),
    };
    let path = f.display().to_string();
    say!("{}", s.render(&path, &m));
    finish(&path, s.mismatch(&m), out, s.stopped.as_deref())
}

/// A Hesai capture or bag with the unit's angle corrections.
fn hesai(
    f: &std::path::Path,
    topic: Option<&str>,
    corrections: &std::path::Path,
    mut out: Option<crate::output::Staged>,
) -> ExitCode {
    let w = out.as_mut().map(|w| w as &mut dyn std::io::Write);
    let c = match crate::hesai::corrections::load(corrections) {
        Ok(c) => c,
        Err(e) => return fail("decode", e),
    };
    let s = match crate::hesai::decode::decode_file(f, topic, &c, w) {
        Ok(s) => s,
        Err(e) => return fail("decode", e),
    };
    let path = f.display().to_string();
    say!("{}", s.render(&path, c.channels()));
    let none = (s.data_packets == 0)
        .then(|| "no Hesai data packet (PandarXT16, XT32, QT64 or QT128) to decode".to_string());
    finish(&path, s.mismatch(&c).or(none), out, s.stopped.as_deref())
}

/// The end of an Ouster's or a Hesai's decode, its summary printed: refused for `why` (the
/// listing dropped, not written), else the listing kept and a file that stopped early said.
fn finish(
    path: &str,
    why: Option<String>,
    out: Option<crate::output::Staged>,
    stopped: Option<&str>,
) -> ExitCode {
    if let Some(why) = why {
        return fail("decode", format!("{path}: {why}"));
    }
    if let Some(Err(e)) = out.map(crate::output::Staged::commit) {
        return fail("decode", e);
    }
    match stopped {
        Some(stop) => fail("decode", format!("{path}: {stop}")),
        None => ExitCode::SUCCESS,
    }
}

/// A capture with no Velodyne packet whose first datagram on another port went to an Ouster's
/// default lidar or IMU port.
fn looks_ouster(s: &crate::decode::DecodeSummary) -> bool {
    let ports = [spherecal::ouster::LIDAR_PORT, spherecal::ouster::IMU_PORT];
    s.data_packets == 0
        && s.position_packets == 0
        && s.skips.lines().iter().any(|l| {
            l.reason == "other port"
                && ports
                    .iter()
                    .any(|&p| l.first == spherecal_hal::SkipReason::OtherPort(p).to_string())
        })
}

//! The input files as the user named them (files, folders, patterns) and what is read from
//! them before the readers start: the captures in order, the GPS week of their RMC dates.

use super::*;
use spherecal_hal::pcap::PcapChain;
use std::path::Path;

/// Input files as the user named them: files, folders, patterns, several of each (the shell
/// expands an unquoted `logs/*.pcap` into several).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Files(pub Vec<PathBuf>);

impl Files {
    /// Every file named: each entry through [`expand_files`], in the order given, each file
    /// once.
    pub fn expand(&self) -> Result<Vec<PathBuf>, crate::Error> {
        let mut out: Vec<PathBuf> = Vec::new();
        for p in &self.0 {
            for f in expand_files(p)? {
                if !out.contains(&f) {
                    out.push(f);
                }
            }
        }
        if out.is_empty() {
            return Err("no input file given".into());
        }
        Ok(out)
    }

    /// The names as given, for messages.
    pub fn display(&self) -> String {
        self.0
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(" ")
    }
}

impl From<PathBuf> for Files {
    fn from(p: PathBuf) -> Self {
        Self(vec![p])
    }
}

impl From<&Path> for Files {
    fn from(p: &Path) -> Self {
        Self(vec![p.to_path_buf()])
    }
}

impl From<&PathBuf> for Files {
    fn from(p: &PathBuf) -> Self {
        Self(vec![p.clone()])
    }
}

impl From<&Files> for Files {
    fn from(f: &Files) -> Self {
        f.clone()
    }
}

impl From<Vec<PathBuf>> for Files {
    fn from(v: Vec<PathBuf>) -> Self {
        Self(v)
    }
}

/// The files `path` names: itself; a folder's `.pcap`/`.pcapng` files; or, with `*` or `?` in
/// its file name, the files of its folder that match (the rig's rotated logs:
/// `logs/20261122T084638Z-lidar-*.pcap`). Sorted by name; none is an error.
pub fn expand_files(path: &Path) -> Result<Vec<PathBuf>, crate::Error> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let (dir, pattern) = if name.contains(['*', '?']) {
        (path.parent().unwrap_or(Path::new(".")), Some(name))
    } else if path.is_dir() {
        (path, None)
    } else {
        return Ok(vec![path.to_path_buf()]);
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .filter(|p| {
            let n = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            match pattern {
                Some(pat) => glob_match(pat.as_bytes(), n.as_bytes()),
                None => n.ends_with(".pcap") || n.ends_with(".pcapng"),
            }
        })
        .collect();
    out.sort();
    if out.is_empty() {
        return Err(format!("{}: no file matches", path.display()).into());
    }
    Ok(out)
}

/// `*` (any run) and `?` (any one byte) against a file name.
fn glob_match(pat: &[u8], name: &[u8]) -> bool {
    match (pat.first(), name.first()) {
        (None, None) => true,
        (Some(b'*'), _) => {
            glob_match(&pat[1..], name) || (!name.is_empty() && glob_match(pat, &name[1..]))
        }
        (Some(b'?'), Some(_)) => glob_match(&pat[1..], &name[1..]),
        (Some(a), Some(b)) if a == b => glob_match(&pat[1..], &name[1..]),
        _ => false,
    }
}

/// The LiDAR's packets: captures, or a ROS 2 bag's `VelodyneScan` topic.
pub enum Captures {
    /// Capture files in time order.
    Pcap(Box<PcapChain>),
    /// A bag's scans.
    Bag(Box<spherecal_hal::rosbag::sources::ScanPackets>),
    /// A bag's point clouds (returns, not packets).
    Clouds(Box<spherecal_hal::rosbag::clouds::CloudChunks>),
}

/// What a bag of point clouds cannot give.
pub const CLOUDS_HOLD_NO_PACKETS: &str = "this bag's LiDAR topic is sensor_msgs/msg/PointCloud2: points the driver computed, not its packets; it can be decoded, georeferenced and calibrated from, not replayed as packets (record velodyne_msgs/msg/VelodyneScan, e.g. /velodyne_packets, for that)";

/// Why a capture or a bag stopped being read.
#[derive(Debug)]
pub struct CaptureError(String);

impl std::fmt::Display for CaptureError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CaptureError {}

impl PacketSource for Captures {
    type Error = CaptureError;

    fn next_record(&mut self) -> Result<Option<Record<'_>>, CaptureError> {
        match self {
            Captures::Pcap(c) => c.next_record().map_err(|e| CaptureError(e.to_string())),
            Captures::Bag(b) => b.next_record().map_err(|e| CaptureError(e.to_string())),
            Captures::Clouds(_) => Err(CaptureError(CLOUDS_HOLD_NO_PACKETS.into())),
        }
    }
}

/// A source read through a borrow (so that what it knew at the end, a bag's cut, can be asked
/// after).
impl PacketSource for &mut Captures {
    type Error = CaptureError;

    fn next_record(&mut self) -> Result<Option<Record<'_>>, CaptureError> {
        (**self).next_record()
    }
}

impl Captures {
    /// The MCAP files of a bag found cut short, with the byte each ends at.
    pub fn cut(&self) -> &[(std::path::PathBuf, u64)] {
        match self {
            Captures::Bag(b) => b.cut(),
            Captures::Clouds(c) => c.cut(),
            Captures::Pcap(_) => &[],
        }
    }
}

/// The bag `files` names, if it names one (a single `.mcap`, `.db3` or bag folder).
pub fn as_bag(files: &Files) -> Option<&Path> {
    match files.0.as_slice() {
        [one] if spherecal_hal::rosbag::is_bag(one) => Some(one),
        _ => None,
    }
}

/// The capture(s) `files` names (see [`expand_files`]) as one source in time order; or a
/// ROS 2 bag's scans or point clouds (`lidar_topic`, else the only `VelodyneScan` topic, else
/// the only `PointCloud2` one; a cloud's rings are read as `model`'s, by default a VLP-16's).
pub fn open_captures(
    files: &Files,
    lidar_topic: Option<&str>,
    model: Option<Model>,
) -> Result<Captures, crate::Error> {
    if let Some(bag) = as_bag(files) {
        let b = crate::bag::open(bag, lidar_topic, None, false)?;
        if b.lidar_is_cloud() {
            return Ok(Captures::Clouds(Box::new(
                b.clouds(model.unwrap_or(Model::Vlp16))?,
            )));
        }
        return Ok(Captures::Bag(Box::new(b.packets()?)));
    }
    PcapChain::open(&files.expand()?)
        .map(|c| Captures::Pcap(Box::new(c)))
        .map_err(|e| e.to_string().into())
}

/// The GPS week of the first RMC date in a capture (for SBET times).
pub fn week_from_capture(pcap: &Files, leap: i64) -> Option<u16> {
    let mut src = open_captures(pcap, None, None).ok()?;
    while let Ok(Some(rec)) = src.next_record() {
        if let Record::Udp(d) = rec {
            if let Ok(Vlp16Packet::Position { packet, .. }) = classify(&d, Ports::default()) {
                if let Some(utc) = packet.nmea_time().ok().and_then(|t| t.utc()) {
                    let g =
                        spherecal::time::unix_ns_to_gps(utc.unix_seconds() * 1_000_000_000, leap);
                    return u16::try_from(g.week_tow_ns().0).ok();
                }
            }
        }
    }
    None
}

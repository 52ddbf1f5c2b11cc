//! A bag's `sensor_msgs/msg/PointCloud2` (velodyne_pointcloud's XYZIRT clouds) as returns
//! ([`CloudChunks`]): each cloud's points in time order, in chunks of at most [`CHUNK`]
//! returns that fit a ring item, each return as the decoder's [`Point`] in the LiDAR frame
//! with its firing time after the chunk's first. What is lost against the raw packets
//! (DESIGN.md "ROS 2 bags"): the sensor's own clock (the times are the host's), the position
//! packets, the azimuth's precision (velodyne_pointcloud rounds it to 0.01 deg), returns
//! inside its min_range, and the raw distance (float32 metres instead).

use super::{BagError, Messages};
use crate::packet::{HostTime, SkipReason};
use crate::velodyne::SkipStats;
use spherecal::ros2::cloud::{Lasers, Layout, PointCloud2, PointSkip};
use spherecal::velodyne::{Model, Point};

/// Returns per chunk (a chunk is one LiDAR ring item, about a packet's bytes).
pub const CHUNK: usize = 32;

/// Returns fired within [`Self::span_ns`] of the first, on the host's clock.
#[derive(Debug, Clone, Copy)]
pub struct Chunk {
    /// The first return's time (the cloud's stamp plus its `time`) [host clock].
    pub t0: HostTime,
    points: [Point; CHUNK],
    len: usize,
}

impl Default for Chunk {
    fn default() -> Self {
        Self {
            t0: HostTime(0),
            points: [Point::default(); CHUNK],
            len: 0,
        }
    }
}

impl Chunk {
    /// An empty chunk whose returns fire after `t0`.
    pub fn new(t0: HostTime) -> Self {
        Self {
            t0,
            ..Self::default()
        }
    }

    /// Add a return (its `offset_ns` after `t0`); `false` when the chunk is full.
    pub fn push(&mut self, p: Point) -> bool {
        match self.points.get_mut(self.len) {
            Some(slot) => {
                *slot = p;
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// The returns (firing time after `t0` in each `offset_ns`).
    pub fn points(&self) -> &[Point] {
        &self.points[..self.len]
    }

    /// The last return's time after the first [ns].
    pub fn span_ns(&self) -> i64 {
        self.points().last().map_or(0, |p| i64::from(p.offset_ns))
    }
}

/// What a [`CloudChunks`] met.
#[derive(Debug, Clone, Default)]
pub struct CloudStats {
    /// Clouds read.
    pub clouds: u64,
    /// Returns handed on.
    pub returns: u64,
    /// The first cloud's frame_id.
    pub frame_id: Option<String>,
    /// Cells and messages not used, by reason (empty cells, rings the model has not, points off
    /// their ring's elevation, clouds that do not parse), each with the first's place.
    pub skips: SkipStats,
}

impl CloudStats {
    /// The share of returns that were not on their ring's elevation: near 1 when the cloud is
    /// not in the LiDAR's own frame (a target_frame was set in velodyne_pointcloud).
    pub fn off_elevation(&self) -> f64 {
        let off = self.skips.get(PointSkip::Elevation.name());
        off as f64 / (off + self.returns).max(1) as f64
    }
}

/// Its reason's name, for the skip counts.
trait Named {
    fn name(&self) -> &'static str;
}

impl Named for PointSkip {
    fn name(&self) -> &'static str {
        match self {
            PointSkip::Ring => "point with a ring the model has not",
            PointSkip::Elevation => "point off its ring's elevation",
            PointSkip::NoRange => "point at the origin",
        }
    }
}

/// The returns of a topic of `sensor_msgs/msg/PointCloud2`, in chunks.
pub struct CloudChunks {
    msgs: Messages,
    lasers: Lasers,
    buf: Vec<u8>,
    cur: Option<Current>,
    /// What was met.
    pub stats: CloudStats,
}

/// The cloud being read.
struct Current {
    layout: Layout,
    data: std::ops::Range<usize>,
    cells: usize,
    next: usize,
    stamp_ns: i64,
    at: u64,
}

impl CloudChunks {
    /// Over `msgs` (one topic of clouds) from a LiDAR of `model` (its rings).
    pub fn new(msgs: Messages, model: Model) -> Self {
        Self {
            msgs,
            lasers: Lasers::new(model),
            buf: Vec::new(),
            cur: None,
            stats: CloudStats::default(),
        }
    }

    /// The model whose rings are read.
    pub fn model(&self) -> Model {
        self.lasers.model()
    }

    /// Fill `out` with the next returns: false at the end of the topic. A chunk ends at
    /// [`CHUNK`] returns, at the end of a cloud, or where the time goes back or jumps by more
    /// than a second.
    pub fn next_chunk(&mut self, out: &mut Chunk) -> Result<bool, BagError> {
        out.len = 0;
        loop {
            let Some(c) = self.cur.as_mut() else {
                if !self.next_cloud()? {
                    return Ok(out.len > 0);
                }
                continue;
            };
            let data = &self.buf[c.data.clone()];
            while c.next < c.cells {
                let i = c.next;
                let Some(p) = c.layout.point(data, i) else {
                    c.next += 1;
                    self.stats.skips.count(c.at, &SkipReason::EmptyCell);
                    continue;
                };
                let t = c.stamp_ns.saturating_add(p.time_ns);
                let offset = if out.len == 0 { 0 } else { t - out.t0.0 };
                if out.len > 0 && !(0..1_000_000_000).contains(&offset) {
                    return Ok(true);
                }
                c.next += 1;
                match self.lasers.point(&p, offset as u32) {
                    Ok(q) => {
                        if out.len == 0 {
                            out.t0 = HostTime(t);
                        }
                        out.points[out.len] = q;
                        out.len += 1;
                        self.stats.returns += 1;
                        if out.len == CHUNK {
                            return Ok(true);
                        }
                    }
                    Err(e) => self
                        .stats
                        .skips
                        .count(c.at, &SkipReason::CloudPoint(e.name())),
                }
            }
            self.cur = None;
            if out.len > 0 {
                return Ok(true);
            }
        }
    }

    /// Read the next cloud that parses (those that do not are counted): false at the end.
    fn next_cloud(&mut self) -> Result<bool, BagError> {
        loop {
            let Some(m) = self.msgs.next()? else {
                return Ok(false);
            };
            let at = m.at;
            self.buf.clear();
            self.buf.extend_from_slice(m.data);
            match PointCloud2::parse(&self.buf) {
                Ok(c) => {
                    self.stats.clouds += 1;
                    if self.stats.frame_id.is_none() {
                        self.stats.frame_id = Some(c.header.frame_id.to_string());
                    }
                    let start = c.data.as_ptr() as usize - self.buf.as_ptr() as usize;
                    self.cur = Some(Current {
                        layout: c.layout,
                        data: start..start + c.data.len(),
                        cells: c.len(),
                        next: 0,
                        stamp_ns: c.header.stamp.ns(),
                        at,
                    });
                    return Ok(true);
                }
                Err(e) => self.stats.skips.count(at, &SkipReason::BadCloud(e)),
            }
        }
    }
}

impl CloudChunks {
    /// The MCAP files found cut short so far ([`super::Messages::cut`]).
    pub fn cut(&self) -> &[(std::path::PathBuf, u64)] {
        self.msgs.cut()
    }
}

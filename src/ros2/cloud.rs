//! `sensor_msgs/msg/PointCloud2` as velodyne_pointcloud publishes it (ros-drivers/velodyne
//! branch `ros2`, `PointcloudXYZIRT`): per point `x y z intensity` (float32), `ring` (uint16),
//! `time` (float32 seconds after the cloud's stamp), in the ROS sensor frame (REP-103: x
//! forward, y left, z up). [`PointCloud2::parse`] checks the layout once; [`Layout::point`]
//! then reads any point without failing. [`Lasers`] turns a point back into the decoder's
//! [`Point`] in the LiDAR frame of the Velodyne manual (x right, y forward, z up), its ring
//! into the model's laser id (PROTOCOLS.md "PointCloud2").

use super::cdr::{Error, Reader};
use super::Header;
use crate::velodyne::{Model, Point, Return};

/// `sensor_msgs/msg/PointField` datatypes.
pub mod datatype {
    /// int8.
    pub const INT8: u8 = 1;
    /// uint8.
    pub const UINT8: u8 = 2;
    /// int16.
    pub const INT16: u8 = 3;
    /// uint16.
    pub const UINT16: u8 = 4;
    /// int32.
    pub const INT32: u8 = 5;
    /// uint32.
    pub const UINT32: u8 = 6;
    /// float32.
    pub const FLOAT32: u8 = 7;
    /// float64.
    pub const FLOAT64: u8 = 8;
}

/// Size of a datatype [bytes] (0: not a datatype).
const fn size(t: u8) -> usize {
    match t {
        1 | 2 => 1,
        3 | 4 => 2,
        5..=7 => 4,
        8 => 8,
        _ => 0,
    }
}

/// One field of a point: where it is and how it is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    /// Byte offset in the point.
    pub offset: u32,
    /// Its [`datatype`].
    pub datatype: u8,
}

/// Why a cloud's layout is not one spherecal reads (the message itself parsed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LayoutError {
    /// A field spherecal needs is not there: its name.
    Missing(&'static str),
    /// A field of a type it cannot be: its name and datatype.
    Type(&'static str, u8),
    /// A field that does not fit in `point_step`: its name.
    Outside(&'static str),
    /// `row_step`, `point_step`, `width` and `height` do not fit the data: the data's length
    /// and what they need.
    Size {
        /// The data's length.
        data: usize,
        /// What width, height and the steps need.
        needed: u64,
    },
}

impl core::fmt::Display for LayoutError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LayoutError::Missing(n) => write!(
                f,
                "no '{n}' field (velodyne_pointcloud's XYZIRT clouds have x y z intensity ring time)"
            ),
            LayoutError::Type(n, t) => write!(f, "field '{n}' has datatype {t}, not a number spherecal reads"),
            LayoutError::Outside(n) => write!(f, "field '{n}' does not fit in point_step"),
            LayoutError::Size { data, needed } => write!(
                f,
                "{data} bytes of data, but width, height and the steps need {needed}"
            ),
        }
    }
}

/// Why a cloud is not read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CloudError {
    /// Not a well-formed message.
    Cdr(Error),
    /// Well formed, but not points spherecal reads.
    Layout(LayoutError),
}

impl core::fmt::Display for CloudError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            CloudError::Cdr(e) => e.fmt(f),
            CloudError::Layout(e) => e.fmt(f),
        }
    }
}

impl From<Error> for CloudError {
    fn from(e: Error) -> Self {
        CloudError::Cdr(e)
    }
}

/// Where a cloud's fields are, checked once against `point_step`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// x, y, z (float32 or float64).
    pub xyz: [Field; 3],
    /// Intensity, if recorded.
    pub intensity: Option<Field>,
    /// The ring (any integer type).
    pub ring: Field,
    /// The firing time: `time` [s after the stamp, float] or `t` [ns after it, uint32].
    pub time: Field,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row.
    pub row_step: u32,
    /// Points per row.
    pub width: u32,
    /// Values are big endian.
    pub big: bool,
}

/// A point as recorded (the ROS sensor frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CloudPoint {
    /// x forward [m].
    pub x: f32,
    /// y left [m].
    pub y: f32,
    /// z up [m].
    pub z: f32,
    /// Intensity (0 when not recorded).
    pub intensity: f32,
    /// Ring: the laser's place in order of elevation, 0 the lowest.
    pub ring: u16,
    /// Time after the cloud's stamp [ns] (negative before it).
    pub time_ns: i64,
}

impl Layout {
    fn value(&self, d: &[u8], at: usize, f: Field) -> f64 {
        let at = at + f.offset as usize;
        let n = size(f.datatype);
        let mut b = [0u8; 8];
        if let Some(s) = d.get(at..at + n) {
            b[..n].copy_from_slice(s);
        }
        if self.big {
            b[..n].reverse();
        }
        match f.datatype {
            datatype::INT8 => f64::from(b[0] as i8),
            datatype::UINT8 => f64::from(b[0]),
            datatype::INT16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            datatype::UINT16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            datatype::INT32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            datatype::UINT32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            datatype::FLOAT32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            _ => f64::from_le_bytes(b),
        }
    }

    /// Point `i` of `data` (row-major), or None when it is not a return (a non-finite
    /// coordinate: an organised cloud's empty cell) or outside the data.
    pub fn point(&self, data: &[u8], i: usize) -> Option<CloudPoint> {
        let w = self.width.max(1) as usize;
        let at = (i / w)
            .checked_mul(self.row_step as usize)?
            .checked_add((i % w).checked_mul(self.point_step as usize)?)?;
        if at.checked_add(self.point_step as usize)? > data.len() {
            return None;
        }
        let [x, y, z] = self.xyz.map(|f| self.value(data, at, f) as f32);
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            return None;
        }
        let t = self.value(data, at, self.time);
        let time_ns =
            if self.time.datatype == datatype::FLOAT32 || self.time.datatype == datatype::FLOAT64 {
                let ns = t * 1e9;
                if !ns.is_finite() || ns.abs() > 1e12 {
                    return None;
                }
                libm::round(ns) as i64
            } else {
                t as i64
            };
        Some(CloudPoint {
            x,
            y,
            z,
            intensity: self
                .intensity
                .map_or(0.0, |f| self.value(data, at, f) as f32),
            ring: self.value(data, at, self.ring) as u16,
            time_ns,
        })
    }
}

/// A `sensor_msgs/msg/PointCloud2` message, its layout checked.
#[derive(Debug, Clone)]
pub struct PointCloud2<'a> {
    /// Header: stamp (host time of the scan) and the frame the points are in.
    pub header: Header<'a>,
    /// Rows (1: unorganised).
    pub height: u32,
    /// The fields spherecal reads.
    pub layout: Layout,
    /// The points' bytes.
    pub data: &'a [u8],
    /// No invalid points (the publisher's claim).
    pub is_dense: bool,
}

impl<'a> PointCloud2<'a> {
    /// Parse a CDR message and check that its fields and sizes fit its data.
    pub fn parse(b: &'a [u8]) -> Result<Self, CloudError> {
        let mut r = Reader::new(b)?;
        let header = Header::read(&mut r)?;
        let height = r.u32("height")?;
        let width = r.u32("width")?;
        // A PointField: name (>= 5 bytes), offset, datatype, count.
        let nf = r.count(13, "fields")?;
        let mut xyz: [Option<Field>; 3] = [None; 3];
        let (mut intensity, mut ring, mut time) = (None, None, None);
        let mut ns_time = None;
        for _ in 0..nf {
            let name = r.string("field name")?;
            let offset = r.u32("field offset")?;
            let datatype = r.u8("field datatype")?;
            let _count = r.u32("field count")?;
            let f = Some(Field { offset, datatype });
            match name {
                "x" => xyz[0] = f,
                "y" => xyz[1] = f,
                "z" => xyz[2] = f,
                "intensity" => intensity = f,
                "ring" => ring = f,
                "time" => time = f,
                "t" => ns_time = f,
                _ => {}
            }
        }
        let big = r.bool("is_bigendian")?;
        let point_step = r.u32("point_step")?;
        let row_step = r.u32("row_step")?;
        let n = r.count(1, "data")? as usize;
        let data = r.bytes(n, "data")?;
        let is_dense = r.bool("is_dense")?;
        let layout = |e| CloudError::Layout(e);
        let need = |f: Option<Field>, name: &'static str, ok: &[u8]| match f {
            None => Err(layout(LayoutError::Missing(name))),
            Some(f) if !ok.contains(&f.datatype) => {
                Err(layout(LayoutError::Type(name, f.datatype)))
            }
            Some(f) if f.offset as usize + size(f.datatype) > point_step as usize => {
                Err(layout(LayoutError::Outside(name)))
            }
            Some(f) => Ok(f),
        };
        use datatype::*;
        const FLOATS: &[u8] = &[FLOAT32, FLOAT64];
        const NUMBERS: &[u8] = &[INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64];
        const INTS: &[u8] = &[UINT8, UINT16, UINT32, INT8, INT16, INT32];
        let xyz = [
            need(xyz[0], "x", FLOATS)?,
            need(xyz[1], "y", FLOATS)?,
            need(xyz[2], "z", FLOATS)?,
        ];
        let ring = need(ring, "ring", INTS)?;
        let time = match (time, ns_time) {
            (None, Some(t)) => need(Some(t), "t", &[UINT32])?,
            (t, _) => need(t, "time", FLOATS)?,
        };
        let intensity = match intensity {
            Some(_) => Some(need(intensity, "intensity", NUMBERS)?),
            None => None,
        };
        let needed = if height == 0 || width == 0 {
            0
        } else {
            u64::from(height - 1) * u64::from(row_step) + u64::from(width) * u64::from(point_step)
        };
        if u64::from(row_step) < u64::from(width) * u64::from(point_step) && height > 1
            || needed > data.len() as u64
        {
            return Err(layout(LayoutError::Size {
                data: data.len(),
                needed,
            }));
        }
        Ok(Self {
            header,
            height,
            layout: Layout {
                xyz,
                intensity,
                ring,
                time,
                point_step,
                row_step,
                width,
                big,
            },
            data,
            is_dense,
        })
    }

    /// Points (cells) in the cloud, returns or not.
    pub fn len(&self) -> usize {
        self.layout.width as usize * self.height as usize
    }

    /// No cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Cell `i`, if it is a return.
    pub fn point(&self, i: usize) -> Option<CloudPoint> {
        self.layout.point(self.data, i)
    }
}

/// Sine of the largest difference between a point's elevation and its ring's that still counts
/// as "in the LiDAR's frame": 1 deg (beam-origin offsets move a return at 1 m by < 0.5 deg).
const ELEVATION_TOLERANCE_SIN: f32 = 0.0175;

/// A model's rings: velodyne_pointcloud numbers the lasers by elevation (its calibration's
/// `laser_ring`), spherecal by firing order (the laser id, manual 9.3).
#[derive(Debug, Clone)]
pub struct Lasers {
    model: Model,
    by_ring: [u8; 32],
    sin_elevation: [f32; 32],
    /// Per ring: the beam-origin offset [m], and it times sin and 1 - cos of the elevation.
    origin: [(f32, f32, f32); 32],
}

/// How a cloud's point becomes a decoded return, or why not.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointSkip {
    /// A ring the model does not have.
    Ring,
    /// The point's elevation is not its ring's: the cloud is not in the LiDAR's frame.
    Elevation,
    /// At the origin (no range).
    NoRange,
}

impl Lasers {
    /// The ring -> laser table of `model`.
    pub fn new(model: Model) -> Self {
        let beams = model.beams();
        let mut by_ring = [0u8; 32];
        let mut sin_elevation = [0f32; 32];
        let mut origin = [(0f32, 0f32, 0f32); 32];
        let n = beams.len().min(32);
        for (laser, b) in beams.iter().enumerate().take(n) {
            // The ring is the number of lasers below this one (ties by id).
            let ring = beams
                .iter()
                .enumerate()
                .filter(|(j, o)| {
                    o.elevation_deg < b.elevation_deg
                        || (o.elevation_deg == b.elevation_deg && *j < laser)
                })
                .count();
            by_ring[ring] = laser as u8;
            let (sin, cos) = libm::sincos(b.elevation_deg.to_radians());
            sin_elevation[ring] = sin as f32;
            let o = b.vertical_offset_m;
            origin[ring] = (o as f32, (o * sin) as f32, (o * (1.0 - cos)) as f32);
        }
        Self {
            model,
            by_ring,
            sin_elevation,
            origin,
        }
    }

    /// The model.
    pub fn model(&self) -> Model {
        self.model
    }

    /// The laser id of `ring`.
    pub fn laser(&self, ring: u16) -> Option<u8> {
        (usize::from(ring) < self.model.lasers()).then(|| self.by_ring[usize::from(ring)])
    }

    /// `p` as the decoder's return in the LiDAR frame (x right = -y, y forward = x), fired
    /// `offset_ns` after its chunk's first return; checked to lie on its ring's cone.
    /// velodyne_pointcloud applies a laser's beam-origin offset `o` across the beam (its
    /// calibration model, rawdata.cpp: horizontal `d cos v - o sin v`, z `d sin v + o cos v`);
    /// the manual (and the decoder) add it to z only: undone here, so that a cloud's return is
    /// the packet's up to the driver's rounding.
    pub fn point(&self, p: &CloudPoint, offset_ns: u32) -> Result<Point, PointSkip> {
        let laser = self.laser(p.ring).ok_or(PointSkip::Ring)?;
        let ring = usize::from(p.ring);
        let (mut x, mut y, z) = (-p.y, p.x, p.z);
        let h = libm::sqrtf(x * x + y * y);
        let r = libm::sqrtf(h * h + z * z);
        if r.is_nan() || r <= 0.0 {
            return Err(PointSkip::NoRange);
        }
        if libm::fabsf(z / r - self.sin_elevation[ring]) > ELEVATION_TOLERANCE_SIN {
            return Err(PointSkip::Elevation);
        }
        let (o, o_sin, o_1mcos) = self.origin[ring];
        if h > 0.0 {
            let k = (h + o_sin) / h;
            x *= k;
            y *= k;
        }
        let z = z + o_1mcos;
        // The range is the beam's, from its origin (the decoder's distance).
        let range = libm::sqrtf(x * x + y * y + (z - o) * (z - o));
        let mut azimuth = libm::atan2f(x, y);
        if azimuth < 0.0 {
            azimuth += core::f32::consts::TAU;
        }
        let unit = self.model.distance_unit_m() as f32;
        Ok(Point {
            x,
            y,
            z,
            azimuth,
            offset_ns,
            distance_raw: libm::roundf(range / unit).clamp(1.0, 65_535.0) as u16,
            range,
            intensity: p.intensity.clamp(0.0, 255.0) as u8,
            block: 0,
            channel: laser,
            laser,
            ret: Return::Strongest,
        })
    }
}

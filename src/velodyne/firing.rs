//! Firing times, azimuth interpolation and the point in the sensor frame, for every
//! [`Model`].
//!
//! Manual appendix B (timing) and section 9.5 (azimuth interpolation), in the corrected form of
//! `docs/PROTOCOLS.md`, generalised over the models' tables ([`super::model`]):
//! - single return: offset(b, c) = T_block b + t_c; dual return: T_block floor(b/2) + t_c
//!   (blocks in pairs), with t_c the channel's firing time within its block;
//! - azimuth of a firing: A_b + gap_b t_c / T_block + o_l with
//!   gap_b = (A_{b+1} - A_b) mod 36000 (next pair in dual mode; the last reuses the previous)
//!   and o_l the laser's azimuth offset (VLP-32C);
//! - point (DESIGN.md, eq. 1 plus the beam-origin offset): x = d cos w sin t, y = d cos w cos t,
//!   z = d sin w + v_l, x right, y forward, z up, t clockwise from +y.
//!
//! No trig per point: cos w and sin w come from the model's table, sin t and cos t from one
//! `sincosf` per block rotated by the small in-block increment (a 5th-order series, exact to
//! 1e-9 rad for any real rotation rate and the VLP-32C's 4.2 deg offsets).

use super::data::field::{BLOCKS, CHANNELS};
use super::model::Model;
use super::{DataPacket, Error, ReturnMode};

/// Points a data packet can hold (12 blocks x 32 channels).
pub const POINTS_PER_PACKET: usize = BLOCKS * CHANNELS;

/// Duration of one VLP-16 laser firing, nanoseconds (manual appendix B).
pub const FIRING_NS: u32 = 2_304;
/// Duration of one VLP-16 16-laser firing sequence, nanoseconds.
pub const SEQUENCE_NS: u32 = 55_296;
/// Duration of one VLP-16 block (two sequences), nanoseconds.
pub const BLOCK_NS: u32 = 110_592;

/// Which return a point is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Return {
    /// Single-return mode, strongest.
    #[default]
    Strongest,
    /// Single-return mode, last.
    Last,
    /// Dual-return mode, the odd block: strongest (second strongest when the last is also the
    /// strongest).
    DualStrongest,
    /// Dual-return mode, the even block: last.
    DualLast,
}

impl Return {
    /// The name used in CSV output.
    pub fn name(self) -> &'static str {
        match self {
            Return::Strongest => "strongest",
            Return::Last => "last",
            Return::DualStrongest => "dual_strongest",
            Return::DualLast => "dual_last",
        }
    }

    /// The return a block holds in a given mode.
    pub fn of_block(mode: ReturnMode, block: usize) -> Self {
        match mode {
            ReturnMode::Strongest => Return::Strongest,
            ReturnMode::Last => Return::Last,
            ReturnMode::Dual if block.is_multiple_of(2) => Return::DualLast,
            ReturnMode::Dual => Return::DualStrongest,
        }
    }
}

/// Firing time of `channel` in `block` after the packet timestamp, in nanoseconds.
#[inline]
pub fn firing_offset_ns(model: Model, mode: ReturnMode, block: usize, channel: usize) -> u32 {
    let slot = match mode {
        ReturnMode::Dual => (block % BLOCKS) / 2,
        _ => block % BLOCKS,
    };
    slot as u32 * model.block_ns() + model.channels()[channel % CHANNELS].offset_ns
}

/// One laser return, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Point {
    /// x in the sensor frame (right), metres, [manual 9.5].
    pub x: f32,
    /// y in the sensor frame (forward), metres.
    pub y: f32,
    /// z in the sensor frame (up), metres, including the laser's vertical beam-origin offset.
    pub z: f32,
    /// Interpolated azimuth, radians in [0, 2 pi), clockwise from +y.
    pub azimuth: f32,
    /// Firing time after the packet timestamp, nanoseconds.
    pub offset_ns: u32,
    /// Raw distance in the model's units (2 mm; VLP-32C 4 mm; never 0 here).
    pub distance_raw: u16,
    /// Range [m].
    pub range: f32,
    /// Calibrated reflectivity.
    pub intensity: u8,
    /// Block 0..11.
    pub block: u8,
    /// Channel 0..31 of the block.
    pub channel: u8,
    /// Laser id (VLP-16: channel % 16; 32-laser models: the channel).
    pub laser: u8,
    /// Which return.
    pub ret: Return,
}

impl Point {
    /// Firing sequence 0 or 1 within the block (16-laser models; 0 on 32-laser ones).
    #[inline]
    pub fn sequence(&self) -> usize {
        usize::from(self.channel != self.laser)
    }
    /// Laser id (firing order).
    #[inline]
    pub fn laser(&self) -> usize {
        usize::from(self.laser)
    }
    /// Range in metres.
    #[inline]
    pub fn distance_m(&self) -> f32 {
        self.range
    }
}

/// Fixed-capacity output of [`decode`]: the returns of one packet.
#[derive(Debug, Clone)]
pub struct PointBuf {
    points: [Point; POINTS_PER_PACKET],
    len: usize,
}

impl Default for PointBuf {
    fn default() -> Self {
        Self::new()
    }
}

impl PointBuf {
    /// An empty buffer.
    pub const fn new() -> Self {
        const ZERO: Point = Point {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            azimuth: 0.0,
            offset_ns: 0,
            distance_raw: 0,
            range: 0.0,
            intensity: 0,
            block: 0,
            channel: 0,
            laser: 0,
            ret: Return::Strongest,
        };
        Self {
            points: [ZERO; POINTS_PER_PACKET],
            len: 0,
        }
    }
    /// The decoded points.
    #[inline]
    pub fn as_slice(&self) -> &[Point] {
        &self.points[..self.len]
    }
    /// Number of points.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }
    /// No points.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Empty it (another decoder's points follow: an Ouster's or a Hesai's).
    #[inline]
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Add a point; false (and not added) when the buffer is full.
    #[inline]
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
}

pub(super) const CDEG_TO_RAD: f32 = core::f32::consts::PI / 18_000.0;

const TWO_PI: f32 = core::f32::consts::TAU;
/// Above this block-to-block azimuth step (about 5.7 deg; a VLP-16 at 1200 rpm turns 0.8 deg per
/// block) the small-angle series is not used and each point gets an exact sincos.
const SERIES_MAX_GAP_RAD: f32 = 0.1;

/// A block's azimuth in 0.01 deg, 0..=35999: real units also send 36000, which the ROS driver
/// and velodyne_decoder read as 0 (PROTOCOLS.md).
#[inline]
pub(super) fn azimuth_cdeg<T: AsRef<[u8]>>(p: &DataPacket<T>, b: usize) -> u16 {
    let a = p.azimuth_raw(b);
    if a == 36_000 {
        0
    } else {
        a
    }
}

/// Fastest rotation any model is specified for (1200 rpm = 7200 deg/s) with a 50 % margin, in
/// 0.01 deg per ns of block duration.
const MAX_RATE_CDEG_PER_NS: f64 = 1.5 * 720_000.0 * 1e-9;

/// Azimuth step (0.01 deg) for each block, per PROTOCOLS.md: to the next block (single) or
/// next pair (dual); the last block or pair reuses the previous step. A step no rotation rate
/// can make in a block of `block_ns` (a block azimuth out of line with its neighbours, as a
/// stray 36000 is) is replaced by the median of the packet's plausible steps, so one bad
/// azimuth does not smear its neighbour's firings round the circle.
fn azimuth_gaps<T: AsRef<[u8]>>(
    p: &DataPacket<T>,
    mode: ReturnMode,
    block_ns: u32,
) -> [u16; BLOCKS] {
    let stride = if mode == ReturnMode::Dual { 2 } else { 1 };
    let max_gap = (MAX_RATE_CDEG_PER_NS * f64::from(block_ns)) as u16;
    let mut gaps = [0u16; BLOCKS];
    let mut plausible = [0u16; BLOCKS];
    let mut n_ok = 0;
    let mut last = 0u16;
    let mut b = 0;
    while b < BLOCKS {
        let next = b + stride;
        let gap = if next < BLOCKS {
            // Both in 0..36000: the step round the circle without a division.
            let g = 36_000 + u32::from(azimuth_cdeg(p, next)) - u32::from(azimuth_cdeg(p, b));
            last = if g >= 36_000 { g - 36_000 } else { g } as u16;
            if last <= max_gap {
                plausible[n_ok] = last;
                n_ok += 1;
            }
            last
        } else {
            last
        };
        for g in gaps.iter_mut().skip(b).take(stride) {
            *g = gap;
        }
        b = next;
    }
    // An implausible gap (a dropped block, the scan's seam) takes the plausible ones' median,
    // found only then (a sort per packet otherwise: most packets have none).
    if gaps.iter().any(|&g| g > max_gap) {
        let fallback = if n_ok == 0 {
            0
        } else {
            let v = &mut plausible[..n_ok];
            v.sort_unstable();
            v[n_ok / 2]
        };
        for g in gaps.iter_mut() {
            if *g > max_gap {
                *g = fallback;
            }
        }
    }
    gaps
}

#[inline(always)]
fn small_sincos(d: f32) -> (f32, f32) {
    let d2 = d * d;
    let s = d * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0)));
    let c = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)));
    (s, c)
}

/// Decode every non-zero return of a data packet into `out` (cleared first) as the model its
/// product byte names; returns the count. An unknown product byte is refused
/// ([`Error::UnknownProduct`]), never decoded as some other model; to choose the model (early
/// VLP-16 firmware writes the HDL-32E's 0x21) use [`decode_as`].
pub fn decode<T: AsRef<[u8]>>(packet: &DataPacket<T>, out: &mut PointBuf) -> Result<usize, Error> {
    out.len = 0;
    let found = packet.product_raw();
    let model = Model::from_product(found).ok_or(Error::UnknownProduct { found })?;
    decode_as(packet, model, out)
}

/// The packet's return mode and each block's azimuth gap ([`azimuth_gaps`]); fails on an
/// unknown return mode or a block azimuth above 36000.
pub(super) fn mode_and_gaps<T: AsRef<[u8]>>(
    packet: &DataPacket<T>,
    model: Model,
) -> Result<(ReturnMode, [u16; BLOCKS]), Error> {
    let mode = packet.return_mode()?;
    for b in 0..BLOCKS {
        let found = packet.azimuth_raw(b);
        if found > 36_000 {
            return Err(Error::BadAzimuth {
                block: b as u8,
                found,
            });
        }
    }
    Ok((mode, azimuth_gaps(packet, mode, model.block_ns())))
}

/// Decode every non-zero return of a data packet as `model` into `out` (cleared first); returns
/// the count.
///
/// Fails, leaving `out` empty, on an unknown return mode or a block azimuth above 36000 (36000
/// is 0). Block flags are checked by [`DataPacket::new_checked`].
pub fn decode_as<T: AsRef<[u8]>>(
    packet: &DataPacket<T>,
    model: Model,
    out: &mut PointBuf,
) -> Result<usize, Error> {
    out.len = 0;
    let (mode, gaps) = mode_and_gaps(packet, model)?;
    let channels = model.channels();
    let beams = model.beams();
    let unit = model.distance_unit_m() as f32;
    let block_ns = model.block_ns();
    let mut n = 0;
    for (b, &gap_cdeg) in gaps.iter().enumerate() {
        let a0 = f32::from(azimuth_cdeg(packet, b)) * CDEG_TO_RAD;
        let (sa, ca) = libm::sincosf(a0);
        let gap = f32::from(gap_cdeg) * CDEG_TO_RAD;
        let exact = gap > SERIES_MAX_GAP_RAD;
        let ret = Return::of_block(mode, b);
        let slot = if mode == ReturnMode::Dual { b / 2 } else { b };
        let block_base = slot as u32 * block_ns;
        for (ch, c) in channels.iter().enumerate() {
            let d = packet.distance_raw(b, ch);
            if d == 0 {
                continue;
            }
            let Some(beam) = beams.get(usize::from(c.laser)) else {
                continue;
            };
            // The firing sits `fraction` of the way to the next block; plus the laser's offset.
            let delta = gap * c.fraction + beam.azimuth_offset_deg as f32 * (CDEG_TO_RAD * 100.0);
            let (st, ct) = if exact {
                libm::sincosf(a0 + delta)
            } else {
                let (sd, cd) = small_sincos(delta);
                (sa * cd + ca * sd, ca * cd - sa * sd)
            };
            let r = f32::from(d) * unit;
            let rxy = r * beam.cos_el as f32;
            let az = a0 + delta;
            let az = if az >= TWO_PI {
                az - TWO_PI
            } else if az < 0.0 {
                az + TWO_PI
            } else {
                az
            };
            if let Some(slot) = out.points.get_mut(n) {
                *slot = Point {
                    x: rxy * st,
                    y: rxy * ct,
                    z: r * beam.sin_el as f32 + beam.vertical_offset_m as f32,
                    azimuth: az,
                    offset_ns: block_base + c.offset_ns,
                    distance_raw: d,
                    range: r,
                    intensity: packet.reflectivity(b, ch),
                    block: b as u8,
                    channel: ch as u8,
                    laser: c.laser,
                    ret,
                };
                n += 1;
            }
        }
    }
    out.len = n;
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::velodyne::data::DATA_PACKET_LEN;

    #[test]
    fn offsets_follow_the_timing_table() {
        // Manual appendix B, single return: block 1 sequence 1 laser 15 fires at
        // 110.592 + 55.296 + 15 * 2.304 = 200.448 us.
        let m = Model::Vlp16;
        assert_eq!(firing_offset_ns(m, ReturnMode::Strongest, 1, 31), 200_448);
        // Last firing of the packet: 11 * 110.592 + 55.296 + 34.56 = 1306.368 us.
        assert_eq!(firing_offset_ns(m, ReturnMode::Last, 11, 31), 1_306_368);
        // Dual: blocks 10 and 11 fire together, at pair 5.
        assert_eq!(firing_offset_ns(m, ReturnMode::Dual, 11, 0), 552_960);
        assert_eq!(firing_offset_ns(m, ReturnMode::Dual, 10, 0), 552_960);
        // HDL-32E: block 11, laser 31: 11 * 46.08 + 31 * 1.152 = 542.592 us.
        assert_eq!(
            firing_offset_ns(Model::Hdl32e, ReturnMode::Strongest, 11, 31),
            542_592
        );
        // VLP-32C: block 11, lasers 30/31: 11 * 55.296 + 15 * 2.304 = 642.816 us.
        assert_eq!(
            firing_offset_ns(Model::Vlp32c, ReturnMode::Strongest, 11, 30),
            642_816
        );
    }

    #[test]
    fn series_matches_libm() {
        let mut d = -0.1f32;
        while d <= 0.1 {
            let (s, c) = small_sincos(d);
            assert!(
                (s - libm::sinf(d)).abs() < 1e-7 && (c - libm::cosf(d)).abs() < 1e-7,
                "{d}"
            );
            d += 0.001;
        }
    }

    /// Each block's step to the next, the last block the one before's; across 0 deg round
    /// the circle; a step no rotation makes (a stray azimuth) the median of the plausible ones.
    #[test]
    fn azimuth_gaps_wrap_and_a_stray_takes_the_median() {
        let mut buf = [0u8; DATA_PACKET_LEN];
        let mut p = DataPacket::new_unchecked(&mut buf[..]);
        // 0.4 deg a block (VLP-16 at 600 rpm: 1.33 us per 0.01 deg), crossing 360 deg at
        // block 3 (36000 reads as 0), block 8 out of line.
        let az = [
            35_880, 35_920, 35_960, 36_000, 40, 80, 120, 160, 9_000, 240, 280, 320,
        ];
        for (b, a) in az.into_iter().enumerate() {
            p.set_flag(b);
            p.set_azimuth_raw(b, a);
        }
        p.set_return_mode(ReturnMode::Strongest);
        let p = DataPacket::new_checked(&buf[..]).unwrap();
        let gaps = azimuth_gaps(&p, ReturnMode::Strongest, Model::Vlp16.block_ns());
        assert_eq!(gaps, [40; BLOCKS], "{gaps:?}");
        // In line, no median is taken: the steps as they are.
        let mut buf = [0u8; DATA_PACKET_LEN];
        let mut q = DataPacket::new_unchecked(&mut buf[..]);
        for b in 0..BLOCKS {
            q.set_flag(b);
            q.set_azimuth_raw(b, ((35_990 + 39 * b as u32) % 36_000) as u16);
        }
        q.set_return_mode(ReturnMode::Strongest);
        let q = DataPacket::new_checked(&buf[..]).unwrap();
        assert_eq!(
            azimuth_gaps(&q, ReturnMode::Strongest, Model::Vlp16.block_ns()),
            [39; BLOCKS]
        );
    }

    #[test]
    fn wrong_return_mode_leaves_buffer_empty() {
        let mut buf = [0u8; DATA_PACKET_LEN];
        let mut p = DataPacket::new_unchecked(&mut buf[..]);
        for b in 0..12 {
            p.set_flag(b);
            p.set_channel(b, 0, 100, 1);
        }
        p.set_product_raw(0x22);
        buf[1204] = 0x00;
        let p = DataPacket::new_checked(&buf[..]).unwrap();
        let mut out = PointBuf::new();
        assert_eq!(
            decode(&p, &mut out),
            Err(Error::UnknownReturnMode { found: 0 })
        );
        assert!(out.is_empty());
    }
}

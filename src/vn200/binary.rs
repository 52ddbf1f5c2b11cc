//! VectorNav binary output frames (VN-200 user manual, "Binary Output Message Format";
//! PROTOCOLS.md): a checked view ([`Frame`]) and the emit side ([`emit`]).
//!
//! ```text
//! 0xFA | group byte(s) | one u16 LE mask per set group bit (+1 word if its bit 15) | payload | CRC
//! ```
//! The payload holds the fields group by group, bit by bit, without padding. The CRC is
//! CRC-16/XMODEM over everything after 0xFA, sent big-endian.

use super::fields::{Comp, FieldDef, Group, Size, Ty, GROUPS};
use super::Error;
use crate::time::GpsTime;

/// The sync byte.
pub const SYNC: u8 = 0xFA;

/// CRC-16/XMODEM (poly 0x1021, init 0, no reflection, no xorout), slice-by-16 tables.
pub const CRC16: crc::Crc<u16, crc::Table<16>> =
    crc::Crc::<u16, crc::Table<16>>::new(&crc::CRC_16_XMODEM);

/// The 8-bit XOR checksum of VectorNav ASCII and NMEA sentences.
pub fn xor8(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0, |a, &b| a ^ b)
}

/// Per group (index = group bit), the fields present as a 32-bit mask: bits 0..14 are the first
/// mask word, bits 16..30 the extension word (bit 15 is the extension flag on the wire and never
/// set here).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct Masks(pub [u32; GROUPS]);

impl Masks {
    /// Set a field present.
    pub fn with(mut self, group: Group, bit: u8) -> Self {
        if bit < 31 && bit != 15 {
            self.0[group as usize] |= 1 << bit;
        }
        self
    }

    /// Is a field present?
    pub fn has(&self, group: Group, bit: u8) -> bool {
        bit < 32 && self.0[group as usize] & (1 << bit) != 0
    }

    /// Bytes of the header on the wire (sync, group byte, mask words).
    pub fn header_len(&self) -> usize {
        1 + 1
            + self
                .0
                .iter()
                .map(|&m| {
                    if m == 0 {
                        0
                    } else if m >> 16 != 0 {
                        4
                    } else {
                        2
                    }
                })
                .sum::<usize>()
    }

    /// Fields present, in wire order.
    pub fn fields(&self) -> impl Iterator<Item = (Group, u8)> + '_ {
        Group::ALL
            .into_iter()
            .flat_map(move |g| bits(self.0[g as usize]).map(move |b| (g, b)))
    }
}

/// The set bits of a mask, lowest first.
fn bits(mut m: u32) -> impl Iterator<Item = u8> {
    core::iter::from_fn(move || {
        if m == 0 {
            return None;
        }
        let b = m.trailing_zeros() as u8;
        m &= m - 1;
        Some(b)
    })
}

/// Parse the header at the start of `bytes` (which begin with 0xFA): the masks and the header
/// length. `Error::Incomplete` if more bytes are needed to tell.
pub fn parse_header(bytes: &[u8]) -> Result<(Masks, usize), Error> {
    let mut at = 1;
    let groups = *bytes.get(at).ok_or(Error::Incomplete)?;
    at += 1;
    if groups & 0x80 != 0 {
        // A second group byte names groups 7.. which PROTOCOLS.md does not define.
        return Err(Error::UnknownGroup { byte: groups });
    }
    if groups == 0 {
        return Err(Error::NoGroups);
    }
    let mut masks = Masks::default();
    for g in 0..GROUPS {
        if groups & (1 << g) == 0 {
            continue;
        }
        let w0 = le_u16(bytes, at).ok_or(Error::Incomplete)?;
        at += 2;
        let mut m = u32::from(w0 & 0x7FFF);
        if w0 & 0x8000 != 0 {
            let w1 = le_u16(bytes, at).ok_or(Error::Incomplete)?;
            at += 2;
            if w1 & 0x8000 != 0 {
                return Err(Error::UnknownField {
                    group: g as u8,
                    bit: 31,
                });
            }
            m |= u32::from(w1) << 16;
        }
        masks.0[g] = m;
    }
    Ok((masks, at))
}

fn le_u16(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes([*b.get(at)?, *b.get(at + 1)?]))
}

/// Size of one field whose bytes start at `payload[at]` (variable fields read their count).
#[inline]
fn field_size(def: &FieldDef, payload: &[u8], at: usize) -> Result<usize, Error> {
    Ok(match def.size {
        Size::Fixed(n) => usize::from(n),
        Size::SatInfo => 2 + 8 * usize::from(*payload.get(at).ok_or(Error::Incomplete)?),
        Size::RawMeas => 12 + 28 * usize::from(*payload.get(at + 10).ok_or(Error::Incomplete)?),
    })
}

/// Where everything of a frame lies: its masks, where the payload and each group start, and its
/// total length (sync to CRC). One walk over the mask bits gives all of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// Fields present.
    pub masks: Masks,
    /// Offset of the payload.
    pub payload_at: usize,
    /// Offset of each group's first field.
    pub group_at: [u16; GROUPS],
    /// Total length, sync to CRC.
    pub len: usize,
}

/// The layout of the frame at the start of `bytes`, or `Error::Incomplete` if more bytes are
/// needed to know it.
pub fn layout(bytes: &[u8]) -> Result<Layout, Error> {
    let (masks, payload_at) = parse_header(bytes)?;
    let mut group_at = [0u16; GROUPS];
    let mut at = payload_at;
    for g in Group::ALL {
        group_at[g as usize] = at as u16;
        for bit in bits(masks.0[g as usize]) {
            let def = g.field(bit).ok_or(Error::UnknownField {
                group: g as u8,
                bit,
            })?;
            at += field_size(def, bytes, at)?;
        }
    }
    Ok(Layout {
        masks,
        payload_at,
        group_at,
        len: at + 2,
    })
}

/// Total frame length (sync to CRC) of the frame at the start of `bytes`, or
/// `Error::Incomplete` if more bytes are needed to know it.
pub fn frame_len(bytes: &[u8]) -> Result<usize, Error> {
    layout(bytes).map(|l| l.len)
}

/// A checked binary frame: header known, length exact, CRC verified.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    bytes: &'a [u8],
    masks: Masks,
    payload_at: usize,
    /// Byte offset of each group's first field (so a field lookup walks one group only).
    group_at: [u16; GROUPS],
}

/// One field of a frame.
#[derive(Debug, Clone, Copy)]
pub struct FieldRef<'a> {
    /// Its group.
    pub group: Group,
    /// Its mask bit.
    pub bit: u8,
    /// Its definition.
    pub def: &'static FieldDef,
    /// Its bytes.
    pub bytes: &'a [u8],
}

/// A decoded scalar.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    /// Unsigned integer.
    U(u64),
    /// Signed integer.
    I(i64),
    /// f32.
    F32(f32),
    /// f64.
    F64(f64),
}

impl Value {
    /// As f64 (integers converted).
    pub fn as_f64(self) -> f64 {
        match self {
            Value::U(v) => v as f64,
            Value::I(v) => v as f64,
            Value::F32(v) => f64::from(v),
            Value::F64(v) => v,
        }
    }
}

impl core::fmt::Display for Value {
    /// Shortest decimal that reads back to the same value.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Value::U(v) => write!(f, "{v}"),
            Value::I(v) => write!(f, "{v}"),
            Value::F32(v) => write!(f, "{v:?}"),
            Value::F64(v) => write!(f, "{v:?}"),
        }
    }
}

/// Read one little-endian scalar at `at` (None past the end).
#[inline]
pub fn read_scalar(b: &[u8], at: usize, ty: Ty) -> Option<Value> {
    let s = b.get(at..at + ty.size())?;
    Some(match ty {
        Ty::U8 => Value::U(u64::from(s[0])),
        Ty::I8 => Value::I(i64::from(s[0] as i8)),
        Ty::U16 => Value::U(u64::from(u16::from_le_bytes([s[0], s[1]]))),
        Ty::I16 => Value::I(i64::from(i16::from_le_bytes([s[0], s[1]]))),
        Ty::U32 => Value::U(u64::from(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))),
        Ty::U64 => Value::U(u64::from_le_bytes([
            s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7],
        ])),
        Ty::F32 => Value::F32(f32::from_le_bytes([s[0], s[1], s[2], s[3]])),
        Ty::F64 => Value::F64(f64::from_le_bytes([
            s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7],
        ])),
    })
}

impl<'a> FieldRef<'a> {
    /// The scalars of the field (for SatInfo/RawMeas: the fixed head).
    pub fn scalars(&self) -> impl Iterator<Item = (&'static Comp, Value)> + 'a {
        let bytes = self.bytes;
        let mut at = 0;
        self.def.comps.iter().filter_map(move |c| {
            let v = read_scalar(bytes, at, c.ty);
            at += c.ty.size();
            v.map(|v| (c, v))
        })
    }
}

impl<'a> Frame<'a> {
    /// Check a whole frame: sync byte, known header, exact length, CRC.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, Error> {
        if bytes.first() != Some(&SYNC) {
            return Err(Error::NoSync);
        }
        let l = match layout(bytes) {
            Err(Error::Incomplete) => {
                return Err(Error::Truncated {
                    expected: None,
                    got: bytes.len(),
                })
            }
            r => r?,
        };
        let len = l.len;
        if bytes.len() != len {
            return Err(Error::Truncated {
                expected: Some(len),
                got: bytes.len(),
            });
        }
        let sent = u16::from_be_bytes([bytes[len - 2], bytes[len - 1]]);
        let computed = CRC16.checksum(&bytes[1..len - 2]);
        if sent != computed {
            return Err(Error::Crc { computed, sent });
        }
        Ok(Self::from_layout(bytes, &l))
    }

    /// A frame whose layout and CRC the caller has checked (`bytes` is exactly `l.len` long).
    pub(crate) fn from_layout(bytes: &'a [u8], l: &Layout) -> Self {
        Self {
            bytes,
            masks: l.masks,
            payload_at: l.payload_at,
            group_at: l.group_at,
        }
    }

    /// All bytes, sync to CRC.
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// Which fields are present.
    pub fn masks(&self) -> &Masks {
        &self.masks
    }

    /// The group byte and mask words as they are on the wire.
    pub fn header_bytes(&self) -> &'a [u8] {
        &self.bytes[1..self.payload_at]
    }

    /// The fields, in wire order.
    pub fn fields(&self) -> impl Iterator<Item = FieldRef<'a>> + '_ {
        let bytes = self.bytes;
        let end = bytes.len() - 2;
        let mut at = self.payload_at;
        self.masks.fields().map_while(move |(group, bit)| {
            let def = group.field(bit)?;
            let n = field_size(def, bytes, at).ok()?;
            let field = bytes.get(at..(at + n).min(end))?;
            at += n;
            Some(FieldRef {
                group,
                bit,
                def,
                bytes: field,
            })
        })
    }

    /// The bytes of one field, if present.
    pub fn field(&self, group: Group, bit: u8) -> Option<&'a [u8]> {
        if !self.masks.has(group, bit) {
            return None;
        }
        let mut at = usize::from(self.group_at[group as usize]);
        for b in bits(self.masks.0[group as usize]) {
            let n = field_size(group.field(b)?, self.bytes, at).ok()?;
            if b == bit {
                return self.bytes.get(at..at + n);
            }
            at += n;
        }
        None
    }

    fn f32s<const N: usize>(&self, group: Group, bit: u8) -> Option<[f32; N]> {
        let b = self.field(group, bit)?;
        let mut out = [0f32; N];
        for (i, o) in out.iter_mut().enumerate() {
            *o = f32::from_le_bytes(b.get(4 * i..4 * i + 4)?.try_into().ok()?);
        }
        Some(out)
    }

    fn u64_field(&self, group: Group, bit: u8) -> Option<u64> {
        Some(u64::from_le_bytes(self.field(group, bit)?.try_into().ok()?))
    }

    /// GPS time: Common/Time TimeGps [ns since 1980-01-06, no leap seconds], else
    /// Time.GpsWeek * 604800 s + Time.GpsTow; `None` when the time is not a valid GPS time
    /// ([`GpsTime::is_valid`]).
    pub fn gps_time(&self) -> Option<GpsTime> {
        if let Some(ns) = self
            .u64_field(Group::Common, 1)
            .or_else(|| self.u64_field(Group::Time, 1))
        {
            return i64::try_from(ns).ok().and_then(GpsTime::checked);
        }
        let tow = self.u64_field(Group::Time, 2)?;
        let week = u16::from_le_bytes(self.field(Group::Time, 3)?.try_into().ok()?);
        GpsTime::from_week_tow_ns(week, tow)
    }

    /// The unit's free-running clock: Common/Time TimeStartup [ns since power-on] (VN-200
    /// manual, Common group bit 0 / Time group bit 0; PROTOCOLS.md). It keeps counting when
    /// the GPS time steps, so the two together tell a clock step from lost frames.
    pub fn time_startup(&self) -> Option<i64> {
        self.u64_field(Group::Common, 0)
            .or_else(|| self.u64_field(Group::Time, 0))
            .and_then(|ns| i64::try_from(ns).ok())
    }

    /// Yaw, pitch, roll [deg] from Common or Attitude.
    pub fn yaw_pitch_roll_deg(&self) -> Option<[f32; 3]> {
        self.f32s(Group::Common, 3)
            .or_else(|| self.f32s(Group::Attitude, 1))
    }

    /// Attitude quaternion (x, y, z, w: scalar last) from Common or Attitude.
    pub fn quaternion(&self) -> Option<[f32; 4]> {
        self.f32s(Group::Common, 4)
            .or_else(|| self.f32s(Group::Attitude, 2))
    }

    /// INS position: latitude, longitude [deg], ellipsoidal height [m] from Common.Position or
    /// Ins.PosLla (never the GNSS antenna's own fix).
    pub fn position_lla(&self) -> Option<[f64; 3]> {
        let b = self
            .field(Group::Common, 6)
            .or_else(|| self.field(Group::Ins, 1))?;
        let mut out = [0f64; 3];
        for (i, o) in out.iter_mut().enumerate() {
            *o = f64::from_le_bytes(b.get(8 * i..8 * i + 8)?.try_into().ok()?);
        }
        Some(out)
    }

    /// The INS filter's own attitude 1-sigma: Attitude.YprU, yaw, pitch, roll [deg]
    /// (PROTOCOLS.md, Attitude group bit 8); `None` when absent or not finite and >= 0.
    pub fn ypr_uncertainty_deg(&self) -> Option<[f32; 3]> {
        self.f32s::<3>(Group::Attitude, 8)
            .filter(|v| v.iter().all(|x| x.is_finite() && *x >= 0.0))
    }

    /// The INS filter's own position 1-sigma: Ins.PosU [m] (one number; PROTOCOLS.md, INS group
    /// bit 9); `None` when absent or not finite and >= 0.
    pub fn position_uncertainty_m(&self) -> Option<f32> {
        self.f32s::<1>(Group::Ins, 9)
            .map(|v| v[0])
            .filter(|x| x.is_finite() && *x >= 0.0)
    }

    /// INS status word from Common or Ins.
    pub fn ins_status(&self) -> Option<u16> {
        let b = self
            .field(Group::Common, 12)
            .or_else(|| self.field(Group::Ins, 0))?;
        Some(u16::from_le_bytes(b.try_into().ok()?))
    }
}

/// Write a frame: sync, group byte, masks, `payload` (the fields in wire order, already
/// encoded) and the CRC. Returns the frame length; fails if `out` is too small or the payload
/// length does not match what the masks (and variable-field counts) imply.
pub fn emit(out: &mut [u8], masks: &Masks, payload: &[u8]) -> Result<usize, Error> {
    let mut groups = 0u8;
    for (g, &m) in masks.0.iter().enumerate() {
        if m & 0x8000 != 0 || m & 0x8000_0000 != 0 {
            return Err(Error::UnknownField {
                group: g as u8,
                bit: 15,
            });
        }
        if m != 0 {
            groups |= 1 << g;
        }
    }
    if groups == 0 {
        return Err(Error::NoGroups);
    }
    let head = masks.header_len();
    let total = head + payload.len() + 2;
    if out.len() < total {
        return Err(Error::BufferTooSmall { needed: total });
    }
    out[0] = SYNC;
    out[1] = groups;
    let mut at = 2;
    for &m in masks.0.iter().filter(|&&m| m != 0) {
        let ext = m >> 16;
        let w0 = (m & 0x7FFF) as u16 | if ext != 0 { 0x8000 } else { 0 };
        out[at..at + 2].copy_from_slice(&w0.to_le_bytes());
        at += 2;
        if ext != 0 {
            out[at..at + 2].copy_from_slice(&(ext as u16).to_le_bytes());
            at += 2;
        }
    }
    out[at..at + payload.len()].copy_from_slice(payload);
    at += payload.len();
    let crc = CRC16.checksum(&out[1..at]);
    out[at..at + 2].copy_from_slice(&crc.to_be_bytes());
    match frame_len(&out[..total]) {
        Ok(n) if n == total => Ok(total),
        Ok(n) => Err(Error::Truncated {
            expected: Some(n),
            got: total,
        }),
        Err(Error::Incomplete) => Err(Error::Truncated {
            expected: None,
            got: total,
        }),
        Err(e) => Err(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_check_value() {
        // CRC-16/XMODEM check value (PROTOCOLS.md): "123456789" -> 0x31C3.
        assert_eq!(CRC16.checksum(b"123456789"), 0x31C3);
    }

    /// VectorNav programming library example: one 26-byte frame, worked out by hand from
    /// PROTOCOLS.md: group byte 0x01 (Common), mask 0x0009 (TimeStartup, YawPitchRoll).
    #[test]
    fn vnproglib_mock_frame_by_hand() {
        let bytes = [
            0xFA, 0x01, 0x09, 0x00, 0x70, 0x05, 0x00, 0x03, 0x0A, 0x00, 0x00, 0x00, 0x48, 0x0E,
            0x2C, 0x42, 0x08, 0x4C, 0x37, 0xC1, 0x10, 0x38, 0x8B, 0xC2, 0xD4, 0xCB,
        ];
        assert_eq!(frame_len(&bytes), Ok(1 + 1 + 2 + 8 + 12 + 2));
        let f = Frame::parse(&bytes).unwrap();
        // TimeStartup = 0x0000000A03000570 ns = 43000006000 ns.
        assert_eq!(f.u64_field(Group::Common, 0), Some(43_000_006_000));
        let ypr = f.yaw_pitch_roll_deg().unwrap();
        assert_eq!(
            ypr,
            [
                f32::from_bits(0x422C_0E48),
                f32::from_bits(0xC137_4C08),
                f32::from_bits(0xC28B_3810)
            ]
        );
        assert!((ypr[0] - 43.013_946).abs() < 1e-5);
        // Over the CRC too, the CRC is 0 (PROTOCOLS.md).
        assert_eq!(CRC16.checksum(&bytes[1..]), 0);
        let mut bad = bytes;
        bad[10] ^= 1;
        assert!(matches!(
            Frame::parse(&bad),
            Err(Error::Crc { sent: 0xD4CB, .. })
        ));
    }

    #[test]
    fn extension_word_addresses_fields_16_and_up() {
        // GNSS1 Status (field 17) and AltMsl (18): mask word 0x8000, extension 0x0006.
        let masks = Masks::default()
            .with(Group::Gnss1, 17)
            .with(Group::Gnss1, 18);
        let mut out = [0u8; 64];
        let payload = [0x34, 0x12, 0, 0, 0, 0, 0, 0, 0xF0, 0x3F];
        let n = emit(&mut out, &masks, &payload).unwrap();
        assert_eq!(&out[..6], &[0xFA, 0x08, 0x00, 0x80, 0x06, 0x00]);
        let f = Frame::parse(&out[..n]).unwrap();
        let fields: heapless::Vec<_, 4> = f.fields().map(|x| (x.def.name, x.bytes.len())).collect();
        assert_eq!(&fields[..], &[("Status", 2), ("AltMsl", 8)]);
        assert_eq!(f.field(Group::Gnss1, 18), Some(&payload[2..]));
    }

    #[test]
    fn the_ins_stated_uncertainties() {
        // Attitude YprU (bit 8, 3 x f32) and Ins PosU (bit 9, f32): group byte 0x30 (Attitude,
        // Ins), masks 0x0100 and 0x0200, the fields in group order.
        let masks = Masks::default()
            .with(Group::Attitude, 8)
            .with(Group::Ins, 9);
        let mut payload = [0u8; 16];
        for (i, v) in [0.2f32, 0.03, 0.025, 0.021].iter().enumerate() {
            payload[4 * i..4 * i + 4].copy_from_slice(&v.to_le_bytes());
        }
        let mut out = [0u8; 64];
        let n = emit(&mut out, &masks, &payload).unwrap();
        assert_eq!(&out[..6], &[0xFA, 0x30, 0x00, 0x01, 0x00, 0x02]);
        let f = Frame::parse(&out[..n]).unwrap();
        assert_eq!(f.ypr_uncertainty_deg(), Some([0.2, 0.03, 0.025]));
        assert_eq!(f.position_uncertainty_m(), Some(0.021));
        payload[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
        let n = emit(&mut out, &masks, &payload).unwrap();
        assert_eq!(
            Frame::parse(&out[..n]).unwrap().position_uncertainty_m(),
            None
        );
    }

    #[test]
    fn variable_fields_read_their_counts() {
        // SatInfo with 2 satellites: 2 + 16 bytes.
        let masks = Masks::default().with(Group::Gnss1, 14);
        let mut payload = [0u8; 18];
        payload[0] = 2;
        let mut out = [0u8; 64];
        let n = emit(&mut out, &masks, &payload).unwrap();
        assert_eq!(n, 1 + 1 + 2 + 18 + 2);
        assert_eq!(frame_len(&out[..4]), Err(Error::Incomplete));
        assert!(emit(&mut out, &masks, &payload[..17]).is_err());
    }

    #[test]
    fn headers_we_cannot_size_are_refused() {
        assert_eq!(parse_header(&[0xFA, 0x00]), Err(Error::NoGroups));
        assert_eq!(
            parse_header(&[0xFA, 0x81, 0x01]),
            Err(Error::UnknownGroup { byte: 0x81 })
        );
        // GNSS1 field 15 does not exist.
        assert_eq!(frame_len(&[0xFA, 0x08, 0x00, 0x80, 0x00, 0x00]), Ok(6 + 2));
        assert_eq!(
            frame_len(&[0xFA, 0x08, 0x00, 0x80, 0x00, 0x80]),
            Err(Error::UnknownField { group: 3, bit: 31 })
        );
        // Common bit 14 (TimeGpsPps, 8 bytes) exists; Time bit 10 does not.
        assert_eq!(frame_len(&[0xFA, 0x01, 0x00, 0x40]), Ok(4 + 8 + 2));
        assert_eq!(
            frame_len(&[0xFA, 0x02, 0x00, 0x04]),
            Err(Error::UnknownField { group: 1, bit: 10 })
        );
        assert_eq!(frame_len(&[0xFA]), Err(Error::Incomplete));
    }
}

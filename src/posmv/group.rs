//! The POS MV group (and message) frame: a checked view and the emit side (ICD 3.2.3,
//! Tables 2 and 3; messages: 4.3, Table 43).
//!
//! ```text
//! offset  size  field
//!      0     4  "$GRP" (a group) or "$MSG" (a control message)
//!      4     2  group / message ID, ushort LE
//!      6     2  byte count: every byte after this field (the group's length minus 8)
//!      8    26  time/distance fields (groups only): time 1, time 2, distance (f64 LE),
//!               time types (bits 0-3 time 1, 4-7 time 2), distance type
//!     34     n  data
//!        0..3   pad (zeros) so that the group's length is a multiple of 4
//!   L-4     2  checksum: the group's 16-bit LE words sum to 0
//!   L-2     2  "$#"
//! ```

use super::Error;
pub(crate) use crate::le::{le16, le32};

/// Byte layout of the frame (ICD Tables 2, 3).
pub mod field {
    use core::ops::Range;
    /// `$GRP` or `$MSG`.
    pub const START: Range<usize> = 0..4;
    /// Group or message ID.
    pub const ID: Range<usize> = 4..6;
    /// Byte count.
    pub const BYTE_COUNT: Range<usize> = 6..8;
    /// Header length (start, ID, byte count): the byte count excludes these.
    pub const HEADER: usize = 8;
    /// Time 1.
    pub const TIME1: Range<usize> = 8..16;
    /// Time 2.
    pub const TIME2: Range<usize> = 16..24;
    /// Distance tag.
    pub const DISTANCE: Range<usize> = 24..32;
    /// Time types.
    pub const TIME_TYPES: usize = 32;
    /// Distance type.
    pub const DISTANCE_TYPE: usize = 33;
    /// First data byte of a group.
    pub const DATA: usize = 34;
    /// Checksum and end.
    pub const FOOTER: usize = 4;
    /// The group start delimiter.
    pub const GROUP_START: [u8; 4] = *b"$GRP";
    /// The message start delimiter.
    pub const MESSAGE_START: [u8; 4] = *b"$MSG";
    /// The end delimiter.
    pub const END: [u8; 2] = *b"$#";
    /// The smallest byte count of a group: time/distance fields and footer.
    pub const MIN_GROUP_COUNT: u16 = 30;
    /// The smallest byte count of a message: a transaction number and footer.
    pub const MIN_MESSAGE_COUNT: u16 = 6;
}

/// A time base of the time/distance fields (Table 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TimeType {
    /// 0: seconds since POS power-on.
    Pos,
    /// 1: GPS seconds of the week.
    Gps,
    /// 2: UTC seconds of the week.
    Utc,
    /// 3: user time (time 2 only).
    User,
    /// Anything else.
    Other(u8),
}

impl TimeType {
    /// From its 4-bit code.
    pub fn from_code(c: u8) -> Self {
        match c & 0x0F {
            0 => TimeType::Pos,
            1 => TimeType::Gps,
            2 => TimeType::Utc,
            3 => TimeType::User,
            x => TimeType::Other(x),
        }
    }

    /// Its 4-bit code.
    pub fn code(self) -> u8 {
        match self {
            TimeType::Pos => 0,
            TimeType::Gps => 1,
            TimeType::Utc => 2,
            TimeType::User => 3,
            TimeType::Other(x) => x & 0x0F,
        }
    }
}

/// The time/distance fields every group carries (Table 3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeFields {
    /// Time 1 [s] in its time base (the data's time of validity; UTC by default).
    pub time1: f64,
    /// Time 2 [s] (POS time by default).
    pub time2: f64,
    /// Distance tag [m].
    pub distance: f64,
    /// Time 1's base.
    pub time1_type: TimeType,
    /// Time 2's base.
    pub time2_type: TimeType,
    /// Distance type: 0 none, 1 POS distance, 2 DMI.
    pub distance_type: u8,
}

impl Default for TimeFields {
    fn default() -> Self {
        Self {
            time1: 0.0,
            time2: 0.0,
            distance: 0.0,
            time1_type: TimeType::Utc,
            time2_type: TimeType::Pos,
            distance_type: 1,
        }
    }
}

#[inline]
pub(crate) fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(le32(b, at))
}

#[inline]
pub(crate) fn f64_at(b: &[u8], at: usize) -> f64 {
    let mut w = [0u8; 8];
    w.copy_from_slice(&b[at..at + 8]);
    f64::from_le_bytes(w)
}

/// The sum of a buffer's 16-bit little-endian words (an odd last byte counts as a low byte).
pub fn word_sum(b: &[u8]) -> u16 {
    let (words, rest) = b.as_chunks::<2>();
    let mut s = words
        .iter()
        .fold(0u16, |s, w| s.wrapping_add(u16::from_le_bytes(*w)));
    if let Some(&x) = rest.first() {
        s = s.wrapping_add(u16::from(x));
    }
    s
}

/// A checked view of one group or message.
///
/// Built with [`Group::new_checked`], every accessor is infallible.
#[derive(Debug, Clone, Copy)]
pub struct Group<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Group<T> {
    /// Wrap a buffer without checking it (accessors may panic on a short one).
    pub const fn new_unchecked(buffer: T) -> Self {
        Self { buffer }
    }

    /// Wrap a buffer holding at least one whole group or message, checking its start, byte
    /// count, end delimiter and checksum. Bytes past the group are ignored.
    pub fn new_checked(buffer: T) -> Result<Self, Error> {
        let g = Self::new_unchecked(buffer);
        let len = g.check_header()?;
        let b = g.buffer.as_ref();
        if b.len() < len {
            return Err(Error::Truncated {
                expected: Some(len),
                got: b.len(),
            });
        }
        let end = [b[len - 2], b[len - 1]];
        if end != field::END {
            return Err(Error::BadEnd { found: end });
        }
        let sum = word_sum(&b[..len]);
        if sum != 0 {
            return Err(Error::Checksum { sum });
        }
        Ok(g)
    }

    /// The start, and a byte count that can be a group's: the total length it implies.
    pub fn check_header(&self) -> Result<usize, Error> {
        header_len(self.buffer.as_ref())
    }

    /// A control message (`$MSG`) rather than a data group.
    pub fn is_message(&self) -> bool {
        self.buffer.as_ref()[field::START] == field::MESSAGE_START
    }

    /// Group or message ID.
    pub fn id(&self) -> u16 {
        le16(self.buffer.as_ref(), field::ID.start)
    }

    /// The byte count field.
    pub fn byte_count(&self) -> u16 {
        le16(self.buffer.as_ref(), field::BYTE_COUNT.start)
    }

    /// The whole group's length (byte count + 8).
    pub fn len(&self) -> usize {
        usize::from(self.byte_count()) + field::HEADER
    }

    /// Never empty (a checked group is at least 16 bytes).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The group's bytes.
    pub fn as_bytes(&self) -> &[u8] {
        &self.buffer.as_ref()[..self.len()]
    }

    /// The time/distance fields (a group's; a message has none and gives zeros).
    pub fn time_fields(&self) -> TimeFields {
        if self.is_message() {
            return TimeFields::default();
        }
        let b = self.buffer.as_ref();
        let types = b[field::TIME_TYPES];
        TimeFields {
            time1: f64_at(b, field::TIME1.start),
            time2: f64_at(b, field::TIME2.start),
            distance: f64_at(b, field::DISTANCE.start),
            time1_type: TimeType::from_code(types & 0x0F),
            time2_type: TimeType::from_code(types >> 4),
            distance_type: b[field::DISTANCE_TYPE],
        }
    }

    /// The data between the header (and, for a group, the time/distance fields) and the
    /// checksum, pad included.
    pub fn data(&self) -> &[u8] {
        let start = if self.is_message() {
            field::HEADER
        } else {
            field::DATA
        };
        &self.buffer.as_ref()[start..self.len() - field::FOOTER]
    }
}

/// The total length a header announces, after checking the start and that the byte count can
/// be a group's (or a message's).
pub fn header_len(b: &[u8]) -> Result<usize, Error> {
    if b.len() < field::HEADER {
        return Err(Error::Truncated {
            expected: None,
            got: b.len(),
        });
    }
    let start = &b[field::START];
    let min = if start == field::GROUP_START {
        field::MIN_GROUP_COUNT
    } else if start == field::MESSAGE_START {
        field::MIN_MESSAGE_COUNT
    } else {
        return Err(Error::NoStart);
    };
    let byte_count = le16(b, field::BYTE_COUNT.start);
    let len = usize::from(byte_count) + field::HEADER;
    if byte_count < min || !len.is_multiple_of(4) {
        return Err(Error::BadLength { byte_count });
    }
    Ok(len)
}

/// Write a frame: `start` (`$GRP` or `$MSG`), `id`, then `body` (for a group: the
/// time/distance fields and the data), the pad, the checksum and `$#`. Returns its length, or
/// `None` if `out` is too short or the frame would exceed a byte count's range.
pub fn emit_frame(start: [u8; 4], id: u16, body: &[u8], out: &mut [u8]) -> Option<usize> {
    let unpadded = field::HEADER + body.len() + field::FOOTER;
    let len = unpadded.div_ceil(4) * 4;
    let byte_count = u16::try_from(len - field::HEADER).ok()?;
    let o = out.get_mut(..len)?;
    o[field::START].copy_from_slice(&start);
    o[field::ID].copy_from_slice(&id.to_le_bytes());
    o[field::BYTE_COUNT].copy_from_slice(&byte_count.to_le_bytes());
    o[field::HEADER..field::HEADER + body.len()].copy_from_slice(body);
    o[field::HEADER + body.len()..len - field::FOOTER].fill(0);
    o[len - 4..len - 2].fill(0);
    o[len - 2..].copy_from_slice(&field::END);
    let sum = word_sum(o);
    o[len - 4..len - 2].copy_from_slice(&0u16.wrapping_sub(sum).to_le_bytes());
    Some(len)
}

/// Write a group `id` with its time/distance fields and `data` (pad and checksum added);
/// returns its length (see [`emit_frame`]). At most 256 bytes of data.
pub fn emit_group(id: u16, t: &TimeFields, data: &[u8], out: &mut [u8]) -> Option<usize> {
    let mut body = [0u8; 26 + 256];
    let n = 26 + data.len();
    if n > body.len() {
        return None;
    }
    body[0..8].copy_from_slice(&t.time1.to_le_bytes());
    body[8..16].copy_from_slice(&t.time2.to_le_bytes());
    body[16..24].copy_from_slice(&t.distance.to_le_bytes());
    body[24] = t.time1_type.code() | (t.time2_type.code() << 4);
    body[25] = t.distance_type;
    body[26..n].copy_from_slice(data);
    emit_frame(field::GROUP_START, id, &body[..n], out)
}

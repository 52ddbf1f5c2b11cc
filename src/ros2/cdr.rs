//! The CDR encoding ROS 2 messages are stored in (rosbag2, MCAP `cdr` encoding): OMG CDR (XCDR1)
//! with a 4-byte encapsulation header (`00 00` big endian, `00 01` little endian, then two option
//! bytes), each primitive aligned to its size (8 at most) from the end of that header; strings
//! are a `uint32` length counting the closing NUL, then the bytes and the NUL; a sequence is a
//! `uint32` count then its elements; a fixed array has no count (DDS-XTypes 1.3, 7.4.1;
//! PROTOCOLS.md "ROS 2 messages").

/// Why bytes are not the message expected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// The encapsulation header is not plain CDR (big or little endian): its first two bytes.
    Encapsulation([u8; 2]),
    /// The message ends before a field: its offset [bytes from the message's start] and what
    /// was expected there.
    Truncated {
        /// Offset of the field.
        offset: usize,
        /// The field.
        expected: &'static str,
    },
    /// A string without its closing NUL, or not UTF-8: its offset.
    BadString {
        /// Offset of the string's length.
        offset: usize,
    },
    /// A sequence longer than the bytes left could hold: its offset and count.
    BadCount {
        /// Offset of the count.
        offset: usize,
        /// The count.
        count: u32,
    },
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::Encapsulation(b) => write!(
                f,
                "not a CDR message: encapsulation {:02x} {:02x} (expected 00 00 or 00 01)",
                b[0], b[1]
            ),
            Error::Truncated { offset, expected } => {
                write!(
                    f,
                    "the message ends at byte {offset}, before its {expected}"
                )
            }
            Error::BadString { offset } => {
                write!(f, "byte {offset}: a string without its NUL or not UTF-8")
            }
            Error::BadCount { offset, count } => write!(
                f,
                "byte {offset}: a sequence of {count} elements, more than the message holds"
            ),
        }
    }
}

/// The encapsulation header's length.
pub const HEADER: usize = 4;

/// A cursor over one CDR message.
#[derive(Debug, Clone)]
pub struct Reader<'a> {
    b: &'a [u8],
    at: usize,
    little: bool,
}

impl<'a> Reader<'a> {
    /// After the encapsulation header of `b`.
    pub fn new(b: &'a [u8]) -> Result<Self, Error> {
        let h = b.get(..HEADER).ok_or(Error::Truncated {
            offset: 0,
            expected: "encapsulation header",
        })?;
        let little = match [h[0], h[1]] {
            [0, 1] => true,
            [0, 0] => false,
            other => return Err(Error::Encapsulation(other)),
        };
        Ok(Self {
            b,
            at: HEADER,
            little,
        })
    }

    /// Offset of the next byte [from the message's start].
    pub fn offset(&self) -> usize {
        self.at
    }

    /// Bytes left.
    pub fn remaining(&self) -> usize {
        self.b.len().saturating_sub(self.at)
    }

    /// `n` bytes aligned to `align` (from the end of the encapsulation header).
    fn take(&mut self, n: usize, align: usize, expected: &'static str) -> Result<&'a [u8], Error> {
        let pad = (align - (self.at - HEADER) % align) % align;
        let start = self.at + pad;
        let end = start.checked_add(n).filter(|e| *e <= self.b.len());
        match end {
            Some(end) => {
                self.at = end;
                Ok(&self.b[start..end])
            }
            None => Err(Error::Truncated {
                offset: start.min(self.b.len()),
                expected,
            }),
        }
    }

    fn array<const N: usize>(&mut self, expected: &'static str) -> Result<[u8; N], Error> {
        let s = self.take(N, N, expected)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        if !self.little {
            a.reverse();
        }
        Ok(a)
    }

    /// A `uint8` (or `byte`, `char`).
    pub fn u8(&mut self, expected: &'static str) -> Result<u8, Error> {
        Ok(self.take(1, 1, expected)?[0])
    }

    /// A `bool` (any non-zero byte is true).
    pub fn bool(&mut self, expected: &'static str) -> Result<bool, Error> {
        Ok(self.u8(expected)? != 0)
    }

    /// A `uint16`.
    pub fn u16(&mut self, expected: &'static str) -> Result<u16, Error> {
        Ok(u16::from_le_bytes(self.array(expected)?))
    }

    /// A `uint32`.
    pub fn u32(&mut self, expected: &'static str) -> Result<u32, Error> {
        Ok(u32::from_le_bytes(self.array(expected)?))
    }

    /// An `int32`.
    pub fn i32(&mut self, expected: &'static str) -> Result<i32, Error> {
        Ok(i32::from_le_bytes(self.array(expected)?))
    }

    /// A `uint64`.
    pub fn u64(&mut self, expected: &'static str) -> Result<u64, Error> {
        Ok(u64::from_le_bytes(self.array(expected)?))
    }

    /// A `float32`.
    pub fn f32(&mut self, expected: &'static str) -> Result<f32, Error> {
        Ok(f32::from_le_bytes(self.array(expected)?))
    }

    /// A `float64`.
    pub fn f64(&mut self, expected: &'static str) -> Result<f64, Error> {
        Ok(f64::from_le_bytes(self.array(expected)?))
    }

    /// Three `float64` (a `geometry_msgs` Vector3 or Point).
    pub fn f64x3(&mut self, expected: &'static str) -> Result<[f64; 3], Error> {
        Ok([
            self.f64(expected)?,
            self.f64(expected)?,
            self.f64(expected)?,
        ])
    }

    /// A `string` (without its NUL).
    pub fn string(&mut self, expected: &'static str) -> Result<&'a str, Error> {
        let offset = self.at;
        let n = self.u32(expected)? as usize;
        let s = self.take(n, 1, expected)?;
        match s.split_last() {
            Some((0, body)) => core::str::from_utf8(body).map_err(|_| Error::BadString { offset }),
            _ => Err(Error::BadString { offset }),
        }
    }

    /// A sequence's count, checked against the bytes left for elements of at least
    /// `min_element` bytes each.
    pub fn count(&mut self, min_element: usize, expected: &'static str) -> Result<u32, Error> {
        let offset = self.at;
        let count = self.u32(expected)?;
        if (count as usize).saturating_mul(min_element.max(1)) > self.remaining() {
            return Err(Error::BadCount { offset, count });
        }
        Ok(count)
    }

    /// `n` raw bytes (a `uint8[n]` array or sequence's elements).
    pub fn bytes(&mut self, n: usize, expected: &'static str) -> Result<&'a [u8], Error> {
        self.take(n, 1, expected)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_is_from_the_end_of_the_header() {
        // uint8 1, then a uint32 at 4 (padding 3), a uint64 at 8, big endian too.
        let le = [
            0, 1, 0, 0, 1, 0xAA, 0xAA, 0xAA, 2, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0,
        ];
        let mut r = Reader::new(&le).unwrap();
        assert_eq!(r.u8("a"), Ok(1));
        assert_eq!(r.u32("b"), Ok(2));
        assert_eq!(r.u64("c"), Ok(3));
        assert_eq!(r.remaining(), 0);
        let be = [0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 2];
        let mut r = Reader::new(&be).unwrap();
        assert_eq!(r.u8("a"), Ok(1));
        assert_eq!(r.u32("b"), Ok(2));
    }

    #[test]
    fn bad_input_is_named() {
        assert_eq!(
            Reader::new(&[0, 7, 0, 0]).unwrap_err(),
            Error::Encapsulation([0, 7])
        );
        let mut r = Reader::new(&[0, 1, 0, 0, 1, 0]).unwrap();
        assert_eq!(
            r.u32("count"),
            Err(Error::Truncated {
                offset: 4,
                expected: "count"
            })
        );
        // A string whose length runs past the end, one without its NUL.
        let mut r = Reader::new(&[0, 1, 0, 0, 9, 0, 0, 0, b'a', 0]).unwrap();
        assert!(matches!(r.string("s"), Err(Error::Truncated { .. })));
        let mut r = Reader::new(&[0, 1, 0, 0, 1, 0, 0, 0, b'a']).unwrap();
        assert_eq!(r.string("s"), Err(Error::BadString { offset: 4 }));
        // A count no message of this length holds.
        let mut r = Reader::new(&[0, 1, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF, 0]).unwrap();
        assert_eq!(
            r.count(1, "n"),
            Err(Error::BadCount {
                offset: 4,
                count: u32::MAX
            })
        );
    }
}

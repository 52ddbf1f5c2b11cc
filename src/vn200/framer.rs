//! The streaming framer: bytes in any chunking -> binary frames, `$VN` sentences, NMEA
//! sentences, and reported errors. Fixed buffer, no heap.
//!
//! Resynchronisation: at every byte that is not part of an accepted item the framer looks for a
//! 0xFA or a `$`. A binary candidate is accepted only when its header is known, all its bytes
//! are there and its CRC-16 matches; if the CRC fails the framer moves on by ONE byte, never by
//! the candidate's length, so a frame that starts inside a corrupt or foreign run (or right
//! after a frame whose CRC byte is 0xFA) is still found.

use super::ascii::{self, Sentence, MAX_SENTENCE};
use super::binary::{layout, Frame, Layout, CRC16, SYNC};
use super::Error;
use crate::framing::{FixedBuffer, StreamBuffer};

/// What the framer found, and where it starts in the stream.
#[derive(Debug, Clone, Copy)]
pub struct Framed<'a> {
    /// Byte offset of its first byte (0xFA or `$`) since the framer was created.
    pub offset: u64,
    /// The item.
    pub item: Item<'a>,
}

/// One framed item.
#[derive(Debug, Clone, Copy)]
pub enum Item<'a> {
    /// A binary frame with a valid CRC.
    Binary(Frame<'a>),
    /// A `$VN` sentence with a valid checksum.
    Ascii(Sentence<'a>),
    /// Another device's sentence with a valid checksum (hand it to [`ascii::parse_nmea`]).
    Nmea(Sentence<'a>),
    /// A frame or sentence rejected for its checksum.
    Error(Error),
}

/// Counts of everything the framer saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Binary frames accepted.
    pub frames: u64,
    /// Binary candidates whose CRC failed.
    pub crc_failures: u64,
    /// 0xFA bytes whose header names nothing we can size.
    pub bad_headers: u64,
    /// Candidates longer than the buffer.
    pub too_long: u64,
    /// `$VN` sentences accepted.
    pub ascii: u64,
    /// Sentences whose checksum failed.
    pub ascii_bad_checksum: u64,
    /// Other sentences accepted (checksum valid).
    pub nmea: u64,
    /// Of those, how many the `nmea` crate could decode.
    pub nmea_decoded: u64,
    /// Bytes that were part of no accepted item.
    pub skipped_bytes: u64,
}

/// The streaming framer over a fixed `N`-byte buffer (at least 512; the longest binary frame it
/// can accept is `N` bytes).
#[derive(Debug, Clone)]
pub struct Framer<const N: usize = 8192> {
    stream: StreamBuffer<FixedBuffer<N>>,
    stats: Stats,
}

impl<const N: usize> Default for Framer<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// What the bytes at a range (consumed, or the one skipped byte of a rejected candidate) are.
enum Found {
    Binary(Layout),
    /// The line without its CR LF.
    Line,
    Rejected(Error),
}

impl<const N: usize> Framer<N> {
    /// An empty framer.
    pub const fn new() -> Self {
        const { assert!(N >= 2 * MAX_SENTENCE, "framer buffer too small") };
        Self {
            stream: StreamBuffer::fixed(),
            stats: Stats {
                frames: 0,
                crc_failures: 0,
                bad_headers: 0,
                too_long: 0,
                ascii: 0,
                ascii_bad_checksum: 0,
                nmea: 0,
                nmea_decoded: 0,
                skipped_bytes: 0,
            },
        }
    }

    /// Counts so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Bytes buffered and not yet framed.
    pub fn pending(&self) -> usize {
        self.stream.pending()
    }

    /// Copy in as many bytes as fit; returns how many were taken. Call [`Self::next`] until it
    /// returns `None` before pushing the rest.
    pub fn push(&mut self, data: &[u8]) -> usize {
        self.stream.push(data)
    }

    /// No more bytes will come: what is left is framed as far as it goes and the rest skipped.
    pub fn finish(&mut self) {
        self.stream.finish();
    }

    /// Feed `data` and hand every item to `f` (the whole-buffer convenience).
    pub fn consume(&mut self, mut data: &[u8], mut f: impl FnMut(Framed<'_>)) {
        loop {
            let n = self.push(data);
            data = &data[n..];
            while let Some(item) = self.next() {
                f(item);
            }
            if data.is_empty() {
                return;
            }
        }
    }

    /// Skip `n` bytes (counted); returns where they were.
    fn skip(&mut self, n: usize) -> core::ops::Range<usize> {
        let r = self.stream.take(n);
        self.stats.skipped_bytes += r.len() as u64;
        r
    }

    /// The next item from the buffered bytes, or `None` when more bytes are needed (or, after
    /// [`Self::finish`], when all is done).
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Option<Framed<'_>> {
        let eof = self.stream.is_finished();
        let (start, found) = loop {
            if self.stream.settle() {
                return None;
            }
            let full = self.stream.is_full();
            let avail = self.stream.unconsumed();
            match avail[0] {
                SYNC => match layout(avail).map(|l| (l.len, l)) {
                    Err(Error::Incomplete) => {
                        if eof || full {
                            self.skip(1);
                            continue;
                        }
                        return None;
                    }
                    Err(_) => {
                        self.stats.bad_headers += 1;
                        self.skip(1);
                    }
                    Ok((l, _)) if l > N => {
                        self.stats.too_long += 1;
                        self.skip(1);
                    }
                    Ok((l, _)) if l > avail.len() => {
                        if eof {
                            self.skip(1);
                            continue;
                        }
                        return None;
                    }
                    Ok((l, lay)) => {
                        let sent = u16::from_be_bytes([avail[l - 2], avail[l - 1]]);
                        let computed = CRC16.checksum(&avail[1..l - 2]);
                        if sent == computed {
                            self.stats.frames += 1;
                            break (self.stream.take(l), Found::Binary(lay));
                        }
                        self.stats.crc_failures += 1;
                        break (self.skip(1), Found::Rejected(Error::Crc { computed, sent }));
                    }
                },
                b'$' => {
                    let window = &avail[..avail.len().min(MAX_SENTENCE + 2)];
                    let mut end = None;
                    let mut broken = false;
                    for (i, &c) in window.iter().enumerate() {
                        if c == b'\n' {
                            end = Some(i);
                            break;
                        }
                        if !(0x20..0x7F).contains(&c) && c != b'\r' {
                            broken = true;
                            break;
                        }
                    }
                    let (end, consumed) = match end {
                        Some(i) => (i, i + 1),
                        // Too long only once the whole window (the longest line, CR, LF) is seen.
                        None if broken || window.len() >= MAX_SENTENCE + 2 => {
                            self.skip(1);
                            continue;
                        }
                        None if eof => (window.len(), window.len()),
                        None => return None,
                    };
                    let line_end = if end > 0 && avail[end - 1] == b'\r' {
                        end - 1
                    } else {
                        end
                    };
                    match ascii::parse(&avail[..line_end]) {
                        Ok(s) => {
                            if s.is_vn() {
                                self.stats.ascii += 1;
                            } else {
                                self.stats.nmea += 1;
                                if ascii::parse_nmea(s.line()).is_some() {
                                    self.stats.nmea_decoded += 1;
                                }
                            }
                            let r = self.stream.take(consumed);
                            break (r.start..r.start + line_end, Found::Line);
                        }
                        Err(e @ Error::AsciiChecksum { .. }) => {
                            self.stats.ascii_bad_checksum += 1;
                            break (self.skip(1), Found::Rejected(e));
                        }
                        Err(_) => {
                            self.skip(1);
                        }
                    }
                }
                _ => {
                    // Foreign bytes: jump to the next possible start in one step.
                    let n = avail
                        .iter()
                        .position(|&b| b == SYNC || b == b'$')
                        .unwrap_or(avail.len());
                    self.skip(n);
                }
            }
        };
        let offset = self.stream.offset(start.start);
        let item = match found {
            Found::Binary(l) => Item::Binary(Frame::from_layout(self.stream.get(start), &l)),
            Found::Line => match ascii::parse(self.stream.get(start)) {
                Ok(s) if s.is_vn() => Item::Ascii(s),
                Ok(s) => Item::Nmea(s),
                Err(e) => Item::Error(e),
            },
            Found::Rejected(e) => Item::Error(e),
        };
        Some(Framed { offset, item })
    }
}

//! The streaming framer: bytes in any chunking (UDP datagrams, a TCP stream, a logged `.000`
//! file) -> checked groups and messages, and the rejected ones reported. Fixed buffer, no heap.
//!
//! Resynchronisation: a candidate starts at every `$GRP` or `$MSG`; it is accepted only when
//! its byte count can be a group's, all its bytes are there, it ends with `$#` and its 16-bit
//! words sum to zero (ICD 3.2.3). A rejected candidate moves the framer on by ONE byte, never
//! by its length, so a group starting inside a corrupt or foreign run is still found.

use super::group::{header_len, Group};
use super::Error;
use crate::framing::{FixedBuffer, StreamBuffer};

/// What the framer found, and where it starts in the stream.
#[derive(Debug, Clone, Copy)]
pub struct Framed<'a> {
    /// Byte offset of its first byte since the framer was created.
    pub offset: u64,
    /// The item.
    pub item: Item<'a>,
}

/// One framed item.
#[derive(Debug, Clone, Copy)]
pub enum Item<'a> {
    /// A data group (`$GRP`) with a valid checksum.
    Group(Group<&'a [u8]>),
    /// A control message (`$MSG`) with a valid checksum.
    Message(Group<&'a [u8]>),
    /// A candidate rejected for its end delimiter or checksum.
    Error(Error),
}

/// Counts of everything the framer saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Groups accepted.
    pub groups: u64,
    /// Messages accepted.
    pub messages: u64,
    /// Candidates whose checksum failed.
    pub checksum_failures: u64,
    /// Candidates without the `$#` end where their byte count puts it.
    pub bad_ends: u64,
    /// Starts followed by a byte count no group can have.
    pub bad_lengths: u64,
    /// Candidates longer than the buffer.
    pub too_long: u64,
    /// Bytes that were part of no accepted item.
    pub skipped_bytes: u64,
}

/// The streaming framer over a fixed `N`-byte buffer (the longest group it accepts is `N`
/// bytes; 8192 holds every fixed-size group of the ICD, Group 8's 4856 the longest).
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

impl<const N: usize> Framer<N> {
    /// An empty framer.
    pub const fn new() -> Self {
        const { assert!(N >= 256, "framer buffer too small") };
        Self {
            stream: StreamBuffer::fixed(),
            stats: Stats {
                groups: 0,
                messages: 0,
                checksum_failures: 0,
                bad_ends: 0,
                bad_lengths: 0,
                too_long: 0,
                skipped_bytes: 0,
            },
        }
    }

    /// Counts so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Copy in as many bytes as fit; returns how many were taken. Call [`Self::next`] until it
    /// returns `None` before pushing the rest.
    pub fn push(&mut self, data: &[u8]) -> usize {
        self.stream.push(data)
    }

    /// No more bytes will come: what is left is framed as far as it goes, the rest skipped.
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
        let (at, err) = loop {
            if self.stream.settle() {
                return None;
            }
            let full = self.stream.is_full();
            let avail = self.stream.unconsumed();
            // Garbage up to the next '$' in one step.
            let Some(d) = avail.iter().position(|&c| c == b'$') else {
                let n = avail.len();
                self.skip(n);
                continue;
            };
            if d > 0 {
                self.skip(d);
                continue;
            }
            let prefix = &avail[..avail.len().min(4)];
            if !b"$GRP".starts_with(prefix) && !b"$MSG".starts_with(prefix) {
                self.skip(1);
                continue;
            }
            let len = match header_len(avail) {
                Ok(l) => l,
                Err(Error::Truncated { .. }) => {
                    if eof || full {
                        self.skip(1);
                        continue;
                    }
                    return None;
                }
                Err(_) => {
                    self.stats.bad_lengths += 1;
                    self.skip(1);
                    continue;
                }
            };
            if len > N {
                self.stats.too_long += 1;
                self.skip(1);
                continue;
            }
            if len > avail.len() {
                if eof {
                    self.skip(1);
                    continue;
                }
                return None;
            }
            match Group::new_checked(&avail[..len]) {
                Ok(_) => break (self.stream.take(len), None),
                Err(e) => {
                    match e {
                        Error::Checksum { .. } => self.stats.checksum_failures += 1,
                        _ => self.stats.bad_ends += 1,
                    }
                    break (self.skip(1), Some(e));
                }
            }
        };
        let offset = self.stream.offset(at.start);
        if let Some(e) = err {
            return Some(Framed {
                offset,
                item: Item::Error(e),
            });
        }
        let g = Group::new_unchecked(self.stream.get(at));
        let item = if g.is_message() {
            self.stats.messages += 1;
            Item::Message(g)
        } else {
            self.stats.groups += 1;
            Item::Group(g)
        };
        Some(Framed { offset, item })
    }
}

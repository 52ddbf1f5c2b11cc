//! The byte store under both INS framers (VN-200, POS MV): a buffer trait and a fixed-size
//! implementation (ublox's `parser/buffer.rs` pattern: `UnderlyingBuffer`, `FixedBuffer<N>`),
//! and the stream cursor the framers share: bytes pushed in any chunking, consumed from the
//! front one item or one skipped byte at a time, every byte's offset since the stream began.
//! No heap: the consumed bytes are dropped only when a push needs their room.

use core::ops::{Index, Range};

/// A byte buffer a framer owns or borrows.
pub trait UnderlyingBuffer: Index<Range<usize>, Output = [u8]> {
    /// Forget every byte.
    fn clear(&mut self);
    /// Bytes held.
    fn len(&self) -> usize;
    /// Whether no byte is held.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The most bytes it can hold.
    fn max_capacity(&self) -> usize;
    /// Copy in as much of `other` as fits; returns how many bytes were *not* copied.
    fn extend_from_slice(&mut self, other: &[u8]) -> usize;
    /// Drop the first `count` bytes (all of them if `count` is larger).
    fn drain(&mut self, count: usize);
}

/// An `N`-byte array as an [`UnderlyingBuffer`].
#[derive(Debug, Clone)]
pub struct FixedBuffer<const N: usize> {
    buf: [u8; N],
    len: usize,
}

impl<const N: usize> FixedBuffer<N> {
    /// Empty.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
        }
    }
}

impl<const N: usize> Default for FixedBuffer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Index<Range<usize>> for FixedBuffer<N> {
    type Output = [u8];
    fn index(&self, r: Range<usize>) -> &[u8] {
        &self.buf[..self.len][r]
    }
}

impl<const N: usize> UnderlyingBuffer for FixedBuffer<N> {
    fn clear(&mut self) {
        self.len = 0;
    }
    fn len(&self) -> usize {
        self.len
    }
    fn max_capacity(&self) -> usize {
        N
    }
    fn extend_from_slice(&mut self, other: &[u8]) -> usize {
        let n = other.len().min(N - self.len);
        self.buf[self.len..self.len + n].copy_from_slice(&other[..n]);
        self.len += n;
        other.len() - n
    }
    fn drain(&mut self, count: usize) {
        let count = count.min(self.len);
        self.buf.copy_within(count..self.len, 0);
        self.len -= count;
    }
}

/// A stream over an [`UnderlyingBuffer`]: the unconsumed bytes, their offset in the stream,
/// and whether the input has ended.
#[derive(Debug, Clone)]
pub struct StreamBuffer<B> {
    buf: B,
    /// Buffer index of the first unconsumed byte.
    pos: usize,
    /// Stream offset of the buffer's first byte.
    base: u64,
    eof: bool,
}

impl<const N: usize> StreamBuffer<FixedBuffer<N>> {
    /// A stream starting at offset 0 over an empty `N`-byte array.
    pub const fn fixed() -> Self {
        Self {
            buf: FixedBuffer::new(),
            pos: 0,
            base: 0,
            eof: false,
        }
    }
}

impl<B: UnderlyingBuffer> StreamBuffer<B> {
    /// A stream starting at offset 0 over `buf` (emptied).
    pub fn new(mut buf: B) -> Self {
        buf.clear();
        Self {
            buf,
            pos: 0,
            base: 0,
            eof: false,
        }
    }

    /// Copy in as many bytes as fit (dropping consumed bytes first if that makes room);
    /// returns how many were taken.
    pub fn push(&mut self, data: &[u8]) -> usize {
        if self.pos > 0 && self.buf.len() + data.len() > self.buf.max_capacity() {
            self.buf.drain(self.pos);
            self.base += self.pos as u64;
            self.pos = 0;
        }
        data.len() - self.buf.extend_from_slice(data)
    }

    /// No more bytes will come.
    pub fn finish(&mut self) {
        self.eof = true;
    }

    /// Whether [`Self::finish`] was called.
    pub fn is_finished(&self) -> bool {
        self.eof
    }

    /// Bytes pushed and not yet consumed.
    pub fn pending(&self) -> usize {
        self.buf.len() - self.pos
    }

    /// When every byte is consumed, empty the buffer and say so (`true`); otherwise `false`.
    pub fn settle(&mut self) -> bool {
        if self.pos < self.buf.len() {
            return false;
        }
        self.base += self.buf.len() as u64;
        self.pos = 0;
        self.buf.clear();
        true
    }

    /// The unconsumed bytes.
    pub fn unconsumed(&self) -> &[u8] {
        &self.buf[self.pos..self.buf.len()]
    }

    /// Whether the unconsumed bytes fill the buffer (no push can add to them).
    pub fn is_full(&self) -> bool {
        self.pending() >= self.buf.max_capacity()
    }

    /// Consume `n` bytes (at most the pending ones); returns their buffer range, valid until
    /// the next push.
    pub fn take(&mut self, n: usize) -> Range<usize> {
        let start = self.pos;
        self.pos += n.min(self.pending());
        start..self.pos
    }

    /// The stream offset of buffer index `i`.
    pub fn offset(&self, i: usize) -> u64 {
        self.base + i as u64
    }

    /// Bytes at a buffer range (from [`Self::take`]).
    pub fn get(&self, r: Range<usize>) -> &[u8] {
        &self.buf[r]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_buffer_fills_drains_and_says_what_did_not_fit() {
        let mut b = FixedBuffer::<4>::new();
        assert_eq!(b.extend_from_slice(b"abc"), 0);
        assert_eq!(b.extend_from_slice(b"def"), 2);
        assert_eq!(&b[0..4], b"abcd");
        b.drain(3);
        assert_eq!(&b[0..1], b"d");
        b.drain(9);
        assert!(b.is_empty());
    }

    #[test]
    fn stream_offsets_survive_compaction() {
        let mut s = StreamBuffer::new(FixedBuffer::<8>::new());
        assert_eq!(s.push(b"0123456789"), 8);
        let r = s.take(3);
        assert_eq!((s.offset(r.start), s.get(r)), (0, &b"012"[..]));
        // A push that needs room drops the consumed bytes; offsets keep counting.
        assert_eq!(s.push(b"89"), 2);
        assert_eq!(s.unconsumed(), b"3456789");
        let r = s.take(2);
        assert_eq!((s.offset(r.start), s.get(r)), (3, &b"34"[..]));
        assert!(!s.settle());
        let r = s.take(100);
        assert_eq!(s.get(r), b"56789");
        assert!(s.settle());
        assert_eq!(s.push(b"x"), 1);
        let r = s.take(1);
        assert_eq!(s.offset(r.start), 10);
    }

    #[test]
    fn a_full_buffer_is_said() {
        let mut s = StreamBuffer::new(FixedBuffer::<4>::new());
        s.push(b"abcd");
        assert!(s.is_full());
        s.take(1);
        assert!(!s.is_full());
        assert!(!s.is_finished());
        s.finish();
        assert!(s.is_finished());
    }
}

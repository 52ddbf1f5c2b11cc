//! IPv4 reassembly (RFC 791 section 3.2, "Fragmentation and Reassembly") for captures of
//! datagrams larger than the link's MTU: an Ouster's lidar packets (6-25 kB) recorded on a
//! 1500-byte (or 9000-byte jumbo) link arrive as fragments.
//!
//! Bounded: at most [`SLOTS`] datagrams in reassembly at once (the oldest is given up for a new
//! one, counted), each at most 65,535 bytes. A datagram is complete when its fragments cover
//! every byte up to the one without "more fragments".

use super::slice::Fragment;
use std::net::Ipv4Addr;

/// Datagrams reassembled at once (a sensor sends one at a time; interleaved streams a few).
pub const SLOTS: usize = 8;
/// The largest IPv4 datagram's payload.
const MAX_PAYLOAD: usize = 65_535 - 20;

#[derive(Debug, Default)]
struct Slot {
    key: Option<(Ipv4Addr, Ipv4Addr, u16, u8)>,
    data: Vec<u8>,
    /// Byte ranges received (merged as they arrive).
    have: Vec<(usize, usize)>,
    /// The payload's length, once its last fragment arrived.
    total: Option<usize>,
    /// When it last grew (fragments seen so far).
    touched: u64,
}

/// What one fragment did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Added {
    /// Held until the rest arrives.
    Held,
    /// Its datagram is whole: [`Reassembly::payload`] holds it (the IP payload: the UDP header
    /// and data).
    Complete,
    /// A fragment no datagram can hold (beyond 65,535 bytes, or past its own last fragment).
    Bad,
}

/// Datagrams being put together.
#[derive(Debug, Default)]
pub struct Reassembly {
    slots: Vec<Slot>,
    done: Vec<u8>,
    seen: u64,
    /// Datagrams given up unfinished (their slot needed for a newer one).
    pub abandoned: u64,
}

impl Reassembly {
    /// Add `f`.
    pub fn add(&mut self, f: &Fragment<'_>) -> Added {
        self.seen += 1;
        let key = (f.src, f.dst, f.id, f.protocol);
        let (start, end) = (f.offset, f.offset + f.payload.len());
        if end > MAX_PAYLOAD {
            return Added::Bad;
        }
        let i = match self.slots.iter().position(|s| s.key == Some(key)) {
            Some(i) => i,
            None => {
                let i = if self.slots.len() < SLOTS {
                    self.slots.push(Slot::default());
                    self.slots.len() - 1
                } else {
                    let (i, _) = self
                        .slots
                        .iter()
                        .enumerate()
                        .min_by_key(|(_, s)| (s.key.is_some(), s.touched))
                        .unwrap_or((0, &self.slots[0]));
                    if self.slots[i].key.is_some() {
                        self.abandoned += 1;
                    }
                    i
                };
                let s = &mut self.slots[i];
                s.key = Some(key);
                s.data.clear();
                s.have.clear();
                s.total = None;
                i
            }
        };
        let s = &mut self.slots[i];
        s.touched = self.seen;
        if s.total.is_some_and(|t| end > t) || (!f.more && s.have.iter().any(|r| r.1 > end)) {
            s.key = None;
            return Added::Bad;
        }
        if !f.more {
            s.total = Some(end);
        }
        if s.data.len() < end {
            s.data.resize(end, 0);
        }
        s.data[start..end].copy_from_slice(f.payload);
        s.have.push((start, end));
        // Merged in place: touching or overlapping ranges become one.
        s.have.sort_unstable();
        let mut w = 0;
        for i in 0..s.have.len() {
            let (a, b) = s.have[i];
            if w > 0 && a <= s.have[w - 1].1 {
                s.have[w - 1].1 = s.have[w - 1].1.max(b);
            } else {
                s.have[w] = (a, b);
                w += 1;
            }
        }
        s.have.truncate(w);
        match s.total {
            Some(t) if s.have.first() == Some(&(0, t)) => {
                std::mem::swap(&mut self.done, &mut s.data);
                self.done.truncate(t);
                s.key = None;
                Added::Complete
            }
            _ => Added::Held,
        }
    }

    /// The last datagram completed: its IP payload.
    pub fn payload(&self) -> &[u8] {
        &self.done
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frag(id: u16, offset: usize, more: bool, payload: &[u8]) -> Fragment<'_> {
        Fragment {
            src: Ipv4Addr::new(10, 0, 0, 2),
            dst: Ipv4Addr::new(10, 0, 0, 1),
            id,
            protocol: 17,
            offset,
            more,
            payload,
        }
    }

    /// Fragments in any order make the datagram once every byte is in; two datagrams
    /// interleave; one past 65,535 bytes or past its own end is refused; a ninth datagram
    /// gives up the oldest unfinished one.
    #[test]
    fn fragments_in_any_order_make_the_datagram() {
        let whole: Vec<u8> = (0..4000u32).map(|i| (i % 251) as u8).collect();
        let mut r = Reassembly::default();
        assert_eq!(r.add(&frag(7, 2960, false, &whole[2960..])), Added::Held);
        assert_eq!(r.add(&frag(9, 0, true, &whole[..1480])), Added::Held);
        assert_eq!(r.add(&frag(7, 0, true, &whole[..1480])), Added::Held);
        assert_eq!(
            r.add(&frag(7, 1480, true, &whole[1480..2960])),
            Added::Complete
        );
        assert_eq!(r.payload(), &whole[..]);
        assert_eq!(
            r.add(&frag(9, 1480, false, &whole[1480..2000])),
            Added::Complete
        );
        assert_eq!(r.payload(), &whole[..2000]);
        let big = vec![0u8; 1480];
        assert_eq!(r.add(&frag(3, 64_800, true, &big)), Added::Bad);
        assert_eq!(r.add(&frag(4, 0, false, &big[..100])), Added::Complete);
        assert_eq!(r.add(&frag(5, 1480, true, &big)), Added::Held);
        assert_eq!(r.add(&frag(5, 0, false, &big[..100])), Added::Bad);
        for id in 10..10 + SLOTS as u16 + 1 {
            assert_eq!(r.add(&frag(id, 0, true, &big)), Added::Held);
        }
        assert_eq!(r.abandoned, 1);
    }
}

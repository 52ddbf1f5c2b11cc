//! Room the caller lends the solver (the core has no heap): a fixed slice on the chip, storage
//! the host grows on its first use (memory never written costs nothing there, so the room a
//! long survey could need is not paid for on every short one).

/// Room for up to some number of items.
pub trait Room<T>: core::fmt::Debug {
    /// Room for `n` items, or for fewer when that is all there is. Its contents are whatever
    /// the last use left: the solver writes before it reads.
    fn room(&mut self, n: usize) -> &mut [T];
}

impl<T: core::fmt::Debug> Room<T> for [T] {
    /// The slice's first `n` items (all of it when it is shorter).
    fn room(&mut self, n: usize) -> &mut [T] {
        let k = n.min(self.len());
        &mut self[..k]
    }
}

impl<T: core::fmt::Debug, const N: usize> Room<T> for [T; N] {
    /// As the slice's.
    fn room(&mut self, n: usize) -> &mut [T] {
        self.as_mut_slice().room(n)
    }
}

#[cfg(test)]
mod tests {
    use super::Room;

    #[test]
    fn a_slice_lends_what_it_has() {
        let mut a = [7u8; 4];
        assert_eq!(a.room(3).len(), 3);
        assert_eq!(a[..].room(5).len(), 4);
        assert_eq!(a.room(9).len(), 4);
        assert!(a.room(0).is_empty());
    }
}

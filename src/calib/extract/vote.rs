//! Hough voting on the centre: the voxel grid over a slice (the caller's scratch) and the
//! strongest distinct peaks in it.

use super::V3;

/// The strongest distinct cells of the vote grid.
pub(super) struct Peaks<const K: usize> {
    pub(super) cell: [u32; K],
    pub(super) at: [[i32; 3]; K],
    pub(super) count: [u16; K],
    pub(super) dims: [u32; 3],
}

impl<const K: usize> Peaks<K> {
    pub(super) fn new(dims: [u32; 3]) -> Self {
        Self {
            cell: [u32::MAX; K],
            at: [[i32::MIN; 3]; K],
            count: [0; K],
            dims,
        }
    }

    pub(super) fn xyz(&self, k: u32) -> [i32; 3] {
        let z = k % self.dims[2];
        let y = (k / self.dims[2]) % self.dims[1];
        let x = k / (self.dims[2] * self.dims[1]);
        [x as i32, y as i32, z as i32]
    }

    /// Cell `k` now holds `v` votes.
    #[inline(always)]
    pub(super) fn offer(&mut self, k: u32, v: u16, min: &mut u16) {
        if v > *min {
            self.enter(k, v, min);
        }
    }

    /// [`Self::offer`] of a count above the least kept.
    fn enter(&mut self, k: u32, v: u16, min: &mut u16) {
        // A slot near this cell (within 2 cells) is the same blob: keep the higher one.
        let p = self.xyz(k);
        let slot = (0..K).find(|&i| {
            let q = self.at[i];
            if self.cell[i] == u32::MAX {
                return false;
            }
            (p[0] - q[0]).abs() <= 2 && (p[1] - q[1]).abs() <= 2 && (p[2] - q[2]).abs() <= 2
        });
        let i = match slot {
            Some(i) if v > self.count[i] => i,
            Some(_) => return,
            None => (0..K).min_by_key(|&i| self.count[i]).unwrap_or(0),
        };
        self.cell[i] = k;
        self.at[i] = p;
        self.count[i] = v;
        *min = if self.cell.contains(&u32::MAX) {
            0
        } else {
            self.count.iter().copied().min().unwrap_or(0)
        };
    }
}

/// The vote grid over a region: origin, cell size and dimensions.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid {
    pub(super) lo: V3,
    pub(super) h: f32,
    pub(super) dims: [u32; 3],
}

impl Grid {
    #[inline]
    pub(super) fn index(&self, c: V3) -> Option<u32> {
        let mut k = 0u32;
        for ((&ca, &lo), &dim) in c.iter().zip(&self.lo).zip(&self.dims) {
            let f = (ca - lo) / self.h;
            // NaN fails both tests.
            if f.is_nan() || f < 0.0 || f >= dim as f32 {
                return None;
            }
            k = k * dim + f as u32;
        }
        Some(k)
    }

    pub(super) fn center(&self, xyz: [i32; 3]) -> V3 {
        [
            self.lo[0] + (xyz[0] as f32 + 0.5) * self.h,
            self.lo[1] + (xyz[1] as f32 + 0.5) * self.h,
            self.lo[2] + (xyz[2] as f32 + 0.5) * self.h,
        ]
    }
}

//! Scan lines and slices: each return's run along its laser's scan line (ranges that do not
//! jump) and its slice of time (0.4 s, at most a slice buffer long), found once per solve.

use super::{norm, sub};
use crate::align::window::Observation;
use core::ops::Range;

/// Scan-line segments: consecutive firings of one laser whose ranges differ by less than
/// `jump` form a segment; every return gets its segment's length (first to last return, with
/// the current mounting) in `work.run`. A sphere in front of its background is crossed by
/// segments no longer than its diameter; a deck or a wall by long ones. Observations must be in
/// time order; a second return of the same firing (dual mode) is a segment of its own.
pub fn runs(obs: &mut [Observation], firing_ns: i64, jump: f64) {
    let jump = jump as f32;
    let max_dt = firing_ns + firing_ns / 2;
    let joins = |a: &Observation, b: &Observation| {
        let dt = b.time.0 - a.time.0;
        dt > 0 && dt <= max_dt && (b.range - a.range).abs() < jump
    };
    let twin = |a: &Observation, b: &Observation| b.time == a.time;
    // Pass 1: each segment's length, kept in its first return.
    let mut state: [Option<(usize, usize)>; 64] = [None; 64];
    for i in 0..obs.len() {
        let l = usize::from(obs[i].laser) & 63;
        match state[l] {
            Some((_, last)) if twin(&obs[last], &obs[i]) => obs[i].work.run = 0.0,
            Some((s, last)) if joins(&obs[last], &obs[i]) => state[l] = Some((s, i)),
            prev => {
                if let Some((s, last)) = prev {
                    obs[s].work.run = norm(sub(obs[last].work.x, obs[s].work.x));
                }
                state[l] = Some((i, i));
            }
        }
    }
    for (s, last) in state.iter().flatten() {
        obs[*s].work.run = norm(sub(obs[*last].work.x, obs[*s].work.x));
    }
    // Pass 2: the same walk hands every return its segment's length.
    let mut state: [Option<(usize, usize)>; 64] = [None; 64];
    for i in 0..obs.len() {
        let l = usize::from(obs[i].laser) & 63;
        match state[l] {
            Some((_, last)) if twin(&obs[last], &obs[i]) => {}
            Some((s, last)) if joins(&obs[last], &obs[i]) => {
                obs[i].work.run = obs[s].work.run;
                state[l] = Some((s, i));
            }
            _ => state[l] = Some((i, i)),
        }
    }
}

/// Number the slices of time of observations sorted by time (into `work.slice`): runs no
/// longer than `slice_ns` and no more than `max_len` returns; a gap longer than
/// `slice_ns / 2` also ends one. Returns how many.
pub fn assign_slices(obs: &mut [Observation], slice_ns: i64, max_len: usize) -> u32 {
    let mut id = 0u32;
    let (mut t0, mut len) = (i64::MIN, 0usize);
    for i in 0..obs.len() {
        let t = obs[i].time.0;
        let gap = i > 0 && !(0..=slice_ns / 2).contains(&(t - obs[i - 1].time.0));
        if i == 0 || gap || t - t0 > slice_ns || len >= max_len.max(1) {
            if i > 0 {
                id += 1;
            }
            t0 = t;
            len = 0;
        }
        len += 1;
        obs[i].work.slice = id;
    }
    if obs.is_empty() {
        0
    } else {
        id + 1
    }
}

/// The slices of observations grouped by `work.slice` (any order within a slice): the index
/// ranges of equal slice numbers.
pub fn slices(obs: &[Observation]) -> impl Iterator<Item = Range<usize>> + '_ {
    let mut cursor = SliceCursor::default();
    core::iter::from_fn(move || cursor.next(obs))
}

/// A walk over the slices of observations grouped by `work.slice` that holds no borrow: each
/// step is given the observations afresh, so the caller may change (tag, reorder) the slice it
/// was just given before asking for the next.
#[derive(Debug, Clone, Copy, Default)]
pub struct SliceCursor {
    at: usize,
}

impl SliceCursor {
    /// The next slice's index range in `obs` (the same observations each step), `None` at the
    /// end.
    pub fn next(&mut self, obs: &[Observation]) -> Option<Range<usize>> {
        let start = self.at;
        let id = obs.get(start)?.work.slice;
        let len = obs[start..]
            .iter()
            .take_while(|o| o.work.slice == id)
            .count();
        self.at = start + len;
        Some(start..self.at)
    }
}

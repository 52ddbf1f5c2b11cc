//! Scan lines and slices: each return's run along its laser's scan line (ranges that do not
//! jump) and its slice of time (0.4 s, at most a slice buffer long), found once per solve.

use super::{norm, sub, ExtractSettings, ReturnClass};
use crate::align::window::{Observation, Target};
use crate::calib::objective::TimeOffset;
use crate::georef::Mount;
use crate::time::GpsTime;
use core::ops::Range;

/// Scan-line segments: consecutive firings of one laser whose ranges differ by less than
/// `jump` form a segment; every return gets its segment's length (first to last return, with
/// the current mounting) in `work.run`. A sphere in front of its background is crossed by
/// segments no longer than its diameter; a deck or a wall by long ones. Observations must be in
/// time order; a second return of the same firing (dual mode) is a segment of its own.
pub fn runs(obs: &mut [Observation], firing_ns: i64, jump: f64) {
    let mut seg = Segments::new(firing_ns, jump);
    for i in 0..obs.len() {
        seg.measure(obs, i);
    }
    seg.hand_out(obs, |_| {});
}

/// The walk [`runs`] makes, a return at a time: [`Segments::measure`] in time order keeps each
/// segment's length in its first return, [`Segments::hand_out`] then gives it to the rest.
pub(super) struct Segments {
    jump: f32,
    max_dt: i64,
    /// Per laser: the open segment's first and last return.
    state: [Option<(usize, usize)>; 64],
}

impl Segments {
    pub(super) fn new(firing_ns: i64, jump: f64) -> Self {
        Self {
            jump: jump as f32,
            max_dt: firing_ns + firing_ns / 2,
            state: [None; 64],
        }
    }

    /// Whether `b` continues the segment whose last return is `a`.
    fn joins(&self, a: &Observation, b: &Observation) -> bool {
        let dt = b.time.0 - a.time.0;
        dt > 0 && dt <= self.max_dt && (b.range - a.range).abs() < self.jump
    }

    /// Return `i` (its `work.x` placed, every return before it measured).
    #[inline]
    pub(super) fn measure(&mut self, obs: &mut [Observation], i: usize) {
        let l = usize::from(obs[i].laser) & 63;
        match self.state[l] {
            // A second return of the same firing.
            Some((_, last)) if obs[last].time == obs[i].time => obs[i].work.run = 0.0,
            Some((s, last)) if self.joins(&obs[last], &obs[i]) => self.state[l] = Some((s, i)),
            prev => {
                if let Some((s, last)) = prev {
                    obs[s].work.run = norm(sub(obs[last].work.x, obs[s].work.x));
                }
                self.state[l] = Some((i, i));
            }
        }
    }

    /// After every return was measured: the open segments closed, and every return given its
    /// segment's length by the same walk (and then to `each`).
    pub(super) fn hand_out(mut self, obs: &mut [Observation], mut each: impl FnMut(&Observation)) {
        for (s, last) in self.state.iter().flatten() {
            obs[*s].work.run = norm(sub(obs[*last].work.x, obs[*s].work.x));
        }
        self.state = [None; 64];
        for i in 0..obs.len() {
            let l = usize::from(obs[i].laser) & 63;
            match self.state[l] {
                Some((_, last)) if obs[last].time == obs[i].time => {}
                Some((s, last)) if self.joins(&obs[last], &obs[i]) => {
                    obs[i].work.run = obs[s].work.run;
                    self.state[l] = Some((s, i));
                }
                _ => self.state[l] = Some((i, i)),
            }
            each(&obs[i]);
        }
    }
}

/// Number the slices of time of observations sorted by time (into `work.slice`): runs no
/// longer than `slice_ns` and no more than `max_len` returns; a gap longer than
/// `slice_ns / 2` also ends one. Returns how many.
pub fn assign_slices(obs: &mut [Observation], slice_ns: i64, max_len: usize) -> u32 {
    let mut slicer = Slicer::new(slice_ns, max_len);
    for o in obs.iter_mut() {
        o.work.slice = slicer.next(o.time.0);
    }
    slicer.count()
}

/// The numbering [`assign_slices`] makes, a return's time at a time.
pub(super) struct Slicer {
    slice_ns: i64,
    max_len: usize,
    id: u32,
    /// The slice's first time, its returns so far, the last return's time.
    t0: i64,
    len: usize,
    prev: Option<i64>,
}

impl Slicer {
    pub(super) fn new(slice_ns: i64, max_len: usize) -> Self {
        Self {
            slice_ns,
            max_len: max_len.max(1),
            id: 0,
            t0: i64::MIN,
            len: 0,
            prev: None,
        }
    }

    /// The slice of the next return, at `t`.
    #[inline]
    pub(super) fn next(&mut self, t: i64) -> u32 {
        match self.prev {
            None => self.t0 = t,
            Some(p) => {
                let gap = !(0..=self.slice_ns / 2).contains(&(t - p));
                if gap || t - self.t0 > self.slice_ns || self.len >= self.max_len {
                    self.id += 1;
                    self.t0 = t;
                    self.len = 0;
                }
            }
        }
        self.prev = Some(t);
        self.len += 1;
        self.id
    }

    /// Slices numbered so far.
    pub(super) fn count(&self) -> u32 {
        if self.prev.is_some() {
            self.id + 1
        } else {
            0
        }
    }
}

/// One sphere's windowed returns made ready for the rounds in one walk (they are 10^5 of
/// 160 bytes: each walk over them costs what memory moves, so the steps share it): put in
/// time order ([`time_order`]), georeferenced with `mount` ([`super::georeference`]), their
/// scan-line segments measured ([`runs`]), their slices numbered ([`assign_slices`]) and
/// tagged `Unclassified`; each then given to `each`, in time order. Returns the nearest
/// return's range [m] (infinite without returns).
pub fn prepare(
    obs: &mut [Observation],
    t: &Target,
    mount: &Mount,
    st: &ExtractSettings,
    max_len: usize,
    mut each: impl FnMut(&Observation),
) -> f32 {
    if let Some(near) = walk(obs, t, mount, st, max_len, &mut each) {
        return near;
    }
    // Out of order (rare: the collection appends in arrival order): sorted, and walked again.
    obs.sort_unstable_by_key(time_order);
    walk(obs, t, mount, st, max_len, &mut each).unwrap_or(f32::INFINITY)
}

/// The returns' order in time (a firing's returns by channel, then block): a slice's returns
/// together, and the least squares' clusters.
pub fn time_order(o: &Observation) -> (GpsTime, u8, u8) {
    (o.time, o.channel, o.block)
}

/// [`prepare`]'s walk: the nearest range; `None` (the segments not handed out, nothing given
/// to `each`) when the returns are not in time order.
fn walk(
    obs: &mut [Observation],
    t: &Target,
    mount: &Mount,
    st: &ExtractSettings,
    max_len: usize,
    each: &mut impl FnMut(&Observation),
) -> Option<f32> {
    let mut seg = Segments::new(st.firing_ns, st.jump);
    let mut slicer = Slicer::new(st.slice_ns, max_len);
    let (mut near, mut sorted) = (f32::INFINITY, true);
    let none = TimeOffset::default();
    for i in 0..obs.len() {
        if i > 0 && time_order(&obs[i - 1]) > time_order(&obs[i]) {
            sorted = false;
        }
        let o = &mut obs[i];
        super::place(o, t, mount, &none);
        o.work.slice = slicer.next(o.time.0);
        o.work.verdict = ReturnClass::Unclassified as u8;
        near = near.min(o.range);
        seg.measure(obs, i);
    }
    if !sorted {
        return None;
    }
    seg.hand_out(obs, each);
    Some(near)
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

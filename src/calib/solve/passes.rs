//! Passes: each sphere's returns split by the course (a 90 deg turn or a 20 s gap; a piece of
//! under 2 s after a turn joins the pass before).

use super::outcome::PassReport;
use super::MAX_PASSES;
use crate::align::window::Observation;
use crate::time::GpsTime;

/// The pass holding time `t` (the last one starting at or before it).
pub(super) fn pass_of(ps: &mut [PassReport], t: GpsTime) -> Option<&mut PassReport> {
    ps.get_mut(index_of(ps, t)?)
}

/// The index of [`pass_of`]'s pass.
fn index_of(ps: &[PassReport], t: GpsTime) -> Option<usize> {
    ps.partition_point(|p| p.start <= t).checked_sub(1)
}

/// [`pass_of`] for times that mostly follow each other: the pass found last is tried first
/// (a sphere's 10^5 returns, most in time order, against a few passes).
#[derive(Debug, Default)]
pub(super) struct PassCursor {
    last: Option<usize>,
}

impl PassCursor {
    /// As [`pass_of`].
    pub(super) fn pass_of<'p>(
        &mut self,
        ps: &'p mut [PassReport],
        t: GpsTime,
    ) -> Option<&'p mut PassReport> {
        let hit = self.last.filter(|&i| {
            ps.get(i).is_some_and(|p| p.start <= t) && ps.get(i + 1).is_none_or(|p| p.start > t)
        });
        let i = match hit {
            Some(i) => i,
            None => index_of(ps, t)?,
        };
        self.last = Some(i);
        ps.get_mut(i)
    }
}

/// The passes over one sphere, its windowed returns given in time order ([`PassFinder::see`]):
/// split where the platform's course has turned more than 90 deg from the pass's first course,
/// and at gaps longer than `gap_ns` (a second visit on the same course); a piece shorter than
/// `min_ns` after a turn (the turn itself) joins the pass before it. The course decides, not
/// the window: a level scan sees a sphere's window from everywhere, a tilted one only when
/// abeam, and turns show the sphere in fragments. Appended to `out` (beyond its capacity the
/// last one is extended).
pub(super) struct PassFinder<'o> {
    sphere: u8,
    gap_ns: i64,
    min_ns: i64,
    out: &'o mut heapless::Vec<PassReport, MAX_PASSES>,
    /// This sphere's first pass in `out`.
    first: usize,
    last: Option<GpsTime>,
    first_course: Option<[f32; 2]>,
}

impl<'o> PassFinder<'o> {
    /// Sphere `j`'s passes, appended to `out`.
    pub(super) fn new(
        j: usize,
        gap_ns: i64,
        min_ns: i64,
        out: &'o mut heapless::Vec<PassReport, MAX_PASSES>,
    ) -> Self {
        let first = out.len();
        Self {
            sphere: j as u8,
            gap_ns,
            min_ns,
            out,
            first,
            last: None,
            first_course: None,
        }
    }

    /// The next return in time order.
    #[inline]
    pub(super) fn see(&mut self, o: &Observation) {
        /// Slower than this the course is not defined [m/s].
        const MOVING: f32 = 0.3;
        let (n, e) = (o.velocity.x, o.velocity.y);
        let s = libm::sqrtf(n * n + e * e);
        let c = (s > MOVING).then(|| [n / s, e / s]);
        let gap = self.last.is_none_or(|l| o.time.0 - l.0 > self.gap_ns);
        let turned =
            matches!((self.first_course, c), (Some(a), Some(b)) if a[0] * b[0] + a[1] * b[1] < 0.0);
        if turned && !gap {
            join_short(self.out, self.first, self.min_ns);
        }
        self.last = Some(o.time);
        if gap || turned || self.first_course.is_none() {
            self.first_course = c;
        }
        if (gap || turned) && !self.out.is_full() {
            let _ = self.out.push(PassReport::starting(self.sphere, o.time));
        } else if let Some(p) = self.out.last_mut() {
            p.end = o.time;
        }
    }

    /// After the last return.
    pub(super) fn finish(self) {
        join_short(self.out, self.first, self.min_ns);
    }
}

/// The last pass joins the one before it (of the same sphere, from index `first` of `out`)
/// when it is shorter than `min_ns` and follows it within `min_ns`.
pub(super) fn join_short(
    out: &mut heapless::Vec<PassReport, MAX_PASSES>,
    first: usize,
    min_ns: i64,
) {
    let n = out.len();
    if n < first + 2 {
        return;
    }
    let (prev, last) = (out[n - 2], out[n - 1]);
    if last.end.0 - last.start.0 < min_ns && last.start.0 - prev.end.0 <= min_ns {
        out[n - 2].end = last.end;
        out.pop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cursor finds the pass the binary search finds, for times in order, out of order,
    /// before the first pass and after the last.
    #[test]
    fn the_cursor_finds_what_the_search_finds() {
        let mut ps = [0i64, 10, 25, 40].map(|s| PassReport::starting(0, GpsTime(s)));
        let mut at = PassCursor::default();
        for t in [
            -5i64, 0, 3, 9, 10, 11, 30, 24, 25, 26, 39, 40, 99, 1, -1, 12, 12,
        ] {
            let want = pass_of(&mut ps, GpsTime(t)).map(|p| p.start);
            let got = at.pass_of(&mut ps, GpsTime(t)).map(|p| p.start);
            assert_eq!(got, want, "t = {t}");
        }
    }
}

//! Passes: each sphere's returns split by the course (a 90 deg turn or a 20 s gap; a piece of
//! under 2 s after a turn joins the pass before).

use super::outcome::PassReport;
use super::MAX_PASSES;
use crate::align::window::Observation;
use crate::time::GpsTime;

/// The pass holding time `t` (the last one starting at or before it).
pub(super) fn pass_of(ps: &mut [PassReport], t: GpsTime) -> Option<&mut PassReport> {
    let i = ps.partition_point(|p| p.start <= t);
    ps.get_mut(i.checked_sub(1)?)
}

/// The passes over one sphere: its windowed returns (in time order) split where the platform's
/// course has turned more than 90 deg from the pass's first course, and at gaps longer than
/// `gap_ns` (a second visit on the same course); a piece shorter than `min_ns` after a turn
/// (the turn itself) joins the pass before it. The course decides, not the window: a level
/// scan sees a sphere's window from everywhere, a tilted one only when abeam, and turns show
/// the sphere in fragments. Appended to `out` (beyond its capacity the last one is extended).
pub(super) fn find_passes(
    v: &[Observation],
    j: usize,
    gap_ns: i64,
    min_ns: i64,
    out: &mut heapless::Vec<PassReport, MAX_PASSES>,
) {
    /// Slower than this the course is not defined [m/s].
    const MOVING: f32 = 0.3;
    let course = |o: &Observation| {
        let (n, e) = (o.velocity.x, o.velocity.y);
        let s = libm::sqrtf(n * n + e * e);
        (s > MOVING).then(|| [n / s, e / s])
    };
    let first = out.len();
    let mut last: Option<GpsTime> = None;
    let mut first_course: Option<[f32; 2]> = None;
    for o in v {
        let c = course(o);
        let gap = last.is_none_or(|l| o.time.0 - l.0 > gap_ns);
        let turned =
            matches!((first_course, c), (Some(a), Some(b)) if a[0] * b[0] + a[1] * b[1] < 0.0);
        if turned && !gap {
            join_short(out, first, min_ns);
        }
        last = Some(o.time);
        if gap || turned || first_course.is_none() {
            first_course = c;
        }
        if (gap || turned) && !out.is_full() {
            let _ = out.push(PassReport::starting(j as u8, o.time));
        } else if let Some(p) = out.last_mut() {
            p.end = o.time;
        }
    }
    join_short(out, first, min_ns);
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

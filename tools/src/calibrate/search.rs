//! The coarse search of the time offset for a LiDAR clock that is not trusted.

use super::Calibrated;
use crate::report::SearchCandidate;
use spherecal::calib::solve::Solution;

/// The half-width of the time offset search when the LiDAR clock is not trusted [s].
pub const DEFAULT_SEARCH_S: f64 = 2.0;
/// The search's step [s]: the joint solve pulls in from at least twice this (a 0.4 s error
/// converges from 0 on table1).
pub const SEARCH_STEP_S: f64 = 0.25;

/// A coarse 1-D search of the time offset over `centre +- half` in steps of [`SEARCH_STEP_S`]:
/// at each start the windows are collected and the joint solve run; what each found is
/// returned. The clock error moves the spheres' returns along the track by speed x error, so a
/// wrong start gives fewer sphere returns (detection fails in the slices it smears) and a larger
/// RMS: [`best_candidate`] picks the most compact.
pub fn search_time_offset<E>(
    centre: f64,
    half: f64,
    at_centre: &Solution,
    attempt: &mut impl FnMut(f64) -> Result<Calibrated, E>,
) -> Result<Vec<SearchCandidate>, E> {
    let n = (half / SEARCH_STEP_S).round().clamp(1.0, 400.0) as i64;
    let mut out = Vec::with_capacity(2 * n as usize + 1);
    let bar = crate::progress::bar(2 * n as u64 + 1, "time offset search");
    for k in -n..=n {
        bar.inc(1);
        let start = centre + k as f64 * SEARCH_STEP_S;
        let one = |sol: &Solution| SearchCandidate {
            start_s: start,
            found_s: sol
                .lm
                .filter(|l| l.converged && sol.dt.is_finite())
                .map(|_| start + sol.dt),
            kept: sol.spheres.iter().map(|s| s.used).sum(),
            rms_m: sol.lm.map(|l| l.rms).filter(|r| r.is_finite()),
        };
        if k == 0 {
            out.push(one(at_centre));
        } else {
            // A start where the clocks no longer overlap finds nothing; it does not end the
            // search.
            match attempt(start) {
                Ok((_, _, sol, _)) => out.push(one(&sol)),
                Err(_) => out.push(SearchCandidate {
                    start_s: start,
                    found_s: None,
                    kept: 0,
                    rms_m: None,
                }),
            }
        }
    }
    bar.finish_and_clear();
    Ok(out)
}

/// The widest search around `centre` [s] that keeps at least half the LiDAR data's span
/// (`lidar`, GPS seconds without any offset) within the INS's (`ins`): beyond it the clocks
/// barely overlap and nothing can be found; `half` clipped to it.
pub fn search_half_width(
    centre: f64,
    half: f64,
    lidar: Option<(f64, f64)>,
    ins: Option<(f64, f64)>,
) -> f64 {
    let (Some((l0, l1)), Some((i0, i1))) = (lidar, ins) else {
        return half;
    };
    // Offsets dt with [l0 + dt, l1 + dt] half inside [i0, i1].
    let w = 0.5 * (l1 - l0);
    let (lo, hi) = (i0 - l0 - w, i1 - l1 + w);
    let reach = (centre - lo).min(hi - centre).max(SEARCH_STEP_S);
    half.min(reach)
}

/// The most compact start: among those whose solve converged, the lowest RMS of those that
/// kept at least 80 % of the most sphere returns any kept.
pub fn best_candidate(c: &[SearchCandidate]) -> Option<SearchCandidate> {
    let ok = || {
        c.iter()
            .filter(|c| c.found_s.is_some() && c.rms_m.is_some())
    };
    let most = ok().map(|c| c.kept).max()?;
    ok().filter(|c| c.kept * 5 >= most * 4)
        .min_by(|a, b| a.rms_m.unwrap_or(0.0).total_cmp(&b.rms_m.unwrap_or(0.0)))
        .copied()
}

//! Why, in words: a refusal ([`refusal_text`]), a lost sphere's code ([`lost_name`]), windows
//! that caught nothing ([`empty_windows`]). The core gives the values; these say them.

use crate::pipeline::Closest;
use spherecal::calib::solve::{Lost, Refusal};
use spherecal::georef::NAMES;

/// The words of a refusal a located stretch may explain, once every candidate stretch was set
/// aside in turn and none left the rest clean (`crate::stretches`).
pub const NO_STRETCH: &str = "; no stretch of the survey set aside explained it: find it in the passes below and set it aside with --exclude GPS_T0..GPS_T1";

/// A refusal's first words under a LiDAR clock whose offset from the INS nothing tells
/// (`Session::look_into`), the clock's state in `clock` (else the words point to its line).
pub fn unknown_offset(clock: Option<&str>) -> String {
    format!(
        "the LiDAR clock is not PPS-locked and gives no RMC time ({}), and the time offset between the LiDAR's and the INS's clocks was neither searched nor given: an offset of a second smears each sphere metres along the track, so nothing the returns show can be trusted; search it (calibrate's default for such a clock, unless --search-time-offset 0) or give it (--time-offset)",
        clock.unwrap_or("see the LiDAR clock line")
    )
}

/// A refusal's first words where the LiDAR's RMC time (its stamps `rmc_offset_s` ahead, to
/// within the half second its whole second hides) puts the time offset elsewhere than the one
/// applied (`applied_s`) [s].
pub fn belied_offset(applied_s: f64, rmc_offset_s: f64) -> String {
    format!(
        "the LiDAR clock is not PPS-locked, and its RMC time puts the time offset between {:+.2} and {:+.2} s (its whole second), not at the {applied_s:+.3} s applied: an offset wrong by a second smears each sphere metres along the track, so nothing the returns show can be trusted; leave the start to the RMC (no --time-offset) or search it (--search-time-offset)",
        -rmc_offset_s - 0.5,
        -rmc_offset_s + 0.5
    )
}

/// A refusal in words; `dt_estimated`: the time offset was estimated with the mounting (else
/// held), so that a refusal does not blame an offset that was not left out.
pub fn refusal_text(r: &Refusal, ids: &[String], weak: &[String], dt_estimated: bool) -> String {
    refusal_text_clock(r, ids, weak, None, dt_estimated)
}

/// [`refusal_text`], with the LiDAR clock's state in words where a refusal is about it.
pub fn refusal_text_clock(
    r: &Refusal,
    ids: &[String],
    weak: &[String],
    lidar_clock: Option<&str>,
    dt_estimated: bool,
) -> String {
    let clock_words = lidar_clock.unwrap_or("see the LiDAR clock line");
    match r {
        Refusal::InsClockStep(st) => format!(
            "the INS clock stepped by {:+.1} ms {:.1} s into the LiDAR data (GPS {:.3} s){}: one frame's time is not one output period after the one before it with nothing lost between them, so the poses after it are {:+.1} ms off those before; calibrate the parts on either side separately, or fix the INS time",
            st.step_s * 1e3,
            st.into_s,
            st.at_s,
            if st.count > 1 { format!(", and {} more times", st.count - 1) } else { String::new() },
            st.step_s * 1e3
        ),
        Refusal::LidarClockUntrusted { offset_s, explained, allowed: false, .. } => format!(
            "the LiDAR clock is not PPS-locked with a valid RMC ({clock_words}); the time offset found is {offset_s:+.4} s{}: --allow-unlocked-clock claims the solution",
            match explained {
                Some(true) => ", which explains the stamps' disagreement with the RMC",
                Some(false) => ", which does NOT explain the stamps' disagreement with the RMC",
                None => "",
            }
        ),
        Refusal::LidarClockUntrusted { offset_s, rmc_offset_s, .. } => format!(
            "the LiDAR clock is not PPS-locked ({clock_words}) and the time offset found is {offset_s:+.4} s, which does not explain the stamps' disagreement with the RMC ({:+.3} s)",
            rmc_offset_s.unwrap_or(0.0)
        ),
        Refusal::TooFewTargets { given } => format!("the site gives {given} sphere(s): at least two are needed (one sphere cannot fix the rotation about the line to it)"),
        Refusal::TooFewSpheres { have } => format!("{have} sphere(s) found: at least two are needed (one sphere cannot fix the rotation about the line to it)"),
        Refusal::TooFewPoints { sphere, have, need } => format!("sphere {}: {have} returns, at least {need} are needed", ids.get(*sphere).map_or("?", |s| s.as_str())),
        Refusal::IllConditioned { condition, limit } => format!(
            "ill-conditioned: condition number {condition:.3e} > {limit:.0e}; the geometry cannot separate {}",
            if weak.is_empty() { "the parameters".to_string() } else { weak.join(", ") }
        ),
        Refusal::NotConverged { iterations } => format!("the least squares did not converge (stalled after {iterations} iterations)"),
        Refusal::OverDispersed { rms, predicted } => format!(
            "residual RMS {:.1} mm is {:.1}x what the sensors' noise predicts ({:.1} mm): returns that are not on the spheres, or a model that does not fit",
            rms * 1e3,
            rms / predicted.max(1e-12),
            predicted * 1e3
        ),
        Refusal::PriorDisagrees { parameter, moved, sigma, z } => {
            let (v, sg, unit) = if *parameter < 3 {
                (moved.to_degrees(), sigma.to_degrees(), "deg")
            } else {
                (*moved * 1e3, sigma * 1e3, "mm")
            };
            format!(
                "the data move the {} {v:+.4} {unit} from its measured value, {z:.1} times what its declared sigma ({sg:.4} {unit}, [apriori]) leaves room for: the measurement of the mounting or its sigma is wrong (or the data: see the passes below)",
                NAMES.get(*parameter).copied().unwrap_or("?")
            )
        }
        Refusal::Remnant { sphere, kept, rounds } => format!(
            "sphere {}: the last extraction, around its surveyed centre, kept {kept} of the {rounds} returns the rounds kept around where the returns put it: somewhere the navigation puts the sphere elsewhere than its returns do (a GNSS outage the INS status did not show, a sphere moved){NO_STRETCH}",
            ids.get(*sphere).map_or("?", |s| s.as_str())
        ),
        Refusal::Noisier { factor, limit } => format!(
            "the returns scatter {factor:.1}x the white noise the noise model declares (limit {limit:.1}): somewhere the navigation errors are not the declared ones (a GNSS outage, multipath){NO_STRETCH}, or declare the INS's errors in the site's [ins.correlated]"
        ),
        Refusal::Ambiguous(a) => {
            let d = (a.offset[0].powi(2) + a.offset[1].powi(2) + a.offset[2].powi(2)).sqrt();
            format!(
                "ambiguous: sphere {}: another mounting puts other sphere-like returns {:.2} m from the chosen ones (N {:+.2}, E {:+.2}, D {:+.2} m) on it and explains the survey nearly as well ({} of its slices against {}; {:.0} of all against {:.0}): a buoy, fender or other round object of its size beside it, or passes that cannot tell them apart; move the object, or add passes from other directions",
                ids.get(a.sphere).map_or("?", |s| s.as_str()),
                d,
                a.offset[0],
                a.offset[1],
                a.offset[2],
                a.support[1],
                a.support[0],
                a.score[1],
                a.score[0]
            )
        }
        Refusal::OutOfBounds { parameter, change, limit } => {
            let (v, l, unit) = if *parameter < 3 {
                (change.to_degrees(), limit.to_degrees(), "deg")
            } else {
                (*change, *limit, "m")
            };
            format!(
                "the solve left the a-priori bounds: {} moved {v:.3} {unit} from the start, more than the {l:.3} {unit} the windows' margin allows (the spheres would have been outside their windows): the returns kept are not the spheres'; check the a-priori values and the site",
                NAMES.get(*parameter).copied().unwrap_or("?")
            )
        }
        Refusal::ClockStep { into, step, sigma, after, passes, .. } => format!(
            "the clocks are not steady: the passes from {into:.1} s into the data on ({after} of {passes}) put the time offset {:+.1} ms (sigma {:.1} ms, {:.0} sigma) off those before: an INS time step (a POS MV's stream cannot show one) or a LiDAR clock drifting; look for the step in the INS line above (time going back or jumping), or give the LiDAR PPS",
            step * 1e3,
            sigma * 1e3,
            step.abs() / sigma.max(1e-12)
        ),
        Refusal::ClockInconsistent { sphere, pass, into, shift, sigma, .. } => format!(
            "the clocks are not steady: in pass {} over sphere {} ({:.1}-{:.1} s into the data) the returns put the time offset {:+.1} ms (sigma {:.1} ms, {:.0} sigma) off the rest of the survey's: an INS time step or a LiDAR clock drifting; look for the step in the INS line above (time going back or jumping), or give the LiDAR PPS",
            pass + 1,
            ids.get(*sphere).map_or("?", |s| s.as_str()),
            into[0],
            into[1],
            shift * 1e3,
            sigma * 1e3,
            shift.abs() / sigma.max(1e-12)
        ),
        Refusal::Unsettled { lost, first, slices } => format!(
            "the detect-and-solve rounds did not settle: they lost sphere {} and ended as \"{}\" (the spheres detected in {} slices); started again from the a-priori mounting they left the bounds ({} slices): no mounting explains the spheres together. Check the a-priori values and the site; from the air, spheres resting on the ground are hard to tell from it under a wrong mounting: put them on tripods (`spherecal plan --design`)",
            ids.get(*lost).map_or("?", |s| s.as_str()),
            first.termination().words(),
            slices[0],
            slices[1]
        ),
        Refusal::TimeOffsetContradicted { held, found, sigma } => format!(
            "the time offset held is contradicted by the data: free to estimate it, they move it by {:+.6} s (sigma {sigma:.6} s, {:.0} sigma); the mounting found with it held has absorbed the clock error (drop --hold-time-offset, or hold the offset the data give)",
            found - held,
            (found - held).abs() / sigma.max(1e-12)
        ),
        Refusal::NavigationJump { at, step, sigmas } => format!(
            "the navigation jumps at GPS {:.1} s: N {:+.1} E {:+.1} D {:+.1} mm, heading {:+.4} deg between consecutive pieces of the survey, {sigmas:.0} times what the declared model ([ins.correlated]) lets it move: an INS that lost its fix or a trajectory edited, and no pass around it set aside left the rest clean; set the bad stretch aside with --exclude {:.0}..{:.0} (widen it to where the INS recovered) and calibrate again",
            at.0 as f64 * 1e-9,
            step[0] * 1e3,
            step[1] * 1e3,
            step[2] * 1e3,
            step[5].to_degrees(),
            at.0 as f64 * 1e-9 - 5.0,
            at.0 as f64 * 1e-9 + 5.0
        ),
        Refusal::SurveyDisagrees { sphere, moved, chi2, sigma } => {
            let d = (moved[0] * moved[0] + moved[1] * moved[1] + moved[2] * moved[2]).sqrt();
            format!(
                "sphere {}'s surveyed centre disagrees with the other spheres and the navigation model: the returns move it N {:+.1} E {:+.1} D {:+.1} mm ({:.1} mm; chi-square {chi2:.0} with 3 degrees of freedom against its survey sigma {:.1} mm): check its survey, or whether it was moved",
                ids.get(*sphere).map_or("?", |s| s.as_str()),
                moved[0] * 1e3,
                moved[1] * 1e3,
                moved[2] * 1e3,
                d * 1e3,
                sigma * 1e3
            )
        }
        Refusal::Inconsistent { sphere, pass, offset, along_track, chi2 } => {
            let d = (offset[0] * offset[0] + offset[1] * offset[1] + offset[2] * offset[2]).sqrt();
            format!(
                "inconsistent: in pass {} over sphere {} the calibrated returns put its centre {:.1} mm off the surveyed one ({:.1} mm along the track; chi-square {chi2:.0} with 3 degrees of freedom){}",
                pass + 1,
                ids.get(*sphere).map_or("?", |s| s.as_str()),
                d * 1e3,
                along_track * 1e3,
                match (along_track.abs() > 0.7 * d, dt_estimated) {
                    (false, _) => "",
                    (true, false) => ": an along-track error of this kind is what a time offset between the clocks does, and it was held (drop --hold-time-offset)",
                    (true, true) => ": an along-track error of this kind, with the time offset estimated, is what a clock that steps or drifts within the survey does (see the passes' own time offsets), or the navigation in that pass",
                }
            )
        }
    }
}

/// A lost sphere's reason code in reports.
pub fn lost_name(l: Lost) -> &'static str {
    match l {
        Lost::NoReturns => "no_returns",
        Lost::NotDetected => "not_detected",
        Lost::Disagrees => "disagrees",
        Lost::TooFewReturns => "too_few_returns",
        Lost::Stopped => "stopped",
    }
}

/// Why the windows of some spheres (id, how close the trajectory came, window radius: the
/// sphere's radius + the margin) caught no return, from how close the trajectory came to them
/// and the LiDAR's reach: out of reach, the site and the trajectory do not meet; within it,
/// the a-priori mounting puts the returns elsewhere.
pub fn empty_windows(empty: &[(&str, Closest, f64)], reach: f64) -> Option<String> {
    let far = |d: f64| {
        if d >= 10_000.0 {
            format!("{:.0} km", d / 1000.0)
        } else {
            format!("{d:.1} m")
        }
    };
    let list = |v: &[&(&str, Closest, f64)]| {
        v.iter()
            .map(|(id, c, _)| format!("{id} {} at GPS {:.1} s", far(c.distance_m), c.time_s))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let names = |v: &[&(&str, Closest, f64)]| v.iter().map(|e| e.0).collect::<Vec<_>>().join(", ");
    let unread: Vec<_> = empty
        .iter()
        .filter(|e| !e.1.distance_m.is_finite())
        .collect();
    let out: Vec<_> = empty
        .iter()
        .filter(|e| e.1.distance_m.is_finite() && e.1.distance_m > reach)
        .collect();
    let near: Vec<_> = empty.iter().filter(|e| e.1.distance_m <= reach).collect();
    let mut why = Vec::new();
    if !unread.is_empty() {
        why.push(format!(
            "no return in the windows of {}: no INS pose was read",
            names(&unread)
        ));
    }
    if !out.is_empty() {
        why.push(format!(
            "no return in the windows of {}: the trajectory never came within the LiDAR's {reach:.0} m of them (closest: {}): the site and the trajectory do not meet — check the site's coordinates, CRS (zone, easting/northing order) and datum against the trajectory's",
            names(&out),
            list(&out)
        ));
    }
    if !near.is_empty() {
        why.push(format!(
            "no return in the windows of {}: the trajectory passed within the LiDAR's reach ({}), yet no return fell within {:.2} m of their centres: the a-priori mounting puts the returns elsewhere (check the site's [apriori] or --init: roll,pitch,heading in degrees, x,y,z in metres; or widen window_margin_m), the surveyed heights are off (their datum or unit), or the spheres were hidden",
            names(&near),
            list(&near),
            near.iter().map(|e| e.2).fold(0.0, f64::max)
        ));
    }
    (!why.is_empty()).then(|| why.join("; "))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An along-track pass offset blames a held time offset only when it was held (issue 46:
    /// the refusal blamed an unestimated offset that had been estimated).
    #[test]
    fn an_along_track_refusal_names_the_offset_as_it_was_treated() {
        let r = Refusal::Inconsistent {
            sphere: 1,
            pass: 7,
            offset: [0.14, 0.0, 0.0],
            along_track: -0.14,
            chi2: 63.0,
        };
        let ids = ["S1".to_string(), "S2".to_string()];
        let held = refusal_text(&r, &ids, &[], false);
        assert!(
            held.contains("it was held (drop --hold-time-offset)"),
            "{held}"
        );
        let free = refusal_text(&r, &ids, &[], true);
        assert!(
            free.contains("with the time offset estimated") && !free.contains("held"),
            "{free}"
        );
        assert!(
            free.starts_with("inconsistent: in pass 8 over sphere S2"),
            "{free}"
        );
    }
}

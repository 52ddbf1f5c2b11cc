//! The reports in words: a calibration's summary (a refusal first, then the mounting with its
//! sigmas, the passes, spheres and checks) and a Monte Carlo run's.

use super::{McReport, Report};
use spherecal::georef::{NAMES, P};
use std::fmt::Write as _;

/// A report's `termination` in words ("the rounds ended: ...").
pub fn termination_words(name: &str) -> String {
    spherecal::calib::Termination::words_of(name)
        .map_or_else(|| format!("ended: {name}"), |w| format!("ended: {w}"))
}

/// GPS seconds as UTC, `YYYY-MM-DD hh:mm:ss UTC` (`leap`: GPS - UTC [s]).
pub fn utc(gps_s: f64, leap: i64) -> String {
    let unix = spherecal::time::gps_to_unix_ns(
        spherecal::time::GpsTime((gps_s * 1e9).round() as i64),
        leap,
    );
    let t = spherecal::time::UtcDateTime::from_unix_ns(unix);
    format!(
        "{:04}-{:02}-{:02} {:02}:{:02}:{:02} UTC",
        t.year, t.month, t.day, t.hour, t.minute, t.second
    )
}

/// `v` with `prec` decimals, or `-` when it is not a number (no sigma without least squares).
fn num(v: f64, prec: usize) -> String {
    if v.is_finite() {
        format!("{v:.prec$}")
    } else {
        "-".into()
    }
}

/// The white noise found against the declared, in words: none when the solve stopped before
/// its least squares (never `xNaN`).
pub fn white_noise_words(variance_factor: f64) -> String {
    if variance_factor.is_finite() && variance_factor >= 0.0 {
        format!("white noise x{:.2} the declared", variance_factor.sqrt())
    } else {
        "white noise not estimated (the solve stopped before its least squares)".into()
    }
}

/// The human summary.
/// `truth`: roll, pitch, heading [deg], x, y, z [m], time offset [s].
pub fn render(r: &Report, truth: Option<&[f64; P + 1]>) -> String {
    let mut o = String::new();
    // A refusal comes first: the numbers below it are where the solver stopped, not a result.
    if let Some(why) = &r.reason {
        let _ = writeln!(
            o,
            "NOT CONVERGED: {why}\n(the values below are where the solver stopped, not a calibration)"
        );
    }
    parameters(&mut o, r, truth);
    fit(&mut o, r);
    navigation(&mut o, r);
    centres(&mut o, r);
    search_and_accuracy(&mut o, r);
    spheres(&mut o, r);
    closing(&mut o, r);
    o
}

/// The mounting and the time offset: start, solution, sigma (and truth, error).
fn parameters(o: &mut String, r: &Report, truth: Option<&[f64; P + 1]>) {
    let (b, s) = (r.deg_m(), r.sigma.deg_m());
    let _ = writeln!(
        o,
        "{:<10}{:>14}{:>12}{:>14}{}",
        "parameter",
        "start",
        "solution",
        "1-sigma",
        if truth.is_some() {
            "         truth      error"
        } else {
            ""
        }
    );
    for i in 0..P {
        let unit = if i < 3 { "deg" } else { "m" };
        let _ = write!(
            o,
            "{:<10}{:>14.4}{:>12}{:>10} {unit:<3}",
            NAMES[i],
            r.start[NAMES[i]],
            num(b[i], 5),
            num(s[i], 5)
        );
        if let Some(t) = truth {
            let _ = write!(o, "{:>14.4}{:>11.2e}", t[i], b[i] - t[i]);
        }
        let _ = writeln!(o);
    }
    // The time offset: INS time = LiDAR time + dt.
    let start = r.start.get("time_offset").copied().unwrap_or(0.0);
    if r.time_offset_estimated {
        let _ = write!(
            o,
            "{:<10}{:>14.4}{:>12}{:>10} {:<3}",
            "dt",
            start,
            num(r.time_offset_s, 6),
            num(r.sigma.time_offset_s, 6),
            "s"
        );
    } else {
        let _ = write!(
            o,
            "{:<10}{:>14.4}{:>12.6}{:>10} {:<3}",
            "dt", start, r.time_offset_s, "held", "s"
        );
    }
    if let Some(t) = truth {
        let _ = write!(o, "{:>14.4}{:>11.2e}", t[P], r.time_offset_s - t[P]);
    }
    let _ = writeln!(o);
}

/// The fit's figures and its consistency tests, with what was set aside after it.
fn fit(o: &mut String, r: &Report) {
    let _ = writeln!(
        o,
        "residual RMS {} mm, L1 {} m, condition number {}, centre RMS {}",
        num(r.rms_m * 1e3, 2),
        num(r.objective_l1_m, 4),
        if r.condition_number.is_finite() {
            format!("{:.3e}", r.condition_number)
        } else {
            "-".into()
        },
        r.sphere_centre_rms_m
            .map_or("-".into(), |c| format!("{:.2} mm", c * 1e3))
    );
    let c = &r.consistency;
    // Without least squares there is no consistency test to report.
    if c.dispersion.is_finite() {
        let _ = writeln!(
        o,
        "consistency: RMS {:.2}x the {:.1} mm the noise model predicts (limit 2); worst pass chi-square {:.1} (limit 25){}",
        c.dispersion,
        c.predicted_rms_m * 1e3,
        c.worst_pass_chi2,
        c.free_time_offset_s.map_or(String::new(), |[d, sg]| format!(
            "; time offset held, the data give {d:+.6} +- {sg:.6} s more"
        ))
    );
        let ([m, mp], [i, is]) = (c.misfit_pieces_set_aside, c.influential_set_aside);
        if m + i > 0 {
            let mut why = Vec::new();
            if m > 0 {
                why.push(format!(
                    "{m} returns in {mp} piece(s) the navigation model could not join to their neighbours"
                ));
            }
            if i > 0 {
                why.push(format!(
                    "{i} returns in {is} isolated stretch(es) that lay off the spheres and alone moved the answer beyond what their information can"
                ));
            }
            let _ = writeln!(
                o,
                "set aside after the fit (not the sphere: counted as undetected): {}",
                why.join("; ")
            );
        }
        if let Some([first, second, taken]) = c.second_start {
            let _ = writeln!(
                o,
                "a sphere was lost, so the rounds started again from the a-priori mounting: the spheres detected in {second} slices against {first} from the first start's consensus; {}",
                if taken == 1 {
                    "the second start's answer is this one"
                } else {
                    "the first start's answer kept"
                }
            );
        }
    }
}

/// The navigation model and its corrections over each stretch of the survey.
fn navigation(o: &mut String, r: &Report) {
    if let Some(n) = r.navigation.as_ref().filter(|n| n.is_white()) {
        let _ = writeln!(
            o,
            "navigation errors: white ({}); the sphere centres estimated with the mounting, each with its survey's sigma; {}",
            n.source,
            white_noise_words(n.white_noise_factor)
        );
    } else if let Some(n) = &r.navigation {
        let _ = writeln!(
            o,
            "navigation errors: estimated with the mounting ({}: {:.1} / {:.1} cm, {:.3} / {:.3} deg, wandering over {} s) in {} pieces; {}",
            n.source,
            n.position_sigma_m[0] * 1e2,
            n.position_sigma_m[1] * 1e2,
            n.attitude_sigma_deg[0],
            n.attitude_sigma_deg[1],
            n.correlation_s,
            n.pieces,
            white_noise_words(n.white_noise_factor)
        );
        if n.footprint_spread > 0.0 {
            let _ = writeln!(
                o,
                "  the range grows at grazing incidence: the returns weighed by the beam footprint's spread x{:.1}",
                n.footprint_spread
            );
        }
        // The corrections over each stretch of the survey (pieces less than 2 s apart; seconds
        // from the first), as means with the pieces' mean sigma (report.json has every piece).
        let t0 = n.corrections.first().map_or(0.0, |c| c.start_gps_s);
        let mut k = 0;
        while k < n.corrections.len() {
            let mut e = k + 1;
            while e < n.corrections.len()
                && n.corrections[e].start_gps_s - n.corrections[e - 1].end_gps_s < 2.0
            {
                e += 1;
            }
            let part = &n.corrections[k..e];
            let m = part.len() as f64;
            let mean = |f: &dyn Fn(&super::NavCorrectionReport) -> f64| {
                part.iter().map(f).sum::<f64>() / m
            };
            let _ = writeln!(
                o,
                "  {:.1} to {:.1} s ({} pieces): INS position off by N {:+.1} E {:+.1} D {:+.1} mm (+- {:.1} {:.1} {:.1}), heading {:+.4} deg (+- {:.4})",
                part[0].start_gps_s - t0,
                part[part.len() - 1].end_gps_s - t0,
                part.len(),
                mean(&|c| c.position_m[0]) * 1e3,
                mean(&|c| c.position_m[1]) * 1e3,
                mean(&|c| c.position_m[2]) * 1e3,
                mean(&|c| c.position_sigma_m[0]) * 1e3,
                mean(&|c| c.position_sigma_m[1]) * 1e3,
                mean(&|c| c.position_sigma_m[2]) * 1e3,
                mean(&|c| c.rotation_deg[2]),
                mean(&|c| c.rotation_sigma_deg[2]),
            );
            k = e;
        }
    }
}

/// The sphere centres' corrections from their survey.
fn centres(o: &mut String, r: &Report) {
    if let Some(n) = &r.navigation {
        for c in &n.centres {
            if c.prior_sigma_m <= 0.0 {
                let _ = writeln!(
                    o,
                    "  {}: centre held at its survey (the site declares no sigma_m)",
                    c.sphere
                );
                continue;
            }
            if c.correction_m
                .iter()
                .chain(&c.sigma_m)
                .any(|v| !v.is_finite())
            {
                let _ = writeln!(
                    o,
                    "  {}: centre not estimated (the solve stopped before its least squares; its survey's sigma {:.1} mm)",
                    c.sphere,
                    c.prior_sigma_m * 1e3
                );
                continue;
            }
            let [x, y, z] = c.correction_m.map(|v| v * 1e3);
            let [sx, sy, sz] = c.sigma_m.map(|v| v * 1e3);
            let _ = writeln!(
                o,
                "  {}: centre moved N {x:+.1} E {y:+.1} D {z:+.1} mm (+- {sx:.1} {sy:.1} {sz:.1}) from the survey (its sigma {:.1} mm)",
                c.sphere,
                c.prior_sigma_m * 1e3
            );
        }
    }
}

/// The time offset's search, what the calibration ran and the trajectory's accuracy file.
fn search_and_accuracy(o: &mut String, r: &Report) {
    if let (Some(a), Some(b)) = (r.time_offset_search.first(), r.time_offset_search.last()) {
        let found = r
            .time_offset_search
            .iter()
            .filter(|c| c.found_s.is_some())
            .count();
        let _ = writeln!(
            o,
            "time offset searched from {:+.2} to {:+.2} s in 0.25 s steps ({} starts, {found} converged; a search is kept to offsets that leave half the LiDAR data within the INS's)",
            a.start_s,
            b.start_s,
            r.time_offset_search.len()
        );
    }
    if let Some(e) = r
        .effort
        .filter(|e| e.collections > 1 || e.solves > e.collections)
    {
        let _ = writeln!(
            o,
            "ran {} collections of the windows, {} solves{}",
            e.collections,
            e.solves,
            match e.radius_probes {
                0 => String::new(),
                n => format!(", {n} radius probes"),
            }
        );
    }
    if let Some(a) = r.inputs.as_ref().and_then(|i| i.accuracy.as_ref()) {
        let _ = writeln!(
            o,
            "trajectory accuracy {}: {} returns weighted by their own INS sigma (position {:.1}-{:.1} mm, attitude {:.4}-{:.4} deg){}",
            a.file,
            a.returns_given,
            a.position_sigma_m[0] * 1e3,
            a.position_sigma_m[1] * 1e3,
            a.attitude_sigma_deg[0],
            a.attitude_sigma_deg[1],
            if a.returns_outside > 0 {
                format!("; {} outside its records use the site's noise", a.returns_outside)
            } else {
                String::new()
            }
        );
    }
}

/// Each sphere: what was kept and why the rest was not.
fn spheres(o: &mut String, r: &Report) {
    for p in &r.per_sphere {
        let v = &p.verdicts;
        if !p.found {
            let why = match p.lost.as_deref() {
                Some("no_returns") => "no returns in its window".to_string(),
                Some("not_detected") => "nothing sphere-like in its window".to_string(),
                Some("stopped") => {
                    let _ = writeln!(
                        o,
                        "  {}: {} windowed returns, found by the consensus in {} of {} slices; not solved (the reason above)",
                        p.id, p.windowed, p.agreed_slices, p.slices
                    );
                    continue;
                }
                Some("disagrees") => format!(
                    "sphere-like returns in {} of {} slices, none where the mounting the other spheres agree on puts it (clutter, a decoy, or the sphere hidden or moved)",
                    p.detected, p.slices
                ),
                _ => format!(
                    "detected in {} of {} slices, too few returns kept",
                    p.detected, p.slices
                ),
            };
            let _ = writeln!(
                o,
                "  {}: NOT FOUND among {} windowed returns: {why}; left out",
                p.id, p.windowed
            );
            continue;
        }
        let mut why = format!(
            "{} off the sphere, {} in slices without it",
            v.outside_shell, v.undetected
        );
        for (n, what) in [
            (v.plane, "on a plane"),
            (v.pole, "on a pole or stand"),
            (v.hidden_side, "behind it"),
        ] {
            if n > 0 {
                let _ = write!(why, ", {n} {what}");
            }
        }
        let _ = writeln!(
            o,
            "  {}: kept {} of {} windowed returns (the rounds kept {}), seen in {} of {} slices; rejected {} ({why}); RMS {:.2} mm",
            p.id,
            p.points,
            p.windowed,
            p.rounds_kept,
            p.detected,
            p.slices,
            v.rejected(),
            p.rms_after_m * 1e3
        );
    }
}

/// The prior, what was set aside, the clutter, the solver's effort and the verdict.
fn closing(o: &mut String, r: &Report) {
    o.push_str(&super::prior::words(&r.mounting_prior));
    let first = r.per_pass.iter().map(|p| p.start_gps_s).reduce(f64::min);
    for sp in &r.set_aside {
        let _ = writeln!(o, "SET ASIDE: {}", sp.describe(first));
    }
    let _ = writeln!(
        o,
        "clutter rejected: {} of {} windowed returns; kept: within {:.1} mm of a sphere",
        r.clutter_rejected,
        r.per_sphere.iter().map(|p| p.windowed).sum::<usize>(),
        r.shell_m * 1e3
    );
    if r.batch_overflow > 0 {
        let _ = writeln!(
            o,
            "WARNING: {} windowed returns lost to full batches",
            r.batch_overflow
        );
    }
    let _ = writeln!(o, "Nelder-Mead {} evaluations ({} iterations), {} detect-and-solve rounds ({}), LM {} iterations, {:.1} ms", r.evaluations, r.nm_iterations, r.rounds, termination_words(&r.termination), r.lm_iterations, r.solve_ms);
    match (&r.reason, &r.targets) {
        (None, Some(t)) if t.met => {
            let _ = writeln!(o, "converged: {}", t.words(r));
        }
        (None, Some(t)) => {
            let _ = writeln!(
                o,
                "converged, but {}; more passes or better sensors bring them in (`spherecal plan`): exit 3",
                t.words(r)
            );
        }
        (None, None) => {
            let _ = writeln!(o, "converged");
        }
        (Some(why), _) => {
            let _ = writeln!(o, "NOT CONVERGED: {why}");
        }
    }
}

/// Monte Carlo in words.
pub fn render_montecarlo(r: &McReport) -> String {
    let mut o = format!(
        "{}: {} trials from starts within +-{} deg / +-{} m of the truth (seed {})\nwithin 1e-3 deg / 1e-3 m: {:.1} %   claimed converged: {:.1} %   {:.1} ms per trial\nworst |error|:",
        r.scenario,
        r.trials,
        r.angle_noise_deg,
        r.lever_noise_m,
        r.seed,
        100.0 * r.fraction_within,
        100.0 * r.fraction_converged,
        r.ms_per_trial
    );
    for (i, (name, w)) in NAMES.iter().zip(&r.worst_error).enumerate() {
        o.push_str(&format!(
            " {name} {w:.2e}{}",
            if i < 3 { " deg" } else { " m" }
        ));
    }
    o.push('\n');
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A refusal before the least squares has no variance factor: said in words, never NaN.
    #[test]
    fn white_noise_without_a_fit_is_no_nan() {
        assert_eq!(white_noise_words(1.21), "white noise x1.10 the declared");
        for v in [f64::NAN, f64::INFINITY, -1.0] {
            let w = white_noise_words(v);
            assert!(w.contains("not estimated") && !w.contains("NaN"), "{w}");
        }
    }
}

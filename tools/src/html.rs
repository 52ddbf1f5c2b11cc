//! The calibration as one self-contained HTML page (`calibrate --html`): no script, no
//! network, the figures inline SVG ([`crate::plot`]). In the order a surveyor reads it: the
//! verdict (and the refusal's reason), the parameters with their sigma and change from the
//! start, the checks, the inputs and their state, each sphere and pass, the correlations, and
//! the figures.

use crate::plot::{sphere_figures, strip_xml_header, Figures};
use crate::report::{utc, Report};
use spherecal::georef::{NAMES, P};
use std::fmt::Write as _;

mod cover;

/// Under this long [s] (or under 3 scan slices) a pass is a glimpse.
const GLIMPSE_S: f64 = 1.5;

/// `s` with `&`, `<`, `>` and `"` escaped.
pub fn escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            _ => o.push(c),
        }
    }
    o
}

/// `v` with `prec` decimals, or a dash when it is not a number.
fn num(v: f64, prec: usize) -> String {
    if v.is_finite() {
        format!("{v:.prec$}")
    } else {
        "&ndash;".into()
    }
}

/// The pages' style sheet.
pub const STYLE: &str = "body{font-family:sans-serif;margin:24px;color:#222;max-width:1500px}
h1{font-size:22px}h2{font-size:18px;margin-top:28px;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f2f2f2}td.l,th.l{text-align:left}
.ok{background:#e3f4e3;border:2px solid #3a3;padding:10px 14px;font-size:17px}
.no{background:#fbe4e4;border:2px solid #c33;padding:10px 14px;font-size:17px}
.short{background:#fdf3d8;border:2px solid #c90;padding:10px 14px;font-size:17px}
.figs{display:flex;flex-wrap:wrap;gap:6px}.figs svg{border:1px solid #ddd}
.note{color:#555;font-size:13px}tr.dim td{color:#999}tr.bad td{background:#fbe4e4}";

/// The page.
pub fn render(r: &Report, figs: &Figures, leap: i64) -> Result<String, crate::Error> {
    let mut o = String::new();
    let title = r
        .inputs
        .as_ref()
        .map_or("calibration".to_string(), |i| i.pcap.clone());
    let _ = write!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>spherecal: {}</title><style>{STYLE}</style></head><body>\n",
        escape(&title)
    );
    let _ = writeln!(
        o,
        "<h1>LiDAR boresight and lever-arm calibration</h1><p class=\"note\">{} &middot; written {}</p>",
        escape(&r.version),
        utc(
            spherecal::time::unix_ns_to_gps(spherecal_hal::clock::wall().0, leap).as_secs_f64(),
            leap
        )
    );
    cover::cover(&mut o, r, leap);
    o.push_str("<h2>Details</h2>\n");
    parameters(&mut o, r);
    checks(&mut o, r);
    inputs(&mut o, r, leap);
    spheres(&mut o, r);
    navigation(&mut o, r, leap);
    correlation(&mut o, r);
    search(&mut o, r);
    figures(&mut o, figs)?;
    o.push_str("</body></html>\n");
    Ok(o)
}

/// The verdict in one banner (on the cover sheet).
fn verdict(o: &mut String, r: &Report) {
    match &r.reason {
        None if r.targets.as_ref().is_some_and(|t| !t.met) => {
            let t = r.targets.as_ref().map(|t| t.words(r)).unwrap_or_default();
            let _ = writeln!(
                o,
                "<p class=\"short\"><b>Converged, but the sigmas miss the targets: not enough to use.</b> The solution passed the consistency tests, but {} More passes or better sensors bring them in (<code>spherecal plan</code>). Exit 3.</p>",
                escape(&format!("{t}."))
            );
        }
        None => {
            let t = r
                .targets
                .as_ref()
                .map(|t| format!(" {}.", t.words(r)))
                .unwrap_or_default();
            let _ = writeln!(
                o,
                "<p class=\"ok\"><b>Converged.</b> The solution passed the consistency tests (residuals as the noise model predicts, every pass agreeing, the geometry well conditioned).{}</p>",
                escape(&t)
            );
        }
        Some(why) => {
            let _ = writeln!(
                o,
                "<p class=\"no\"><b>Refused: no calibration is claimed.</b> {}<br>The values below are where the solver stopped.</p>",
                escape(why)
            );
        }
    }
}

fn parameters(o: &mut String, r: &Report) {
    o.push_str("<h2>Mounting</h2><table><tr><th class=\"l\">parameter</th><th>start</th><th>solution</th><th>1-sigma</th><th>change</th><th class=\"l\">unit</th></tr>\n");
    let (b, s) = (r.deg_m(), r.sigma.deg_m());
    let label = [
        "boresight roll",
        "boresight pitch",
        "boresight heading",
        "lever arm x",
        "lever arm y",
        "lever arm z",
    ];
    for i in 0..P {
        let start = r.start.get(NAMES[i]).copied().unwrap_or(f64::NAN);
        let (unit, prec) = if i < 3 { ("deg", 5) } else { ("m", 5) };
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{}</td><td>{}</td><td><b>{}</b></td><td>{}</td><td>{}</td><td class=\"l\">{unit}</td></tr>",
            label[i],
            num(start, 4),
            num(b[i], prec),
            num(s[i], prec),
            num(b[i] - start, prec)
        );
    }
    let start = r.start.get("time_offset").copied().unwrap_or(0.0);
    let _ = writeln!(
        o,
        "<tr><td class=\"l\">time offset (INS - LiDAR)</td><td>{}</td><td><b>{}</b></td><td>{}</td><td>{}</td><td class=\"l\">s</td></tr></table>",
        num(start, 4),
        num(r.time_offset_s, 6),
        if r.time_offset_estimated {
            num(r.sigma.time_offset_s, 6)
        } else {
            "held".into()
        },
        num(r.time_offset_s - start, 6)
    );
    if !r.held.is_empty() {
        let _ = writeln!(
            o,
            "<p class=\"short\"><b>Held, not calibrated:</b> {}: the data do not determine {} under this navigation model; {} at the a-priori value, the sigma the hold's. Measure it on the vessel ([apriori] sigmas) or declare the INS's real accuracy.</p>",
            escape(&r.held.join(", ")),
            if r.held.len() > 1 { "them" } else { "it" },
            if r.held.len() > 1 { "they stay" } else { "it stays" }
        );
    }
    if !r.mounting_prior.is_empty() {
        o.push_str("<h3>As measured on the vessel</h3><table><tr><th class=\"l\">parameter</th><th>measured</th><th>1-sigma</th><th>calibration - measured</th><th>z</th></tr>\n");
        for m in &r.mounting_prior {
            let warn = if m.z.abs() > 3.0 {
                " class=\"bad\""
            } else {
                ""
            };
            let _ = writeln!(
                o,
                "<tr{warn}><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                escape(&m.parameter),
                num(m.measured, 5),
                num(m.sigma, 5),
                num(m.moved, 5),
                num(m.z, 1)
            );
        }
        o.push_str("</table>\n");
    }
    o.push_str("<p class=\"note\">Roll, pitch, heading rotate the LiDAR frame into the INS body frame (z-y-x, DESIGN.md); the lever arm is the LiDAR origin in the INS body frame.</p>\n");
}

fn checks(o: &mut String, r: &Report) {
    let c = &r.consistency;
    o.push_str("<h2>Checks</h2><table>");
    let mut row = |k: &str, v: String, limit: &str| {
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{k}</td><td>{v}</td><td class=\"l\">{limit}</td></tr>"
        );
    };
    row(
        "residual RMS",
        format!("{} mm", num(r.rms_m * 1e3, 2)),
        &format!(
            "each kept return's distance to its sphere's surface, with the solution, over all spheres; the noise model predicts {} mm",
            num(c.predicted_rms_m * 1e3, 2)
        ),
    );
    row(
        "dispersion (RMS / predicted)",
        num(c.dispersion, 2),
        "refused above 2",
    );
    row(
        "worst pass chi-square",
        num(c.worst_pass_chi2, 1),
        "refused above 25 (3 degrees of freedom) with more than 3 mm",
    );
    row(
        "condition number",
        if r.condition_number.is_finite() {
            format!("{:.3e}", r.condition_number)
        } else {
            "&ndash;".into()
        },
        "refused above 1000; parameters named weak above 100",
    );
    row(
        "weak parameters",
        if r.weak_parameters.is_empty() {
            "none".into()
        } else {
            escape(&r.weak_parameters.join(", "))
        },
        "",
    );
    row(
        "fitted minus surveyed centres, RMS",
        r.sphere_centre_rms_m
            .map_or("&ndash;".into(), |v| format!("{:.2} mm", v * 1e3)),
        "each sphere fitted to its own kept returns (radius held) against its surveyed centre: the survey and the calibration together, not a residual",
    );
    if let Some([d, s]) = c.free_time_offset_s {
        row(
            "time offset held; the data give",
            format!("{d:+.6} &plusmn; {s:.6} s more"),
            "refused beyond 5 sigma and 1 ms",
        );
    }
    row(
        "clutter rejected",
        format!(
            "{} of {} windowed returns",
            r.clutter_rejected,
            r.per_sphere.iter().map(|p| p.windowed).sum::<usize>()
        ),
        &format!("kept: within {:.1} mm of a sphere", r.shell_m * 1e3),
    );
    row(
        "solver",
        format!(
            "{} rounds, {} Nelder-Mead evaluations, {} LM iterations, {:.1} ms",
            r.rounds, r.evaluations, r.lm_iterations, r.solve_ms
        ),
        &escape(&format!(
            "the rounds {}",
            crate::report::termination_words(&r.termination)
        )),
    );
    if r.batch_overflow > 0 {
        row(
            "<b>returns lost to full batches</b>",
            r.batch_overflow.to_string(),
            "never expected",
        );
    }
    o.push_str("</table>\n");
}

fn inputs(o: &mut String, r: &Report, leap: i64) {
    let Some(i) = &r.inputs else { return };
    o.push_str("<h2>Inputs</h2><table>");
    let mut row = |k: &str, v: String| {
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{k}</td><td class=\"l\">{v}</td></tr>"
        );
    };
    row("LiDAR capture", escape(&i.pcap));
    row(
        "data packets",
        format!(
            "{}{}",
            i.data_packets,
            i.lidar_span_gps_s.map_or(String::new(), |(a, b)| format!(
                " from {} to {} ({:.1} s)",
                utc(a, leap),
                utc(b, leap),
                b - a
            ))
        ),
    );
    let skipped: u64 = i.skipped.values().sum();
    row(
        "skipped",
        if skipped == 0 {
            "none".into()
        } else {
            escape(
                &i.skipped
                    .iter()
                    .map(|(k, v)| format!("{k}: {v}"))
                    .collect::<Vec<_>>()
                    .join("; "),
            )
        },
    );
    row(
        "LiDAR clock",
        format!(
            "{}{}",
            escape(&i.clock.describe()),
            if i.clock_trusted {
                ""
            } else {
                " &mdash; <b>not trusted</b>"
            }
        ),
    );
    row("trajectory", escape(&i.ins));
    row("trajectory state", escape(&i.ins_state.describe()));
    if let Some(a) = &i.accuracy {
        row(
            "trajectory accuracy",
            format!(
                "{}: {} returns weighted by their own sigma (position {:.1}&ndash;{:.1} mm, attitude {:.4}&ndash;{:.4} deg); {} outside its records",
                escape(&a.file),
                a.returns_given,
                a.position_sigma_m[0] * 1e3,
                a.position_sigma_m[1] * 1e3,
                a.attitude_sigma_deg[0],
                a.attitude_sigma_deg[1],
                a.returns_outside
            ),
        );
    }
    let [b, a, g] = i.not_georeferenced;
    row(
        "returns not georeferenced",
        format!("{b} before the trajectory, {a} after it, {g} in its gaps"),
    );
    row(
        "time offset applied to the windows",
        format!("{:.6} s", i.time_offset_applied_s),
    );
    o.push_str("</table>\n");
}

fn spheres(o: &mut String, r: &Report) {
    o.push_str("<h2>Spheres</h2><table><tr><th class=\"l\">sphere</th><th>windowed</th><th>kept</th><th>seen in slices</th><th>residual RMS at the start [mm]</th><th>residual RMS, solution [mm]</th><th>fitted - surveyed N, E, D [mm]</th><th class=\"l\">rejected</th></tr>\n");
    for p in &r.per_sphere {
        let v = &p.verdicts;
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{} of {}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr>",
            escape(&p.id),
            p.windowed,
            if p.found { p.points.to_string() } else { "<b>not found</b>".into() },
            p.detected,
            p.slices,
            num(p.rms_before_m * 1e3, 1),
            num(p.rms_after_m * 1e3, 2),
            p.centre_offset_m.map_or("&ndash;".into(), |c| format!(
                "{:+.1}, {:+.1}, {:+.1}",
                c[0] * 1e3,
                c[1] * 1e3,
                c[2] * 1e3
            )),
            format_args!(
                "{} off the sphere, {} in slices without it, {} on a plane, {} on a pole, {} behind it",
                v.outside_shell, v.undetected, v.plane, v.pole, v.hidden_side
            )
        );
    }
    o.push_str("</table>\n<h3>Passes</h3><table><tr><th class=\"l\">sphere</th><th>pass</th><th>start [s]</th><th>duration [s]</th><th>windowed</th><th>kept</th><th>detected slices</th><th>centre offset [mm]</th><th>along track [mm]</th><th>chi-square</th></tr>\n");
    let t0 = r
        .per_pass
        .iter()
        .map(|p| p.start_gps_s)
        .fold(f64::INFINITY, f64::min);
    let mut count: std::collections::BTreeMap<&str, usize> = Default::default();
    for p in &r.per_pass {
        let k = count.entry(p.sphere.as_str()).or_default();
        *k += 1;
        let c = p.centre_offset_m;
        let d = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        // A glimpse: the sphere seen for a moment (in a turn), not a pass to judge.
        let glimpse = p.end_gps_s - p.start_gps_s < GLIMPSE_S || p.slices < 3;
        let _ = writeln!(
            o,
            "<tr{}><td class=\"l\">{}</td><td>{k}{}</td><td>{:.1}</td><td>{:.1}</td><td>{}</td><td>{}</td><td>{} of {}</td><td>{:.1}</td><td>{:+.1}</td><td>{:.1}</td></tr>",
            if glimpse { " class=\"dim\"" } else { "" },
            escape(&p.sphere),
            if glimpse { " (a glimpse)" } else { "" },
            p.start_gps_s - t0,
            p.end_gps_s - p.start_gps_s,
            p.windowed,
            p.verdicts.kept,
            p.detected,
            p.slices,
            d * 1e3,
            p.along_track_m * 1e3,
            p.chi2
        );
    }
    o.push_str("</table><p class=\"note\">Pass: numbered per sphere in time order, as in the figures. Start: seconds after the first pass. Centre offset: the sphere fitted to the pass's own returns with the solution, minus the surveyed centre (zero under 10 returns). A glimpse (greyed): the sphere seen for under 1.5 s or in fewer than 3 scan slices, in a turn or at the edge of the view: its returns count in the calibration, but it is too short to judge as a pass.</p>\n");
}

/// The navigation model's section: the model, each centre's correction, and the corrections
/// to the INS along the survey (one row a second of pieces: report.json has every piece).
fn navigation(o: &mut String, r: &Report, leap: i64) {
    let Some(n) = &r.navigation else {
        return;
    };
    if n.is_white() {
        let _ = writeln!(
            o,
            "<h2>Sphere centres</h2><p class=\"note\">The INS errors white ({}); the sphere centres estimated with the mounting, each with its survey's sigma (0: held); the white noise found {}x the declared.</p>",
            escape(&n.source),
            num(n.white_noise_factor.sqrt(), 2)
        );
    } else {
        let _ = writeln!(
        o,
        "<h2>Navigation errors</h2><p class=\"note\">Estimated with the mounting under {} (position {} / {} cm, attitude {} / {} deg, correlation {} s) in {} pieces; the white noise found {}x the declared{}. Reported minus true: subtract from the INS.</p>",
        escape(&n.source),
        num(n.position_sigma_m[0] * 1e2, 1),
        num(n.position_sigma_m[1] * 1e2, 1),
        num(n.attitude_sigma_deg[0], 3),
        num(n.attitude_sigma_deg[1], 3),
        num(n.correlation_s, 0),
        n.pieces,
        num(n.white_noise_factor.sqrt(), 2),
        if n.footprint_spread > 0.0 {
            format!(
                "; the range grows at grazing incidence (the returns weighed by the beam footprint's spread x{})",
                num(n.footprint_spread, 1)
            )
        } else {
            String::new()
        }
    );
    }
    o.push_str("<table><tr><th class=\"l\">sphere</th><th>survey sigma [mm]</th><th>centre moved N, E, D [mm]</th><th>1-sigma N, E, D [mm]</th></tr>\n");
    for c in &n.centres {
        let mm = |v: [f64; 3]| v.map(|x| num(x * 1e3, 1)).join(", ");
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            escape(&c.sphere),
            num(c.prior_sigma_m * 1e3, 1),
            mm(c.correction_m),
            mm(c.sigma_m)
        );
    }
    o.push_str("</table>\n");
    if n.corrections.is_empty() {
        return;
    }
    match crate::plot::nav_corrections(&n.corrections) {
        Ok(Some(svg)) => {
            let _ = writeln!(
                o,
                "<figure>{}<figcaption>The corrections to the INS the calibration estimated, against time, with their 1-sigma band (one line per stretch of contiguous pieces: a pass and its turn).</figcaption></figure>",
                crate::plot::strip_xml_header(&svg)
            );
        }
        Ok(None) => {}
        Err(e) => {
            let _ = writeln!(
                o,
                "<p class=\"no\">The navigation figure failed: {}</p>",
                escape(&e.to_string())
            );
        }
    }
    o.push_str("<details><summary>The corrections to the INS, second by second (table)</summary>");
    o.push_str("<table><tr><th class=\"l\">time</th><th>pieces</th><th>position N, E, D [mm]</th><th>1-sigma [mm]</th><th>heading [deg]</th><th>1-sigma [deg]</th></tr>\n");
    let mut k = 0;
    while k < n.corrections.len() {
        let second = n.corrections[k].start_gps_s.floor();
        let mut e = k + 1;
        while e < n.corrections.len() && n.corrections[e].start_gps_s.floor() == second {
            e += 1;
        }
        let part = &n.corrections[k..e];
        let mean = |f: &dyn Fn(&crate::report::NavCorrectionReport) -> f64| {
            part.iter().map(f).sum::<f64>() / part.len() as f64
        };
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}, {}, {}</td><td>{}, {}, {}</td><td>{}</td><td>{}</td></tr>",
            utc(part[0].start_gps_s, leap),
            part.len(),
            num(mean(&|c| c.position_m[0]) * 1e3, 1),
            num(mean(&|c| c.position_m[1]) * 1e3, 1),
            num(mean(&|c| c.position_m[2]) * 1e3, 1),
            num(mean(&|c| c.position_sigma_m[0]) * 1e3, 1),
            num(mean(&|c| c.position_sigma_m[1]) * 1e3, 1),
            num(mean(&|c| c.position_sigma_m[2]) * 1e3, 1),
            num(mean(&|c| c.rotation_deg[2]), 4),
            num(mean(&|c| c.rotation_sigma_deg[2]), 4)
        );
        k = e;
    }
    o.push_str("</table></details>\n");
}

fn correlation(o: &mut String, r: &Report) {
    if r.correlation.is_empty() {
        return;
    }
    let n = if r.time_offset_estimated { P + 1 } else { P };
    let labels: Vec<String> = (0..n)
        .map(|i| {
            r.correlation_labels
                .get(i)
                .cloned()
                .unwrap_or_else(|| i.to_string())
        })
        .collect();
    o.push_str("<h2>Correlations</h2><table><tr><th></th>");
    for l in &labels {
        let _ = write!(o, "<th>{}</th>", escape(l));
    }
    o.push_str("</tr>\n");
    for (i, l) in labels.iter().enumerate() {
        let _ = write!(o, "<tr><th class=\"l\">{}</th>", escape(l));
        for j in 0..n {
            let v = r
                .correlation
                .get(i)
                .and_then(|row| row.get(j))
                .copied()
                .unwrap_or(f64::NAN);
            // Shade by |r|: white at 0, red at 1.
            let a = if v.is_finite() { v.abs().min(1.0) } else { 0.0 };
            let g = (255.0 - 150.0 * a) as u8;
            let _ = write!(
                o,
                "<td style=\"background:rgb(255,{g},{g})\">{}</td>",
                num(v, 2)
            );
        }
        o.push_str("</tr>\n");
    }
    o.push_str("</table>\n");
}

fn search(o: &mut String, r: &Report) {
    if r.time_offset_search.is_empty() {
        return;
    }
    o.push_str("<h2>Time offset search</h2><table><tr><th>start [s]</th><th>found [s]</th><th>returns kept</th><th>RMS [mm]</th></tr>\n");
    for c in &r.time_offset_search {
        let _ = writeln!(
            o,
            "<tr><td>{:+.2}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            c.start_s,
            c.found_s.map_or("&ndash;".into(), |f| format!("{f:+.4}")),
            c.kept,
            c.rms_m.map_or("&ndash;".into(), |v| num(v * 1e3, 2))
        );
    }
    o.push_str("</table>\n");
}

fn figures(o: &mut String, f: &Figures) -> Result<(), crate::Error> {
    o.push_str("<h2>Figures</h2><p class=\"note\">Per sphere: the kept returns' distance from the surveyed sphere's surface with the starting mounting and with the solution (each histogram on its own axis), the residuals after against time coloured by pass, and cross-sections at 1:1 (horizontal distance from the surveyed centre against height above it; the line is the sphere).</p>\n");
    if f.spheres.is_empty() {
        o.push_str("<p>No sphere returns were kept: nothing to draw.</p>\n");
    }
    for d in &f.spheres {
        let _ = writeln!(o, "<h3>{}</h3><div class=\"figs\">", escape(&d.id));
        for svg in sphere_figures(d)? {
            o.push_str(strip_xml_header(&svg));
            o.push('\n');
        }
        o.push_str("</div>\n");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup() {
        assert_eq!(
            escape("<a href=\"x\">&</a>"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&lt;/a&gt;"
        );
    }

    /// By hand: 2024-06-12 11:00:00 UTC is Unix 1718190000 (19886 days x 86400 + 39600); the
    /// GPS epoch is Unix 315964800, and GPS ran 18 s ahead of UTC then.
    #[test]
    fn gps_seconds_as_utc() {
        let gps = 1_718_190_000.0 - 315_964_800.0 + 18.0;
        assert_eq!(utc(gps, 18), "2024-06-12 11:00:00 UTC");
    }
}

//! The page's first screen, a cover sheet to file (issue 47 item 7): the verdict, the
//! mounting with its sigmas against the targets, the checks in one line, what was calibrated
//! from (the site, the inputs with their SHA-256, the command and the build), when. The
//! details follow it.

use super::{escape, num};
use crate::report::{utc, Report};
use spherecal::georef::{NAMES, P};
use std::fmt::Write as _;

/// The cover sheet.
pub(super) fn cover(o: &mut String, r: &Report, leap: i64) {
    o.push_str("<section class=\"cover\"><h2>Cover sheet</h2>\n");
    super::verdict(o, r);
    mounting(o, r);
    checks_line(o, r);
    source(o, r, leap);
    o.push_str("</section>\n");
}

/// The six with their sigmas, each against its target.
fn mounting(o: &mut String, r: &Report) {
    let (b, s) = (r.deg_m(), r.sigma.deg_m());
    let t = r.targets.as_ref();
    let names = NAMES;
    o.push_str("<table><tr><th class=\"l\">mounting</th><th>value</th><th>1-sigma</th><th>target</th><th class=\"l\">meets it</th></tr>\n");
    for i in 0..P {
        let (unit, target) = if i < 3 {
            ("deg", t.and_then(|t| t.sigma_deg))
        } else {
            ("m", t.and_then(|t| t.sigma_m))
        };
        let missed = t.is_some_and(|t| t.missed.iter().any(|m| m == names[i]));
        let held = r.held.iter().any(|h| h == names[i]);
        let _ = writeln!(
            o,
            "<tr{}><td class=\"l\">{}</td><td><b>{}</b> {unit}</td><td>{} {unit}</td><td>{}</td><td class=\"l\">{}</td></tr>",
            if missed || held { " class=\"bad\"" } else { "" },
            names[i],
            num(b[i], 5),
            num(s[i], 5),
            target.map_or("-".into(), |v| format!("{} {unit}", num(v, 4))),
            if held {
                "held at its a-priori value: not determined"
            } else if missed {
                "no"
            } else if t.is_some() {
                "yes"
            } else {
                "-"
            }
        );
    }
    let _ = writeln!(
        o,
        "<tr><td class=\"l\">time offset (INS - LiDAR)</td><td><b>{}</b> s</td><td>{}</td><td>-</td><td class=\"l\">-</td></tr></table>",
        num(r.time_offset_s, 6),
        if r.time_offset_estimated {
            format!("{} s", num(r.sigma.time_offset_s, 6))
        } else {
            "held".into()
        }
    );
}

/// The consistency checks in one line.
fn checks_line(o: &mut String, r: &Report) {
    let c = &r.consistency;
    let _ = writeln!(
        o,
        "<p>Checks: residual RMS {} mm against {} mm predicted by the noise model (ratio {}, refused above 2); the worst pass chi-square {} (refused above 25); {} passes over {} spheres; condition number {}.</p>",
        num(r.rms_m * 1e3, 1),
        num(c.predicted_rms_m * 1e3, 1),
        num(c.dispersion, 2),
        num(c.worst_pass_chi2, 1),
        r.per_pass.len(),
        r.per_sphere.len(),
        num(r.condition_number, 0)
    );
}

/// The site, the inputs and the build; the survey's date.
fn source(o: &mut String, r: &Report, leap: i64) {
    let Some(p) = &r.provenance else {
        return;
    };
    let first = p
        .inputs
        .iter()
        .filter_map(|i| i.gps_span_s.map(|s| s.0))
        .reduce(f64::min);
    let _ = writeln!(
        o,
        "<table><tr><th class=\"l\">surveyed</th><td class=\"l\">{}</td></tr><tr><th class=\"l\">site</th><td class=\"l\">{} ({} spheres; {}; heights {}; {})</td></tr>",
        first.map_or("-".into(), |t| escape(&utc(t, leap))),
        escape(&p.site.file.path),
        p.site.spheres.len(),
        escape(p.site.crs.as_deref().unwrap_or("latitude, longitude")),
        escape(p.site.heights.as_deref().unwrap_or("ellipsoidal")),
        escape(&p.site.transformation)
    );
    if let Some(pl) = &p.platform {
        let board = match (&pl.board_name, &pl.board) {
            (Some(n), Some(f)) => format!("board {} ({})", escape(n), escape(&f.path)),
            _ => "-".into(),
        };
        let _ = writeln!(
            o,
            "<tr><th class=\"l\">vessel</th><td class=\"l\">{} ({board})</td></tr><tr><th class=\"l\">operator</th><td class=\"l\">{}</td></tr>",
            escape(pl.vessel.as_deref().unwrap_or("-")),
            escape(pl.operator.as_deref().unwrap_or("-"))
        );
    }
    for i in &p.inputs {
        let _ = writeln!(
            o,
            "<tr><th class=\"l\">{}</th><td class=\"l\">{} ({} bytes, SHA-256 {}...)</td></tr>",
            escape(&i.role),
            escape(&i.path),
            i.bytes,
            escape(i.sha256.get(..16).unwrap_or(&i.sha256))
        );
    }
    let _ = writeln!(
        o,
        "<tr><th class=\"l\">command</th><td class=\"l\"><code>{}</code></td></tr><tr><th class=\"l\">build</th><td class=\"l\">{} (report made {})</td></tr></table>",
        escape(&p.command.join(" ")),
        escape(&p.version),
        escape(&p.made_utc)
    );
}

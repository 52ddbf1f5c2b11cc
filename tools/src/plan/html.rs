//! The plan as one self-contained HTML page (`plan --report OUT.html`): the verdict, the
//! predicted sigmas against the targets (a table and a bar chart), the plan from above (each
//! pass coloured by its share of the information, the spheres), what each pass and sphere
//! brings, the recommendations, the correlations. No script, no network; inline SVG.

use super::{segments, PlanReport, Segment};
use crate::config::scenario::Scenario;
use crate::html::escape;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use spherecal::georef::{NAMES, P};
use std::fmt::Write as _;

fn e<E: std::fmt::Display>(x: E) -> String {
    x.to_string()
}

/// A colour from light grey (share 0) to deep red (share 1).
fn heat(share: f64) -> RGBColor {
    let s = share.clamp(0.0, 1.0);
    let mix = |a: f64, b: f64| (a + (b - a) * s) as u8;
    RGBColor(mix(200.0, 180.0), mix(200.0, 20.0), mix(200.0, 30.0))
}

/// A convex polygon clipped to the box `[x0, x1, y0, y1]` (Sutherland-Hodgman).
fn clip(mut poly: Vec<(f64, f64)>, b: [f64; 4]) -> Vec<(f64, f64)> {
    // Each edge of the box: inside when `s * (coordinate - at) >= 0`.
    for (axis, at, s) in [
        (0, b[0], 1.0),
        (0, b[1], -1.0),
        (1, b[2], 1.0),
        (1, b[3], -1.0),
    ] {
        let val = |p: (f64, f64)| s * (if axis == 0 { p.0 } else { p.1 } - at);
        let mut out = Vec::with_capacity(poly.len() + 2);
        for k in 0..poly.len() {
            let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
            let (vp, vq) = (val(p), val(q));
            if vp >= 0.0 {
                out.push(p);
            }
            if (vp >= 0.0) != (vq >= 0.0) {
                let f = vp / (vp - vq);
                out.push((p.0 + f * (q.0 - p.0), p.1 + f * (q.1 - p.1)));
            }
        }
        poly = out;
        if poly.is_empty() {
            break;
        }
    }
    poly
}

/// The map's chart: east and north in metres.
type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A segment and its points from above (east, north) [m].
type Path = (Segment, Vec<(f64, f64)>);

/// Each segment's path from above (east, north), sampled every 0.5 s.
fn paths_of(s: &Scenario) -> Result<Vec<Path>, crate::Error> {
    let segs = segments(s);
    let paths = s
        .with_world(|w| {
            segs.iter()
                .map(|&(seg, a, b)| {
                    let (a, b) = if a.is_finite() {
                        (a, b)
                    } else {
                        (0.0, w.trajectory.duration())
                    };
                    let n = ((b - a) / 0.5).ceil().max(1.0) as usize;
                    let pts = (0..=n)
                        .map(|k| {
                            let st = w.trajectory.state(a + (b - a) * k as f64 / n as f64);
                            (st.position.y, st.position.x)
                        })
                        .collect();
                    (seg, pts)
                })
                .collect()
        })
        .map_err(|e| e.to_string())?;
    Ok(paths)
}

/// The first recommendation's new passes (east, north from start to end), numbered.
fn proposed_passes(r: &PlanReport) -> Vec<[(f64, f64); 2]> {
    r.recommendations
        .first()
        .map(|rec| {
            rec.changes
                .iter()
                .filter_map(|c| match c {
                    super::recommend::Change::AddPass(p) => {
                        let (h, d) = (p.heading_deg.to_radians(), p.speed_mps * p.duration_s);
                        let (n, e) = (p.start_ne_m[0], p.start_ne_m[1]);
                        Some([(e, n), (e + d * h.sin(), n + d * h.cos())])
                    }
                    _ => None,
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The view: the paths, the proposed passes and the spheres with a margin (east from, to;
/// north from, to).
fn view(s: &Scenario, paths: &[Path], proposed: &[[(f64, f64); 2]]) -> (f64, f64, f64, f64) {
    let all = paths
        .iter()
        .flat_map(|p| p.1.iter().copied())
        .chain(proposed.iter().flatten().copied())
        .chain(s.sphere.iter().map(|sp| (sp.ned_m[1], sp.ned_m[0])));
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for (x, y) in all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let pad = 0.08 * (x1 - x0).max(y1 - y0).max(10.0);
    (x0 - pad, x1 + pad, y0 - pad, y1 + pad)
}

/// The site as a map: its buildings, vehicles and structures (boxes) and its posts and
/// trees (poles) from above, in grey, within the view `[x0, x1, y0, y1]`.
fn draw_site(
    ch: &mut Chart<'_, '_>,
    s: &Scenario,
    [x0, x1, y0, y1]: [f64; 4],
) -> Result<(), crate::Error> {
    let grey = RGBColor(205, 205, 205);
    let inside = |(x, y): (f64, f64)| (x0..=x1).contains(&x) && (y0..=y1).contains(&y);
    for b in &s.boxes {
        let (h, [n, e0]) = (b.heading_deg.to_radians(), [b.center_m[0], b.center_m[1]]);
        let corner = |u: f64, v: f64| {
            let (du, dv) = (u * b.size_m[0] / 2.0, v * b.size_m[1] / 2.0);
            (
                e0 + du * h.sin() + dv * h.cos(),
                n + du * h.cos() - dv * h.sin(),
            )
        };
        let ring = vec![
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ];
        // Drawn where it overlaps the view (a deck or a quay wall may hold it all).
        let (bx0, bx1, by0, by1) = ring.iter().fold(
            (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ),
            |(a, b, c, d), &(x, y)| (a.min(x), b.max(x), c.min(y), d.max(y)),
        );
        if bx1 >= x0 && bx0 <= x1 && by1 >= y0 && by0 <= y1 {
            let ring = clip(ring, [x0, x1, y0, y1]);
            ch.draw_series([Polygon::new(ring, grey.filled())])
                .map_err(e)?;
        }
    }
    for p in &s.poles {
        let c = (p.base_m[1], p.base_m[0]);
        if inside(c) {
            ch.draw_series([Circle::new(c, 3, grey.filled())])
                .map_err(e)?;
        }
    }
    Ok(())
}

/// The recommended passes (dashed, numbered R1, R2, ...) and the spheres.
fn draw_proposed_and_spheres(
    ch: &mut Chart<'_, '_>,
    s: &Scenario,
    proposed: &[[(f64, f64); 2]],
) -> Result<(), crate::Error> {
    let green = RGBColor(20, 140, 60);
    for (k, [a, b]) in proposed.iter().enumerate() {
        ch.draw_series(DashedLineSeries::new([*a, *b], 6, 4, green.stroke_width(2)))
            .map_err(e)?;
        ch.draw_series([Circle::new(*b, 3, green.filled())])
            .map_err(e)?;
        ch.draw_series([Text::new(
            format!("R{}", k + 1),
            {
                // Staggered along the line, so that passes on one track keep apart.
                let f = 0.2 + 0.15 * (k % 5) as f64;
                (a.0 + f * (b.0 - a.0) + 0.8, a.1 + f * (b.1 - a.1))
            },
            ("sans-serif", 13).into_font().color(&green),
        )])
        .map_err(e)?;
    }
    for sp in &s.sphere {
        let c = (sp.ned_m[1], sp.ned_m[0]);
        ch.draw_series([Circle::new(c, 5, RGBColor(30, 90, 180).filled())])
            .map_err(e)?;
        ch.draw_series([Text::new(
            sp.id.clone(),
            (c.0 + 0.8, c.1 + 0.8),
            ("sans-serif", 12).into_font().color(&RGBColor(30, 90, 180)),
        )])
        .map_err(e)?;
    }
    Ok(())
}

/// The plan from above: east to the right, north up, 1:1.
pub fn map_svg(s: &Scenario, r: &PlanReport) -> Result<String, crate::Error> {
    let paths = paths_of(s)?;
    let share_of = |seg: Segment| -> f64 {
        let name = super::segment_name(s, seg);
        r.passes
            .iter()
            .find(|p| p.what == name)
            .map_or(0.0, |p| p.share)
    };
    let proposed = proposed_passes(r);
    let (x0, x1, y0, y1) = view(s, &paths, &proposed);
    // 1:1 within 620 x 560 px.
    let scale = (560.0 / (x1 - x0)).min(480.0 / (y1 - y0));
    let (w, h) = (
        (((x1 - x0) * scale) as u32 + 90).max(320),
        ((y1 - y0) * scale) as u32 + 80,
    );
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let mut ch = ChartBuilder::on(&root)
            .caption(
                if proposed.is_empty() {
                    "from above (red: passes with a large share)"
                } else {
                    "from above (red: large share; dashed: recommended)"
                },
                ("sans-serif", 14),
            )
            .margin(10)
            .x_label_area_size(34)
            .y_label_area_size(50)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(e)?;
        ch.configure_mesh()
            .x_desc("east [m]")
            .y_desc("north [m]")
            .light_line_style(WHITE)
            .draw()
            .map_err(e)?;
        draw_site(&mut ch, s, [x0, x1, y0, y1])?;
        for (seg, pts) in &paths {
            let (colour, width) = match seg {
                Segment::Turn(_) => (RGBColor(170, 170, 170), 1),
                _ => (heat(share_of(*seg)), 3),
            };
            ch.draw_series(LineSeries::new(pts.clone(), colour.stroke_width(width)))
                .map_err(e)?;
            if let (Segment::Pass(i), Some(&last)) = (seg, pts.last()) {
                // Staggered along the line: lines that cross over the targets keep apart.
                let mid = pts[(pts.len() * (2 + 2 * (*i % 3)) / 10).min(pts.len() - 1)];
                // A flight's lines with their height above the spheres' ground.
                let above = s.trajectory.pass[*i]
                    .down_m
                    .filter(|_| super::design::is_aerial(s))
                    .map(|d| format!(" ({:.0} m)", super::design::ground(s) - d))
                    .unwrap_or_default();
                ch.draw_series([Text::new(
                    format!("{}{above}", i + 1),
                    mid,
                    ("sans-serif", 13).into_font().color(&BLACK),
                )])
                .map_err(e)?;
                ch.draw_series([Circle::new(last, 3, colour.filled())])
                    .map_err(e)?;
            }
        }
        draw_proposed_and_spheres(&mut ch, s, &proposed)?;
        root.present().map_err(e)?;
    }
    Ok(out)
}

/// The predicted sigma of each parameter over its target (1: the target).
pub fn sigma_svg(r: &PlanReport) -> Result<String, crate::Error> {
    let ratio: Vec<f64> = (0..P)
        .map(|i| {
            let t = if i < 3 {
                r.goal.sigma_deg
            } else {
                r.goal.sigma_m
            };
            r.predicted.sigma_deg_m[i].map_or(10.0, |s| (s / t).min(10.0))
        })
        .collect();
    let top = ratio.iter().copied().fold(1.2f64, f64::max) * 1.1;
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (460, 300)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let mut ch = ChartBuilder::on(&root)
            .caption("predicted sigma / target", ("sans-serif", 14))
            .margin(10)
            .x_label_area_size(34)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..P as f64, 0.0..top)
            .map_err(e)?;
        ch.configure_mesh()
            .disable_x_mesh()
            .x_labels(4 * P + 1)
            .x_label_formatter(&|x| {
                // Names under the bars' centres only.
                let i = x.floor();
                if (x - i - 0.5).abs() < 0.01 {
                    NAMES
                        .get(i as usize)
                        .map_or(String::new(), |s| s.to_string())
                } else {
                    String::new()
                }
            })
            .y_desc("sigma / target")
            .draw()
            .map_err(e)?;
        ch.draw_series(ratio.iter().enumerate().map(|(i, &v)| {
            let c = if v <= 1.0 {
                RGBColor(60, 160, 60)
            } else {
                RGBColor(200, 50, 40)
            };
            Rectangle::new([(i as f64 + 0.2, 0.0), (i as f64 + 0.8, v)], c.filled())
        }))
        .map_err(e)?;
        ch.draw_series(LineSeries::new(
            [(0.0, 1.0), (P as f64, 1.0)],
            BLACK.stroke_width(2),
        ))
        .map_err(e)?;
        root.present().map_err(e)?;
    }
    Ok(out)
}

fn fmt(v: Option<f64>, i: usize) -> String {
    super::sigma_text(v, i, false).unwrap_or_else(|| "&ndash;".into())
}

/// The page.
pub fn render(
    s: &Scenario,
    r: &PlanReport,
    design: Option<&super::design::Design>,
    lines: Option<&super::site::Lines>,
) -> Result<String, crate::Error> {
    let mut o = String::new();
    let _ = write!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>spherecal plan: {}</title><style>{}</style></head><body>\n<h1>Calibration survey plan: {}</h1>\n",
        escape(&r.scenario),
        crate::html::STYLE,
        escape(&r.scenario)
    );
    if r.meets {
        let _ = writeln!(
            o,
            "<p class=\"ok\">The plan meets the targets ({} deg, {} mm).</p>",
            r.goal.sigma_deg,
            r.goal.sigma_m * 1e3
        );
    } else {
        let _ = writeln!(
            o,
            "<p class=\"no\">The plan misses the targets: {}.</p>",
            escape(&r.missing.join("; "))
        );
    }
    for w in &r.warnings {
        let _ = writeln!(o, "<p class=\"no\">Warning: {}.</p>", escape(w));
    }
    if let Some(d) = design {
        design_table(&mut o, d);
    }
    let n = &r.noise;
    let _ = writeln!(
        o,
        "<p class=\"note\">{} sphere returns predicted; noise{}: range {} m{}, INS attitude {} deg and position {} m per sample at {} Hz. Condition number {}; weakest direction: {}.</p>",
        r.predicted.returns,
        if n.assumed { " (the scenario states none: the sensors' specified values)" } else { "" },
        n.range_m,
        if n.incidence_divergence_mrad > 0.0 { format!(", growing at grazing incidence ({} mrad)", n.incidence_divergence_mrad) } else { String::new() },
        n.attitude_deg,
        n.position_m,
        n.ins_rate_hz,
        r.predicted.condition.map_or("infinite".into(), |c| format!("{c:.1}")),
        escape(&super::weakest_words(&r.weakest))
    );
    if let Some(l) = lines {
        o.push_str(&super::site::html(l));
    }
    predicted_table(&mut o, r);
    let _ = writeln!(
        o,
        "<div class=\"figs\">{}{}</div>",
        crate::plot::strip_xml_header(&map_svg(s, r)?),
        crate::plot::strip_xml_header(&sigma_svg(r)?)
    );
    shares_table(&mut o, r);
    recommendations_and_correlations(&mut o, r);
    o.push_str("</table>\n</body></html>\n");
    Ok(o)
}

/// The design's chosen survey and the candidates weighed.
fn design_table(o: &mut String, d: &super::design::Design) {
    let c = &d.candidates[d.chosen];
    let _ = writeln!(
        o,
        "<h2>Design</h2><p>Proposed ({} survey, {} candidates weighed): {} <span class=\"note\">({}; cost {:.0} s with the spheres' set-up)</span>. The map and the tables below are this survey's.</p>",
        d.kind,
        d.candidates.len(),
        escape(&c.words),
        if c.meets { "meets the targets" } else { "the closest: none meets them" },
        c.cost_s
    );
    o.push_str("<table><tr><th>height [m]</th><th>speed [m/s]</th><th>spheres</th><th>radius [m]</th><th class=\"l\">where</th><th>cost [s]</th>");
    for name in NAMES {
        let _ = write!(o, "<th>{name}</th>");
    }
    o.push_str("<th>meets</th></tr>\n");
    let order = d.order();
    for &k in order.iter().take(super::design::SHOWN) {
        let c = &d.candidates[k];
        let _ = write!(
            o,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.2}</td><td class=\"l\">{}</td><td>{:.0}</td>",
            c.height_m.map_or("&ndash;".into(), |h| format!("{h:.0}")),
            c.speed_mps.map_or("&ndash;".into(), |v| format!("{v:.0}")),
            c.spheres,
            c.radius_m,
            escape(&c.layout),
            c.cost_s
        );
        for i in 0..P {
            let _ = write!(o, "<td>{}</td>", fmt(c.predicted.sigma_deg_m[i], i));
        }
        let _ = writeln!(o, "<td>{}</td></tr>", if c.meets { "yes" } else { "no" });
    }
    o.push_str("</table>\n");
}

/// The predicted sigmas against the targets.
fn predicted_table(o: &mut String, r: &PlanReport) {
    o.push_str("<h2>Predicted 1-sigma</h2><table><tr><th class=\"l\">parameter</th><th>predicted</th><th>target</th></tr>\n");
    for (i, name) in NAMES.iter().enumerate() {
        let (t, unit) = if i < 3 {
            (format!("{}", r.goal.sigma_deg), "deg")
        } else {
            (format!("{:.1}", r.goal.sigma_m * 1e3), "mm")
        };
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{} [{unit}]</td><td>{}</td><td>{t}</td></tr>",
            name,
            fmt(r.predicted.sigma_deg_m[i], i)
        );
    }
    let _ = writeln!(
        o,
        "<tr><td class=\"l\">time offset [ms]</td><td>{}</td><td></td></tr></table>",
        r.predicted
            .sigma_time_offset_s
            .map_or("&ndash;".into(), |v| format!("{:.3}", v * 1e3))
    );
}

/// What each pass and sphere brings: its share and the sigmas without it.
fn shares_table(o: &mut String, r: &PlanReport) {
    o.push_str("<h2>What each pass and sphere brings</h2><p class=\"note\">Share: the mean over the six of 1 &minus; (sigma / sigma without it)&sup2;. Sigmas without it: deg for the angles, mm for the lever arm.</p><table><tr><th class=\"l\"></th><th>returns</th><th>ranges [m]</th><th>share</th>");
    for name in NAMES {
        let _ = write!(o, "<th>{name} without</th>");
    }
    o.push_str("</tr>\n");
    for sh in r.passes.iter().chain(&r.spheres) {
        let _ = write!(
            o,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{:.0} %</td>",
            escape(&sh.what),
            sh.returns,
            sh.range_m.map_or("&ndash;".into(), |r| format!(
                "{:.0}&ndash;{:.0}",
                r[0], r[1]
            )),
            sh.share * 100.0
        );
        for i in 0..P {
            let _ = write!(o, "<td>{}</td>", fmt(sh.sigma_without[i], i));
        }
        o.push_str("</tr>\n");
    }
    o.push_str("</table>\n");
}

/// The recommendations and the correlations.
fn recommendations_and_correlations(o: &mut String, r: &PlanReport) {
    if !r.recommendations.is_empty() {
        o.push_str("<h2>Recommendations</h2><ol>\n");
        for rec in &r.recommendations {
            let _ = writeln!(
                o,
                "<li>{} <span class=\"note\">({:.0} s of survey; {})</span></li>",
                escape(&rec.words),
                rec.cost_s,
                if rec.meets {
                    "meets the targets"
                } else {
                    "still short of them"
                }
            );
        }
        o.push_str("</ol>\n");
    }
    o.push_str("<h2>Correlations</h2><table><tr><th></th>");
    let names: Vec<&str> = NAMES.iter().copied().chain(["dt"]).collect();
    for n in &names {
        let _ = write!(o, "<th>{n}</th>");
    }
    o.push_str("</tr>\n");
    for (i, row) in r.correlation.iter().enumerate() {
        let _ = write!(o, "<tr><th>{}</th>", names[i]);
        for v in row {
            let _ = write!(
                o,
                "<td>{}</td>",
                if v.is_finite() {
                    format!("{v:+.2}")
                } else {
                    "&ndash;".into()
                }
            );
        }
        o.push_str("</tr>\n");
    }
}

#[cfg(test)]
mod tests {
    /// By hand: a 2 m square at the origin clipped to [1, 3] x [1, 3] is the 1 m square at
    /// (1, 1); a diamond wholly inside is unchanged; one wholly outside is empty.
    #[test]
    fn polygons_are_clipped_to_the_view() {
        let area = |p: &[(f64, f64)]| {
            (0..p.len())
                .map(|k| {
                    let (a, b) = (p[k], p[(k + 1) % p.len()]);
                    a.0 * b.1 - b.0 * a.1
                })
                .sum::<f64>()
                .abs()
                / 2.0
        };
        let sq = vec![(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)];
        let c = super::clip(sq, [1.0, 3.0, 1.0, 3.0]);
        assert!((area(&c) - 1.0).abs() < 1e-12, "{c:?}");
        assert!(c
            .iter()
            .all(|p| (1.0..=2.0).contains(&p.0) && (1.0..=2.0).contains(&p.1)));
        let diamond = vec![(2.0, 1.5), (2.5, 2.0), (2.0, 2.5), (1.5, 2.0)];
        assert_eq!(super::clip(diamond.clone(), [1.0, 3.0, 1.0, 3.0]), diamond);
        assert!(super::clip(diamond, [5.0, 6.0, 5.0, 6.0]).is_empty());
    }
}

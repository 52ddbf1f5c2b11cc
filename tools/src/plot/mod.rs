//! The calibration's figures as SVG (plotters): per sphere, the residual histograms before and
//! after on their own axes, the residuals after against time coloured by pass, and 1:1
//! cross-sections before and after (horizontal distance from the surveyed centre against
//! height, with the sphere's outline: the paper's figures 4 and 6). The HTML report inlines
//! them; `--plot` writes them into one SVG file.

use crate::report::Report;
use plotters::prelude::*;
use spherecal::align::window::{Observation, Target};
use spherecal::calib::solve::Solution;
use spherecal::georef::{Mount, Params};
use std::path::Path;

mod nav;
pub use nav::nav_corrections;

/// Scatter plots draw at most this many returns (evenly spread; the caption says so): a
/// survey's 10^5 kept returns would make a page of tens of megabytes.
pub const MAX_DOTS: usize = 3000;

/// Figure width and height [px].
const W: u32 = 460;
const H: u32 = 300;
/// Space for the axes' labels [px].
const X_LABELS: u32 = 38;
const Y_LABELS: u32 = 58;
const MARGIN: u32 = 10;
const CAPTION: u32 = 26;

/// Colours of the passes, in turn.
const PASS_COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];
const BEFORE: RGBColor = RGBColor(200, 60, 40);
const AFTER: RGBColor = RGBColor(30, 90, 180);

/// One sphere's kept returns as the figures need them.
#[derive(Debug, Clone, Default)]
pub struct SphereData {
    /// Sphere id.
    pub id: String,
    /// Radius [m].
    pub radius: f64,
    /// Signed distance from the surface with the starting mounting [mm] ...
    pub before_mm: Vec<f64>,
    /// ... and with the solution [mm].
    pub after_mm: Vec<f64>,
    /// Seconds since the first pass.
    pub time_s: Vec<f64>,
    /// The pass over this sphere each return belongs to (index into `passes`).
    pub pass: Vec<usize>,
    /// This sphere's passes (the report's `per_pass`, in time order): seconds since the
    /// first pass, start and end.
    pub passes: Vec<(f64, f64)>,
    /// Cross-section: (horizontal distance from the centre, height above it) [m], before ...
    pub section_before: Vec<(f64, f64)>,
    /// ... and after.
    pub section_after: Vec<(f64, f64)>,
}

/// Everything the figures draw.
#[derive(Debug, Clone, Default)]
pub struct Figures {
    /// Per sphere (found ones only).
    pub spheres: Vec<SphereData>,
}

impl Figures {
    /// From the solver's kept returns (the first `used` of each sphere's), the starting
    /// mounting `b0` and the report's passes.
    pub fn new(
        targets: &[Target],
        ids: &[String],
        obs: &[Vec<Observation>],
        sol: &Solution,
        b0: &Params,
        report: &Report,
    ) -> Self {
        let before = Mount::from_params(b0);
        let after = Mount::from_params(&sol.b);
        let kept = |j: usize| {
            let n = sol.spheres.get(j).map_or(0, |s| s.used);
            &obs[j][..n.min(obs[j].len())]
        };
        // Time zero: the first pass's start (as in the report's pass table), else the first
        // kept return.
        let first_pass = report
            .per_pass
            .iter()
            .map(|p| p.start_gps_s)
            .fold(f64::INFINITY, f64::min);
        let first_kept = (0..obs.len())
            .flat_map(|j| kept(j).iter().map(|o| o.time.as_secs_f64()))
            .fold(f64::INFINITY, f64::min);
        let t0 = [first_pass, first_kept, 0.0]
            .into_iter()
            .find(|t| t.is_finite())
            .unwrap_or(0.0);
        let mut spheres = Vec::new();
        for (j, t) in targets.iter().enumerate() {
            let k = kept(j);
            if k.is_empty() {
                continue;
            }
            let id = ids.get(j).cloned().unwrap_or_default();
            let passes = sphere_passes(report, &id, t0);
            let mut d = SphereData {
                id,
                radius: t.radius,
                ..SphereData::default()
            };
            for o in k {
                let xb = o.georef(&before) - t.center;
                let xa = o.georef_dt(&after, sol.dt) - t.center;
                d.before_mm.push((xb.norm() - t.radius) * 1e3);
                d.after_mm.push((xa.norm() - t.radius) * 1e3);
                let ts = o.time.as_secs_f64() - t0;
                d.time_s.push(ts);
                // The pass holding it: the last one starting at or before it.
                d.pass
                    .push(passes.iter().rposition(|&(a, _)| a <= ts).unwrap_or(0));
                // Height above the centre: NED down is positive, so up is -z.
                d.section_before.push((xb.x.hypot(xb.y), -xb.z));
                d.section_after.push((xa.x.hypot(xa.y), -xa.z));
            }
            d.passes = passes;
            spheres.push(d);
        }
        Self { spheres }
    }
}

/// Sphere `id`'s passes from the report, in time order, in seconds since `t0`.
pub fn sphere_passes(r: &Report, id: &str, t0: f64) -> Vec<(f64, f64)> {
    let mut iv: Vec<(f64, f64)> = r
        .per_pass
        .iter()
        .filter(|p| p.sphere == id)
        .map(|p| (p.start_gps_s - t0, p.end_gps_s - t0))
        .collect();
    iv.sort_by(|a, b| a.0.total_cmp(&b.0));
    iv
}

/// Every `k`-th index so that at most [`MAX_DOTS`] remain, and `k`.
fn thin(n: usize) -> (impl Iterator<Item = usize>, usize) {
    let k = n.div_ceil(MAX_DOTS).max(1);
    ((0..n).step_by(k), k)
}

/// `s` for a caption: "N returns" or "every k-th of N returns".
fn dots(n: usize) -> String {
    let (_, k) = thin(n);
    if k == 1 {
        format!("{n} returns")
    } else {
        format!("every {k}th of {n} returns")
    }
}

pub(crate) type Res<T> = Result<T, crate::Error>;

pub(crate) fn e<E: std::fmt::Display>(x: E) -> String {
    x.to_string()
}

/// A histogram of `v` [mm] on its own axis (40 bins over its range).
pub fn histogram(v: &[f64], title: &str, colour: RGBColor) -> Res<String> {
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (W, H)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let (lo, hi) = v
            .iter()
            .filter(|x| x.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let (lo, hi) = if lo.is_finite() && hi > lo {
            (lo, hi)
        } else {
            (-1.0, 1.0)
        };
        let bins = 40usize;
        let w = (hi - lo) / bins as f64;
        let mut counts = vec![0u32; bins];
        for &x in v.iter().filter(|x| x.is_finite()) {
            counts[(((x - lo) / w) as usize).min(bins - 1)] += 1;
        }
        let top = counts.iter().copied().max().unwrap_or(1).max(1);
        let mut ch = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 15))
            .margin(MARGIN)
            .x_label_area_size(X_LABELS)
            .y_label_area_size(Y_LABELS)
            .build_cartesian_2d(lo..hi, 0u32..top + top / 10 + 1)
            .map_err(e)?;
        ch.configure_mesh()
            .x_desc("distance from the sphere's surface [mm]")
            .y_desc("returns")
            .disable_x_mesh()
            .draw()
            .map_err(e)?;
        ch.draw_series(counts.iter().enumerate().map(|(i, &c)| {
            let a = lo + w * i as f64;
            Rectangle::new([(a, 0), (a + w, c)], colour.mix(0.75).filled())
        }))
        .map_err(e)?;
        root.present().map_err(e)?;
    }
    Ok(s)
}

/// The residuals after against time, coloured by the pass over the sphere.
pub fn residuals_vs_time(d: &SphereData) -> Res<String> {
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (W, H)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let lim = d.after_mm.iter().fold(
            0.1f64,
            |m, x| if x.is_finite() { m.max(x.abs()) } else { m },
        ) * 1.05;
        let t1 = d.time_s.iter().copied().fold(1.0f64, f64::max);
        let mut ch = ChartBuilder::on(&root)
            .caption(
                format!("{}: after, against time ({})", d.id, dots(d.after_mm.len())),
                ("sans-serif", 15),
            )
            .margin(MARGIN)
            .x_label_area_size(X_LABELS)
            .y_label_area_size(Y_LABELS)
            .build_cartesian_2d(0.0..t1 * 1.02, -lim..lim)
            .map_err(e)?;
        ch.configure_mesh()
            .x_desc("seconds since the first pass")
            .y_desc("residual [mm]")
            .draw()
            .map_err(e)?;
        let (idx, _) = thin(d.after_mm.len());
        ch.draw_series(idx.map(|i| {
            let c = PASS_COLOURS[d.pass[i] % PASS_COLOURS.len()];
            Circle::new((d.time_s[i], d.after_mm[i]), 2, c.filled())
        }))
        .map_err(e)?;
        // The legend: one entry per pass that holds returns of this sphere.
        for k in 0..d.passes.len() {
            if d.pass.contains(&k) {
                let c = PASS_COLOURS[k % PASS_COLOURS.len()];
                ch.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                    .map_err(e)?
                    .label(format!("pass {}", k + 1))
                    .legend(move |(x, y)| Circle::new((x, y), 4, c.filled()));
            }
        }
        ch.configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.85))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(e)?;
        root.present().map_err(e)?;
    }
    Ok(s)
}

/// A 1:1 cross-section of one sphere's returns (horizontal distance from the surveyed centre
/// against height above it) with the sphere's outline; `half`: the half-extent shown [m].
pub fn cross_section(
    pts: &[(f64, f64)],
    radius: f64,
    title: &str,
    colour: RGBColor,
) -> Res<String> {
    // The extent: the returns (at most 3 m out), at least 1.6 radii.
    let far = pts
        .iter()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .fold(0.0f64, |m, p| m.max(p.0).max(p.1.abs()))
        .min(3.0);
    let half = (1.6 * radius).max(far * 1.05);
    // A square plotting area: the figure's size follows from the label areas.
    let side = H - CAPTION - X_LABELS - 2 * MARGIN;
    let (w, h) = (side + Y_LABELS + 2 * MARGIN, H);
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let mut ch = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 15))
            .margin(MARGIN)
            .x_label_area_size(X_LABELS)
            .y_label_area_size(Y_LABELS)
            .build_cartesian_2d(-0.1 * half..1.9 * half, -half..half)
            .map_err(e)?;
        ch.configure_mesh()
            .x_desc("horizontal from centre [m]")
            .y_desc("height [m]")
            .draw()
            .map_err(e)?;
        let outline: Vec<(f64, f64)> = (0..=180)
            .map(|i| {
                let a = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * f64::from(i) / 180.0;
                (radius * a.cos(), radius * a.sin())
            })
            .collect();
        ch.draw_series(LineSeries::new(outline, BLACK.stroke_width(1)))
            .map_err(e)?;
        let (idx, _) = thin(pts.len());
        ch.draw_series(idx.map(|i| Circle::new(pts[i], 1, colour.filled())))
            .map_err(e)?;
        root.present().map_err(e)?;
    }
    Ok(s)
}

/// One sphere's figures: histograms before and after, residuals against time, cross-sections
/// before and after.
pub fn sphere_figures(d: &SphereData) -> Res<[String; 5]> {
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    Ok([
        histogram(
            &d.before_mm,
            &format!("{}: before, RMS {:.1} mm", d.id, rms(&d.before_mm)),
            BEFORE,
        )?,
        histogram(
            &d.after_mm,
            &format!("{}: after, RMS {:.2} mm", d.id, rms(&d.after_mm)),
            AFTER,
        )?,
        residuals_vs_time(d)?,
        cross_section(
            &d.section_before,
            d.radius,
            &format!("{}: before (1:1)", d.id),
            BEFORE,
        )?,
        cross_section(
            &d.section_after,
            d.radius,
            &format!("{}: after (1:1)", d.id),
            AFTER,
        )?,
    ])
}

/// `--plot`: every sphere's figures in one SVG, a row per sphere.
pub fn plot(path: &Path, f: &Figures) -> Res<()> {
    let mut rows = Vec::new();
    for d in &f.spheres {
        rows.push(sphere_figures(d)?);
    }
    let width = 3 * W + 2 * (H - CAPTION - X_LABELS - 2 * MARGIN + Y_LABELS + 2 * MARGIN);
    let height = (H as usize * rows.len()).max(H as usize);
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\">\n"
    );
    for (r, figs) in rows.iter().enumerate() {
        let mut x = 0u32;
        for fig in figs {
            let w = svg_width(fig).unwrap_or(W);
            out.push_str(&format!(
                "<g transform=\"translate({x},{})\">{}</g>\n",
                r as u32 * H,
                strip_xml_header(fig)
            ));
            x += w;
        }
    }
    out.push_str("</svg>\n");
    crate::output::write(path, out.as_bytes())
}

/// A figure's width from its `<svg width="...">`.
fn svg_width(svg: &str) -> Option<u32> {
    let i = svg.find("width=\"")? + 7;
    svg[i..].split('"').next()?.parse().ok()
}

/// A figure without an XML declaration, to nest or inline.
pub fn strip_xml_header(svg: &str) -> &str {
    match svg.find("<svg") {
        Some(i) => &svg[i..],
        None => svg,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cross-section's plotting area is square and its axes span the same length: one
    /// metre across is one metre up.
    #[test]
    fn cross_section_is_one_to_one() {
        let side = H - CAPTION - X_LABELS - 2 * MARGIN;
        let svg = cross_section(&[(0.19, 0.0), (0.0, 0.19)], 0.19, "t", AFTER).unwrap();
        assert_eq!(svg_width(&svg), Some(side + Y_LABELS + 2 * MARGIN));
        // The outline is a circle: its rightmost and topmost points are as far from the centre
        // in pixels. Points of the outline are the polyline's.
        let pts: Vec<(f64, f64)> = svg
            .split("<polyline")
            .skip(1)
            .map(|p| {
                let p = &p[p.find("points=\"").unwrap() + 8..];
                p[..p.find('"').unwrap()]
                    .split_whitespace()
                    .map(|p| {
                        let (x, y) = p.split_once(',').unwrap();
                        (x.parse().unwrap(), y.parse().unwrap())
                    })
                    .collect::<Vec<(f64, f64)>>()
            })
            .max_by_key(Vec::len)
            .unwrap();
        assert_eq!(pts.len(), 181);
        let (bottom, right, top) = (pts[0], pts[90], pts[180]);
        let cy = (bottom.1 + top.1) / 2.0;
        let cx = bottom.0;
        let rx = right.0 - cx;
        let ry = (bottom.1 - top.1) / 2.0;
        assert!(rx > 20.0, "{rx}");
        assert!((rx - ry).abs() <= 1.5, "x radius {rx} px, y radius {ry} px");
        assert!((right.1 - cy).abs() <= 1.0);
    }

    /// Each histogram has its own axis: 0.4 mm residuals are not drawn on a 2 m axis.
    #[test]
    fn histograms_on_their_own_axes() {
        let after: Vec<f64> = (0..200).map(|i| (f64::from(i) - 100.0) * 0.004).collect();
        let svg = histogram(&after, "after", AFTER).unwrap();
        // Tick labels of a +-0.4 mm axis, not of +-2000 mm.
        let labels: Vec<&str> = svg
            .split("</text>")
            .filter_map(|t| t.rsplit('>').next())
            .map(str::trim)
            .collect();
        assert!(labels.contains(&"0.2"), "{labels:?}");
        assert!(!labels.iter().any(|l| l.starts_with("1000")), "{labels:?}");
    }
}

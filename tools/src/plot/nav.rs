//! The navigation corrections the calibration estimated, against time with their 1-sigma
//! band (issue 47: the report's figure; the per-second table is folded under it).

use super::{e, Res, MARGIN, X_LABELS, Y_LABELS};
use crate::report::NavCorrectionReport;
use plotters::prelude::*;

/// One panel's width and height [px].
const PW: u32 = 460;
const PH: u32 = 210;
/// Colours: position (left) and attitude (right).
const POSITION: RGBColor = RGBColor(30, 90, 180);
const ATTITUDE: RGBColor = RGBColor(200, 90, 30);

/// The pieces in runs of contiguous time (a pass and its turn): a new run where the gap to
/// the previous piece exceeds 3 pieces' median length (1 s at least).
fn runs(c: &[NavCorrectionReport]) -> Vec<std::ops::Range<usize>> {
    let mut len: Vec<f64> = c.iter().map(|p| p.end_gps_s - p.start_gps_s).collect();
    len.sort_by(f64::total_cmp);
    let gap = (3.0 * len.get(len.len() / 2).copied().unwrap_or(0.0)).max(1.0);
    let mut out = Vec::new();
    let mut a = 0;
    for k in 1..=c.len() {
        if k == c.len() || c[k].start_gps_s - c[k - 1].end_gps_s > gap {
            if k > a {
                out.push(a..k);
            }
            a = k;
        }
    }
    out
}

/// Six panels: the position correction north, east, down [mm] (left) and the attitude's
/// about north, east, down [deg] (right), each with its 1-sigma band, against seconds since
/// the first piece; `None` without pieces.
pub fn nav_corrections(c: &[NavCorrectionReport]) -> Res<Option<String>> {
    if c.is_empty() {
        return Ok(None);
    }
    let t0 = c[0].start_gps_s;
    let t1 = c.iter().map(|p| p.end_gps_s - t0).fold(1.0f64, f64::max);
    let runs = runs(c);
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (2 * PW, 3 * PH)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let panels = root.split_evenly((3, 2));
        const AXES: [&str; 3] = ["north", "east", "down"];
        for (k, area) in panels.iter().enumerate() {
            let (row, attitude) = (k / 2, k % 2 == 1);
            let value = |p: &NavCorrectionReport| -> (f64, f64) {
                if attitude {
                    (p.rotation_deg[row], p.rotation_sigma_deg[row])
                } else {
                    (p.position_m[row] * 1e3, p.position_sigma_m[row] * 1e3)
                }
            };
            let lim = c
                .iter()
                .map(|p| {
                    let (v, s) = value(p);
                    v.abs() + s
                })
                .filter(|x| x.is_finite())
                .fold(if attitude { 1e-3 } else { 0.1 }, f64::max)
                * 1.1;
            let (what, unit, colour) = if attitude {
                (format!("attitude about {}", AXES[row]), "deg", ATTITUDE)
            } else {
                (format!("position {}", AXES[row]), "mm", POSITION)
            };
            let mut ch = ChartBuilder::on(area)
                .caption(format!("{what} [{unit}]"), ("sans-serif", 14))
                .margin(MARGIN)
                .x_label_area_size(X_LABELS)
                .y_label_area_size(Y_LABELS)
                .build_cartesian_2d(0.0..t1 * 1.02, -lim..lim)
                .map_err(e)?;
            ch.configure_mesh()
                .x_desc(if row == 2 {
                    "seconds since the first piece"
                } else {
                    ""
                })
                .y_labels(5)
                .draw()
                .map_err(e)?;
            for r in &runs {
                let mid = |p: &NavCorrectionReport| 0.5 * (p.start_gps_s + p.end_gps_s) - t0;
                let part = &c[r.clone()];
                let mut band: Vec<(f64, f64)> = part
                    .iter()
                    .map(|p| (mid(p), value(p).0 + value(p).1))
                    .collect();
                band.extend(part.iter().rev().map(|p| (mid(p), value(p).0 - value(p).1)));
                if band.iter().all(|(x, y)| x.is_finite() && y.is_finite()) {
                    ch.draw_series(std::iter::once(Polygon::new(
                        band,
                        colour.mix(0.2).filled(),
                    )))
                    .map_err(e)?;
                }
                ch.draw_series(LineSeries::new(
                    part.iter()
                        .map(|p| (mid(p), value(p).0))
                        .filter(|(_, y)| y.is_finite()),
                    colour.stroke_width(1),
                ))
                .map_err(e)?;
            }
        }
        root.present().map_err(e)?;
    }
    Ok(Some(s))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn piece(t: f64, v: f64) -> NavCorrectionReport {
        NavCorrectionReport {
            start_gps_s: t,
            end_gps_s: t + 0.5,
            returns: 10,
            position_m: [v, 0.0, 0.0],
            position_sigma_m: [0.002; 3],
            rotation_deg: [0.0; 3],
            rotation_sigma_deg: [0.001; 3],
        }
    }

    /// Two passes 30 s apart are two runs; the figure has six panels, a band (polygon) and a
    /// line per run and panel.
    #[test]
    fn runs_split_at_gaps_and_every_panel_is_drawn() {
        let mut c: Vec<NavCorrectionReport> =
            (0..20).map(|k| piece(f64::from(k) * 0.5, 0.01)).collect();
        c.extend((0..20).map(|k| piece(40.0 + f64::from(k) * 0.5, -0.01)));
        assert_eq!(runs(&c), vec![0..20, 20..40]);
        let svg = nav_corrections(&c).unwrap().unwrap();
        assert_eq!(
            svg.matches("<polygon").count(),
            12,
            "a band per run and panel"
        );
        let lines = |colour: &str| {
            svg.split("<polyline")
                .skip(1)
                .filter(|p| p.split('>').next().is_some_and(|t| t.contains(colour)))
                .count()
        };
        assert_eq!(lines("#1E5AB4"), 6, "position: a line per run and panel");
        assert_eq!(lines("#C85A1E"), 6, "attitude: a line per run and panel");
        assert!(svg.contains("position north [mm]") && svg.contains("attitude about down [deg]"));
        assert!(nav_corrections(&[]).unwrap().is_none());
    }
}

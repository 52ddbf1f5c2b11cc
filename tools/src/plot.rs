//! `--plot`: residuals before and after per sphere, and a cross-section of one sphere's returns
//! before and after (the paper's figures 4 and 6), as SVG.

use spherecal::calib::solve::Solution;
use spherecal::calib::Params;
use spherecal::georef::Mount;
use spherecal::window::{Observation, Target};
use std::path::Path;

/// Draw the plots into one SVG.
pub fn plot(
    path: &Path,
    targets: &[Target],
    ids: &[String],
    obs: &[Vec<Observation>],
    sol: &Solution,
    b0: &Params,
) -> Result<(), String> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (1200, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (top, bottom) = root.split_vertically(450);
    let before = Mount::from_params(b0);
    let after = Mount::from_params(&sol.b);
    let used: Vec<usize> = sol.spheres.iter().map(|s| s.used).collect();
    // Residuals (mm) by return index, before and after, per sphere.
    let panels = top.split_evenly((1, targets.len().max(1)));
    for (j, area) in panels.iter().enumerate() {
        let t = &targets[j];
        let kept = &obs[j][..used.get(j).copied().unwrap_or(0).min(obs[j].len())];
        let res = |m: &Mount| -> Vec<f64> {
            kept.iter()
                .map(|o| ((o.georef(m) - t.center).norm() - t.radius) * 1e3)
                .collect()
        };
        let (rb, ra) = (res(&before), res(&after));
        let lim = rb
            .iter()
            .chain(&ra)
            .fold(1.0f64, |m, x| m.max(x.abs()))
            .min(3000.0);
        let mut ch = ChartBuilder::on(area)
            .caption(
                format!(
                    "{}: residuals (mm) before / after",
                    ids.get(j).map_or("", |s| s.as_str())
                ),
                ("sans-serif", 16),
            )
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d(0..kept.len().max(1), -lim..lim)
            .map_err(|e| e.to_string())?;
        ch.configure_mesh()
            .x_desc("return")
            .y_desc("mm")
            .draw()
            .map_err(|e| e.to_string())?;
        ch.draw_series(
            rb.iter()
                .enumerate()
                .map(|(i, v)| Circle::new((i, *v), 1, RED.filled())),
        )
        .map_err(|e| e.to_string())?
        .label("before")
        .legend(|(x, y)| Circle::new((x, y), 3, RED.filled()));
        ch.draw_series(
            ra.iter()
                .enumerate()
                .map(|(i, v)| Circle::new((i, *v), 1, BLUE.filled())),
        )
        .map_err(|e| e.to_string())?
        .label("after")
        .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
        ch.configure_series_labels()
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
    }
    // Cross-section of the first sphere: horizontal distance from the centre vs height.
    if let (Some(t), Some(o)) = (targets.first(), obs.first()) {
        let kept = &o[..used.first().copied().unwrap_or(0).min(o.len())];
        let pts = |m: &Mount| -> Vec<(f64, f64)> {
            kept.iter()
                .map(|ob| {
                    let d = ob.georef(m) - t.center;
                    (d.x.hypot(d.y), -d.z)
                })
                .collect()
        };
        let (pb, pa) = (pts(&before), pts(&after));
        let lim = (t.radius * 4.0).max(
            pb.iter()
                .fold(0.0f64, |m, p| m.max(p.0.abs()).max(p.1.abs()))
                .min(3.0),
        );
        let mut ch = ChartBuilder::on(&bottom)
            .caption(
                format!(
                    "{}: cross-section (m), horizontal distance from centre vs height",
                    ids.first().map_or("", |s| s.as_str())
                ),
                ("sans-serif", 16),
            )
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..lim, -lim..lim)
            .map_err(|e| e.to_string())?;
        ch.configure_mesh().draw().map_err(|e| e.to_string())?;
        ch.draw_series(pb.iter().map(|p| Circle::new(*p, 1, RED.filled())))
            .map_err(|e| e.to_string())?;
        ch.draw_series(pa.iter().map(|p| Circle::new(*p, 1, BLUE.filled())))
            .map_err(|e| e.to_string())?;
        let circle: Vec<(f64, f64)> = (0..=90)
            .map(|i| {
                let a = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * f64::from(i) / 90.0;
                (t.radius * a.cos(), t.radius * a.sin())
            })
            .collect();
        ch.draw_series(LineSeries::new(circle, BLACK))
            .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

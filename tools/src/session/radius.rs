//! The spheres' radii against their returns (issue 47 item 6): each slice of a sphere's
//! windowed returns searched for a sphere at radii from a quarter to four times the site's
//! ([`spherecal::calib::extract::detections_at_radii`], the rounds' own detection), the radius
//! detected in most slices against the site's. A diameter typed as the radius, or feet read as
//! metres, is named before any other cause, and no stretch of the survey is set aside for it
//! (a wrong radius refuses every stretch).

use serde::{Deserialize, Serialize};
use spherecal::align::window::{Observation, Target};
use spherecal::calib::extract::{detections_at_radii, ExtractSettings};
use spherecal::georef::Mount;

use super::scratch::Scratch;

/// The radii tried, as factors of the site's: the slips a site file suffers (a diameter: 2 or
/// 0.5; feet and metres: 3.2808 or 0.3048) and a geometric grid between (steps of ~25 %).
const FACTORS: [f64; 13] = [
    0.25, 0.3048, 0.4, 0.5, 0.63, 0.8, 1.0, 1.25, 1.6, 2.0, 2.5, 3.2808, 4.0,
];
/// Slices searched per sphere, spread over the survey (a trial of table1-noisy: ~100; each
/// costs a detection per radius).
const MAX_SLICES: usize = 40;
/// The site's radius is index 6.
const SITE: usize = 6;
/// The apparent radius may differ from the site's by this fraction before it is named (a
/// diameter is -50 %, feet +228 %).
pub const MAX_RADIUS_ERROR: f64 = 0.2;

/// One sphere's radius as its returns show it.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct ApparentRadius {
    /// The radius its returns are detected at [m]: the centre of the peak over [`FACTORS`]
    /// times the site's.
    pub radius_m: f64,
    /// Slices in which the most detected radius was detected.
    pub slices: u32,
    /// Slices in which the site's radius was detected.
    pub slices_at_site_radius: u32,
}

impl ApparentRadius {
    /// The returns show another radius than the site's: more than [`MAX_RADIUS_ERROR`] off,
    /// detected in at least five slices and in twice as many as at the site's radius.
    pub fn disagrees(&self, site_m: f64) -> bool {
        (self.radius_m / site_m - 1.0).abs() > MAX_RADIUS_ERROR
            && self.slices >= 5
            && self.slices >= 2 * self.slices_at_site_radius
    }
}

/// Each sphere's apparent radius from its windowed returns `obs` georeferenced with `mount`
/// (None: detected at no radius), on the detection's buffers of `scratch`.
pub fn apparent(
    obs: &[Vec<Observation>],
    targets: &[Target],
    mount: &Mount,
    st: &ExtractSettings,
    scratch: &mut Scratch,
) -> Vec<Option<ApparentRadius>> {
    let w = scratch.workspace();
    let (grid, keys) = (w.grid, w.keys);
    obs.iter()
        .zip(targets)
        .map(|(v, t)| {
            let mut v = v.clone();
            let radii = FACTORS.map(|f| f * t.radius);
            let mut n = [0u32; FACTORS.len()];
            detections_at_radii(&mut v, t, mount, st, keys, grid, &radii, MAX_SLICES, &mut n);
            let most = *n.iter().max()?;
            // The peak's centre: the radii detected in at least 70 % of the most slices,
            // averaged in log weighted by their slices (the detection accepts a sphere a
            // shell's width larger or smaller: the peak is a few factors wide).
            let (mut w, mut sum) = (0.0, 0.0);
            for (f, &k) in FACTORS.iter().zip(&n) {
                if f64::from(k) >= 0.7 * f64::from(most) {
                    w += f64::from(k);
                    sum += f64::from(k) * f.ln();
                }
            }
            (most > 0).then(|| ApparentRadius {
                radius_m: t.radius * (sum / w).exp(),
                slices: most,
                slices_at_site_radius: n[SITE],
            })
        })
        .collect()
}

/// The spheres whose returns show another radius than the site's, in words (None: every one
/// agrees or shows nothing).
pub fn disagreement(
    found: &[Option<ApparentRadius>],
    targets: &[Target],
    ids: &[String],
) -> Option<String> {
    let bad: Vec<String> = found
        .iter()
        .zip(targets)
        .zip(ids)
        .filter_map(|((a, t), id)| {
            let a = a.as_ref().filter(|a| a.disagrees(t.radius))?;
            let ratio = a.radius_m / t.radius;
            // Within 15 % of a slip's factor.
            let near = |f: f64| (ratio / f).ln().abs() < 0.14;
            let hint = if near(0.5) {
                " - a diameter?"
            } else if near(0.3048) {
                " - feet read as metres?"
            } else if near(3.2808) {
                " - metres read as feet?"
            } else if near(2.0) {
                " - the site holds half of it?"
            } else {
                ""
            };
            Some(format!(
                "{id}'s returns fit a radius of ~{:.3} m (detected in {} slices, at the site's {:.3} m in {}){hint}",
                a.radius_m, a.slices, t.radius, a.slices_at_site_radius
            ))
        })
        .collect();
    (!bad.is_empty()).then(|| {
        format!(
            "{}: correct radius_m in the site (every sphere is fitted at its surveyed radius)",
            bad.join("; ")
        )
    })
}

/// On a refusal: each sphere's apparent radius into `rep.per_sphere`, and the radii the
/// returns do not show (`wrong`, [`disagreement`]'s words) named before the refusal's own
/// reason.
pub fn name_first(
    rep: &mut crate::report::Report,
    radii: &[Option<ApparentRadius>],
    wrong: Option<String>,
) {
    for (p, a) in rep.per_sphere.iter_mut().zip(radii) {
        p.apparent_radius_m = a.map(|a| a.radius_m);
    }
    let Some(why) = wrong else {
        return;
    };
    // (No stretch is set aside for a wrong radius: the refusal's words say none was tried.)
    rep.reason = Some(match rep.reason.take() {
        Some(r) => format!("{why}; so: {}", r.replace(crate::reasons::NO_STRETCH, "")),
        None => why,
    });
}

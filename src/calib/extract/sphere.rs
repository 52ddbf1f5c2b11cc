//! One sphere's extraction over its windowed returns: every slice's detection and the returns
//! it keeps ([`extract_sphere`]), and the returns that can no longer be the sphere's set
//! behind the others ([`place_and_compact`]), and how far the slices' apparent spheres lie from the
//! surveyed one ([`apparent_offsets`]). docs/extraction.md, section 2.

use super::attach::set_aside_ground;
use super::detect::{detect, keep};
use super::scan::{slices, SliceCursor};
use super::score::Key;
use super::{georeference, place, tag, Detection, Directions, ExtractSettings, ReturnClass};
use crate::align::window::{Observation, Target};
use crate::calib::histogram::Histogram;
use crate::calib::noise::Noise;
use crate::calib::objective::TimeOffset;
use crate::calib::sphere_fit::fit_center;
use crate::georef::Mount;
use crate::time::GpsTime;
use nalgebra::Vector3;

/// How one sphere is extracted: the shell, the prior, around what, and the settings.
#[derive(Debug, Clone, Copy)]
pub struct Extraction<'a> {
    /// The inlier shell [m].
    pub tau: f64,
    /// How far the centre may be from the surveyed one [m] (`None`: anywhere in the window).
    pub prior: Option<f64>,
    /// Keep around the surveyed centre (the last extraction) rather than the detection; the
    /// ground a sphere rests on is set aside first.
    pub surveyed: bool,
    /// The vote directions.
    pub dirs: &'a Directions,
    /// The extraction's settings.
    pub settings: &'a ExtractSettings,
    /// The noise model (the shell of a return with its own INS sigmas widens).
    pub noise: &'a Noise,
}

/// Detect the sphere in every slice of one sphere's observations `v` (grouped by slice, in
/// time order of slices) and tag them. Returns (kept, slices, detected); `on_slice` is told
/// each slice's first time and its detection.
pub fn extract_sphere(
    v: &mut [Observation],
    t: &Target,
    how: &Extraction<'_>,
    grid: &mut [u16],
    keys: &mut [Key],
    mut on_slice: impl FnMut(GpsTime, Option<&Detection>),
) -> (usize, u32, u32) {
    let Extraction {
        tau,
        prior,
        surveyed,
        dirs,
        settings: st,
        noise,
    } = *how;
    let (mut kept, mut slices, mut detected) = (0, 0, 0);
    let mut cursor = SliceCursor::default();
    while let Some(sl) = cursor.next(v) {
        slices += 1;
        let t0 = v[sl.clone()]
            .iter()
            .map(|o| o.time)
            .min()
            .unwrap_or(GpsTime(0));
        // Around the surveyed centre, the ground a sphere rests on is set aside first.
        let sl = if surveyed {
            let band = 3.5 * noise.range + 0.01;
            sl.start..sl.start + set_aside_ground(&mut v[sl.clone()], t.radius, tau, band)
        } else {
            sl
        };
        let det = detect(&v[sl.clone()], keys, t.radius, tau, prior, grid, dirs, st);
        match det {
            Some(d) => {
                detected += 1;
                let c = if surveyed { [0.0; 3] } else { d.center };
                kept += keep(&mut v[sl.clone()], c, t.radius, tau, noise);
            }
            None => tag(&mut v[sl.clone()], ReturnClass::Undetected),
        }
        on_slice(t0, det.as_ref());
    }
    (kept, slices, detected)
}

/// Georeference one sphere's returns (as [`super::georeference`]) and, given `reach`, move
/// those farther than `reach` from its surface behind the others, tagged `OutsideShell` (the
/// near ones keep their order), in one walk. Returns how many take part (all without `reach`).
pub fn place_and_compact(
    v: &mut [Observation],
    t: &Target,
    mount: &Mount,
    time: &TimeOffset,
    reach: Option<f64>,
) -> usize {
    let Some(reach) = reach else {
        georeference(v, t, mount, time);
        return v.len();
    };
    let (r, reach) = (t.radius as f32, reach as f32);
    let mut w = 0;
    for i in 0..v.len() {
        place(&mut v[i], t, mount, time);
        let x = v[i].work.x;
        let d = libm::sqrtf(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        if (d - r).abs() <= reach {
            v.swap(i, w);
            w += 1;
        } else {
            v[i].work.verdict = ReturnClass::OutsideShell as u8;
        }
    }
    w
}

/// How far the slices' apparent spheres (fitted to their kept returns, fixed radius) lie from
/// the surveyed one with the current mounting, into `h` (slices with eight or more kept
/// returns: a slice's fit is poor with fewer). `v` holds kept returns grouped by slice.
pub(crate) fn apparent_offsets(v: &[Observation], r: f64, h: &mut Histogram) {
    for sl in slices(v) {
        let kept = v[sl].iter().map(|o| {
            Vector3::new(
                f64::from(o.work.x[0]),
                f64::from(o.work.x[1]),
                f64::from(o.work.x[2]),
            )
        });
        if kept.len() < 8 {
            continue;
        }
        if let Some(c) = fit_center(kept, r, Vector3::zeros()) {
            h.add(c.norm());
        }
    }
}

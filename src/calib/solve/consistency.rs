//! The per-pass checks (see the module [`super`] for the limits): each pass's sphere centre
//! against the surveyed one (the dispersion and its chi-square), and each pass's own time
//! offset (a clock that steps or drifts moves some passes and not others).

use super::outcome::{PassReport, Refusal};
use super::settings::Settings;
use super::{fit_with_covariance, MAX_PASSES};
use crate::align::window::{Observation, Target};
use crate::calib::nav::NavModel;
use crate::calib::objective::TimeOffset;
use crate::georef::{Mount, Params, P};
use nalgebra::{Matrix3, Vector3};

/// What the per-pass checks judge: the spheres, their returns (the first `used` of each kept),
/// the solution's mounting `b` and its time offset model.
#[derive(Clone, Copy)]
pub(super) struct Answer<'a, 'o> {
    pub(super) targets: &'a [Target],
    pub(super) obs: &'a [&'o mut [Observation]],
    pub(super) used: &'a [usize],
    pub(super) b: &'a [f64; P],
    pub(super) time: &'a TimeOffset,
}

impl<'a> Answer<'a, '_> {
    /// Pass `p`'s sphere and its kept returns within the pass (None: a sphere not given).
    fn pass(
        &self,
        p: &PassReport,
    ) -> Option<(
        &'a Target,
        impl Iterator<Item = &'a Observation> + Clone + 'a,
    )> {
        let j = usize::from(p.sphere);
        let (t, v) = (self.targets.get(j)?, self.obs.get(j)?);
        let v: &'a [Observation] = v.get(..*self.used.get(j)?)?;
        let (start, end) = (p.start, p.end);
        Some((
            t,
            v.iter().filter(move |o| o.time >= start && o.time <= end),
        ))
    }
}

/// Each pass's sphere centre (fitted, radius fixed, to its kept returns with the solution)
/// against the surveyed one: its offset, along-track component and chi-square into `passes`;
/// returns the worst pass as a refusal if any fails (beyond `max_pass_chi2` and
/// `pass_offset_floor`). The uncertainty: the fit's, from the pass's residual scatter (at least
/// 1 mm), inflated by the returns per 20 ms cluster (they share INS errors).
pub(super) fn consistency(
    at: &Answer<'_, '_>,
    s: &Settings,
    passes: &mut heapless::Vec<PassReport, MAX_PASSES>,
) -> Option<Refusal> {
    let mount = Mount::from_params(&Params(*at.b));
    let mut worst: Option<(f64, Refusal)> = None;
    for (k, p) in passes.iter_mut().enumerate() {
        let j = usize::from(p.sphere);
        let Some((t, kept)) = at.pass(p) else {
            continue;
        };
        let Some(fit) = fit_with_covariance(kept.clone(), &mount, at.time, t) else {
            continue;
        };
        let (d, jtj, rms, n) = fit;
        // Clusters of 20 ms: returns within one share INS errors.
        let mut clusters = 0usize;
        let mut last = i64::MIN;
        for o in kept.clone() {
            let c = o.time.0.div_euclid(s.cluster_ns.max(1));
            if c != last {
                clusters += 1;
                last = c;
            }
        }
        let inflate = n as f64 / clusters.max(1) as f64;
        let s2 = rms.max(1e-3) * rms.max(1e-3) * inflate;
        let chi2 = match &s.nav {
            // Under the navigation model the pass's centre is also off by the pass's
            // navigation error and the survey's: its covariance adds theirs.
            Some(m) => {
                let arm = t.center - mean_position(kept.clone());
                let extra = nav_offset_covariance(m, &arm)
                    + Matrix3::identity() * s.centre_sigma[j] * s.centre_sigma[j];
                jtj.try_inverse()
                    .map(|inv| inv * s2 + extra)
                    .and_then(|c| c.try_inverse())
                    .map_or(f64::INFINITY, |ci| d.dot(&(ci * d)))
            }
            None => d.dot(&(jtj * d)) / s2,
        };
        // Along the pass's course (its kept returns' mean horizontal velocity, unit or zero).
        let along = d.x * f64::from(p.course[0]) + d.y * f64::from(p.course[1]);
        p.centre_offset = [d.x as f32, d.y as f32, d.z as f32];
        p.along_track = along as f32;
        p.chi2 = chi2 as f32;
        if chi2 > s.max_pass_chi2
            && d.norm() > s.pass_offset_floor
            && worst.as_ref().is_none_or(|(c, _)| chi2 > *c)
        {
            worst = Some((
                chi2,
                Refusal::Inconsistent {
                    sphere: j,
                    pass: k,
                    offset: [d.x, d.y, d.z],
                    along_track: along,
                    chi2,
                },
            ));
        }
    }
    worst.map(|(_, r)| r)
}

/// Each pass's own time offset: the returns of one pass over one sphere, with the mounting and
/// the time offset model held, fitted for a shift of the offset and a radius offset (`r_k = c -
/// J_k shift`, `J_k = dr/ddt`, the platform's motion along the surface normal); its sigma from
/// the fit's scatter inflated by the returns per cluster, as [`consistency`]. Into `passes`;
/// the pass furthest off as a refusal when it is off by more than `held_dt_sigmas` sigmas and
/// `held_dt_floor` seconds: a clock that steps or drifts moves some passes and not others.
pub(super) fn pass_clocks(
    at: &Answer<'_, '_>,
    s: &Settings,
    passes: &mut heapless::Vec<PassReport, MAX_PASSES>,
) -> Option<Refusal> {
    let Answer { b, time, .. } = *at;
    let lin = super::super::objective::Linearised::at(b).with_footprint(s.footprint);
    let first = passes.iter().map(|p| p.start.0).min().unwrap_or(0);
    let mut worst: Option<(f64, Refusal)> = None;
    for (k, p) in passes.iter_mut().enumerate() {
        let j = usize::from(p.sphere);
        let Some((t, kept)) = at.pass(p) else {
            continue;
        };
        // Sums for the two-parameter fit, and the clusters.
        let (mut n, mut sj, mut sr, mut sjj, mut sjr, mut srr) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut clusters, mut last) = (0usize, i64::MIN);
        for o in kept.clone() {
            let Some(row) = lin.row(o, t, time.at(o)) else {
                continue;
            };
            let (jd, r) = (row.row[6], row.residual);
            n += 1.0;
            sj += jd;
            sr += r;
            sjj += jd * jd;
            sjr += jd * r;
            srr += r * r;
            let c = o.time.0.div_euclid(s.cluster_ns.max(1));
            if c != last {
                clusters += 1;
                last = c;
            }
        }
        if n < 10.0 {
            continue;
        }
        let vjj = sjj - sj * sj / n;
        if vjj.is_nan() || vjj <= 0.0 {
            continue;
        }
        // r = c + J kk; a residual r at the model's offset is what -J (dt_data - dt_model)
        // leaves, so the pass's own offset is the model's minus kk.
        let kk = (sjr - sj * sr / n) / vjj;
        let c = (sr - kk * sj) / n;
        // Residual scatter (at least 1 mm), inflated by the returns per cluster.
        let e2 =
            (srr - 2.0 * c * sr - 2.0 * kk * sjr + n * c * c + 2.0 * c * kk * sj + kk * kk * sjj)
                / (n - 2.0).max(1.0);
        let s2 = e2.max(1e-6) * n / clusters.max(1) as f64;
        let mut sigma = libm::sqrt(s2 / vjj);
        if let Some(m) = &s.nav {
            // The pass's navigation error along the track looks like a clock shift of that
            // distance over the speed.
            sigma = libm::sqrt(sigma * sigma + nav_shift_variance(m, kept.clone()));
        }
        let shift = -kk;
        p.dt_shift = shift as f32;
        p.dt_sigma = sigma as f32;
        let z = shift.abs() / sigma;
        if s.offsets_apart(shift, sigma) && worst.as_ref().is_none_or(|(w, _)| z > *w) {
            worst = Some((
                z,
                Refusal::ClockInconsistent {
                    sphere: j,
                    pass: k,
                    start: p.start,
                    end: p.end,
                    into: [
                        (p.start.0 - first) as f64 * 1e-9,
                        (p.end.0 - first) as f64 * 1e-9,
                    ],
                    shift,
                    sigma,
                },
            ));
        }
    }
    worst
        .map(|(_, r)| r)
        .or_else(|| clock_step(passes, first, s))
}

/// A step of the time offset between passes ([`Refusal::ClockStep`]): at each pass's start,
/// the inverse-variance means of the passes' own offsets wholly after it and wholly before it
/// (a pass spanning it is in neither); the split furthest off, when by more than
/// `held_dt_sigmas` sigmas and `held_dt_floor` seconds. A step shifts every pass after it
/// alike, so together they show what each alone may not.
fn clock_step(passes: &[PassReport], first: i64, s: &Settings) -> Option<Refusal> {
    let judged =
        |p: &&PassReport| p.dt_sigma > 0.0 && p.dt_sigma.is_finite() && p.dt_shift.is_finite();
    let mut best: Option<(f64, Refusal)> = None;
    for at in passes.iter().filter(judged).map(|p| p.start) {
        // (weight, weighted sum, passes) of one side.
        let side = |after: bool| {
            let (mut w, mut wx, mut n) = (0.0f64, 0.0f64, 0u16);
            for p in passes.iter().filter(judged) {
                let on = if after {
                    p.start.0 >= at.0
                } else {
                    p.end.0 < at.0
                };
                if on {
                    let wi = 1.0 / (f64::from(p.dt_sigma) * f64::from(p.dt_sigma));
                    w += wi;
                    wx += wi * f64::from(p.dt_shift);
                    n += 1;
                }
            }
            (w, wx, n)
        };
        let ((wb, xb, nb), (wa, xa, na)) = (side(false), side(true));
        if nb == 0 || na == 0 {
            continue;
        }
        let step = xa / wa - xb / wb;
        let sigma = libm::sqrt(1.0 / wa + 1.0 / wb);
        let z = step.abs() / sigma;
        if s.offsets_apart(step, sigma) && best.as_ref().is_none_or(|(b, _)| z > *b) {
            best = Some((
                z,
                Refusal::ClockStep {
                    at,
                    into: (at.0 - first) as f64 * 1e-9,
                    step,
                    sigma,
                    after: na,
                    passes: na + nb,
                },
            ));
        }
    }
    best.map(|(_, r)| r)
}

/// The mean INS position of a pass's returns.
fn mean_position<'a>(obs: impl Iterator<Item = &'a Observation>) -> Vector3<f64> {
    let (mut sum, mut n) = (Vector3::zeros(), 0.0);
    for o in obs {
        sum += o.position;
        n += 1.0;
    }
    if n > 0.0 {
        sum / n
    } else {
        sum
    }
}

/// The covariance a navigation error puts on a sphere centre seen along `arm` (INS to centre,
/// NED): the position's, and each rotation's `e_a x arm` (first order).
fn nav_offset_covariance(m: &NavModel, arm: &Vector3<f64>) -> Matrix3<f64> {
    let sg = m.sigmas();
    let mut c = Matrix3::from_diagonal(&Vector3::new(sg[0] * sg[0], sg[1] * sg[1], sg[2] * sg[2]));
    for (a, s) in sg[3..].iter().enumerate() {
        let mut e = Vector3::zeros();
        e[a] = 1.0;
        let d = e.cross(arm);
        c += d * d.transpose() * (s * s);
    }
    c
}

/// The variance [s^2] a navigation error puts on a pass's own clock shift: its displacement
/// along the track (the position's horizontal sigma, the rotations' at the pass's mean range)
/// over the pass's mean speed.
fn nav_shift_variance<'a>(m: &NavModel, obs: impl Iterator<Item = &'a Observation>) -> f64 {
    let (mut speed, mut range, mut n) = (0.0, 0.0, 0.0);
    for o in obs {
        speed += f64::from(o.velocity.norm());
        range += f64::from(o.range);
        n += 1.0;
    }
    if n == 0.0 {
        return 0.0;
    }
    let (speed, range) = ((speed / n).max(0.1), range / n);
    let sg = m.sigmas();
    let along = sg[0] * sg[0] + range * range * (sg[3] * sg[3] + sg[5] * sg[5]);
    along / (speed * speed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::GpsTime;

    /// Passes 10 s apart, each 6 s long, with their own offsets and sigmas [ms].
    fn passes(own: &[(f32, f32)]) -> heapless::Vec<PassReport, MAX_PASSES> {
        own.iter()
            .enumerate()
            .map(|(k, &(shift, sigma))| PassReport {
                end: GpsTime(k as i64 * 10_000_000_000 + 6_000_000_000),
                dt_shift: shift * 1e-3,
                dt_sigma: sigma * 1e-3,
                ..PassReport::starting((k % 2) as u8, GpsTime(k as i64 * 10_000_000_000))
            })
            .collect()
    }

    /// The POS MV step of `clocks::a_clock_step_the_stream_cannot_show_*` (+50 ms, the passes'
    /// own offsets as measured there, none beyond 5 sigma alone): found at the first pass
    /// after it. The same offsets in no order of time, or half as far apart, are not a step.
    #[test]
    fn a_step_the_passes_show_together_is_found() {
        let s = Settings::default();
        let measured = [
            (-3.7, 2.68),
            (-2.6, 1.56),
            (-18.1, 7.07),
            (-21.5, 6.79),
            (19.7, 4.19),
            (34.3, 9.74),
            (30.9, 9.43),
            (18.3, 6.94),
        ];
        let Some(Refusal::ClockStep {
            at,
            step,
            sigma,
            after,
            passes: n,
            ..
        }) = clock_step(&passes(&measured), 0, &s)
        else {
            panic!("no step found");
        };
        assert_eq!((at.0, after, n), (40_000_000_000, 4, 8));
        assert!(
            (step - 0.0263).abs() < 1e-3 && (sigma - 0.0034).abs() < 3e-4,
            "{step} {sigma}"
        );
        let mixed = [
            measured[4],
            measured[0],
            measured[5],
            measured[1],
            measured[6],
            measured[2],
            measured[7],
            measured[3],
        ];
        assert_eq!(clock_step(&passes(&mixed), 0, &s), None);
        let half: heapless::Vec<(f32, f32), 8> =
            measured.iter().map(|&(x, sg)| (x / 2.0, sg)).collect();
        assert_eq!(clock_step(&passes(&half), 0, &s), None);
    }
}

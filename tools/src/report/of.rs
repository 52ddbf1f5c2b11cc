//! The report of one solve ([`Report::of`]): the solution, its sigmas and correlations, the
//! passes and spheres with their verdicts, the consistency tests, the refusal in words.

use super::{
    Angles, Consistency, NavigationReport, PerPass, PerSphere, Report, Sigma, Verdicts, Xyz,
};
use crate::reasons::{lost_name, refusal_text};
use spherecal::calib::nav::Piece;
use spherecal::calib::solve::{PassReport, Settings, Solution, SphereReport};
use spherecal::georef::{Params, NAMES, P};

impl Report {
    /// The report of `sol`, solved from `b0` with settings `s` over the spheres `ids` in
    /// `solve_ms`; `nav_pieces` the navigation model's pieces the solve left in its scratch.
    /// The inputs, targets, provenance and the like are the caller's to fill in.
    pub fn of(
        sol: &Solution,
        ids: &[String],
        b0: &Params,
        s: &Settings,
        nav_pieces: &[Piece],
        solve_ms: f64,
    ) -> Report {
        let b = sol.b.0;
        let lm = sol.lm;
        let sigma = lm.map_or([f64::NAN; P], |l| l.sigma);
        let weak: Vec<String> = NAMES
            .iter()
            .chain(&["time_offset"])
            .zip(sol.weak)
            .filter(|(_, w)| *w)
            .map(|(n, _)| n.to_string())
            .collect();
        let ((boresight_deg, lever_arm_m), (sigma_deg, sigma_m)) = (split(&b), split(&sigma));
        Report {
            boresight_deg,
            lever_arm_m,
            sigma: Sigma {
                boresight_deg: sigma_deg,
                lever_arm_m: sigma_m,
                time_offset_s: lm.map_or(f64::NAN, |l| l.sigma_dt),
            },
            time_offset_s: sol.dt,
            time_offset_estimated: s.estimate_dt,
            time_drift_ppm: sol.drift * 1e6,
            time_drift_sigma_ppm: lm.map_or(0.0, |l| l.sigma_drift * 1e6),
            time_offset_reference_gps_s: sol.t_ref.as_secs_f64(),
            rms_m: lm.map_or(f64::NAN, |l| l.rms),
            objective_l1_m: sol.l1,
            points_per_sphere: sol.spheres.iter().map(|s| s.used).collect(),
            evaluations: sol.nm.evaluations,
            nm_iterations: sol.nm.iterations,
            lm_iterations: lm.map_or(0, |l| l.iterations),
            rounds: sol.rounds,
            termination: sol.termination.name().into(),
            converged: sol.refusal.is_none(),
            reason: sol
                .refusal
                .as_ref()
                .map(|r| refusal_text(r, ids, &weak, s.estimate_dt)),
            correlation: correlation(sol),
            correlation_labels: NAMES
                .iter()
                .chain(&["time_offset"])
                .map(|n| n.to_string())
                .collect(),
            version: format!("spherecal {}", env!("CARGO_PKG_VERSION")),
            condition_number: lm.map_or(f64::INFINITY, |l| l.condition),
            weak_parameters: weak,
            sphere_centre_rms_m: sol.center_rms,
            per_pass: sol.passes.iter().map(|p| PerPass::of(p, ids)).collect(),
            shell_m: sol.shell,
            consistency: Consistency::of(sol),
            batch_overflow: 0,
            inputs: None,
            navigation: s.nav.map(|m| {
                let pieces = sol
                    .nav
                    .map_or(&[][..], |f| &nav_pieces[..f.pieces.min(nav_pieces.len())]);
                NavigationReport::of(&m, sol.nav.as_ref(), pieces, s, ids)
            }),
            set_aside: Vec::new(),
            targets: None,
            held: Vec::new(),
            mounting_prior: Vec::new(),
            conventions: None,
            provenance: None,
            clutter_rejected: sol
                .spheres
                .iter()
                .map(|s| u64::from(Verdicts::from_tally(&s.verdicts).rejected()))
                .sum(),
            per_sphere: sol
                .spheres
                .iter()
                .zip(ids)
                .map(|(s, id)| PerSphere::of(s, id))
                .collect(),
            solve_ms,
            time_offset_search: Vec::new(),
            effort: None,
            start: NAMES
                .iter()
                .zip(b0.deg_m().0)
                .map(|(n, v)| (n.to_string(), v))
                .collect(),
        }
    }
}

impl PerPass {
    /// One pass of the solution over one of the spheres `ids`.
    fn of(p: &PassReport, ids: &[String]) -> Self {
        PerPass {
            sphere: ids.get(usize::from(p.sphere)).cloned().unwrap_or_default(),
            start_gps_s: p.start.as_secs_f64(),
            end_gps_s: p.end.as_secs_f64(),
            slices: p.slices,
            detected: p.detected,
            mean_inliers: p.mean_inliers,
            windowed: p.verdicts.iter().sum(),
            verdicts: Verdicts::from_tally(&p.verdicts),
            centre_offset_m: p.centre_offset,
            along_track_m: p.along_track,
            chi2: p.chi2,
            time_offset_shift_s: p.dt_shift,
            time_offset_shift_sigma_s: p.dt_sigma,
        }
    }
}

impl PerSphere {
    /// One sphere of the solution, named `id`.
    fn of(s: &SphereReport, id: &str) -> Self {
        PerSphere {
            id: id.to_string(),
            found: s.found,
            windowed: s.windowed,
            points: s.used,
            rounds_kept: s.rounds_kept,
            slices: s.slices,
            detected: s.detected,
            verdicts: Verdicts::from_tally(&s.verdicts),
            rms_before_m: s.rms_before,
            rms_after_m: s.rms_after,
            centre_offset_m: s.center_offset.map(|c| [c.x, c.y, c.z]),
            agreed_slices: s.agreed,
            lost: s.lost.map(|l| lost_name(l).to_string()),
            apparent_radius_m: None,
        }
    }
}

impl Consistency {
    /// The tests `sol` passed or failed.
    fn of(sol: &Solution) -> Self {
        let lm = sol.lm;
        Consistency {
            predicted_rms_m: sol.predicted_rms,
            dispersion: lm.map_or(f64::NAN, |l| l.rms) / sol.predicted_rms.max(1e-12),
            worst_pass_chi2: sol
                .passes
                .iter()
                .map(|p| f64::from(p.chi2))
                .fold(0.0, f64::max),
            free_time_offset_s: sol.dt_free.map(|(d, sg)| [d - sol.dt, sg]),
            misfit_pieces_set_aside: sol.set_aside.misfit_pieces.into(),
            influential_set_aside: sol.set_aside.influential.into(),
            second_start: sol
                .second_start
                .map(|s| [s.first, s.second, u32::from(s.taken)]),
        }
    }
}

/// The correlations of the six and the time offset (NaN without a least-squares solve; the
/// time offset's row and column 0 when it was held).
fn correlation(sol: &Solution) -> Vec<Vec<f64>> {
    let lm = sol.lm;
    (0..=P)
        .map(|i| {
            (0..=P)
                .map(|j| {
                    lm.map_or(f64::NAN, |l| match (i, j) {
                        (P, P) => f64::from(u8::from(l.estimated_dt)),
                        (P, k) | (k, P) => l.dt_correlation[k],
                        _ => l.correlation[(i, j)],
                    })
                })
                .collect()
        })
        .collect()
}

/// The six [rad, m] as the report writes them: the angles in degrees, the lever arm in metres.
fn split(v: &[f64; P]) -> (Angles, Xyz) {
    (
        Angles {
            roll: v[0].to_degrees(),
            pitch: v[1].to_degrees(),
            heading: v[2].to_degrees(),
        },
        Xyz {
            x: v[3],
            y: v[4],
            z: v[5],
        },
    )
}

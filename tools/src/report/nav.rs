//! The navigation model's part of the report (`report.json` `navigation`).

use super::{CentreCorrection, NavCorrectionReport, NavigationReport};

impl NavigationReport {
    /// The navigation model's part of the report: the model, the fit's centres and every
    /// piece's correction (the source is the session's to name).
    pub fn of(
        m: &spherecal::calib::nav::NavModel,
        fit: Option<&spherecal::calib::nav::NavFit>,
        pieces: &[spherecal::calib::nav::Piece],
        s: &spherecal::calib::Settings,
        ids: &[String],
    ) -> Self {
        // Under white errors the pieces are held at zero: nothing to list.
        let pieces = if m.is_white() { &[][..] } else { pieces };
        let corrections = pieces
            .iter()
            .map(|p| NavCorrectionReport {
                start_gps_s: p.start.0 as f64 * 1e-9,
                end_gps_s: p.end.0 as f64 * 1e-9,
                returns: p.n,
                position_m: [p.error[0], p.error[1], p.error[2]],
                position_sigma_m: [p.sigma[0], p.sigma[1], p.sigma[2]],
                rotation_deg: [p.error[3], p.error[4], p.error[5]].map(f64::to_degrees),
                rotation_sigma_deg: [p.sigma[3], p.sigma[4], p.sigma[5]].map(f64::to_degrees),
            })
            .collect();
        Self {
            source: "site [ins.correlated]".into(),
            position_sigma_m: m.position_sigma,
            attitude_sigma_deg: m.attitude_sigma.map(f64::to_degrees),
            correlation_s: m.correlation_s,
            pieces: fit.map_or(0, |f| f.pieces),
            white_noise_factor: fit.map_or(f64::NAN, |f| f.variance_factor),
            footprint_spread: fit.map_or(0.0, |f| f.spread_share),
            centres: ids
                .iter()
                .enumerate()
                .map(|(j, id)| CentreCorrection {
                    sphere: id.clone(),
                    prior_sigma_m: s.centre_sigma.get(j).copied().unwrap_or(0.0),
                    correction_m: fit
                        .and_then(|f| f.centre.get(j).copied())
                        .unwrap_or([f64::NAN; 3]),
                    sigma_m: fit
                        .and_then(|f| f.centre_sigma.get(j).copied())
                        .unwrap_or([f64::NAN; 3]),
                })
                .collect(),
            corrections,
            worst_step_sigmas: fit.map_or(f64::NAN, |f| f.worst_step.0),
            worst_step_gps_s: fit.map_or(f64::NAN, |f| f.worst_step.1 .0 as f64 * 1e-9),
        }
    }
}

impl NavigationReport {
    /// No error that wanders (white INS errors): only the sphere centres were estimated with
    /// the mounting ([`spherecal::calib::nav::NavModel::WHITE`]).
    pub fn is_white(&self) -> bool {
        self.position_sigma_m
            .iter()
            .chain(&self.attitude_sigma_deg)
            .all(|s| *s == 0.0)
    }
}

//! `report.json` `mounting_prior`: the mounting as measured on the vessel (`[apriori]`'s
//! sigmas), each measured parameter beside what the calibration made of it.

use super::Report;
use serde::{Deserialize, Serialize};
use spherecal::georef::NAMES;

/// One measured parameter of the mounting.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct MeasuredParameter {
    /// roll, pitch, heading, x, y or z.
    pub parameter: String,
    /// The measured value [deg or m].
    pub measured: f64,
    /// Its declared 1-sigma [deg or m].
    pub sigma: f64,
    /// The calibration minus the measurement [deg or m].
    pub moved: f64,
    /// `moved` over what the measurement leaves unexplained (its variance less the
    /// calibration's, at least a tenth of its own): beyond 3, the measurement is named.
    pub z: f64,
}

/// The measured parameters of `site`'s `[apriori]` against the report's calibration (empty
/// without sigmas).
pub fn of(site: &crate::config::site::SiteApriori, r: &Report) -> Vec<MeasuredParameter> {
    let measured = site.mount().deg_m().0;
    let mut sigma = [f64::NAN; 6];
    if let Some(s) = site.boresight_sigma_deg {
        sigma[..3].copy_from_slice(&s);
    }
    if let Some(s) = site.lever_arm_sigma_m {
        sigma[3..].copy_from_slice(&s);
    }
    let (got, post) = (r.deg_m(), r.sigma.deg_m());
    (0..6)
        .filter(|&i| sigma[i].is_finite())
        .map(|i| {
            let moved = got[i] - measured[i];
            let (sp2, p2) = (sigma[i] * sigma[i], post[i] * post[i]);
            let left = (sp2 - if p2.is_finite() { p2 } else { 0.0 }).max(0.1 * sp2);
            MeasuredParameter {
                parameter: NAMES[i].into(),
                measured: measured[i],
                sigma: sigma[i],
                moved,
                z: moved / left.sqrt(),
            }
        })
        .collect()
}

/// The measured parameters in words, one line each; a WARNING for one the data move beyond 3.
pub fn words(m: &[MeasuredParameter]) -> String {
    let mut o = String::new();
    for p in m {
        let (scale, unit, prec) = if p.parameter.len() > 1 {
            (1.0, "deg", 4)
        } else {
            (1e3, "mm", 1)
        };
        let line = format!(
            "{} measured {:.prec$} +- {:.prec$} {unit}: the calibration moved it {:+.prec$} {unit} ({:.1} of what the measurement leaves)",
            p.parameter,
            p.measured * scale,
            p.sigma * scale,
            p.moved * scale,
            p.z.abs()
        );
        if p.z.abs() > 3.0 {
            o.push_str(&format!(
                "WARNING: the measured mounting: {line}: check the measurement or its sigma\n"
            ));
        } else {
            o.push_str(&format!("measured mounting: {line}\n"));
        }
    }
    o
}

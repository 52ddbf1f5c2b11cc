//! A parameter the data cannot determine under the navigation model (issue 47 item 2: the
//! vertical lever arm under a VN-200's metre-level vertical error), held at its a-priori value
//! with a prior and named, the others calibrated: not "stalled", not "condition number inf".
//! Solved again with every parameter the site measured no sigma for under a wide prior at its
//! a-priori value ([`HOLD_DEG`] / [`HOLD_M`]: far wider than what the data fix of a determined
//! parameter, so that it moves nothing there); those whose sigma stays above half the hold's
//! are the undetermined ones, named as held (their sigma says it: exit 3 against any target),
//! and the others' sigmas carry their uncertainty. Nothing undetermined: the refusal stands.

use crate::config::site::Site;
use spherecal::calib::{Refusal, Solution};
use spherecal::georef::{Params, NAMES, P};

/// An undetermined angle's prior when the site measured none [deg].
pub const HOLD_DEG: f64 = 5.0;
/// An undetermined lever-arm component's prior when the site measured none [m].
pub const HOLD_M: f64 = 0.5;

/// The parameters among the six the data may leave undetermined: after a refusal for
/// conditioning or convergence, those the site holds by no prior of its own; after a claim,
/// those of them whose sigma is already over half the hold's (the data alone pin them no
/// better than the hold would: a lever arm's height at +- 0.6 m is not a calibration). Empty:
/// nothing to try.
pub fn candidates(sol: &Solution, site: &Site) -> Vec<usize> {
    let prior = site.apriori.prior();
    let free = (0..P).filter(|&i| prior.info[i] <= 0.0);
    match (&sol.refusal, &sol.lm) {
        (Some(Refusal::IllConditioned { .. } | Refusal::NotConverged { .. }), _) => free.collect(),
        (None, Some(l)) => undetermined(&free.collect::<Vec<_>>(), &Params(l.sigma).deg_m().0),
        _ => Vec::new(),
    }
}

/// Of the `candidates` held by the hold's prior, those the data left undetermined: the
/// calibrated sigma more than half the hold's (the data took less than three quarters of its
/// variance away). `sigma`: the calibration's, roll, pitch, heading [deg], x, y, z [m].
pub fn undetermined(candidates: &[usize], sigma: &[f64; P]) -> Vec<usize> {
    candidates
        .iter()
        .copied()
        .filter(|&i| {
            let hold = if i < 3 { HOLD_DEG } else { HOLD_M };
            sigma[i].is_nan() || sigma[i] > 0.5 * hold
        })
        .collect()
}

/// Why the claimed `sol` left `idx` undetermined: their sigmas with the data alone.
pub fn alone(sol: &Solution, idx: &[usize]) -> String {
    let s = sol.lm.map(|l| l.sigma).unwrap_or_default();
    idx.iter()
        .map(|&i| match i {
            0..3 => format!("{} +- {:.2} deg", NAMES[i], s[i].to_degrees()),
            _ => format!("{} +- {:.0} mm", NAMES[i], s[i] * 1e3),
        })
        .collect::<Vec<_>>()
        .join(", ")
        + " with the data alone"
}

/// `site` with the parameters `idx` held at their a-priori values: their prior the site's
/// sigma, else the hold's; the others as the site had them (none: no prior).
pub fn holding(site: &Site, idx: &[usize]) -> Site {
    let mut s = site.clone();
    let a = &mut s.apriori;
    let mut deg = a.boresight_sigma_deg.unwrap_or([f64::NAN; 3]);
    let mut m = a.lever_arm_sigma_m.unwrap_or([f64::NAN; 3]);
    for &i in idx {
        if i < 3 {
            deg[i] = HOLD_DEG;
        } else {
            m[i - 3] = HOLD_M;
        }
    }
    a.boresight_sigma_deg = deg.iter().any(|v| v.is_finite()).then_some(deg);
    a.lever_arm_sigma_m = m.iter().any(|v| v.is_finite()).then_some(m);
    s
}

/// The held parameters in words, one line each.
pub fn words(idx: &[usize], site: &Site, why: &str) -> String {
    let b = site.apriori.mount().deg_m().0;
    idx.iter()
        .map(|&i| {
            let (v, sg) = if i < 3 {
                (format!("{:.3} deg", b[i]), format!("{HOLD_DEG} deg"))
            } else {
                (format!("{:.3} m", b[i]), format!("{:.0} mm", HOLD_M * 1e3))
            };
            format!(
                "HELD: {} at its a-priori value {v} +- {sg}: the data do not determine it under this navigation model ({why}); the others are calibrated with it held. Measure it on the vessel and give its sigma ([apriori] {}), or declare the INS's real accuracy ([ins.correlated])\n",
                NAMES[i],
                if i < 3 { "boresight_sigma_deg" } else { "lever_arm_sigma_m" }
            )
        })
        .collect()
}

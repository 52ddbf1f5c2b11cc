//! The accuracy wanted, one type for the planner and the verdict ([`Goal`]), and the board's
//! `[calibration]` table that may give it ([`Targets`]).

use serde::{Deserialize, Serialize};

/// The accuracy wanted: the planner plans for it, the verdict judges the data so far by it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Goal {
    /// Each boresight angle's 1-sigma [deg].
    pub sigma_deg: f64,
    /// Each lever-arm component's 1-sigma [m].
    pub sigma_m: f64,
    /// The solver's largest acceptable condition number (it refuses beyond).
    pub max_condition: f64,
    /// Fewest returns per sphere the solver needs.
    pub min_returns: u32,
}

impl Default for Goal {
    fn default() -> Self {
        let st = spherecal::calib::Settings::default();
        Self {
            sigma_deg: 0.01,
            sigma_m: 0.005,
            max_condition: st.max_condition,
            min_returns: st.min_points as u32,
        }
    }
}

/// The accuracy wanted (board `[calibration]`): each sigma at most this. Without them the
/// survey is done when another pass would improve no sigma by more than
/// [`crate::plan::live::ENOUGH_GAIN`] (what the board's sensors can reach, by the planner).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Targets {
    /// Each boresight angle's 1-sigma at most [deg].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_sigma_deg: Option<f64>,
    /// Each lever-arm component's 1-sigma at most [m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_sigma_m: Option<f64>,
}

impl Targets {
    /// Each target given is a positive, finite sigma; an error names the key (under `table`,
    /// e.g. `calibration`).
    pub fn check(&self, table: &str) -> Result<(), crate::Error> {
        for (k, v) in [
            ("target_sigma_deg", self.target_sigma_deg),
            ("target_sigma_m", self.target_sigma_m),
        ] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(format!("{table}.{k} = {v}: expected a positive, finite sigma").into());
            }
        }
        Ok(())
    }

    /// The planner's goal for these targets (a target not given constrains nothing); `None`
    /// without any.
    pub fn goal(&self) -> Option<Goal> {
        if self.target_sigma_deg.is_none() && self.target_sigma_m.is_none() {
            return None;
        }
        Some(Goal {
            sigma_deg: self.target_sigma_deg.unwrap_or(f64::INFINITY),
            sigma_m: self.target_sigma_m.unwrap_or(f64::INFINITY),
            ..Goal::default()
        })
    }
}

/// The targets a calibration is judged by when neither the site nor the board gives one
/// (README "Accuracy targets"): each boresight angle 0.01 deg and each lever-arm component
/// 5 mm, 1 sigma. At 50 m, the far end of a VLP-16 survey's useful range, a 0.01 deg error
/// moves a point 8.7 mm, and 5 mm of lever arm moves every point by as much: together under a
/// fifth of the 5 cm RMSE of the ASPRS Positional Accuracy Standards' (2023) 5-cm horizontal
/// class, and under a tenth of the 0.5 m (95 %) total horizontal uncertainty of an IHO S-44
/// (6th ed.) Exclusive Order survey; the calibration is one term of such a budget among
/// several (the INS, the LiDAR's own noise, the survey of the spheres).
pub const DEFAULT_TARGETS: (f64, f64) = (0.01, 0.005);

/// The targets a calibration is judged by, and where they came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetChoice {
    /// Each boresight angle's 1-sigma at most [deg] (infinite: not targeted).
    pub sigma_deg: f64,
    /// Each lever-arm component's 1-sigma at most [m] (infinite: not targeted).
    pub sigma_m: f64,
    /// Where they came from, in words.
    pub source: String,
}

impl TargetChoice {
    /// The site's `[calibration]`, else the board's, else [`DEFAULT_TARGETS`].
    pub fn of(site: Option<&Targets>, board: Option<&Targets>) -> Self {
        let given = |t: &Targets| t.target_sigma_deg.is_some() || t.target_sigma_m.is_some();
        for (t, owner) in [
            (site, "the site's [calibration]"),
            (board, "the board's [calibration]"),
        ] {
            if let Some(t) = t.filter(|t| given(t)) {
                return Self {
                    sigma_deg: t.target_sigma_deg.unwrap_or(f64::INFINITY),
                    sigma_m: t.target_sigma_m.unwrap_or(f64::INFINITY),
                    source: owner.into(),
                };
            }
        }
        Self {
            sigma_deg: DEFAULT_TARGETS.0,
            sigma_m: DEFAULT_TARGETS.1,
            source: "the default, README \"Accuracy targets\"; the site's [calibration] sets them"
                .into(),
        }
    }

    /// The planner's and the live verdict's goal for these targets.
    pub fn goal(&self) -> Goal {
        Goal {
            sigma_deg: self.sigma_deg,
            sigma_m: self.sigma_m,
            ..Goal::default()
        }
    }

    /// The parameters whose sigma `sigma` (roll, pitch, heading [deg], x, y, z [m]) misses its
    /// target, by name (a sigma that is not a number misses).
    pub fn missed(&self, sigma: &[f64; 6]) -> Vec<&'static str> {
        const NAMES: [&str; 6] = ["roll", "pitch", "heading", "x", "y", "z"];
        (0..6)
            .filter(|&i| {
                let t = if i < 3 { self.sigma_deg } else { self.sigma_m };
                sigma[i].is_nan() || sigma[i] > t
            })
            .map(|i| NAMES[i])
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_site_then_the_board_then_the_default() {
        let site = Targets {
            target_sigma_deg: Some(0.02),
            target_sigma_m: None,
        };
        let board = Targets {
            target_sigma_deg: Some(0.05),
            target_sigma_m: Some(0.01),
        };
        let c = TargetChoice::of(Some(&site), Some(&board));
        assert_eq!((c.sigma_deg, c.sigma_m), (0.02, f64::INFINITY));
        assert!(c.source.contains("site"));
        let c = TargetChoice::of(Some(&Targets::default()), Some(&board));
        assert_eq!((c.sigma_deg, c.sigma_m), (0.05, 0.01));
        let c = TargetChoice::of(None, None);
        assert_eq!((c.sigma_deg, c.sigma_m), DEFAULT_TARGETS);
        assert!(c.source.contains("default"));
        assert_eq!(
            c.missed(&[0.005, 0.02, f64::NAN, 0.001, 0.006, 0.004]),
            ["pitch", "heading", "y"]
        );
    }
}

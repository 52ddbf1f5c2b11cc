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

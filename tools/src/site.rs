//! `site.toml`: the surveyed targets and the a-priori mounting (README "site.toml").

use serde::{Deserialize, Serialize};

/// Site origin.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Origin {
    /// Latitude [deg].
    pub lat_deg: f64,
    /// Longitude [deg].
    pub lon_deg: f64,
    /// Ellipsoidal height [m].
    pub h_m: f64,
}

/// A surveyed sphere.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteSphere {
    /// Name.
    pub id: String,
    /// Centre latitude [deg].
    pub lat_deg: f64,
    /// Centre longitude [deg].
    pub lon_deg: f64,
    /// Centre ellipsoidal height [m].
    pub h_m: f64,
    /// Radius [m].
    pub radius_m: f64,
}

/// A-priori mounting and window margin.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteApriori {
    /// Roll, pitch, heading [deg].
    pub boresight_deg: [f64; 3],
    /// x, y, z [m].
    pub lever_arm_m: [f64; 3],
    /// Window margin beyond the radius [m].
    pub window_margin_m: f64,
}

/// The whole file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Site {
    /// GPS - UTC [s].
    pub leap_seconds: i64,
    /// Local NED origin.
    pub origin: Origin,
    /// Spheres.
    pub sphere: Vec<SiteSphere>,
    /// A-priori values.
    pub apriori: SiteApriori,
}

impl Site {
    /// Read and check a site file; errors name the file and the key.
    pub fn load(path: &std::path::Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let s: Site = toml::from_str(&text)
            .map_err(|e| format!("{}: {}", path.display(), e.to_string().trim()))?;
        s.check().map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(s)
    }

    /// Values a calibration can use.
    pub fn check(&self) -> Result<(), String> {
        if self.origin.lat_deg.abs() > 90.0 || self.origin.lon_deg.abs() > 180.0 {
            return Err("origin: latitude/longitude out of range".into());
        }
        for (i, s) in self.sphere.iter().enumerate() {
            if s.radius_m.is_nan()
                || s.radius_m <= 0.0
                || !s.lat_deg.is_finite()
                || !s.lon_deg.is_finite()
                || !s.h_m.is_finite()
            {
                return Err(format!(
                    "sphere[{i}] ({}): radius must be > 0 and the centre finite",
                    s.id
                ));
            }
        }
        if self.apriori.window_margin_m.is_nan() || self.apriori.window_margin_m <= 0.0 {
            return Err("apriori.window_margin_m: must be > 0".into());
        }
        Ok(())
    }

    /// The a-priori values as [roll, pitch, heading (deg), x, y, z (m)].
    pub fn apriori_deg_m(&self) -> [f64; 6] {
        deg_m(self.apriori.boresight_deg, self.apriori.lever_arm_m)
    }

    /// As TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }
}

/// Boresight [deg] and lever arm [m] as the solver's six parameters: roll, pitch, heading, x,
/// y, z.
pub fn deg_m(boresight_deg: [f64; 3], lever_arm_m: [f64; 3]) -> [f64; 6] {
    let (b, l) = (boresight_deg, lever_arm_m);
    [b[0], b[1], b[2], l[0], l[1], l[2]]
}

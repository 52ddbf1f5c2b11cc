//! Surveyed coordinates in any EPSG coordinate reference system, to and from WGS84.
//!
//! The EPSG code's PROJ.4 definition and WKT come from `crs-definitions`; `proj4rs` (pure
//! Rust) projects and shifts datums (`+towgs84` Helmert parameters where the definition has
//! them; no grid files). Conventions (docs/DESIGN.md "Site coordinates"):
//! - a projected CRS takes easting, northing in its own unit; a geographic one takes
//!   longitude, latitude in degrees (x east, y north, whatever the EPSG axis order);
//! - heights are metres: ellipsoidal on the CRS's datum, or orthometric with a geoid
//!   undulation N above that datum's ellipsoid (h = H + N);
//! - the result is WGS84 latitude, longitude [deg] and ellipsoidal height [m].

use proj4rs::Proj;
use serde::{Deserialize, Serialize};

/// A CRS by EPSG code, ready to transform.
pub struct Crs {
    /// The EPSG code.
    pub code: u16,
    /// Its OGC WKT (for the LAS CRS record and the report).
    pub wkt: &'static str,
    /// Its PROJ.4 definition.
    pub proj4: &'static str,
    proj: Proj,
    wgs84: Proj,
}

impl std::fmt::Debug for Crs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "EPSG:{} ({})", self.code, self.proj4)
    }
}

/// WGS84 geographic, 3D (the GNSS/INS's frame).
const WGS84: &str = "+proj=longlat +datum=WGS84 +no_defs";

impl Crs {
    /// `EPSG:n` (or `n`).
    pub fn parse(s: &str) -> Result<Self, String> {
        let t = s.trim();
        let digits = t
            .strip_prefix("EPSG:")
            .or_else(|| t.strip_prefix("epsg:"))
            .unwrap_or(t);
        let code: u16 = digits
            .parse()
            .map_err(|_| format!("CRS {s:?}: expected EPSG:<code>, e.g. EPSG:32630"))?;
        Self::epsg(code)
    }

    /// The CRS with EPSG code `code`.
    pub fn epsg(code: u16) -> Result<Self, String> {
        let def = crs_definitions::from_code(code)
            .ok_or_else(|| format!("EPSG:{code}: not a CRS this build knows"))?;
        let proj = Proj::from_proj_string(def.proj4)
            .map_err(|e| format!("EPSG:{code} ({}): {e}", def.proj4))?;
        if proj.is_geocent() {
            return Err(format!(
                "EPSG:{code}: a geocentric CRS; give a geographic or projected one"
            ));
        }
        let wgs84 = Proj::from_proj_string(WGS84).map_err(|e| format!("WGS84: {e}"))?;
        Ok(Self {
            code,
            wkt: def.wkt,
            proj4: def.proj4,
            proj,
            wgs84,
        })
    }

    /// Longitude, latitude in degrees (else easting, northing).
    pub fn is_geographic(&self) -> bool {
        self.proj.is_latlong()
    }

    /// (x, y) in this CRS and an ellipsoidal height on its datum -> WGS84 latitude, longitude
    /// [deg] and ellipsoidal height [m].
    pub fn to_wgs84(&self, x: f64, y: f64, h: f64) -> Result<(f64, f64, f64), String> {
        if ![x, y, h].iter().all(|v| v.is_finite()) {
            return Err(format!("EPSG:{}: ({x}, {y}, {h}) is not finite", self.code));
        }
        let mut p = if self.is_geographic() {
            (x.to_radians(), y.to_radians(), h)
        } else {
            (x, y, h)
        };
        proj4rs::transform::transform(&self.proj, &self.wgs84, &mut p)
            .map_err(|e| format!("EPSG:{}: ({x}, {y}, {h}): {e}", self.code))?;
        let (lon, lat, h) = (p.0.to_degrees(), p.1.to_degrees(), p.2);
        if !(lat.is_finite() && lon.is_finite() && h.is_finite()) || lat.abs() > 90.0 {
            return Err(format!(
                "EPSG:{}: ({x}, {y}) is outside the projection's domain",
                self.code
            ));
        }
        Ok((lat, lon, h))
    }

    /// WGS84 latitude, longitude [deg], ellipsoidal height [m] -> (x, y) in this CRS and the
    /// ellipsoidal height on its datum.
    pub fn from_wgs84(&self, lat: f64, lon: f64, h: f64) -> Result<(f64, f64, f64), String> {
        let mut p = (lon.to_radians(), lat.to_radians(), h);
        proj4rs::transform::transform(&self.wgs84, &self.proj, &mut p)
            .map_err(|e| format!("EPSG:{}: ({lat}, {lon}): {e}", self.code))?;
        Ok(if self.is_geographic() {
            (p.0.to_degrees(), p.1.to_degrees(), p.2)
        } else {
            p
        })
    }
}

/// What a surveyed height is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum HeightSystem {
    /// Above the CRS datum's ellipsoid (what GNSS gives).
    #[default]
    Ellipsoidal,
    /// Above the geoid (levelled heights, a chart datum's land survey): h = H + N.
    Orthometric,
}

impl std::str::FromStr for HeightSystem {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "ellipsoidal" => Ok(Self::Ellipsoidal),
            "orthometric" => Ok(Self::Orthometric),
            _ => Err(format!(
                "height system {s:?}: expected ellipsoidal or orthometric"
            )),
        }
    }
}

/// The `[crs]` section of a site file: the CRS and height system the spheres' `easting`,
/// `northing`, `height_m` are in.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteCrs {
    /// EPSG code of the horizontal CRS.
    pub epsg: u16,
    /// What the heights are.
    #[serde(default)]
    pub height: HeightSystem,
    /// Geoid undulation N above the datum's ellipsoid [m] (orthometric heights; a constant
    /// for a small site).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub geoid_undulation_m: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl SiteCrs {
    /// The ellipsoidal height of a surveyed height.
    pub fn ellipsoidal(&self, height: f64) -> f64 {
        match self.height {
            HeightSystem::Ellipsoidal => height,
            HeightSystem::Orthometric => height + self.geoid_undulation_m,
        }
    }

    /// What is subtracted from an ellipsoidal height to give this system's height (N for
    /// orthometric heights, else 0).
    pub fn undulation(&self) -> f64 {
        self.ellipsoidal(0.0)
    }

    /// A surveyed point (x, y, height) -> WGS84 latitude, longitude [deg], ellipsoidal
    /// height [m].
    pub fn to_wgs84(
        &self,
        crs: &Crs,
        x: f64,
        y: f64,
        height: f64,
    ) -> Result<(f64, f64, f64), String> {
        crs.to_wgs84(x, y, self.ellipsoidal(height))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// UTM zone 30N's central meridian is 3 deg W, its false easting 500 km: a point on it has
    /// that longitude exactly, whatever the northing; WGS84 to WGS84 leaves heights alone.
    #[test]
    fn utm_central_meridian_by_hand() {
        let c = Crs::parse("EPSG:32630").unwrap();
        assert!(!c.is_geographic());
        let (lat, lon, h) = c.to_wgs84(500_000.0, 5_360_000.0, 10.0).unwrap();
        assert!((lon + 3.0).abs() < 1e-12, "{lon}");
        assert!((h - 10.0).abs() < 1e-9);
        // The equator is at northing 0.
        let (lat0, _, _) = c.to_wgs84(500_000.0, 0.0, 0.0).unwrap();
        assert!(lat0.abs() < 1e-12);
        let (x, y, _) = c.from_wgs84(lat, lon, h).unwrap();
        assert!((x - 500_000.0).abs() < 1e-6 && (y - 5_360_000.0).abs() < 1e-6);
    }

    #[test]
    fn geographic_takes_degrees_and_bad_codes_are_named() {
        let c = Crs::parse("4326").unwrap();
        assert!(c.is_geographic());
        let (lat, lon, _) = c.to_wgs84(-4.49, 48.38, 0.0).unwrap();
        assert!((lat - 48.38).abs() < 1e-12 && (lon + 4.49).abs() < 1e-12);
        assert!(Crs::parse("EPSG:1").unwrap_err().contains("EPSG:1"));
        assert!(Crs::parse("UTM30").unwrap_err().contains("EPSG:<code>"));
        assert!(Crs::parse("EPSG:4978").unwrap_err().contains("geocentric"));
        assert!(c.to_wgs84(f64::NAN, 0.0, 0.0).is_err());
    }

    #[test]
    fn orthometric_heights_add_the_undulation() {
        let s = SiteCrs {
            epsg: 32630,
            height: HeightSystem::Orthometric,
            geoid_undulation_m: 51.25,
        };
        assert_eq!(s.ellipsoidal(3.5), 54.75);
        let e = SiteCrs {
            height: HeightSystem::Ellipsoidal,
            ..s
        };
        assert_eq!(e.ellipsoidal(3.5), 3.5);
    }
}

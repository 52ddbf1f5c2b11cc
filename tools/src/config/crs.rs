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
    /// Geographic coordinates on the CRS's own datum (its ellipsoid and `+towgs84`).
    geog: Proj,
}

impl std::fmt::Debug for Crs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "EPSG:{} ({})", self.code, self.proj4)
    }
}

/// WGS84 geographic, 3D (the GNSS/INS's frame).
const WGS84: &str = "+proj=longlat +datum=WGS84 +no_defs";

/// The unit heights are given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum HeightUnit {
    /// Metres.
    #[default]
    #[serde(rename = "m")]
    Metre,
    /// The US survey foot (1200/3937 m: US State Plane CRSs in feet, e.g. EPSG:2248).
    #[serde(rename = "us-ft")]
    UsFoot,
    /// The international foot (0.3048 m).
    #[serde(rename = "ft")]
    Foot,
}

impl HeightUnit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            HeightUnit::Metre => 1.0,
            HeightUnit::UsFoot => 1200.0 / 3937.0,
            HeightUnit::Foot => 0.3048,
        }
    }

    /// Its name as `--height-unit` takes it.
    pub fn key(self) -> &'static str {
        match self {
            HeightUnit::Metre => "m",
            HeightUnit::UsFoot => "us-ft",
            HeightUnit::Foot => "ft",
        }
    }

    /// A unit from its spelling in an option or a CSV header (`m`, `metre(s)`, `meter(s)`,
    /// `us-ft`, `usft`, `sft`, `ftus`, `us survey foot`, `ft`, `feet`, `foot`, `intl ft`).
    pub fn parse(s: &str) -> Option<Self> {
        let w: String = s
            .trim()
            .to_ascii_lowercase()
            .chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .collect();
        Some(match w.as_str() {
            "m" | "metre" | "metres" | "meter" | "meters" => HeightUnit::Metre,
            "usft" | "sft" | "ftus" | "ussurveyfoot" | "ussurveyfeet" | "surveyfoot"
            | "surveyfeet" => HeightUnit::UsFoot,
            "ft" | "feet" | "foot" | "intlft" | "ift" | "internationalfoot" => HeightUnit::Foot,
            _ => return None,
        })
    }
}

impl std::str::FromStr for HeightUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::parse(s).ok_or_else(|| format!("{s:?}: expected m, us-ft or ft"))
    }
}

impl Crs {
    /// The unit of its projected coordinates, from its definition (`+units=`, `+to_meter=`):
    /// metres for a geographic CRS and when it says none.
    pub fn linear_unit(&self) -> HeightUnit {
        for t in self.proj4.split_whitespace() {
            match t {
                "+units=us-ft" => return HeightUnit::UsFoot,
                "+units=ft" => return HeightUnit::Foot,
                _ => {}
            }
            if let Some(v) = t
                .strip_prefix("+to_meter=")
                .and_then(|v| v.parse::<f64>().ok())
            {
                if (v - HeightUnit::UsFoot.metres()).abs() < 1e-9 {
                    return HeightUnit::UsFoot;
                }
                if (v - 0.3048).abs() < 1e-9 {
                    return HeightUnit::Foot;
                }
            }
        }
        HeightUnit::Metre
    }

    /// `EPSG:n` (or `n`).
    pub fn parse(s: &str) -> Result<Self, crate::Error> {
        let t = s.trim();
        let digits = t
            .strip_prefix("EPSG:")
            .or_else(|| t.strip_prefix("epsg:"))
            .unwrap_or(t);
        let code: u32 = digits.parse().map_err(|_| {
            format!("CRS {s:?}: expected EPSG:<code> (digits), e.g. EPSG:32630 or EPSG:2949")
        })?;
        let code = u16::try_from(code).map_err(|_| {
            format!("EPSG:{code}: not a CRS this build knows (no EPSG CRS code is that large)")
        })?;
        Self::epsg(code)
    }

    /// What a code that is not a horizontal CRS is: a compound (horizontal + vertical) or a
    /// vertical CRS, said with the parts to give instead.
    pub fn not_horizontal(code: u16) -> Option<String> {
        use super::epsg_tables::{COMPOUND, VERTICAL};
        if let Ok(i) = COMPOUND.binary_search_by_key(&code, |c| c.0) {
            let (_, name, h, v) = COMPOUND[i];
            return Some(format!(
                "EPSG:{code} ({name}) is a compound CRS: give its horizontal part and its heights separately, --crs EPSG:{h} --vertical-crs EPSG:{v} (with --height orthometric and the geoid)"
            ));
        }
        VERTICAL.binary_search_by_key(&code, |v| v.0).ok().map(|_| {
            format!(
                "EPSG:{code} is a vertical CRS (heights only): give the horizontal CRS as --crs and this one as --vertical-crs EPSG:{code}"
            )
        })
    }

    /// The CRS with EPSG code `code`.
    pub fn epsg(code: u16) -> Result<Self, crate::Error> {
        if let Some(why) = Self::not_horizontal(code) {
            return Err(why.into());
        }
        let def = crs_definitions::from_code(code).ok_or_else(|| {
            format!("EPSG:{code}: not a CRS this build knows (a geographic or projected CRS of the EPSG dataset)")
        })?;
        let proj = Proj::from_proj_string(def.proj4)
            .map_err(|e| format!("EPSG:{code} ({}): {e}", def.proj4))?;
        if proj.is_geocent() {
            return Err(format!(
                "EPSG:{code}: a geocentric CRS; give a geographic or projected one"
            )
            .into());
        }
        let wgs84 = Proj::from_proj_string(WGS84).map_err(|e| format!("WGS84: {e}"))?;
        // The same datum, as longitude and latitude: the CRS's datum parameters, nothing else.
        let keep: Vec<&str> = def
            .proj4
            .split_whitespace()
            .filter(|t| {
                [
                    "+ellps=",
                    "+datum=",
                    "+towgs84=",
                    "+a=",
                    "+b=",
                    "+rf=",
                    "+f=",
                    "+nadgrids=",
                ]
                .iter()
                .any(|p| t.starts_with(p))
            })
            .collect();
        let geog_def = format!("+proj=longlat {} +no_defs", keep.join(" "));
        let geog = Proj::from_proj_string(&geog_def)
            .map_err(|e| format!("EPSG:{code} ({geog_def}): {e}"))?;
        Ok(Self {
            code,
            wkt: def.wkt,
            proj4: def.proj4,
            proj,
            wgs84,
            geog,
        })
    }

    /// (x, y) in this CRS -> latitude, longitude [deg] on its own datum (no datum shift); `h`
    /// passes through.
    pub fn to_geographic(&self, x: f64, y: f64, h: f64) -> Result<(f64, f64, f64), crate::Error> {
        if ![x, y, h].iter().all(|v| v.is_finite()) {
            return Err(format!("EPSG:{}: ({x}, {y}, {h}) is not finite", self.code).into());
        }
        if self.is_geographic() {
            return if y.abs() <= 90.0 && x.abs() <= 360.0 {
                Ok((y, x, h))
            } else {
                Err(format!(
                    "EPSG:{}: ({x}, {y}) is not a longitude, latitude",
                    self.code
                )
                .into())
            };
        }
        let mut p = (x, y, 0.0);
        proj4rs::transform::transform(&self.proj, &self.geog, &mut p)
            .map_err(|e| format!("EPSG:{}: ({x}, {y}): {e}", self.code))?;
        let (lon, lat) = (p.0.to_degrees(), p.1.to_degrees());
        if !(lat.is_finite() && lon.is_finite()) || lat.abs() > 90.0 {
            return Err(format!(
                "EPSG:{}: ({x}, {y}) is outside the projection's domain",
                self.code
            )
            .into());
        }
        Ok((lat, lon, h))
    }

    /// Latitude, longitude [deg] on this CRS's datum -> (x, y) in it; `h` passes through.
    pub fn from_geographic(
        &self,
        lat: f64,
        lon: f64,
        h: f64,
    ) -> Result<(f64, f64, f64), crate::Error> {
        if self.is_geographic() {
            return Ok((lon, lat, h));
        }
        let mut p = (lon.to_radians(), lat.to_radians(), 0.0);
        proj4rs::transform::transform(&self.geog, &self.proj, &mut p)
            .map_err(|e| format!("EPSG:{}: ({lat}, {lon}): {e}", self.code))?;
        Ok((p.0, p.1, h))
    }

    /// Longitude, latitude in degrees (else easting, northing).
    pub fn is_geographic(&self) -> bool {
        self.proj.is_latlong()
    }

    /// (x, y) in this CRS and an ellipsoidal height on its datum -> WGS84 latitude, longitude
    /// [deg] and ellipsoidal height [m].
    pub fn to_wgs84(&self, x: f64, y: f64, h: f64) -> Result<(f64, f64, f64), crate::Error> {
        if ![x, y, h].iter().all(|v| v.is_finite()) {
            return Err(format!("EPSG:{}: ({x}, {y}, {h}) is not finite", self.code).into());
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
            )
            .into());
        }
        Ok((lat, lon, h))
    }

    /// WGS84 latitude, longitude [deg], ellipsoidal height [m] -> (x, y) in this CRS and the
    /// ellipsoidal height on its datum.
    pub fn from_wgs84(&self, lat: f64, lon: f64, h: f64) -> Result<(f64, f64, f64), crate::Error> {
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteCrs {
    /// EPSG code of the horizontal CRS.
    pub epsg: u16,
    /// What the heights are.
    #[serde(default)]
    pub height: HeightSystem,
    /// Geoid undulation N above the datum's ellipsoid [m] for orthometric heights, one for the
    /// whole site ...
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geoid_undulation_m: Option<f64>,
    /// ... or a geoid grid (GTX, on the CRS's datum), its path relative to the site file's
    /// folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geoid_grid: Option<String>,
    /// The EPSG code of the orthometric heights' vertical CRS (e.g. 6647, CGVD2013(CGG2013)
    /// height): the LAS file's compound CRS names it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vertical_epsg: Option<u16>,
    /// The unit the survey gave its heights in (the site's `height_m` are in metres,
    /// converted at import).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_unit: Option<HeightUnit>,
}

/// How a site's heights become ellipsoidal: h = H + N.
#[derive(Debug, Clone, PartialEq)]
pub enum Undulation {
    /// Ellipsoidal heights: N = 0.
    None,
    /// One N for the site [m].
    Constant(f64),
    /// N from a geoid grid.
    Grid(Box<super::geoid::Geoid>),
}

impl Undulation {
    /// N at latitude, longitude [deg] on the CRS's datum.
    pub fn at(&self, lat: f64, lon: f64) -> Result<f64, crate::Error> {
        match self {
            Undulation::None => Ok(0.0),
            Undulation::Constant(n) => Ok(*n),
            Undulation::Grid(g) => g.undulation(lat, lon).ok_or_else(|| {
                format!(
                    "({lat:.6}, {lon:.6}) is outside the geoid grid {} (or beside its holes)",
                    g.path.display()
                )
                .into()
            }),
        }
    }
}

impl SiteCrs {
    /// The heights' undulation, the grid read from `base` (the site file's folder); refused:
    /// orthometric heights without a geoid, a geoid with ellipsoidal heights, both N and a grid.
    pub fn undulation(&self, base: &std::path::Path) -> Result<Undulation, crate::Error> {
        match (self.height, self.geoid_undulation_m, &self.geoid_grid) {
            (HeightSystem::Ellipsoidal, None, None) => Ok(Undulation::None),
            (HeightSystem::Ellipsoidal, _, _) => Err(
                "crs: a geoid (geoid_undulation_m, geoid_grid) goes with height = \"orthometric\"; ellipsoidal heights need none".into(),
            ),
            (HeightSystem::Orthometric, Some(n), None) => {
                if n.is_finite() && n.abs() <= 150.0 {
                    Ok(Undulation::Constant(n))
                } else {
                    Err("crs.geoid_undulation_m: expected a finite N, |N| <= 150 m".into())
                }
            }
            (HeightSystem::Orthometric, None, Some(g)) => {
                let path = base.join(g);
                super::geoid::Geoid::load(&path)
                    .map(|g| Undulation::Grid(Box::new(g)))
                    .map_err(|e| format!("crs.geoid_grid: {e}").into())
            }
            (HeightSystem::Orthometric, Some(_), Some(_)) => {
                Err("crs: give geoid_undulation_m or geoid_grid, not both".into())
            }
            (HeightSystem::Orthometric, None, None) => Err(
                "crs: orthometric heights need the geoid: geoid_undulation_m (N [m] for the site) or geoid_grid (a GTX file); N = 0 is never assumed".into(),
            ),
        }
    }

    /// A surveyed point (x, y, height) -> latitude, longitude [deg] and ellipsoidal height [m]
    /// on the CRS's own datum.
    pub fn to_geographic(
        &self,
        crs: &Crs,
        n: &Undulation,
        x: f64,
        y: f64,
        height: f64,
    ) -> Result<(f64, f64, f64), crate::Error> {
        let (lat, lon, _) = crs.to_geographic(x, y, 0.0)?;
        Ok((lat, lon, height + n.at(lat, lon)?))
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
        assert!(Crs::parse("EPSG:1")
            .unwrap_err()
            .to_string()
            .contains("EPSG:1"));
        assert!(Crs::parse("UTM30")
            .unwrap_err()
            .to_string()
            .contains("EPSG:<code>"));
        assert!(Crs::parse("EPSG:4978")
            .unwrap_err()
            .to_string()
            .contains("geocentric"));
        assert!(c.to_wgs84(f64::NAN, 0.0, 0.0).is_err());
    }

    /// h = H + N with one N, none with ellipsoidal heights, refused without a geoid
    /// (never N = 0) or with both N and a grid; a point on UTM 30N's central meridian.
    #[test]
    fn orthometric_heights_add_the_undulation() {
        let s = SiteCrs {
            epsg: 32630,
            height: HeightSystem::Orthometric,
            geoid_undulation_m: Some(51.25),
            geoid_grid: None,
            vertical_epsg: None,
            height_unit: None,
        };
        let here = std::path::Path::new(".");
        let n = s.undulation(here).unwrap();
        let c = Crs::epsg(32630).unwrap();
        let (_, lon, h) = s
            .to_geographic(&c, &n, 500_000.0, 5_360_000.0, 3.5)
            .unwrap();
        assert!((lon + 3.0).abs() < 1e-12 && h == 54.75);
        let e = SiteCrs {
            height: HeightSystem::Ellipsoidal,
            geoid_undulation_m: None,
            ..s.clone()
        };
        assert_eq!(e.undulation(here).unwrap(), Undulation::None);
        let none = SiteCrs {
            geoid_undulation_m: None,
            ..s.clone()
        };
        assert!(none
            .undulation(here)
            .unwrap_err()
            .to_string()
            .contains("N = 0 is never assumed"));
        let both = SiteCrs {
            geoid_grid: Some("x.gtx".into()),
            ..s.clone()
        };
        assert!(both
            .undulation(here)
            .unwrap_err()
            .to_string()
            .contains("not both"));
        let stray = SiteCrs {
            height: HeightSystem::Ellipsoidal,
            ..s
        };
        assert!(stray.undulation(here).is_err());
    }
}

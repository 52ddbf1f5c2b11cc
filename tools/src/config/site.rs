//! `site.toml`: the surveyed targets and the a-priori mounting (docs/REFERENCE.md "site.toml").

use super::crs::{Crs, SiteCrs};
use serde::{Deserialize, Serialize};
use spherecal::frames::{Geodetic, LocalFrame};
use spherecal::georef::DegM;

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

/// A surveyed sphere: its centre as latitude, longitude, ellipsoidal height on the site's
/// datum, or as surveyed in the site's `[crs]` (easting, northing, height), from which those
/// are computed on loading (given both, they must agree to a millimetre).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteSphere {
    /// Name.
    pub id: String,
    /// Centre latitude [deg] (on the site's datum).
    #[serde(default = "nan", skip_serializing_if = "is_nan")]
    pub lat_deg: f64,
    /// Centre longitude [deg] (on the site's datum).
    #[serde(default = "nan", skip_serializing_if = "is_nan")]
    pub lon_deg: f64,
    /// Centre ellipsoidal height [m] (on the site's datum's ellipsoid).
    #[serde(default = "nan", skip_serializing_if = "is_nan")]
    pub h_m: f64,
    /// Easting in the site's CRS (longitude [deg] for a geographic one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub easting: Option<f64>,
    /// Northing in the site's CRS (latitude [deg] for a geographic one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub northing: Option<f64>,
    /// Height in the site's height system [m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_m: Option<f64>,
    /// Radius [m].
    pub radius_m: f64,
    /// The surveyed centre's 1 sigma [m] (optional): under a navigation model
    /// (`[ins.correlated]`) the centre is a parameter with this prior (default
    /// [`DEFAULT_CENTRE_SIGMA_M`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_m: Option<f64>,
}

/// A surveyed centre's 1 sigma when the site gives none [m]: an RTK survey of a sphere's
/// centre (1-2 cm).
pub const DEFAULT_CENTRE_SIGMA_M: f64 = 0.02;

/// What the INS delivers, as the scenario's `[ins]` says it (optional).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteIns {
    /// Its errors that wander: `[ins.correlated]` (a preset and/or the sigmas and correlation
    /// time; see `spherecal synth --print-scenario`).
    #[serde(default)]
    pub correlated: super::nav_errors::CorrelatedSpec,
}

fn nan() -> f64 {
    f64::NAN
}

fn is_nan(v: &f64) -> bool {
    v.is_nan()
}

impl SiteSphere {
    /// A sphere at WGS84 `lat`, `lon` [deg], ellipsoidal height `h` [m].
    pub fn wgs84(id: &str, lat: f64, lon: f64, h: f64, radius_m: f64) -> Self {
        Self {
            id: id.into(),
            lat_deg: lat,
            lon_deg: lon,
            h_m: h,
            easting: None,
            northing: None,
            height_m: None,
            radius_m,
            sigma_m: None,
        }
    }
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
    /// The boresight's 1-sigma as measured (roll, pitch, heading [deg]), when the mounting's
    /// angles are known: a prior the calibration weighs with the data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub boresight_sigma_deg: Option<[f64; 3]>,
    /// The lever arm's 1-sigma as measured (x, y, z [m]; a total-station survey of the
    /// vessel to a few millimetres): a prior the calibration weighs with the data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lever_arm_sigma_m: Option<[f64; 3]>,
}

impl SiteApriori {
    /// The prior on the mounting the sigmas give (none without them): roll, pitch, heading
    /// [rad], x, y, z [m].
    pub fn prior(&self) -> spherecal::calib::nav::MountPrior {
        let b = self.mount().deg_m().params().0;
        let [r, p, h] = self
            .boresight_sigma_deg
            .map_or([0.0; 3], |s| s.map(f64::to_radians));
        let [x, y, z] = self.lever_arm_sigma_m.unwrap_or([0.0; 3]);
        spherecal::calib::nav::MountPrior::of(&b, &[r, p, h, x, y, z])
    }

    /// The a-priori mounting.
    pub fn mount(&self) -> super::MountDegM {
        super::MountDegM {
            boresight_deg: self.boresight_deg,
            lever_arm_m: self.lever_arm_m,
        }
    }
}

/// The sensors' noise, 1 sigma, for the consistency test (optional; the defaults are the
/// VLP-16's specified range accuracy and a navigation-grade INS).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteNoise {
    /// LiDAR range [m] (VLP-16 user manual: +-3 cm typical).
    pub range_m: f64,
    /// INS roll, pitch, heading [deg].
    pub attitude_deg: f64,
    /// INS position [m].
    pub position_m: f64,
}

impl Default for SiteNoise {
    fn default() -> Self {
        let s = spherecal::calib::Settings::default();
        Self {
            range_m: s.range_noise,
            attitude_deg: s.attitude_noise.to_degrees(),
            position_m: s.position_noise,
        }
    }
}

/// The whole file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Site {
    /// GPS - UTC [s].
    pub leap_seconds: i64,
    /// The geodetic datum of `origin` and the spheres' latitude, longitude and height: a name
    /// (`WGS84`, `NAD83(CSRS)`, `ETRS89`, `ITRF2014`, ...), `EPSG:<CRS>` or `datum:<code>`
    /// (default WGS 84; with `[crs]`, its CRS's datum).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub datum: Option<String>,
    /// The datum, resolved on loading.
    #[serde(skip)]
    pub geodetic: Option<super::datum::Datum>,
    /// The folder of the site file (a geoid grid's path is relative to it).
    #[serde(skip)]
    pub base: std::path::PathBuf,
    /// The CRS and height system of the spheres' surveyed coordinates (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crs: Option<SiteCrs>,
    /// Local NED origin.
    pub origin: Origin,
    /// Spheres.
    pub sphere: Vec<SiteSphere>,
    /// A-priori values.
    pub apriori: SiteApriori,
    /// The sensors' noise (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<SiteNoise>,
    /// The LiDAR's beam where its model's manual does not give it, or to say an ideal ray (a
    /// simulated one) (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lidar: Option<super::lidar::SiteLidar>,
    /// What the INS delivers (optional): with `[ins.correlated]` the calibration estimates
    /// the navigation errors with the mounting.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ins: Option<SiteIns>,
    /// The accuracy the calibration must reach (`target_sigma_deg`, `target_sigma_m`; else the
    /// board's, else [`super::goal::DEFAULT_TARGETS`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<super::goal::Targets>,
}

impl Site {
    /// Read and check a site file; errors name the file and the key.
    pub fn load(path: &std::path::Path) -> Result<Self, crate::Error> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut s: Site = toml::from_str(&text)
            .map_err(|e| format!("{}: {}", path.display(), e.to_string().trim()))?;
        s.base = path
            .parent()
            .map(std::path::Path::to_path_buf)
            .unwrap_or_default();
        s.resolve()
            .map_err(|e| format!("{}: {e}", path.display()))?;
        s.check().map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(s)
    }

    /// The datum of its coordinates (WGS 84 unless the file says otherwise).
    pub fn datum(&self) -> super::datum::Datum {
        self.geodetic
            .clone()
            .unwrap_or_else(super::datum::Datum::wgs84)
    }

    /// The site with its origin and spheres in datum `to` (the trajectory's), and the
    /// transformation applied (none when it is the site's own); refused when no transformation
    /// between them is known. The surveyed coordinates stay as they are.
    pub fn in_datum(
        &self,
        to: &super::datum::Datum,
    ) -> Result<(Site, super::datum::DatumShift), crate::Error> {
        let shift = super::datum::DatumShift::between(&self.datum(), to)?;
        let mut s = self.clone();
        let o = &mut s.origin;
        (o.lat_deg, o.lon_deg, o.h_m) = shift.apply(o.lat_deg, o.lon_deg, o.h_m)?;
        for sp in s.sphere.iter_mut() {
            (sp.lat_deg, sp.lon_deg, sp.h_m) = shift
                .apply(sp.lat_deg, sp.lon_deg, sp.h_m)
                .map_err(|e| format!("sphere {}: {e}", sp.id))?;
        }
        s.geodetic = Some(to.clone());
        Ok((s, shift))
    }

    /// Compute each sphere's centre on the datum of `[crs]` from its surveyed coordinates
    /// (checking any latitude, longitude, height also given against them); without `[crs]`,
    /// surveyed coordinates are refused. Resolves the site's datum.
    pub fn resolve(&mut self) -> Result<(), crate::Error> {
        let crs = match &self.crs {
            Some(c) => Some((c, Crs::epsg(c.epsg).map_err(|e| format!("crs.epsg: {e}"))?)),
            None => None,
        };
        let named = match &self.datum {
            Some(d) => Some(super::datum::Datum::parse(d).map_err(|e| format!("datum: {e}"))?),
            None => None,
        };
        self.geodetic = match (&crs, named) {
            (Some((c, _)), named) => {
                let own =
                    super::datum::Datum::of_crs(c.epsg).map_err(|e| format!("crs.epsg: {e}"))?;
                if let Some(n) = named.filter(|n| n.code != own.code) {
                    return Err(format!(
                        "datum: {} is not the datum of crs.epsg = {} ({}): leave it out or give the CRS of that datum",
                        n.label(),
                        c.epsg,
                        own.label()
                    ).into());
                }
                Some(own)
            }
            (None, named) => named,
        };
        let undulation = match &crs {
            Some((c, _)) => c.undulation(&self.base)?,
            None => super::crs::Undulation::None,
        };
        for (i, sp) in self.sphere.iter_mut().enumerate() {
            let key = format!("sphere[{i}] ({})", sp.id);
            let surveyed = (sp.easting, sp.northing, sp.height_m);
            let (x, y, z, c, crs) = match (surveyed, &crs) {
                ((None, None, None), _) => continue,
                ((Some(x), Some(y), Some(z)), Some((c, crs))) => (x, y, z, c, crs),
                (_, None) => {
                    return Err(format!(
                        "{key}: easting/northing/height_m need a [crs] section (epsg, height)"
                    )
                    .into())
                }
                _ => return Err(format!("{key}: give all of easting, northing, height_m").into()),
            };
            let (lat, lon, h) = c
                .to_geographic(crs, &undulation, x, y, z)
                .map_err(|e| format!("{key}: {e}"))?;
            if sp.lat_deg.is_finite() || sp.lon_deg.is_finite() || sp.h_m.is_finite() {
                let f = LocalFrame::new(Geodetic::from_deg(lat, lon, h));
                let given = Geodetic::from_deg(sp.lat_deg, sp.lon_deg, sp.h_m);
                let d = f.to_ned(&given).norm();
                if d.is_nan() || d > 1e-3 {
                    return Err(format!(
                        "{key}: lat_deg/lon_deg/h_m are {d:.3} m from easting/northing/height_m in EPSG:{}; give one or the other",
                        c.epsg
                    ).into());
                }
            }
            (sp.lat_deg, sp.lon_deg, sp.h_m) = (lat, lon, h);
        }
        Ok(())
    }

    /// The navigation errors' model `[ins.correlated]` declares (`None`: none declared, or
    /// all zero).
    pub fn nav_model(&self) -> Result<Option<spherecal::calib::nav::NavModel>, crate::Error> {
        let Some(ins) = &self.ins else {
            return Ok(None);
        };
        let c = ins.correlated.resolve("ins.correlated")?;
        Ok(c.is_on().then_some(spherecal::calib::nav::NavModel {
            position_sigma: c.position_sigma,
            attitude_sigma: c.attitude_sigma,
            correlation_s: c.correlation_s,
        }))
    }

    /// Values a calibration can use: every number finite and in its range, named by its key.
    pub fn check(&self) -> Result<(), crate::Error> {
        self.nav_model()?;
        if let Some(t) = &self.calibration {
            t.check("calibration")?;
        }
        for (k, v) in [
            (
                "apriori.boresight_sigma_deg",
                self.apriori.boresight_sigma_deg,
            ),
            ("apriori.lever_arm_sigma_m", self.apriori.lever_arm_sigma_m),
        ] {
            if v.is_some_and(|v| v.iter().any(|s| !(s.is_finite() && *s > 0.0))) {
                return Err(format!("{k}: expected three positive, finite sigmas").into());
            }
        }
        let fin = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let need = |ok: bool, key: String, why: &str| {
            if ok {
                Ok(())
            } else {
                Err(format!("{key}: {why}"))
            }
        };
        let o = &self.origin;
        need(
            fin(&[o.lat_deg]) && o.lat_deg.abs() <= 90.0,
            "origin.lat_deg".into(),
            "expected a finite latitude -90..=90",
        )?;
        need(
            fin(&[o.lon_deg]) && o.lon_deg.abs() <= 180.0,
            "origin.lon_deg".into(),
            "expected a finite longitude -180..=180",
        )?;
        need(
            fin(&[o.h_m]) && o.h_m.abs() < 1e4,
            "origin.h_m".into(),
            "expected a finite height under 10 km",
        )?;
        need(
            (0..=100).contains(&self.leap_seconds),
            "leap_seconds".into(),
            "expected 0..=100",
        )?;
        for (i, s) in self.sphere.iter().enumerate() {
            let key = format!("sphere[{i}] ({})", s.id);
            need(
                !s.id.trim().is_empty(),
                format!("sphere[{i}].id"),
                "expected a name (reports and the rig name spheres by it)",
            )?;
            if let Some(sg) = s.sigma_m {
                need(
                    sg.is_finite() && sg > 0.0 && sg < 10.0,
                    format!("{key}.sigma_m"),
                    "expected a centre sigma 0 < s < 10 m",
                )?;
            }
            if let Some(k) = self.sphere[..i].iter().position(|o| o.id == s.id) {
                return Err(format!(
                    "sphere[{i}].id: {:?} is also sphere[{k}]'s: every sphere needs its own id",
                    s.id
                )
                .into());
            }
            need(
                s.radius_m.is_finite() && s.radius_m > 0.0 && s.radius_m < 5.0,
                format!("{key}.radius_m"),
                "expected a finite radius 0 < r < 5 m",
            )?;
            need(
                fin(&[s.lat_deg, s.lon_deg, s.h_m])
                    && s.lat_deg.abs() <= 90.0
                    && s.lon_deg.abs() <= 180.0,
                key.clone(),
                "expected a finite centre (lat_deg, lon_deg in range, h_m; or easting, northing, height_m with [crs])",
            )?;
        }
        let a = &self.apriori;
        need(
            fin(&a.boresight_deg),
            "apriori.boresight_deg".into(),
            "expected finite angles",
        )?;
        need(
            fin(&a.lever_arm_m) && a.lever_arm_m.iter().all(|x| x.abs() < 50.0),
            "apriori.lever_arm_m".into(),
            "expected finite offsets under 50 m",
        )?;
        need(
            a.window_margin_m.is_finite() && a.window_margin_m > 0.0 && a.window_margin_m < 20.0,
            "apriori.window_margin_m".into(),
            "expected 0 < m < 20",
        )?;
        if let Some(n) = &self.noise {
            for (key, v, hi) in [
                ("noise.range_m", n.range_m, 1.0),
                ("noise.attitude_deg", n.attitude_deg, 5.0),
                ("noise.position_m", n.position_m, 10.0),
            ] {
                need(
                    v.is_finite() && v > 0.0 && v < hi,
                    key.into(),
                    &format!("expected a finite sigma 0 < s < {hi}"),
                )?;
            }
        }
        if let Some(l) = &self.lidar {
            need(
                l.valid(),
                "lidar.beam_divergence_mrad".into(),
                "expected two full angles 0 <= mrad < 20, both zero (an ideal ray) or both positive",
            )?;
        }
        Ok(())
    }

    /// The a-priori values.
    pub fn apriori_deg_m(&self) -> DegM {
        self.apriori.mount().deg_m()
    }

    /// As TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "leap_seconds = 18\n[origin]\nlat_deg = 48.38\nlon_deg = -4.49\nh_m = 52.0\n[[sphere]]\nid = \"S1\"\nlat_deg = 48.38\nlon_deg = -4.49\nh_m = 53.6\nradius_m = 0.19\n[apriori]\nboresight_deg = [181.787, -42.423, 2.431]\nlever_arm_m = [1.312, -1.205, -1.759]\nwindow_margin_m = 3.0\n";

    /// TOML reads `inf` and `nan`: every non-finite value is refused with its key.
    #[test]
    fn non_finite_values_are_refused_by_name() {
        let s: Site = toml::from_str(GOOD).unwrap();
        assert_eq!(s.check(), Ok(()));
        for (from, to, key) in [
            (
                "radius_m = 0.19",
                "radius_m = inf",
                "sphere[0] (S1).radius_m",
            ),
            (
                "radius_m = 0.19",
                "radius_m = nan",
                "sphere[0] (S1).radius_m",
            ),
            ("h_m = 53.6", "h_m = -inf", "sphere[0] (S1)"),
            (
                "[181.787, -42.423, 2.431]",
                "[nan, -42.423, 2.431]",
                "apriori.boresight_deg",
            ),
            (
                "[1.312, -1.205, -1.759]",
                "[1.312, inf, -1.759]",
                "apriori.lever_arm_m",
            ),
            (
                "window_margin_m = 3.0",
                "window_margin_m = inf",
                "apriori.window_margin_m",
            ),
            ("h_m = 52.0", "h_m = nan", "origin.h_m"),
            (
                "lat_deg = 48.38\nlon_deg = -4.49\nh_m = 52.0",
                "lat_deg = nan\nlon_deg = -4.49\nh_m = 52.0",
                "origin.lat_deg",
            ),
        ] {
            let s: Site = toml::from_str(&GOOD.replacen(from, to, 1)).unwrap();
            let e = s.check().unwrap_err().to_string();
            assert!(e.starts_with(&format!("{key}: ")), "{to}: {e}");
        }
    }

    /// The LiDAR's beam: a Velodyne's divergence is read; an ideal ray (zeros) is none; a
    /// non-finite, negative, one-sided or implausibly wide beam is refused by its key.
    #[test]
    fn the_lidar_beam_is_read_and_bad_ones_refused() {
        let with = |v: &str| -> Site {
            toml::from_str(&format!("{GOOD}[lidar]\nbeam_divergence_mrad = {v}\n")).unwrap()
        };
        let s = with("[3.0, 1.5]");
        assert_eq!(s.check(), Ok(()));
        let fp = s.lidar.unwrap().footprint().unwrap();
        assert!((fp.sigma[0] - 0.75e-3).abs() < 1e-12 && (fp.sigma[1] - 0.375e-3).abs() < 1e-12);
        let s = with("[0.0, 0.0]");
        assert_eq!(s.check(), Ok(()));
        assert_eq!(s.lidar.unwrap().footprint(), None);
        for bad in [
            "[nan, 1.5]",
            "[3.0, inf]",
            "[-3.0, 1.5]",
            "[3.0, 0.0]",
            "[30.0, 1.5]",
        ] {
            let e = with(bad).check().unwrap_err().to_string();
            assert!(e.starts_with("lidar.beam_divergence_mrad: "), "{bad}: {e}");
        }
    }

    /// Every sphere needs its own, non-empty id.
    #[test]
    fn duplicate_and_empty_ids_are_refused() {
        let second = "[[sphere]]\nid = \"S2\"\nlat_deg = 48.3801\nlon_deg = -4.49\nh_m = 53.6\nradius_m = 0.19\n[apriori]";
        let two = GOOD.replacen("[apriori]", second, 1);
        let s: Site = toml::from_str(&two).unwrap();
        assert_eq!(s.check(), Ok(()));
        let s: Site = toml::from_str(&two.replacen("id = \"S2\"", "id = \"S1\"", 1)).unwrap();
        let e = s.check().unwrap_err().to_string();
        assert!(
            e.starts_with("sphere[1].id: \"S1\" is also sphere[0]'s"),
            "{e}"
        );
        let s: Site = toml::from_str(&two.replacen("id = \"S2\"", "id = \" \"", 1)).unwrap();
        assert!(s
            .check()
            .unwrap_err()
            .to_string()
            .starts_with("sphere[1].id: expected a name"));
    }

    /// Surveyed coordinates: computed into WGS84, refused without `[crs]`, incomplete, or
    /// contradicting WGS84 values given beside them.
    #[test]
    fn surveyed_centres_resolve_or_are_refused() {
        let base = GOOD.replace(
            "lat_deg = 48.38\nlon_deg = -4.49\nh_m = 53.6\n",
            "easting = 500000.0\nnorthing = 5360000.0\nheight_m = 3.5\n",
        );
        let crs = "[crs]\nepsg = 32630\nheight = \"orthometric\"\ngeoid_undulation_m = 50.0\n";
        let with_crs = base.replacen("[origin]", &format!("{crs}[origin]"), 1);
        let mut s: Site = toml::from_str(&with_crs).unwrap();
        s.resolve().unwrap();
        s.check().unwrap();
        assert!((s.sphere[0].lon_deg + 3.0).abs() < 1e-12);
        assert!((s.sphere[0].h_m - 53.5).abs() < 1e-9);
        // Written out with both: they agree, so it reads back.
        let mut back: Site = toml::from_str(&s.to_toml()).unwrap();
        back.resolve().unwrap();
        assert_eq!(back, s);
        // A WGS84 height 1 cm off the surveyed one is refused.
        let mut off = s.clone();
        off.sphere[0].h_m += 0.01;
        let e = off.resolve().unwrap_err().to_string();
        assert!(e.contains("sphere[0] (S1)") && e.contains("0.010 m"), "{e}");
        let mut no_crs: Site = toml::from_str(&base).unwrap();
        assert!(no_crs
            .resolve()
            .unwrap_err()
            .to_string()
            .contains("need a [crs] section"));
        let partial = with_crs.replace("height_m = 3.5\n", "");
        let mut p: Site = toml::from_str(&partial).unwrap();
        assert!(p.resolve().unwrap_err().to_string().contains("give all of"));
        let bad = with_crs.replace("epsg = 32630", "epsg = 1");
        let mut b: Site = toml::from_str(&bad).unwrap();
        assert!(b
            .resolve()
            .unwrap_err()
            .to_string()
            .starts_with("crs.epsg: EPSG:1"));
    }
}

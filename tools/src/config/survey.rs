//! A surveyor's CSV of sphere centres (`id,easting,northing,height[,radius]` in one EPSG CRS and
//! height system) into a site file: the centres kept as surveyed under `[crs]`, their WGS84
//! values computed beside them, the origin at their mean.

use super::crs::{Crs, SiteCrs};
use super::site::{Origin, Site, SiteApriori, SiteSphere};

/// What the CSV does not say.
#[derive(Debug, Clone)]
pub struct ImportOptions {
    /// CRS and height system of the coordinates.
    pub crs: SiteCrs,
    /// Radius for rows without one [m].
    pub radius_m: Option<f64>,
    /// GPS - UTC [s].
    pub leap_seconds: i64,
    /// The a-priori mounting and window margin.
    pub apriori: SiteApriori,
    /// The folder the site file goes to (a geoid grid's path is relative to it).
    pub base: std::path::PathBuf,
}

/// What a column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Col {
    Id,
    /// Easting, or longitude.
    X,
    /// Northing, or latitude.
    Y,
    Height,
    Radius,
    /// The centre's 1 sigma [m] (optional: the navigation model's prior on it).
    Sigma,
}

/// A header word's column, and whether it names a geographic coordinate.
fn column_of(word: &str) -> Option<(Col, bool)> {
    let w = word.trim().to_ascii_lowercase().replace([' ', '-'], "_");
    Some(match w.as_str() {
        "id" | "name" | "point" | "pt" | "sphere" | "target" => (Col::Id, false),
        "easting" | "east" | "e" | "x" | "easting_m" | "x_m" => (Col::X, false),
        "northing" | "north" | "n" | "y" | "northing_m" | "y_m" => (Col::Y, false),
        "lon" | "long" | "longitude" | "lng" | "lon_deg" => (Col::X, true),
        "lat" | "latitude" | "lat_deg" => (Col::Y, true),
        "height" | "h" | "z" | "elevation" | "elev" | "alt" | "altitude" | "height_m" | "h_m"
        | "ellipsoidal_height" | "orthometric_height" => (Col::Height, false),
        "radius" | "r" | "radius_m" => (Col::Radius, false),
        "sigma" | "sigma_m" | "sd" | "std" | "precision" | "accuracy" => (Col::Sigma, false),
        _ => return None,
    })
}

/// The columns a header names, in order; `None` when the line is not a header (its second
/// field is a number).
fn header(fields: &[&str], geographic: bool, epsg: u16) -> Option<Result<Vec<Col>, crate::Error>> {
    if fields.get(1).is_some_and(|s| s.parse::<f64>().is_ok()) {
        return None;
    }
    let mut cols = Vec::new();
    for f in fields {
        match column_of(f) {
            Some((c, geo)) => {
                if geo && !geographic {
                    return Some(Err(format!(
                        "the header says {f:?} but EPSG:{epsg} is projected (easting, northing): give the geographic CRS of the survey (e.g. EPSG:4326) or its projected coordinates"
                    ).into()));
                }
                if cols.contains(&c) {
                    return Some(Err(format!("the header names {f:?}'s column twice").into()));
                }
                cols.push(c);
            }
            None => {
                return Some(Err(format!(
                "header column {f:?}: expected id, easting/northing (or lon/lat), height, radius, sigma"
            )
                .into()))
            }
        }
    }
    for need in [Col::Id, Col::X, Col::Y, Col::Height] {
        if !cols.contains(&need) {
            return Some(Err(format!(
                "the header has no {} column",
                match need {
                    Col::Id => "id",
                    Col::X => "easting (or longitude)",
                    Col::Y => "northing (or latitude)",
                    _ => "height",
                }
            )
            .into()));
        }
    }
    Some(Ok(cols))
}

/// Spheres farther than this from the others' middle cannot be one calibration site [m].
pub const SITE_EXTENT_M: f64 = 2_000.0;

/// The site for the CSV `text` (read from `name`, for errors as `name:line: why`), resolved
/// and checked, and the columns as read (from its header, or the default order). Refused:
/// a header that names unknown, missing or geographic columns for a projected CRS; a point
/// outside the CRS's area of use (a wrong CRS, swapped columns); a sphere farther than
/// [`SITE_EXTENT_M`] from the others' middle; fewer than two spheres.
pub fn import_csv(
    text: &str,
    name: &str,
    o: &ImportOptions,
) -> Result<(Site, String), crate::Error> {
    let crs = Crs::epsg(o.crs.epsg)?;
    let undulation = o.crs.undulation(&o.base)?;
    let area = super::datum::area_of_use(crs.code);
    let mut spheres: Vec<SiteSphere> = Vec::new();
    let mut lines: Vec<usize> = Vec::new();
    let mut cols: Option<Vec<Col>> = None;
    let word = |c: &Col| match (c, crs.is_geographic()) {
        (Col::Id, _) => "id",
        (Col::X, false) => "easting",
        (Col::Y, false) => "northing",
        (Col::X, true) => "longitude",
        (Col::Y, true) => "latitude",
        (Col::Height, _) => "height",
        (Col::Radius, _) => "radius",
        (Col::Sigma, _) => "sigma",
    };
    for (i, raw) in text.lines().enumerate() {
        let at = |why: String| crate::Error::bad_input(format!("{name}:{}: {why}", i + 1));
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if cols.is_none() {
            match header(&f, crs.is_geographic(), crs.code) {
                Some(Ok(c)) => {
                    cols = Some(c);
                    continue;
                }
                Some(Err(e)) => return Err(at(e.to_string())),
                None => {
                    let mut c = vec![Col::Id, Col::X, Col::Y, Col::Height];
                    if f.len() == 5 {
                        c.push(Col::Radius);
                    }
                    cols = Some(c);
                }
            }
        }
        let c = cols.as_deref().unwrap_or(&[]);
        if f.len() != c.len() {
            let names: Vec<&str> = c.iter().map(word).collect();
            return Err(at(format!(
                "expected {} fields ({}), got {}",
                c.len(),
                names.join(","),
                f.len()
            )));
        }
        let get = |k: Col| c.iter().position(|x| *x == k).map(|p| f[p]);
        let num = |k: Col| -> Result<Option<f64>, crate::Error> {
            match get(k) {
                None => Ok(None),
                Some(s) => s
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .map(Some)
                    .ok_or_else(|| at(format!("{} {s:?} is not a finite number", word(&k)))),
            }
        };
        let id = get(Col::Id).unwrap_or("");
        if id.is_empty() || spheres.iter().any(|s| s.id == id) {
            return Err(at(format!("sphere id {id:?} is empty or repeated")));
        }
        let (x, y, h) = (
            num(Col::X)?.unwrap_or(f64::NAN),
            num(Col::Y)?.unwrap_or(f64::NAN),
            num(Col::Height)?.unwrap_or(f64::NAN),
        );
        let radius_m = match num(Col::Radius)? {
            Some(r) => r,
            None => o
                .radius_m
                .ok_or_else(|| at("no radius column: give --radius".into()))?,
        };
        let (lat, lon, h_ell) = o
            .crs
            .to_geographic(&crs, &undulation, x, y, h)
            .map_err(|e| at(e.to_string()))?;
        if let Some([w, so, e, n]) = area {
            // A little beyond the edge is fine (a quay on a zone's border).
            let tol = 0.5;
            let inside_lon = if w <= e {
                lon >= w - tol && lon <= e + tol
            } else {
                lon >= w - tol || lon <= e + tol
            };
            if !(inside_lon && lat >= so - tol && lat <= n + tol) {
                return Err(at(format!(
                    "sphere {id}: ({:.5}, {:.5}) = lat {lat:.4}, lon {lon:.4} is outside EPSG:{}'s area of use (lon {w} to {e}, lat {so} to {n}): the wrong CRS, or its columns swapped?",
                    x, y, crs.code
                )));
            }
        }
        let sigma_m = num(Col::Sigma)?;
        if sigma_m.is_some_and(|v| !(v > 0.0 && v < 10.0)) {
            return Err(at(format!(
                "sphere {id}: sigma {sigma_m:?} m: expected 0 < s < 10"
            )));
        }
        let mut s = SiteSphere::wgs84(id, lat, lon, h_ell, radius_m);
        (s.easting, s.northing, s.height_m) = (Some(x), Some(y), Some(h));
        s.sigma_m = sigma_m;
        spheres.push(s);
        lines.push(i + 1);
    }
    if spheres.len() < 2 {
        return Err(format!(
            "{name}: {} sphere row(s): a calibration needs at least two spheres (one cannot fix the rotation about the line to it)",
            spheres.len()
        ).into());
    }
    // The middle (median latitude and longitude) and each sphere's distance from it.
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (mlat, mlon) = (
        median(spheres.iter().map(|s| s.lat_deg).collect()),
        median(spheres.iter().map(|s| s.lon_deg).collect()),
    );
    let mid =
        spherecal::frames::LocalFrame::new(spherecal::frames::Geodetic::from_deg(mlat, mlon, 0.0));
    for (s, line) in spheres.iter().zip(&lines) {
        let d = mid.to_ned(&spherecal::frames::Geodetic::from_deg(
            s.lat_deg, s.lon_deg, 0.0,
        ));
        let far = d.x.hypot(d.y);
        if far > SITE_EXTENT_M {
            return Err(format!(
                "{name}:{line}: sphere {} is {:.1} km from the others' middle: more than one calibration site can hold ({} km); a typing error, or the wrong CRS?",
                s.id,
                far / 1e3,
                SITE_EXTENT_M / 1e3
            ).into());
        }
    }
    let n = spheres.len() as f64;
    let mean = |f: fn(&SiteSphere) -> f64| spheres.iter().map(f).sum::<f64>() / n;
    let mut site = Site {
        leap_seconds: o.leap_seconds,
        datum: None,
        geodetic: None,
        base: o.base.clone(),
        crs: Some(o.crs.clone()),
        origin: Origin {
            lat_deg: mean(|s| s.lat_deg),
            lon_deg: mean(|s| s.lon_deg),
            h_m: mean(|s| s.h_m),
        },
        sphere: spheres,
        apriori: o.apriori.clone(),
        noise: None,
        ins: None,
    };
    site.resolve().map_err(|e| format!("{name}: {e}"))?;
    site.check().map_err(|e| format!("{name}: {e}"))?;
    let c = cols.unwrap_or_default();
    let names: Vec<&str> = c.iter().map(word).collect();
    Ok((site, names.join(",")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::crs::HeightSystem;

    fn opts(epsg: u16, height: HeightSystem, n: Option<f64>) -> ImportOptions {
        ImportOptions {
            crs: SiteCrs {
                epsg,
                height,
                geoid_undulation_m: n,
                geoid_grid: None,
                vertical_epsg: None,
            },
            radius_m: Some(0.1),
            leap_seconds: 18,
            apriori: SiteApriori {
                boresight_deg: [0.0; 3],
                lever_arm_m: [0.0; 3],
                window_margin_m: 2.5,
            },
            base: std::path::PathBuf::new(),
        }
    }

    #[test]
    fn a_sigma_column_gives_each_centre_its_prior() {
        let csv = "id,easting,northing,height,radius,sigma\nS1,500000,5360000,3.5,0.2,0.015\nS2,500010,5360000,4.0,0.2,0.03\n";
        let o = opts(32630, HeightSystem::Orthometric, Some(50.0));
        let (s, cols) = import_csv(csv, "q.csv", &o).unwrap();
        assert_eq!(cols, "id,easting,northing,height,radius,sigma");
        assert_eq!(
            (s.sphere[0].sigma_m, s.sphere[1].sigma_m),
            (Some(0.015), Some(0.03))
        );
        let bad = csv.replace("0.03\n", "-1\n");
        let e = import_csv(&bad, "q.csv", &o).unwrap_err().to_string();
        assert!(e.contains("q.csv:3") && e.contains("sigma"), "{e}");
    }

    #[test]
    fn header_comments_radius_and_heights() {
        let csv = "# quay survey\nid,easting,northing,height,radius\nS1, 500000, 5360000, 3.5, 0.2\nS2,500010,5360000,4.0,0.1 # radius given\n";
        let o = opts(32630, HeightSystem::Orthometric, Some(50.0));
        let (s, cols) = import_csv(csv, "q.csv", &o).unwrap();
        assert_eq!(cols, "id,easting,northing,height,radius");
        assert_eq!(s.sphere.len(), 2);
        assert_eq!(s.sphere[0].radius_m, 0.2);
        // On the central meridian; h = H + N.
        assert!((s.sphere[0].lon_deg + 3.0).abs() < 1e-12);
        assert!((s.sphere[0].h_m - 53.5).abs() < 1e-9);
        assert_eq!(s.sphere[1].height_m, Some(4.0));
        assert_eq!(s.datum().code, 6326);
        // Written and read back: the same site.
        let mut back: Site = toml::from_str(&s.to_toml()).unwrap();
        back.resolve().unwrap();
        assert_eq!(back, s);
        // Without a radius column, --radius.
        let csv = "S1,500000,5360000,3.5\nS2,500010,5360000,4.0\n";
        let (s, cols) = import_csv(csv, "q.csv", &o).unwrap();
        assert_eq!(
            (cols.as_str(), s.sphere[1].radius_m),
            ("id,easting,northing,height", 0.1)
        );
        let no_default = ImportOptions {
            radius_m: None,
            ..o
        };
        let e = import_csv(csv, "q.csv", &no_default)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("q.csv:1: no radius column"), "{e}");
    }

    /// The header decides the columns: northing before easting, lat/lon either way, with the
    /// same points as the default order.
    #[test]
    fn header_names_decide_the_columns() {
        let o = opts(32630, HeightSystem::Ellipsoidal, None);
        let (a, _) = import_csv("S1,500000,5360000,3.5\nS2,500010,5360000,4\n", "q", &o).unwrap();
        let (b, cols) = import_csv(
            "id,northing,easting,h\nS1,5360000,500000,3.5\nS2,5360000,500010,4\n",
            "q",
            &o,
        )
        .unwrap();
        assert_eq!(cols, "id,northing,easting,height");
        assert_eq!(a.sphere, b.sphere);
        let g = opts(4326, HeightSystem::Ellipsoidal, None);
        let (c, cols) = import_csv(
            "name,lat,lon,h\nS1,46.8,-71.2,10\nS2,46.8001,-71.2,10\n",
            "q",
            &g,
        )
        .unwrap();
        assert_eq!(cols, "id,latitude,longitude,height");
        assert!(
            (c.sphere[0].lat_deg - 46.8).abs() < 1e-12
                && (c.sphere[0].lon_deg + 71.2).abs() < 1e-12
        );
        let e = import_csv("id,lat,lon,h\nS1,46.8,-71.2,10\n", "q", &o)
            .unwrap_err()
            .to_string();
        assert!(e.contains("EPSG:32630 is projected"), "{e}");
    }

    #[test]
    fn bad_rows_are_named() {
        let o = opts(32630, HeightSystem::Ellipsoidal, None);
        for (csv, want) in [
            (
                "S1,500000,5360000\nS2,500000,5360000\n",
                "q.csv:1: expected",
            ),
            ("S1,500000,x,1\n", "q.csv:1: northing \"x\""),
            (
                "S1,500000,5360000,1\nS1,500000,5360000,1\n",
                "q.csv:2: sphere id \"S1\"",
            ),
            ("# nothing\n", "q.csv: 0 sphere row(s)"),
            (
                "S1,500000,5360000,1\n",
                "q.csv: 1 sphere row(s): a calibration needs at least two",
            ),
            (
                "S1,500000,5360000,1,-1\nS2,500010,5360000,1,0.1\n",
                "radius",
            ),
            ("id,east,north,elev,colour\n", "header column \"colour\""),
            ("id,east,elev\n", "the header has no northing"),
            // A typing error: one sphere 9 km away.
            (
                "S1,500000,5360000,1\nS2,500010,5360000,1\nS3,509000,5360000,1\n",
                "q.csv:3: sphere S3 is 9.0 km from the others' middle",
            ),
            // Northing and easting swapped without a header: lat -> 48 deg S... off the zone.
            (
                "S1,5360000,500000,1\nS2,5360010,500000,1\n",
                "outside EPSG:32630's area of use",
            ),
        ] {
            let e = import_csv(csv, "q.csv", &o).unwrap_err().to_string();
            assert!(e.contains(want), "{csv:?}: {e}");
        }
    }
}

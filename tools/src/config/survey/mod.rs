//! A surveyor's CSV of sphere centres (`id,easting,northing,height[,radius]` in one EPSG CRS and
//! height system) into a site file: the centres kept as surveyed under `[crs]`, their WGS84
//! values computed beside them, the origin at their mean.

use super::crs::{Crs, HeightUnit, SiteCrs};
use super::site::{Origin, Site, SiteApriori, SiteSphere};

mod columns;
use columns::{header, height_unit, number, Col, Dialect};

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

/// Spheres farther than this from the others' middle cannot be one calibration site [m].
pub const SITE_EXTENT_M: f64 = 2_000.0;

/// `(lat, lon)` [deg] of the point `(x, y)` within EPSG `code`'s area of use `area` ([west,
/// south, east, north], a little beyond its edge is fine: a quay on a zone's border), else
/// why not.
fn inside_area(
    area: Option<[f64; 4]>,
    (x, y): (f64, f64),
    (lat, lon): (f64, f64),
    code: u16,
) -> Result<(), String> {
    let Some([w, so, e, n]) = area else {
        return Ok(());
    };
    let tol = 0.5;
    let inside_lon = if w <= e {
        lon >= w - tol && lon <= e + tol
    } else {
        lon >= w - tol || lon <= e + tol
    };
    if inside_lon && lat >= so - tol && lat <= n + tol {
        return Ok(());
    }
    Err(format!(
        "({x:.5}, {y:.5}) = lat {lat:.4}, lon {lon:.4} is outside EPSG:{code}'s area of use (lon {w} to {e}, lat {so} to {n}): the wrong CRS, or its columns swapped?"
    ))
}

/// Every sphere within [`SITE_EXTENT_M`] of the others' middle (the median latitude and
/// longitude); `lines`: each sphere's line in `name`.
fn within_extent(name: &str, spheres: &[SiteSphere], lines: &[usize]) -> Result<(), crate::Error> {
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
    for (s, line) in spheres.iter().zip(lines) {
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
    Ok(())
}

/// The site of the imported spheres: its origin their mean, the import's CRS (heights in
/// `unit`), base, leap seconds and a-priori mounting.
fn site_of(o: &ImportOptions, spheres: Vec<SiteSphere>, unit: Option<HeightUnit>) -> Site {
    let n = spheres.len() as f64;
    let mean = |f: fn(&SiteSphere) -> f64| spheres.iter().map(f).sum::<f64>() / n;
    Site {
        leap_seconds: o.leap_seconds,
        datum: None,
        geodetic: None,
        base: o.base.clone(),
        crs: Some(SiteCrs {
            height_unit: unit,
            ..o.crs.clone()
        }),
        origin: Origin {
            lat_deg: mean(|s| s.lat_deg),
            lon_deg: mean(|s| s.lon_deg),
            h_m: mean(|s| s.h_m),
        },
        sphere: spheres,
        apriori: o.apriori.clone(),
        noise: None,
        lidar: None,
        ins: None,
        calibration: None,
    }
}

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
    // A spreadsheet's "CSV UTF-8" starts with a byte-order mark.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let dialect = Dialect::of(text);
    let mut header_unit: Option<HeightUnit> = None;
    let mut used_unit: Option<HeightUnit> = None;
    for (i, raw) in text.lines().enumerate() {
        let at = |why: String| crate::Error::bad_input(format!("{name}:{}: {why}", i + 1));
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let owned = dialect.fields(line);
        let f: Vec<&str> = owned.iter().map(String::as_str).collect();
        if cols.is_none() {
            match header(&owned, crs.is_geographic(), crs.code) {
                Some(Ok((c, u))) => {
                    cols = Some(c);
                    header_unit = u;
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
                Some(s) => number(s)
                    .filter(|v| v.is_finite())
                    .map(Some)
                    .ok_or_else(|| at(format!("{} {s:?} is not a finite number", word(&k)))),
            }
        };
        let id = get(Col::Id).unwrap_or("");
        if id.is_empty() || spheres.iter().any(|s| s.id == id) {
            return Err(at(format!("sphere id {id:?} is empty or repeated")));
        }
        let unit = height_unit(&crs, header_unit, o.crs.height_unit).map_err(&at)?;
        used_unit = Some(unit);
        let (x, y, h_given) = (
            num(Col::X)?.unwrap_or(f64::NAN),
            num(Col::Y)?.unwrap_or(f64::NAN),
            num(Col::Height)?.unwrap_or(f64::NAN),
        );
        // Heights in metres from here on (the unit recorded in the site's [crs]).
        let h = h_given * unit.metres();
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
        inside_area(area, (x, y), (lat, lon), crs.code)
            .map_err(|why| at(format!("sphere {id}: {why}")))?;
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
    within_extent(name, &spheres, &lines)?;
    let mut site = site_of(o, spheres, used_unit);
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
                height_unit: None,
            },
            radius_m: Some(0.1),
            leap_seconds: 18,
            apriori: SiteApriori {
                boresight_deg: [0.0; 3],
                lever_arm_m: [0.0; 3],
                window_margin_m: 2.5,
                boresight_sigma_deg: None,
                lever_arm_sigma_m: None,
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
    /// A spreadsheet's exports: Excel's "CSV UTF-8" (a byte-order mark, CRLF), a locale with
    /// decimal commas (`;` separated), tab separated, quoted fields, the header names
    /// surveyors use in any case: each reads as the plain CSV does.
    #[test]
    fn spreadsheet_exports_read_as_the_plain_csv() {
        let o = opts(32630, HeightSystem::Ellipsoidal, None);
        let plain = "id,easting,northing,height\nS1,500000.25,5360000.5,3.5\nS2,500010,5360000,4\n";
        let (want, _) = import_csv(plain, "q", &o).unwrap();
        for csv in [
            "\u{feff}Point,E,N,Elevation\r\nS1,500000.25,5360000.5,3.5\r\nS2,500010,5360000,4\r\n",
            "POINT;EASTING;NORTHING;ELEV\nS1;500000,25;5360000,5;3,5\nS2;500010;5360000;4\n",
            "Name\tX\tY\tZ\nS1\t500000.25\t5360000.5\t3.5\nS2\t500010\t5360000\t4\n",
            "\"Point ID\",\"Easting\",\"Northing\",\"Height\"\n\"S1\",\"500000.25\",\"5360000.5\",\"3.5\"\n\"S2\",500010,5360000,4\n",
            "\u{feff}id;e;n;h\r\n\"S1\";\"500000,25\";5360000,5;3,5\r\nS2;500010;5360000;4\r\n",
        ] {
            let (got, _) = import_csv(csv, "q", &o).unwrap_or_else(|e| panic!("{csv:?}: {e}"));
            assert_eq!(got.sphere, want.sphere, "{csv:?}");
        }
        // Anything else is named with the names taken.
        let e = import_csv("Pt;Ost;Nord;Hoehe\nS1;1;2;3\n", "q", &o)
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"Ost\"") && e.contains("Easting"), "{e}");
    }

    /// Heights in feet: a CRS in US survey feet (EPSG:2248, Maryland) needs their unit said,
    /// by `--height-unit` or in the header (`Elevation (ftUS)`); they are converted to metres
    /// (1200/3937 m) and the unit recorded; a header and an option that disagree are refused.
    #[test]
    fn heights_in_feet_are_said_and_converted() {
        let csv = "id,easting,northing,elevation\nS1,1300000,500000,100\nS2,1300030,500000,110\n";
        let o = opts(2248, HeightSystem::Ellipsoidal, None);
        let e = import_csv(csv, "q", &o).unwrap_err().to_string();
        assert!(
            e.contains("US survey feet") && e.contains("--height-unit"),
            "{e}"
        );
        let mut ft = opts(2248, HeightSystem::Ellipsoidal, None);
        ft.crs.height_unit = Some(HeightUnit::UsFoot);
        let (s, _) = import_csv(csv, "q", &ft).unwrap();
        assert!(
            (s.sphere[0].h_m - 100.0 * 1200.0 / 3937.0).abs() < 1e-9,
            "{}",
            s.sphere[0].h_m
        );
        assert_eq!(
            s.crs.as_ref().unwrap().height_unit,
            Some(HeightUnit::UsFoot)
        );
        let header = csv.replace("elevation", "Elevation (ftUS)");
        let (h, _) = import_csv(&header, "q", &o).unwrap();
        assert_eq!(h.sphere, s.sphere);
        // A metric CRS with heights in international feet, from the header.
        let m = opts(32630, HeightSystem::Ellipsoidal, None);
        let (f, _) = import_csv(
            "id,e,n,z_ft\nS1,500000,5360000,10\nS2,500010,5360000,10\n",
            "q",
            &m,
        )
        .unwrap();
        assert!((f.sphere[0].h_m - 3.048).abs() < 1e-9);
        let mut both = ft.clone();
        both.crs.height_unit = Some(HeightUnit::Metre);
        let e = import_csv(&header, "q", &both).unwrap_err().to_string();
        assert!(e.contains("which?"), "{e}");
    }

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

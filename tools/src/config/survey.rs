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
}

/// The site for the CSV `text` (read from `name`, for errors as `name:line: why`), resolved
/// and checked.
pub fn import_csv(text: &str, name: &str, o: &ImportOptions) -> Result<Site, String> {
    let crs = Crs::epsg(o.crs.epsg)?;
    let mut spheres: Vec<SiteSphere> = Vec::new();
    let mut header_seen = false;
    for (i, raw) in text.lines().enumerate() {
        let at = |why: String| format!("{name}:{}: {why}", i + 1);
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let num = |k: usize, what: &str| -> Result<f64, String> {
            let s = f.get(k).copied().unwrap_or("");
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| at(format!("{what} {s:?} is not a finite number")))
        };
        if spheres.is_empty() && !header_seen && f.get(1).is_some_and(|s| s.parse::<f64>().is_err())
        {
            header_seen = true;
            continue;
        }
        if !(4..=5).contains(&f.len()) {
            return Err(at(format!(
                "expected id,easting,northing,height[,radius], got {} fields",
                f.len()
            )));
        }
        let id = f[0];
        if id.is_empty() || spheres.iter().any(|s| s.id == id) {
            return Err(at(format!("sphere id {id:?} is empty or repeated")));
        }
        let (x, y, h) = (num(1, "easting")?, num(2, "northing")?, num(3, "height")?);
        let radius_m = match f.get(4) {
            Some(_) => num(4, "radius")?,
            None => o
                .radius_m
                .ok_or_else(|| at("no radius column: give --radius".into()))?,
        };
        let (lat, lon, h_ell) = o.crs.to_wgs84(&crs, x, y, h).map_err(at)?;
        let mut s = SiteSphere::wgs84(id, lat, lon, h_ell, radius_m);
        (s.easting, s.northing, s.height_m) = (Some(x), Some(y), Some(h));
        spheres.push(s);
    }
    if spheres.is_empty() {
        return Err(format!("{name}: no sphere rows"));
    }
    let n = spheres.len() as f64;
    let mean = |f: fn(&SiteSphere) -> f64| spheres.iter().map(f).sum::<f64>() / n;
    let mut site = Site {
        leap_seconds: o.leap_seconds,
        crs: Some(o.crs),
        origin: Origin {
            lat_deg: mean(|s| s.lat_deg),
            lon_deg: mean(|s| s.lon_deg),
            h_m: mean(|s| s.h_m),
        },
        sphere: spheres,
        apriori: o.apriori.clone(),
        noise: None,
    };
    site.resolve().map_err(|e| format!("{name}: {e}"))?;
    site.check().map_err(|e| format!("{name}: {e}"))?;
    Ok(site)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::crs::HeightSystem;

    fn opts(height: HeightSystem, n: f64) -> ImportOptions {
        ImportOptions {
            crs: SiteCrs {
                epsg: 32630,
                height,
                geoid_undulation_m: n,
            },
            radius_m: Some(0.1),
            leap_seconds: 18,
            apriori: SiteApriori {
                boresight_deg: [0.0; 3],
                lever_arm_m: [0.0; 3],
                window_margin_m: 2.5,
            },
        }
    }

    #[test]
    fn header_comments_radius_and_heights() {
        let csv = "# quay survey\nid,easting,northing,height,radius\nS1, 500000, 5360000, 3.5, 0.2\nS2,500010,5360000,4.0 # no radius\n";
        let o = opts(HeightSystem::Orthometric, 50.0);
        let no_default = ImportOptions {
            radius_m: None,
            ..o.clone()
        };
        let e = import_csv(csv, "q.csv", &no_default).unwrap_err();
        assert!(e.starts_with("q.csv:4: no radius column"), "{e}");
        let s = import_csv(csv, "q.csv", &o).unwrap();
        assert_eq!(s.sphere.len(), 2);
        assert_eq!(s.sphere[0].radius_m, 0.2);
        assert_eq!(s.sphere[1].radius_m, 0.1);
        // On the central meridian; h = H + N.
        assert!((s.sphere[0].lon_deg + 3.0).abs() < 1e-12);
        assert!((s.sphere[0].h_m - 53.5).abs() < 1e-9);
        assert_eq!(s.sphere[1].height_m, Some(4.0));
        // Written and read back: the same site.
        let mut back: Site = toml::from_str(&s.to_toml()).unwrap();
        back.resolve().unwrap();
        assert_eq!(back, s);
    }

    #[test]
    fn bad_rows_are_named() {
        let o = opts(HeightSystem::Ellipsoidal, 0.0);
        for (csv, want) in [
            ("S1,500000,5360000\n", "q.csv:1: expected id,easting"),
            ("S1,500000,x,1\n", "q.csv:1: northing \"x\""),
            ("S1,1,2,3\nS1,1,2,3\n", "q.csv:2: sphere id \"S1\""),
            ("# nothing\n", "q.csv: no sphere rows"),
            ("S1,500000,5360000,1,-1\n", "radius"),
        ] {
            let e = import_csv(csv, "q.csv", &o).unwrap_err();
            assert!(e.contains(want), "{csv:?}: {e}");
        }
    }
}

//! `spherecal plan --site SITE.toml`: a plan for a surveyor's own site file (issue 47 item
//! 8). The lines come back in the site's grid: checked against pyproj (the GeoJSON's WGS 84
//! ends projected independently) and against the surveyed centres' own grid coordinates (the
//! vessel's first line 8 m off their line); the targets are the site's.

use crate::common;
use std::path::{Path, PathBuf};

/// The README's sample survey (table1's spheres in UTM 30N) imported into `dir`.
fn sample_site(dir: &Path, calibration: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let out = dir.join("site.toml");
    let mut cmd = common::spherecal();
    cmd.args(["site", "import"])
        .arg(common::repo_root().join("examples/survey-utm30n.csv"))
        .args(["--crs", "EPSG:32630", "--height", "ellipsoidal"])
        .args(["--margin", "3", "--force"])
        .args(["--apriori", "181.787,-42.423,2.431,1.312,-1.205,-1.759"])
        .arg("-o")
        .arg(&out);
    common::stdout_of(&mut cmd);
    if !calibration.is_empty() {
        let mut t = std::fs::read_to_string(&out).unwrap();
        t += calibration;
        std::fs::write(&out, t).unwrap();
    }
    out
}

fn read_json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn pair(v: &serde_json::Value) -> [f64; 2] {
    [v[0].as_f64().unwrap(), v[1].as_f64().unwrap()]
}

/// The distance of `p` from the line through `a` and `b`.
fn off_line(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    ((p[0] - a[0]) * dy - (p[1] - a[1]) * dx).abs() / dx.hypot(dy)
}

#[test]
fn a_vessel_plan_for_the_sample_site_in_its_grid() {
    let dir = common::tmp("plan-site", "vessel");
    let site = sample_site(&dir, "");
    let (json, geo) = (dir.join("plan.json"), dir.join("lines.geojson"));
    let out = common::spherecal()
        .args(["plan", "--site"])
        .arg(&site)
        .arg("--report")
        .arg(&json)
        .arg("--geojson")
        .arg(&geo)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    // table1's spheres at the same height: pitch misses the default 0.01 deg: exit 1.
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(
        text.contains("lines to run (EPSG:32630, easting, northing [m]"),
        "{text}"
    );
    assert!(
        text.contains("wrote") && text.contains("lines.geojson"),
        "{text}"
    );
    let j = read_json(&json);
    let lines = j["lines"]["lines"].as_array().unwrap();
    let planned: Vec<&serde_json::Value> = lines
        .iter()
        .filter(|l| l["name"].as_str().unwrap().starts_with('L'))
        .collect();
    assert_eq!(planned.len(), 4, "{j}");
    // The surveyed centres (examples/survey-utm30n.csv): S1, S2.
    let (s1, s2) = (
        [389_672.24, 5_359_609.597_6],
        [389_672.628_7, 5_359_629.588_6],
    );
    for (l, want) in planned.iter().zip([8.0, 12.0, 20.0, 30.0]) {
        for end in ["start", "end"] {
            let d = off_line(pair(&l[end]), s1, s2);
            // The grid's scale factor at 4.49 W in zone 30: 0.99966 (0.3 mm per m).
            assert!(
                (d - want).abs() < 0.02,
                "{}: {d} m off, want {want}: {l}",
                l["name"]
            );
        }
    }
    // The grid coordinates are the WGS 84 ends projected (pyproj, independently).
    let ends: Vec<[f64; 2]> = lines.iter().map(|l| pair(&l["start_wgs84"])).collect();
    for (l, p) in lines.iter().zip(common::pyproj_forward(32630, &ends)) {
        let g = pair(&l["start"]);
        assert!(
            (g[0] - p[0]).abs() < 1e-3 && (g[1] - p[1]).abs() < 1e-3,
            "{g:?} {p:?}"
        );
    }
    // GeoJSON: the lines and the spheres, S1 where table1 puts it (48.38 N, 0.6 m west of
    // 4.49 W).
    let g = read_json(&geo);
    assert_eq!(g["type"], "FeatureCollection");
    let f = g["features"].as_array().unwrap();
    assert_eq!(f.len(), lines.len() + 2);
    let s1 = f.iter().find(|x| x["properties"]["name"] == "S1").unwrap();
    let c = pair(&s1["geometry"]["coordinates"]);
    assert!(
        (c[1] - 48.38).abs() < 1e-8 && (c[0] + 4.490_008_1).abs() < 1e-7,
        "{c:?}"
    );
    assert_eq!(f[0]["geometry"]["type"], "LineString");
    // The prediction is the planner's: what it misses and what it recommends.
    assert_eq!(j["plan"]["meets"], false);
    assert!(text.contains("recommendation 1:"), "{text}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_sites_targets_and_a_drone() {
    let dir = common::tmp("plan-site", "drone");
    let site = sample_site(
        &dir,
        "\n[calibration]\ntarget_sigma_deg = 0.05\ntarget_sigma_m = 0.02\n",
    );
    let out = common::spherecal()
        .args(["plan", "--no-recommend", "--site"])
        .arg(&site)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("(target 0.05 deg, 20 mm)"), "{text}");
    assert_eq!(
        out.status.code(),
        Some(0),
        "the site's targets are met: {text}"
    );
    // A drone at 30 m over the spheres (their ground 1.55 m below their centres).
    let json = dir.join("drone.json");
    let out = common::spherecal()
        .args([
            "plan",
            "--no-recommend",
            "--platform",
            "drone",
            "--height",
            "30",
            "--site",
        ])
        .arg(&site)
        .arg("--report")
        .arg(&json)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    // The lower line and the crossing one pass over the spheres' midpoint (the surveyed
    // centres' in the CSV), the opposing pair 3 m (0.1 h) either side of it.
    let lines = read_json(&json)["lines"]["lines"].clone();
    let (s1, s2) = (
        [389_672.24, 5_359_609.597_6],
        [389_672.628_7, 5_359_629.588_6],
    );
    let mid = [(s1[0] + s2[0]) / 2.0, (s1[1] + s2[1]) / 2.0];
    for (k, want) in [(0, 3.0), (1, 3.0), (2, 0.0), (3, 0.0)] {
        let l = &lines[k];
        let d = off_line(mid, pair(&l["start"]), pair(&l["end"]));
        assert!(
            (d - want).abs() < 0.05,
            "line {k}: {d} m from the spheres' midpoint"
        );
    }
    assert!(text.contains("INS 30.0 m above the ground"), "{text}");
    assert!(
        text.contains("INS 18.0 m above the ground"),
        "the lower line: {text}"
    );
    // A flag for a site without one.
    let out = common::spherecal()
        .args(["plan", "--scenario", "table1", "--platform", "drone"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("give --site"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A CRS in US survey feet: the lines in feet, as pyproj gives them.
#[test]
fn lines_in_a_feet_grid() {
    let dir = common::tmp("plan-site", "feet");
    std::fs::create_dir_all(&dir).unwrap();
    // Two spheres by the water at Annapolis, Maryland (EPSG:2248, NAD83 / Maryland (ftUS)).
    let ll = [[-76.4800, 38.9700], [-76.4800, 38.97018]];
    let xy = common::pyproj_forward(2248, &ll);
    let mut csv = String::from("Point,Easting,Northing,Elevation (usft)\n");
    for (k, p) in xy.iter().enumerate() {
        csv += &format!("S{},{:.3},{:.3},{:.3}\n", k + 1, p[0], p[1], 5.0);
    }
    std::fs::write(dir.join("survey.csv"), csv).unwrap();
    let site = dir.join("site.toml");
    let mut cmd = common::spherecal();
    cmd.args(["site", "import"])
        .arg(dir.join("survey.csv"))
        .args([
            "--crs",
            "EPSG:2248",
            "--height",
            "ellipsoidal",
            "--radius",
            "0.2",
        ])
        .args(["--apriori", "180,-42,0,1.3,-1.2,-1.8", "-o"])
        .arg(&site);
    common::stdout_of(&mut cmd);
    let json = dir.join("plan.json");
    let out = common::spherecal()
        .args(["plan", "--no-recommend", "--side", "e", "--site"])
        .arg(&site)
        .arg("--report")
        .arg(&json)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("easting, northing [us-ft]"), "{text}");
    assert!(text.contains("on the east side"), "{text}");
    let j = read_json(&json);
    let lines = j["lines"]["lines"].as_array().unwrap();
    let wgs: Vec<[f64; 2]> = lines.iter().map(|l| pair(&l["end_wgs84"])).collect();
    // NAD83 here is within a metre of WGS 84 and the site's datum shift is PROJ's
    // null transformation for it: pyproj from WGS 84 agrees to a millimetre.
    for (l, p) in lines.iter().zip(common::pyproj_forward(2248, &wgs)) {
        let g = pair(&l["end"]);
        assert!(
            (g[0] - p[0]).abs() < 0.01 && (g[1] - p[1]).abs() < 0.01,
            "{g:?} {p:?}"
        );
    }
    // The first line 8 m (26.2 ft) east of the spheres.
    let d = lines[0]["start"][0].as_f64().unwrap() - xy[0][0];
    assert!((d / 3.280_833 - 8.0).abs() < 0.5, "{d} ft");
    std::fs::remove_dir_all(&dir).unwrap();
}

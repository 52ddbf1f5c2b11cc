//! Datums end to end (issue 26): a sphere survey in NAD83(CSRS) / MTM zone 7 with CGVD2013
//! heights near Quebec City, the trajectory a VN-200's WGS 84. pyproj (PROJ 9, installed by
//! scripts/test.sh) is the independent reference: its default NAD83(CSRS) -> WGS 84 is EPSG:1946
//! (a Helmert transformation, 1.05 m horizontally and 1.08 m vertically there).

use crate::common;

use spherecal_tools::config::datum::Datum;
use spherecal_tools::config::geoid::gtx_bytes;
use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::config::site::Site;
use std::path::Path;

/// The geoid undulation used near Quebec City [m] (CGG2013 there is about -28.6).
const N: f64 = -28.6;

/// WGS 84 (lat, lon, h) -> NAD83(CSRS) MTM 7 easting, northing and CGVD2013 height H = h - N,
/// by pyproj (EPSG:4979 -> EPSG:4955 -> EPSG:2949).
fn to_mtm7(pts: &[(f64, f64, f64)]) -> Vec<(f64, f64, f64)> {
    let list: Vec<String> = pts
        .iter()
        .map(|p| format!("({}, {}, {})", p.1, p.0, p.2))
        .collect();
    let script = format!(
        "from pyproj import Transformer\na = Transformer.from_crs('EPSG:4979', 'EPSG:4955', always_xy=True)\nb = Transformer.from_crs('EPSG:4955', 'EPSG:2949', always_xy=True)\nfor lon, lat, h in [{}]:\n    lo, la, hh = a.transform(lon, lat, h)\n    x, y = b.transform(lo, la)\n    print(repr(x), repr(y), repr(hh - ({N})))",
        list.join(", ")
    );
    common::python(&script, "pyproj")
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split(' ').map(|s| s.parse().unwrap()).collect();
            (v[0], v[1], v[2])
        })
        .collect()
}

/// `site import` of those points as a CSV (northing first, to exercise the header).
fn import(dir: &Path, pts: &[(f64, f64, f64)], geoid: &[&str]) -> std::process::Output {
    let mtm = to_mtm7(pts);
    let mut csv = String::from("id,northing,easting,height\n");
    for (i, (x, y, h)) in mtm.iter().enumerate() {
        csv += &format!("S{},{y:.4},{x:.4},{h:.4}\n", i + 1);
    }
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("survey.csv"), csv).unwrap();
    common::spherecal()
        .args(["site", "import"])
        .arg(dir.join("survey.csv"))
        .args([
            "--crs",
            "EPSG:2949",
            "--height",
            "orthometric",
            "--radius",
            "0.19",
        ])
        .args(["--vertical-crs", "EPSG:6647", "--force", "-o"])
        .arg(dir.join("site.toml"))
        .args(geoid)
        .output()
        .unwrap()
}

/// Within `tol` metres, each point.
fn assert_near(got: &[(f64, f64, f64)], want: &[(f64, f64, f64)], tol: f64, what: &str) {
    for (g, w) in got.iter().zip(want) {
        let dn = (g.0 - w.0).to_radians() * 6.371e6;
        let de = (g.1 - w.1).to_radians() * 6.371e6 * w.0.to_radians().cos();
        assert!(
            dn.hypot(de) < tol && (g.2 - w.2).abs() < tol,
            "{what}: {g:?} vs {w:?} ({dn:.4} m N, {de:.4} m E, {:.4} m up)",
            g.2 - w.2
        );
    }
}

/// The survey imported keeps its datum, and taken to WGS 84 lands where pyproj put the
/// points (3 mm: the CSV's 0.1 mm and two Helmert implementations); N is never assumed, a
/// grid gives the same as the constant it holds; a projected CRS is refused lat/lon columns.
#[test]
fn a_nad83_csrs_survey_meets_wgs84_by_the_named_transformation() {
    let pts = [
        (46.812_310, -71.203_450, 12.314),
        (46.812_620, -71.202_980, 12.902),
        (46.812_900, -71.202_410, 11.871),
    ];
    let dir = common::tmp("datums", "import");
    let out = import(&dir, &pts, &[]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("N = 0 is never assumed"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = import(&dir, &pts, &["--geoid-n", &N.to_string()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("columns id,northing,easting,height"),
        "{text}"
    );
    assert!(
        text.contains("datum: NAD83(CSRS) (EPSG datum 6140)"),
        "{text}"
    );
    let site = Site::load(&dir.join("site.toml")).unwrap();
    assert_eq!(site.datum().code, 6140);
    let (wgs, shift) = site.in_datum(&Datum::wgs84()).unwrap();
    assert!(
        shift
            .describe()
            .contains("EPSG:1946 NAD83(CSRS) to WGS 84 (2) (Helmert, accuracy 1 m)"),
        "{}",
        shift.describe()
    );
    let got: Vec<_> = wgs
        .sphere
        .iter()
        .map(|s| (s.lat_deg, s.lon_deg, s.h_m))
        .collect();
    assert_near(&got, &pts, 3e-3, "NAD83(CSRS) -> WGS 84");
    // Assuming NAD83(CSRS) = WGS 84 would have put them a metre away.
    let raw: Vec<_> = site
        .sphere
        .iter()
        .map(|s| (s.lat_deg, s.lon_deg, s.h_m))
        .collect();
    let d = (raw[0].0 - pts[0].0).to_radians() * 6.371e6;
    assert!(
        d.abs() > 0.9 && (raw[0].2 - pts[0].2).abs() > 0.9,
        "{raw:?}"
    );
    // A geoid grid holding the same N gives the same site.
    let grid = dir.join("flat.gtx");
    std::fs::write(
        &grid,
        gtx_bytes(46.0, 288.0, [0.5, 0.5], 4, &[N as f32; 16]),
    )
    .unwrap();
    let out = import(&dir, &pts, &["--geoid", grid.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let gsite = Site::load(&dir.join("site.toml")).unwrap();
    assert_eq!(
        gsite.crs.as_ref().unwrap().geoid_grid.as_deref(),
        Some("flat.gtx")
    );
    for (a, b) in gsite.sphere.iter().zip(&site.sphere) {
        assert!((a.h_m - b.h_m).abs() < 1e-6 && (a.lat_deg - b.lat_deg).abs() < 1e-12);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A VN-200 survey at Quebec City calibrated against its spheres surveyed in NAD83(CSRS) / MTM
/// 7: the transformation is applied and named, the truth found to 1e-3; the LAS carries the
/// compound CRS (EPSG:2949 + EPSG:6647), its points where pyproj puts the local ones; an SBET
/// without its datum is refused.
#[test]
fn a_vn200_survey_calibrates_against_a_nad83_csrs_site() {
    let mut s = Scenario::load("table1-bare").unwrap();
    s.site.lat_deg = 46.81;
    s.site.lon_deg = -71.2;
    s.site.h_m = 10.0;
    let dir = common::tmp("datums", "quebec");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let wgs = Site::load(&dir.join("site.toml")).unwrap();
    let pts: Vec<_> = wgs
        .sphere
        .iter()
        .map(|s| (s.lat_deg, s.lon_deg, s.h_m))
        .collect();
    let sdir = dir.join("survey");
    let out = import(&sdir, &pts, &["--geoid-n", &N.to_string()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The imported site needs the a-priori values and margin of the synthetic one, and its
    // INS's declaration (white: else a VN-200's metre-level default).
    let text = std::fs::read_to_string(sdir.join("site.toml")).unwrap();
    let i = text.find("[apriori]").unwrap();
    let j = text[i..].find("\n\n").map_or(text.len(), |k| i + k);
    let apriori = wgs.to_toml();
    let a = apriori.find("[apriori]").unwrap();
    let b = apriori[a..].find("\n\n").map_or(apriori.len(), |k| a + k);
    let site = sdir.join("site.toml");
    std::fs::write(
        &site,
        format!(
            "{}{}{}\n[ins.correlated]\npreset = \"white\"\n",
            &text[..i],
            &apriori[a..b],
            &text[j..]
        ),
    )
    .unwrap();
    let las = dir.join("cloud.las");
    let out = common::spherecal()
        .arg("calibrate")
        .arg("--pcap")
        .arg(dir.join("lidar.pcap"))
        .arg("--ins")
        .arg(dir.join("ins.bin"))
        .arg("--site")
        .arg(&site)
        .arg("--report")
        .arg(dir.join("r.json"))
        .arg("--las")
        .arg(&las)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("datums: the spheres' survey NAD83(CSRS) (EPSG datum 6140) -> the trajectory's WGS 84 (EPSG datum 6326) (the VN-200's): ")
            && text.contains("EPSG:1946"),
        "{text}"
    );
    assert!(
        text.contains("warning: that transformation is good to 1 m only"),
        "{text}"
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("r.json")).unwrap()).unwrap();
    common::assert_within(
        &common::report_deg_m(&r),
        &s.mount.truth.deg_m().0,
        1e-3,
        "Quebec",
    );
    // The LAS: compound CRS, heights CGVD2013, points where pyproj puts the spheres' returns.
    let script = format!(
        r#"import laspy, numpy as np
from pyproj import CRS
m = laspy.read({las:?})
crs = m.header.parse_crs()
print(crs.is_compound, *[c.to_epsg() for c in crs.sub_crs_list])
w = np.asarray(m.window)
print(int(np.count_nonzero(w)))"#,
        las = las.to_str().unwrap()
    );
    let out = common::python(&script, "laspy and pyproj");
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "True 2949 6647", "{out}");
    // Each sphere fitted (radius fixed) to the LAS points on it (within 5 mm of its surface,
    // the `residual` dimension) in the LAS's own coordinates, against its surveyed MTM 7 easting,
    // northing and CGVD2013 height: the cloud lands where the survey says the spheres are.
    let mtm = to_mtm7(&pts);
    let script = format!(
        r#"import laspy, numpy as np
m = laspy.read({las:?})
w = np.asarray(m.window); r = np.asarray(m.residual)
for k, c in ((1, {c1:?}), (2, {c2:?})):
    sel = (w == k) & (np.abs(r) < 0.005)
    P = np.stack([np.asarray(m.x)[sel], np.asarray(m.y)[sel], np.asarray(m.z)[sel]], 1)
    c = np.array(c)
    for _ in range(20):
        d = P - c; n = np.linalg.norm(d, axis=1); J = -d / n[:, None]
        c = c - np.linalg.lstsq(J, n - 0.19, rcond=None)[0]
    print(len(P), *(c - np.array({c1:?} if k == 1 else {c2:?})))"#,
        las = las.to_str().unwrap(),
        c1 = [mtm[0].0, mtm[0].1, mtm[0].2],
        c2 = [mtm[1].0, mtm[1].1, mtm[1].2],
    );
    let out = common::python(&script, "laspy");
    for line in out.lines() {
        let v: Vec<f64> = line.split(' ').map(|x| x.parse().unwrap()).collect();
        let d = (v[1].powi(2) + v[2].powi(2) + v[3].powi(2)).sqrt();
        assert!(
            v[0] > 500.0 && d < 0.004,
            "{line}: the fitted centre is {d} m off"
        );
    }
    // An SBET must say its datum.
    let out = common::spherecal()
        .arg("georef")
        .arg("--pcap")
        .arg(dir.join("lidar.pcap"))
        .arg("--sbet")
        .arg(dir.join("ins.bin"))
        .arg("--site")
        .arg(&site)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("give --trajectory-datum"));
    std::fs::remove_dir_all(&dir).unwrap();
}

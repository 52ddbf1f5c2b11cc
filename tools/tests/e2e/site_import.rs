//! `spherecal site import` against an independent transform: pyproj (PROJ 9, installed by
//! scripts/test.sh) projects known WGS84 points into each CRS; the survey CSV holds those
//! projected coordinates (and orthometric heights H = h - N); the imported site must give back
//! the WGS84 points.

use crate::common;

use spherecal_tools::config::site::Site;

/// Known centres near Brest (WGS84 lat, lon [deg], ellipsoidal h [m]).
const BREST: [(f64, f64, f64); 3] = [
    (48.380_512, -4.492_113, 55.214),
    (48.380_905, -4.491_530, 54.902),
    (48.381_377, -4.490_802, 56.017),
];
/// ... and near San Francisco (for NAD83 / UTM 10N).
const SF: [(f64, f64, f64); 2] = [(37.808_2, -122.409_9, -28.5), (37.808_6, -122.409_1, -27.9)];

/// Each point projected into EPSG `epsg` by pyproj (x east, y north).
fn pyproj_forward(epsg: u16, pts: &[(f64, f64, f64)]) -> Vec<(f64, f64)> {
    let ll: Vec<[f64; 2]> = pts.iter().map(|p| [p.1, p.0]).collect();
    common::pyproj_forward(u32::from(epsg), &ll)
        .into_iter()
        .map(|p| (p[0], p[1]))
        .collect()
}

fn import(epsg: u16, pts: &[(f64, f64, f64)], n: Option<f64>) -> Site {
    let xy = pyproj_forward(epsg, pts);
    let mut csv = String::from("# surveyed centres\nid,easting,northing,height,radius\n");
    for (i, ((x, y), p)) in xy.iter().zip(pts).enumerate() {
        let height = p.2 - n.unwrap_or(0.0);
        csv += &format!("S{},{x:.4},{y:.4},{height:.4},0.1{}\n", i + 1, i);
    }
    let dir = common::tmp("site-import", &format!("{epsg}"));
    std::fs::create_dir_all(&dir).unwrap();
    let csv_path = dir.join("survey.csv");
    std::fs::write(&csv_path, csv).unwrap();
    let out = dir.join("site.toml");
    let mut cmd = common::spherecal();
    cmd.args(["site", "import"])
        .arg(&csv_path)
        .args(["--crs", &format!("EPSG:{epsg}"), "--force", "-o"])
        .arg(&out);
    match n {
        Some(n) => cmd.args(["--height", "orthometric", "--geoid-n", &n.to_string()]),
        None => cmd.args(["--height", "ellipsoidal"]),
    };
    let text = common::stdout_of(&mut cmd);
    assert!(text.contains(&format!("{} spheres", pts.len())), "{text}");
    Site::load(&out).unwrap()
}

/// Within 1 mm (0.1 mm of rounding in the CSV, the rest the two implementations).
fn assert_same(site: &Site, pts: &[(f64, f64, f64)], what: &str) {
    assert_eq!(site.sphere.len(), pts.len());
    for (s, p) in site.sphere.iter().zip(pts) {
        let dn = (s.lat_deg - p.0).to_radians() * 6.371e6;
        let de = (s.lon_deg - p.1).to_radians() * 6.371e6 * p.0.to_radians().cos();
        let dh = s.h_m - p.2;
        assert!(
            dn.hypot(de) < 1e-3 && dh.abs() < 1e-3,
            "{what} {}: off by {dn:.5} m N, {de:.5} m E, {dh:.5} m up",
            s.id
        );
    }
}

#[test]
fn utm_with_orthometric_heights() {
    let site = import(32630, &BREST, Some(51.37));
    assert_same(&site, &BREST, "EPSG:32630");
    assert_eq!(site.sphere[0].radius_m, 0.1);
    assert!(
        site.sphere[1].radius_m > 0.1,
        "the CSV's radius column is used"
    );
    // The origin is at the spheres' mean.
    assert!((site.origin.lat_deg - 48.380_931).abs() < 1e-6);
}

#[test]
fn lambert93_ellipsoidal() {
    let site = import(2154, &BREST, None);
    assert_same(&site, &BREST, "EPSG:2154");
}

#[test]
fn nad83_utm10() {
    let site = import(26910, &SF, None);
    assert_same(&site, &SF, "EPSG:26910");
}

#[test]
fn refusals_name_the_problem() {
    let dir = common::tmp("site-import", "bad");
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("bad.csv");
    std::fs::write(&csv, "S1,389518.4,5359668.2,nope\n").unwrap();
    let out = common::spherecal()
        .args(["site", "import"])
        .arg(&csv)
        .args(["--crs", "EPSG:32630", "--radius", "0.1", "--force"])
        .args(["--height", "ellipsoidal", "-o"])
        .arg(dir.join("s.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.csv:1: height \"nope\""), "{err}");
    let out = common::spherecal()
        .args(["site", "import"])
        .arg(&csv)
        .args(["--crs", "EPSG:99999", "--height", "ellipsoidal", "-o"])
        .arg(dir.join("s.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("EPSG:99999"));
}

/// A compound or vertical code given as `--crs` names the parts to give instead, as the EPSG
/// dataset (pyproj) splits them; a code no CRS has says so.
#[test]
fn compound_and_unknown_codes_say_what_to_give() {
    let codes = [6649u16, 5498, 9518, 7415];
    let script = format!(
        "from pyproj import CRS\nfor c in {codes:?}:\n    s = CRS.from_epsg(c).sub_crs_list\n    print(c, s[0].to_epsg(), s[1].to_epsg())\n"
    );
    let csv = common::tmp("site-import-codes", "s.csv");
    std::fs::write(
        &csv,
        "id,easting,northing,height\nA,250000,5186000,10\nB,250010,5186000,10\n",
    )
    .unwrap();
    let run = |crs: &str| {
        let out = common::spherecal()
            .args(["site", "import"])
            .arg(&csv)
            .args(["--radius", "0.19", "--crs", crs, "--force"])
            .args(["--height", "ellipsoidal", "-o"])
            .arg(csv.with_extension("toml"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{crs}");
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    for line in common::python(&script, "pyproj").lines() {
        let v: Vec<&str> = line.split_whitespace().collect();
        let said = run(&format!("EPSG:{}", v[0]));
        assert!(said.contains("is a compound CRS"), "{said}");
        assert!(
            said.contains(&format!("--crs EPSG:{} --vertical-crs EPSG:{}", v[1], v[2])),
            "{said}"
        );
    }
    let said = run("EPSG:5703");
    assert!(
        said.contains("is a vertical CRS") && said.contains("--vertical-crs EPSG:5703"),
        "{said}"
    );
    for code in ["EPSG:99999", "EPSG:60000"] {
        assert!(run(code).contains("not a CRS this build knows"), "{code}");
    }
    assert!(run("EPSG:x1").contains("expected EPSG:<code> (digits)"));
}

/// A surveyor's first calibration (issue 47): table1's spheres surveyed in UTM 30N and exported
/// by a spreadsheet in a decimal-comma locale (a byte-order mark, `;`, decimal commas, CRLF,
/// `Point;Easting;Northing;Elevation`), projected by pyproj; `site import` (its heights said
/// ellipsoidal) gives back the survey's centres; `calibrate` on the synthesised VN-200 stream
/// (noise-free but for the VLP-16's beam: it states no accuracy) without a navigation model takes the VN-200's
/// metre-level default, which cannot determine the vertical lever arm: held at its a-priori
/// value and named, the rest calibrated, exit 3; with `--ins white` declared (the noise-free scenario)
/// claims within its targets: exit 0, `targets.met`, and the report files its provenance
/// (the site's CRS, the CSV-made site's SHA-256) and the mounting as a ROS transform.
#[test]
fn a_spreadsheet_survey_imported_then_calibrated() {
    let mut s = spherecal_tools::config::scenario::Scenario::load("table1").unwrap();
    // A real VLP-16's beam (the imported site says nothing of it: the model's is taken).
    s.lidar.beam_divergence_mrad = [3.0, 1.5];
    let dir = common::tmp("site-import", "first-calibration");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let synth_site = Site::load(&dir.join("site.toml")).unwrap();
    let pts: Vec<(f64, f64, f64)> = synth_site
        .sphere
        .iter()
        .map(|p| (p.lat_deg, p.lon_deg, p.h_m))
        .collect();
    let xy = pyproj_forward(32630, &pts);
    let comma = |v: f64| format!("{v:.4}").replace('.', ",");
    let mut csv = String::from("\u{feff}Point;Easting;Northing;Elevation\r\n");
    for (sp, ((x, y), p)) in synth_site.sphere.iter().zip(xy.iter().zip(&pts)) {
        csv += &format!("{};{};{};{}\r\n", sp.id, comma(*x), comma(*y), comma(p.2));
    }
    let csv_path = dir.join("survey.csv");
    std::fs::write(&csv_path, csv).unwrap();
    let a = synth_site.apriori.clone();
    let apriori = format!(
        "{},{},{},{},{},{}",
        a.boresight_deg[0],
        a.boresight_deg[1],
        a.boresight_deg[2],
        a.lever_arm_m[0],
        a.lever_arm_m[1],
        a.lever_arm_m[2]
    );
    let import = |extra: &[&str], out: &std::path::Path| {
        let mut cmd = common::spherecal();
        cmd.args(["site", "import"])
            .arg(&csv_path)
            .args(["--crs", "EPSG:32630", "--height", "ellipsoidal"])
            .args(["--radius", "0.19", "--margin", "3", "--force"])
            .args(["--apriori", &apriori])
            .args(extra)
            .arg("-o")
            .arg(out);
        common::stdout_of(&mut cmd)
    };
    let bare = dir.join("imported.toml");
    let said = import(&[], &bare);
    assert!(said.contains("navigation errors: none declared"), "{said}");
    let imported = Site::load(&bare).unwrap();
    for (a, b) in imported.sphere.iter().zip(&synth_site.sphere) {
        assert!((a.lat_deg - b.lat_deg).abs() < 1e-8 && (a.lon_deg - b.lon_deg).abs() < 1e-8);
        assert!((a.h_m - b.h_m).abs() < 1e-4);
    }
    let calibrate = |site: &std::path::Path, report: &std::path::Path| {
        common::calibrate_survey(&dir, site, report)
    };
    let o = calibrate(&bare, &dir.join("bare.json"));
    let t = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    // The metre-level default cannot determine the lever arm's height: held at its a-priori
    // value and named, the others calibrated, exit 3 (its sigma misses every target).
    assert_eq!(o.status.code(), Some(3), "{t}");
    assert!(
        t.contains(
            "HELD: z at its a-priori value -1.759 m +- 500 mm: the data do not determine it"
        ),
        "{t}"
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("bare.json")).unwrap()).unwrap();
    assert_eq!(r["held"], serde_json::json!(["z"]), "{}", r["held"]);
    assert_eq!(r["targets"]["met"], false);
    assert!(
        r.get("mounting_prior").is_none(),
        "the holds are not measurements"
    );
    // Honest: each parameter within 3 of its sigma of the truth, the held one too.
    let truth = s.mount.truth.deg_m().0;
    let got = [
        &r["boresight_deg"]["roll"],
        &r["boresight_deg"]["pitch"],
        &r["boresight_deg"]["heading"],
        &r["lever_arm_m"]["x"],
        &r["lever_arm_m"]["y"],
        &r["lever_arm_m"]["z"],
    ];
    let sg = [
        &r["sigma"]["boresight_deg"]["roll"],
        &r["sigma"]["boresight_deg"]["pitch"],
        &r["sigma"]["boresight_deg"]["heading"],
        &r["sigma"]["lever_arm_m"]["x"],
        &r["sigma"]["lever_arm_m"]["y"],
        &r["sigma"]["lever_arm_m"]["z"],
    ];
    for i in 0..6 {
        let (g, e) = (got[i].as_f64().unwrap(), sg[i].as_f64().unwrap());
        assert!(
            (g - truth[i]).abs() < 3.0 * e,
            "{i}: {g} vs {} ({e})",
            truth[i]
        );
    }
    let white = dir.join("white.toml");
    assert!(import(&["--ins", "white"], &white).contains("preset \"white\" (--ins)"));
    let report = dir.join("white.json");
    let o = calibrate(&white, &report);
    let t = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(o.status.code(), Some(0), "{t}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["targets"]["met"], true, "{}", r["targets"]);
    assert_eq!(r["provenance"]["site"]["crs"], "EPSG:32630");
    assert_eq!(
        r["provenance"]["site"]["file"]["sha256"]
            .as_str()
            .map(str::len),
        Some(64)
    );
    assert!(r["conventions"]["ros2_static_transform"]
        .as_str()
        .is_some_and(|c| c.contains("--frame-id base_link --child-frame-id velodyne")));
    common::assert_within(
        &common::report_deg_m(&r),
        &s.mount.truth.deg_m().0,
        1e-3,
        "imported site",
    );
    std::fs::remove_dir_all(dir).unwrap();
}

/// The sample survey the README walks (`examples/survey-utm30n.csv`: a spreadsheet's export
/// with a byte-order mark, `;`, decimal commas and CRLF) imports to table1's spheres, so that
/// `calibrate` of `synth --scenario table1-noisy` with it calibrates as the README says.
#[test]
fn the_readme_sample_survey_is_table1s() {
    let s = spherecal_tools::config::scenario::Scenario::load("table1").unwrap();
    let dir = common::tmp("site-import", "sample");
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let want = Site::load(&dir.join("site.toml")).unwrap();
    let out = dir.join("my-site.toml");
    let mut cmd = common::spherecal();
    cmd.args(["site", "import"])
        .arg(common::repo_root().join("examples/survey-utm30n.csv"))
        .args([
            "--crs",
            "EPSG:32630",
            "--height",
            "ellipsoidal",
            "--margin",
            "3",
        ])
        .args(["--apriori", "181.787,-42.423,2.431,1.312,-1.205,-1.759"])
        .arg("-o")
        .arg(&out);
    let said = common::stdout_of(&mut cmd);
    assert!(said.contains("2 spheres"), "{said}");
    let got = Site::load(&out).unwrap();
    for (a, b) in got.sphere.iter().zip(&want.sphere) {
        assert_eq!(a.id, b.id);
        // 0.1 mm in the CSV: 1e-9 deg.
        assert!((a.lat_deg - b.lat_deg).abs() < 2e-9, "{a:?} {b:?}");
        assert!((a.lon_deg - b.lon_deg).abs() < 2e-9, "{a:?} {b:?}");
        assert!((a.h_m - b.h_m).abs() < 1e-4 && a.radius_m == b.radius_m);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

//! Alignment, georeferencing and windows end to end on the synthetic table1 survey in the
//! paper's idealised world (`table1-bare`: the spheres on thin poles and nothing else, so that
//! the windows at the truth hold exactly the sphere returns), with the VN-200 stream and with an
//! SBET trajectory; INS gaps; the LAS output read by another reader.

use crate::common;

use spherecal::align::window::Observation;
use spherecal::frames::{roll_pitch_heading, rotation};
use spherecal::georef::Mount;
use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::config::site::Site;
use spherecal_tools::georef::LasFrame;
use spherecal_tools::pipeline::{targets, Inputs, InsInput};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// table1, synthesised once for all tests of this file.
fn table1() -> &'static (PathBuf, Vec<u64>) {
    static DIR: OnceLock<(PathBuf, Vec<u64>)> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("spherecal-georef-{}", std::process::id()));
        let s = Scenario::load("table1-bare").unwrap();
        let truth = spherecal_tools::synth::synth(&s, &dir).unwrap();
        (dir, truth.points_per_sphere)
    })
}

fn truth_mount() -> Mount {
    Mount::new(
        [
            179.5f64.to_radians(),
            (-44.9f64).to_radians(),
            1.2f64.to_radians(),
        ],
        [1.5, -1.24, -1.36],
    )
}

fn inputs(dir: &Path, ins: InsInput, mount: Mount, margin: f64) -> Inputs {
    Inputs {
        pcap: dir.join("lidar.pcap").into(),
        model: None,
        ins,
        site: Site::load(&dir.join("site.toml")).unwrap(),
        mount,
        margin,
        max_gap_ns: 50_000_000,
        time_offset_ns: 0,
        keep_untracked_ins: false,
        accuracy: None,
        ports: Default::default(),
        lidar_topic: None,
        exclude: Vec::new(),
        hesai: None,
        ouster: None,
    }
}

fn observations(inp: &Inputs) -> (spherecal_tools::pipeline::RunStats, Vec<Vec<Observation>>) {
    spherecal_tools::calibrate::collect(inp).unwrap()
}

/// Distance of each observation, georeferenced with `mount`, from its sphere's surface.
fn residuals(inp: &Inputs, obs: &[Vec<Observation>], mount: &Mount) -> Vec<Vec<f64>> {
    let (_, t) = targets(&inp.site);
    obs.iter()
        .enumerate()
        .map(|(i, v)| {
            v.iter()
                .map(|o| (o.georef(mount) - t[i].center).norm() - t[i].radius)
                .collect()
        })
        .collect()
}

#[test]
fn truth_windows_hold_exactly_the_sphere_returns_within_a_millimetre() {
    let (dir, truth) = table1();
    let inp = inputs(
        dir,
        InsInput::Vn200(dir.join("ins.bin").into()),
        truth_mount(),
        0.01,
    );
    let (stats, obs) = observations(&inp);
    assert_eq!(
        stats.align.rollovers, 1,
        "table1 crosses the top of the hour"
    );
    assert_eq!(
        stats.align.window.before_history
            + stats.align.window.after_history
            + stats.align.window.in_gap,
        0
    );
    let counts: Vec<u64> = obs.iter().map(|v| v.len() as u64).collect();
    assert_eq!(
        &counts, truth,
        "window counts = truth.json points_per_sphere"
    );
    let r = residuals(&inp, &obs, &truth_mount());
    let worst = r.iter().flatten().fold(0f64, |a, &e| a.max(e.abs()));
    eprintln!(
        "truth windows: {counts:?}, worst |residual| {:.3} mm",
        worst * 1e3
    );
    assert!(worst < 1.2e-3, "worst residual {worst}");
}

#[test]
fn apriori_windows_still_catch_every_sphere_return() {
    let (dir, truth) = table1();
    let site = Site::load(&dir.join("site.toml")).unwrap();
    let a = Mount::new(
        site.apriori.boresight_deg.map(f64::to_radians),
        site.apriori.lever_arm_m,
    );
    let inp = inputs(
        dir,
        InsInput::Vn200(dir.join("ins.bin").into()),
        a,
        site.apriori.window_margin_m,
    );
    let (_, obs) = observations(&inp);
    // Re-georeferenced with the truth, the sphere returns among them are all there.
    let r = residuals(&inp, &obs, &truth_mount());
    for (i, v) in r.iter().enumerate() {
        let on = v.iter().filter(|e| e.abs() < 1.2e-3).count() as u64;
        assert_eq!(
            on,
            truth[i],
            "sphere {i}: {} windowed, {on} on the sphere",
            v.len()
        );
        assert!(
            v.len() as u64 > on,
            "the a-priori windows also hold clutter (the tripod)"
        );
    }
}

#[test]
fn sbet_trajectory_gives_the_same_windows() {
    let (dir, truth) = table1();
    // Write an SBET of the same truth: 200 Hz, wander angle 0.3 rad, from the scenario.
    let s = Scenario::load("table1-bare").unwrap();
    let (passes, objects) = (s.passes(), s.objects());
    let w = s.world(&[], &passes, &objects);
    let mut bytes = Vec::new();
    let (week, _) = s.start().week_tow_ns();
    for j in 0..(65.0 * 200.0) as i64 {
        let t = spherecal::time::GpsTime(s.start().0 - 1_000_000_000 + j * 5_000_000);
        let st = w.trajectory.state(w.t_of(t));
        let g = w.site.to_geodetic(&st.position);
        let local = w.site.from_local_level(g.lat, g.lon).transpose()
            * rotation(st.rph[0], st.rph[1], st.rph[2]);
        let [roll, pitch, heading] = roll_pitch_heading(&local);
        let rec = spherecal_hal::sbet::SbetRecord {
            tow_s: t.week_tow_ns().1 as f64 * 1e-9,
            lat: g.lat,
            lon: g.lon,
            h: g.h,
            roll,
            pitch,
            platform_heading: heading + 0.3,
            wander: 0.3,
        };
        bytes.extend_from_slice(&rec.emit());
    }
    let sbet = dir.join("traj.sbet");
    std::fs::write(&sbet, bytes).unwrap();
    // The week comes from the capture's RMC date.
    assert_eq!(
        spherecal_tools::pipeline::week_from_capture(&dir.join("lidar.pcap").into(), 18),
        Some(week as u16)
    );
    let inp = inputs(dir, InsInput::Sbet(sbet.into(), None), truth_mount(), 0.01);
    let (_, obs) = observations(&inp);
    let counts: Vec<u64> = obs.iter().map(|v| v.len() as u64).collect();
    assert_eq!(&counts, truth);
    let worst = residuals(&inp, &obs, &truth_mount())
        .iter()
        .flatten()
        .fold(0f64, |a, &e| a.max(e.abs()));
    assert!(worst < 1.2e-3, "{worst}");
}

#[test]
fn ins_gap_is_counted_not_bridged() {
    let (dir, _) = table1();
    // Cut 0.4 s of VN-200 frames (60 bytes each at 200 Hz) while the first pass sees S1.
    let bytes = std::fs::read(dir.join("ins.bin")).unwrap();
    let frame = 60;
    let (a, b) = (frame * 600, frame * 680);
    let mut cut = bytes[..a].to_vec();
    cut.extend_from_slice(&bytes[b..]);
    let ins = dir.join("ins_gap.bin");
    std::fs::write(&ins, cut).unwrap();
    let inp = inputs(dir, InsInput::Vn200(ins.into()), truth_mount(), 0.01);
    let (stats, obs) = observations(&inp);
    // 0.4 s of returns are refused (the gap exceeds 50 ms), nothing else.
    assert!(stats.align.window.in_gap > 0, "{:?}", stats.align.window);
    assert_eq!(
        stats.align.window.georeferenced + stats.align.window.in_gap,
        stats.align.window.points
    );
    let worst = residuals(&inp, &obs, &truth_mount())
        .iter()
        .flatten()
        .fold(0f64, |a, &e| a.max(e.abs()));
    assert!(worst < 1.2e-3);
}

#[test]
fn las_file_reads_back() {
    let (dir, _) = table1();
    let las = dir.join("cloud.las");
    let inp = inputs(
        dir,
        InsInput::Vn200(dir.join("ins.bin").into()),
        truth_mount(),
        0.01,
    );
    let (stats, _, _) =
        spherecal_tools::georef::georef(&inp, Some((&las, LasFrame::Local)), None).unwrap();
    // With the las crate.
    let mut r = las::Reader::from_path(&las).unwrap();
    let n = r.header().number_of_points();
    assert_eq!(n, stats.align.window.georeferenced);
    let data = r.read_points(1000).unwrap();
    let pts: Vec<las::Point> = data.points().map(|p| p.unwrap()).collect();
    assert!(pts.iter().all(|p| p.gps_time.is_some()));
    // With laspy, an independent reader (installed by scripts/test.sh).
    let script = format!(
        "import laspy, numpy\nf = laspy.read({:?})\nprint(f.header.point_count, f.header.version, f.header.point_format.id)\nprint(float(f.x[0]), float(f.y[0]), float(f.z[0]), float(f.gps_time[0]), int(numpy.count_nonzero(f.user_data)))",
        las.to_str().unwrap()
    );
    let text = common::python(&script, "laspy");
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), format!("{n} 1.4 6"));
    let v: Vec<f64> = lines
        .next()
        .unwrap()
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    let p0 = &pts[0];
    assert!((v[0] - p0.x).abs() < 1e-4 && (v[1] - p0.y).abs() < 1e-4 && (v[2] - p0.z).abs() < 1e-4);
    assert!((v[3] - p0.gps_time.unwrap()).abs() < 1e-6);
    assert_eq!(v[4] as u64, stats.align.window.windowed.iter().sum::<u64>());
}

/// The projected LAS lands on the map: laspy finds its CRS (UTM 30N for a site near Brest
/// without its own), and each point taken through pyproj to WGS84, ECEF and east-north-up at
/// the site origin (numpy, by hand) is the local-frame LAS's point to 1 mm; the extra bytes,
/// date, GUID and software are there.
#[test]
fn las_lands_on_the_map() {
    let (dir, _) = table1();
    let inp = inputs(
        dir,
        InsInput::Vn200(dir.join("ins.bin").into()),
        truth_mount(),
        0.01,
    );
    let (map, local) = (dir.join("map.las"), dir.join("local.las"));
    spherecal_tools::georef::georef(&inp, Some((&map, LasFrame::Projected)), None).unwrap();
    let (stats, _, _) =
        spherecal_tools::georef::georef(&inp, Some((&local, LasFrame::Local)), None).unwrap();
    let o = &inp.site.origin;
    let script = format!(
        r#"import laspy, numpy as np
from pyproj import Transformer
m = laspy.read({map:?}); l = laspy.read({local:?})
crs = m.header.parse_crs()
print(crs.to_2d().to_epsg(), [a.name for a in crs.axis_info][2].replace(" ", "_"), m.header.creation_date is not None, m.header.uuid.int != 0, m.header.generating_software.startswith("spherecal"))
k = np.arange(0, len(m.points), 7)
lon, lat, h = Transformer.from_crs(crs, "EPSG:4979", always_xy=True).transform(np.asarray(m.x)[k], np.asarray(m.y)[k], np.asarray(m.z)[k])
ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
X = np.array(ecef.transform(lon, lat, h))
X0 = np.array(ecef.transform({lon0}, {lat0}, {h0}))
p, q = np.radians({lat0}), np.radians({lon0})
R = np.array([[-np.sin(q), np.cos(q), 0], [-np.sin(p)*np.cos(q), -np.sin(p)*np.sin(q), np.cos(p)], [np.cos(p)*np.cos(q), np.cos(p)*np.sin(q), np.sin(p)]])
enu = R @ (X - X0[:, None])
d = np.abs(enu - np.array([np.asarray(l.x)[k], np.asarray(l.y)[k], np.asarray(l.z)[k]]))
print(len(k), float(d.max()))
w = np.asarray(m.window); r = np.asarray(m.residual)
print(int(np.count_nonzero(w)), int(np.asarray(m.laser).max()), float(np.nanmax(np.abs(r[w > 0]))), bool(np.all(np.isnan(r[w == 0]))))"#,
        map = map.to_str().unwrap(),
        local = local.to_str().unwrap(),
        lon0 = o.lon_deg,
        lat0 = o.lat_deg,
        h0 = o.h_m,
    );
    let text = common::python(&script, "laspy and pyproj");
    let lines: Vec<Vec<&str>> = text
        .lines()
        .map(|l| l.split_whitespace().collect())
        .collect();
    // EPSG:32630 with ellipsoidal heights (the compound CRS's vertical part), read as one 3D
    // CRS.
    assert_eq!(
        lines[0],
        ["32630", "Ellipsoidal_height", "True", "True", "True"],
        "{text}"
    );
    let (n, worst): (usize, f64) = (lines[1][0].parse().unwrap(), lines[1][1].parse().unwrap());
    assert!(n > 400 && worst < 1e-3, "{n} points, worst {worst} m");
    let windowed: u64 = lines[2][0].parse().unwrap();
    assert_eq!(windowed, stats.align.window.windowed.iter().sum::<u64>());
    assert_eq!(lines[2][1], "15", "laser ids 0-15");
    let r: f64 = lines[2][2].parse().unwrap();
    let margin_and_radius = 0.01
        + inp
            .site
            .sphere
            .iter()
            .map(|s| s.radius_m)
            .fold(0.0, f64::max);
    assert!(r <= margin_and_radius + 1e-6, "residual {r}");
    assert_eq!(lines[2][3], "True", "no residual outside the windows");
}

/// A VN-200 sending its attitude as a Quaternion instead of YawPitchRoll (the same survey, the
/// same samples): the same windows, every return within 1 mm. With the quaternion read as
/// NED -> body (its transpose) the returns move by metres and the windows empty.
#[test]
fn quaternion_attitude_gives_the_same_windows_as_yaw_pitch_roll() {
    let (dir, truth) = table1();
    let mut s = Scenario::load("table1-bare").unwrap();
    s.ins.attitude = "quaternion".into();
    let qdir = dir.join("quaternion");
    spherecal_tools::synth::synth_ins(&s, &qdir).unwrap();
    let run = |ins: PathBuf| {
        let inp = inputs(dir, InsInput::Vn200(ins.into()), truth_mount(), 0.01);
        let (_, obs) = observations(&inp);
        (inp, obs)
    };
    let (_, ypr) = run(dir.join("ins.bin"));
    let (inp, quat) = run(qdir.join("ins.bin"));
    let counts: Vec<u64> = quat.iter().map(|v| v.len() as u64).collect();
    assert_eq!(&counts, truth, "quaternion windows = truth.json");
    let mut worst = 0f64;
    for (a, b) in ypr.iter().zip(&quat) {
        assert_eq!(a.len(), b.len());
        for (oa, ob) in a.iter().zip(b) {
            assert_eq!(
                (oa.time, oa.channel, oa.block),
                (ob.time, ob.channel, ob.block)
            );
            worst = worst.max((oa.georef(&truth_mount()) - ob.georef(&truth_mount())).norm());
        }
    }
    eprintln!("quaternion vs yaw/pitch/roll: worst {:.4} mm", worst * 1e3);
    assert!(worst < 1e-3, "{worst}");
    let r = residuals(&inp, &quat, &truth_mount());
    assert!(r.iter().flatten().all(|e| e.abs() < 1.2e-3));
}

//! Helpers shared by the end-to-end tests.

use std::path::{Path, PathBuf};

/// The repository root (tests run with the crate's manifest dir as cwd).
pub fn repo_root() -> PathBuf {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    if here.join("Cargo.lock").exists()
        || here.join("src/lib.rs").exists() && here.join("hal").exists()
    {
        here
    } else {
        here.parent().expect("crate dir has a parent").to_path_buf()
    }
}

/// A file under `tests/data` (real captures; origins and licences in its README). Panics
/// (fails the test loudly) when it is missing: these tests must never skip silently.
pub fn test_data(rel: &str) -> PathBuf {
    let p = repo_root().join("tests").join("data").join(rel);
    assert!(p.exists(), "missing test data {}", p.display());
    p
}

/// The `spherecal` binary of this build.
pub fn spherecal() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_spherecal"))
}

/// `spherecal calibrate` of the survey `synth` wrote to `dir` (its `lidar.pcap` and VN-200
/// `ins.bin`) with the site `site`, its report to `report` (removed first).
pub fn calibrate_survey(dir: &Path, site: &Path, report: &Path) -> std::process::Output {
    let _ = std::fs::remove_file(report);
    spherecal()
        .arg("calibrate")
        .arg("--pcap")
        .arg(dir.join("lidar.pcap"))
        .arg("--ins")
        .arg(dir.join("ins.bin"))
        .arg("--site")
        .arg(site)
        .arg("--report")
        .arg(report)
        .output()
        .unwrap()
}

/// A path in a per-process scratch folder for test `group` (created).
pub fn tmp(group: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("spherecal-{group}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// WGS 84 (longitude, latitude) points projected into EPSG `epsg` by pyproj (x, y: easting,
/// northing in the CRS's unit).
pub fn pyproj_forward(epsg: u32, lon_lat: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let list: Vec<String> = lon_lat
        .iter()
        .map(|p| format!("({}, {})", p[0], p[1]))
        .collect();
    let script = format!(
        "from pyproj import Transformer\nt = Transformer.from_crs('EPSG:4326', 'EPSG:{epsg}', always_xy=True)\nfor lon, lat in [{}]:\n    x, y = t.transform(lon, lat)\n    print(repr(x), repr(y))",
        list.join(", ")
    );
    python(&script, "pyproj")
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split(' ').map(|s| s.parse().unwrap()).collect();
            [v[0], v[1]]
        })
        .collect()
}

/// Run a Python script (an independent reference: laspy, pyproj, installed by
/// scripts/test.sh); it must succeed. Returns its stdout.
pub fn python(script: &str, needs: &str) -> String {
    let out = std::process::Command::new("python3")
        .args(["-c", script])
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "{needs} must be installed (scripts/test.sh does it): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Run a command; it must succeed (or claim a calibration that misses its targets: exit 3).
/// Returns its stdout.
pub fn stdout_of(cmd: &mut std::process::Command) -> String {
    let out = cmd.output().unwrap();
    // 3: a calibration claimed whose sigmas miss the default targets (the noisy scenarios').
    assert!(
        matches!(out.status.code(), Some(0 | 3)),
        "{cmd:?}: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// `--pcap DIR/lidar.pcap --ins DIR/ins.bin --site DIR/site.toml` (as `synth` writes them).
pub fn survey_args(dir: &std::path::Path) -> Vec<std::ffi::OsString> {
    vec![
        "--pcap".into(),
        dir.join("lidar.pcap").into(),
        "--ins".into(),
        dir.join("ins.bin").into(),
        "--site".into(),
        dir.join("site.toml").into(),
    ]
}

/// Every one of the six parameters (roll, pitch, heading [deg], x, y, z [m]) within `tol` of
/// the truth, naming the first that is not.
/// A JSON report's six: boresight roll, pitch, heading [deg], lever arm x, y, z [m].
pub fn report_deg_m(r: &serde_json::Value) -> [f64; 6] {
    let b = &r["boresight_deg"];
    let l = &r["lever_arm_m"];
    [
        b["roll"].as_f64().unwrap(),
        b["pitch"].as_f64().unwrap(),
        b["heading"].as_f64().unwrap(),
        l["x"].as_f64().unwrap(),
        l["y"].as_f64().unwrap(),
        l["z"].as_f64().unwrap(),
    ]
}

pub fn assert_within(got: &[f64; 6], want: &[f64; 6], tol: f64, what: &str) {
    for i in 0..6 {
        assert!(
            (got[i] - want[i]).abs() <= tol,
            "{what}: {} {} vs {} (error {:.2e})",
            spherecal::georef::NAMES[i],
            got[i],
            want[i],
            got[i] - want[i]
        );
    }
}

/// The inputs of a survey `synth` wrote to `dir` (its VN-200 stream and site), from the site's
/// a-priori values.
pub fn survey_inputs(dir: &std::path::Path) -> spherecal_tools::pipeline::Inputs {
    spherecal_tools::pipeline::Inputs::apriori(
        dir.join("lidar.pcap").into(),
        spherecal_tools::pipeline::InsInput::Vn200(dir.join("ins.bin").into()),
        spherecal_tools::config::site::Site::load(&dir.join("site.toml")).unwrap(),
    )
}

/// How far beyond a sphere's window a Monte Carlo trial's packets are kept [m].
pub const WINDOW_EXTRA_M: f64 = 0.5;

/// The Monte Carlo trials' trace of `s`: traced once, only the data packets that hold windowed
/// returns (and two neighbours) kept — the rest cannot change a calibration
/// (`plan::every_windowed_return_of_a_full_trial_is_simulated`); and how many those are.
pub fn trial_cache(
    s: &spherecal_tools::config::scenario::Scenario,
) -> (spherecal_tools::synth::TraceCache, usize, usize) {
    let mut cache = spherecal_tools::synth::trace(s).unwrap();
    let (keep, n) =
        spherecal_tools::montecarlo::windowed_packets(s, &cache, WINDOW_EXTRA_M, 2).unwrap();
    let all = keep.len();
    cache.keep_only(keep);
    (cache, n, all)
}

/// The simulated VN-200 stream, byte by byte, as the tests edit it (independent of the crate's
/// framer and CRC).
pub mod vn200 {
    /// CRC-16/XMODEM (poly 0x1021, init 0), bit by bit (VectorNav's "16-bit CRC"): the
    /// test's own, independent of the crate's.
    pub fn crc16(bytes: &[u8]) -> u16 {
        let mut c: u16 = 0;
        for &b in bytes {
            c ^= u16::from(b) << 8;
            for _ in 0..8 {
                c = if c & 0x8000 != 0 {
                    (c << 1) ^ 0x1021
                } else {
                    c << 1
                };
            }
        }
        c
    }

    /// The synthetic VN-200 frame (what the boards configure): sync 0xFA, groups 0x31 (Common,
    /// Attitude, INS), fields 0x104B (TimeStartup u64, TimeGps u64, YPR 3 f32, Position 3 f64,
    /// InsStatus u16), 0x0100 (YprU 3 f32), 0x0200 (PosU f32), CRC.
    pub const FRAME: usize = 80;
    /// Its header: sync, groups, the three groups' fields.
    pub const HEADER: [u8; 8] = [0xFA, 0x31, 0x4B, 0x10, 0x00, 0x01, 0x00, 0x02];
    /// Where TimeGps, the height and InsStatus sit in it.
    pub const TIME_AT: usize = 16;
    pub const HEIGHT_AT: usize = 52;
    pub const STATUS_AT: usize = 60;

    /// The frames' offsets in the stream.
    pub fn frames(ins: &[u8]) -> Vec<usize> {
        let mut out = Vec::new();
        let mut i = 0;
        while i + FRAME <= ins.len() {
            if ins[i..i + 8] == HEADER && crc16(&ins[i + 1..i + FRAME]) == 0 {
                out.push(i);
                i += FRAME;
            } else {
                i += 1;
            }
        }
        out
    }

    pub fn frame_time_s(ins: &[u8], at: usize) -> f64 {
        u64::from_le_bytes(ins[at + TIME_AT..at + TIME_AT + 8].try_into().unwrap()) as f64 * 1e-9
    }

    /// The frame at `at` with its CRC made again.
    pub fn seal(ins: &mut [u8], at: usize) {
        let c = crc16(&ins[at + 1..at + FRAME - 2]);
        ins[at + FRAME - 2..at + FRAME].copy_from_slice(&c.to_be_bytes());
    }

    pub fn set_status(ins: &mut [u8], at: usize, status: u16) {
        ins[at + STATUS_AT..at + STATUS_AT + 2].copy_from_slice(&status.to_le_bytes());
        seal(ins, at);
    }

    /// The frames at `at` as a unit configured by the older boards sends them (the Common
    /// group only, without TimeStartup: fields 0x104A, 52 bytes), back to back.
    pub fn without_startup(ins: &[u8], at: &[usize]) -> Vec<u8> {
        let mut out = Vec::with_capacity(at.len() * 52);
        for &i in at {
            let mut f = vec![0xFA, 0x01, 0x4A, 0x10];
            // The Common payload after TimeStartup: TimeGps to InsStatus.
            f.extend_from_slice(&ins[i + TIME_AT..i + STATUS_AT + 2]);
            let c = crc16(&f[1..]);
            f.extend_from_slice(&c.to_be_bytes());
            out.extend_from_slice(&f);
        }
        out
    }
}

/// A calibration was claimed: exit 0 (its sigmas within the targets) or 3 (claimed, but the
/// sigmas miss the targets: the noisy scenarios' against the default 0.01 deg / 5 mm).
pub fn claimed(o: &std::process::Output) -> bool {
    matches!(o.status.code(), Some(0 | 3))
}

/// A command's standard output and error, together.
pub fn text(o: &std::process::Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The solve with a helper on a second core (`Scratch::with_helper`, as `calibrate` runs it)
/// is the solve on one: the same solution to the last bit, the same verdict for every return
/// (the pontoon's three spheres split in groups of one and two; under a navigation model,
/// each evaluation's rows made in two halves side by side).
pub fn same_on_two_cores(
    inp: &spherecal_tools::pipeline::Inputs,
    settings: &spherecal::calib::Settings,
) {
    use spherecal_tools::session::scratch::Scratch;
    let (_, obs) = spherecal_tools::calibrate::collect(inp).unwrap();
    let (t, ids) = spherecal_tools::calibrate::site_targets(inp);
    let solve = |mut scratch: Scratch| {
        let mut obs = obs.clone();
        let (sol, _) = spherecal_tools::session::solve_report_in(
            &t,
            &ids,
            &mut obs,
            &inp.mount.params(),
            settings,
            &mut scratch,
            &mut (),
        );
        let verdicts: Vec<Vec<(i64, u8, u8)>> = obs
            .iter()
            .map(|v| {
                v.iter()
                    .map(|o| (o.time.0, o.channel, o.work.verdict))
                    .collect()
            })
            .collect();
        (format!("{sol:?}"), verdicts)
    };
    let (one, two) = (
        solve(Scratch::for_settings(settings)),
        solve(Scratch::for_settings(settings).with_helper()),
    );
    assert!(one.0.contains("converged: true"), "{}", one.0);
    assert!(one.0 == two.0, "one core:\n{}\ntwo:\n{}", one.0, two.0);
    assert!(one.1 == two.1, "the verdicts differ");
}

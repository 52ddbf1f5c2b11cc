//! Every error names the file (or the option) and the reason, with exit code 2, and an output
//! that cannot be written is refused before the work starts: the audit of issue 14's "honest
//! diagnostics", on a synthetic survey and files that are not what they are given as.

use crate::common;

use spherecal_tools::config::scenario::Scenario;
use std::ffi::OsString;
use std::path::Path;

/// Run `spherecal args`: it must exit 2 with every one of `want` in its standard error (and
/// nothing on standard output when `silent`: refused before any work).
fn refused(args: &[OsString], want: &[&str], silent: bool) {
    let out = common::spherecal().args(args).output().unwrap();
    let (so, se) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert_eq!(out.status.code(), Some(2), "{args:?}: {so}{se}");
    for w in want {
        assert!(se.contains(w), "{args:?}: {w:?} not in {se:?}");
    }
    if silent {
        assert!(so.is_empty(), "{args:?}: work done before refusing: {so}");
    }
}

/// `calibrate --pcap PCAP TRAJ FILE --site SITE EXTRA...`.
fn calibrate(pcap: &Path, traj: &str, file: &Path, site: &Path, extra: &[&str]) -> Vec<OsString> {
    let mut v: Vec<OsString> = vec!["calibrate".into(), "--pcap".into(), pcap.into()];
    v.extend([traj.into(), file.into(), "--site".into(), site.into()]);
    v.extend(extra.iter().map(OsString::from));
    v
}

#[test]
fn errors_name_the_file_and_the_reason() {
    let dir = common::tmp("errors", "survey");
    spherecal_tools::synth::synth(&Scenario::load("table1-bare").unwrap(), &dir).unwrap();
    let text = dir.join("notes.txt");
    std::fs::write(&text, "these are not sensor data\n").unwrap();
    let (pcap, ins, site) = (
        dir.join("lidar.pcap"),
        dir.join("ins.bin"),
        dir.join("site.toml"),
    );
    let nodir = "/nonexistent-spherecal-dir/out.html";

    // An output whose folder does not exist: refused at once, naming the option and folder.
    for flag in ["--html", "--report", "--plot", "--las", "--returns"] {
        refused(
            &calibrate(&pcap, "--ins", &ins, &site, &[flag, nodir]),
            &[flag, "/nonexistent-spherecal-dir", "does not exist"],
            true,
        );
    }
    // Text given as an SBET, a capture given as an SBET: what was read and what it looks like.
    let week = ["--gps-week", "2300", "--trajectory-datum", "WGS84"];
    refused(
        &calibrate(&pcap, "--sbet", &text, &site, &week),
        &["notes.txt", "no valid SBET record", "looks like text"],
        false,
    );
    refused(
        &calibrate(&pcap, "--sbet", &pcap, &site, &week),
        &[
            "lidar.pcap",
            "not an SBET file",
            "byte",
            "looks like a pcap capture",
        ],
        false,
    );
    // Text given as the VN-200 stream, to `ins` and to `calibrate`.
    refused(
        &["ins".into(), text.clone().into()],
        &[
            "notes.txt",
            "no VN-200 binary frame or sentence",
            "looks like text",
        ],
        false,
    );
    refused(
        &calibrate(&pcap, "--ins", &text, &site, &[]),
        &["notes.txt", "no VN-200 pose", "looks like text"],
        false,
    );
    // Windows that catch nothing say why: a site thousands of km from the data (its spheres
    // and origin moved 38 deg south), and an a-priori mounting given in radians.
    let far = dir.join("far.toml");
    let moved: String = std::fs::read_to_string(&site)
        .unwrap()
        .lines()
        .map(|l| match l.strip_prefix("lat_deg = ") {
            Some(v) => format!("lat_deg = {}\n", v.parse::<f64>().unwrap() - 38.0),
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(&far, moved).unwrap();
    for (site, extra, want) in [
        (
            &far,
            &[][..],
            "the trajectory never came within the LiDAR's 100 m of them (closest: S1 4136 km at GPS",
        ),
        (
            &site,
            &["--init", "3.17,-0.74,0.042,1.3,-1.2,-1.76"][..],
            "the trajectory passed within the LiDAR's reach (S1 ",
        ),
    ] {
        let report = dir.join("refused.json");
        let mut args = calibrate(&pcap, "--ins", &ins, site, extra);
        args.extend(["--report".into(), report.clone().into()]);
        let out = common::spherecal().args(args).output().unwrap();
        let so = String::from_utf8_lossy(&out.stdout);
        assert_eq!(out.status.code(), Some(1), "{so}");
        assert!(so.contains("NOT CONVERGED: no return in the windows of S1, S2"), "{so}");
        assert!(so.contains("(ended: a round found fewer than two spheres)"), "{so}");
        assert!(so.contains(want), "{want:?} in {so}");
        // The refusal's report.json, its sigmas and RMS written as null (JSON has no NaN),
        // reads back whole: the reason, and NaN where nothing was estimated.
        let text = std::fs::read_to_string(&report).unwrap();
        assert!(text.contains("\"rms_m\": null"), "{text}");
        let r = spherecal_tools::report::Report::parse(&text).unwrap();
        assert!(!r.converged);
        assert!(r.reason.unwrap().contains("no return in the windows of S1, S2"));
        assert!(r.rms_m.is_nan() && r.sigma.deg_m().iter().all(|s| s.is_nan()));
        assert!(r.correlation.iter().flatten().all(|c| c.is_nan()));
    }
    // A site file that is not TOML: the file and the line.
    refused(
        &calibrate(&pcap, "--ins", &ins, &text, &[]),
        &["notes.txt", "line 1"],
        true,
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Inputs that cannot be right are refused with exit 2 before a calibration is claimed (issue
/// 25): two captures of the same minute given together (named), non-finite or negative numbers
/// for options, two spheres with one id or none; and a time offset search wider than the data
/// is kept to where the clocks overlap and says so.
#[test]
fn impossible_inputs_are_refused() {
    let a = common::tmp("errors", "a");
    let b = common::tmp("errors", "b");
    // Two passes (the refusals need valid files, not a whole survey).
    let mut bare = Scenario::load("table1-bare").unwrap();
    bare.trajectory.pass.truncate(2);
    spherecal_tools::synth::synth(&bare, &a).unwrap();
    let mut other = bare.clone();
    other.mount.truth.lever_arm_m[0] += 0.2;
    spherecal_tools::synth::synth(&other, &b).unwrap();
    let (pcap, ins, site) = (a.join("lidar.pcap"), a.join("ins.bin"), a.join("site.toml"));
    // The same minute twice, from two surveys: the second file named with the first.
    let mut args = calibrate(&pcap, "--ins", &ins, &site, &[]);
    args.insert(3, b.join("lidar.pcap").into());
    let b_pcap = b.join("lidar.pcap").display().to_string();
    let a_pcap = pcap.display().to_string();
    let out = common::spherecal().args(&args).output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let se = String::from_utf8_lossy(&out.stderr);
    assert!(se.contains("the captures cover the same time"), "{se}");
    assert!(se.contains(&a_pcap) && se.contains(&b_pcap), "{se}");
    // The same INS data twice (the other survey's stream covers the same minute).
    let mut args = calibrate(&pcap, "--ins", &ins, &site, &[]);
    args.insert(5, b.join("ins.bin").into());
    refused(
        &args,
        &["the INS time goes back", "holds the same time twice"],
        false,
    );
    // Numbers.
    for (opt, v, why) in [
        ("--time-offset", "nan", "expected a finite number"),
        ("--time-offset", "inf", "expected a finite number"),
        ("--search-time-offset", "nan", "expected a finite number"),
        ("--search-time-offset", "-1", "expected a number >= 0"),
    ] {
        refused(
            &calibrate(&pcap, "--ins", &ins, &site, &[opt, v]),
            &[opt, why],
            true,
        );
    }
    for args in [
        vec!["montecarlo", "--scenario", "table1-bare", "--trials", "0"],
        vec![
            "montecarlo",
            "--scenario",
            "table1-bare",
            "--angle-noise-deg",
            "-1",
        ],
        vec![
            "plan",
            "--scenario",
            "table1-bare",
            "--target-sigma-m",
            "nan",
        ],
        vec![
            "georef",
            "--pcap",
            "x",
            "--ins",
            "y",
            "--site",
            "z",
            "--max-gap-ms",
            "0",
        ],
    ] {
        let args: Vec<OsString> = args.iter().map(OsString::from).collect();
        refused(&args, &["invalid value"], true);
    }
    // Sphere ids: two alike, or an empty one.
    let text = std::fs::read_to_string(&site).unwrap();
    for (to, why) in [
        ("id = \"S1\"", "\"S1\" is also sphere[0]'s"),
        ("id = \"\"", "expected a name"),
    ] {
        let bad = a.join("bad-site.toml");
        std::fs::write(&bad, text.replacen("id = \"S2\"", to, 1)).unwrap();
        refused(
            &calibrate(&pcap, "--ins", &ins, &bad, &[]),
            &["sphere[1].id", why],
            true,
        );
    }
    // A search of +-100 s over the two passes (36 s of data; each start of the search is a
    // whole collection and solve): kept to the overlap, and it runs.
    let r = a.join("search.json");
    let mut args = calibrate(
        &pcap,
        "--ins",
        &ins,
        &site,
        &["--search-time-offset", "100"],
    );
    args.extend(["--report".into(), r.clone().into()]);
    let out = common::spherecal().args(&args).output().unwrap();
    let so = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{so}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&r).unwrap()).unwrap();
    let s = rep["time_offset_search"].as_array().unwrap();
    let (lo, hi) = (
        s[0]["start_s"].as_f64().unwrap(),
        s[s.len() - 1]["start_s"].as_f64().unwrap(),
    );
    // The LiDAR's span within the INS's (which starts and ends ~1 s beyond it): offsets of
    // +-(half the span + ~1 s) keep half the LiDAR data inside.
    let half = 0.5 * bare.duration_s();
    eprintln!(
        "searched {lo} .. {hi} s over {} s of data",
        bare.duration_s()
    );
    assert!(
        (lo + half).abs() < 2.0 && (hi - half).abs() < 2.0 && (lo + hi).abs() < 0.6,
        "{lo} {hi} (half the span {half})"
    );
    assert!(so.contains("time offset searched from"), "{so}");
    assert!(rep["time_offset_s"].as_f64().unwrap().abs() < 1e-3);
    std::fs::remove_dir_all(a).unwrap();
    std::fs::remove_dir_all(b).unwrap();
}

/// Outputs are whole or absent (issue 26): a folder that takes no file and a folder given as a
/// file are refused before any work; an output that fails after the calibration (here the LAS,
/// over a file-size limit) is said after the printed result, which stands, with exit 2 and
/// nothing half-written; `synth` interrupted with Ctrl-C leaves no file of its run.
#[test]
fn outputs_are_whole_or_absent() {
    use nix::sys::signal::{kill, Signal};
    use nix::unistd::Pid;
    let dir = common::tmp("outputs", "survey");
    spherecal_tools::synth::synth(&Scenario::load("table1-bare").unwrap(), &dir).unwrap();
    let (pcap, ins, site) = (
        dir.join("lidar.pcap"),
        dir.join("ins.bin"),
        dir.join("site.toml"),
    );
    // /sys takes no new file, even for root.
    refused(
        &calibrate(
            &pcap,
            "--ins",
            &ins,
            &site,
            &["--las", "/sys/spherecal.las"],
        ),
        &[
            "--las /sys/spherecal.las",
            "cannot write in the folder /sys",
        ],
        true,
    );
    refused(
        &calibrate(
            &pcap,
            "--ins",
            &ins,
            &site,
            &["--report", dir.to_str().unwrap()],
        ),
        &["--report", "is a folder, not a file"],
        true,
    );

    // A late failure: the shell lets files grow to 64 blocks (write() then fails with EFBIG
    // instead of killing the process); the report fits, the LAS does not.
    let out_dir = common::tmp("outputs", "late");
    std::fs::create_dir_all(&out_dir).unwrap();
    let (report, las) = (out_dir.join("r.json"), out_dir.join("x.las"));
    let mut args = calibrate(&pcap, "--ins", &ins, &site, &[]);
    args.extend(["--report".into(), report.clone().into()]);
    args.extend(["--las".into(), las.clone().into()]);
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 64; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_spherecal"))
        .args(&args)
        .output()
        .unwrap();
    let (so, se) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert_eq!(out.status.code(), Some(2), "{so}{se}");
    assert!(
        so.contains("boresight") || so.contains("roll"),
        "the result first: {so}"
    );
    assert!(so.contains("converged"), "the verdict first: {so}");
    assert!(
        se.contains("the result above stands, but an output was not written")
            && se.contains("x.las"),
        "{se}"
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert!(r["converged"].as_bool().unwrap(), "{r}");
    let left: Vec<_> = std::fs::read_dir(&out_dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, vec!["r.json".to_string()], "nothing half-written");

    // Ctrl-C during synth: exit 130, no file of the run, no temporary (synthesised, not copied
    // from the test run's cache).
    let s_dir = common::tmp("outputs", "interrupted");
    let child = common::spherecal()
        .args(["synth", "--scenario", "table1-bare", "--out"])
        .arg(&s_dir)
        .env_remove(spherecal_tools::synth::cache::VAR)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let partial = s_dir.join(".lidar.pcap.partial");
    let t0 = std::time::Instant::now();
    while std::fs::metadata(&partial).map_or(0, |m| m.len()) < 4 << 20 {
        assert!(t0.elapsed().as_secs() < 60, "synth never wrote 4 MB");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).unwrap();
    let out = child.wait_with_output().unwrap();
    let se = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{se}");
    assert!(
        se.contains("interrupted: removed ") && se.contains("lidar.pcap (unfinished)"),
        "{se}"
    );
    let left: Vec<_> = std::fs::read_dir(&s_dir).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");

    // Ctrl-C during calibrate's LAS, its report.json already written: both are gone, and the
    // message names them (one run's outputs are all there or none).
    let t_dir = common::tmp("outputs", "table1");
    spherecal_tools::synth::synth(&Scenario::load("table1").unwrap(), &t_dir).unwrap();
    let c_dir = common::tmp("outputs", "calibrate-interrupted");
    std::fs::create_dir_all(&c_dir).unwrap();
    let (report, las, html) = (
        c_dir.join("r.json"),
        c_dir.join("x.las"),
        c_dir.join("r.html"),
    );
    let (pcap1, ins1, site1) = (
        t_dir.join("lidar.pcap"),
        t_dir.join("ins.bin"),
        t_dir.join("site.toml"),
    );
    let mut args = calibrate(&pcap1, "--ins", &ins1, &site1, &[]);
    for (k, p) in [("--report", &report), ("--las", &las), ("--html", &html)] {
        args.extend([k.into(), p.clone().into()]);
    }
    let child = common::spherecal()
        .args(&args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let partial = c_dir.join(".x.las.partial");
    let t0 = std::time::Instant::now();
    while std::fs::metadata(&partial).map_or(0, |m| m.len()) < 1 << 20 {
        assert!(
            t0.elapsed().as_secs() < 120,
            "calibrate never wrote 1 MB of LAS"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).unwrap();
    let out = child.wait_with_output().unwrap();
    let se = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{se}");
    assert!(
        se.contains(&report.display().to_string())
            && se.contains(&format!("{} (unfinished)", las.display())),
        "{se}"
    );
    let left: Vec<_> = std::fs::read_dir(&c_dir).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
    let _ = std::fs::remove_dir_all(&c_dir);
    let _ = std::fs::remove_dir_all(&t_dir);
    for d in [dir, out_dir, s_dir] {
        std::fs::remove_dir_all(d).unwrap();
    }
}

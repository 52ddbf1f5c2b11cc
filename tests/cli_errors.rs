//! Every error names the file (or the option) and the reason, with exit code 2, and an output
//! that cannot be written is refused before the work starts: the audit of issue 14's "honest
//! diagnostics", on a synthetic survey and files that are not what they are given as.

mod common;

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
    let week = ["--gps-week", "2300"];
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
    // A site file that is not TOML: the file and the line.
    refused(
        &calibrate(&pcap, "--ins", &ins, &text, &[]),
        &["notes.txt", "line 1"],
        true,
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

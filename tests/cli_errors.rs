//! Every error names the file (or the option) and the reason, with exit code 2, and an output
//! that cannot be written is refused before the work starts: the audit of issue 14's "honest
//! diagnostics", on a synthetic survey and files that are not what they are given as.

mod common;

use spherecal_tools::config::scenario::Scenario;
use std::path::Path;

/// Run `spherecal args`: it must exit 2 with every one of `want` in its standard error (and
/// nothing on standard output when `silent`: refused before any work).
fn refused(args: &[&std::ffi::OsStr], want: &[&str], silent: bool) {
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

#[test]
fn errors_name_the_file_and_the_reason() {
    let dir = common::tmp("errors", "survey");
    spherecal_tools::synth::synth(&Scenario::load("table1-bare").unwrap(), &dir).unwrap();
    let text = dir.join("notes.txt");
    std::fs::write(&text, "these are not sensor data\n").unwrap();
    let p = |x: &Path| x.as_os_str().to_owned();
    let (pcap, ins, site) = (
        p(&dir.join("lidar.pcap")),
        p(&dir.join("ins.bin")),
        p(&dir.join("site.toml")),
    );
    let nodir = p(Path::new("/nonexistent-spherecal-dir/out.html"));
    let s = |x: &str| std::ffi::OsString::from(x);

    // An output whose folder does not exist: refused at once, naming the option and folder.
    for flag in ["--html", "--report", "--plot", "--las", "--returns"] {
        refused(
            &[
                &s("calibrate"),
                &s("--pcap"),
                &pcap,
                &s("--ins"),
                &ins,
                &s("--site"),
                &site,
                &s(flag),
                &nodir,
            ],
            &[flag, "/nonexistent-spherecal-dir", "does not exist"],
            true,
        );
    }
    // Text given as an SBET, a capture given as an SBET: what was read and what it looks like.
    refused(
        &[
            &s("calibrate"),
            &s("--pcap"),
            &pcap,
            &s("--sbet"),
            &p(&text),
            &s("--gps-week"),
            &s("2300"),
            &s("--site"),
            &site,
        ],
        &["notes.txt", "no valid SBET record", "looks like text"],
        false,
    );
    refused(
        &[
            &s("calibrate"),
            &s("--pcap"),
            &pcap,
            &s("--sbet"),
            &pcap,
            &s("--gps-week"),
            &s("2300"),
            &s("--site"),
            &site,
        ],
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
        &[&s("ins"), &p(&text)],
        &[
            "notes.txt",
            "no VN-200 binary frame or sentence",
            "looks like text",
        ],
        false,
    );
    refused(
        &[
            &s("calibrate"),
            &s("--pcap"),
            &pcap,
            &s("--ins"),
            &p(&text),
            &s("--site"),
            &site,
        ],
        &["notes.txt", "no VN-200 pose", "looks like text"],
        false,
    );
    // A site file that is not TOML: the file and the line.
    refused(
        &[
            &s("calibrate"),
            &s("--pcap"),
            &pcap,
            &s("--ins"),
            &ins,
            &s("--site"),
            &p(&text),
        ],
        &["notes.txt", "line 1"],
        true,
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

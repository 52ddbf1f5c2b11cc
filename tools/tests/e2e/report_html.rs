//! The HTML report and the `--plot` SVG end to end on synthetic table1: self-contained (no
//! script, no link, nothing fetched), the numbers of the JSON report in its tables, five figures
//! per sphere, the refusal's reason first when refused; the SVG parsed by Python's XML parser
//! (an independent reader). The figures' geometry (1:1 cross-sections, histograms on their own
//! axes) is tested in `plot.rs`; the page was looked at in headless Chromium (docs/history/issue-14-surveyor-io.md).

use crate::common;

use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::report::Report;
use std::path::{Path, PathBuf};

fn run(dir: &Path, name: &str, extra: &[&str]) -> (String, Report, PathBuf) {
    let (html, json, svg) = (
        dir.join(format!("{name}.html")),
        dir.join(format!("{name}.json")),
        dir.join(format!("{name}.svg")),
    );
    let out = common::spherecal()
        .arg("calibrate")
        .args(common::survey_args(dir))
        .arg("--html")
        .arg(&html)
        .arg("--report")
        .arg(&json)
        .arg("--plot")
        .arg(&svg)
        .args(extra)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        text.contains("report (HTML)"),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let page = std::fs::read_to_string(&html).unwrap();
    let rep = Report::load(&json).unwrap();
    (page, rep, svg)
}

/// Nothing is fetched: no script, stylesheet link, image or frame source, CSS url(); the only
/// "http" is the SVG namespace name.
fn assert_self_contained(page: &str) {
    let lower = page.to_lowercase();
    for bad in ["<script", "<link", "<img", "<iframe", "src=", "url("] {
        assert!(!lower.contains(bad), "the page holds {bad}");
    }
    let http = lower.matches("http").count();
    let ns = lower.matches("http://www.w3.org/2000/svg").count();
    assert_eq!(http, ns, "only the SVG namespace may name a URL");
}

#[test]
fn html_report_converged_and_refused() {
    let dir = common::tmp("html", "table1");
    let s = Scenario::load("table1-bare").unwrap();
    spherecal_tools::synth::synth(&s, &dir).unwrap();

    let (page, rep, svg) = run(&dir, "ok", &[]);
    assert!(rep.converged);
    assert_self_contained(&page);
    assert!(page.contains("<b>Converged.</b>"));
    assert!(!page.contains("Refused"));
    // A cover sheet first: the verdict, the mounting against the targets, the checks, the
    // inputs with their SHA-256 and the command; the details after it.
    let (cover, details) = page.split_once("<h2>Details</h2>").unwrap();
    assert!(cover.contains("<h2>Cover sheet</h2>") && cover.contains("<b>Converged.</b>"));
    assert!(
        cover.contains(&format!("<b>{:.5}</b> deg", rep.boresight_deg.roll)),
        "{cover}"
    );
    assert!(cover.contains("<th>target</th>") && cover.contains("Checks: residual RMS"));
    let prov = rep.provenance.as_ref().unwrap();
    for i in &prov.inputs {
        assert!(
            cover.contains(&format!("SHA-256 {}...", &i.sha256[..16])),
            "{cover}"
        );
    }
    assert!(
        cover.contains("<code>") && cover.contains("calibrate"),
        "{cover}"
    );
    assert!(!details.contains("<h2>Cover sheet</h2>"));
    // The parameters as the JSON has them, with their sigma and change from the start.
    for (v, start) in [
        (rep.boresight_deg.roll, rep.start["roll"]),
        (rep.lever_arm_m.z, rep.start["z"]),
    ] {
        assert!(page.contains(&format!("<b>{v:.5}</b>")), "{v:.5}");
        assert!(page.contains(&format!("<td>{:.5}</td>", v - start)));
    }
    assert!(page.contains(&format!("<td>{:.5}</td>", rep.sigma.lever_arm_m.x)));
    // The correlation matrix labelled, rows and columns.
    for l in ["roll", "pitch", "heading", "x", "y", "z", "time_offset"] {
        assert!(page.contains(&format!("<th>{l}</th>")), "{l}");
        assert!(page.contains(&format!("<th class=\"l\">{l}</th>")), "{l}");
    }
    // The inputs and the time span in UTC (the scenario starts at 10:59:25 UTC).
    assert!(page.contains("lidar.pcap"));
    assert!(page.contains("2024-06-12 10:59:2"), "the span in UTC");
    let span = rep.inputs.as_ref().unwrap().lidar_span_utc.clone().unwrap();
    assert!(span.0.starts_with("2024-06-12 10:59:2"), "{span:?}");
    assert!(span.1.starts_with("2024-06-12 11:00:"), "{span:?}");
    // Five figures per sphere found, each histogram captioned with its own RMS.
    let found = rep.per_sphere.iter().filter(|p| p.found).count();
    assert_eq!(found, 2);
    assert_eq!(page.matches("<svg").count(), 5 * found);
    for p in &rep.per_sphere {
        assert!(
            page.contains(&format!(
                "{}: after, RMS {:.2} mm",
                p.id,
                p.rms_after_m * 1e3
            )),
            "{}",
            p.id
        );
        assert!(page.contains(&format!("{}: before (1:1)", p.id)));
        assert!(page.contains(&format!("{}: after (1:1)", p.id)));
    }
    // The SVG file: well-formed XML with the same ten figures nested.
    let n = common::python(
        &format!(
            "import xml.etree.ElementTree as E\nr=E.parse({:?}).getroot()\nprint(sum(1 for e in r.iter() if e.tag.endswith('svg')) - 1)",
            svg.display().to_string()
        ),
        "python3",
    );
    assert_eq!(n.trim(), (5 * found).to_string());

    // The rig's board: its name, vessel and operator on the cover and in the provenance, its
    // targets when the site gives none (the sim board's, loosened here).
    let board = dir.join("board.toml");
    let text = std::fs::read_to_string(common::repo_root().join("boards/sim.toml")).unwrap();
    let text = text
        .replace(
            "name = \"sim\"",
            "name = \"sim\"\nvessel = \"RV Tideway\"\noperator = \"crew\"",
        )
        .replace("target_sigma_deg = 0.01", "target_sigma_deg = 0.5");
    std::fs::write(&board, text).unwrap();
    let b = board.display().to_string();
    let (page, rep, _) = run(&dir, "board", &["--board", &b, "--operator", "A. Surveyor"]);
    let (cover, _) = page.split_once("<h2>Details</h2>").unwrap();
    assert!(
        cover.contains("RV Tideway (board sim (") && cover.contains("A. Surveyor"),
        "{cover}"
    );
    let pl = rep.provenance.as_ref().unwrap().platform.clone().unwrap();
    assert_eq!(pl.vessel.as_deref(), Some("RV Tideway"));
    assert_eq!(
        pl.operator.as_deref(),
        Some("A. Surveyor"),
        "--operator wins"
    );
    // The board file's hash as Python's hashlib gives it.
    let sha = common::python(
        &format!(
            "import hashlib\nprint(hashlib.sha256(open({:?}, 'rb').read()).hexdigest())",
            b
        ),
        "python3",
    );
    assert_eq!(pl.board.unwrap().sha256, sha.trim());
    // Each input's hash (made on a thread beside the solve) as hashlib gives it, with its span.
    let inputs = &rep.provenance.as_ref().unwrap().inputs;
    assert_eq!(inputs.len(), 2, "{inputs:?}");
    for i in inputs {
        let p = std::path::Path::new(&i.path);
        let p = if p.is_absolute() {
            p.to_path_buf()
        } else {
            dir.join(p)
        };
        let sha = common::python(
            &format!(
                "import hashlib\nprint(hashlib.sha256(open({:?}, 'rb').read()).hexdigest())",
                p.display().to_string()
            ),
            "python3",
        );
        assert_eq!(i.sha256, sha.trim(), "{}", i.path);
        assert_eq!(i.bytes, std::fs::metadata(&p).unwrap().len());
        assert!(i.gps_span_s.is_some_and(|(a, b)| b > a), "{i:?}");
    }
    let t = rep.targets.as_ref().unwrap();
    assert_eq!(
        (t.sigma_deg, t.source.as_str()),
        (Some(0.5), "the board's [calibration]")
    );

    // Refused: a held time offset 0.3 s wrong. The reason comes first, escaped, before the
    // numbers (which are where the solver stopped).
    let (page, rep, _) = run(
        &dir,
        "refused",
        &["--hold-time-offset", "--time-offset", "0.3"],
    );
    assert!(!rep.converged);
    assert_self_contained(&page);
    let reason = rep.reason.unwrap();
    let at = page.find("Refused: no calibration is claimed.").unwrap();
    let why = page
        .find(&spherecal_tools::html::escape(&reason))
        .expect("the reason on the page");
    assert!(at < why && why < page.find("<h2>Mounting").unwrap());
    std::fs::remove_dir_all(&dir).unwrap();
}

//! `spherecal demo` (and a bare `spherecal`): table1 synthesised and calibrated from the
//! paper's erroneous start, beside the truth.

use super::{claimed, fail};
use std::path::PathBuf;
use std::process::ExitCode;

/// Synthesise table1, calibrate from the paper's erroneous start, show the result beside the
/// truth.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where the survey's files and the report go (kept, so the other commands can be tried
    /// on them).
    #[arg(long, default_value = "spherecal-demo")]
    pub out: PathBuf,
}

impl Default for Args {
    fn default() -> Self {
        Self {
            out: PathBuf::from("spherecal-demo"),
        }
    }
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    let dir = a.out;
    let s = match crate::config::scenario::Scenario::load("table1") {
        Ok(s) => s,
        Err(e) => return fail("demo", e),
    };
    sayln!(
        "spherecal demo: the paper's Table 1 survey, synthesised into {}",
        dir.display()
    );
    let t0 = std::time::Instant::now();
    let truth = match crate::synth::synth(&s, &dir) {
        Ok(t) => t,
        Err(e) => return fail("demo", e),
    };
    sayln!(
        "synthesised {:.1} s of scanning ({} packets, {} VN-200 frames, {:?} sphere returns) in {:.2} s",
        s.duration_s(),
        truth.data_packets,
        truth.ins_frames,
        truth.points_per_sphere,
        t0.elapsed().as_secs_f64()
    );
    sayln!("calibrating from the paper's erroneous a-priori values ...");
    let t6 = s.mount.truth.deg_m().0;
    let truth7 = [
        t6[0],
        t6[1],
        t6[2],
        t6[3],
        t6[4],
        t6[5],
        s.true_time_offset_s(),
    ];
    let out = crate::survey::Outputs {
        report: Some(dir.join("report.json")),
        html: Some(dir.join("report.html")),
        ..Default::default()
    };
    let res = crate::survey::run_calibrate(
        crate::survey::Survey::synth_dir(&dir),
        None,
        Default::default(),
        &out,
        Some(truth7),
    );
    let code = match res {
        Ok(c) => {
            say!("{}", c.text);
            if let Some(code) = super::outputs_failed("demo", &c.output_errors) {
                return code;
            }
            sayln!(
                "report: {} (open {} in a browser)",
                dir.join("report.json").display(),
                dir.join("report.html").display()
            );
            sayln!(
                "the survey's files are in {d}/ (lidar.pcap, ins.bin, site.toml, truth.json); try\n  spherecal calibrate --pcap {d}/lidar.pcap --ins {d}/ins.bin --site {d}/site.toml",
                d = dir.display()
            );
            claimed(c.converged, c.met)
        }
        Err(e) => fail("demo", e),
    };
    code
}

//! `spherecal synth --scenario NAME|FILE --out DIR` / `--print-scenario NAME`.

use super::fail;
use crate::config::scenario::{Scenario, BUILTIN};
use std::path::PathBuf;
use std::process::ExitCode;

/// Simulate a survey: write lidar.pcap, ins.bin, site.toml and truth.json.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A built-in scenario name (table1, table1-noisy, table1-real, pontoon, drone, ...) or a
    /// scenario TOML file.
    #[arg(long, required_unless_present = "print_scenario")]
    pub scenario: Option<String>,
    /// Output folder.
    #[arg(long, required_unless_present = "print_scenario")]
    pub out: Option<PathBuf>,
    /// The LiDAR model to simulate (vlp16, puck-hires, hdl32e, vlp32c; xt16, xt32: a Hesai
    /// PandarXT, its angle correction file written as corrections.csv), instead of the
    /// scenario's `[lidar] model`.
    #[arg(long, value_parser = super::parse_scanner)]
    pub model: Option<spherecal::sim::Scanner>,
    /// The INS to simulate, instead of the scenario's `[ins] kind`: `vn200`, or `posmv` (an
    /// Applanix POS MV: its UDP datagrams in lidar.pcap, its logged stream ins.posmv, and the
    /// same samples post-processed: sbet_ins.out with smrmsg_ins.out).
    #[arg(long, value_parser = ["vn200", "posmv"])]
    pub ins: Option<String>,
    /// Print a built-in scenario as TOML (to edit) and exit.
    #[arg(long, value_name = "NAME", conflicts_with_all = ["scenario", "out"])]
    pub print_scenario: Option<String>,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    if let Some(name) = a.print_scenario {
        return match BUILTIN.iter().find(|b| b.0 == name) {
            Some((_, text)) => {
                say!("{text}");
                ExitCode::SUCCESS
            }
            None => {
                let names: Vec<&str> = BUILTIN.iter().map(|b| b.0).collect();
                fail(
                    "synth",
                    format!("no built-in scenario {name:?} (have: {})", names.join(", ")),
                )
            }
        };
    }
    let (Some(scenario), Some(out)) = (a.scenario, a.out) else {
        return fail("synth", "--scenario and --out are required");
    };
    let mut s = match Scenario::load(&scenario) {
        Ok(s) => s,
        Err(e) => return fail("synth", e),
    };
    if let Some(m) = a.model {
        s.lidar.model = m.key().into();
    }
    if let Some(k) = a.ins {
        s.ins.kind = k;
    }
    crate::output::remove_partial_on_interrupt();
    let t0 = std::time::Instant::now();
    match crate::synth::synth(&s, &out) {
        Ok(t) => {
            sayln!(
                "{}: {:.1} s of scanning with a {}, {} data + {} position packets, {} VN-200 frames, {} rays in {:.2} s",
                s.name,
                s.duration_s(),
                s.scanner().unwrap_or_default().name(),
                t.data_packets,
                t.position_packets,
                t.ins_frames,
                t.rays_traced,
                t0.elapsed().as_secs_f64()
            );
            sayln!(
                "points per sphere: {:?} (clutter: {})",
                t.points_per_sphere,
                t.clutter_points
            );
            for (j, &n) in t.points_per_sphere.iter().enumerate() {
                if n < crate::synth::FEW_RETURNS {
                    let why = crate::synth::why_unseen(&s, j).unwrap_or_else(|| {
                        format!(
                            "{}: in range and on a laser, not hidden at its centre: grazed only, or between the firings",
                            s.sphere[j].id
                        )
                    });
                    sayln!("warning: {n} returns on {why}");
                }
            }
            sayln!(
                "wrote {}/{{{}}}",
                out.display(),
                crate::synth::file_names(&s).join(", ")
            );
            ExitCode::SUCCESS
        }
        Err(e) => fail("synth", e),
    }
}

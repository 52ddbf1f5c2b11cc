//! A full calibration (Nelder-Mead + re-windowing + LM + covariance + centre fits) on table1's
//! windows, from the paper's erroneous start. `cargo bench -p spherecal-tools --bench calibrate`

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use spherecal::calib::{solve, Settings};
use spherecal_tools::pipeline::{Inputs, InsInput};
use spherecal_tools::scenario::Scenario;

fn bench(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("spherecal-bench-cal-{}", std::process::id()));
    spherecal_tools::synth::synth(&Scenario::load("table1").unwrap(), &dir).unwrap();
    let site = spherecal_tools::site::Site::load(&dir.join("site.toml")).unwrap();
    let inp = Inputs::apriori(
        dir.join("lidar.pcap"),
        InsInput::Vn200(dir.join("ins.bin")),
        site,
    );
    let b0 = inp.mount.params();
    let (_, obs) = spherecal_tools::calibrate::collect(&inp).unwrap();
    let (targets, _) = spherecal_tools::calibrate::site_targets(&inp);
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!(
        "windows: {:?} returns",
        obs.iter().map(Vec::len).collect::<Vec<_>>()
    );
    let mut g = c.benchmark_group("calibrate");
    g.sample_size(30);
    let mut scratch = spherecal_tools::calibrate::Scratch::default();
    g.bench_function("table1_nm_lm_from_paper_start", |b| {
        b.iter_batched(
            || obs.clone(),
            |mut o| {
                let mut s: Vec<&mut [spherecal::window::Observation]> =
                    o.iter_mut().map(|v| v.as_mut_slice()).collect();
                solve(
                    &targets,
                    &mut s,
                    &b0,
                    &Settings::default(),
                    &mut scratch.workspace(),
                )
                .b
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! The calibration at the quay (table1: ~2.07 M returns, 193 k of them in the sphere windows,
//! 75x more clutter than sphere returns), from the paper's erroneous start, against the
//! georeferencing pass over the same files. `cargo bench -p spherecal-tools --bench calibrate`
//!
//! - `georef_pass`: the pipeline (pcap + VN-200 files -> decode -> align -> georeference every
//!   return -> windows), what `spherecal georef` does before writing a cloud;
//! - `calibrate_from_files`: the whole `calibrate`: the pipeline (windows only) and the solve
//!   (sphere extraction, detect-and-solve rounds, LM, covariance, per-sphere and per-pass
//!   reports);
//! - `solve`: the solve alone on the collected windows;
//! - `calibrate_from_files_table1_real`, `solve_table1_real`: the same on `table1-real` under
//!   its site's navigation model (issue 28: within 2x of table1's).

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkGroup, Criterion};
use spherecal::align::window::Observation;
use spherecal::calib::{solve, Settings};
use spherecal_tools::calibrate::{collect, site_targets};
use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::pipeline::{run, BatchMsg, Inputs, InsInput};
use spherecal_tools::session::scratch::Scratch;
use spherecal_tools::session::solve_report_in;

fn bench(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("spherecal-bench-cal-{}", std::process::id()));
    spherecal_tools::synth::synth(&Scenario::load("table1").unwrap(), &dir).unwrap();
    let site = spherecal_tools::config::site::Site::load(&dir.join("site.toml")).unwrap();
    let inp = Inputs::apriori(
        dir.join("lidar.pcap").into(),
        InsInput::Vn200(dir.join("ins.bin").into()),
        site,
    );
    let b0 = inp.mount.params();
    let (_, obs) = collect(&inp).unwrap();
    let (targets, ids) = site_targets(&inp);
    eprintln!(
        "windows: {:?} returns",
        obs.iter().map(Vec::len).collect::<Vec<_>>()
    );
    let mut g = c.benchmark_group("calibrate");
    g.sample_size(20);
    g.bench_function("georef_pass", |b| {
        b.iter(|| {
            let mut n = 0u64;
            let mut each = |_: &spherecal::align::window::GeoPoint| n += 1;
            let each: Option<&mut dyn FnMut(&spherecal::align::window::GeoPoint)> = Some(&mut each);
            run(&inp, each, |rx: crossbeam_channel::Receiver<BatchMsg>| {
                rx.iter().count()
            })
            .unwrap();
            n
        })
    });
    g.bench_function("calibrate_from_files", |b| {
        b.iter(|| {
            let (_, mut obs) = collect(&inp).unwrap();
            let s = Settings::default();
            let mut two = Scratch::for_settings(&s).with_helper();
            let (_, rep) = solve_report_in(&targets, &ids, &mut obs, &b0, &s, &mut two, &mut ());
            assert!(rep.converged);
            rep.boresight_deg.pitch
        })
    });
    let (mut one, mut two) = (Scratch::default(), Scratch::default().with_helper());
    let s = Settings::default();
    bench_solve(&mut g, "solve", &obs, &targets, &b0, &s, &mut one);
    bench_solve(&mut g, "solve_two_cores", &obs, &targets, &b0, &s, &mut two);
    // table1-real: the site declares the navigation model; the settings come from it.
    let real = dir.join("real");
    spherecal_tools::synth::synth(&Scenario::load("table1-real").unwrap(), &real).unwrap();
    let site = spherecal_tools::config::site::Site::load(&real.join("site.toml")).unwrap();
    let settings = spherecal_tools::session::settings_for(&site, Default::default(), true, 3.0);
    assert!(settings.nav.is_some());
    let inp = Inputs::apriori(
        real.join("lidar.pcap").into(),
        InsInput::Vn200(real.join("ins.bin").into()),
        site,
    );
    let (_, obs) = collect(&inp).unwrap();
    let (targets, ids) = site_targets(&inp);
    g.bench_function("calibrate_from_files_table1_real", |b| {
        b.iter(|| {
            let (_, mut obs) = collect(&inp).unwrap();
            let mut two = Scratch::for_settings(&settings).with_helper();
            let (_, rep) =
                solve_report_in(&targets, &ids, &mut obs, &b0, &settings, &mut two, &mut ());
            assert!(rep.converged);
            rep.boresight_deg.pitch
        })
    });
    bench_solve(
        &mut g,
        "solve_table1_real",
        &obs,
        &targets,
        &b0,
        &settings,
        &mut one,
    );
    let (t, b) = (&targets, &b0);
    bench_solve(
        &mut g,
        "solve_table1_real_two_cores",
        &obs,
        t,
        b,
        &settings,
        &mut two,
    );
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

/// The solve alone on copies of `obs`, in `scratch` (one core, or two with its helper).
fn bench_solve(
    g: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    obs: &[Vec<Observation>],
    targets: &[spherecal::align::window::Target],
    b0: &spherecal::georef::Params,
    settings: &Settings,
    scratch: &mut Scratch,
) {
    g.bench_function(name, |b| {
        b.iter_batched(
            || obs.to_vec(),
            |mut o| {
                let mut s: Vec<&mut [Observation]> =
                    o.iter_mut().map(|v| v.as_mut_slice()).collect();
                solve(targets, &mut s, b0, settings, &mut scratch.workspace()).b
            },
            BatchSize::LargeInput,
        )
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! The simulator's speed: six 24-second passes (the authors' MATLAB ray tracer: ~250 s) past the
//! quay of table1 (deck, wall, sheds, people, vessel parts: ~2 M returns a minute) traced and
//! written as lidar.pcap + ins.bin + labels; `ideal` with an ideal beam, `footprint` with the
//! VLP-16's 3 x 1.5 mrad footprint (mixed pixels) and noise (table1-noisy's sensor).
//! `cargo bench -p spherecal-tools --bench synth`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use spherecal_tools::config::scenario::{Scenario, BUILTIN};

fn six_passes(name: &str) -> Scenario {
    let text = BUILTIN.iter().find(|b| b.0 == name).unwrap().1;
    let i = text.find("[[trajectory.pass]]").unwrap();
    let scenery = &text[i + text[i..].find("[water]").unwrap()..];
    let mut s = text[..i].to_string();
    for k in 0..6 {
        let (n0, heading) = if k % 2 == 0 {
            (-20.0, 0.0)
        } else {
            (40.0, 180.0)
        };
        s.push_str(&format!(
            "[[trajectory.pass]]\nstart_ne_m = [{n0}, {}]\nheading_deg = {heading}\nspeed_mps = 2.5\nduration_s = 24.0\n",
            8.0 + 4.0 * k as f64
        ));
    }
    s.push_str(scenery);
    let s = s.replace("turn_s = 2.5", "turn_s = 0.0");
    Scenario::from_toml(&s).unwrap()
}

fn bench(c: &mut Criterion) {
    let ideal = six_passes("table1");
    let footprint = six_passes("table1-noisy");
    assert_eq!(ideal.duration_s(), 144.0);
    let dir = std::env::temp_dir().join(format!("spherecal-bench-synth-{}", std::process::id()));
    let mut g = c.benchmark_group("synth");
    g.sample_size(10);
    g.throughput(Throughput::Elements(
        (144.0 / (12.0 * 110.592e-6)) as u64 * 384,
    ));
    g.bench_function("six_24s_passes_quay_ideal", |b| {
        b.iter(|| spherecal_tools::synth::synth(&ideal, &dir).unwrap())
    });
    g.bench_function("six_24s_passes_quay_footprint", |b| {
        b.iter(|| spherecal_tools::synth::synth(&footprint, &dir).unwrap())
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);

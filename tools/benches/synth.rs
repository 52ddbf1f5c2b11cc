//! The simulator's speed: six 24-second passes (the authors' MATLAB ray tracer: ~250 s) traced
//! and written as lidar.pcap + ins.bin. `cargo bench -p spherecal-tools --bench synth`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use spherecal_tools::scenario::{Scenario, BUILTIN};

fn six_passes() -> Scenario {
    let text = BUILTIN[0].1;
    let i = text.find("[[trajectory.pass]]").unwrap();
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
    let s = s.replace("turn_s = 2.5", "turn_s = 0.0");
    Scenario::from_toml(&s).unwrap()
}

fn bench(c: &mut Criterion) {
    let s = six_passes();
    assert_eq!(s.duration_s(), 144.0);
    let dir = std::env::temp_dir().join(format!("spherecal-bench-synth-{}", std::process::id()));
    let mut g = c.benchmark_group("synth");
    g.sample_size(10);
    g.throughput(Throughput::Elements(
        (144.0 / (12.0 * 110.592e-6)) as u64 * 384,
    ));
    g.bench_function("six_24s_passes_rays", |b| {
        b.iter(|| spherecal_tools::synth::synth(&s, &dir).unwrap())
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! The survey planner's speed: table1 and pontoon predicted (their sphere returns traced
//! against the whole scene, the information per pass and sphere, the covariance and each pass's
//! share), on all cores; and the recommendations for a plan that misses (every pass 25 m off
//! the quay, northbound: 21 candidate changes traced and weighed).
//! `cargo bench -p spherecal-tools --bench plan`

use criterion::{criterion_group, criterion_main, Criterion};
use spherecal_tools::config::goal::Goal;
use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::plan;

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("plan");
    g.sample_size(10);
    for name in ["table1", "pontoon"] {
        let s = Scenario::load(name).unwrap();
        g.bench_function(format!("predict {name}"), |b| {
            b.iter(|| plan::plan(&s, &Goal::default(), false).unwrap())
        });
    }
    let far = Scenario::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/data/plans/table1-far-north.toml"
    ))
    .unwrap();
    let goal = Goal {
        sigma_deg: 0.05,
        ..Goal::default()
    };
    g.bench_function("recommend table1 far north", |b| {
        b.iter(|| plan::plan(&far, &goal, true).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

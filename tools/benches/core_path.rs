//! The whole core path per point: decode -> clock -> pose interpolation -> georeference ->
//! sphere windows, on the real MRPT capture (dense returns) with a 200 Hz pose history.
//! `cargo bench -p spherecal-tools --bench core_path`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use spherecal::align::window::Batch;
use spherecal::velodyne::PointBuf;
use spherecal_tools::fixtures::CorePath;

fn bench(c: &mut Criterion) {
    let w = CorePath::load();
    let mut points = PointBuf::new();
    let mut batches: Vec<Batch<1024>> = (0..2).map(|_| Batch::default()).collect();
    let mut g = c.benchmark_group("core_path");
    g.throughput(Throughput::Elements(w.returns as u64));
    g.bench_function("mrpt_decode_align_georef_window", |b| {
        b.iter(|| w.run(&mut points, &mut batches))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

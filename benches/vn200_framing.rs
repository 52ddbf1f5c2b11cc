//! Framing + decoding throughput of the VN-200 stream (MB/s): the real VN-310 and VN-100 files
//! repeated into a 4 MB stream, fed in 4 KiB reads as a serial reader would.
//! `cargo bench -p spherecal --bench vn200_framing`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use spherecal::vn200::{Framer, Item, Pose};
use std::hint::black_box;

fn stream(name: &str) -> Vec<u8> {
    let p = format!("{}/tests/data/vn200/{name}", env!("CARGO_MANIFEST_DIR"));
    let one = std::fs::read(&p).unwrap_or_else(|e| panic!("{p}: {e}"));
    one.iter().copied().cycle().take(4 << 20).collect()
}

/// Frame everything and touch every decoded scalar (and the pose), as `spherecal ins` does.
fn frame_and_decode(bytes: &[u8], framer: &mut Framer) -> u64 {
    let mut sum = 0u64;
    for chunk in bytes.chunks(4096) {
        framer.consume(chunk, |it| {
            if let Item::Binary(f) = it.item {
                for field in f.fields() {
                    for (_, v) in field.scalars() {
                        sum = sum.wrapping_add(v.as_f64().to_bits());
                    }
                }
                if let Some(p) = Pose::from_frame(&f) {
                    sum = sum.wrapping_add(p.time.0 as u64);
                }
            }
        });
    }
    sum
}

/// Frame everything and take the pose of each frame: what the pipeline needs.
fn frame_and_pose(bytes: &[u8], framer: &mut Framer) -> u64 {
    let mut sum = 0u64;
    for chunk in bytes.chunks(4096) {
        framer.consume(chunk, |it| {
            if let Item::Binary(f) = it.item {
                sum = sum.wrapping_add(Pose::from_frame(&f).map_or(1, |p| p.time.0 as u64));
            }
        });
    }
    sum
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("vn200");
    for name in ["vn310_gnss.bin", "vn310_imu.bin", "vn100_F00294.raw"] {
        let bytes = stream(name);
        g.throughput(Throughput::Bytes(bytes.len() as u64));
        let mut framer: Box<Framer> = Box::default();
        g.bench_function(format!("frame_decode_all_{name}"), |b| {
            b.iter(|| frame_and_decode(black_box(&bytes), &mut framer))
        });
        g.bench_function(format!("frame_pose_{name}"), |b| {
            b.iter(|| frame_and_pose(black_box(&bytes), &mut framer))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

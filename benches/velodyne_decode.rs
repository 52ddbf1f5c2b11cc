//! Decoding throughput of the core alone, per model: data packets already in memory -> points.
//! `cargo bench -p spherecal --bench velodyne_decode`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use spherecal::velodyne::{decode, DataPacket, PointBuf};
use std::hint::black_box;

/// The UDP payloads of the data packets of a classic Ethernet pcap (fixed 42-byte headers).
fn payloads(path: &str) -> Vec<Vec<u8>> {
    let b = std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut off = 24;
    let mut out = Vec::new();
    while off + 16 <= b.len() {
        let incl = u32::from_le_bytes(b[off + 8..off + 12].try_into().unwrap()) as usize;
        let frame = &b[off + 16..off + 16 + incl];
        if incl == 1248 {
            out.push(frame[42..].to_vec());
        }
        off += 16 + incl;
    }
    out
}

fn bench(c: &mut Criterion) {
    let root = env!("CARGO_MANIFEST_DIR");
    for (name, file) in [
        ("vlp16_mrpt", "vlp16/mrpt_vlp16_gps.pcap"),
        (
            "hdl32e_lidarutils",
            "velodyne_models/lidarutils_hdl32e_small.pcap",
        ),
        ("vlp32c_crafted", "velodyne_models/vlp32c_crafted.pcap"),
        (
            "puck_hires_crafted",
            "velodyne_models/puck_hires_crafted.pcap",
        ),
    ] {
        let packets = payloads(&format!("{root}/tests/data/{file}"));
        let mut out = PointBuf::new();
        let points: usize = packets
            .iter()
            .map(|p| decode(&DataPacket::new_checked(&p[..]).unwrap(), &mut out).unwrap())
            .sum();
        let mut g = c.benchmark_group("velodyne");
        g.throughput(Throughput::Elements(points as u64));
        g.bench_function(format!("decode_{name}_in_memory"), |b| {
            b.iter(|| {
                let mut n = 0;
                for p in &packets {
                    let view = DataPacket::new_checked(black_box(&p[..])).unwrap();
                    n += decode(&view, &mut out).unwrap();
                    black_box(out.as_slice());
                }
                n
            })
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! Decoding throughput of the core alone: VLP-16 data packets already in memory -> points.
//! `cargo bench -p spherecal --bench vlp16_decode`

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
    let packets = payloads(&format!("{root}/tests/data/vlp16/mrpt_vlp16_gps.pcap"));
    let mut out = PointBuf::new();
    let points: usize = packets
        .iter()
        .map(|p| decode(&DataPacket::new_checked(&p[..]).unwrap(), &mut out).unwrap())
        .sum();
    let mut g = c.benchmark_group("vlp16");
    g.throughput(Throughput::Elements(points as u64));
    g.bench_function("decode_mrpt_in_memory", |b| {
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

criterion_group!(benches, bench);
criterion_main!(benches);

//! Whole-capture decoding: pcap records -> Ethernet/IPv4/UDP slicing -> classification ->
//! points, from memory and from the file. `cargo bench -p spherecal-tools --bench decode_file`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use spherecal::velodyne::{decode, PointBuf};
use spherecal_hal::pcap::PcapSource;
use spherecal_hal::velodyne::{classify, Ports, Vlp16Packet};
use spherecal_hal::{PacketSource, Record};
use std::hint::black_box;
use std::io::Read;

fn run<R: Read>(mut src: PcapSource<R>, out: &mut PointBuf) -> usize {
    let mut n = 0;
    while let Some(rec) = src.next_record().unwrap() {
        if let Record::Udp(d) = rec {
            if let Ok(Vlp16Packet::Data { packet, .. }) = classify(&d, Ports::default()) {
                n += decode(&packet, out).unwrap_or(0);
                black_box(out.as_slice());
            }
        }
    }
    n
}

fn bench(c: &mut Criterion) {
    let path = format!(
        "{}/../tests/data/vlp16/mrpt_vlp16_gps.pcap",
        env!("CARGO_MANIFEST_DIR")
    );
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut out = PointBuf::new();
    let points = run(PcapSource::from_bytes(&bytes).unwrap(), &mut out);
    let mut g = c.benchmark_group("capture");
    g.throughput(Throughput::Elements(points as u64));
    g.bench_function("mrpt_from_memory", |b| {
        b.iter(|| run(PcapSource::from_bytes(black_box(&bytes)).unwrap(), &mut out))
    });
    g.bench_function("mrpt_from_file", |b| {
        b.iter(|| run(PcapSource::open(&path).unwrap(), &mut out))
    });
    g.bench_function("mrpt_decode_command_no_csv", |b| {
        b.iter(|| {
            spherecal_tools::decode::decode_file(std::path::Path::new(&path), None, None)
                .unwrap()
                .points
        })
    });
    // One CSV row per point, into a 1 MiB buffered sink: rows/s is the throughput.
    g.bench_function("mrpt_decode_command_csv", |b| {
        b.iter(|| {
            let mut w = std::io::BufWriter::with_capacity(1 << 20, std::io::sink());
            spherecal_tools::decode::decode_file(std::path::Path::new(&path), Some(&mut w), None)
                .unwrap()
                .points
        })
    });
    // The same packets from a ROS 2 bag (rosbags' MCAP of this capture): the MCAP reader,
    // the CDR scans and the decoding (issue 29: at least half the capture's speed).
    let bag = format!(
        "{}/../tests/data/ros2/bags/mrpt_vlp16",
        env!("CARGO_MANIFEST_DIR")
    );
    g.bench_function("mrpt_decode_command_no_csv_from_bag", |b| {
        b.iter(|| {
            spherecal_tools::pipeline::bag_decode::decode_bag(
                std::path::Path::new(&bag),
                None,
                None,
                None,
            )
            .unwrap()
            .points
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

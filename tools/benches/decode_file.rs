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

/// An Ouster capture's lidar packets (classic Ethernet pcap, fixed 42-byte headers) decoded by
/// the core's views and turned into sensor-frame points with the metadata's geometry, in
/// memory: the Ouster path's counterpart of the VLP-16 core decode (issue 50 item 7).
fn ouster(c: &mut Criterion) {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/ouster/");
    for name in [
        "OS-1-32-G_v2.1.1_1024x10",
        "OS-0-32-U1_v2.2.0_1024x10",
        "windowed_frame1",
    ] {
        let m = spherecal_tools::ouster::Metadata::load(std::path::Path::new(&format!(
            "{root}{name}.json"
        )))
        .unwrap();
        let b = std::fs::read(format!("{root}{name}.pcap")).unwrap();
        let (mut off, mut packets) = (24, Vec::new());
        while off + 16 <= b.len() {
            let incl = u32::from_le_bytes(b[off + 8..off + 12].try_into().unwrap()) as usize;
            let frame = &b[off + 16..off + 16 + incl];
            if frame.len() == 42 + m.format.packet_len() {
                packets.push(frame[42..].to_vec());
            }
            off += 16 + incl;
        }
        let decode = |packets: &[Vec<u8>]| {
            let mut n = 0usize;
            let mut acc = 0.0;
            for p in packets {
                let p = spherecal::ouster::LidarPacket::new_checked(&p[..], m.format).unwrap();
                for col in p.columns().filter(|c| c.valid()) {
                    let geo = m.intrinsics.column(col.measurement_id());
                    col.for_each_return(|ch, _, r| {
                        acc += geo.xyz(ch, r)[0];
                        n += 1;
                    });
                }
            }
            (n, acc)
        };
        let returns = decode(&packets).0;
        let mut g = c.benchmark_group("ouster");
        g.throughput(Throughput::Elements(returns as u64));
        g.bench_function(format!("decode_{name}_in_memory"), |bch| {
            bch.iter(|| black_box(decode(black_box(&packets))))
        });
        g.finish();
    }
}

/// A Hesai's data packets (tier4/nebula's XT32 and QT64 bags) decoded by the core's view and
/// turned into sensor-frame points with the unit's corrections, in memory (issue 50 item 7).
fn hesai(c: &mut Criterion) {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/hesai/");
    for (dir, csv) in [("xt32", "PandarXT32.csv"), ("qt64", "PandarQT64.csv")] {
        let corr = spherecal_tools::hesai::corrections::load(std::path::Path::new(&format!(
            "{root}{csv}"
        )))
        .unwrap();
        let bag_dir = std::fs::read_dir(format!("{root}{dir}"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.is_dir())
            .unwrap();
        let bag = spherecal_hal::rosbag::Bag::open(&bag_dir).unwrap();
        let mut src =
            spherecal_hal::rosbag::sources::ScanPackets::pandar(bag.messages(&["/pandar_packets"]));
        let mut packets = Vec::new();
        while let Some(rec) = src.next_record().unwrap() {
            if let Record::Udp(d) = rec {
                packets.push(d.payload.to_vec());
            }
        }
        let decode = |packets: &[Vec<u8>]| {
            let (mut n, mut acc) = (0usize, 0.0);
            for p in packets {
                let p = spherecal::hesai::DataPacket::new_checked(&p[..]).unwrap();
                let m = p.model();
                let unit = f64::from(p.distance_unit_mm()) * 1e-3;
                for b in 0..m.blocks() {
                    let geo = corr.block(p.azimuth(b));
                    for ch in 0..m.channels() {
                        let (d, _) = p.unit(b, ch);
                        if d != 0 {
                            acc += geo.xyz(ch, f64::from(d) * unit)[0];
                            n += 1;
                        }
                    }
                }
            }
            (n, acc)
        };
        let returns = decode(&packets).0;
        let mut g = c.benchmark_group("hesai");
        g.throughput(Throughput::Elements(returns as u64));
        g.bench_function(format!("decode_{dir}_in_memory"), |bch| {
            bch.iter(|| black_box(decode(black_box(&packets))))
        });
        g.finish();
    }
}

criterion_group!(benches, bench, ouster, hesai);
criterion_main!(benches);

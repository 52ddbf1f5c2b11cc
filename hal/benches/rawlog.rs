//! Raw logging throughput: VLP-16 data datagrams into rotating pcap files (frame rebuilt,
//! checksummed, buffered, handed to the OS), and serial reads into serial logs.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use spherecal_hal::packet::HostTime;
use spherecal_hal::rawlog::{PcapLog, SerialLog};
use spherecal_hal::serial::RxStamp;
use std::net::Ipv4Addr;

fn bench(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("spherecal-bench-rawlog-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let payload: Vec<u8> = (0..1206u32).map(|i| (i * 7) as u8).collect();
    let n = 10_000u64;
    let mut g = c.benchmark_group("rawlog");
    g.throughput(Throughput::Elements(n));
    g.sample_size(10);
    g.bench_function("pcap 10k data datagrams", |b| {
        b.iter(|| {
            let mut log = PcapLog::create_pcap(&dir, "bench-lidar", 64 << 20).unwrap();
            for i in 0..n {
                log.write(
                    HostTime(1_700_000_000_000_000_000 + i as i64 * 1_326_000),
                    (Ipv4Addr::new(192, 168, 1, 201), 2368),
                    (Ipv4Addr::new(192, 168, 1, 77), 2368),
                    &payload,
                )
                .unwrap();
            }
            drop(log.flush().unwrap());
        })
    });
    let chunk = [0xAAu8; 52];
    g.bench_function("serial log 10k reads of 52 bytes", |b| {
        b.iter(|| {
            let mut log = SerialLog::create_vnlog(&dir, "bench-ins", 64 << 20, 921_600).unwrap();
            for i in 0..n {
                let stamp = RxStamp {
                    mono_ns: i * 5_000_000,
                    wall: HostTime(i as i64 * 5_000_000),
                };
                log.write(stamp, &chunk).unwrap();
            }
            drop(log.flush().unwrap());
        })
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);

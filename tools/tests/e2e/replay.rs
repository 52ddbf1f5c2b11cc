//! `replay` through loopback and a byte sink: everything sent arrives, paced as recorded.

use crate::common;

use spherecal_hal::pcap::PcapSource;
use spherecal_hal::udp::UdpSource;
use spherecal_hal::{PacketSource, Record};
use spherecal_tools::replay::{replay_serial, replay_udp, Speed};
use std::net::Ipv4Addr;
use std::time::{Duration, Instant};

#[test]
fn capture_replayed_to_loopback_arrives_whole() {
    let pcap = common::test_data("vlp16/mrpt_vlp16_gps.pcap");
    // Bind both VLP-16 ports on loopback (any free ports would do, but the capture names them).
    let Ok(data) = UdpSource::bind(Ipv4Addr::LOCALHOST, 2368, Duration::from_millis(50)) else {
        panic!("UDP 2368 on loopback is taken: another spherecal is running");
    };
    let pos = UdpSource::bind(Ipv4Addr::LOCALHOST, 8308, Duration::from_millis(50)).unwrap();
    // The payloads in the file.
    let mut want = Vec::new();
    let mut src = PcapSource::open(&pcap).unwrap();
    while let Some(Record::Udp(d)) = src.next_record().unwrap() {
        want.push((d.dst_port, d.payload.to_vec()));
    }
    let n_data = want.iter().filter(|w| w.0 == 2368).count();
    let n_pos = want.len() - n_data;
    // One receiver thread per port, as the rig has.
    let recv_all = |mut src: UdpSource, n: usize| {
        std::thread::spawn(move || {
            let mut got = Vec::new();
            let t = Instant::now();
            while got.len() < n && t.elapsed() < Duration::from_secs(20) {
                if let Some(d) = src.recv().unwrap() {
                    got.push(d.payload.to_vec());
                }
            }
            got
        })
    };
    let (rd, rp) = (recv_all(data, n_data), recv_all(pos, n_pos));
    let t0 = Instant::now();
    let sent = replay_udp(&pcap, Ipv4Addr::LOCALHOST, Speed::Factor(4.0)).unwrap();
    let (got_data, got_pos) = (rd.join().unwrap(), rp.join().unwrap());
    assert_eq!(sent.sent as usize, want.len());
    let want_data: Vec<_> = want
        .iter()
        .filter(|w| w.0 == 2368)
        .map(|w| w.1.clone())
        .collect();
    let want_pos: Vec<_> = want
        .iter()
        .filter(|w| w.0 == 8308)
        .map(|w| w.1.clone())
        .collect();
    assert_eq!(got_data.len(), want_data.len(), "every data packet arrives");
    assert_eq!(
        got_pos.len(),
        want_pos.len(),
        "every position packet arrives"
    );
    assert!(
        got_data == want_data,
        "data packets arrive whole and in order"
    );
    assert!(got_pos == want_pos, "position packets too");
    // The capture spans 0.39 s: at 4x it takes about 0.1 s, not much less.
    assert!(
        t0.elapsed() >= Duration::from_millis(80),
        "{:?}",
        t0.elapsed()
    );
}

#[test]
fn serial_bytes_replayed_at_the_baud_rate() {
    let file = common::test_data("vn200/vn310_imu.bin");
    let bytes = std::fs::read(&file).unwrap();
    let mut out = Vec::new();
    let t = Instant::now();
    // 3,438 bytes at 115200 baud x 4: 3438 * 10 / 460800 = 75 ms.
    let n = replay_serial(&file, &mut out, 115_200, Speed::Factor(4.0)).unwrap();
    assert_eq!(n as usize, bytes.len());
    assert_eq!(out, bytes);
    assert!(
        t.elapsed() >= Duration::from_millis(65),
        "{:?}",
        t.elapsed()
    );
    let mut fast = Vec::new();
    replay_serial(&file, &mut fast, 115_200, Speed::Max).unwrap();
    assert_eq!(fast, bytes);
}

/// A serial log goes out at its recorded timing: 40 reads stamped 10 ms apart, at 2x, take at
/// least 195 ms and arrive whole and in order.
#[test]
fn serial_log_replayed_at_its_recorded_pace() {
    use spherecal_hal::clock::HostTime;
    use spherecal_hal::serial::{LogWriter, RxStamp};
    let data: Vec<u8> = (0..40 * 50).map(|i| (i % 251) as u8).collect();
    let mut log = LogWriter::new(Vec::new(), 921_600).unwrap();
    for (i, c) in data.chunks(50).enumerate() {
        let stamp = RxStamp {
            mono_ns: i as u64 * 10_000_000,
            wall: HostTime(1_700_000_000_000_000_000 + i as i64 * 10_000_000),
        };
        log.record(stamp, c).unwrap();
    }
    let file = common::tmp("replay", "paced.vnlog");
    std::fs::write(&file, log.into_inner()).unwrap();
    let mut out = Vec::new();
    let t = Instant::now();
    let n = replay_serial(&file, &mut out, 921_600, Speed::Factor(2.0)).unwrap();
    assert_eq!(n as usize, data.len());
    assert_eq!(out, data);
    assert!(
        t.elapsed() >= Duration::from_millis(195),
        "{:?}",
        t.elapsed()
    );
    assert!(
        t.elapsed() < Duration::from_millis(1000),
        "{:?}",
        t.elapsed()
    );
}

/// `spherecal replay --ports` sends the capture's data and position packets to other ports, as
/// fast as asked, and says how many it sent.
#[test]
fn cli_replay_to_other_ports() {
    let pcap = common::test_data("vlp16/mrpt_vlp16_gps.pcap");
    let mut data = UdpSource::bind(Ipv4Addr::LOCALHOST, 0, Duration::from_millis(50)).unwrap();
    let mut pos = UdpSource::bind(Ipv4Addr::LOCALHOST, 0, Duration::from_millis(50)).unwrap();
    let ports = format!("{},{}", data.port(), pos.port());
    let out = common::stdout_of(common::spherecal().args([
        "replay".as_ref(),
        "--pcap".as_ref(),
        pcap.as_os_str(),
        "--ports".as_ref(),
        ports.as_ref(),
        "--speed".as_ref(),
        "2".as_ref(),
    ]));
    let mut want = (0, 0);
    let mut src = PcapSource::open(&pcap).unwrap();
    while let Some(Record::Udp(d)) = src.next_record().unwrap() {
        if d.dst_port == 2368 {
            want.0 += 1;
        } else {
            want.1 += 1;
        }
    }
    assert!(
        out.contains(&format!("sent {} datagrams", want.0 + want.1)),
        "{out}"
    );
    let mut got = (0, 0);
    while data.recv().unwrap().is_some() {
        got.0 += 1;
    }
    while pos.recv().unwrap().is_some() {
        got.1 += 1;
    }
    assert_eq!(got, want);
}

/// A writer that notes the mock clock's time of every write.
struct Stamped<'c> {
    clock: &'c spherecal_hal::clock::MockClock,
    writes: Vec<(u64, Vec<u8>)>,
}

impl std::io::Write for Stamped<'_> {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        use spherecal_hal::clock::Clock;
        self.writes.push((self.clock.mono_ns(), b.to_vec()));
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The pacing on the mock clock (no sleeping): a serial log's reads 10 ms apart at 2x go out
/// at exactly 0, 5, 10, ... 195 ms; raw bytes at 115200 baud x 4 go out in 64-byte chunks, the
/// k-th at k x 64 x 10 / 460800 s.
#[test]
fn replay_pacing_on_the_mock_clock() {
    use spherecal_hal::clock::{HostTime, MockClock};
    use spherecal_hal::serial::{LogWriter, RxStamp};
    use spherecal_tools::replay::{replay_serial_on, Pacer};
    let t0 = 1_700_000_000_000_000_000i64;
    let data: Vec<u8> = (0..40 * 50).map(|i| (i % 251) as u8).collect();
    let mut log = LogWriter::new(Vec::new(), 921_600).unwrap();
    for (i, c) in data.chunks(50).enumerate() {
        let stamp = RxStamp {
            mono_ns: i as u64 * 10_000_000,
            wall: HostTime(t0 + i as i64 * 10_000_000),
        };
        log.record(stamp, c).unwrap();
    }
    let file = common::tmp("replay", "mock-paced.vnlog");
    std::fs::write(&file, log.into_inner()).unwrap();
    let clock = MockClock::new(HostTime(0));
    let mut out = Stamped {
        clock: &clock,
        writes: Vec::new(),
    };
    let pacer = Pacer::new(&clock, HostTime(t0), Speed::Factor(2.0));
    replay_serial_on(&file, &mut out, 921_600, &pacer).unwrap();
    assert_eq!(out.writes.len(), 40);
    for (i, (at, bytes)) in out.writes.iter().enumerate() {
        let due = i as i64 * 5_000_000;
        assert!(
            (*at as i64 - due).abs() <= 1,
            "read {i} at {at} ns, due {due}"
        );
        assert_eq!(bytes[..], data[i * 50..(i + 1) * 50]);
    }

    let raw = common::test_data("vn200/vn310_imu.bin");
    let bytes = std::fs::read(&raw).unwrap();
    let clock = MockClock::new(HostTime(0));
    let mut out = Stamped {
        clock: &clock,
        writes: Vec::new(),
    };
    let pacer = Pacer::new(&clock, HostTime(0), Speed::Factor(4.0));
    replay_serial_on(&raw, &mut out, 115_200, &pacer).unwrap();
    assert_eq!(out.writes.len(), bytes.len().div_ceil(64));
    for (k, (at, _)) in out.writes.iter().enumerate() {
        let due = (k * 64 * 10) as f64 / 460_800.0 * 1e9;
        assert!(
            (*at as f64 - due).abs() < 2.0,
            "chunk {k} at {at} ns, due {due}"
        );
    }
    let all: Vec<u8> = out.writes.into_iter().flat_map(|w| w.1).collect();
    assert_eq!(all, bytes);
}

/// `replay --bag`: the real MRPT capture's bag sends the capture's very data packets, in order;
/// a bag with the VectorNav groups writes one VN-200 binary frame per CommonGroup (the core's
/// emitter), each with its time, position and the filter's sigmas, framed by the rig's framer.
#[test]
fn a_bag_replayed_sends_the_packets_and_writes_the_vn200_frames() {
    use spherecal::vn200::{Framer, Item};
    use spherecal_tools::replay::{replay_bag, BagReplay, Target};
    let sock = std::net::UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    let port = sock.local_addr().unwrap().port();
    let mut to = Target::host(Ipv4Addr::LOCALHOST);
    to.ports[0] = (2368, port);
    let mut want = Vec::new();
    let mut src = PcapSource::open(common::test_data("vlp16/mrpt_vlp16_gps.pcap")).unwrap();
    while let Some(Record::Udp(d)) = src.next_record().unwrap() {
        if d.dst_port == 2368 {
            want.push(d.payload.to_vec());
        }
    }
    let rx = std::thread::spawn(move || {
        let mut got = Vec::new();
        let mut buf = [0u8; 2048];
        while let Ok(n) = sock.recv(&mut buf) {
            got.push(buf[..n].to_vec());
        }
        got
    });
    let bag = common::test_data("ros2/bags/mrpt_vlp16");
    let (sent, wrote) =
        replay_bag(&bag, &BagReplay::default(), to, None, Speed::Factor(2.0)).unwrap();
    let got = rx.join().unwrap();
    assert_eq!((sent.sent as usize, wrote), (want.len(), None));
    assert!(
        got == want,
        "{} of {} arrive, in order and whole",
        got.len(),
        want.len()
    );

    let bag = common::test_data("ros2/bags/small_zstd.mcap");
    let expected: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(common::test_data("ros2/bags/expected.json")).unwrap(),
    )
    .unwrap();
    let mut serial: Vec<u8> = Vec::new();
    let mut to = Target::host(Ipv4Addr::LOCALHOST);
    to.ports[0] = (2368, port);
    let (sent, wrote) = replay_bag(
        &bag,
        &BagReplay::default(),
        to,
        Some(&mut serial),
        Speed::Max,
    )
    .unwrap();
    assert_eq!(sent.sent, 12);
    assert_eq!(wrote, Some(serial.len() as u64));
    let mut framer: Box<Framer> = Box::default();
    let mut frames = Vec::new();
    framer.consume(&serial, |it| {
        if let Item::Binary(f) = it.item {
            frames.push((
                f.gps_time().map(|t| t.0),
                f.position_lla(),
                f.position_uncertainty_m(),
            ));
        }
    });
    assert_eq!(
        frames.len() as u64,
        expected["ins_messages"].as_u64().unwrap()
    );
    assert_eq!(framer.stats().crc_failures, 0);
    for (k, w) in expected["ins"].as_array().unwrap().iter().enumerate() {
        assert_eq!(frames[k].0, w["timegps"].as_i64(), "{k}");
        let lla = frames[k].1.unwrap();
        assert!(
            (lla[0] - w["lla"][0].as_f64().unwrap()).abs() < 1e-12,
            "{k}"
        );
    }
    assert!(frames[1..].iter().all(|f| f.2 == Some(0.03)));
}

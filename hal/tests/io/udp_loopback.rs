//! The UDP source on loopback: datagrams sent arrive whole, in order, stamped; a read with
//! nothing to read returns promptly.

use spherecal_hal::udp::UdpSource;
use std::net::{Ipv4Addr, UdpSocket};
use std::time::{Duration, Instant};

#[test]
fn loopback_datagrams_arrive_whole_and_in_order() {
    let mut src = UdpSource::bind(Ipv4Addr::LOCALHOST, 0, Duration::from_millis(50)).unwrap();
    assert!(
        src.recv_buffer().unwrap() >= 100_000,
        "a receive buffer of at least 100 kB"
    );
    let port = src.port();
    let tx = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
    let mut payload = vec![0u8; 1206];
    for i in 0..200u32 {
        payload[1200..1204].copy_from_slice(&i.to_le_bytes());
        tx.send_to(&payload, (Ipv4Addr::LOCALHOST, port)).unwrap();
    }
    let mut last = None;
    for i in 0..200u32 {
        let d = src.recv().unwrap().expect("a datagram");
        assert_eq!(d.payload.len(), 1206);
        assert_eq!(
            u32::from_le_bytes(d.payload[1200..1204].try_into().unwrap()),
            i
        );
        assert_eq!(d.dst_port, port);
        assert_eq!(d.src_addr, Ipv4Addr::LOCALHOST);
        if let Some(t) = last {
            assert!(
                d.time >= t,
                "receive times never go back: datagram {i} is {} ns before the one before it",
                t.0 - d.time.0
            );
        }
        last = Some(d.time);
    }
    assert_eq!(src.received, 200);
    // Nothing more: the read times out within its limit.
    let t = Instant::now();
    assert!(src.recv().unwrap().is_none());
    assert!(t.elapsed() < Duration::from_millis(500));
}

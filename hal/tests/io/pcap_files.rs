//! The capture reader on files it writes itself: every skip reason, pcapng, nanosecond and
//! big-endian pcap, truncation at every byte, wrong magic, random bytes, odd chunking.

use pcap_file::pcapng::blocks::enhanced_packet::EnhancedPacketBlock;
use pcap_file::pcapng::blocks::interface_description::{
    InterfaceDescriptionBlock, InterfaceDescriptionOption,
};
use pcap_file::pcapng::PcapNgWriter;
use pcap_file::DataLink;
use proptest::prelude::*;
use spherecal::velodyne::{DataPacket, PositionPacket, PpsStatus, ReturnMode};
use spherecal_hal::packet::HostTime;
use spherecal_hal::pcap::{build_udp_frame, PcapError, PcapSource, PcapWriter, UdpEndpoints};
use spherecal_hal::velodyne::{classify, Ports, SkipStats, Vlp16Packet};
use spherecal_hal::{PacketSource, Record, SkipReason};
use std::borrow::Cow;
use std::io::Read;
use std::time::Duration;

fn data_payload(stamp: u32, flag_ok: bool) -> Vec<u8> {
    let mut buf = vec![0u8; 1206];
    let mut p = DataPacket::new_unchecked(&mut buf[..]);
    for b in 0..12 {
        p.set_flag(b);
        p.set_azimuth_raw(b, 100 * b as u16);
        p.set_channel(b, b, 1000 + b as u16, 7);
    }
    p.set_timestamp_us(stamp);
    p.set_return_mode(ReturnMode::Strongest);
    p.set_product_raw(0x22);
    if !flag_ok {
        buf[500] = 0x00;
    }
    buf
}

fn position_payload() -> Vec<u8> {
    let mut buf = vec![0u8; 512];
    let mut p = PositionPacket::new_unchecked(&mut buf[..]);
    p.set_timestamp_us(1_082_342_001);
    p.set_pps(PpsStatus::Locked);
    p.set_nmea(b"$GPRMC,081802.00,A,3649.7478558,N,00224.4542928,W,0.034,212.5,210116,0.0,E,A*2E");
    buf
}

/// The frames of a small capture with one of each kind of skip; each with its time.
fn frames() -> Vec<(HostTime, Vec<u8>, u32)> {
    let ep = UdpEndpoints::default();
    let mut out = Vec::new();
    let mut f = Vec::new();
    let t = |i: i64| HostTime(1_453_364_282_000_000_000 + i * 1_326_000);
    build_udp_frame(&mut f, &ep, 2368, 2368, &data_payload(1, true)).unwrap();
    out.push((t(0), f.clone(), f.len() as u32));
    build_udp_frame(&mut f, &ep, 8308, 8308, &position_payload()).unwrap();
    out.push((t(1), f.clone(), f.len() as u32));
    // Canned IPv4 total length (1234) on a position frame, as some recorders write.
    let mut canned = f.clone();
    canned[16..18].copy_from_slice(&1234u16.to_be_bytes());
    out.push((t(2), canned, f.len() as u32));
    // ARP: not IPv4.
    let mut arp = vec![0xFFu8; 12];
    arp.extend_from_slice(&[0x08, 0x06]);
    arp.extend_from_slice(&[0u8; 28]);
    out.push((t(3), arp.clone(), arp.len() as u32));
    // UDP to another port.
    build_udp_frame(&mut f, &ep, 5000, 5353, b"hello").unwrap();
    out.push((t(4), f.clone(), f.len() as u32));
    // Data port, wrong length.
    build_udp_frame(&mut f, &ep, 2368, 2368, &[0u8; 1000]).unwrap();
    out.push((t(5), f.clone(), f.len() as u32));
    // Data port, right length, broken block flag.
    build_udp_frame(&mut f, &ep, 2368, 2368, &data_payload(2, false)).unwrap();
    out.push((t(6), f.clone(), f.len() as u32));
    // A record cut by the snap length: 200 of 1248 bytes captured.
    build_udp_frame(&mut f, &ep, 2368, 2368, &data_payload(3, true)).unwrap();
    out.push((t(7), f[..200].to_vec(), f.len() as u32));
    // A last good data packet.
    build_udp_frame(&mut f, &ep, 2368, 2368, &data_payload(4, true)).unwrap();
    out.push((t(8), f.clone(), f.len() as u32));
    out
}

fn classic_bytes() -> Vec<u8> {
    let mut w = PcapWriter::new(Vec::new()).unwrap();
    for (t, f, orig) in frames() {
        if orig as usize == f.len() {
            w.write_frame(t, &f).unwrap();
        }
    }
    let mut bytes = w.into_inner();
    // The snap-length-cut record, written by hand (the writer only writes whole frames).
    let (t, f, orig) = frames().remove(7);
    let ns = t.0 as u64;
    let mut rec = Vec::new();
    rec.extend_from_slice(&((ns / 1_000_000_000) as u32).to_le_bytes());
    rec.extend_from_slice(&(((ns % 1_000_000_000) / 1000) as u32).to_le_bytes());
    rec.extend_from_slice(&(f.len() as u32).to_le_bytes());
    rec.extend_from_slice(&orig.to_le_bytes());
    rec.extend_from_slice(&f);
    // Insert it before the last record to keep file order = frames() order.
    let last_len = 16 + frames()[8].1.len();
    let at = bytes.len() - last_len;
    bytes.splice(at..at, rec);
    bytes
}

#[derive(Debug, PartialEq)]
enum Seen {
    Data {
        stamp: u32,
        time: HostTime,
        offset: u64,
    },
    Position {
        pps: PpsStatus,
        time: HostTime,
    },
    Skip(&'static str, u64),
}

fn read_all<R: Read>(mut src: PcapSource<R>) -> (Vec<Seen>, SkipStats) {
    let mut seen = Vec::new();
    let mut stats = SkipStats::default();
    while let Some(rec) = src.next_record().unwrap() {
        match rec {
            Record::Skipped { offset, reason } => {
                stats.count(offset, &reason);
                seen.push(Seen::Skip(reason.name(), offset));
            }
            Record::Udp(d) => match classify(&d, Ports::default()) {
                Ok(Vlp16Packet::Data {
                    packet,
                    time,
                    offset,
                }) => seen.push(Seen::Data {
                    stamp: packet.timestamp_us(),
                    time,
                    offset,
                }),
                Ok(Vlp16Packet::Position { packet, time, .. }) => seen.push(Seen::Position {
                    pps: packet.pps(),
                    time,
                }),
                Err(r) => {
                    stats.count(d.offset, &r);
                    seen.push(Seen::Skip(r.name(), d.offset));
                }
            },
            Record::Idle => panic!("a file is never idle"),
        }
    }
    (seen, stats)
}

#[test]
fn every_skip_reason_is_counted() {
    let bytes = classic_bytes();
    let (seen, stats) = read_all(PcapSource::from_bytes(&bytes).unwrap());
    let names: Vec<_> = seen
        .iter()
        .map(|s| match s {
            Seen::Data { .. } => "data",
            Seen::Position { .. } => "position",
            Seen::Skip(n, _) => n,
        })
        .collect();
    assert_eq!(
        names,
        [
            "data",
            "position",
            "position", // the canned IPv4 length does not matter
            "not IPv4/UDP",
            "other port",
            "wrong payload length",
            "bad block flag",
            "truncated record",
            "data"
        ]
    );
    assert_eq!(stats.total(), 5);
    // First record sits right after the 24-byte global header; the second after 16 + 1248.
    assert!(matches!(
        seen[0],
        Seen::Data {
            stamp: 1,
            offset: 24,
            ..
        }
    ));
    if let Seen::Skip(_, off) = seen[3] {
        assert_eq!(off, 24 + (16 + 1248) + 2 * (16 + 554));
    }
    let line = stats
        .lines()
        .iter()
        .find(|l| l.reason == "bad block flag")
        .unwrap();
    assert_eq!(
        line.first,
        "data block 5: expected flag 0xFFEE, found 0x00EE"
    );
    let line = stats
        .lines()
        .iter()
        .find(|l| l.reason == "wrong payload length")
        .unwrap();
    assert_eq!(
        line.first,
        "UDP port 2368: expected a 1206-byte payload, got 1000"
    );
}

#[test]
fn microsecond_stamps_survive() {
    let bytes = classic_bytes();
    let (seen, _) = read_all(PcapSource::from_bytes(&bytes).unwrap());
    assert!(matches!(
        seen[1],
        Seen::Position {
            time: HostTime(1_453_364_282_001_326_000),
            ..
        }
    ));
}

/// A reader that hands out 1..=7 bytes at a time.
struct Trickle<'a> {
    bytes: &'a [u8],
    n: usize,
}
impl Read for Trickle<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.n = self.n % 7 + 1;
        let k = self.n.min(buf.len()).min(self.bytes.len());
        buf[..k].copy_from_slice(&self.bytes[..k]);
        self.bytes = &self.bytes[k..];
        Ok(k)
    }
}

#[test]
fn chunked_reading_gives_the_same_records() {
    let bytes = classic_bytes();
    let whole = read_all(PcapSource::from_bytes(&bytes).unwrap()).0;
    let trickled = read_all(
        PcapSource::new(Trickle {
            bytes: &bytes,
            n: 0,
        })
        .unwrap(),
    )
    .0;
    assert_eq!(whole, trickled);
}

#[test]
fn pcapng_gives_the_same_records() {
    for (resol, scale) in [(9u8, 1u64), (6, 1000)] {
        let mut w = PcapNgWriter::new(Vec::new()).unwrap();
        let idb = InterfaceDescriptionBlock {
            linktype: DataLink::ETHERNET,
            snaplen: 65_535,
            options: vec![InterfaceDescriptionOption::IfTsResol(resol)],
        };
        w.write_pcapng_block(idb).unwrap();
        for (t, f, orig) in frames() {
            let units = t.0 as u64 / scale;
            let epb = EnhancedPacketBlock {
                interface_id: 0,
                // pcap-file stores the raw timestamp units in a Duration's nanoseconds.
                timestamp: Duration::from_nanos(units),
                original_len: orig,
                data: Cow::Owned(f),
                options: vec![],
            };
            w.write_pcapng_block(epb).unwrap();
        }
        let bytes = w.into_inner();
        let src = PcapSource::from_bytes(&bytes).unwrap();
        assert!(src.is_pcapng());
        let (ng, _) = read_all(src);
        let classic = read_all(PcapSource::from_bytes(&classic_bytes()).unwrap()).0;
        assert_eq!(ng.len(), classic.len());
        for (a, b) in ng.iter().zip(&classic) {
            match (a, b) {
                (
                    Seen::Data {
                        stamp: s1,
                        time: t1,
                        ..
                    },
                    Seen::Data {
                        stamp: s2,
                        time: t2,
                        ..
                    },
                ) => {
                    assert_eq!((s1, t1), (s2, t2))
                }
                (Seen::Skip(n1, _), Seen::Skip(n2, _)) => assert_eq!(n1, n2),
                (a, b) => assert_eq!(a, b),
            }
        }
    }
}

/// Hand-made classic headers: nanosecond magic, big-endian byte order.
#[test]
fn nanosecond_and_big_endian_pcap() {
    let (t, f, _) = frames().remove(0);
    for big in [false, true] {
        let mut bytes = Vec::new();
        let u32b = |v: u32| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        let u16b = |v: u16| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        bytes.extend_from_slice(&u32b(0xA1B2_3C4D)); // nanosecond magic
        bytes.extend_from_slice(&u16b(2));
        bytes.extend_from_slice(&u16b(4));
        bytes.extend_from_slice(&[0; 8]);
        bytes.extend_from_slice(&u32b(65_535));
        bytes.extend_from_slice(&u32b(1));
        let ns = t.0 as u64 + 123;
        bytes.extend_from_slice(&u32b((ns / 1_000_000_000) as u32));
        bytes.extend_from_slice(&u32b((ns % 1_000_000_000) as u32));
        bytes.extend_from_slice(&u32b(f.len() as u32));
        bytes.extend_from_slice(&u32b(f.len() as u32));
        bytes.extend_from_slice(&f);
        let (seen, _) = read_all(PcapSource::from_bytes(&bytes).unwrap());
        assert_eq!(
            seen,
            [Seen::Data {
                stamp: 1,
                time: HostTime(ns as i64),
                offset: 24
            }]
        );
    }
}

#[test]
fn truncation_at_every_byte_is_reported_not_panicked() {
    let bytes = classic_bytes();
    let full = read_all(PcapSource::from_bytes(&bytes).unwrap()).0;
    // Record boundaries.
    let mut ends = vec![24usize];
    let mut off = 24;
    while off < bytes.len() {
        let incl = u32::from_le_bytes(bytes[off + 8..off + 12].try_into().unwrap()) as usize;
        off += 16 + incl;
        ends.push(off);
    }
    for cut in 0..bytes.len() {
        let head = &bytes[..cut];
        match PcapSource::from_bytes(head) {
            Err(PcapError::TruncatedHeader { expected: 24, got }) => {
                assert!(cut < 24 && got == cut)
            }
            Err(e) => panic!("cut {cut}: {e}"),
            Ok(src) => {
                assert!(cut >= 24);
                let (seen, _) = read_all(src);
                let whole = ends.iter().filter(|&&e| e <= cut).count() - 1;
                assert_eq!(&seen[..whole], &full[..whole], "cut {cut}");
                if ends.contains(&cut) {
                    assert_eq!(seen.len(), whole);
                } else {
                    let start = ends[whole];
                    assert_eq!(
                        seen[whole..],
                        [Seen::Skip("truncated file", start as u64)],
                        "cut {cut}"
                    );
                }
            }
        }
    }
}

#[test]
fn wrong_magic_is_named() {
    let mut bytes = classic_bytes();
    bytes[..4].copy_from_slice(b"GIF8");
    let e = PcapSource::from_bytes(&bytes).err().unwrap();
    assert!(matches!(
        e,
        PcapError::BadMagic {
            found: [b'G', b'I', b'F', b'8']
        }
    ));
    assert!(
        e.to_string()
            .starts_with("offset 0: not a pcap or pcapng file"),
        "{e}"
    );
}

#[test]
fn corrupt_record_length_stops_with_offset() {
    let mut bytes = classic_bytes();
    let second = 24 + 16 + 1248;
    bytes[second + 8..second + 12].copy_from_slice(&0x7FFF_FFFFu32.to_le_bytes());
    let mut src = PcapSource::from_bytes(&bytes).unwrap();
    assert!(matches!(src.next_record(), Ok(Some(Record::Udp(_)))));
    let e = src.next_record().err().unwrap();
    assert!(
        e.to_string()
            .starts_with(&format!("offset {second}: record claims")),
        "{e}"
    );
}

#[test]
fn linux_sll_and_raw_ip_links() {
    let (_, f, _) = frames().remove(0);
    let ip = &f[14..];
    // LINUX_SLL: 16-byte cooked header with protocol 0x0800 at 14..16.
    let mut sll = vec![0u8; 14];
    sll.extend_from_slice(&[0x08, 0x00]);
    sll.extend_from_slice(ip);
    for (link, frame) in [(113u32, sll), (101, ip.to_vec()), (147, ip.to_vec())] {
        let r = spherecal_hal::pcap::slice_udp(link, &frame);
        if link == 147 {
            assert_eq!(r.err(), Some(SkipReason::UnsupportedLinkType(147)));
        } else {
            let (_, _, port, payload) = r.unwrap();
            assert_eq!((port, payload.len()), (2368, 1206));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]
    /// Random bytes behind either magic: an error or records, never a panic or a hang.
    #[test]
    fn random_bytes_never_panic(ng in any::<bool>(), tail in prop::collection::vec(any::<u8>(), 0..3000)) {
        let mut bytes = if ng { vec![0x0A, 0x0D, 0x0D, 0x0A] } else { vec![0xD4, 0xC3, 0xB2, 0xA1] };
        bytes.extend_from_slice(&tail);
        if let Ok(mut src) = PcapSource::from_bytes(&bytes) {
            let mut n = 0;
            while let Ok(Some(_)) = src.next_record() {
                n += 1;
                prop_assert!(n < 10_000);
            }
        }
    }

    /// Random byte flips in a valid capture: never a panic.
    #[test]
    fn flipped_bytes_never_panic(flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8)) {
        let mut bytes = classic_bytes();
        for (i, v) in flips {
            let at = i.index(bytes.len());
            bytes[at] = v;
        }
        if let Ok(mut src) = PcapSource::from_bytes(&bytes) {
            let mut stats = SkipStats::default();
            while let Ok(Some(rec)) = src.next_record() {
                if let Record::Udp(d) = rec {
                    if let Err(r) = classify(&d, Ports::default()) { stats.count(d.offset, &r) }
                }
            }
        }
    }
}

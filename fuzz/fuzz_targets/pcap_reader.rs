//! Any bytes as a capture file: the reader, the link/IP/UDP slicer and the VLP-16 classifier.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::velodyne::{decode, PointBuf};
use spherecal_hal::pcap::PcapSource;
use spherecal_hal::velodyne::{classify, Ports, SkipStats, Vlp16Packet};
use spherecal_hal::{PacketSource, Record};

fuzz_target!(|data: &[u8]| {
    let Ok(mut src) = PcapSource::from_bytes(data) else {
        return;
    };
    let mut stats = SkipStats::default();
    let mut out = PointBuf::new();
    while let Ok(Some(rec)) = src.next_record() {
        match rec {
            Record::Skipped { offset, reason } => stats.count(offset, &reason),
            Record::Udp(d) => match classify(&d, Ports::default()) {
                Ok(Vlp16Packet::Data { packet, .. }) => {
                    let _ = decode(&packet, &mut out);
                }
                Ok(Vlp16Packet::Position { packet, .. }) => {
                    let _ = packet.nmea_time();
                }
                Err(r) => stats.count(d.offset, &r),
            },
            Record::Idle => panic!("a file source is never idle"),
        }
    }
});

//! Any bytes as a spherecal serial log (the target puts the 16-byte header in front when the
//! input lacks it, so the fuzzer reaches the records): the reader ends without a panic, with the
//! record bytes it returns fitting in the input. Then the input, cut into records at
//! fuzzer-chosen lengths, is written with `LogWriter` and must read back identically.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal_hal::clock::HostTime;
use spherecal_hal::serial::{LogReader, LogWriter, RxStamp, LOG_MAGIC, LOG_VERSION};

fuzz_target!(|data: &[u8]| {
    let mut file = Vec::with_capacity(data.len() + 16);
    if !data.starts_with(LOG_MAGIC) {
        file.extend_from_slice(LOG_MAGIC);
        file.extend_from_slice(&LOG_VERSION.to_le_bytes());
        file.extend_from_slice(&115_200u32.to_le_bytes());
    }
    file.extend_from_slice(data);
    if let Ok(mut rd) = LogReader::new(&file[..]) {
        let mut buf = Vec::new();
        let mut total = 0usize;
        for _ in 0..=file.len() {
            match rd.next_record(&mut buf) {
                Ok(Some(_)) => {
                    total += buf.len();
                    assert!(total <= file.len());
                }
                Ok(None) | Err(_) => break,
            }
        }
    }

    // Round trip: record lengths from the input's own bytes.
    let mut w = LogWriter::new(Vec::new(), 460_800).unwrap();
    let mut records = Vec::new();
    let mut rest = data;
    let mut i = 0u64;
    while !rest.is_empty() {
        let n = (usize::from(rest[0]) + 1).min(rest.len());
        let stamp = RxStamp {
            mono_ns: i.wrapping_mul(1_000_003),
            wall: HostTime((i as i64).wrapping_mul(-7_000_001)),
        };
        w.record(stamp, &rest[..n]).unwrap();
        records.push((stamp, rest[..n].to_vec()));
        rest = &rest[n..];
        i += 1;
    }
    let bytes = w.into_inner();
    let mut rd = LogReader::new(&bytes[..]).unwrap();
    assert_eq!(rd.baud, 460_800);
    let mut buf = Vec::new();
    for (stamp, rec) in &records {
        let got = rd.next_record(&mut buf).unwrap().unwrap();
        assert_eq!((got.mono_ns, got.wall), (stamp.mono_ns, stamp.wall));
        assert_eq!(&buf, rec);
    }
    assert!(rd.next_record(&mut buf).unwrap().is_none());
    assert!(rd.truncated_tail.is_none());
});

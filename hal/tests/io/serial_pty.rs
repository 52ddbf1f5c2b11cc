//! The serial path over a pseudo-terminal pair: bytes written at one end arrive at the other,
//! stamped, logged and framed, with nothing lost; the serial log reads back the same.

use serialport::TTYPort;
use spherecal::vn200::{Framer, Item};
use spherecal_hal::clock::HostTime;
use spherecal_hal::serial::{
    read_byte_file, ByteSource, LogReader, LogWriter, ReadOutcome, RxStamp, SerialSource,
};
use std::io::Write;
use std::time::{Duration, Instant};

fn vn100() -> Vec<u8> {
    let p = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/data/vn200/vn100_F00294.raw"
    );
    std::fs::read(p).unwrap_or_else(|e| panic!("{p}: {e}: the repository's tests/data"))
}

fn frames_of(bytes: &[u8]) -> Vec<(u64, Vec<u8>)> {
    let mut f: Box<Framer> = Box::default();
    let mut out = Vec::new();
    f.consume(bytes, |it| {
        if let Item::Binary(fr) = it.item {
            out.push((it.offset, fr.bytes().to_vec()));
        }
    });
    out
}

#[test]
fn pty_bytes_arrive_framed_stamped_and_logged() {
    let data = vn100();
    let (mut master, slave) = TTYPort::pair().expect("a pseudo-terminal pair");
    let mut src = SerialSource::from_port(Box::new(slave));
    let to_send = data.clone();
    let writer = std::thread::spawn(move || {
        // The VN-200's own pace would be slow; write in bursts like a UART FIFO.
        for chunk in to_send.chunks(97) {
            master.write_all(chunk).unwrap();
            std::thread::sleep(Duration::from_micros(200));
        }
        master.flush().unwrap();
        // Keep the master open until the reader has everything.
        std::thread::sleep(Duration::from_millis(500));
    });

    let mut log = LogWriter::new(Vec::new(), 115_200).unwrap();
    let mut received = Vec::new();
    let mut buf = [0u8; 512];
    let mut framer: Box<Framer> = Box::default();
    let mut framed = Vec::new();
    let mut last = RxStamp::default();
    let deadline = Instant::now() + Duration::from_secs(10);
    while received.len() < data.len() && Instant::now() < deadline {
        match src.read_chunk(&mut buf).unwrap() {
            ReadOutcome::Data { len, stamp } => {
                let stamp = stamp.expect("a serial read is stamped");
                assert!(stamp.mono_ns >= last.mono_ns, "receive times never go back");
                last = stamp;
                log.record(stamp, &buf[..len]).unwrap();
                received.extend_from_slice(&buf[..len]);
                framer.consume(&buf[..len], |it| {
                    if let Item::Binary(fr) = it.item {
                        framed.push((it.offset, fr.bytes().to_vec()));
                    }
                });
            }
            ReadOutcome::Idle => {}
            ReadOutcome::End => break,
        }
    }
    writer.join().unwrap();
    assert_eq!(received.len(), data.len(), "nothing lost");
    assert_eq!(received, data, "nothing changed");
    assert_eq!(framed, frames_of(&data));
    assert_eq!(framed.len(), 99);

    // The log reads back as the same bytes, record by record, with the same stamps.
    let bytes = log.into_inner();
    let mut r = LogReader::new(&bytes[..]).unwrap();
    assert_eq!(r.baud, 115_200);
    let mut rec = Vec::new();
    let mut back = Vec::new();
    let mut n = 0;
    while let Some(_stamp) = r.next_record(&mut rec).unwrap() {
        back.extend_from_slice(&rec);
        n += 1;
    }
    assert!(n > 1);
    assert_eq!(back, data);
    assert!(r.truncated_tail.is_none());
}

#[test]
fn log_cut_anywhere_reads_up_to_the_cut() {
    let mut log = LogWriter::new(Vec::new(), 0).unwrap();
    for i in 0..5u8 {
        log.record(
            RxStamp {
                mono_ns: u64::from(i) * 1000,
                wall: HostTime(7),
            },
            &[i; 10],
        )
        .unwrap();
    }
    let bytes = log.into_inner();
    for cut in 16..bytes.len() {
        let mut r = LogReader::new(&bytes[..cut]).unwrap();
        let mut rec = Vec::new();
        let mut got = Vec::new();
        while let Some(s) = r.next_record(&mut rec).unwrap() {
            got.extend_from_slice(&rec);
            assert_eq!(s.wall, HostTime(7));
        }
        let whole = (cut - 16) / 30;
        assert!(got.len() >= whole * 10, "cut {cut}");
        assert_eq!(
            r.truncated_tail.is_some(),
            (cut - 16) % 30 != 0,
            "cut {cut}"
        );
    }
    assert!(LogReader::new(&bytes[..15]).is_err());
    assert!(LogReader::new(&b"NOTALOG!xxxxxxxx"[..]).is_err());
}

#[test]
fn raw_and_logged_files_give_the_same_stream() {
    let data = vn100();
    let dir = std::env::temp_dir().join(format!("spherecal-serial-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let raw = dir.join("ins.bin");
    std::fs::write(&raw, &data).unwrap();
    let mut log = LogWriter::new(Vec::new(), 921_600).unwrap();
    for (i, c) in data.chunks(333).enumerate() {
        log.record(
            RxStamp {
                mono_ns: i as u64 * 1_000_000,
                wall: HostTime(0),
            },
            c,
        )
        .unwrap();
    }
    let logged = dir.join("ins.vnlog");
    std::fs::write(&logged, log.into_inner()).unwrap();
    let (a, sa) = read_byte_file(&raw).unwrap();
    let (b, sb) = read_byte_file(&logged).unwrap();
    assert_eq!(a, b);
    assert!(sa.is_none());
    let sb = sb.unwrap();
    assert_eq!(sb.len(), data.len().div_ceil(333));
    assert_eq!(sb[1].0, 333);
}

/// `FileSource` hands out a serial log's record bytes with each record's stamp, in any buffer
/// size, and a raw file's bytes without stamps; a log cut inside a record ends at the cut.
#[test]
fn file_source_gives_the_log_bytes_with_their_stamps() {
    use spherecal_hal::serial::FileSource;
    let dir = std::env::temp_dir().join(format!("sc-filesource-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let recs: Vec<(RxStamp, Vec<u8>)> = (0..5u8)
        .map(|i| {
            let stamp = RxStamp {
                mono_ns: u64::from(i) * 1_000,
                wall: HostTime(1_700_000_000_000_000_000 + i64::from(i) * 1_000),
            };
            (stamp, (0..(10 + 7 * i)).map(|b| b ^ i).collect())
        })
        .collect();
    let mut w = LogWriter::new(Vec::new(), 115_200).unwrap();
    for (s, b) in &recs {
        w.record(*s, b).unwrap();
    }
    let log = w.into_inner();
    let read_all = |path: &std::path::Path, chunk: usize| {
        let mut src = FileSource::open(path).unwrap();
        let mut buf = vec![0u8; chunk];
        let mut got: Vec<(Option<RxStamp>, Vec<u8>)> = Vec::new();
        loop {
            match src.read_chunk(&mut buf).unwrap() {
                ReadOutcome::Data { len, stamp } => got.push((stamp, buf[..len].to_vec())),
                ReadOutcome::Idle => panic!("a file is never idle"),
                ReadOutcome::End => break got,
            }
        }
    };
    let logged = dir.join("a.vnlog");
    std::fs::write(&logged, &log).unwrap();
    for chunk in [1, 7, 64, 4096] {
        let got = read_all(&logged, chunk);
        let bytes: Vec<u8> = got.iter().flat_map(|g| g.1.clone()).collect();
        let want: Vec<u8> = recs.iter().flat_map(|r| r.1.clone()).collect();
        assert_eq!(bytes, want, "chunk {chunk}");
        // Every piece carries its own record's stamp.
        let mut at = 0usize;
        for (stamp, piece) in &got {
            let (mut start, mut k) = (0usize, 0usize);
            while start + recs[k].1.len() <= at {
                start += recs[k].1.len();
                k += 1;
            }
            assert_eq!(*stamp, Some(recs[k].0), "chunk {chunk} at {at}");
            at += piece.len();
        }
    }
    // Cut inside the last record: the stream ends with the records before it.
    let cut = dir.join("cut.vnlog");
    std::fs::write(&cut, &log[..log.len() - 3]).unwrap();
    let got: Vec<u8> = read_all(&cut, 64).into_iter().flat_map(|g| g.1).collect();
    let before: usize = recs[..4].iter().map(|r| r.1.len()).sum();
    assert!(
        got.len() >= before && got.len() < before + recs[4].1.len(),
        "{}",
        got.len()
    );
    // Raw bytes: as they are, no stamps.
    let raw = dir.join("raw.bin");
    std::fs::write(&raw, b"\xfa\x01raw bytes").unwrap();
    let got = read_all(&raw, 4);
    assert!(got.iter().all(|g| g.0.is_none()));
    let bytes: Vec<u8> = got.into_iter().flat_map(|g| g.1).collect();
    assert_eq!(bytes, b"\xfa\x01raw bytes");
    std::fs::remove_dir_all(&dir).unwrap();
}

//! Any bytes through the VN-200 framer (whole and split at a fuzzer-chosen point must agree),
//! the frame view, the ASCII parser and pose extraction; register echoes read back and written
//! again (the VN-200 configuration's round trip).
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::vn200::ascii;
use spherecal::vn200::binary::Frame;
use spherecal::vn200::command::{self, BinaryOutput};
use spherecal::vn200::{Framer, Item, Pose};

fn run(parts: &[&[u8]]) -> (Vec<(u64, Vec<u8>)>, spherecal::vn200::Stats) {
    let mut f: Box<Framer<1024>> = Box::default();
    let mut out = Vec::new();
    for p in parts {
        f.consume(p, |it| match it.item {
            Item::Binary(fr) => {
                assert_eq!(
                    Frame::parse(fr.bytes()).map(|x| x.bytes().len()),
                    Ok(fr.bytes().len())
                );
                for field in fr.fields() {
                    for _ in field.scalars() {}
                }
                let _ = Pose::from_frame(&fr);
                out.push((it.offset, fr.bytes().to_vec()));
            }
            Item::Ascii(s) | Item::Nmea(s) => {
                // A unit's register echo read back as the configuration does; written again,
                // it reads back the same.
                if let Ok(ascii::Vn::Register { values, .. }) = s.decode() {
                    if let Ok(b) = BinaryOutput::parse(values) {
                        let mut cmd = [0u8; 128];
                        if let Ok(n) = command::write_binary_output(&mut cmd, 75, &b) {
                            let line = &cmd[..n - 2];
                            if let Ok(ascii::Vn::Register { values, .. }) =
                                ascii::parse(line).and_then(|x| x.decode())
                            {
                                assert_eq!(BinaryOutput::parse(values), Ok(b));
                            } else {
                                panic!("our own command does not parse");
                            }
                        }
                    }
                }
                out.push((it.offset, s.line().as_bytes().to_vec()));
            }
            Item::Error(_) => {}
        });
    }
    f.finish();
    while let Some(it) = f.next() {
        if let Item::Binary(fr) = it.item {
            out.push((it.offset, fr.bytes().to_vec()));
        }
    }
    (out, *f.stats())
}

fuzz_target!(|data: &[u8]| {
    let _ = ascii::parse(data);
    let _ = Frame::parse(data);
    if data.is_empty() {
        return;
    }
    let split = usize::from(data[0]) * data.len() / 256;
    let whole = run(&[data]);
    let parts = run(&[&data[..split], &data[split..]]);
    assert_eq!(whole, parts);
});

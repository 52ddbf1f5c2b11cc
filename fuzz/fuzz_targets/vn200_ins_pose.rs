//! Any bytes as the body of a checksummed `$VNINS` sentence (the target adds `$`, `*` and the
//! XOR checksum so the fuzzer reaches the field parser): the decoder, the GPS time (week and
//! time of week from the wire) and `Pose::from_ins` must never panic, and a pose must be finite
//! and in range.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::vn200::ascii::{self, Vn};
use spherecal::vn200::{Attitude, Pose};

fuzz_target!(|data: &[u8]| {
    // Printable, no '$' or '*' (those would end the body early), at most the sentence limit.
    let body: Vec<u8> = data
        .iter()
        .take(ascii::MAX_SENTENCE - 4)
        .map(|&c| match c {
            b'$' | b'*' => b',',
            0x20..=0x7E => c,
            _ => b'0' + c % 10,
        })
        .collect();
    let cs = body.iter().fold(0u8, |a, &c| a ^ c);
    let mut line = Vec::with_capacity(body.len() + 4);
    line.push(b'$');
    line.extend_from_slice(&body);
    line.extend_from_slice(format!("*{cs:02X}").as_bytes());
    let Ok(s) = ascii::parse(&line) else { return };
    let Ok(Vn::Ins(ins)) = s.decode() else { return };
    let _ = ins.gps_time();
    if let Some(p) = Pose::from_ins(&ins) {
        assert!(p.lat.is_finite() && p.lat.abs() <= core::f64::consts::FRAC_PI_2);
        assert!(p.lon.is_finite() && p.h.is_finite());
        match p.attitude {
            Attitude::YawPitchRoll(a) => assert!(a.iter().all(|x| x.is_finite())),
            Attitude::Quaternion(q) => assert!(q.iter().all(|x| x.is_finite())),
        }
        assert_eq!(Some(p.time), ins.gps_time());
    }
});

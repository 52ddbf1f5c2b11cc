//! Any bytes as an Ouster lidar packet: the first byte picks the profile and header, the second
//! the pixels per column (1-128), the third the columns per packet (1-64), the next eight the
//! beam angles' seed; the rest is the packet. Every column, pixel and point is read.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::ouster::{Format, HeaderKind, Intrinsics, LidarPacket, Profile};

fuzz_target!(|data: &[u8]| {
    if data.len() < 11 {
        return;
    }
    let (profile, header) = match data[0] % 6 {
        0 => (Profile::Legacy, HeaderKind::Legacy),
        1 => (Profile::Single, HeaderKind::Standard),
        2 => (Profile::Dual, HeaderKind::Standard),
        3 => (Profile::LowRate, HeaderKind::Standard),
        4 => (Profile::LowRateDual, HeaderKind::Fusa),
        _ => (Profile::LowRateDual, HeaderKind::Standard),
    };
    let pixels = usize::from(data[1]) % 128 + 1;
    let columns = usize::from(data[2]) % 64 + 1;
    let Ok(format) = Format::new(profile, header, columns, pixels) else {
        return;
    };
    let seed = f64::from_le_bytes(data[3..11].try_into().unwrap());
    let alt: Vec<f64> = (0..pixels).map(|i| seed * i as f64).collect();
    let az: Vec<f64> = (0..pixels).map(|i| -seed / (i + 1) as f64).collect();
    let t = [1.0, 0.0, 0.0, seed, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let geometry = Intrinsics::new(&alt, &az, 1024, [seed, 0.0], &t);
    let body = &data[11..];
    // The packet as given, and padded to the format's length.
    let mut padded = body.to_vec();
    padded.resize(format.packet_len(), 0);
    for bytes in [body, &padded[..]] {
        let Ok(p) = LidarPacket::new_checked(bytes, format) else {
            continue;
        };
        let _ = (p.frame_id(), p.init_id(), p.serial());
        for c in p.columns() {
            let _ = (c.valid(), c.timestamp_ns(), c.encoder_count());
            let mut n = 0usize;
            c.for_each_return(|ch, r, mm| {
                assert!(ch < pixels && r < 2 && mm > 0);
                n += 1;
            });
            for ch in 0..pixels {
                let px = c.pixel(ch);
                if let Some(g) = &geometry {
                    for r in px.range_mm {
                        let _ = g.point(c.measurement_id(), ch, r);
                    }
                }
            }
        }
    }
});

//! Any bytes as a Hesai data packet and as a GPS packet: the first eight bytes seed the angle
//! corrections, the rest is the packet. Every block, channel, time and point is read.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::hesai::{Corrections, DataPacket, GpsPacket};

fuzz_target!(|data: &[u8]| {
    if data.len() < 8 {
        return;
    }
    let seed = f64::from_le_bytes(data[..8].try_into().unwrap());
    let el: Vec<f64> = (0..128).map(|i| (seed * i as f64) % 90.0).collect();
    let az: Vec<f64> = (0..64).map(|i| (-seed / (i + 1) as f64) % 180.0).collect();
    let corrections = Corrections::new(&el, &az);
    let body = &data[8..];
    if let Ok(p) = DataPacket::new_checked(body) {
        let m = p.model();
        let n = p.return_mode().returns();
        let _ = (p.unix_ns(), p.motor_rpm(), p.udp_sequence(), p.distance_unit_mm(), p.crc());
        for b in 0..m.blocks() {
            let g = corrections.as_ref().map(|c| c.block(p.azimuth(b)));
            for ch in 0..m.channels() {
                let (d, _) = p.unit(b, ch);
                let _ = (p.firing_offset_ns(b, ch), m.firing_offset_ns(b, ch, n, 2));
                if let Some(g) = &g {
                    let _ = (g.xyz(ch, f64::from(d) * 0.004), g.angles_deg(ch));
                }
            }
        }
    }
    if let Ok(g) = GpsPacket::new_checked(body) {
        let _ = (g.utc(), g.nmea(), g.pps_locked(), g.positioning());
    }
});

//! Any bytes as a Velodyne data or position packet: views, Repr parsing and decoding as the
//! product byte says and as every model.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::velodyne::{
    decode, decode_as, DataPacket, DataRepr, Model, PointBuf, PositionPacket, PositionRepr,
};

fuzz_target!(|data: &[u8]| {
    if let Ok(p) = DataPacket::new_checked(data) {
        let mut out = PointBuf::new();
        if let Ok(n) = decode(&p, &mut out) {
            assert_eq!(n, out.len());
            for pt in out.as_slice() {
                assert!(pt.x.is_finite() && pt.y.is_finite() && pt.z.is_finite());
            }
        }
        for m in Model::ALL {
            if let Ok(n) = decode_as(&p, m, &mut out) {
                assert_eq!(n, out.len());
                for pt in out.as_slice() {
                    assert!(pt.x.is_finite() && pt.y.is_finite() && pt.z.is_finite());
                    assert!(usize::from(pt.laser) < m.lasers());
                }
            }
        }
        if let Ok(repr) = DataRepr::parse(&p) {
            let mut buf = [0u8; 1206];
            repr.emit(&mut DataPacket::new_unchecked(&mut buf[..]));
            assert_eq!(&buf[..], &data[..1206]);
        }
    }
    if let Ok(p) = PositionPacket::new_checked(data) {
        let _ = p.nmea_time();
        let _ = PositionRepr::parse(&p);
    }
});

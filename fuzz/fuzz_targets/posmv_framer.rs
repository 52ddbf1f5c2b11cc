//! Any bytes through the POS MV framer (whole and split at a fuzzer-chosen point must agree),
//! the group view and every group parser; a parsed group emitted again parses the same.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::posmv::{
    Framer, GnssStatus, Group, Item, Metrics, Navigation, Pose, PpsTime, SensorNavigation,
};

fn run(parts: &[&[u8]]) -> (Vec<(u64, Vec<u8>)>, spherecal::posmv::Stats) {
    let mut f: Box<Framer<1024>> = Box::default();
    let mut out = Vec::new();
    for p in parts {
        f.consume(p, |it| {
            if let Item::Group(g) | Item::Message(g) = it.item {
                assert!(Group::new_checked(g.as_bytes()).is_ok());
                let _ = g.time_fields();
                let mut buf = [0u8; 512];
                if let Ok(n) = Navigation::parse(&g) {
                    let _ = Pose::from_navigation(&n, 2290, 18);
                    let len = n.emit(&mut buf).unwrap();
                    let again = Navigation::parse(&Group::new_checked(&buf[..len]).unwrap());
                    let mut buf2 = [0u8; 512];
                    assert_eq!(again.unwrap().emit(&mut buf2), Some(len));
                    assert_eq!(&buf[..len], &buf2[..len]);
                }
                if let Ok(s) = SensorNavigation::parse(&g) {
                    let len = s.emit(&mut buf).unwrap();
                    assert!(
                        SensorNavigation::parse(&Group::new_checked(&buf[..len]).unwrap()).is_ok()
                    );
                }
                if let Ok(s) = GnssStatus::parse(&g) {
                    let len = s.emit(&mut buf).unwrap();
                    let back =
                        GnssStatus::parse(&Group::new_checked(&buf[..len]).unwrap()).unwrap();
                    assert_eq!((back.week, back.solution), (s.week, s.solution));
                }
                if let Ok(p) = PpsTime::parse(&g) {
                    let len = p.emit(&mut buf).unwrap();
                    let back = PpsTime::parse(&Group::new_checked(&buf[..len]).unwrap()).unwrap();
                    assert_eq!((back.pps_count, back.sync), (p.pps_count, p.sync));
                }
                let _ = Metrics::parse(&g);
                out.push((it.offset, g.as_bytes().to_vec()));
            }
        });
    }
    f.finish();
    while let Some(it) = f.next() {
        if let Item::Group(g) | Item::Message(g) = it.item {
            out.push((it.offset, g.as_bytes().to_vec()));
        }
    }
    (out, *f.stats())
}

fuzz_target!(|data: &[u8]| {
    let _ = Group::new_checked(data);
    if data.is_empty() {
        return;
    }
    let split = usize::from(data[0]) * data.len() / 256;
    let whole = run(&[data]);
    let parts = run(&[&data[..split], &data[split..]]);
    assert_eq!(whole, parts);
});

//! Any bytes as the ROS 2 messages a bag holds (VelodyneScan, CommonGroup, TimeGroup, InsGroup): an error
//! or a message, never a panic; a scan's packets are all there when it parses.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::ros2::{AttitudeGroup, CommonGroup, InsGroup, TimeGroup, VelodyneScan};

fuzz_target!(|data: &[u8]| {
    if let Ok(s) = VelodyneScan::parse(data) {
        assert_eq!(s.packets().count() as u32, s.count);
    }
    if let Ok(c) = CommonGroup::parse(data) {
        let _ = c.insstatus.word();
    }
    let _ = InsGroup::parse(data);
    let _ = TimeGroup::parse(data);
    let _ = AttitudeGroup::parse(data);
});

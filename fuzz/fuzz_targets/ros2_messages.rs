//! Any bytes as the ROS 2 messages a bag holds (VelodyneScan, PandarScan, PacketMsg, CommonGroup, TimeGroup, InsGroup,
//! AttitudeGroup, PointCloud2, Imu, NavSatFix, TimeReference, and the MCAP raw log's Datagram and
//! SerialChunk): an error or a message, never a panic; a scan's packets are all
//! there when it parses; every cell of a cloud that parses reads, and becomes a return or a
//! reason.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::ros2::cloud::{Lasers, PointCloud2};
use spherecal::ros2::nav::{Imu, NavSatFix, TimeReference};
use spherecal::ros2::{AttitudeGroup, CommonGroup, InsGroup, TimeGroup, VelodyneScan};
use spherecal::velodyne::Model;

fuzz_target!(|data: &[u8]| {
    if let Ok(s) = VelodyneScan::parse(data) {
        assert_eq!(s.packets().count() as u32, s.count);
    }
    if let Ok(s) = spherecal::ros2::PandarScan::parse(data) {
        assert_eq!(s.packets().count() as u32, s.count);
    }
    let _ = spherecal::ros2::PacketMsg::parse(data);
    if let Ok(c) = CommonGroup::parse(data) {
        let _ = c.insstatus.word();
    }
    let _ = InsGroup::parse(data);
    let _ = TimeGroup::parse(data);
    let _ = AttitudeGroup::parse(data);
    if let Ok(i) = Imu::parse(data) {
        let _ = (i.enu(), i.vn_quaternion(true));
    }
    let _ = NavSatFix::parse(data);
    let _ = spherecal::ros2::raw::Datagram::parse(data);
    let _ = spherecal::ros2::raw::SerialChunk::parse(data);
    if let Ok(r) = TimeReference::parse(data) {
        let _ = r.gps_minus_host_ns(18);
    }
    if let Ok(c) = PointCloud2::parse(data) {
        let l = Lasers::new(Model::Vlp16);
        // A cloud claims up to 2^64 cells; its data bounds the ones that can be read.
        for i in 0..c.len().min(4096) {
            if let Some(p) = c.point(i) {
                let _ = l.point(&p, 0);
            }
        }
    }
});

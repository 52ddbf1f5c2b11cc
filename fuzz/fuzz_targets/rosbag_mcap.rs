//! Any bytes as a bag's MCAP file (the `mcap` crate's reader under spherecal's, zstd and lz4
//! chunks decompressed), and every message through the ROS 2 view its type names, the
//! VectorNav groups on into VN-200 frames: an error or messages, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use spherecal::ros2::{AttitudeGroup, CommonGroup, InsGroup, VelodyneScan, VN200_FRAME_MAX};

fuzz_target!(|data: &[u8]| {
    let _ = spherecal_hal::rosbag::mcap_messages_in(data, |_, ty, _, msg| match ty {
        "velodyne_msgs/msg/VelodyneScan" => {
            if let Ok(s) = VelodyneScan::parse(msg) {
                assert_eq!(s.packets().count(), s.count as usize);
            }
        }
        "vectornav_msgs/msg/CommonGroup" => {
            if let Ok(c) = CommonGroup::parse(msg) {
                let _ = c.vn200_frame(Some([0.1; 3]), Some(0.1), &mut [0u8; VN200_FRAME_MAX]);
            }
        }
        "sensor_msgs/msg/PointCloud2" => {
            if let Ok(c) = spherecal::ros2::cloud::PointCloud2::parse(msg) {
                let l = spherecal::ros2::cloud::Lasers::new(spherecal::velodyne::Model::Vlp16);
                for p in (0..c.len().min(4096)).filter_map(|i| c.point(i)) {
                    let _ = l.point(&p, 0);
                }
            }
        }
        "sensor_msgs/msg/Imu" => {
            if let Ok(i) = spherecal::ros2::nav::Imu::parse(msg) {
                let _ = (i.enu(), i.vn_quaternion(true));
            }
        }
        "sensor_msgs/msg/NavSatFix" => {
            let _ = spherecal::ros2::nav::NavSatFix::parse(msg);
        }
        "sensor_msgs/msg/TimeReference" => {
            if let Ok(r) = spherecal::ros2::nav::TimeReference::parse(msg) {
                let _ = r.gps_minus_host_ns(18);
            }
        }
        "spherecal_msgs/msg/Datagram" => {
            let _ = spherecal::ros2::raw::Datagram::parse(msg);
        }
        "spherecal_msgs/msg/SerialChunk" => {
            let _ = spherecal::ros2::raw::SerialChunk::parse(msg);
        }
        "vectornav_msgs/msg/InsGroup" => {
            let _ = InsGroup::parse(msg);
        }
        "vectornav_msgs/msg/AttitudeGroup" => {
            let _ = AttitudeGroup::parse(msg);
        }
        _ => {}
    });
});

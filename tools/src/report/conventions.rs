//! The mounting in the conventions users paste into other software (`report.json`
//! `conventions`), each from its published specification:
//!
//! - ROS 2 (REP 103: body frames x forward, y left, z up; REP 105 `base_link`): the transform
//!   of the LiDAR's frame as the ROS Velodyne driver publishes its points (`velodyne`: x
//!   forward, y left, z up) in `base_link`, as `static_transform_publisher` arguments (tf2's
//!   roll, pitch, yaw: `R = Rz(yaw) Ry(pitch) Rx(roll)`, about fixed axes) and as a URDF fixed
//!   joint (`<origin xyz rpy>`, the same angles).
//! - PDAL `filters.transformation` (a point-cloud package): the 4x4 matrix, row-major, that
//!   takes a point from the LiDAR's own frame (the Velodyne manual's: x right, y forward, z up)
//!   into the INS body frame (x forward, y starboard, z down), as its `matrix` option takes it.
//!
//! This project's own (DESIGN.md "Conventions"): the boresight `R(roll, pitch, heading) =
//! Rz(heading) Ry(pitch) Rx(roll)` takes LiDAR-frame vectors into the INS body frame, and the
//! lever arm is the LiDAR's origin in the INS body frame.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use spherecal::frames::{roll_pitch_heading, rotation};

/// The Velodyne manual's LiDAR frame (x right, y forward, z up) into the ROS driver's (x
/// forward, y left, z up): `v = A l`.
fn manual_to_ros() -> Matrix3<f64> {
    Matrix3::new(0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0)
}

/// The INS body frame (x forward, y starboard, z down) into `base_link` (x forward, y left, z
/// up): `b = C i`.
fn frd_to_flu() -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0)
}

/// The mounting in others' conventions.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Conventions {
    /// `base_link` -> `velodyne` (REP 103/105): x, y, z [m], roll, pitch, yaw [rad].
    pub ros_xyz_rpy: [f64; 6],
    /// `ros2 run tf2_ros static_transform_publisher ...` (ROS 2 Humble and later).
    pub ros2_static_transform: String,
    /// A URDF fixed joint.
    pub urdf_joint: String,
    /// PDAL `filters.transformation` `matrix`: LiDAR frame (manual's) -> INS body frame (FRD),
    /// row-major.
    pub pdal_matrix: String,
}

impl Conventions {
    /// For the boresight roll, pitch, heading [rad] and the lever arm x, y, z [m] (this
    /// project's convention).
    pub fn of(b: &[f64; 6]) -> Self {
        let r_li = rotation(b[0], b[1], b[2]);
        let a = Vector3::new(b[3], b[4], b[5]);
        // p_b = C i = C (R_li l + a) = C R_li A^T v + C a.
        let r_bv = frd_to_flu() * r_li * manual_to_ros().transpose();
        let t = frd_to_flu() * a;
        let [roll, pitch, yaw] = roll_pitch_heading(&r_bv);
        let x = [t.x, t.y, t.z, roll, pitch, yaw].map(|v| if v.abs() < 5e-13 { 0.0 } else { v });
        let ros2_static_transform = format!(
            "ros2 run tf2_ros static_transform_publisher --x {:.6} --y {:.6} --z {:.6} --roll {:.9} --pitch {:.9} --yaw {:.9} --frame-id base_link --child-frame-id velodyne",
            x[0], x[1], x[2], x[3], x[4], x[5]
        );
        let urdf_joint = format!(
            "<joint name=\"velodyne_joint\" type=\"fixed\"><parent link=\"base_link\"/><child link=\"velodyne\"/><origin xyz=\"{:.6} {:.6} {:.6}\" rpy=\"{:.9} {:.9} {:.9}\"/></joint>",
            x[0], x[1], x[2], x[3], x[4], x[5]
        );
        let m = r_li;
        let row = |i: usize, ti: f64| {
            format!(
                "{:.9} {:.9} {:.9} {:.6}",
                m[(i, 0)],
                m[(i, 1)],
                m[(i, 2)],
                ti
            )
        };
        let pdal_matrix = format!("{} {} {} 0 0 0 1", row(0, a.x), row(1, a.y), row(2, a.z));
        Self {
            ros_xyz_rpy: x,
            ros2_static_transform,
            urdf_joint,
            pdal_matrix,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hand-computed: a VLP-16 upright with its forward (y) along the vessel's bow and its x to
    /// starboard is boresight (180, 0, 90) deg here (x_i = y_l, y_i = x_l, z_i = -z_l), and in
    /// ROS the driver's frame then coincides with base_link's axes: rpy (0, 0, 0). Its lever
    /// arm 1 m forward, 2 m to starboard, 3 m down is (1, -2, -3) in base_link.
    #[test]
    fn an_upright_forward_lidar_is_the_identity_in_ros() {
        let c = Conventions::of(&[180f64.to_radians(), 0.0, 90f64.to_radians(), 1.0, 2.0, 3.0]);
        let want = [1.0, -2.0, -3.0, 0.0, 0.0, 0.0];
        for (g, w) in c.ros_xyz_rpy.iter().zip(want) {
            assert!((g - w).abs() < 1e-9, "{:?}", c.ros_xyz_rpy);
        }
        assert!(c
            .ros2_static_transform
            .contains("--x 1.000000 --y -2.000000 --z -3.000000"));
        assert!(c
            .urdf_joint
            .contains("xyz=\"1.000000 -2.000000 -3.000000\""));
        // PDAL: the manual's LiDAR frame into FRD, row-major, translation in the last column.
        let m: Vec<f64> = c
            .pdal_matrix
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect();
        let want = [
            0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0, -1.0, 3.0, 0.0, 0.0, 0.0, 1.0,
        ];
        assert_eq!(m.len(), 16);
        for (g, w) in m.iter().zip(want) {
            assert!((g - w).abs() < 1e-9, "{}", c.pdal_matrix);
        }
    }

    /// The same LiDAR turned 90 deg to port about the vertical (its forward along the vessel's
    /// port side: boresight heading 0 here) is a ROS yaw of +90 deg (y left is +90 from x
    /// forward, counter-clockwise seen from above).
    #[test]
    fn a_lidar_facing_port_is_a_positive_ros_yaw() {
        let c = Conventions::of(&[180f64.to_radians(), 0.0, 0.0, 0.0, 0.0, 0.0]);
        let [_, _, _, r, p, y] = c.ros_xyz_rpy;
        assert!(r.abs() < 1e-9 && p.abs() < 1e-9, "{:?}", c.ros_xyz_rpy);
        assert!((y - std::f64::consts::FRAC_PI_2).abs() < 1e-9, "{y}");
    }
}

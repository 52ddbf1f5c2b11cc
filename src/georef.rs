//! Georeferencing, the paper's eqs. 1-3 with the VLP-16 beam-origin offsets (DESIGN.md):
//!
//! ```text
//! u_l = [cos w sin t, cos w cos t, sin w]                          (eq. 1)
//! x_g = P_g + R_ig (a_i + R_li (d u_l + v_k e_z))                  (eqs. 2-3)
//! ```
//! l = LiDAR frame (x right, y forward, z up), i = INS body (x forward, y starboard, z down),
//! g = the site's local NED frame. `R_li` is the boresight rotation and `a_i` the lever arm.

use crate::frames::{rotation, Geodetic, LocalFrame};
use crate::velodyne::Beam;
use nalgebra::{Matrix3, Vector3};

/// The LiDAR's mounting: boresight angles and lever arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mount {
    /// Boresight roll, pitch, heading [rad] (`R_li = R(roll, pitch, heading)`).
    pub boresight: [f64; 3],
    /// Lever arm `a_i` [m] in the INS body frame.
    pub lever: Vector3<f64>,
    /// `R_li`.
    pub r_li: Matrix3<f64>,
}

impl Mount {
    /// From boresight [rad] and lever arm [m].
    pub fn new(boresight: [f64; 3], lever: [f64; 3]) -> Self {
        Self {
            boresight,
            lever: Vector3::from(lever),
            r_li: rotation(boresight[0], boresight[1], boresight[2]),
        }
    }

    /// From the parameters b = [roll, pitch, heading, ax, ay, az] of eq. 6.
    pub fn from_params(b: &Params) -> Self {
        let b = &b.0;
        Self::new([b[0], b[1], b[2]], [b[3], b[4], b[5]])
    }

    /// The parameters of eq. 6.
    pub fn params(&self) -> Params {
        Params([
            self.boresight[0],
            self.boresight[1],
            self.boresight[2],
            self.lever.x,
            self.lever.y,
            self.lever.z,
        ])
    }
}

/// The six mounting parameters b of eq. 6 in the solver's units: boresight roll, pitch,
/// heading [rad] and lever arm x, y, z [m]. People read and write them in degrees ([`DegM`]);
/// the two types keep the units apart.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Params(pub [f64; P]);

/// Number of parameters.
pub const P: usize = 6;
/// Parameter names, in order.
pub const NAMES: [&str; P] = ["roll", "pitch", "heading", "x", "y", "z"];

/// The same six in the units of the command line, the TOML files and the reports: roll,
/// pitch, heading [deg], x, y, z [m].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DegM(pub [f64; P]);

impl Params {
    /// In degrees and metres.
    pub fn deg_m(&self) -> DegM {
        let b = &self.0;
        DegM([
            b[0].to_degrees(),
            b[1].to_degrees(),
            b[2].to_degrees(),
            b[3],
            b[4],
            b[5],
        ])
    }

    /// The mounting these parameters describe.
    pub fn mount(&self) -> Mount {
        Mount::from_params(self)
    }
}

impl DegM {
    /// In radians and metres.
    pub fn params(&self) -> Params {
        let x = &self.0;
        Params([
            x[0].to_radians(),
            x[1].to_radians(),
            x[2].to_radians(),
            x[3],
            x[4],
            x[5],
        ])
    }
}

/// The platform's pose in the site frame: INS position and body -> site-NED rotation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformPose {
    /// `P_g`: the INS reference point in site NED [m].
    pub position: Vector3<f64>,
    /// `R_ig`: INS body -> site NED.
    pub r_ig: Matrix3<f64>,
}

impl PlatformPose {
    /// From an INS solution: WGS84 position and roll, pitch, heading [rad] relative to the
    /// local-level NED frame at that position (as every INS reports them), turned into the
    /// site's NED frame exactly.
    pub fn from_ins(site: &LocalFrame, at: &Geodetic, roll: f64, pitch: f64, heading: f64) -> Self {
        Self {
            position: site.to_ned(at),
            r_ig: site.from_local_level(at.lat, at.lon) * rotation(roll, pitch, heading),
        }
    }
}

/// Eq. 1: the unit beam direction in the LiDAR frame for a laser and the azimuth's sin, cos
/// (the azimuth the laser points at, its offset included).
#[inline]
pub fn beam_unit(beam: &Beam, sin_t: f64, cos_t: f64) -> Vector3<f64> {
    let cw = beam.cos_el;
    Vector3::new(cw * sin_t, cw * cos_t, beam.sin_el)
}

/// The beam origin in the LiDAR frame: the laser's vertical offset along z.
#[inline]
pub fn beam_origin_l(beam: &Beam) -> Vector3<f64> {
    Vector3::new(0.0, 0.0, beam.vertical_offset_m)
}

/// Eqs. 2-3: the return of `beam` at range `d` [m] and azimuth (sin, cos) in the site frame.
#[inline]
pub fn point(
    pose: &PlatformPose,
    mount: &Mount,
    d: f64,
    beam: &Beam,
    sin_t: f64,
    cos_t: f64,
) -> Vector3<f64> {
    let in_l = beam_unit(beam, sin_t, cos_t) * d + beam_origin_l(beam);
    pose.position + pose.r_ig * (mount.lever + mount.r_li * in_l)
}

/// The beam as a ray in the site frame: origin and unit direction (for ray tracing).
#[inline]
pub fn ray(
    pose: &PlatformPose,
    mount: &Mount,
    beam: &Beam,
    sin_t: f64,
    cos_t: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let r = pose.r_ig * mount.r_li;
    (
        pose.position + pose.r_ig * mount.lever + r * beam_origin_l(beam),
        r * beam_unit(beam, sin_t, cos_t),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::FRAC_PI_2;

    /// Hand-worked: platform heading east (90 deg) at NED (10, 20, 0); LiDAR mounted upright
    /// with boresight (0, 0, 0)... i.e. l-frame axes equal body axes; lever arm 1 m forward.
    /// Laser 7 (+7 deg) at azimuth 0 looks along l-frame y = body y = starboard = south.
    #[test]
    fn hand_worked_point() {
        let pose = PlatformPose {
            position: Vector3::new(10.0, 20.0, 0.0),
            r_ig: rotation(0.0, 0.0, FRAC_PI_2),
        };
        let mount = Mount::new([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        let d = 10.0;
        let beam = crate::velodyne::Model::Vlp16.beam(7);
        let p = point(&pose, &mount, d, beam, 0.0, 1.0);
        let w = 7f64.to_radians();
        // In l = body: (0, d cos w, d sin w - 5.1 mm); body -> NED with heading 90:
        // x_b -> east, y_b -> south (-north), z_b -> down.
        let body = Vector3::new(1.0, d * w.cos(), d * w.sin() - 0.0051);
        let want = Vector3::new(10.0 - body.y, 20.0 + body.x, body.z);
        assert!((p - want).norm() < 1e-12, "{p} vs {want}");
        // The ray meets the point at distance d.
        let (o, dir) = ray(&pose, &mount, beam, 0.0, 1.0);
        assert!((o + dir * d - p).norm() < 1e-12);
        assert!((dir.norm() - 1.0).abs() < 1e-15);
    }

    /// The paper's mounting (boresight 179.5, -44.9, 1.2 deg): the spin axis (l-frame z) points
    /// forward and up in the body frame.
    #[test]
    fn paper_mount_spin_axis() {
        let m = Mount::new(
            [
                179.5f64.to_radians(),
                (-44.9f64).to_radians(),
                1.2f64.to_radians(),
            ],
            [1.5, -1.24, -1.36],
        );
        let z = m.r_li * Vector3::z();
        assert!(z.x > 0.69 && z.z < -0.69, "{z}");
        assert_eq!(Mount::from_params(&m.params()), m);
    }

    /// Angles change units, lever arms do not.
    #[test]
    fn degrees_and_radians_kept_apart() {
        use core::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
        let d = DegM([90.0, -45.0, 180.0, 1.5, -2.0, 0.25]);
        let p = d.params();
        assert_eq!(p, Params([FRAC_PI_2, -FRAC_PI_4, PI, 1.5, -2.0, 0.25]));
        let back = p.deg_m();
        for (a, b) in back.0.iter().zip(d.0) {
            assert!((a - b).abs() < 1e-12, "{back:?}");
        }
        assert_eq!(p.mount().boresight, [FRAC_PI_2, -FRAC_PI_4, PI]);
    }
}

//! The beams' geometry from the sensor's metadata and the point of a pixel in the sensor
//! frame (Ouster firmware manual, "Lidar Range to XYZ"):
//!
//! ```text
//! theta_e = 2 pi (1 - m / W)          encoder angle of measurement id m of W per frame
//! theta_a = -2 pi azimuth_i / 360     beam i's azimuth offset
//! phi     =  2 pi altitude_i / 360    beam i's altitude
//! u  = (cos(theta_e + theta_a) cos phi, sin(theta_e + theta_a) cos phi, sin phi)
//! p_lidar = r u + (n_x cos theta_e, n_x sin theta_e, n_z) - |n| u     [mm]
//! p_sensor = lidar_to_sensor_transform * p_lidar
//! ```
//!
//! with `n = (n_x, 0, n_z)` the beam origin's offset from the lidar origin
//! (`beam_to_lidar_transform`'s translation; older metadata: `lidar_origin_to_beam_origin_mm`
//! as `n_x`). The angles are tabulated once per measurement id and beam, so a point is two
//! multiply-adds per axis.

use nalgebra::{Matrix3, Vector3};

/// Most beams a sensor has (OS0/OS1/OS2-128).
pub const MAX_BEAMS: usize = 128;
/// Most columns per frame (the 4096x5 mode of Rev 7 sensors).
pub const MAX_COLUMNS: usize = 4096;

/// A sensor's beam geometry, its transform to the sensor frame and the tables of the encoder
/// angle's sine and cosine per measurement id.
#[derive(Debug, Clone)]
pub struct Intrinsics {
    beams: usize,
    columns: usize,
    /// Per beam: the altitude's cos and sin, the azimuth offset theta_a's cos and sin, and
    /// both angles [deg].
    alt_cos: [f64; MAX_BEAMS],
    alt_sin: [f64; MAX_BEAMS],
    az_cos: [f64; MAX_BEAMS],
    az_sin: [f64; MAX_BEAMS],
    alt_deg: [f64; MAX_BEAMS],
    az_deg: [f64; MAX_BEAMS],
    /// Per measurement id: theta_e's cos and sin.
    enc_cos: [f64; MAX_COLUMNS],
    enc_sin: [f64; MAX_COLUMNS],
    /// The beam origin's offset [mm] along x and z, and its length.
    n_x: f64,
    n_z: f64,
    n: f64,
    /// `lidar_to_sensor_transform`: rotation and translation [mm].
    rot: Matrix3<f64>,
    trans: Vector3<f64>,
}

/// A pixel's point: the sensor-frame position [m], and the beam's azimuth and elevation in
/// the lidar frame [deg] (for listings).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamPoint {
    /// Position in the sensor frame [m].
    pub xyz: [f64; 3],
    /// Azimuth of the beam in the lidar frame, counter-clockwise from +x [deg, 0..360).
    pub azimuth_deg: f64,
    /// Elevation of the beam [deg].
    pub elevation_deg: f64,
}

impl Intrinsics {
    /// From the metadata's tables: `altitude_deg` and `azimuth_deg` per beam (as long as each
    /// other, 1-128), `columns` per frame (512, 1024, 2048 or 4096, at most [`MAX_COLUMNS`]), the
    /// beam origin offset `[n_x, n_z]` [mm] and the row-major 4x4 `lidar_to_sensor` [mm].
    /// `None` when the tables are not a sensor's (lengths, non-finite values).
    pub fn new(
        altitude_deg: &[f64],
        azimuth_deg: &[f64],
        columns: usize,
        beam_origin_mm: [f64; 2],
        lidar_to_sensor: &[f64; 16],
    ) -> Option<Self> {
        let beams = altitude_deg.len();
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if beams == 0
            || beams > MAX_BEAMS
            || azimuth_deg.len() != beams
            || !(1..=MAX_COLUMNS).contains(&columns)
            || !finite(altitude_deg)
            || !finite(azimuth_deg)
            || !finite(&beam_origin_mm)
            || !finite(lidar_to_sensor)
        {
            return None;
        }
        let mut s = Self {
            beams,
            columns,
            alt_cos: [0.0; MAX_BEAMS],
            alt_sin: [0.0; MAX_BEAMS],
            az_cos: [0.0; MAX_BEAMS],
            az_sin: [0.0; MAX_BEAMS],
            alt_deg: [0.0; MAX_BEAMS],
            az_deg: [0.0; MAX_BEAMS],
            enc_cos: [0.0; MAX_COLUMNS],
            enc_sin: [0.0; MAX_COLUMNS],
            n_x: beam_origin_mm[0],
            n_z: beam_origin_mm[1],
            n: if beam_origin_mm[1] != 0.0 {
                libm::hypot(beam_origin_mm[0], beam_origin_mm[1])
            } else {
                beam_origin_mm[0]
            },
            rot: Matrix3::from_fn(|r, c| lidar_to_sensor[4 * r + c]),
            trans: Vector3::new(lidar_to_sensor[3], lidar_to_sensor[7], lidar_to_sensor[11]),
        };
        for i in 0..beams {
            (s.alt_sin[i], s.alt_cos[i]) = libm::sincos(altitude_deg[i].to_radians());
            (s.az_sin[i], s.az_cos[i]) = libm::sincos(-azimuth_deg[i].to_radians());
            (s.alt_deg[i], s.az_deg[i]) = (altitude_deg[i], azimuth_deg[i]);
        }
        for m in 0..columns {
            let te = core::f64::consts::TAU * (1.0 - m as f64 / columns as f64);
            (s.enc_sin[m], s.enc_cos[m]) = libm::sincos(te);
        }
        Some(s)
    }

    /// Beams (pixels per column).
    pub fn beams(&self) -> usize {
        self.beams
    }

    /// Columns per frame.
    pub fn columns(&self) -> usize {
        self.columns
    }

    /// The geometry of measurement id `m` (modulo the columns per frame): what every beam's
    /// point in that column shares, for [`ColumnGeometry::point`].
    #[inline]
    pub fn column(&self, m: u16) -> ColumnGeometry<'_> {
        let m = usize::from(m) % self.columns;
        let (ce, se) = (self.enc_cos[m], self.enc_sin[m]);
        // With e1 = (ce, se, 0), e2 = (-se, ce, 0), e3 = z: a beam's direction is
        // u = cos(phi) cos(theta_a) e1 + cos(phi) sin(theta_a) e2 + sin(phi) e3, and its point
        // p = (r - |n|) R u + n_x R e1 + n_z R e3 + t.
        let re1 = self.rot * Vector3::new(ce, se, 0.0);
        let re2 = self.rot * Vector3::new(-se, ce, 0.0);
        let re3 = self.rot.column(2).into_owned();
        ColumnGeometry {
            g: self,
            re1,
            re2,
            re3,
            base: re1 * self.n_x + re3 * self.n_z + self.trans,
            turn_deg: 360.0 * (1.0 - m as f64 / self.columns as f64),
        }
    }

    /// The point of beam `beam` (modulo the beams) at measurement id `m` (modulo the columns
    /// per frame), range `range_mm`: from the tables, no trigonometry.
    pub fn point(&self, m: u16, beam: usize, range_mm: u32) -> BeamPoint {
        self.column(m).point(beam, range_mm)
    }
}

/// One measurement id's geometry ([`Intrinsics::column`]).
#[derive(Debug, Clone, Copy)]
pub struct ColumnGeometry<'a> {
    g: &'a Intrinsics,
    re1: Vector3<f64>,
    re2: Vector3<f64>,
    re3: Vector3<f64>,
    base: Vector3<f64>,
    turn_deg: f64,
}

impl ColumnGeometry<'_> {
    /// The sensor-frame position [m] of beam `beam` (modulo the beams) at `range_mm`.
    #[inline]
    pub fn xyz(&self, beam: usize, range_mm: u32) -> [f64; 3] {
        let g = self.g;
        let i = beam % g.beams;
        let a = g.alt_cos[i] * g.az_cos[i];
        let b = g.alt_cos[i] * g.az_sin[i];
        let ru = self.re1 * a + self.re2 * b + self.re3 * g.alt_sin[i];
        let p = ru * (f64::from(range_mm) - g.n) + self.base;
        [p.x * 1e-3, p.y * 1e-3, p.z * 1e-3]
    }

    /// The point of beam `beam` at `range_mm`, with the beam's azimuth and elevation.
    pub fn point(&self, beam: usize, range_mm: u32) -> BeamPoint {
        let i = beam % self.g.beams;
        // Into [0, 360).
        let az = self.turn_deg - self.g.az_deg[i];
        let az = az - 360.0 * libm::floor(az / 360.0);
        BeamPoint {
            xyz: self.xyz(beam, range_mm),
            azimuth_deg: az,
            elevation_deg: self.g.alt_deg[i],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const IDENTITY: [f64; 16] = [
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ];

    /// Hand-computed points: measurement id 0 looks along +x (theta_e = 2 pi); a quarter frame
    /// later along -y (the sensor turns clockwise seen from above); a beam 10 deg up at
    /// 10 m rises 10 sin(10 deg); the beam origin offset (15.806 mm, an OS1's) moves the
    /// point to `r - n` along the beam plus `n` along the encoder direction; the OS1's
    /// lidar-to-sensor transform turns x and y over and lifts z by 36.18 mm.
    #[test]
    fn points_are_the_manuals_equations() {
        let g = Intrinsics::new(&[0.0, 10.0], &[0.0, 0.0], 1024, [0.0, 0.0], &IDENTITY).unwrap();
        let p = g.point(0, 0, 10_000);
        assert!(
            (p.xyz[0] - 10.0).abs() < 1e-12 && p.xyz[1].abs() < 1e-9,
            "{p:?}"
        );
        let p = g.point(256, 0, 10_000);
        assert!(
            (p.xyz[1] + 10.0).abs() < 1e-9 && p.xyz[0].abs() < 1e-9,
            "{p:?}"
        );
        assert!((p.azimuth_deg - 270.0).abs() < 1e-9);
        let p = g.point(0, 1, 10_000);
        assert!((p.xyz[2] - 10.0 * 10f64.to_radians().sin()).abs() < 1e-12);
        assert!((p.elevation_deg - 10.0).abs() < 1e-12);
        // Beam azimuth +4.24 deg (to the left of the encoder's direction): theta_a negative.
        let g = Intrinsics::new(&[0.0], &[4.24], 1024, [15.806, 0.0], &IDENTITY).unwrap();
        let p = g.point(0, 0, 10_000);
        let a = -4.24f64.to_radians();
        let want = [9.984194 * a.cos() + 0.015806, 9.984194 * a.sin()];
        assert!(
            (p.xyz[0] - want[0]).abs() < 1e-9 && (p.xyz[1] - want[1]).abs() < 1e-9,
            "{p:?}"
        );
        let os1 = [
            -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 36.18, 0.0, 0.0, 0.0, 1.0,
        ];
        let g = Intrinsics::new(&[0.0], &[0.0], 1024, [0.0, 0.0], &os1).unwrap();
        let p = g.point(0, 0, 10_000);
        assert!((p.xyz[0] + 10.0).abs() < 1e-12 && (p.xyz[2] - 0.03618).abs() < 1e-12);
        assert!(Intrinsics::new(&[0.0; 3], &[0.0; 2], 1024, [0.0; 2], &IDENTITY).is_none());
        assert!(Intrinsics::new(&[f64::NAN], &[0.0], 1024, [0.0; 2], &IDENTITY).is_none());
        assert!(Intrinsics::new(&[0.0], &[0.0], 0, [0.0; 2], &IDENTITY).is_none());
    }
}

//! Rotations and WGS84 geodesy (DESIGN.md "Conventions"):
//! - one rotation for platform attitude and boresight, `R(roll, pitch, heading) =
//!   Rz(heading) Ry(pitch) Rx(roll)`, body -> NED;
//! - exact WGS84 geodetic <-> ECEF (NIMA TR8350.2 eq. 4-14; inverse by Bowring's iteration to
//!   machine precision) and ECEF <-> local NED at a site origin, no flat-earth shortcut.

use nalgebra::{Matrix3, Vector3};

/// WGS84 semi-major axis [m] (NIMA TR8350.2 table 3.1).
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// First eccentricity squared.
pub const WGS84_E2: f64 = WGS84_F * (2.0 - WGS84_F);
/// Semi-minor axis [m].
pub const WGS84_B: f64 = WGS84_A * (1.0 - WGS84_F);

/// `R(roll, pitch, heading) = Rz(heading) Ry(pitch) Rx(roll)` [rad]: body -> NED.
pub fn rotation(roll: f64, pitch: f64, heading: f64) -> Matrix3<f64> {
    let (sr, cr) = libm::sincos(roll);
    let (sp, cp) = libm::sincos(pitch);
    let (sh, ch) = libm::sincos(heading);
    Matrix3::new(
        ch * cp,
        ch * sp * sr - sh * cr,
        ch * sp * cr + sh * sr,
        sh * cp,
        sh * sp * sr + ch * cr,
        sh * sp * cr - ch * sr,
        -sp,
        cp * sr,
        cp * cr,
    )
}

/// Roll, pitch, heading [rad] of a rotation built by [`rotation`] (pitch in [-pi/2, pi/2],
/// heading in (-pi, pi]).
pub fn roll_pitch_heading(m: &Matrix3<f64>) -> [f64; 3] {
    let pitch = libm::asin((-m[(2, 0)]).clamp(-1.0, 1.0));
    let roll = libm::atan2(m[(2, 1)], m[(2, 2)]);
    let heading = libm::atan2(m[(1, 0)], m[(0, 0)]);
    [roll, pitch, heading]
}

/// A WGS84 geodetic position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geodetic {
    /// Latitude [rad].
    pub lat: f64,
    /// Longitude [rad].
    pub lon: f64,
    /// Ellipsoidal height [m].
    pub h: f64,
}

impl Geodetic {
    /// From degrees and metres (the edges: site files, NMEA, VN-200 output).
    pub fn from_deg(lat_deg: f64, lon_deg: f64, h: f64) -> Self {
        Self {
            lat: lat_deg.to_radians(),
            lon: lon_deg.to_radians(),
            h,
        }
    }
}

/// Geodetic -> ECEF [m] (TR8350.2 eq. 4-14).
pub fn geodetic_to_ecef(g: &Geodetic) -> Vector3<f64> {
    let (sl, cl) = libm::sincos(g.lat);
    let (so, co) = libm::sincos(g.lon);
    let n = WGS84_A / libm::sqrt(1.0 - WGS84_E2 * sl * sl);
    Vector3::new(
        (n + g.h) * cl * co,
        (n + g.h) * cl * so,
        (n * (1.0 - WGS84_E2) + g.h) * sl,
    )
}

/// ECEF -> geodetic, by Bowring's parametric-latitude iteration (converges to 1e-15 rad in
/// three steps anywhere above the Earth's centre region).
pub fn ecef_to_geodetic(x: &Vector3<f64>) -> Geodetic {
    let p = libm::hypot(x.x, x.y);
    let lon = libm::atan2(x.y, x.x);
    let ep2 = WGS84_E2 / (1.0 - WGS84_E2);
    // Parametric latitude start.
    let mut beta = libm::atan2(x.z, (1.0 - WGS84_F) * p);
    let mut lat = 0.0;
    for _ in 0..5 {
        let (sb, cb) = libm::sincos(beta);
        lat = libm::atan2(
            x.z + ep2 * WGS84_B * sb * sb * sb,
            p - WGS84_E2 * WGS84_A * cb * cb * cb,
        );
        let nb = libm::atan2((1.0 - WGS84_F) * libm::sin(lat), libm::cos(lat));
        if (nb - beta).abs() < 1e-16 {
            break;
        }
        beta = nb;
    }
    let (sl, cl) = libm::sincos(lat);
    let n = WGS84_A / libm::sqrt(1.0 - WGS84_E2 * sl * sl);
    // Height: well conditioned at any latitude.
    let h = p * cl + x.z * sl - WGS84_A * WGS84_A / n;
    Geodetic { lat, lon, h }
}

/// ECEF -> NED rotation at a geodetic position (rows: north, east, down in ECEF).
pub fn ecef_to_ned_rotation(lat: f64, lon: f64) -> Matrix3<f64> {
    let (sl, cl) = libm::sincos(lat);
    let (so, co) = libm::sincos(lon);
    Matrix3::new(
        -sl * co,
        -sl * so,
        cl,
        -so,
        co,
        0.0,
        -cl * co,
        -cl * so,
        -sl,
    )
}

/// The site's local NED tangent frame at a WGS84 origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    /// The origin.
    pub origin: Geodetic,
    origin_ecef: Vector3<f64>,
    r_en: Matrix3<f64>,
}

impl LocalFrame {
    /// The frame at `origin`.
    pub fn new(origin: Geodetic) -> Self {
        Self {
            origin,
            origin_ecef: geodetic_to_ecef(&origin),
            r_en: ecef_to_ned_rotation(origin.lat, origin.lon),
        }
    }

    /// ECEF -> local NED [m].
    pub fn ecef_to_ned(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.r_en * (x - self.origin_ecef)
    }

    /// Local NED -> ECEF [m].
    pub fn ned_to_ecef(&self, ned: &Vector3<f64>) -> Vector3<f64> {
        self.origin_ecef + self.r_en.transpose() * ned
    }

    /// Geodetic -> local NED.
    pub fn to_ned(&self, g: &Geodetic) -> Vector3<f64> {
        self.ecef_to_ned(&geodetic_to_ecef(g))
    }

    /// Local NED -> geodetic.
    pub fn to_geodetic(&self, ned: &Vector3<f64>) -> Geodetic {
        ecef_to_geodetic(&self.ned_to_ecef(ned))
    }

    /// Rotation from the local-level NED frame at `(lat, lon)` (in which an INS reports its
    /// attitude) to the site's NED frame. Identity at the origin; about 1.6e-5 rad per 100 m.
    pub fn from_local_level(&self, lat: f64, lon: f64) -> Matrix3<f64> {
        self.r_en * ecef_to_ned_rotation(lat, lon).transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::FRAC_PI_2;

    fn close(a: &Vector3<f64>, b: &Vector3<f64>, tol: f64) -> bool {
        (a - b).norm() < tol
    }

    #[test]
    fn heading_90_maps_body_x_to_east() {
        let r = rotation(0.0, 0.0, FRAC_PI_2);
        assert!(close(
            &(r * Vector3::x()),
            &Vector3::new(0.0, 1.0, 0.0),
            1e-15
        ));
        // Starboard (body y) then points south.
        assert!(close(
            &(r * Vector3::y()),
            &Vector3::new(-1.0, 0.0, 0.0),
            1e-15
        ));
    }

    #[test]
    fn pitch_up_raises_the_nose_and_roll_dips_starboard() {
        // Pitch +30 deg: body x points north and up (NED down negative).
        let r = rotation(0.0, 30f64.to_radians(), 0.0);
        let x = r * Vector3::x();
        assert!(close(
            &x,
            &Vector3::new(3f64.sqrt() / 2.0, 0.0, -0.5),
            1e-15
        ));
        // Roll +30 deg: body y (starboard) points east and down.
        let r = rotation(30f64.to_radians(), 0.0, 0.0);
        assert!(close(
            &(r * Vector3::y()),
            &Vector3::new(0.0, 3f64.sqrt() / 2.0, 0.5),
            1e-15
        ));
    }

    #[test]
    fn rotation_is_z_y_x_and_angles_come_back() {
        let (r, p, h): (f64, f64, f64) = (0.3, -0.7, 2.9);
        let rz = Matrix3::new(h.cos(), -h.sin(), 0.0, h.sin(), h.cos(), 0.0, 0.0, 0.0, 1.0);
        let ry = Matrix3::new(p.cos(), 0.0, p.sin(), 0.0, 1.0, 0.0, -p.sin(), 0.0, p.cos());
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, r.cos(), -r.sin(), 0.0, r.sin(), r.cos());
        assert!((rotation(r, p, h) - rz * ry * rx).norm() < 1e-15);
        let back = roll_pitch_heading(&rotation(r, p, h));
        assert!(
            (back[0] - r).abs() < 1e-14
                && (back[1] - p).abs() < 1e-14
                && (back[2] - h).abs() < 1e-14
        );
    }

    #[test]
    fn ecef_of_known_points() {
        // Equator / prime meridian, and the pole (TR8350.2: b = 6356752.3142 m).
        assert!(close(
            &geodetic_to_ecef(&Geodetic::from_deg(0.0, 0.0, 0.0)),
            &Vector3::new(WGS84_A, 0.0, 0.0),
            1e-9
        ));
        assert!(close(
            &geodetic_to_ecef(&Geodetic::from_deg(90.0, 0.0, 0.0)),
            &Vector3::new(0.0, 0.0, 6_356_752.314_245),
            1e-5
        ));
        // Equator at 90 E, 1000 m up.
        assert!(close(
            &geodetic_to_ecef(&Geodetic::from_deg(0.0, 90.0, 1000.0)),
            &Vector3::new(0.0, WGS84_A + 1000.0, 0.0),
            1e-8
        ));
        // 45 N: N = a / sqrt(1 - e2/2); x = z-scale worked by hand.
        let n = WGS84_A / (1.0 - WGS84_E2 / 2.0).sqrt();
        let s = 0.5f64.sqrt();
        let want = Vector3::new(n * s, 0.0, n * (1.0 - WGS84_E2) * s);
        assert!(close(
            &geodetic_to_ecef(&Geodetic::from_deg(45.0, 0.0, 0.0)),
            &want,
            1e-8
        ));
    }

    #[test]
    fn geodetic_round_trip_everywhere() {
        for lat in [
            -89.9, -60.0, -12.3, 0.0, 0.001, 36.829_13, 45.0, 78.0, 89.99,
        ] {
            for lon in [-179.9, -2.407_57, 0.0, 100.0] {
                for h in [-100.0, 0.0, 35.2, 10_000.0] {
                    let g = Geodetic::from_deg(lat, lon, h);
                    let b = ecef_to_geodetic(&geodetic_to_ecef(&g));
                    assert!((b.lat - g.lat).abs() < 1e-14, "{lat} {lon} {h}");
                    assert!((b.lon - g.lon).abs() < 1e-14);
                    assert!((b.h - g.h).abs() < 1e-7, "{} vs {h}", b.h);
                }
            }
        }
    }

    #[test]
    fn ned_of_simple_offsets() {
        let site = LocalFrame::new(Geodetic::from_deg(45.0, 7.0, 100.0));
        // Straight up 10 m: down = -10.
        assert!(close(
            &site.to_ned(&Geodetic::from_deg(45.0, 7.0, 110.0)),
            &Vector3::new(0.0, 0.0, -10.0),
            1e-8
        ));
        // A small step north along the meridian, at the origin's height h = 100 m: the arc is
        // (M + h) dlat with the meridian radius M = a(1-e2)/(1-e2 sin^2)^1.5.
        let m = WGS84_A * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * 0.5).powf(1.5);
        let dlat = 100.0 / (m + 100.0);
        let ned = site.to_ned(&Geodetic {
            lat: 45f64.to_radians() + dlat,
            lon: 7f64.to_radians(),
            h: 100.0,
        });
        assert!((ned.x - 100.0).abs() < 1e-3, "{ned}");
        // The ellipsoid curves away: 100 m north at constant height is ~0.8 mm below the plane.
        assert!(ned.z > 0.0 && ned.z < 1e-3);
        assert!(ned.y.abs() < 1e-9);
        // Round trip.
        let p = Vector3::new(123.4, -56.7, 8.9);
        assert!(close(&site.to_ned(&site.to_geodetic(&p)), &p, 1e-8));
    }

    #[test]
    fn local_level_rotation() {
        let site = LocalFrame::new(Geodetic::from_deg(45.0, 7.0, 0.0));
        let g = site.to_geodetic(&Vector3::new(0.0, 100.0, 0.0));
        let c = site.from_local_level(g.lat, g.lon);
        // The two NED frames differ by a rotation of dlon = 100 m / (N cos lat) = 2.2e-5 rad
        // (about north by dlon cos lat, about down by dlon sin lat): |C - I|_F = sqrt(2) dlon.
        let n = WGS84_A / (1.0 - WGS84_E2 / 2.0).sqrt();
        let dlon = 100.0 / (n * 0.5f64.sqrt());
        assert!(((c - Matrix3::identity()).norm() - 2f64.sqrt() * dlon).abs() < 1e-9);
        let c0 = site.from_local_level(site.origin.lat, site.origin.lon);
        assert!((c0 - Matrix3::identity()).norm() < 1e-15);
    }
}

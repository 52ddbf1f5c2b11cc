//! What the beams can hit: the target spheres (the paper's eqs. 4-5: the line-sphere
//! intersection), and clutter — vertical poles (tripods) and boxes (dock slab, quay wall).
//! Water returns nothing.

use nalgebra::Vector3;

/// A shape in site NED [m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Sphere: centre and radius.
    Sphere {
        /// Centre.
        c: Vector3<f64>,
        /// Radius.
        r: f64,
    },
    /// Vertical cylinder (a pole): bottom centre, radius, height (upwards).
    Pole {
        /// Bottom centre (NED; the top is `height` metres higher, i.e. smaller down).
        base: Vector3<f64>,
        /// Radius.
        r: f64,
        /// Height.
        height: f64,
    },
    /// Axis-aligned box: minimum and maximum corners.
    Box {
        /// Minimum north, east, down.
        min: Vector3<f64>,
        /// Maximum north, east, down.
        max: Vector3<f64>,
    },
}

/// A shape in the scene; `target` is the index of a calibration sphere, `None` for clutter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Object {
    /// The shape.
    pub shape: Shape,
    /// Which target sphere this is, if any.
    pub target: Option<u8>,
}

impl Object {
    /// A bounding sphere (centre, radius) for broad-phase culling.
    pub fn bound(&self) -> (Vector3<f64>, f64) {
        match self.shape {
            Shape::Sphere { c, r } => (c, r),
            Shape::Pole { base, r, height } => (
                base - Vector3::new(0.0, 0.0, height / 2.0),
                libm::hypot(r, height / 2.0),
            ),
            Shape::Box { min, max } => ((min + max) / 2.0, (max - min).norm() / 2.0),
        }
    }
}

/// Eqs. 4-5: the ray `o + t d` (|d| = 1) meets the sphere where
/// `t^2 + 2 t d.(o - c) + |o - c|^2 - r^2 = 0`. Returns the nearest `t > 0` (the exit point
/// when `o` is inside; the touching point of a tangent ray), or `None`.
pub fn ray_sphere(o: &Vector3<f64>, d: &Vector3<f64>, c: &Vector3<f64>, r: f64) -> Option<f64> {
    let oc = o - c;
    let b = d.dot(&oc);
    let k = oc.norm_squared() - r * r;
    let disc = b * b - k;
    if disc < 0.0 {
        return None;
    }
    let s = libm::sqrt(disc);
    let (t1, t2) = (-b - s, -b + s);
    if t1 > 0.0 {
        Some(t1)
    } else if t2 > 0.0 {
        Some(t2)
    } else {
        None
    }
}

/// Ray against a vertical pole's side (caps ignored: thin poles).
pub fn ray_pole(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    base: &Vector3<f64>,
    r: f64,
    height: f64,
) -> Option<f64> {
    let (ox, oy) = (o.x - base.x, o.y - base.y);
    let a = d.x * d.x + d.y * d.y;
    if a < 1e-18 {
        return None;
    }
    let b = ox * d.x + oy * d.y;
    let k = ox * ox + oy * oy - r * r;
    let disc = b * b - a * k;
    if disc < 0.0 {
        return None;
    }
    let s = libm::sqrt(disc);
    for t in [(-b - s) / a, (-b + s) / a] {
        let z = o.z + t * d.z;
        if t > 0.0 && z <= base.z && z >= base.z - height {
            return Some(t);
        }
    }
    None
}

/// Ray against an axis-aligned box (slab method); the entry point, or the exit from inside.
pub fn ray_box(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    min: &Vector3<f64>,
    max: &Vector3<f64>,
) -> Option<f64> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..3 {
        if d[i].abs() < 1e-15 {
            if o[i] < min[i] || o[i] > max[i] {
                return None;
            }
            continue;
        }
        let (a, b) = ((min[i] - o[i]) / d[i], (max[i] - o[i]) / d[i]);
        let (a, b) = if a < b { (a, b) } else { (b, a) };
        t0 = t0.max(a);
        t1 = t1.min(b);
    }
    if t0 > t1 || t1 <= 0.0 {
        None
    } else if t0 > 0.0 {
        Some(t0)
    } else {
        Some(t1)
    }
}

impl Shape {
    /// Nearest intersection distance along a unit ray.
    pub fn intersect(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
        match self {
            Shape::Sphere { c, r } => ray_sphere(o, d, c, *r),
            Shape::Pole { base, r, height } => ray_pole(o, d, base, *r, *height),
            Shape::Box { min, max } => ray_box(o, d, min, max),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    #[test]
    fn sphere_hand_worked_cases() {
        let c = v(10.0, 0.0, 0.0);
        let near = |t: Option<f64>, want: f64| t.is_some_and(|t| (t - want).abs() < 1e-12);
        // Through the centre: hits at 10 - r.
        assert!(near(
            ray_sphere(&v(0.0, 0.0, 0.0), &v(1.0, 0.0, 0.0), &c, 0.19),
            9.81
        ));
        // Tangent: offset by exactly r, touches at t = 10.
        let t = ray_sphere(&v(0.0, 0.19, 0.0), &v(1.0, 0.0, 0.0), &c, 0.19).unwrap();
        assert!((t - 10.0).abs() < 1e-9);
        // Just outside the tangent: miss.
        assert_eq!(
            ray_sphere(&v(0.0, 0.1901, 0.0), &v(1.0, 0.0, 0.0), &c, 0.19),
            None
        );
        // Behind the sensor: both roots negative.
        assert_eq!(
            ray_sphere(&v(0.0, 0.0, 0.0), &v(-1.0, 0.0, 0.0), &c, 0.19),
            None
        );
        // From inside: the exit point, r away from the centre.
        assert!(near(
            ray_sphere(&v(10.0, 0.0, 0.0), &v(0.0, 1.0, 0.0), &c, 0.19),
            0.19
        ));
        // Oblique: from (0, 0.1, 0) along x: chord half-length sqrt(r^2 - 0.1^2).
        let t = ray_sphere(&v(0.0, 0.1, 0.0), &v(1.0, 0.0, 0.0), &c, 0.19).unwrap();
        assert!((t - (10.0 - (0.19f64 * 0.19 - 0.01).sqrt())).abs() < 1e-12);
    }

    #[test]
    fn pole_and_box_hand_worked() {
        // Pole of radius 0.05 at (5, 0), from down 0 up to down -2.
        let base = v(5.0, 0.0, 0.0);
        assert!(
            (ray_pole(&v(0.0, 0.0, -1.0), &v(1.0, 0.0, 0.0), &base, 0.05, 2.0).unwrap() - 4.95)
                .abs()
                < 1e-12
        );
        assert_eq!(
            ray_pole(&v(0.0, 0.0, -3.0), &v(1.0, 0.0, 0.0), &base, 0.05, 2.0),
            None
        ); // above it
           // Box from (1,-1,-1) to (2,1,1): entry at 1, from inside exit at 2.
        let (mn, mx) = (v(1.0, -1.0, -1.0), v(2.0, 1.0, 1.0));
        assert_eq!(
            ray_box(&v(0.0, 0.0, 0.0), &v(1.0, 0.0, 0.0), &mn, &mx),
            Some(1.0)
        );
        assert_eq!(
            ray_box(&v(1.5, 0.0, 0.0), &v(1.0, 0.0, 0.0), &mn, &mx),
            Some(0.5)
        );
        assert_eq!(
            ray_box(&v(0.0, 2.0, 0.0), &v(1.0, 0.0, 0.0), &mn, &mx),
            None
        );
    }

    /// Against a brute-force march along random rays.
    #[test]
    fn sphere_matches_a_ray_march() {
        let mut rng = super::super::rng::Rng::new(3);
        let c = v(6.0, -2.0, 1.0);
        let r = 0.5;
        for _ in 0..200 {
            let o = v(
                rng.range(-2.0, 2.0),
                rng.range(-2.0, 2.0),
                rng.range(-2.0, 2.0),
            );
            let target = c + v(
                rng.range(-0.8, 0.8),
                rng.range(-0.8, 0.8),
                rng.range(-0.8, 0.8),
            );
            let d = (target - o).normalize();
            // March in 1e-4 m steps to the first point inside.
            let mut hit = None;
            let mut t = 0.0;
            while t < 12.0 {
                if (o + d * t - c).norm() <= r {
                    hit = Some(t);
                    break;
                }
                t += 1e-4;
            }
            match (ray_sphere(&o, &d, &c, r), hit) {
                (Some(a), Some(b)) => assert!(a <= b + 1e-12 && b - a < 1.1e-4, "{a} vs {b}"),
                (None, None) => {}
                (a, b) => {
                    // Grazing rays may differ by less than one march step.
                    let closest = (c - o).cross(&d).norm();
                    assert!((closest - r).abs() < 1e-3, "{a:?} vs {b:?}");
                }
            }
        }
    }
}

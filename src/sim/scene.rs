//! What the beams can hit: the target spheres (the paper's eqs. 4-5, the line-sphere
//! intersection) and the clutter of a real site — finite cylinders of any axis (poles, bollards,
//! tripod legs, rails, masts), oriented boxes (deck slabs, quay walls, buildings, crates,
//! vehicles) and flat rectangles. Each object has a diffuse reflectivity, may move at a
//! constant velocity (a person walking along the deck), and lives either in the site frame or
//! fixed to the vessel (its rail, mast and antenna, which a real VLP-16 sees on every rotation).
//! Water returns nothing (the simulator's water surface, [`Water`]) except specular glints.

use nalgebra::{Matrix3, Vector3};

/// A shape, in its object's frame (site NED, or the INS body frame for vessel parts) [m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Sphere: centre and radius.
    Sphere {
        /// Centre.
        c: Vector3<f64>,
        /// Radius.
        r: f64,
    },
    /// A finite solid cylinder from `a` to `b` (end caps included), any direction.
    Cylinder {
        /// One end of the axis.
        a: Vector3<f64>,
        /// The other end.
        b: Vector3<f64>,
        /// Radius.
        r: f64,
    },
    /// An oriented box: centre, half sizes along its own axes, and the rotation from its axes
    /// into the frame (columns = the box axes).
    Box {
        /// Centre.
        c: Vector3<f64>,
        /// Half sizes along the box axes.
        half: Vector3<f64>,
        /// Box axes -> frame.
        rot: Matrix3<f64>,
    },
    /// A flat parallelogram without thickness: corner `p`, edges `u` and `v`.
    Rect {
        /// Corner.
        p: Vector3<f64>,
        /// First edge.
        u: Vector3<f64>,
        /// Second edge.
        v: Vector3<f64>,
    },
}

/// The frame an object's shape is given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Frame {
    /// The site's local NED frame: the site's scenery.
    Site,
    /// The INS body frame (x forward, y starboard, z down): the vessel's own structure.
    Body,
}

/// A shape in the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Object {
    /// The shape (where it is at trajectory time 0 if it moves).
    pub shape: Shape,
    /// Which target sphere this is, if any.
    pub target: Option<u8>,
    /// Diffuse (Lambertian) reflectivity 0..1: the VLP-16's calibrated reflectivity / 100
    /// (manual section 6.1).
    pub reflectivity: f64,
    /// Constant velocity in the site frame [m/s] (site objects only).
    pub velocity: Vector3<f64>,
    /// The frame of `shape`.
    pub frame: Frame,
}

impl Object {
    /// A static site object of reflectivity 0.5.
    pub fn new(shape: Shape, target: Option<u8>) -> Self {
        Self {
            shape,
            target,
            reflectivity: 0.5,
            velocity: Vector3::zeros(),
            frame: Frame::Site,
        }
    }

    /// The same object with another reflectivity.
    pub fn with_reflectivity(mut self, rho: f64) -> Self {
        self.reflectivity = rho;
        self
    }

    /// A bounding sphere (centre, radius) at trajectory time 0, for broad-phase culling.
    pub fn bound(&self) -> (Vector3<f64>, f64) {
        self.shape.bound()
    }

    /// The object moves.
    pub fn moves(&self) -> bool {
        self.velocity != Vector3::zeros()
    }
}

/// The water surface of a site: a horizontal plane that absorbs the beam (no return at
/// 905 nm) except for specular glints close to nadir.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Water {
    /// Its height as NED down [m].
    pub down: f64,
    /// Beams within this angle of the vertical may glint [rad].
    pub specular: f64,
    /// Probability that such a beam returns from the surface.
    pub specular_prob: f64,
}

impl Water {
    /// Distance along a ray to the surface (from above), if the ray goes down to it.
    pub fn intersect(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
        if d.z <= 1e-12 || o.z >= self.down {
            return None;
        }
        Some((self.down - o.z) / d.z)
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

/// Ray against a finite solid cylinder from `a` to `b` of radius `r`: its side and its two end
/// caps; the nearest `t > 0`.
pub fn ray_cylinder(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    r: f64,
) -> Option<f64> {
    let axis = b - a;
    let len = axis.norm();
    if len <= 0.0 {
        return None;
    }
    let w = axis / len;
    let ao = o - a;
    // Components perpendicular to the axis.
    let (dw, aow) = (d.dot(&w), ao.dot(&w));
    let dp = d - w * dw;
    let op = ao - w * aow;
    let mut best: Option<f64> = None;
    let mut take = |t: f64| {
        if t > 0.0 && best.is_none_or(|b| t < b) {
            best = Some(t);
        }
    };
    let qa = dp.norm_squared();
    if qa > 1e-18 {
        let qb = op.dot(&dp);
        let qc = op.norm_squared() - r * r;
        let disc = qb * qb - qa * qc;
        if disc >= 0.0 {
            let s = libm::sqrt(disc);
            for t in [(-qb - s) / qa, (-qb + s) / qa] {
                let h = aow + t * dw;
                if (0.0..=len).contains(&h) {
                    take(t);
                }
            }
        }
    }
    if dw.abs() > 1e-15 {
        for h in [0.0, len] {
            let t = (h - aow) / dw;
            if (op + dp * t).norm_squared() <= r * r {
                take(t);
            }
        }
    }
    best
}

/// Ray against an oriented box (slab method in the box's axes); the entry point, or the exit
/// from inside.
pub fn ray_box(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    c: &Vector3<f64>,
    half: &Vector3<f64>,
    rot: &Matrix3<f64>,
) -> Option<f64> {
    let ob = rot.tr_mul(&(o - c));
    let db = rot.tr_mul(d);
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..3 {
        if db[i].abs() < 1e-15 {
            if ob[i].abs() > half[i] {
                return None;
            }
            continue;
        }
        let (p, q) = ((-half[i] - ob[i]) / db[i], (half[i] - ob[i]) / db[i]);
        let (p, q) = if p < q { (p, q) } else { (q, p) };
        t0 = t0.max(p);
        t1 = t1.min(q);
    }
    if t0 > t1 || t1 <= 0.0 {
        None
    } else if t0 > 0.0 {
        Some(t0)
    } else {
        Some(t1)
    }
}

/// Ray against a flat parallelogram (either side).
pub fn ray_rect(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    p: &Vector3<f64>,
    u: &Vector3<f64>,
    v: &Vector3<f64>,
) -> Option<f64> {
    let n = u.cross(v);
    let dn = d.dot(&n);
    if dn.abs() < 1e-15 {
        return None;
    }
    let t = (p - o).dot(&n) / dn;
    if t <= 0.0 {
        return None;
    }
    // Coordinates of the hit in (u, v): solve with the Gram matrix.
    let x = o + d * t - p;
    let (uu, uv, vv) = (u.dot(u), u.dot(v), v.dot(v));
    let (xu, xv) = (x.dot(u), x.dot(v));
    let det = uu * vv - uv * uv;
    if det <= 0.0 {
        return None;
    }
    let s = (xu * vv - xv * uv) / det;
    let q = (xv * uu - xu * uv) / det;
    ((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&q)).then_some(t)
}

impl Shape {
    /// A vertical pole standing on `base` (NED: its top is `height` metres higher).
    pub fn pole(base: Vector3<f64>, r: f64, height: f64) -> Self {
        Shape::Cylinder {
            a: base,
            b: base - Vector3::new(0.0, 0.0, height),
            r,
        }
    }

    /// An axis-aligned box between two corners.
    pub fn aabb(min: Vector3<f64>, max: Vector3<f64>) -> Self {
        Shape::Box {
            c: (min + max) / 2.0,
            half: (max - min) / 2.0,
            rot: Matrix3::identity(),
        }
    }

    /// A box with its length along `heading` [rad from north], standing on `base_center` (the
    /// centre of its bottom face, NED), of size length x width x height.
    pub fn box_on(base_center: Vector3<f64>, size: [f64; 3], heading: f64) -> Self {
        let (s, c) = libm::sincos(heading);
        Shape::Box {
            c: base_center - Vector3::new(0.0, 0.0, size[2] / 2.0),
            half: Vector3::new(size[0], size[1], size[2]) / 2.0,
            rot: Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
        }
    }

    /// A bounding sphere (centre, radius).
    pub fn bound(&self) -> (Vector3<f64>, f64) {
        match *self {
            Shape::Sphere { c, r } => (c, r),
            Shape::Cylinder { a, b, r } => ((a + b) / 2.0, libm::hypot(r, (b - a).norm() / 2.0)),
            Shape::Box { c, half, .. } => (c, half.norm()),
            Shape::Rect { p, u, v } => {
                let c = p + (u + v) / 2.0;
                (c, ((u + v) / 2.0).norm().max(((u - v) / 2.0).norm()))
            }
        }
    }

    /// Nearest intersection distance along a unit ray.
    pub fn intersect(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
        match self {
            Shape::Sphere { c, r } => ray_sphere(o, d, c, *r),
            Shape::Cylinder { a, b, r } => ray_cylinder(o, d, a, b, *r),
            Shape::Box { c, half, rot } => ray_box(o, d, c, half, rot),
            Shape::Rect { p, u, v } => ray_rect(o, d, p, u, v),
        }
    }

    /// The unit surface normal at a surface point `x` (outward; for a rectangle, either side).
    pub fn normal(&self, x: &Vector3<f64>) -> Vector3<f64> {
        let unit = |v: Vector3<f64>| {
            let n = v.norm();
            if n > 0.0 {
                v / n
            } else {
                Vector3::z()
            }
        };
        match self {
            Shape::Sphere { c, .. } => unit(x - c),
            Shape::Cylinder { a, b, r } => {
                let len = (b - a).norm();
                let w = unit(b - a);
                let h = (x - a).dot(&w);
                let radial = (x - a) - w * h;
                // On a cap when the point sits at an end and inside the rim.
                let rim = radial.norm() / r.max(1e-12);
                if (h.abs() < 1e-9 || (h - len).abs() < 1e-9) && rim < 1.0 - 1e-9 {
                    if h < len / 2.0 {
                        -w
                    } else {
                        w
                    }
                } else {
                    unit(radial)
                }
            }
            Shape::Box { c, half, rot } => {
                let q = rot.tr_mul(&(x - c));
                let mut k = 0;
                let mut best = f64::INFINITY;
                for i in 0..3 {
                    let gap = (half[i] - q[i].abs()).abs();
                    if gap < best {
                        best = gap;
                        k = i;
                    }
                }
                let mut nb = Vector3::zeros();
                nb[k] = if q[k] >= 0.0 { 1.0 } else { -1.0 };
                rot * nb
            }
            Shape::Rect { u, v, .. } => unit(u.cross(v)),
        }
    }

    /// Distance of a point from the surface (for tests and truth checks).
    pub fn distance(&self, x: &Vector3<f64>) -> f64 {
        match self {
            Shape::Sphere { c, r } => ((x - c).norm() - r).abs(),
            Shape::Cylinder { a, b, r } => {
                let len = (b - a).norm();
                let w = (b - a) / len.max(1e-300);
                let h = (x - a).dot(&w);
                let rho = ((x - a) - w * h).norm();
                // Outside or inside the solid: distance to the side or the caps.
                let hc = h.clamp(0.0, len);
                if (0.0..=len).contains(&h) {
                    (rho - r).abs().min(if rho <= *r {
                        h.min(len - h)
                    } else {
                        f64::INFINITY
                    })
                } else {
                    let dr = (rho - r).max(0.0);
                    libm::hypot(dr, h - hc)
                }
            }
            Shape::Box { c, half, rot } => {
                let q = rot.tr_mul(&(x - c));
                let out = Vector3::new(
                    (q.x.abs() - half.x).max(0.0),
                    (q.y.abs() - half.y).max(0.0),
                    (q.z.abs() - half.z).max(0.0),
                );
                if out.norm() > 0.0 {
                    out.norm()
                } else {
                    (half.x - q.x.abs())
                        .min(half.y - q.y.abs())
                        .min(half.z - q.z.abs())
                }
            }
            Shape::Rect { p, u, v } => (x - p).dot(&u.cross(v).normalize()).abs(),
        }
    }

    /// The shape grown (`d > 0`) or shrunk (`d < 0`) by `d` on every side; `None` when shrinking
    /// leaves nothing.
    pub fn offset(&self, d: f64) -> Option<Self> {
        match *self {
            Shape::Sphere { c, r } => (r + d > 0.0).then_some(Shape::Sphere { c, r: r + d }),
            Shape::Cylinder { a, b, r } => {
                let len = (b - a).norm();
                if r + d <= 0.0 || len + 2.0 * d <= 0.0 || len <= 0.0 {
                    return None;
                }
                let w = (b - a) / len;
                Some(Shape::Cylinder {
                    a: a - w * d,
                    b: b + w * d,
                    r: r + d,
                })
            }
            Shape::Box { c, half, rot } => {
                let h = half.add_scalar(d);
                (h.min() > 0.0).then_some(Shape::Box { c, half: h, rot })
            }
            Shape::Rect { p, u, v } => {
                let (lu, lv) = (u.norm(), v.norm());
                if lu + 2.0 * d <= 0.0 || lv + 2.0 * d <= 0.0 || lu <= 0.0 || lv <= 0.0 {
                    return None;
                }
                let (uu, vv) = (u / lu, v / lv);
                Some(Shape::Rect {
                    p: p - (uu + vv) * d,
                    u: u + uu * (2.0 * d),
                    v: v + vv * (2.0 * d),
                })
            }
        }
    }

    /// The same shape moved by `dx`.
    pub fn translated(&self, dx: &Vector3<f64>) -> Self {
        match *self {
            Shape::Sphere { c, r } => Shape::Sphere { c: c + dx, r },
            Shape::Cylinder { a, b, r } => Shape::Cylinder {
                a: a + dx,
                b: b + dx,
                r,
            },
            Shape::Box { c, half, rot } => Shape::Box {
                c: c + dx,
                half,
                rot,
            },
            Shape::Rect { p, u, v } => Shape::Rect { p: p + dx, u, v },
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
    fn cylinder_box_and_rect_hand_worked() {
        // Vertical pole of radius 0.05 at (5, 0), from down 0 up to down -2.
        let pole = Shape::pole(v(5.0, 0.0, 0.0), 0.05, 2.0);
        let t = pole
            .intersect(&v(0.0, 0.0, -1.0), &v(1.0, 0.0, 0.0))
            .unwrap();
        assert!((t - 4.95).abs() < 1e-12);
        assert_eq!(pole.intersect(&v(0.0, 0.0, -3.0), &v(1.0, 0.0, 0.0)), None); // above it
                                                                                 // Looking straight down onto its top cap (down -2) from down -5.
        let t = pole
            .intersect(&v(5.01, 0.0, -5.0), &v(0.0, 0.0, 1.0))
            .unwrap();
        assert!((t - 3.0).abs() < 1e-12);
        assert_eq!(pole.normal(&v(5.01, 0.0, -2.0)), v(0.0, 0.0, -1.0));
        // A leg inclined at 45 deg in the north-down plane: from (0,0,0) to (1,0,-1), r = 0.1.
        // A ray along east at down -0.5 crosses its axis at north 0.5: hits at the side, where
        // the perpendicular distance to the axis is r: the axis direction (1,0,-1)/sqrt2,
        // the ray's perpendicular component is all of it (east), so t = -3 + ... from e = -3.
        let leg = Shape::Cylinder {
            a: v(0.0, 0.0, 0.0),
            b: v(1.0, 0.0, -1.0),
            r: 0.1,
        };
        let t = leg
            .intersect(&v(0.5, -3.0, -0.5), &v(0.0, 1.0, 0.0))
            .unwrap();
        assert!((t - 2.9).abs() < 1e-12, "{t}");
        // Box from (1,-1,-1) to (2,1,1): entry at 1, from inside exit at 2.
        let b = Shape::aabb(v(1.0, -1.0, -1.0), v(2.0, 1.0, 1.0));
        assert_eq!(b.intersect(&v(0.0, 0.0, 0.0), &v(1.0, 0.0, 0.0)), Some(1.0));
        assert_eq!(b.intersect(&v(1.5, 0.0, 0.0), &v(1.0, 0.0, 0.0)), Some(0.5));
        assert_eq!(b.intersect(&v(0.0, 2.0, 0.0), &v(1.0, 0.0, 0.0)), None);
        assert_eq!(b.normal(&v(1.0, 0.3, 0.2)), v(-1.0, 0.0, 0.0));
        // The same box turned 90 deg: its length now along east.
        let tb = Shape::box_on(
            v(0.0, 0.0, 0.0),
            [4.0, 1.0, 2.0],
            core::f64::consts::FRAC_PI_2,
        );
        let t = tb
            .intersect(&v(0.0, -10.0, -1.0), &v(0.0, 1.0, 0.0))
            .unwrap();
        assert!((t - 8.0).abs() < 1e-12, "{t}");
        // A 2 x 3 rectangle in the north-east plane at down 1, seen from above.
        let r = Shape::Rect {
            p: v(0.0, 0.0, 1.0),
            u: v(2.0, 0.0, 0.0),
            v: v(0.0, 3.0, 0.0),
        };
        assert_eq!(
            r.intersect(&v(1.0, 1.0, -4.0), &v(0.0, 0.0, 1.0)),
            Some(5.0)
        );
        assert_eq!(r.intersect(&v(2.5, 1.0, -4.0), &v(0.0, 0.0, 1.0)), None);
        assert_eq!(
            r.intersect(&v(1.0, 1.0, 4.0), &v(0.0, 0.0, -1.0)),
            Some(3.0)
        );
        let w = Water {
            down: 1.5,
            specular: 0.0,
            specular_prob: 0.0,
        };
        assert_eq!(
            w.intersect(&v(0.0, 0.0, -0.5), &v(0.0, 0.0, 1.0)),
            Some(2.0)
        );
        assert_eq!(w.intersect(&v(0.0, 0.0, -0.5), &v(1.0, 0.0, 0.0)), None);
    }

    /// Every shape against a brute-force march along random rays: the analytic hit is the
    /// first point inside the solid (to the march step), the normal is perpendicular to the
    /// surface and the hit is on it.
    #[test]
    fn shapes_match_a_ray_march() {
        let mut rng = super::super::rng::Rng::new(3);
        let (s, c) = libm::sincos(0.7);
        let rot = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        let shapes = [
            Shape::Sphere {
                c: v(6.0, -2.0, 1.0),
                r: 0.5,
            },
            Shape::Cylinder {
                a: v(5.0, -2.5, 1.5),
                b: v(6.5, -1.5, 0.2),
                r: 0.3,
            },
            Shape::Box {
                c: v(6.0, -2.0, 1.0),
                half: v(0.8, 0.3, 0.5),
                rot,
            },
        ];
        // Inside tests for the march.
        let inside = |sh: &Shape, x: &Vector3<f64>| -> bool {
            match *sh {
                Shape::Sphere { c, r } => (x - c).norm() <= r,
                Shape::Cylinder { a, b, r } => {
                    let len = (b - a).norm();
                    let w = (b - a) / len;
                    let h = (x - a).dot(&w);
                    (0.0..=len).contains(&h) && ((x - a) - w * h).norm() <= r
                }
                Shape::Box { c, half, rot } => {
                    let q = rot.tr_mul(&(x - c));
                    (0..3).all(|i| q[i].abs() <= half[i])
                }
                Shape::Rect { .. } => false,
            }
        };
        for sh in &shapes {
            let (centre, _) = sh.bound();
            let mut hits = 0;
            for _ in 0..300 {
                let o = v(
                    rng.range(-2.0, 2.0),
                    rng.range(-2.0, 2.0),
                    rng.range(-2.0, 2.0),
                );
                let target = centre
                    + v(
                        rng.range(-0.9, 0.9),
                        rng.range(-0.9, 0.9),
                        rng.range(-0.9, 0.9),
                    );
                let d = (target - o).normalize();
                let step = 1e-4;
                let mut hit = None;
                let mut t = 0.0;
                while t < 12.0 {
                    if inside(sh, &(o + d * t)) {
                        hit = Some(t);
                        break;
                    }
                    t += step;
                }
                match (sh.intersect(&o, &d), hit) {
                    (Some(a), Some(b)) => {
                        assert!(a <= b + 1e-12 && b - a < 1.1 * step, "{sh:?}: {a} vs {b}");
                        let x = o + d * a;
                        assert!(sh.distance(&x) < 1e-9, "{sh:?}: off by {}", sh.distance(&x));
                        let n = sh.normal(&x);
                        assert!((n.norm() - 1.0).abs() < 1e-12);
                        // The normal points against the incoming ray at an entry point.
                        assert!(n.dot(&d) <= 1e-9, "{sh:?}: normal {n} along the ray {d}");
                        hits += 1;
                    }
                    (None, None) => {}
                    (a, b) => {
                        // Grazing rays may differ by less than one march step: the march
                        // point is then within a step of the surface.
                        let t = a.or(b).unwrap_or(0.0);
                        assert!(
                            sh.distance(&(o + d * t)) < 2.0 * step,
                            "{sh:?}: {a:?} vs {b:?}"
                        );
                    }
                }
            }
            assert!(hits > 50, "{sh:?}: only {hits} hits");
        }
    }
}

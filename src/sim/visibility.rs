//! Why a target sphere gets no returns: the survey sampled in time, and at each sample the
//! line from the LiDAR to the sphere's centre checked against the lasers' fan, the range, and
//! every other object in the way; and whether the LiDAR itself sits inside an object (a
//! mounting that puts it in the cabin). `synth` and `plan` say it in words.

use super::scene::{Frame, Shape};
use super::World;
use nalgebra::Vector3;

/// What the samples found for one sphere.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Visibility {
    /// Samples of the survey.
    pub samples: u32,
    /// Samples with the sphere within range.
    pub in_range: u32,
    /// ... and a laser's cone through it.
    pub on_a_laser: u32,
    /// ... and nothing in the way (the line of sight to its centre free).
    pub seen: u32,
    /// The object most often in the way, and how often.
    pub blocker: Option<(usize, u32)>,
    /// An object the LiDAR is inside, and at how many samples.
    pub lidar_inside: Option<(usize, u32)>,
    /// The sphere's elevation in the LiDAR frame over the samples in range [deg].
    pub elevation_deg: Option<(f64, f64)>,
}

impl Shape {
    /// The point is inside the solid (a rectangle has no inside).
    pub fn contains(&self, x: &Vector3<f64>) -> bool {
        match *self {
            Shape::Sphere { c, r } => (x - c).norm() < r,
            Shape::Cylinder { a, b, r } => {
                let len = (b - a).norm();
                let w = (b - a) / len.max(1e-300);
                let h = (x - a).dot(&w);
                h > 0.0 && h < len && ((x - a) - w * h).norm() < r
            }
            Shape::Box { c, half, rot } => {
                let q = rot.tr_mul(&(x - c));
                q.x.abs() < half.x && q.y.abs() < half.y && q.z.abs() < half.z
            }
            Shape::Rect { .. } => false,
        }
    }
}

/// Sample the survey every `step_s` seconds for target sphere `target` (its index in the
/// targets): see [`Visibility`]. Objects in the body frame move with the platform, moving site
/// objects with their velocity.
pub fn visibility(
    world: &World<'_>,
    scanner: super::lidar::Scanner,
    max_range: f64,
    target: u8,
    step_s: f64,
) -> Visibility {
    let mut v = Visibility::default();
    let Some(Shape::Sphere { c, r }) = world
        .objects
        .iter()
        .find(|o| o.target == Some(target))
        .map(|o| o.shape)
    else {
        return v;
    };
    let mut blocked = [0u32; 64];
    let mut blocked_other = (0usize, 0u32);
    let mut inside = (usize::MAX, 0u32);
    let n = (world.trajectory.duration() / step_s.max(1e-3)) as u32 + 1;
    for k in 0..n {
        let t = f64::from(k) * step_s;
        let s = world.trajectory.state(t);
        let r_ig = s.r_ig();
        let origin = s.position + r_ig * world.mount.lever;
        v.samples += 1;
        // The LiDAR inside something (in the body frame it is at the lever arm).
        let in_body = world.mount.lever;
        for (i, o) in world.objects.iter().enumerate() {
            if o.target.is_some() {
                continue;
            }
            let p = match o.frame {
                Frame::Body => in_body,
                Frame::Site => origin - o.velocity * t,
            };
            if o.shape.contains(&p) {
                if inside.0 == usize::MAX || inside.0 == i {
                    inside = (i, inside.1 + 1);
                }
                break;
            }
        }
        let to = c - origin;
        let d = to.norm();
        if d > max_range + r || d <= r {
            continue;
        }
        v.in_range += 1;
        let u = (r_ig * world.mount.r_li).tr_mul(&(to / d));
        let el = libm::asin(u.z.clamp(-1.0, 1.0)).to_degrees();
        let half = libm::asin((r / d).min(1.0)).to_degrees();
        v.elevation_deg = Some(match v.elevation_deg {
            Some((a, b)) => (a.min(el), b.max(el)),
            None => (el, el),
        });
        if !(0..scanner.lasers()).any(|k| (scanner.beam(k).elevation_deg - el).abs() <= half) {
            continue;
        }
        v.on_a_laser += 1;
        // The first other object on the line of sight to the centre, before the sphere.
        let dir = to / d;
        let (o_b, d_b) = (world.mount.lever, r_ig.tr_mul(&dir));
        let mut first: Option<(usize, f64)> = None;
        for (i, o) in world.objects.iter().enumerate() {
            if o.target == Some(target) {
                continue;
            }
            let hit = match o.frame {
                Frame::Body => o.shape.intersect(&o_b, &d_b),
                Frame::Site => o.shape.intersect(&(origin - o.velocity * t), &dir),
            };
            if let Some(h) = hit.filter(|h| *h > 1e-6 && *h < d - r) {
                if first.is_none_or(|(_, f)| h < f) {
                    first = Some((i, h));
                }
            }
        }
        match first {
            None => v.seen += 1,
            Some((i, _)) if i < blocked.len() => blocked[i] += 1,
            Some((i, _)) => {
                if blocked_other.1 == 0 || blocked_other.0 == i {
                    blocked_other = (i, blocked_other.1 + 1);
                }
            }
        }
    }
    let best = blocked
        .iter()
        .enumerate()
        .max_by_key(|(_, c)| **c)
        .map(|(i, c)| (i, *c))
        .filter(|(_, c)| *c > 0);
    v.blocker = match best {
        Some(b) if b.1 >= blocked_other.1 => Some(b),
        _ if blocked_other.1 > 0 => Some(blocked_other),
        b => b,
    };
    v.lidar_inside = (inside.1 > 0).then_some(inside);
    v
}

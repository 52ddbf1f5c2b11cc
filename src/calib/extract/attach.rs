//! What meets a sphere (its stand, a deck, a pole) recognised in the collar around it and its
//! returns rejected ([`reject_attachments`]).

use super::score::eigenvalues;
use super::{dot, norm, sub, Directions, ReturnClass};
use crate::align::window::Observation;
use nalgebra::{Matrix3, Vector3};

/// Reject the kept returns where a structure meets the sphere (centre at the origin of
/// `work.x`, radius `r`, shell `tau` = 3.5 noise sigmas): a tripod head or a pole under it, a
/// deck it sits on, a wall it leans on. Such a structure shows as returns in the collar just
/// outside the shell, gathered in one direction from the centre (returns on a free sphere
/// leave the collar nearly empty; mixed pixels spread around the silhouette). Where at least
/// `min_cluster` collar returns crowd into one direction (three times the collar's average),
/// the kept returns within the cap around it are rejected: its half-angle is the 90th
/// percentile of those collar returns' angles from their mean direction plus `atan(2 sigma /
/// r)` (noise moves the structure's returns sideways), at most 50 deg; at most two such caps.
/// The collar returns' shape names the verdict: `Pole` along a line, `Plane` otherwise.
/// Returns (planes, poles).
pub fn reject_attachments(
    obs: &mut [Observation],
    r: f64,
    tau: f64,
    dirs: &Directions,
    min_cluster: u32,
) -> (usize, usize) {
    let (r, tau) = (r as f32, tau as f32);
    let sigma = tau / 3.5;
    let outer = r + tau + (2.0 * tau).max(0.05);
    let collar = |o: &Observation| {
        let d = norm(o.work.x);
        d > r + tau && d < outer
    };
    let (mut planes, mut poles) = (0, 0);
    let mut taken = [usize::MAX; 2];
    for cap in 0..2 {
        // Collar returns per lattice direction.
        let mut bins = [0u32; 48];
        let mut total = 0u32;
        for o in obs.iter().filter(|o| collar(o)) {
            let x = o.work.x;
            let d = norm(x).max(1e-9);
            let u = [x[0] / d, x[1] / d, x[2] / d];
            let k = (0..48)
                .max_by(|&a, &b| dot(dirs.0[a], u).total_cmp(&dot(dirs.0[b], u)))
                .unwrap_or(0);
            if !taken.contains(&k) {
                bins[k] += 1;
                total += 1;
            }
        }
        let (k, &top) = bins
            .iter()
            .enumerate()
            .max_by_key(|(_, &c)| c)
            .unwrap_or((0, &0));
        if top < min_cluster || top * 48 < 3 * total * 3 {
            break;
        }
        taken[cap] = k;
        // The cluster: collar returns within 40 deg of the bin's direction; their mean
        // direction and spread, and their shape.
        let axis0 = dirs.0[k];
        let cos40 = 0.766f32;
        let mut m = [0f32; 3];
        let mut n = 0f32;
        let mut cov = Matrix3::<f32>::zeros();
        let mut centroid = Vector3::<f32>::zeros();
        for o in obs.iter().filter(|o| collar(o)) {
            let x = o.work.x;
            let d = norm(x).max(1e-9);
            if dot(x, axis0) / d >= cos40 {
                for a in 0..3 {
                    m[a] += x[a] / d;
                }
                n += 1.0;
                let v = Vector3::from(x);
                centroid += v;
                cov += v * v.transpose();
            }
        }
        let mlen = norm(m).max(1e-9);
        let axis = [m[0] / mlen, m[1] / mlen, m[2] / mlen];
        let centroid = centroid / n.max(1.0);
        let cov = cov / n.max(1.0) - centroid * centroid.transpose();
        let line = eigenvalues(cov).is_some_and(|mut ev| {
            ev.sort_unstable_by(|x, y| y.total_cmp(x));
            ev[1] < 0.1 * ev[0]
        });
        // 90th percentile of the angles, from a histogram of 1-degree bins up to 60 deg.
        let mut hist = [0u32; 61];
        for o in obs.iter().filter(|o| collar(o)) {
            let x = o.work.x;
            let c = dot(x, axis) / norm(x).max(1e-9);
            if c >= cos40 {
                let a = libm::acosf(c.clamp(-1.0, 1.0)).to_degrees();
                hist[(a as usize).min(60)] += 1;
            }
        }
        let want = (0.9 * n) as u32;
        let mut acc = 0;
        let mut p90 = 60.0f32;
        for (deg, &c) in hist.iter().enumerate() {
            acc += c;
            if acc >= want.max(1) {
                p90 = deg as f32 + 1.0;
                break;
            }
        }
        let half = (p90 + libm::atanf(2.0 * sigma / r).to_degrees()).min(50.0);
        let cos_half = libm::cosf(half.to_radians());
        for o in obs.iter_mut() {
            if o.work.verdict != ReturnClass::Kept as u8 {
                continue;
            }
            let x = o.work.x;
            if dot(x, axis) / norm(x).max(1e-9) >= cos_half {
                o.work.verdict = if line {
                    poles += 1;
                    ReturnClass::Pole
                } else {
                    planes += 1;
                    ReturnClass::Plane
                } as u8;
            }
        }
    }
    (planes, poles)
}

/// Reject the kept returns on a surface the sphere rests on or leans against (the ground, a
/// deck, a wall: a plane touching it). Within the shell near the contact such a surface's
/// returns lie as close to the sphere as its own, and its collar returns spread round the
/// contact in every direction, so [`reject_attachments`]' one-direction test misses it. The
/// plane is found among the collar returns (centre at the origin of `work.x`, radius `r`,
/// shell `tau`) by a deterministic sample consensus: a plane whose distance from the centre is
/// `r` within `tau`, behind the sphere as the beams see it (their mean direction along its
/// normal positive: the sphere's own visible cap is nearly a tangent plane too, facing them),
/// holding at least `min_inliers` collar returns within `tau` and half of them, spread round
/// the contact point in at least 5 of 8 sectors (a tripod's legs fill three or four; seen
/// under a misfit's wide shell they did fill four); then every kept return within `tau` of it is
/// rejected as [`ReturnClass::Plane`] (of the sphere that is only the cap below
/// `acos(1 - tau / r)` from the contact, hidden by the surface itself from most viewpoints).
/// Returns how many.
pub fn reject_touching_plane(obs: &mut [Observation], r: f64, tau: f64, min_inliers: u32) -> usize {
    let (r, tau) = (r as f32, tau as f32);
    let outer = r + tau + (2.0 * tau).max(0.05);
    let collar = |o: &Observation| {
        let d = norm(o.work.x);
        d > r + tau && d < outer
    };
    let Some((nv, off)) = touching_plane(obs, collar, r, tau, tau, min_inliers) else {
        return 0;
    };
    let mut rejected = 0;
    for o in obs.iter_mut() {
        if o.work.verdict == ReturnClass::Kept as u8 && dot(nv, o.work.x) >= off - tau {
            o.work.verdict = ReturnClass::Plane as u8;
            rejected += 1;
        }
    }
    rejected
}

/// Set aside, in one slice of a sphere's returns (centre at the origin of `work.x` within
/// `tau`, radius `r`), the ground it rests on: from the air a sphere on the grass and the grass
/// round it form one scan-line segment, and within a shell widened for the navigation's errors
/// the grass pulls the slice's fit off the sphere. The plane is found as in
/// [`reject_touching_plane`] among the returns within half a metre of the surface, its inliers
/// within `band` (the range noise's spread); they are tagged [`ReturnClass::Plane`] and moved to
/// the end of `obs`. Returns how many others there are (the front of `obs`).
pub fn set_aside_ground(obs: &mut [Observation], r: f64, tau: f64, band: f64) -> usize {
    let (r, tau, band) = (r as f32, tau as f32, band as f32);
    let reach = r + tau + 0.5;
    let near = |o: &Observation| norm(o.work.x) < reach;
    let Some((nv, off)) = touching_plane(obs, near, r, tau, band, 12) else {
        return obs.len();
    };
    let mut w = 0;
    for i in 0..obs.len() {
        if (dot(nv, obs[i].work.x) - off).abs() > band {
            obs.swap(i, w);
            w += 1;
        } else {
            obs[i].work.verdict = ReturnClass::Plane as u8;
        }
    }
    w
}

/// The plane, among the returns `member` picks, that touches the sphere (centre at the origin
/// of `work.x`, radius `r`: its distance from the centre is `r` within `tau`) from behind as
/// the beams see it, by a deterministic sample consensus: at least `min_inliers` and half of
/// the members within `band` of it, spread round the contact in at least 5 of 8 sectors.
/// Returns its unit normal (away from the centre) and offset (`n.x = off`).
fn touching_plane(
    obs: &[Observation],
    member: impl Fn(&Observation) -> bool,
    r: f32,
    tau: f32,
    band: f32,
    min_inliers: u32,
) -> Option<([f32; 3], f32)> {
    /// Planes tried.
    const TRIES: u32 = 96;
    let n = obs.iter().filter(|o| member(o)).count();
    if n < min_inliers.max(3) as usize {
        return None;
    }
    // The k-th member (walks the slice; the members are few).
    let nth = |k: usize| {
        obs.iter()
            .filter(|o| member(o))
            .nth(k)
            .map_or([0.0; 3], |o| o.work.x)
    };
    let mut best: Option<([f32; 3], f32, u32)> = None;
    let mut state = 0x9E37_79B9u32;
    let mut next = |m: usize| {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as usize % m
    };
    for _ in 0..TRIES {
        let (a, b, c) = (nth(next(n)), nth(next(n)), nth(next(n)));
        let (u, v) = (sub(b, a), sub(c, a));
        let nrm = cross(u, v);
        let len = norm(nrm);
        if len < 1e-6 || !len.is_finite() {
            continue;
        }
        let mut nv = [nrm[0] / len, nrm[1] / len, nrm[2] / len];
        // Oriented away from the centre: the plane is n.x = off, off > 0.
        let mut off = dot(nv, a);
        if off < 0.0 {
            nv = [-nv[0], -nv[1], -nv[2]];
            off = -off;
        }
        if (off - r).abs() > tau {
            continue;
        }
        let (mut inl, mut away) = (0u32, 0f32);
        for o in obs
            .iter()
            .filter(|o| member(o) && (dot(nv, o.work.x) - off).abs() <= band)
        {
            inl += 1;
            away += dot(nv, o.work.u);
        }
        // The beams reach it going away from the centre: a surface behind the sphere as seen
        // from the sensor, not the sphere's own cap facing it (which is nearly a tangent
        // plane too).
        if away <= 0.05 * inl as f32 {
            continue;
        }
        if best.is_none_or(|(_, _, m)| inl > m) {
            best = Some((nv, off, inl));
        }
    }
    let (nv, off, inl) = best?;
    if inl < min_inliers || (inl as usize) * 2 < n {
        return None;
    }
    // Spread round the contact point: sectors of the plane about it.
    let e1 = if nv[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let p1 = {
        let d = dot(e1, nv);
        let t = sub(e1, [nv[0] * d, nv[1] * d, nv[2] * d]);
        let l = norm(t).max(1e-9);
        [t[0] / l, t[1] / l, t[2] / l]
    };
    let p2 = cross(nv, p1);
    let mut sectors = [0u32; 8];
    for o in obs
        .iter()
        .filter(|o| member(o) && (dot(nv, o.work.x) - off).abs() <= band)
    {
        let a = libm::atan2f(dot(o.work.x, p2), dot(o.work.x, p1));
        let k = (((a + core::f32::consts::PI) / core::f32::consts::FRAC_PI_4) as usize).min(7);
        sectors[k] += 1;
    }
    (sectors.iter().filter(|&&c| c >= 3).count() >= 5).then_some((nv, off))
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

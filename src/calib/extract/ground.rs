//! The ground a sphere rests on, recognised along each laser's sweep ([`reject_ground_on_sweeps`]).

use super::scan::slices;
use super::{dot, norm, sub, ReturnClass, V3};
use crate::align::window::Observation;

/// Returns of one sweep of one laser are within this time of each other [ns]: the sweep over
/// a sphere's neighbourhood (a few metres at tens of metres) lasts about a millisecond, the
/// laser's next pass over it comes one revolution later (50 ms at 1,200 RPM, the fastest).
const SWEEP_NS: i64 = 20_000_000;
/// The ground is looked for this far beyond the sphere's shell [m].
const REACH_M: f32 = 1.0;
/// Fewest ground returns, and shortest stretch of them [m], that make a line.
const MIN_GROUND: usize = 4;
const MIN_SPAN_M: f32 = 0.3;
/// Most neighbours one kept return looks at.
const MAX_NEIGHBOURS: usize = 32;
/// Most returns beyond the shell one slice's index holds (a slice with more is walked for
/// each kept return).
const MAX_BEYOND: usize = 256;

/// Reject the kept returns that lie on the ground a sphere rests on, as the laser's own sweep
/// draws it (centre at the origin of `work.x`, radius `r`, shell `tau`, the range noise's
/// spread `band`). From the air a sphere on the grass is crossed by one or two scan lines per
/// slice: too few for [`set_aside_ground`]'s plane, and under a mounting or navigation error
/// of a few centimetres the grass round the sphere's foot (or a lifted patch of it) lies in
/// the shell like the sphere's own returns. The same laser's returns of the same sweep (within
/// [`SWEEP_NS`]) that lie beyond the shell, within [`REACH_M`], trace the ground there as a
/// straight line (a laser's cone meets a plane in a conic, straight over a few metres at tens
/// of metres): at least [`MIN_GROUND`] of them over [`MIN_SPAN_M`], their median distance
/// from the line through the sweep's first and last within `band / 2`. A kept return within
/// `band` of that line is the ground, not the sphere (the sphere's returns on that sweep rise
/// above it by up to its diameter), tagged [`ReturnClass::Plane`]. A sweep that passes a
/// sphere on a stand or a pole (a vessel's upright LiDAR sweeping sideways: a wall or the air
/// behind) draws its line behind the sphere, not through its returns. `obs` holds one sphere's
/// returns grouped by slice (a slice's returns together). Returns how many were rejected.
pub fn reject_ground_on_sweeps(obs: &mut [Observation], r: f64, tau: f64, band: f64) -> usize {
    reject_indexed(obs, r, tau, band, MAX_BEYOND)
}

/// [`reject_ground_on_sweeps`] with a slice's index of the returns beyond the shell holding
/// at most `most` (`MAX_BEYOND`; fewer only to test the walk without it).
fn reject_indexed(obs: &mut [Observation], r: f64, tau: f64, band: f64, most: usize) -> usize {
    let (r, tau, band) = (r as f32, tau as f32, band as f32);
    let beyond = |o: &Observation| {
        let d = norm(o.work.x);
        d > r + tau && d <= r + tau + REACH_M
    };
    let mut rejected = 0;
    let mut start = 0;
    loop {
        let Some(sl) = slices(&obs[start..]).next() else {
            break;
        };
        let sl = start + sl.start..start + sl.end;
        start = sl.end;
        if !obs[sl.clone()]
            .iter()
            .any(|o| o.work.verdict == ReturnClass::Kept as u8)
        {
            continue;
        }
        // The slice's returns beyond the shell, once (a slice with more walks itself).
        let mut index = [(0u8, 0i64, [0f32; 3]); MAX_BEYOND];
        let mut nb = 0;
        let mut whole = false;
        for o in obs[sl.clone()].iter().filter(|o| beyond(o)) {
            if nb == most.min(MAX_BEYOND) {
                whole = true;
                break;
            }
            index[nb] = (o.laser, o.time.0, o.work.x);
            nb += 1;
        }
        for i in sl.clone() {
            if obs[i].work.verdict != ReturnClass::Kept as u8 {
                continue;
            }
            let (laser, t) = (obs[i].laser, obs[i].time.0);
            let mut near = [([0f32; 3], 0i64); MAX_NEIGHBOURS];
            let mut n = 0;
            let mut take = |(l, tt, x): (u8, i64, V3)| {
                if l == laser && tt.abs_diff(t) <= SWEEP_NS.unsigned_abs() && n < MAX_NEIGHBOURS {
                    near[n] = (x, tt);
                    n += 1;
                }
            };
            if whole {
                obs[sl.clone()]
                    .iter()
                    .filter(|o| beyond(o))
                    .for_each(|o| take((o.laser, o.time.0, o.work.x)));
            } else {
                index[..nb].iter().for_each(|&e| take(e));
            }
            if n < MIN_GROUND {
                continue;
            }
            let near = &near[..n];
            let first = near.iter().min_by_key(|p| p.1).map_or([0.0; 3], |p| p.0);
            let last = near.iter().max_by_key(|p| p.1).map_or([0.0; 3], |p| p.0);
            let along = sub(last, first);
            let span = norm(along);
            if span.is_nan() || span < MIN_SPAN_M {
                continue;
            }
            let u = [along[0] / span, along[1] / span, along[2] / span];
            let off_line = |x: V3| {
                let d = sub(x, first);
                let a = dot(d, u);
                norm(sub(d, [u[0] * a, u[1] * a, u[2] * a]))
            };
            // The median distance of the neighbours from the line: a straight trace.
            let mut dist = [0f32; MAX_NEIGHBOURS];
            for (k, p) in near.iter().enumerate() {
                dist[k] = off_line(p.0);
            }
            let dist = &mut dist[..n];
            dist.sort_unstable_by(|a, b| a.total_cmp(b));
            if dist[n / 2].is_nan() || dist[n / 2] > 0.5 * band {
                continue;
            }
            if off_line(obs[i].work.x) <= band {
                obs[i].work.verdict = ReturnClass::Plane as u8;
                rejected += 1;
            }
        }
    }
    rejected
}

#[cfg(test)]
mod tests {
    use super::super::tests::at;
    use super::*;
    use crate::sim::scene::ray_sphere;
    use crate::time::GpsTime;
    use nalgebra::Vector3;

    /// One laser's sweep from `sensor` (number `laser`, from time `t0`): rays in the plane
    /// through `sensor` spanned by `across` and `towards`, 0.2 deg apart (a VLP-16 at 600
    /// RPM), each meeting the sphere (centre at the origin, radius `r`) or else `surface`
    /// (distance along the ray, if any), every point shifted by `shift` (a navigation error).
    #[allow(clippy::too_many_arguments)]
    fn sweep(
        sensor: Vector3<f64>,
        towards: Vector3<f64>,
        across: Vector3<f64>,
        r: f64,
        surface: impl Fn(&Vector3<f64>) -> Option<f64>,
        shift: Vector3<f64>,
        laser: u8,
        t0: i64,
        out: &mut heapless::Vec<(Observation, bool), 1024>,
    ) {
        for k in -40..=40 {
            let a = f64::from(k) * 0.2f64.to_radians();
            let d = (towards * libm::cos(a) + across * libm::sin(a)).normalize();
            let (t, on_sphere) = match ray_sphere(&sensor, &d, &Vector3::zeros(), r) {
                Some(t) => (t, true),
                None => match surface(&d) {
                    Some(t) => (t, false),
                    None => continue,
                },
            };
            let mut o = at(sensor + d * t + shift, sensor);
            o.laser = laser;
            o.time = GpsTime(t0 + i64::from(k + 40) * 55_000);
            let _ = out.push((o, on_sphere));
        }
    }

    /// Tag the returns within the shell kept; reject the ground; (ground kept before, ground
    /// kept after, sphere returns rejected, returns beyond the shell).
    fn run(
        v: &mut heapless::Vec<(Observation, bool), 1024>,
        r: f64,
        tau: f64,
    ) -> (usize, usize, usize, usize) {
        for (o, _) in v.iter_mut() {
            if (norm(o.work.x) - r as f32).abs() < tau as f32 {
                o.work.verdict = ReturnClass::Kept as u8;
            }
        }
        let kept = |v: &[(Observation, bool)], sphere: bool| {
            v.iter()
                .filter(|(o, s)| *s == sphere && o.work.verdict == ReturnClass::Kept as u8)
                .count()
        };
        let (ground_before, sphere_before) = (kept(v, false), kept(v, true));
        let mut obs: heapless::Vec<Observation, 1024> = v.iter().map(|p| p.0).collect();
        // The slice's index (when it holds every return beyond the shell) and the walk
        // without it agree.
        let beyond = v
            .iter()
            .filter(|(o, _)| {
                let d = norm(o.work.x);
                d > (r + tau) as f32 && d <= (r + tau) as f32 + REACH_M
            })
            .count();
        let mut walked = obs.clone();
        let n = reject_ground_on_sweeps(&mut obs, r, tau, 0.04);
        assert_eq!(reject_indexed(&mut walked, r, tau, 0.04, 0), n);
        assert!(walked
            .iter()
            .zip(&obs)
            .all(|(a, b)| a.work.verdict == b.work.verdict));
        for (p, o) in v.iter_mut().zip(&obs) {
            p.0 = *o;
        }
        let (ground_after, sphere_after) = (kept(v, false), kept(v, true));
        assert_eq!(
            n,
            ground_before - ground_after + sphere_before - sphere_after
        );
        (
            ground_before,
            ground_after,
            sphere_before - sphere_after,
            beyond,
        )
    }

    /// From 40 m above (a drone, the VLP-16's sweeps across the track), a 0.25 m sphere resting
    /// on the grass, every point lifted 8 cm and moved 3 cm by a navigation error: sweeps 0.15
    /// m apart along the track cross the sphere and the grass round it. The grass the shell
    /// holds (its ring at the sphere's foot, widened by the lift) is rejected; none of the
    /// sphere's returns are.
    #[test]
    fn the_grass_a_sphere_rests_on_is_rejected_along_the_sweeps_from_above() {
        let (r, tau) = (0.25, 0.125);
        let sensor = Vector3::new(-4.0, 1.0, -40.0);
        let shift = Vector3::new(0.03, 0.0, -0.08);
        let mut v = heapless::Vec::new();
        for (i, a) in (-6..=6).map(|i| (i, f64::from(i) * 0.15)) {
            // The sweep's plane through the sensor and the ground line north = a.
            let towards = (Vector3::new(a, 1.0, r) - sensor).normalize();
            let across = towards.cross(&Vector3::x()).normalize();
            let grass = |d: &Vector3<f64>| (d.z > 0.0).then(|| (r - sensor.z) / d.z);
            sweep(
                sensor,
                towards,
                across,
                r,
                grass,
                shift,
                (i + 6) as u8,
                i64::from(i) * 100_000_000,
                &mut v,
            );
        }
        let (before, after, sphere_lost, beyond) = run(&mut v, r, tau);
        assert!(beyond < MAX_BEYOND, "the index holds them: {beyond}");
        assert!(before >= 5, "the shell holds grass: {before}");
        assert_eq!(after, 0);
        assert_eq!(sphere_lost, 0);
    }

    /// A vessel's upright LiDAR 15 m off a sphere on a pole, a quay wall 1 m behind it (and
    /// one 0.4 m behind): each sweep is nearly level, so the wall's returns on it lie at the
    /// sphere's height, but on a line behind the sphere: nothing is rejected.
    #[test]
    fn a_wall_behind_a_sphere_seen_from_the_side_is_not_its_ground() {
        let (r, tau) = (0.25, 0.125);
        let sensor = Vector3::new(-15.0, 0.5, -1.0);
        for gap in [1.0, 0.4] {
            let mut v = heapless::Vec::new();
            for (i, up) in (-3..=3).map(|i| (i, f64::from(i) * 0.08)) {
                let towards = (Vector3::new(0.0, 0.0, up) - sensor).normalize();
                let across = towards.cross(&Vector3::z()).normalize();
                let wall = |d: &Vector3<f64>| (d.x > 0.0).then(|| (r + gap - sensor.x) / d.x);
                sweep(
                    sensor,
                    towards,
                    across,
                    r,
                    wall,
                    Vector3::zeros(),
                    (i + 3) as u8,
                    i64::from(i) * 100_000_000,
                    &mut v,
                );
            }
            let (_, _, sphere_lost, beyond) = run(&mut v, r, tau);
            // The near wall: more returns beyond the shell than the index holds (walked).
            assert_eq!(beyond > MAX_BEYOND, gap < 0.5, "{beyond}");
            assert!(v.iter().filter(|p| p.1).count() > 20);
            assert_eq!(sphere_lost, 0, "wall {gap} m behind");
        }
    }
}

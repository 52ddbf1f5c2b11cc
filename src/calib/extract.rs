//! Sphere extraction: which of a window's returns are on the sphere, among 10-100 times more
//! returns off the deck, the quay wall, the stand, people and parked vehicles. By step: scan
//! lines and slices (`scan`), Hough votes on the centre (`vote`), scoring a candidate
//! (`score`), one slice's detection and the returns kept (`detect`), what meets the sphere
//! (`attach`), the ground it rests on along the sweeps (`ground`), one sphere's slices in
//! turn (`sphere`). The method: docs/extraction.md, section 2.

use super::objective::TimeOffset;
use crate::align::window::{Observation, Target};
use crate::georef::Mount;

mod attach;
mod detect;
mod ground;
mod radius;
mod scan;
mod score;
mod sphere;
mod vote;

pub use attach::{reject_attachments, reject_touching_plane, set_aside_ground};
pub use detect::{detect, detect_all, keep, Candidates, MAX_CANDIDATES};
pub use ground::reject_ground_on_sweeps;
pub use radius::detections_at_radii;
pub use scan::{assign_slices, prepare, runs, slices, time_order, SliceCursor};
pub use score::Key;
pub(crate) use sphere::apparent_offsets;
pub use sphere::{extract_sphere, place_and_compact, Extraction};

/// Why a windowed return is, or is not, used (stored in `Observation::work.verdict`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ReturnClass {
    /// Not classified.
    Unclassified = 0,
    /// On the sphere: used.
    Kept = 1,
    /// In a slice of time where the sphere was not detected.
    Undetected = 2,
    /// Off the sphere's shell.
    OutsideShell = 3,
    /// On the far side of the sphere as seen from the sensor (a sphere cannot return there).
    Hidden = 4,
    /// On a plane that continues beyond the sphere (deck, wall, crate).
    Plane = 5,
    /// On a pole that continues beyond the sphere (tripod leg or head, bollard).
    Pole = 6,
    /// The sphere was not found at all.
    NotFound = 7,
}

impl ReturnClass {
    /// All verdicts, in their numeric order.
    pub const ALL: [ReturnClass; 8] = [
        ReturnClass::Unclassified,
        ReturnClass::Kept,
        ReturnClass::Undetected,
        ReturnClass::OutsideShell,
        ReturnClass::Hidden,
        ReturnClass::Plane,
        ReturnClass::Pole,
        ReturnClass::NotFound,
    ];

    /// From the stored byte.
    pub fn from_u8(v: u8) -> Self {
        Self::ALL
            .get(usize::from(v))
            .copied()
            .unwrap_or(ReturnClass::Unclassified)
    }

    /// Its name in reports.
    pub fn name(self) -> &'static str {
        match self {
            ReturnClass::Unclassified => "unclassified",
            ReturnClass::Kept => "kept",
            ReturnClass::Undetected => "undetected",
            ReturnClass::OutsideShell => "outside_shell",
            ReturnClass::Hidden => "hidden_side",
            ReturnClass::Plane => "plane",
            ReturnClass::Pole => "pole",
            ReturnClass::NotFound => "sphere_not_found",
        }
    }
}

/// Extraction settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtractSettings {
    /// Length of a slice of time [ns].
    pub slice_ns: i64,
    /// A gap longer than this between a sphere's returns separates two passes even on one
    /// course (a second visit) [ns]; a turn of the course always does.
    pub pass_gap_ns: i64,
    /// A piece of a pass shorter than this after a turn (the turn itself) joins the pass before
    /// it [ns].
    pub pass_min_ns: i64,
    /// Fewest inliers of a detection without a prior.
    pub min_inliers: usize,
    /// Fewest inliers of a detection within the prior.
    pub min_inliers_prior: usize,
    /// Distinct Hough peaks refined per slice.
    pub peaks: usize,
    /// Score penalty per free-space violation.
    pub violation_weight: f32,
    /// Starting inlier band [m] (the smear of a slice under a wrong mounting).
    pub tau0: f64,
    /// Smallest inlier band [m].
    pub tau_floor: f64,
    /// Time between two firings of one laser [ns] (VLP-16: 55,296; manual appendix B).
    pub firing_ns: i64,
    /// A range step larger than this ends a scan-line segment [m].
    pub jump: f64,
    /// Score penalty per return in the collar just outside a candidate sphere.
    pub collar_weight: f32,
    /// The last extraction rejects the ground a sphere rests on along each laser's sweep
    /// ([`reject_ground_on_sweeps`]); off only to show what it does.
    pub ground_sweeps: bool,
}

impl Default for ExtractSettings {
    fn default() -> Self {
        Self {
            slice_ns: 400_000_000,
            pass_gap_ns: 20_000_000_000,
            pass_min_ns: 2_000_000_000,
            min_inliers: 10,
            min_inliers_prior: 4,
            peaks: 12,
            violation_weight: 2.0,
            tau0: 0.05,
            tau_floor: 0.004,
            firing_ns: 55_296,
            jump: 0.3,
            collar_weight: 1.0,
            ground_sweeps: true,
        }
    }
}

/// A sphere detected in one slice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// Centre relative to the surveyed centre [m].
    pub center: [f32; 3],
    /// Inliers (visible side, within the band).
    pub inliers: u32,
    /// MSAC score minus the violation penalty.
    pub score: f32,
    /// Free-space violations.
    pub violations: u32,
}

/// Directions for the Hough votes: a Fibonacci lattice of unit vectors.
#[derive(Debug, Clone)]
pub struct Directions(pub [[f32; 3]; 48]);

impl Default for Directions {
    fn default() -> Self {
        let mut d = [[0f32; 3]; 48];
        let golden = core::f64::consts::PI * (3.0 - libm::sqrt(5.0));
        for (i, v) in d.iter_mut().enumerate() {
            let z = 1.0 - (i as f64 + 0.5) * 2.0 / 48.0;
            let rho = libm::sqrt(1.0 - z * z);
            let (s, c) = libm::sincos(golden * i as f64);
            *v = [(rho * c) as f32, (rho * s) as f32, z as f32];
        }
        Self(d)
    }
}

pub(crate) type V3 = [f32; 3];

#[inline]
pub(super) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub(super) fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub(super) fn norm(a: V3) -> f32 {
    libm::sqrtf(dot(a, a))
}

/// Georeference every observation of one sphere with `mount` and the time offset `time` (on
/// top of the observations' poses, [`Observation::georef_dt`]): the return relative to the
/// surveyed centre and the beam's direction, into `work`.
pub fn georeference(obs: &mut [Observation], t: &Target, mount: &Mount, time: &TimeOffset) {
    for o in obs.iter_mut() {
        place(o, t, mount, time);
    }
}

/// [`georeference`] for one return.
#[inline]
fn place(o: &mut Observation, t: &Target, mount: &Mount, time: &TimeOffset) {
    let rot = o.rot();
    let y = mount.r_li * o.q();
    let x = o.georef_dt(mount, time.at(o)) - t.center;
    let u = rot * y;
    let n = u.norm().max(1e-9);
    o.work.x = [x.x as f32, x.y as f32, x.z as f32];
    o.work.u = [(u.x / n) as f32, (u.y / n) as f32, (u.z / n) as f32];
}

/// Tag every observation of a slice.
pub fn tag(obs: &mut [Observation], v: ReturnClass) {
    for o in obs.iter_mut() {
        o.work.verdict = v as u8;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Rng;
    use crate::time::GpsTime;
    use nalgebra::{Matrix3, Vector3};

    /// An observation at a point `x` (relative to the surveyed centre) seen from `sensor`.
    pub(super) fn at(x: Vector3<f64>, sensor: Vector3<f64>) -> Observation {
        let d = x - sensor;
        let u = d / d.norm();
        Observation {
            q_l: d.cast(),
            position: sensor,
            r_ig: Matrix3::identity(),
            time: GpsTime(0),
            range: d.norm() as f32,
            work: crate::align::window::Work {
                x: [x.x as f32, x.y as f32, x.z as f32],
                u: [u.x as f32, u.y as f32, u.z as f32],
                run: 0.0,
                slice: 0,
                verdict: 0,
            },
            ..Observation::default()
        }
    }

    /// Returns of a scan from `sensor` over the visible cap of a sphere (c, r), on a grid of
    /// directions `step` apart.
    fn sphere_cap(
        sensor: Vector3<f64>,
        c: Vector3<f64>,
        r: f64,
        step: f64,
        out: &mut heapless::Vec<Observation, 8192>,
    ) {
        let to = (c - sensor).normalize();
        let e1 = to.cross(&Vector3::z()).normalize();
        let e2 = to.cross(&e1);
        let half = libm::asin(r / (c - sensor).norm());
        let n = (half / step) as i32 + 1;
        for i in -n..=n {
            for j in -n..=n {
                let d = (to + e1 * (f64::from(i) * step) + e2 * (f64::from(j) * step)).normalize();
                if let Some(t) = crate::sim::scene::ray_sphere(&sensor, &d, &c, r) {
                    let _ = out.push(at(sensor + d * t, sensor));
                }
            }
        }
    }

    #[test]
    fn finds_a_sphere_beside_a_plane_and_among_random_clutter() {
        let mut rng = Rng::new(5);
        let sensor = Vector3::new(-10.0, 2.0, -1.0);
        let c = Vector3::new(0.7, -0.4, 0.3); // the apparent sphere, off the surveyed centre
        let r = 0.19;
        let mut obs = heapless::Vec::<Observation, 8192>::new();
        sphere_cap(sensor, c, r, 0.0015, &mut obs);
        let on_sphere = obs.len();
        for o in obs.iter_mut() {
            o.packet = 1; // marks the sphere's returns
        }
        assert!(on_sphere > 200, "{on_sphere}");
        // A deck 1.4 m below, seen from the sensor: 3000 returns, and 1000 random ones.
        for _ in 0..3000 {
            let p = Vector3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), 1.4);
            let _ = obs.push(at(p, sensor));
        }
        for _ in 0..1000 {
            let p = Vector3::new(
                rng.range(-3.0, 3.0),
                rng.range(-3.0, 3.0),
                rng.range(-1.0, 1.4),
            );
            let _ = obs.push(at(p, sensor));
        }
        let mut grid = [0u16; 32 * 32 * 32];
        let mut keys = [Key::default(); 8192];
        let dirs = Directions::default();
        let st = ExtractSettings::default();
        let det =
            detect(&obs, &mut keys, r, 0.01, None, &mut grid, &dirs, &st).expect("a detection");
        let got = Vector3::new(
            f64::from(det.center[0]),
            f64::from(det.center[1]),
            f64::from(det.center[2]),
        );
        assert!((got - c).norm() < 2e-3, "{got} vs {c}");
        assert!(det.inliers as usize >= on_sphere * 9 / 10, "{det:?}");
        assert!(grid.iter().all(|&v| v == 0), "the grid is left clean");
        // Tagging keeps the sphere's returns and (almost) nothing else.
        let kept = keep(
            &mut obs,
            det.center,
            r,
            0.01,
            &crate::calib::Settings::default().noise(),
        );
        let true_kept = obs
            .iter()
            .filter(|o| o.packet == 1 && o.work.verdict == ReturnClass::Kept as u8)
            .count();
        assert!(
            true_kept >= on_sphere * 95 / 100,
            "{true_kept} of {on_sphere}"
        );
        assert!(kept - true_kept <= 10, "{} clutter kept", kept - true_kept);
        // With a prior that excludes it, nothing is found there.
        let far = detect(&obs, &mut keys, r, 0.01, Some(0.3), &mut grid, &dirs, &st);
        assert!(far.is_none_or(|d| norm(d.center) <= 0.3), "{far:?}");
    }

    #[test]
    fn a_plane_or_a_pole_alone_is_not_a_sphere() {
        let mut rng = Rng::new(9);
        let sensor = Vector3::new(-10.0, 0.0, -1.0);
        let mut obs = heapless::Vec::<Observation, 8192>::new();
        // A wall facing the sensor, and a pole of radius 0.19 (as wide as the sphere).
        for _ in 0..3000 {
            let p = Vector3::new(1.0, rng.range(-3.0, 3.0), rng.range(-1.5, 1.5));
            let _ = obs.push(at(p, sensor));
        }
        for _ in 0..600 {
            let a = rng.range(-1.5, 1.5);
            let p = Vector3::new(
                -0.5 - 0.19 * libm::cos(a),
                0.19 * libm::sin(a),
                rng.range(-1.5, 1.5),
            );
            let _ = obs.push(at(p, sensor));
        }
        let mut grid = [0u16; 32 * 32 * 32];
        let mut keys = [Key::default(); 8192];
        let det = detect(
            &obs,
            &mut keys,
            0.19,
            0.01,
            None,
            &mut grid,
            &Directions::default(),
            &ExtractSettings::default(),
        );
        assert!(det.is_none(), "{det:?}");
    }

    #[test]
    fn slices_split_on_length_and_gaps() {
        let mut obs = heapless::Vec::<Observation, 64>::new();
        for t in [0, 100, 200, 450, 460, 2000, 2100] {
            let mut o = at(Vector3::new(1.0, 0.0, 0.0), Vector3::zeros());
            o.time = GpsTime(t * 1_000_000);
            let _ = obs.push(o);
        }
        assert_eq!(assign_slices(&mut obs, 400_000_000, 100), 3);
        let mut it = slices(&obs);
        assert_eq!(it.next(), Some(0..3));
        assert_eq!(it.next(), Some(3..5));
        assert_eq!(it.next(), Some(5..7));
        assert_eq!(it.next(), None);
    }

    /// Scan-line segments by hand: one laser's consecutive firings whose ranges step under the
    /// jump share their first-to-last length; a range jump, a missed firing or a gap starts a
    /// new one; a second return of a firing is a segment of its own; another laser's returns
    /// between them change nothing.
    #[test]
    fn segments_by_hand() {
        let f = 55_296i64;
        // (laser, firing, range, x along the line)
        let rows = [
            (0u8, 0i64, 5.0f32, 0.0f64),
            (1, 0, 7.0, 9.0),
            (0, 1, 5.1, 0.1),
            (0, 1, 8.0, 4.0), // the second return of firing 1
            (0, 2, 5.2, 0.3),
            (0, 3, 9.0, 2.0), // a range jump of 3.8 m
            (0, 5, 9.1, 2.5), // two firings on: a gap
            (0, 6, 9.2, 2.9),
            (1, 6, 7.1, 9.4),
        ];
        let mut v = heapless::Vec::<Observation, 16>::new();
        for (laser, k, range, x) in rows {
            let mut o = at(Vector3::new(x, 0.0, 0.0), Vector3::new(0.0, -5.0, 0.0));
            (o.laser, o.time, o.range) = (laser, GpsTime(k * f), range);
            let _ = v.push(o);
        }
        runs(&mut v, f, 0.3);
        let run: heapless::Vec<f32, 16> = v.iter().map(|o| o.work.run).collect();
        // Laser 1 fires at 0 and 6 only: two segments of one return each.
        let want = [0.3f32, 0.0, 0.3, 0.0, 0.3, 0.0, 0.4, 0.4, 0.0];
        for (k, (g, w)) in run.iter().zip(want).enumerate() {
            assert!((g - w).abs() < 1e-6, "return {k}: {run:?}");
        }
    }

    /// The one walk of [`prepare`] leaves the returns as the steps it stands for do one after
    /// the other (sort, georeference, segments, slices, tag), returns out of order included,
    /// and finds the nearest range.
    #[test]
    fn prepare_is_the_steps_in_one_walk() {
        let mut rng = Rng::new(3);
        let st = ExtractSettings::default();
        let t = Target {
            center: Vector3::new(1.0, 2.0, 3.0),
            radius: 0.2,
        };
        let mount = Mount::from_params(&crate::georef::Params([0.01, -0.02, 0.03, 0.1, 0.2, -0.3]));
        let mut v = heapless::Vec::<Observation, 2048>::new();
        for i in 0..2000i64 {
            let x = Vector3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), 0.5);
            let mut o = at(x, Vector3::new(-10.0, 0.0, -2.0));
            // Firings of 16 lasers, a few with a second return, a gap of a second.
            o.laser = (i % 16) as u8;
            o.channel = o.laser;
            o.block = u8::from(i % 7 == 0);
            o.time =
                GpsTime(1_000_000_000 + (i / 16) * 55_296 + i64::from(i >= 1000) * 1_000_000_000);
            o.range = rng.range(5.0, 6.0) as f32;
            o.position = Vector3::new(rng.range(-0.1, 0.1), 0.0, 0.0);
            let _ = v.push(o);
        }
        for sorted in [true, false] {
            let mut a = v.clone();
            if !sorted {
                a.reverse();
            }
            let mut b = a.clone();
            let mut seen = 0;
            let near = prepare(&mut a, &t, &mount, &st, 300, |_| seen += 1);
            assert_eq!(
                seen,
                a.len(),
                "each return given once, after the walk that sorted them"
            );
            b.sort_unstable_by_key(time_order);
            georeference(&mut b, &t, &mount, &TimeOffset::default());
            runs(&mut b, st.firing_ns, st.jump);
            let slices = assign_slices(&mut b, st.slice_ns, 300);
            tag(&mut b, ReturnClass::Unclassified);
            assert!(slices > 6, "{slices}");
            assert_eq!(a, b);
            let nearest = b.iter().map(|o| o.range).fold(f32::INFINITY, f32::min);
            assert_eq!(near, nearest);
        }
    }

    /// A 0.25 m sphere resting on the ground seen from 40 m up and 10 m aside (centre at the
    /// origin, NED, ground at down +r), the ground's returns within a 10 cm shell kept with
    /// the sphere's: every kept ground return is rejected, and of the sphere only returns
    /// within the shell's width of the ground. Three tripod legs under it instead of the
    /// ground: nothing is rejected.
    #[test]
    fn the_ground_under_a_sphere_is_rejected_and_a_tripod_is_not() {
        extern crate std;
        // Three scans of 8,192 observations: more than a test thread's stack.
        std::thread::Builder::new()
            .stack_size(64 << 20)
            .spawn(ground_and_tripod)
            .unwrap()
            .join()
            .unwrap();
    }

    fn ground_and_tripod() {
        let (r, tau) = (0.25, 0.1);
        let sensor = Vector3::new(-10.0, 0.0, -40.0);
        let c = Vector3::zeros();
        let mut v: heapless::Vec<Observation, 8192> = heapless::Vec::new();
        sphere_cap(sensor, c, r, 0.0004, &mut v);
        let on_sphere = v.len();
        assert!(on_sphere > 300, "{on_sphere}");
        // The ground within 0.75 m of the contact, where the sphere does not hide it.
        for i in -30..=30 {
            for j in -30..=30 {
                let g = Vector3::new(f64::from(i) * 0.025, f64::from(j) * 0.025, r);
                let d = (g - sensor).normalize();
                if crate::sim::scene::ray_sphere(&sensor, &d, &c, r).is_none() {
                    let _ = v.push(at(g, sensor));
                }
            }
        }
        let shell = |o: &Observation| (norm(o.work.x) - r as f32).abs() < tau as f32;
        let mut obs = v.clone();
        for o in obs.iter_mut() {
            if shell(o) {
                o.work.verdict = ReturnClass::Kept as u8;
            }
        }
        let ground_kept = obs[on_sphere..]
            .iter()
            .filter(|o| o.work.verdict == ReturnClass::Kept as u8)
            .count();
        assert!(ground_kept > 30, "{ground_kept}");
        let n = reject_touching_plane(&mut obs, r, tau, 12);
        assert!(obs[on_sphere..]
            .iter()
            .all(|o| o.work.verdict != ReturnClass::Kept as u8));
        // Of the sphere, only the band within tau of the ground.
        for o in &obs[..on_sphere] {
            let near_ground = f64::from(o.work.x[2]) > r - tau;
            assert_eq!(
                o.work.verdict == ReturnClass::Plane as u8,
                near_ground,
                "{:?}",
                o.work.x
            );
        }
        assert!(n >= ground_kept, "{n} {ground_kept}");
        // A tripod: three legs from under the sphere to the ground 1.5 m below.
        let mut obs: heapless::Vec<Observation, 8192> = heapless::Vec::new();
        sphere_cap(sensor, c, r, 0.0004, &mut obs);
        for leg in 0..3 {
            let a = f64::from(leg) * 2.0 * core::f64::consts::PI / 3.0;
            for k in 0..60 {
                let s = f64::from(k) / 60.0;
                let p = Vector3::new(0.0, 0.0, r + 0.02)
                    + Vector3::new(0.6 * a.cos(), 0.6 * a.sin(), 1.5) * s;
                let _ = obs.push(at(p, sensor));
            }
        }
        for o in obs.iter_mut() {
            if shell(o) {
                o.work.verdict = ReturnClass::Kept as u8;
            }
        }
        assert_eq!(reject_touching_plane(&mut obs, r, tau, 12), 0);
        assert_eq!(set_aside_ground(&mut obs, r, tau, 0.04), obs.len());
        ground_set_aside(&v, on_sphere, sensor, r, tau);
    }

    /// [`set_aside_ground`] on the slice above (sphere and ground, nothing kept yet), its
    /// points shifted 6 cm north and 8 cm down as a navigation error moves them together:
    /// every ground return is set aside at the end, tagged `Plane`; of the sphere only the
    /// band within 4 cm of the ground.
    fn ground_set_aside(
        v: &heapless::Vec<Observation, 8192>,
        on_sphere: usize,
        sensor: Vector3<f64>,
        r: f64,
        tau: f64,
    ) {
        let shift = [0.06f32, 0.0, 0.08];
        let mut obs = v.clone();
        for (k, o) in obs.iter_mut().enumerate() {
            o.work.x = [o.work.x[0] + shift[0], o.work.x[1], o.work.x[2] + shift[2]];
            // The sphere's returns numbered by their place in the slice (the ground's 0).
            o.block = u8::from(k < on_sphere);
            o.channel = (k % 256) as u8;
        }
        let band = 0.04;
        let front = set_aside_ground(&mut obs, r, tau, band);
        let ground = v.len() - on_sphere;
        let sphere_near_ground = v[..on_sphere]
            .iter()
            .filter(|o| f64::from(o.work.x[2]) > r - band)
            .count();
        assert_eq!(v.len() - front, ground + sphere_near_ground, "{sensor:?}");
        assert!(obs[..front].iter().all(|o| o.block == 1));
        assert!(obs[front..]
            .iter()
            .all(|o| o.work.verdict == ReturnClass::Plane as u8));
    }
}

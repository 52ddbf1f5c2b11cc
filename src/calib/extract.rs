//! Sphere extraction: which of a window's returns are on the sphere, among 10-100 times more
//! returns off the deck, the quay wall, the stand, people and parked vehicles.
//!
//! A wrong a-priori mounting moves the apparent sphere by metres, differently on every pass,
//! so the surveyed centre is a prior, not a constraint. Over a short slice of time (0.4 s) the
//! platform barely turns relative to the sphere and the error of the mounting moves the
//! sphere's returns almost rigidly, so the sphere of known radius is detected there:
//!
//! 1. **Hough voting on the centre** (radius known): each return votes for the centres a
//!    sphere through it could have, on the hemisphere of radius r behind it as seen from the
//!    sensor (the inward normal points along the beam), in a voxel grid over the slice (cells of
//!    r/2; the caller's scratch, no heap). The strongest distinct peaks are kept.
//! 2. **Refinement and scoring** of each peak: a fixed-radius centre fit on the returns near
//!    its surface, then an MSAC score `sum (1 - (e/tau)^2)` over the visible-side returns within
//!    `tau` of the surface, minus a penalty for every return the sphere would make impossible:
//!    inside the solid sphere, or behind it on a beam that passes through it (free-space
//!    violations). A plane or a pole through a candidate leaves returns inside it; a real
//!    sphere on a tripod leaves none.
//! 3. **Acceptance**: enough inliers, few violations, and (without a prior) a cap that a plane
//!    does not fit as well as the sphere does. With a prior (later rounds, once the mounting is
//!    close) the centre must also lie within the prior radius of the surveyed centre.
//!
//! The solver (`solve`) then keeps the returns near each slice's detected sphere, solves the
//! six parameters against the surveyed centres, re-georeferences, re-detects with a tighter
//! prior and shell, until the kept set stops changing. Returns are tagged with a [`Verdict`].

use super::objective::{Noise, TimeOffset};
use crate::georef::Mount;
use crate::window::{Observation, Target};
use core::ops::Range;
use nalgebra::{Matrix3, Vector3};

/// Why a windowed return is, or is not, used (stored in `Observation::work.verdict`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Verdict {
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

impl Verdict {
    /// All verdicts, in their numeric order.
    pub const ALL: [Verdict; 8] = [
        Verdict::Unclassified,
        Verdict::Kept,
        Verdict::Undetected,
        Verdict::OutsideShell,
        Verdict::Hidden,
        Verdict::Plane,
        Verdict::Pole,
        Verdict::NotFound,
    ];

    /// From the stored byte.
    pub fn from_u8(v: u8) -> Self {
        Self::ALL
            .get(usize::from(v))
            .copied()
            .unwrap_or(Verdict::Unclassified)
    }

    /// Its name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Unclassified => "unclassified",
            Verdict::Kept => "kept",
            Verdict::Undetected => "undetected",
            Verdict::OutsideShell => "outside_shell",
            Verdict::Hidden => "hidden_side",
            Verdict::Plane => "plane",
            Verdict::Pole => "pole",
            Verdict::NotFound => "sphere_not_found",
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

type V3 = [f32; 3];

#[inline]
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
fn norm(a: V3) -> f32 {
    libm::sqrtf(dot(a, a))
}

/// Georeference every observation of one sphere with `mount` and the time offset `time` (on
/// top of the observations' poses, [`Observation::georef_dt`]): the return relative to the
/// surveyed centre and the beam's direction, into `work`.
pub fn georeference(obs: &mut [Observation], t: &Target, mount: &Mount, time: &TimeOffset) {
    for o in obs.iter_mut() {
        let rot = o.rot();
        let y = mount.r_li * o.q();
        let x = o.georef_dt(mount, time.at(o)) - t.center;
        let u = rot * y;
        let n = u.norm().max(1e-9);
        o.work.x = [x.x as f32, x.y as f32, x.z as f32];
        o.work.u = [(u.x / n) as f32, (u.y / n) as f32, (u.z / n) as f32];
    }
}

/// Scan-line segments: consecutive firings of one laser whose ranges differ by less than
/// `jump` form a segment; every return gets its segment's length (first to last return, with
/// the current mounting) in `work.run`. A sphere in front of its background is crossed by
/// segments no longer than its diameter; a deck or a wall by long ones. Observations must be in
/// time order; a second return of the same firing (dual mode) is a segment of its own.
pub fn runs(obs: &mut [Observation], firing_ns: i64, jump: f64) {
    let jump = jump as f32;
    let max_dt = firing_ns + firing_ns / 2;
    let joins = |a: &Observation, b: &Observation| {
        let dt = b.time.0 - a.time.0;
        dt > 0 && dt <= max_dt && (b.range - a.range).abs() < jump
    };
    let twin = |a: &Observation, b: &Observation| b.time == a.time;
    // Pass 1: each segment's length, kept in its first return.
    let mut state: [Option<(usize, usize)>; 64] = [None; 64];
    for i in 0..obs.len() {
        let l = usize::from(obs[i].laser) & 63;
        match state[l] {
            Some((_, last)) if twin(&obs[last], &obs[i]) => obs[i].work.run = 0.0,
            Some((s, last)) if joins(&obs[last], &obs[i]) => state[l] = Some((s, i)),
            prev => {
                if let Some((s, last)) = prev {
                    obs[s].work.run = norm(sub(obs[last].work.x, obs[s].work.x));
                }
                state[l] = Some((i, i));
            }
        }
    }
    for (s, last) in state.iter().flatten() {
        obs[*s].work.run = norm(sub(obs[*last].work.x, obs[*s].work.x));
    }
    // Pass 2: the same walk hands every return its segment's length.
    let mut state: [Option<(usize, usize)>; 64] = [None; 64];
    for i in 0..obs.len() {
        let l = usize::from(obs[i].laser) & 63;
        match state[l] {
            Some((_, last)) if twin(&obs[last], &obs[i]) => {}
            Some((s, last)) if joins(&obs[last], &obs[i]) => {
                obs[i].work.run = obs[s].work.run;
                state[l] = Some((s, i));
            }
            _ => state[l] = Some((i, i)),
        }
    }
}

/// Number the slices of time of observations sorted by time (into `work.slice`): runs no
/// longer than `slice_ns` and no more than `max_len` returns; a gap longer than
/// `slice_ns / 2` also ends one. Returns how many.
pub fn assign_slices(obs: &mut [Observation], slice_ns: i64, max_len: usize) -> u32 {
    let mut id = 0u32;
    let (mut t0, mut len) = (i64::MIN, 0usize);
    for i in 0..obs.len() {
        let t = obs[i].time.0;
        let gap = i > 0 && !(0..=slice_ns / 2).contains(&(t - obs[i - 1].time.0));
        if i == 0 || gap || t - t0 > slice_ns || len >= max_len.max(1) {
            if i > 0 {
                id += 1;
            }
            t0 = t;
            len = 0;
        }
        len += 1;
        obs[i].work.slice = id;
    }
    if obs.is_empty() {
        0
    } else {
        id + 1
    }
}

/// The slices of observations grouped by `work.slice` (any order within a slice): the index
/// ranges of equal slice numbers.
pub fn slices(obs: &[Observation]) -> impl Iterator<Item = Range<usize>> + '_ {
    let mut i = 0;
    core::iter::from_fn(move || {
        if i >= obs.len() {
            return None;
        }
        let start = i;
        let id = obs[i].work.slice;
        while i < obs.len() && obs[i].work.slice == id {
            i += 1;
        }
        Some(start..i)
    })
}

/// What a candidate centre explains in a slice.
#[derive(Debug, Clone, Copy, Default)]
pub struct Support {
    /// MSAC weight of the inliers.
    pub weight: f32,
    /// Inliers.
    pub inliers: u32,
    /// Free-space violations.
    pub violations: u32,
    /// Visible-side returns in the collar just outside the sphere.
    pub collar: u32,
}

/// A slice of observations with its index sorted by x (`keys`: x and the observation's
/// index): the returns near a point are a contiguous run of the index.
#[derive(Debug, Clone, Copy)]
pub struct Sorted<'a> {
    /// The observations (any order).
    pub obs: &'a [Observation],
    /// (x, index), by x.
    pub keys: &'a [(f32, u32)],
}

impl<'a> Sorted<'a> {
    /// Index `obs` by x into `keys` (at least as long as `obs`; the rest is left alone).
    pub fn new(obs: &'a [Observation], keys: &'a mut [(f32, u32)]) -> Self {
        let n = obs.len().min(keys.len());
        for (i, (k, o)) in keys.iter_mut().zip(obs).enumerate() {
            *k = (o.work.x[0], i as u32);
        }
        keys[..n].sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        Self {
            obs: &obs[..n],
            keys: &keys[..n],
        }
    }

    /// The returns whose x lies within `reach` of `cx`.
    pub fn near(&self, cx: f32, reach: f32) -> impl Iterator<Item = &'a Observation> + Clone {
        let a = self.keys.partition_point(|k| k.0 < cx - reach);
        let b = self.keys.partition_point(|k| k.0 <= cx + reach);
        let obs = self.obs;
        self.keys[a..b.max(a)]
            .iter()
            .map(move |k| &obs[k.1 as usize])
    }
}

/// What a candidate centre `c` (relative) of radius `r` with band `tau` explains among the
/// returns near it (of an x-sorted slice): inliers, returns inside the solid sphere, returns in
/// the collar just outside it.
pub fn support(obs: &Sorted<'_>, c: V3, r: f32, tau: f32) -> Support {
    let mut s = Support::default();
    let collar = r + tau + (2.0 * tau).max(0.05);
    let inner = r - tau.max(0.02);
    for o in obs.near(c[0], collar) {
        let d = sub(o.work.x, c);
        let e2 = dot(d, d);
        if e2 > collar * collar {
            continue;
        }
        let dist = libm::sqrtf(e2);
        let e = dist - r;
        let visible = dot(d, o.work.u) <= 0.25 * dist;
        if e.abs() < tau {
            // The visible side: the outward normal faces the sensor.
            if visible {
                s.weight += 1.0 - (e / tau) * (e / tau);
                s.inliers += 1;
            }
        } else if dist < inner {
            s.violations += 1;
        } else if e > 0.0 && visible {
            // Just outside: a cylinder or a surface that goes on where a sphere ends.
            s.collar += 1;
        }
    }
    s
}

/// Returns seen through the candidate sphere: the beam from the sensor to the return passes
/// through the solid sphere before reaching it (every return of the slice is checked).
/// Going back from the return along its beam, `x - s u`, the beam is nearest the centre at
/// `s = d.u`.
pub fn seen_through(obs: &[Observation], c: V3, r: f32, tau: f32) -> u32 {
    let inner = r - tau.max(0.02);
    let mut n = 0;
    for o in obs {
        let d = sub(o.work.x, c);
        let along = dot(d, o.work.u);
        if along > r && along < o.range {
            let perp2 = dot(d, d) - along * along;
            if perp2 < inner * inner {
                n += 1;
            }
        }
    }
    n
}

/// Fit a sphere centre of radius `r` (fixed) to the visible-side returns within `band` of the
/// surface around `c` (Gauss-Newton, a few steps).
pub fn refine(obs: &Sorted<'_>, mut c: V3, r: f32, band: f32) -> V3 {
    for _ in 0..4 {
        let mut jtj = Matrix3::<f32>::zeros();
        let mut jtr = Vector3::<f32>::zeros();
        let mut n = 0;
        let reach = r + band;
        for o in obs.near(c[0], reach) {
            let d = sub(o.work.x, c);
            let e2 = dot(d, d);
            if e2 > reach * reach {
                continue;
            }
            let dist = libm::sqrtf(e2);
            let e = dist - r;
            if e.abs() > band || dist <= 0.0 || dot(d, o.work.u) > 0.25 * dist {
                continue;
            }
            let j = Vector3::new(-d[0] / dist, -d[1] / dist, -d[2] / dist);
            jtj += j * j.transpose();
            jtr += j * e;
            n += 1;
        }
        if n < 4 {
            return c;
        }
        let Some(ch) = jtj.cholesky() else { return c };
        let step = ch.solve(&(-jtr));
        if !step.iter().all(|x| x.is_finite()) {
            return c;
        }
        c = [c[0] + step.x, c[1] + step.y, c[2] + step.z];
        if step.norm() < 1e-4 {
            break;
        }
    }
    c
}

/// RMS distances of the inliers of `c` from the sphere and from their best plane: a cap of a
/// sphere is fitted better by the sphere; a plane patch (deck, wall) equally well by a plane.
pub fn plane_vs_sphere(obs: &Sorted<'_>, c: V3, r: f32, tau: f32) -> (f32, f32) {
    let (mut n, mut m, mut e2) = (0f32, [0f32; 3], 0f32);
    let inlier = |o: &Observation| {
        let d = sub(o.work.x, c);
        let dist = norm(d);
        let e = dist - r;
        (e.abs() < tau && dot(d, o.work.u) <= 0.25 * dist).then_some(e)
    };
    let obs = obs.near(c[0], r + tau);
    for o in obs.clone() {
        if let Some(e) = inlier(o) {
            n += 1.0;
            e2 += e * e;
            for (k, mk) in m.iter_mut().enumerate() {
                *mk += o.work.x[k];
            }
        }
    }
    if n < 4.0 {
        return (0.0, 0.0);
    }
    let m = [m[0] / n, m[1] / n, m[2] / n];
    let mut cov = Matrix3::<f32>::zeros();
    for o in obs {
        if inlier(o).is_some() {
            let d = Vector3::from(sub(o.work.x, m));
            cov += d * d.transpose();
        }
    }
    let Some(ev) = eigenvalues(cov) else {
        return (0.0, 0.0);
    };
    let lo = ev.iter().copied().fold(f32::INFINITY, f32::min).max(0.0);
    (libm::sqrtf(e2 / n), libm::sqrtf(lo / n))
}

/// Eigenvalues of a symmetric 3x3 matrix, with the iterations bounded (`None` when they do not
/// converge, e.g. on a NaN).
fn eigenvalues(m: Matrix3<f32>) -> Option<[f32; 3]> {
    let e = nalgebra::SymmetricEigen::try_new(m, f32::EPSILON, 100)?;
    let v = [e.eigenvalues[0], e.eigenvalues[1], e.eigenvalues[2]];
    v.iter().all(|x| x.is_finite()).then_some(v)
}

/// The strongest distinct cells of the vote grid.
struct Peaks<const K: usize> {
    cell: [u32; K],
    at: [[i32; 3]; K],
    count: [u16; K],
    dims: [u32; 3],
}

impl<const K: usize> Peaks<K> {
    fn new(dims: [u32; 3]) -> Self {
        Self {
            cell: [u32::MAX; K],
            at: [[i32::MIN; 3]; K],
            count: [0; K],
            dims,
        }
    }

    fn xyz(&self, k: u32) -> [i32; 3] {
        let z = k % self.dims[2];
        let y = (k / self.dims[2]) % self.dims[1];
        let x = k / (self.dims[2] * self.dims[1]);
        [x as i32, y as i32, z as i32]
    }

    /// Cell `k` now holds `v` votes.
    #[inline]
    fn offer(&mut self, k: u32, v: u16, min: &mut u16) {
        if v <= *min {
            return;
        }
        // A slot near this cell (within 2 cells) is the same blob: keep the higher one.
        let p = self.xyz(k);
        let slot = (0..K).find(|&i| {
            let q = self.at[i];
            if self.cell[i] == u32::MAX {
                return false;
            }
            (p[0] - q[0]).abs() <= 2 && (p[1] - q[1]).abs() <= 2 && (p[2] - q[2]).abs() <= 2
        });
        let i = match slot {
            Some(i) if v > self.count[i] => i,
            Some(_) => return,
            None => (0..K).min_by_key(|&i| self.count[i]).unwrap_or(0),
        };
        self.cell[i] = k;
        self.at[i] = p;
        self.count[i] = v;
        *min = if self.cell.contains(&u32::MAX) {
            0
        } else {
            self.count.iter().copied().min().unwrap_or(0)
        };
    }
}

/// The vote grid over a region: origin, cell size and dimensions.
#[derive(Debug, Clone, Copy)]
struct Grid {
    lo: V3,
    h: f32,
    dims: [u32; 3],
}

impl Grid {
    #[inline]
    fn index(&self, c: V3) -> Option<u32> {
        let mut k = 0u32;
        for ((&ca, &lo), &dim) in c.iter().zip(&self.lo).zip(&self.dims) {
            let f = (ca - lo) / self.h;
            // NaN fails both tests.
            if f.is_nan() || f < 0.0 || f >= dim as f32 {
                return None;
            }
            k = k * dim + f as u32;
        }
        Some(k)
    }

    fn center(&self, xyz: [i32; 3]) -> V3 {
        [
            self.lo[0] + (xyz[0] as f32 + 0.5) * self.h,
            self.lo[1] + (xyz[1] as f32 + 0.5) * self.h,
            self.lo[2] + (xyz[2] as f32 + 0.5) * self.h,
        ]
    }
}

/// Detect the sphere of radius `r` in one slice (observations georeferenced by
/// [`georeference`]). `prior`: the centre must lie within this distance of the surveyed one
/// (`None`: anywhere, with the shape test). `grid` is scratch for the votes (all zero on entry
/// and on return; 64^3 cells are plenty); `keys` is scratch for the slice's index by x (at
/// least as long as the slice; a longer slice is searched in its first `keys.len()` returns).
#[allow(clippy::too_many_arguments)]
pub fn detect(
    obs: &[Observation],
    keys: &mut [(f32, u32)],
    r: f64,
    tau: f64,
    prior: Option<f64>,
    grid: &mut [u16],
    dirs: &Directions,
    st: &ExtractSettings,
) -> Option<Detection> {
    let mut all = Candidates::new();
    detect_all(obs, keys, r, tau, prior, grid, dirs, st, 1, &mut all);
    all.first().copied()
}

/// Most sphere-like candidates [`detect_all`] returns per slice.
pub const MAX_CANDIDATES: usize = 4;

/// A slice's accepted candidates, best first.
pub type Candidates = heapless::Vec<Detection, MAX_CANDIDATES>;

/// As [`detect`], the `most` best acceptable candidates into `out` (best score first, at most
/// [`MAX_CANDIDATES`], centres at least a radius apart): a slice can hold the sphere and things
/// that look like it (a buoy, a fender, a bollard's cap seen by one scan line), which only the
/// consensus across slices, passes and spheres tells apart ([`super::consensus`]).
#[allow(clippy::too_many_arguments)]
pub fn detect_all(
    obs: &[Observation],
    keys: &mut [(f32, u32)],
    r: f64,
    tau: f64,
    prior: Option<f64>,
    grid: &mut [u16],
    dirs: &Directions,
    st: &ExtractSettings,
    most: usize,
    out: &mut Candidates,
) {
    const K: usize = 16;
    out.clear();
    let most = most.clamp(1, MAX_CANDIDATES);
    let r = r as f32;
    let tau = tau as f32;
    let prior = prior.map(|p| p as f32);
    // The region the centre may be in.
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    // Voters: returns on scan-line segments no longer than the sphere (a plane's long
    // segments would bury its peak), within reach of the prior.
    let run_max = 2.0 * r + 2.0 * tau + 0.05;
    let voter = |o: &Observation| {
        o.work.run <= run_max
            && match prior {
                Some(p) => o.work.x.iter().all(|v| v.abs() <= p + 2.0 * r),
                None => true,
            }
    };
    let mut voters = 0;
    for o in obs.iter().filter(|o| voter(o)) {
        voters += 1;
        for a in 0..3 {
            lo[a] = lo[a].min(o.work.x[a] - r);
            hi[a] = hi[a].max(o.work.x[a] + r);
        }
    }
    let need = if prior.is_some() {
        st.min_inliers_prior
    } else {
        st.min_inliers
    };
    if voters < need {
        return;
    }
    if let Some(p) = prior {
        for a in 0..3 {
            lo[a] = lo[a].max(-p - r);
            hi[a] = hi[a].min(p + r);
        }
    }
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0f32, f32::max);
    if !extent.is_finite() || extent <= 0.0 {
        return;
    }
    let nmax = (libm::cbrt(grid.len() as f64) as u32).max(1);
    let h = (0.5 * r).max(extent / nmax as f32);
    let mut dims = [1u32; 3];
    for a in 0..3 {
        dims[a] = (((hi[a] - lo[a]) / h) as u32 + 1).min(nmax);
    }
    let g = Grid { lo, h, dims };
    // Indexed by x, the returns near a candidate are a contiguous run of the index.
    let sorted = Sorted::new(obs, keys);
    let obs = sorted.obs;
    let mut peaks = Peaks::<K>::new(dims);
    let mut min = 0u16;
    // Vote; then, per vote, read the cell (its first reader sees its full count: the peaks)
    // and take the vote back (the grid is left all zero).
    for pass in 0..2 {
        for o in obs.iter().filter(|o| voter(o)) {
            let (x, u) = (o.work.x, o.work.u);
            for d in &dirs.0 {
                if dot(*d, u) <= 0.0 {
                    continue;
                }
                let c = [x[0] + r * d[0], x[1] + r * d[1], x[2] + r * d[2]];
                let Some(k) = g.index(c) else { continue };
                let cell = &mut grid[k as usize];
                if pass == 0 {
                    *cell = cell.wrapping_add(1);
                } else {
                    peaks.offer(k, *cell, &mut min);
                    *cell = cell.wrapping_sub(1);
                }
            }
        }
    }
    // Refine and score the strongest peaks; keep the best acceptable one.
    let mut order: [usize; K] = core::array::from_fn(|i| i);
    order.sort_unstable_by(|&a, &b| peaks.count[b].cmp(&peaks.count[a]));
    // With a prior, the surveyed centre itself is the first candidate (refined within a
    // narrow band: the stand's returns are near); then the peaks (from a cell's precision).
    let first = prior.map(|_| ([0f32; 3], (2.0 * tau).max(0.01)));
    let cands = first.into_iter().chain(
        order
            .iter()
            .take(st.peaks.min(K))
            .filter(|&&i| peaks.cell[i] != u32::MAX && usize::from(peaks.count[i]) >= need / 2)
            .map(|&i| (g.center(peaks.at[i]), (1.5 * h).max(2.0 * tau))),
    );
    for (c0, band) in cands {
        let c1 = refine(&sorted, c0, r, band);
        let c = refine(&sorted, c1, r, tau.max(0.01));
        if let Some(p) = prior {
            if norm(c) > p {
                continue;
            }
        }
        let s = support(&sorted, c, r, tau);
        let score = s.weight
            - st.violation_weight * s.violations as f32
            - st.collar_weight * s.collar as f32;
        // A candidate as good as one already accepted within a radius of it adds nothing.
        let beaten = |c: [f32; 3], score: f32| {
            out.iter()
                .any(|d| norm(sub(d.center, c)) < r && d.score >= score)
        };
        // Only what could still enter the list gets the costlier tests below.
        let full = out.len() >= most && out.last().is_some_and(|w| score <= w.score);
        if (s.inliers as usize) < need
            || s.violations as f32 > 0.25 * s.inliers as f32 + 2.0
            || score <= 0.0
            || full
            || beaten(c, score)
        {
            continue;
        }
        if prior.is_none() {
            // Without a prior the cap must be curved like the sphere: a plane must fit it
            // clearly worse.
            let (sph, pl) = plane_vs_sphere(&sorted, c, r, tau);
            if pl < 1.5 * sph || pl < 0.004 {
                continue;
            }
        }
        // Last, the beams that pass through it to returns behind (a scan of the slice).
        let through = seen_through(obs, c, r, tau);
        let violations = s.violations + through;
        let score = score - st.violation_weight * through as f32;
        if violations as f32 > 0.25 * s.inliers as f32 + 2.0 || score <= 0.0 {
            continue;
        }
        if beaten(c, score) {
            continue;
        }
        out.retain(|d| norm(sub(d.center, c)) >= r);
        let d = Detection {
            center: c,
            inliers: s.inliers,
            score,
            violations,
        };
        let at = out.partition_point(|o| o.score >= score);
        if out.len() >= most {
            if at >= out.len() {
                continue;
            }
            out.pop();
        }
        let _ = out.insert(at, d);
    }
}

/// Tag the observations of a slice against a sphere of radius `r` centred at `c` (relative):
/// `Kept` within `tau` of its surface on the visible side, `Hidden` within `tau` on the far
/// side, `OutsideShell` otherwise. Returns the number kept. A return whose trajectory is known
/// to be noisier than the noise model's (its own INS sigmas, [`Noise::inflation`]) gets a shell
/// wider by as much.
pub fn keep(obs: &mut [Observation], c: V3, r: f64, tau: f64, noise: &Noise) -> usize {
    let (r, tau0) = (r as f32, tau as f32);
    let mut n = 0;
    for o in obs.iter_mut() {
        let tau = if o.ins_sigma == [0.0; 2] {
            tau0
        } else {
            tau0 * noise.inflation(o) as f32
        };
        let d = sub(o.work.x, c);
        let dist = norm(d);
        let e = dist - r;
        o.work.verdict = if e.abs() <= tau {
            // Grazing returns with noise may sit slightly beyond the silhouette.
            if dot(d, o.work.u) <= tau.max(0.25 * dist) {
                n += 1;
                Verdict::Kept
            } else {
                Verdict::Hidden
            }
        } else {
            Verdict::OutsideShell
        } as u8;
    }
    n
}

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
            if o.work.verdict != Verdict::Kept as u8 {
                continue;
            }
            let x = o.work.x;
            if dot(x, axis) / norm(x).max(1e-9) >= cos_half {
                o.work.verdict = if line {
                    poles += 1;
                    Verdict::Pole
                } else {
                    planes += 1;
                    Verdict::Plane
                } as u8;
            }
        }
    }
    (planes, poles)
}

/// Tag every observation of a slice.
pub fn tag(obs: &mut [Observation], v: Verdict) {
    for o in obs.iter_mut() {
        o.work.verdict = v as u8;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Rng;
    use crate::time::GpsTime;

    /// An observation at a point `x` (relative to the surveyed centre) seen from `sensor`.
    fn at(x: Vector3<f64>, sensor: Vector3<f64>) -> Observation {
        let d = x - sensor;
        let u = d / d.norm();
        Observation {
            q_l: d.cast(),
            position: sensor,
            r_ig: Matrix3::identity(),
            time: GpsTime(0),
            range: d.norm() as f32,
            work: crate::window::Work {
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
        let mut keys = [(0f32, 0u32); 8192];
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
            .filter(|o| o.packet == 1 && o.work.verdict == Verdict::Kept as u8)
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
        let mut keys = [(0f32, 0u32); 8192];
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
}

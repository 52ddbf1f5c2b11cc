//! The stored batch (stage 4): table1's returns read from flash, and the simplex on them.

use crate::{Digest, Fnv, Meter, BATCH_FILE, BATCH_RETURNS, SIMPLEX_ITERATIONS};
use spherecal::align::window::{Observation, Target};
use spherecal::time::GpsTime;

/// Little-endian reads from the stored batch.
struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (head, rest) = self.0.split_first_chunk::<N>()?;
        self.0 = rest;
        Some(*head)
    }
    fn f64(&mut self) -> Option<f64> {
        self.take().map(f64::from_le_bytes)
    }
    fn f32(&mut self) -> Option<f32> {
        self.take().map(f32::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
}

/// The stored batch's head: its two spheres with their returns' counts, the start and the
/// truth (deg, m).
struct BatchHead {
    spheres: [(Target, usize); 2],
    start: [f64; 6],
    truth: [f64; 6],
}

/// The stored batch: its head, and the returns into `obs`.
fn read_batch(obs: &mut [Observation]) -> Option<BatchHead> {
    let mut r = Reader(BATCH_FILE);
    if r.take::<4>()? != *b"SCB1" || r.u32()? != 2 {
        return None;
    }
    let none = Target {
        center: nalgebra::Vector3::zeros(),
        radius: 0.0,
    };
    let mut spheres = [(none, 0usize); 2];
    for s in &mut spheres {
        let c = nalgebra::Vector3::new(r.f64()?, r.f64()?, r.f64()?);
        s.0 = Target {
            center: c,
            radius: r.f64()?,
        };
        s.1 = r.u32()? as usize;
    }
    let start: [f64; 6] = core::array::from_fn(|_| r.f64().unwrap_or(f64::NAN));
    let truth: [f64; 6] = core::array::from_fn(|_| r.f64().unwrap_or(f64::NAN));
    let n = (spheres[0].1 + spheres[1].1).min(obs.len());
    for o in &mut obs[..n] {
        o.time = GpsTime(i64::from_le_bytes(r.take()?));
        o.q_l = nalgebra::Vector3::new(r.f32()?, r.f32()?, r.f32()?);
        o.position = nalgebra::Vector3::new(r.f64()?, r.f64()?, r.f64()?);
        o.r_ig = nalgebra::Matrix3::from_iterator((0..9).map(|_| r.f32().unwrap_or(f32::NAN)));
        o.velocity = nalgebra::Vector3::new(r.f32()?, r.f32()?, r.f32()?);
        o.omega = nalgebra::Vector3::new(r.f32()?, r.f32()?, r.f32()?);
        o.range = r.f32()?;
    }
    Some(BatchHead {
        spheres,
        start,
        truth,
    })
}

/// The simplex on the stored batch (stage 4): Nelder-Mead on eq. 6 (L1) over the six from
/// the site's a-priori mounting, [`SIMPLEX_ITERATIONS`] iterations (timed by `meter`).
/// Returns the six found and the truth the file holds (deg, m).
pub fn solve_stored(d: &mut Digest, meter: &mut impl Meter) -> Option<([f64; 6], [f64; 6])> {
    use spherecal::calib::nelder_mead::{minimize, NmSettings};
    use spherecal::calib::objective::{Problem, SphereObs};
    use spherecal::georef::DegM;
    let mut obs = [Observation::default(); BATCH_RETURNS];
    let BatchHead {
        spheres,
        start,
        truth,
    } = read_batch(&mut obs)?;
    let n0 = spheres[0].1.min(BATCH_RETURNS);
    let n1 = spheres[1].1.min(BATCH_RETURNS - n0);
    d.batch_returns = (n0 + n1) as u64;
    let mut h = Fnv::default();
    for o in &obs[..n0 + n1] {
        h.u64(o.time.0 as u64);
        for v in o.q_l.iter().chain(o.r_ig.iter()) {
            h.f32(*v);
        }
        for v in o.position.iter() {
            h.f64(*v);
        }
    }
    d.batch_hash = h.0;
    let sets = [
        SphereObs {
            target: spheres[0].0,
            obs: &obs[..n0],
        },
        SphereObs {
            target: spheres[1].0,
            obs: &obs[n0..n0 + n1],
        },
    ];
    let pb = Problem {
        spheres: &sets,
        stride: 1,
        dt: 0.0,
        drift: 0.0,
        t_ref: obs[0].time,
        weights: None,
        footprint: None,
    };
    let settings = NmSettings {
        max_iter: SIMPLEX_ITERATIONS,
        tol_x: 0.0,
        tol_f: 0.0,
        restarts: 0,
    };
    meter.start();
    let nm = minimize::<6, 7>(
        |x| pb.l1(&DegM(*x).params().0),
        &start,
        &[1.0, 1.0, 1.0, 0.1, 0.1, 0.1],
        &settings,
    );
    meter.stop();
    d.simplex_iterations = nm.iterations as u64;
    d.simplex_evaluations = nm.evaluations as u64;
    d.simplex_l1_um = (nm.f * 1e6) as u64;
    let mut h = Fnv::default();
    for v in nm.x.iter().chain([nm.f].iter()) {
        h.f64(*v);
    }
    d.simplex_hash = h.0;
    Some((nm.x, truth))
}

#[cfg(test)]
mod tests {
    /// The stored batch's simplex lands on the mounting table1 was simulated with (its truth,
    /// written beside the returns): 2.3 to 2.5 deg and 0.19 to 0.40 m from where it starts.
    #[test]
    fn the_stored_batch_solves_to_its_truth() {
        let mut d = crate::Digest::default();
        let (x, truth) = super::solve_stored(&mut d, &mut ()).unwrap();
        assert_eq!(d.batch_returns, 400);
        for i in 0..3 {
            assert!((x[i] - truth[i]).abs() < 0.05, "{x:?} against {truth:?}");
            assert!(
                (x[i + 3] - truth[i + 3]).abs() < 0.005,
                "{x:?} against {truth:?}"
            );
        }
    }
}

//! A sphere's centre fitted to its returns with the radius held at the surveyed value
//! (Gauss-Newton on `||x_k - c|| - r`), to compare with the surveyed centre (the paper reports
//! 0.036 m RMS on real data).

use nalgebra::{Matrix3, Vector3};

/// Fit the centre from `c0` over the points `xs` (site NED) for a sphere of radius `r`.
/// `None` with fewer than four points or a singular geometry.
pub fn fit_center(
    xs: impl Iterator<Item = Vector3<f64>> + Clone,
    r: f64,
    c0: Vector3<f64>,
) -> Option<Vector3<f64>> {
    let mut c = c0;
    for _ in 0..50 {
        let mut jtj = Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        let mut n = 0;
        for x in xs.clone() {
            let d = x - c;
            let norm = d.norm();
            if norm == 0.0 {
                continue;
            }
            let j = -d / norm;
            jtj += j * j.transpose();
            jtr += j * (norm - r);
            n += 1;
        }
        if n < 4 {
            return None;
        }
        let step = jtj.cholesky()?.solve(&(-jtr));
        c += step;
        if step.norm() < 1e-10 {
            break;
        }
    }
    Some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_known_centre_from_a_cap() {
        // Points on a 60 deg cap of a sphere of radius 0.19 around (10, -2, 1), seen from one side.
        let c = Vector3::new(10.0, -2.0, 1.0);
        let mut pts = heapless::Vec::<Vector3<f64>, 512>::new();
        for i in 0..20 {
            for j in 0..20 {
                let (th, ph) = (f64::from(i) * 0.05 - 0.5, f64::from(j) * 0.05 - 0.5);
                let dir = Vector3::new(-th.cos() * ph.cos(), th.sin() * ph.cos(), ph.sin());
                pts.push(c + dir * 0.19).unwrap();
            }
        }
        let got = fit_center(
            pts.iter().copied(),
            0.19,
            c + Vector3::new(0.05, 0.03, -0.02),
        )
        .unwrap();
        assert!((got - c).norm() < 1e-9, "{got}");
        assert!(fit_center(pts.iter().take(3).copied(), 0.19, c).is_none());
    }
}

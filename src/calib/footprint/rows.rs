//! The rows under the footprint against finite differences of the corrected residual, for
//! returns whose beams pass near a sphere's limb: the six, the time offset, the navigation
//! pieces' corrections and the centre.

use super::Footprint;
use crate::align::window::{Observation, Target};
use crate::calib::objective::{Linearised, NavCorrection};
use crate::frames::rotation;
use crate::georef::{Mount, Params, P};
use crate::sim::rng::Rng;
use nalgebra::Vector3;

#[test]
fn limb_rows_match_finite_differences() {
    let fp = Some(Footprint::VELODYNE);
    let b = [1.55, 0.0, 1.6, 0.1, 0.0, 0.15];
    let lin = Linearised::at(&b).with_footprint(fp);
    let mount = Mount::from_params(&Params(b));
    let t = Target {
        center: Vector3::new(3.0, 2.0, -38.0),
        radius: 0.25,
    };
    let mut rng = Rng::new(5);
    let mut worst: f64 = 0.0;
    // The largest bloom taken out: the rows are the footprint's, not a ray's.
    let mut bloom: f64 = 0.0;
    for _ in 0..20 {
        let position = Vector3::new(rng.range(-10.0, 10.0), rng.range(-10.0, 10.0), 0.0);
        let rot: nalgebra::Matrix3<f64> = rotation(
            rng.range(-0.05, 0.05),
            rng.range(-0.05, 0.05),
            rng.range(-3.0, 3.0),
        );
        let o_l = position + rot * mount.lever;
        let to_c = t.center - o_l;
        let dist = to_c.norm();
        let u0 = to_c / dist;
        let perp = u0
            .cross(&Vector3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                1.0,
            ))
            .normalize();
        let miss = t.radius + rng.range(-3.0, 2.0) * 0.75e-3 * dist;
        let u = (to_c + perp * miss).normalize();
        let p = o_l + u * (dist - rng.range(-0.05, 0.2));
        let q = mount.r_li.transpose() * (rot.transpose() * (p - position) - mount.lever);
        let o = Observation {
            q_l: q.cast(),
            position,
            r_ig: rot.cast(),
            range: q.norm() as f32,
            velocity: Vector3::new(4.0f32, -1.5, 0.3),
            omega: Vector3::new(0.05f32, -0.02, 0.3),
            ..Observation::default()
        };
        // The time offset.
        {
            let dt0 = 0.002;
            let r = lin
                .row_corrected(&o, &t, dt0, &NavCorrection::NONE)
                .unwrap();
            let h = 1e-7;
            let rp = lin
                .row_corrected(&o, &t, dt0 + h, &NavCorrection::NONE)
                .unwrap()
                .residual;
            let rm = lin
                .row_corrected(&o, &t, dt0 - h, &NavCorrection::NONE)
                .unwrap()
                .residual;
            let fd = (rp - rm) / (2.0 * h);
            assert!(
                (fd - r.row[6]).abs() < 2e-3 * (1.0 + fd.abs()),
                "dt: fd {fd:.5} row {:.5} (residual {:.4})",
                r.row[6],
                r.residual
            );
        }
        // The globals.
        let r0 = lin
            .row_corrected(&o, &t, 0.0, &NavCorrection::NONE)
            .unwrap();
        let ray = Linearised::at(&b).row(&o, &t, 0.0).unwrap();
        bloom = bloom.max((ray.residual - r0.residual).abs());
        for i in 0..P {
            let h = 1e-7;
            let (mut bp, mut bm) = (b, b);
            bp[i] += h;
            bm[i] -= h;
            let rp = Linearised::at(&bp)
                .with_footprint(fp)
                .row_corrected(&o, &t, 0.0, &NavCorrection::NONE)
                .unwrap()
                .residual;
            let rm = Linearised::at(&bm)
                .with_footprint(fp)
                .row_corrected(&o, &t, 0.0, &NavCorrection::NONE)
                .unwrap()
                .residual;
            let fd = (rp - rm) / (2.0 * h);
            worst = worst.max((fd - r0.row[i]).abs() / (1.0 + fd.abs()));
            assert!(
                (fd - r0.row[i]).abs() < 2e-3 * (1.0 + fd.abs()),
                "global {i}: fd {fd:.5} row {:.5} (residual {:.4})",
                r0.row[i],
                r0.residual
            );
        }
        // The navigation corrections and the centre.
        let at = |e: [f64; 9]| {
            let c = NavCorrection {
                position: Vector3::new(e[0], e[1], e[2]),
                rotation: Vector3::new(e[3], e[4], e[5]),
                centre: Vector3::new(e[6], e[7], e[8]),
            };
            lin.row_corrected(&o, &t, 0.0, &c).unwrap()
        };
        let p = r0.pose_row();
        // The centre moves the residual as the position does.
        let je = [p[0], p[1], p[2], p[3], p[4], p[5], p[0], p[1], p[2]];
        for k in 0..9 {
            let h = 1e-7;
            let (mut ep, mut em) = ([0.0; 9], [0.0; 9]);
            ep[k] = h;
            em[k] = -h;
            let fd = (at(ep).residual - at(em).residual) / (2.0 * h);
            assert!(
                (fd - je[k]).abs() < 2e-3 * (1.0 + fd.abs()),
                "nav {k}: fd {fd:.5} row {:.5} (residual {:.4})",
                je[k],
                r0.residual
            );
        }
    }
    assert!(worst > 0.0);
    // A 28 mm footprint (1 sigma, along) at 38 m: blooms of centimetres near the limb.
    assert!(bloom > 5e-3, "largest bloom {bloom}");
}

//! The consensus against hand-made candidates.
use super::*;
use crate::frames::rotation;
use crate::time::GpsTime;

/// A sensor on a platform at `p` heading `h` [rad] sees the point `x`: the centre
/// observation of a candidate at `x` with the true mounting `m`.
fn seen(x: Vector3<f64>, p: Vector3<f64>, h: f64, m: &Mount) -> Observation {
    let r = rotation(0.0, 0.0, h);
    let q = m.r_li.transpose() * (r.transpose() * (x - p) - m.lever);
    Observation {
        q_l: q.cast(),
        position: p,
        r_ig: r.cast(),
        time: GpsTime(0),
        ..Observation::default()
    }
}

/// Two spheres, passes north and south at 8-25 m; every slice of the first also holds a
/// decoy 1.2 m north of it, and the second is lost in half its slices. From a start off by
/// degrees and decimetres the consensus finds the truth, chooses the spheres, and no sphere
/// is ambiguous. With a decoy beside both spheres at the same offset and every pass in one
/// direction, a mounting 1.2 m off explains the decoys as well as the truth the spheres:
/// ambiguous.
#[test]
fn the_spheres_agree_and_the_decoys_do_not() {
    let truth = Params([0.05, -0.7, 0.02, 1.5, -1.2, -1.4]);
    let tm = truth.mount();
    let start = [0.09, -0.66, 0.04, 1.3, -1.1, -1.7];
    let targets = [
        Target {
            center: Vector3::new(0.0, 0.0, -1.6),
            radius: 0.19,
        },
        Target {
            center: Vector3::new(20.0, 0.0, -1.5),
            radius: 0.19,
        },
    ];
    let run = |both_ways: bool, decoy_at_both: bool| {
        let mut cands = vec![Candidate::default(); 1024];
        let mut n = 0;
        let mut slice = 0;
        for (pass, (east, north_bound)) in [(8.0, true), (20.0, false), (12.0, true), (25.0, false)]
            .iter()
            .enumerate()
        {
            let h = if *north_bound || !both_ways {
                0.0
            } else {
                core::f64::consts::PI
            };
            for k in 0..40 {
                let p = Vector3::new(-10.0 + k as f64 * 0.9, *east, 0.0);
                for (j, t) in targets.iter().enumerate() {
                    slice += 1;
                    let mut push = |x: Vector3<f64>| {
                        cands[n] = Candidate {
                            centre: seen(x, p, h, &tm),
                            sphere: j as u8,
                            group: (pass * 2 + j) as u16,
                            slice,
                            ..Candidate::default()
                        };
                        n += 1;
                    };
                    if j == 0 || decoy_at_both {
                        push(t.center + Vector3::new(1.2, 0.0, 0.0));
                    }
                    if !(j == 1 && k % 2 == 0 && !decoy_at_both) {
                        push(t.center);
                    }
                }
            }
        }
        // What the start mounting makes of them (their detections).
        let sm = Params(start).mount();
        for c in cands[..n].iter_mut() {
            let t = targets[usize::from(c.sphere)];
            let d = (c.centre.georef(&sm) - t.center).cast::<f32>();
            c.detected = [d.x, d.y, d.z];
        }
        let mut s = Search {
            cands: &mut cands[..n],
            targets: &targets,
            time: TimeOffset::default(),
            bounds: Bounds {
                start,
                angle: 0.5,
                lever: 3.0,
            },
            settings: ConsensusSettings::default(),
        };
        let mut scratch = [0usize; 1024];
        let c = consensus(&mut s, &start, &mut scratch).unwrap();
        let tm = truth.mount();
        let on = |c: &Candidate| {
            (c.centre.georef(&tm) - targets[usize::from(c.sphere)].center).norm() < 0.01
        };
        let chosen_true = s.cands.iter().filter(|c| c.chosen && on(c)).count();
        let chosen_decoy = s.cands.iter().filter(|c| c.chosen && !on(c)).count();
        (c, chosen_true, chosen_decoy)
    };
    let (c, good, bad) = run(true, false);
    for i in 0..P {
        assert!(
            (c.b[i] - truth.0[i]).abs() < 1e-6,
            "{i}: {:?} vs {:?}",
            c.b,
            truth.0
        );
    }
    assert_eq!((good, bad), (160 + 80, 0), "{c:?}");
    assert_eq!(c.support[..2], [160, 80]);
    assert!(c.ambiguous.is_none(), "{:?}", c.ambiguous);
    // A decoy beside both spheres at the same offset, every pass northbound: a lever arm
    // 1.2 m further forward explains them as well as the truth explains the spheres.
    let (c, _, _) = run(false, true);
    let a = c.ambiguous.expect("ambiguous");
    assert!(a.support[1] as f64 >= 0.8 * a.support[0] as f64, "{a:?}");
    assert!((Vector3::from(a.offset).norm() - 1.2).abs() < 0.05, "{a:?}");
}

#[test]
fn bounds_wrap_angles_and_bound_each_component() {
    let b = Bounds {
        start: [3.1, 0.0, 0.0, 1.0, 0.0, 0.0],
        angle: 0.1,
        lever: 0.5,
    };
    assert!(b.contains(&[-3.1, 0.05, 0.0, 1.4, -0.4, 0.2]));
    assert!(!b.contains(&[3.1, 0.0, 0.0, 1.6, 0.0, 0.0]));
    assert!(!b.contains(&[3.1, 0.2, 0.0, 1.0, 0.0, 0.0]));
    assert!((b.usage(&[3.1, 0.05, 0.0, 1.25, 0.0, 0.0])[1] - 0.5).abs() < 1e-12);
}

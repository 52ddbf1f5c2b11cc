//! The navigation rows against finite differences, and the Monte Carlo of the model's
//! honesty on exact returns.

use super::*;
use crate::calib::objective::{Linearised, NavCorrection};
use nalgebra::Vector3;

mod rows {
    use super::*;
    use crate::align::window::{Observation, Target};
    use crate::frames::rotation;

    /// The navigation rows `-n` (position) and `n x arm` (rotation) are the residual's
    /// derivatives by the correction `row_corrected` takes out.
    #[test]
    fn navigation_rows_match_finite_differences() {
        let mut rng = crate::sim::Rng::new(3);
        let lin = Linearised::at(&[3.13, -0.78, 0.02, 1.5, -1.24, -1.36]);
        let t = Target {
            center: Vector3::new(1.0, 12.0, -1.5),
            radius: 0.19,
        };
        for _ in 0..20 {
            let o = Observation {
                q_l: Vector3::new(
                    rng.range(-5.0, 5.0) as f32,
                    rng.range(5.0, 15.0) as f32,
                    rng.range(-3.0, 3.0) as f32,
                ),
                position: Vector3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), 0.0),
                r_ig: rotation(
                    rng.range(-0.1, 0.1),
                    rng.range(-0.1, 0.1),
                    rng.range(-3.0, 3.0),
                )
                .cast(),
                range: 10.0,
                ..Observation::default()
            };
            let at = |e: [f64; 6]| {
                let c = NavCorrection {
                    position: Vector3::new(e[0], e[1], e[2]),
                    rotation: Vector3::new(e[3], e[4], e[5]),
                    centre: Vector3::zeros(),
                };
                lin.row_corrected(&o, &t, 0.0, &c).unwrap()
            };
            let r0 = at([0.0; 6]);
            let je = r0.pose_row();
            for k in 0..6 {
                let h = 1e-6;
                let (mut ep, mut em) = ([0.0; 6], [0.0; 6]);
                ep[k] = h;
                em[k] = -h;
                let fd = (at(ep).residual - at(em).residual) / (2.0 * h);
                assert!(
                    (fd - je[k]).abs() < 1e-5 * (1.0 + fd.abs()),
                    "{k}: {fd} vs {}",
                    je[k]
                );
            }
        }
    }
}

mod honesty {
    use super::*;
    use crate::align::window::{Observation, Target};
    use crate::calib::noise::Noise;
    use crate::calib::objective::SphereObs;
    use crate::frames::rotation;
    use crate::sim::nav_error::{Correlated, GaussMarkov};
    use std::vec::Vec;

    const TRUTH: [f64; P] = [3.1329, -0.7837, 0.0209, 1.5, -1.24, -1.36];
    const SPHERES: [Target; 2] = [
        Target {
            center: Vector3::new(0.0, -0.6, -1.6),
            radius: 0.19,
        },
        Target {
            center: Vector3::new(20.0, -0.6, -1.55),
            radius: 0.19,
        },
    ];

    /// A survey of four passes (north and south at 9, 12, 21 and 30 m) sampled every 5 ms;
    /// at each sample, returns on the spheres within +-0.38 x range along the track, exact
    /// for the true pose and reported with the navigation error (the error's truth kept);
    /// `along`: the range noise along the beam, growing at incidence `theta` by
    /// `R spread tan(theta)` (a footprint's spread; `Some(0)`: not growing), else (`None`)
    /// across the surface.
    /// The returns on each sphere, and the navigation error's truth at each sample (time [ns],
    /// N, E, D, rotation about N, E, D).
    type Truth = Vec<(i64, [f64; 6])>;

    fn survey(
        seed: u64,
        c: &Correlated,
        range_sigma: f64,
        hetero: bool,
        along: Option<f64>,
    ) -> (Vec<Vec<Observation>>, Truth) {
        let mount = crate::georef::Mount::from_params(&crate::georef::Params(TRUTH));
        let mut gm = GaussMarkov::new(c, 0.005, seed);
        let mut rng = crate::sim::Rng::new(seed ^ 0x55);
        let mut out = std::vec![Vec::new(), Vec::new()];
        let mut truth = Vec::new();
        let passes: [(f64, f64, f64); 4] = [
            (9.0, 0.0, 1.3),
            (12.0, 180.0, 1.8),
            (21.0, 0.0, 3.6),
            (30.0, 180.0, 4.5),
        ];
        let mut t = 0.0f64;
        for (range, hd, speed) in passes {
            let (n0, n1) = if hd == 0.0 {
                (-15.0, 35.0)
            } else {
                (35.0, -15.0)
            };
            let dur = (n1 - n0) / if hd == 0.0 { speed } else { -speed };
            let mut s = 0.0;
            while s < dur {
                let e = gm.step().0;
                truth.push(((t * 1e9) as i64, e));
                let north = n0 + (n1 - n0) * s / dur;
                let roll = 0.026 * libm::sin(s * 1.05);
                let pitch = 0.014 * libm::sin(s * 1.4);
                let r_true = rotation(roll, pitch, hd.to_radians());
                let p_true = Vector3::new(north, range, 0.0);
                let r_rep = rotation(e[3], e[4], e[5]) * r_true;
                let p_rep = p_true + Vector3::new(e[0], e[1], e[2]);
                for (j, tg) in SPHERES.iter().enumerate() {
                    if (tg.center.x - north).abs() > 0.38 * range || rng.uniform() > 0.6 {
                        continue;
                    }
                    let sensor = p_true + r_true * mount.lever;
                    let to = (tg.center - sensor).normalize();
                    let nrm = (-to
                        + Vector3::new(
                            rng.range(-0.6, 0.6),
                            rng.range(-0.6, 0.6),
                            rng.range(-0.6, 0.6),
                        ))
                    .normalize();
                    // Heteroscedastic: the range noise grows with the range squared (as a
                    // footprint's spread does), 0.36-4x the declared over the four passes.
                    let sd = if hetero {
                        range_sigma * (range / 15.0) * (range / 15.0)
                    } else {
                        range_sigma
                    };
                    let on = tg.center + nrm * tg.radius;
                    let x = if let Some(spread) = along {
                        let u = (on - sensor).normalize();
                        let cos = u.dot(&nrm).abs().max(0.1);
                        let tan = libm::sqrt(1.0 - cos * cos) / cos;
                        let s = (on - sensor).norm() * spread * tan;
                        on + u * rng.gauss(libm::sqrt(sd * sd + s * s))
                    } else {
                        tg.center + nrm * (tg.radius + rng.gauss(sd))
                    };
                    let q =
                        mount.r_li.transpose() * (r_true.transpose() * (x - p_true) - mount.lever);
                    out[j].push(Observation {
                        q_l: q.cast(),
                        position: p_rep,
                        r_ig: r_rep.cast(),
                        time: crate::time::GpsTime((t * 1e9) as i64),
                        range: q.norm() as f32,
                        ..Observation::default()
                    });
                }
                s += 0.005;
                t += 0.005;
            }
            // The turn.
            for _ in 0..500 {
                gm.step();
            }
            t += 2.5;
        }
        (out, truth)
    }

    /// The navigation errors simulated (the paper's smrmsg levels) at correlation time `tau`
    /// [s], and the model that declares them.
    fn errors(tau: f64) -> (Correlated, NavModel) {
        let c = Correlated {
            position_sigma: [0.016, 0.033],
            attitude_sigma: [0.011f64.to_radians(), 0.037f64.to_radians()],
            correlation_s: tau,
        };
        let model = NavModel {
            position_sigma: c.position_sigma,
            attitude_sigma: c.attitude_sigma,
            correlation_s: c.correlation_s,
        };
        (c, model)
    }

    /// The two spheres' returns as the solver takes them.
    fn spheres(obs: &[Vec<Observation>]) -> [SphereObs<'_>; 2] {
        core::array::from_fn(|j| SphereObs {
            target: SPHERES[j],
            obs: &obs[j],
        })
    }

    /// The problem over `s` at the true clock, weighted by `noise`.
    fn problem<'a>(s: &'a [SphereObs<'a>], noise: Noise) -> Problem<'a> {
        Problem {
            spheres: s,
            stride: 1,
            dt: 0.0,
            drift: 0.0,
            t_ref: crate::time::GpsTime(0),
            weights: Some(noise),
            footprint: None,
        }
    }

    /// The model's solve from the truth, the spheres free within 2 cm, the clock held.
    fn solve(pb: &Problem<'_>, model: &NavModel, pieces: &mut [Piece]) -> (LmResult, NavFit) {
        refine(
            pb,
            &TRUTH,
            model,
            &[0.02, 0.02],
            &MountPrior::default(),
            pieces,
            None,
            100,
            20_000_000,
            Clock::default(),
        )
    }

    /// Over `runs` surveys with errors of correlation time `tau`: each parameter's RMS
    /// z-score and the fraction within 3 sigma under the navigation model, and the RMS
    /// z-score of the white-noise solve (`lm::refine`, cluster-robust) on the same returns.
    /// With the pieces' RMS z-scores per axis (estimate against the truth's mean over the
    /// piece).
    /// And the RMS z-score of the classic sigmas (the information's inverse alone).
    /// Per parameter (and per piece axis) figures of a Monte Carlo.
    type Figures = ([f64; P], [f64; P], [f64; P], [f64; 6], [f64; P], [f64; P]);

    fn monte_carlo(tau: f64, runs: u64, hetero: bool) -> Figures {
        let (c, model) = errors(tau);
        let noise = Noise {
            range: 0.009,
            attitude: 0.0,
            position: 0.0,
            spread: 0.0,
        };
        let (mut z2, mut within, mut white) = ([0.0; P], [0.0; P], [0.0; P]);
        let (mut pz2, mut pn) = ([0.0; 6], 0.0);
        let (mut err2, mut pred, mut classic) = ([0.0; P], [0.0; P], [0.0; P]);
        let mut pieces = std::vec![Piece::EMPTY; 256];
        for seed in 0..runs {
            let (obs, truth) = survey(seed + 1, &c, 0.009, hetero, None);
            let s = spheres(&obs);
            let pb = problem(&s, noise);
            let m = cut_for(&pb, &model, &mut pieces);
            let clock = Clock::default();
            let p = predict(&pb, &TRUTH, &model, &[0.02, 0.02], &mut pieces[..m], clock)
                .expect("a prediction");
            let (l, _) = solve(&pb, &model, &mut pieces[..m]);
            assert!(l.converged, "seed {seed}: {l:?}");
            for p in &pieces[..m] {
                let inside: Vec<&[f64; 6]> = truth
                    .iter()
                    .filter(|(t, _)| *t >= p.start.0 && *t <= p.end.0)
                    .map(|(_, e)| e)
                    .collect();
                if inside.is_empty() {
                    continue;
                }
                for k in 0..6 {
                    let mean = inside.iter().map(|e| e[k]).sum::<f64>() / inside.len() as f64;
                    let z = (p.error[k] - mean) / p.sigma[k];
                    pz2[k] += z * z;
                }
                pn += 1.0;
            }
            let w = crate::calib::lm::refine(&pb, &TRUTH, 100, 20_000_000, clock);
            for i in 0..P {
                let z = (l.b[i] - TRUTH[i]) / l.sigma[i];
                z2[i] += z * z / runs as f64;
                err2[i] += (l.b[i] - TRUTH[i]).powi(2) / runs as f64;
                pred[i] += p[i] * p[i] / runs as f64;
                within[i] += f64::from(u8::from(z.abs() <= 3.0)) / runs as f64;
                let zc = (l.b[i] - TRUTH[i]) / l.sigma_classic[i];
                classic[i] += zc * zc / runs as f64;
                let zw = (w.b[i] - TRUTH[i]) / w.sigma[i];
                white[i] += zw * zw / runs as f64;
            }
        }
        (
            z2.map(libm::sqrt),
            within,
            white.map(libm::sqrt),
            pz2.map(|v| libm::sqrt(v / pn)),
            core::array::from_fn(|i| libm::sqrt(err2[i] / pred[i])),
            classic.map(libm::sqrt),
        )
    }

    /// With a second worker for the rows (`Split`), the solve is one worker's to the last bit:
    /// rooms of 2, 7 and 301 rows (turns of uneven halves, a last turn part full) and one
    /// with room for every row; a room of one row makes them all on this thread.
    #[test]
    fn a_second_worker_for_the_rows_gives_the_same_solve() {
        let (c, model) = errors(15.0);
        let noise = Noise {
            range: 0.009,
            attitude: 0.0,
            position: 0.0,
            spread: 0.001,
        };
        let (obs, _) = survey(5, &c, 0.009, false, Some(0.001));
        let s = spheres(&obs);
        let pb = problem(&s, noise);
        let mut pieces = std::vec![Piece::EMPTY; 256];
        let m = cut_for(&pb, &model, &mut pieces);
        let all: usize = obs.iter().map(Vec::len).sum();
        /// A test's room: the slice it holds.
        #[derive(Debug)]
        struct Slots<'r>(&'r mut [Row]);
        impl crate::calib::room::Room<Row> for Slots<'_> {
            fn room(&mut self, n: usize) -> &mut [Row] {
                self.0.room(n)
            }
        }
        let mut solve = |room: Option<&mut Slots<'_>>| {
            let split = room.map(|rows| Split {
                fork: &crate::calib::fork::InTurn,
                rows,
            });
            let (l, f) = refine(
                &pb,
                &TRUTH,
                &model,
                &[0.02, 0.02],
                &MountPrior::default(),
                &mut pieces[..m],
                split,
                100,
                20_000_000,
                Clock::default(),
            );
            let errors: Vec<[f64; 6]> = pieces[..m].iter().map(|p| p.error).collect();
            std::format!("{l:?} {f:?} {errors:?}")
        };
        let one = solve(None);
        assert!(one.contains("converged: true"), "{one}");
        for n in [1, 2, 7, 301, 2 * all] {
            let mut rows = std::vec![Row::EMPTY; n];
            assert!(
                solve(Some(&mut Slots(&mut rows))) == one,
                "a room of {n} rows"
            );
        }
    }

    /// The model's sigmas are honest, both bounds, on returns exact but for the range noise
    /// and the navigation errors (first-order Gauss-Markov at the paper's smrmsg levels) at
    /// 15 s and 60 s, the mounting's and each piece's navigation correction's, and the
    /// planner's prediction of them; the white-noise solve on the same returns is not.
    #[test]
    fn sigmas_are_honest_on_exact_returns() {
        for tau in [15.0, 60.0] {
            let (rms, within, white, pieces, predicted, _) = monte_carlo(tau, 60, false);
            std::eprintln!("tau {tau} s: RMS z {rms:.2?}, within 3 sigma {within:.2?}; white solve RMS z {white:.1?}; the pieces' errors RMS z {pieces:.2?}; RMS error / predicted sigma {predicted:.2?}");
            for i in 0..P {
                assert!((0.7..1.4).contains(&rms[i]), "tau {tau}: {rms:?}");
                assert!(within[i] >= 0.95, "tau {tau}: {within:?}");
            }
            // The planner's prediction (`predict`: the same covariance without data) against
            // the spread of the estimates: within 20 %.
            for r in predicted {
                assert!(
                    (0.8..1.2).contains(&r),
                    "tau {tau}: predicted {predicted:?}"
                );
            }
            // The navigation corrections (an output) with their sigmas, against the truth.
            for z in pieces {
                assert!((0.6..1.4).contains(&z), "tau {tau}: the pieces {pieces:?}");
            }
            assert!(
                white.iter().any(|z| *z > 3.0),
                "the white solve is honest? {white:?}"
            );
        }
    }

    /// Where the range noise is not what the weights say (it grows with the range: the
    /// footprint's spread) the information's inverse is wrong for the parameters the far
    /// passes pin; the reported sigmas (cluster-robust, `robust.rs`) stay honest, both bounds.
    #[test]
    fn robust_sigmas_hold_when_the_noise_grows_with_the_range() {
        let (rms, within, _, _, _, classic) = monte_carlo(30.0, 60, true);
        std::eprintln!("RMS z {rms:.2?}, within 3 sigma {within:.2?}; classic RMS z {classic:.2?}");
        for i in 0..P {
            assert!((0.7..1.4).contains(&rms[i]), "{rms:?}");
            assert!(within[i] >= 0.95, "{within:?}");
        }
        // The pitch, which the far passes pin: 1.58 classic, 1.34 robust (60 runs; 100: 1.47, 1.23).
        assert!(
            classic.iter().any(|z| *z > 1.4),
            "the classic sigmas are honest here too? {classic:?}"
        );
    }

    /// A LiDAR whose range grows at grazing incidence (a 0.75 mrad footprint's spread, the
    /// Velodynes'): the residuals show the spread and the weights take it, and the sigmas are
    /// honest, both bounds; the same survey with the range noise not growing does not show it
    /// (the weights leave it out).
    #[test]
    fn the_footprint_spread_is_taken_where_the_residuals_show_it() {
        let (c, model) = errors(30.0);
        let noise = Noise {
            range: 0.009,
            attitude: 0.0,
            position: 0.0,
            spread: 0.75e-3,
        };
        let runs = 40;
        let mut pieces = std::vec![Piece::EMPTY; 256];
        let (mut z2, mut within) = ([0.0; P], [0.0; P]);
        for seed in 0..runs {
            for spread in [0.75e-3, 0.0] {
                let (obs, _) = survey(seed + 1, &c, 0.009, false, Some(spread));
                let s = spheres(&obs);
                let pb = problem(&s, noise);
                let m = cut_for(&pb, &model, &mut pieces);
                let (l, fit) = solve(&pb, &model, &mut pieces[..m]);
                assert!(l.converged, "seed {seed}: {l:?}");
                if spread == 0.0 {
                    assert_eq!(fit.spread_share, 0.0, "seed {seed}: shown without it");
                    continue;
                }
                assert!(fit.spread_share >= 1.0, "seed {seed}: {}", fit.spread_share);
                for i in 0..P {
                    let z = (l.b[i] - TRUTH[i]) / l.sigma[i];
                    z2[i] += z * z / runs as f64;
                    within[i] += f64::from(u8::from(z.abs() <= 3.0)) / runs as f64;
                }
            }
        }
        let rms = z2.map(libm::sqrt);
        std::eprintln!("RMS z {rms:.2?}, within 3 sigma {within:.2?}");
        for i in 0..P {
            assert!((0.7..1.4).contains(&rms[i]), "{rms:?}");
            assert!(within[i] >= 0.95, "{within:?}");
        }
    }

    /// Capped before its steps turn negligible (a crawl along the pieces' weakly damped
    /// directions), the solve is a minimum when the Gauss-Newton step left moves the mounting
    /// by under half its sigma, else not: each capped answer called converged lies within half
    /// a sigma of the uncapped one, some capped answer is called converged, and a solve
    /// stopped after its first step from 0.5 deg and 5 cm off is not.
    #[test]
    fn a_capped_solve_is_converged_only_within_half_a_sigma() {
        let (c, model) = errors(30.0);
        let (obs, _) = survey(3, &c, 0.009, false, None);
        let s = spheres(&obs);
        let noise = Noise {
            range: 0.009,
            attitude: 0.0,
            position: 0.0,
            spread: 0.0,
        };
        let pb = problem(&s, noise);
        let mut pieces = std::vec![Piece::EMPTY; 256];
        let m = cut_for(&pb, &model, &mut pieces);
        let start: [f64; P] =
            core::array::from_fn(|i| TRUTH[i] + if i < 3 { 0.5f64.to_radians() } else { 0.05 });
        let mut solve = |cap: usize| {
            refine(
                &pb,
                &start,
                &model,
                &[0.02, 0.02],
                &MountPrior::default(),
                &mut pieces[..m],
                None,
                cap,
                20_000_000,
                Clock::default(),
            )
            .0
        };
        let best = solve(100);
        assert!(best.converged, "{best:?}");
        let first = solve(1);
        assert!(!first.converged, "one step from 0.5 deg off: {:?}", first.b);
        let mut capped = 0;
        for cap in 2..=8 {
            let l = solve(cap);
            std::eprintln!(
                "cap {cap}: converged {} after {}",
                l.converged,
                l.iterations
            );
            if l.converged {
                for i in 0..P {
                    assert!(
                        (l.b[i] - best.b[i]).abs() <= 0.5 * best.sigma[i],
                        "cap {cap}: {:?} against {:?}",
                        l.b,
                        best.b
                    );
                }
                capped += 1;
            }
        }
        assert!(capped > 0, "no capped solve called converged");
    }
}

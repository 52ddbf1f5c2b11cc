//! `table1-real` against the seed paper's real VLP-16 + POS MV survey (issue 28): the sensor's
//! statistics measured on the simulator's decoded packets as on the published sphere returns,
//! in the sensor frame (each return's range against where its line of sight meets the sphere:
//! here the true sphere, which the simulation knows), and the navigation errors' levels and
//! wander through the scenario's own INS.

use spherecal::sim::{InsSim, LidarSim, SimPacket};
use spherecal::velodyne::firing::{decode, PointBuf};
use spherecal::velodyne::DataPacket;
use spherecal_tools::config::scenario::Scenario;

/// One sphere return in the sensor frame.
#[derive(Debug, Clone, Copy)]
struct Ret {
    intensity: u8,
    laser: u8,
    /// Firing time [ns] (packet time + firing offset).
    t_ns: i64,
    /// Its range minus where its line of sight meets the true sphere (`None`: it misses it,
    /// a blooming edge return), and that sphere's distance [m].
    residual: Option<f64>,
    distance: f64,
    /// Its line of sight within 45 deg of normal incidence on the sphere (disc / r^2 is the
    /// incidence's cos^2): nearer the silhouette the footprint spans the sphere's curvature.
    central: bool,
}

/// The sphere returns of one sphere in one rotation.
struct Sweep {
    rets: Vec<Ret>,
}

/// Every sweep of the scenario's sphere returns (labelled by the simulator, measured from the
/// decoded packets).
fn sweeps(s: &Scenario) -> Vec<Sweep> {
    let mut cfg = s.lidar_config();
    cfg.targets_only = true;
    let centres: Vec<nalgebra::Vector3<f64>> = s
        .sphere
        .iter()
        .map(|b| nalgebra::Vector3::from(b.ned_m))
        .collect();
    let radius = s.sphere[0].radius_m;
    s.with_world(|world| {
        let mut sim = LidarSim::new(world, cfg);
        let mut buf = [0u8; 1206];
        let mut points = PointBuf::new();
        // Open sweeps per target: the last return's time.
        let mut open: Vec<(usize, i64, Vec<Ret>)> = Vec::new();
        let mut done = Vec::new();
        while let Some(p) = sim.next_packet(&mut buf) {
            let SimPacket::Data {
                time,
                dropped: false,
            } = p
            else {
                continue;
            };
            let pkt = DataPacket::new_checked(&buf[..]).unwrap();
            decode(&pkt, &mut points).unwrap();
            for q in points.as_slice() {
                let Some(h) = sim
                    .hits
                    .iter()
                    .find(|h| h.block == q.block && h.channel == q.channel)
                else {
                    continue;
                };
                let Some(tg) = world
                    .objects
                    .get(usize::from(h.object))
                    .and_then(|o| o.target)
                else {
                    continue;
                };
                // The true sphere in the sensor frame at the firing.
                let t_ns = time.0 + i64::from(q.offset_ns);
                let st = world
                    .trajectory
                    .state(world.t_of(spherecal::time::GpsTime(t_ns)));
                let m = &world.mount;
                let c = m.r_li.transpose()
                    * (st.r_ig().transpose() * (centres[usize::from(tg)] - st.position) - m.lever);
                let o = nalgebra::Vector3::new(
                    0.0,
                    0.0,
                    cfg.scanner.beam(usize::from(q.laser)).vertical_offset_m,
                );
                let p = nalgebra::Vector3::new(f64::from(q.x), f64::from(q.y), f64::from(q.z));
                let range = (p - o).norm();
                let u = (p - o) / range;
                let (uc, oc) = (u.dot(&(c - o)), (c - o).norm_squared());
                let disc = uc * uc - (oc - radius * radius);
                let r = Ret {
                    intensity: q.intensity,
                    laser: q.laser,
                    t_ns,
                    residual: (disc > 0.0).then(|| range - (uc - disc.sqrt())),
                    central: disc > 0.5 * radius * radius,
                    distance: (c - o).norm(),
                };
                let tg = usize::from(tg);
                match open.iter_mut().find(|o| o.0 == tg) {
                    // A new rotation: 50 ms without a return on it.
                    Some(o) if r.t_ns - o.1 < 50_000_000 => {
                        o.1 = r.t_ns;
                        o.2.push(r);
                    }
                    Some(o) => {
                        done.push(Sweep {
                            rets: std::mem::take(&mut o.2),
                        });
                        o.1 = r.t_ns;
                        o.2.push(r);
                    }
                    None => open.push((tg, r.t_ns, vec![r])),
                }
            }
        }
        done.extend(open.into_iter().map(|o| Sweep { rets: o.2 }));
        done
    })
    .unwrap()
}

/// The statistics the real returns were described by.
#[derive(Debug)]
struct Stats {
    /// Range scatter of the central returns at 5-12, 12-22, 22-35 m [m], and their counts.
    scatter: [f64; 3],
    counts: [usize; 3],
    /// Of every return on the sphere: beyond 3 sigma, beyond 5 cm.
    beyond3: f64,
    beyond5cm: f64,
    /// Returns saturated at 100; neighbours along an arc 20 or more apart.
    saturated: f64,
    jumps: f64,
    /// Arcs whose second firing is missing and first return weak.
    dropped_arcs: f64,
}

impl Stats {
    /// What does not match the real survey's figures (issue 28), in words.
    fn against_the_real_survey(&self) -> Vec<String> {
        let mut bad = Vec::new();
        let mut say = |ok: bool, what: String| {
            if !ok {
                bad.push(what)
            }
        };
        // ~9 mm (8.6), flat from 5 to 30 m.
        for (k, s) in self.scatter.iter().enumerate() {
            say(
                self.counts[k] > 50,
                format!("range bin {k}: {} returns", self.counts[k]),
            );
            say(
                (0.0065..0.0115).contains(s),
                format!("range scatter {:.1} mm in bin {k}", s * 1e3),
            );
        }
        let (lo, hi) =
            (self.scatter.iter()).fold((1.0f64, 0.0f64), |a, s| (a.0.min(*s), a.1.max(*s)));
        say(
            hi / lo < 1.3,
            format!("scatter not flat with range: {:?}", self.scatter),
        );
        // Thin tails: 0.4-0.6 % beyond 3 sigma, nothing beyond 5 cm in 4,009 returns: a rate
        // that none in 4,009 rules out at 99.9 % (Poisson, 6.9 expected) is too many. (The
        // footprint's Gaussian grid, session 39: 3 of 2,452, the limb's bloom along grazing
        // beams; five sub-rays had none.)
        say(
            (0.001..0.012).contains(&self.beyond3),
            format!("{:.2} % beyond 3 sigma", self.beyond3 * 100.0),
        );
        say(
            self.beyond5cm < 6.9 / 4009.0,
            format!("{:.2} % beyond 5 cm", self.beyond5cm * 100.0),
        );
        // 37 % saturating at 100, jumps of 20 and more between neighbours.
        say(
            (0.30..0.45).contains(&self.saturated),
            format!("{:.1} % saturated", self.saturated * 100.0),
        );
        say(
            self.jumps > 0.08,
            format!("{:.1} % neighbour jumps", self.jumps * 100.0),
        );
        // 12-14 % of the arcs lose the firing after the leading edge, the first weak.
        say(
            (0.09..0.18).contains(&self.dropped_arcs),
            format!("{:.1} % arcs with the dropout", self.dropped_arcs * 100.0),
        );
        bad
    }
}

/// The statistics of scenario `name`'s sphere returns.
fn stats(name: &str) -> Stats {
    let s = Scenario::load(name).unwrap();
    let period = i64::from(s.lidar_config().scanner.laser_period_ns());
    let sweeps = sweeps(&s);
    // Per range bin (5-12, 12-22, 22-35 m): the central returns' range residuals; every
    // residual for the tails; blooming returns (missing the sphere) apart.
    let mut by_range: [Vec<f64>; 3] = Default::default();
    let mut all = Vec::new();
    let (mut saturated, mut total, mut jumps, mut pairs) = (0usize, 0usize, 0usize, 0usize);
    let (mut arcs, mut dropped_arcs, mut blooming) = (0usize, 0usize, 0usize);
    for sw in &sweeps {
        let lasers: std::collections::BTreeSet<u8> = sw.rets.iter().map(|q| q.laser).collect();
        for q in &sw.rets {
            let bin = match q.distance {
                d if (5.0..12.0).contains(&d) => 0,
                d if (12.0..22.0).contains(&d) => 1,
                d if (22.0..35.0).contains(&d) => 2,
                _ => continue,
            };
            match q.residual {
                Some(e) => {
                    all.push(e);
                    if q.central {
                        by_range[bin].push(e);
                    }
                }
                None => blooming += 1,
            }
        }
        total += sw.rets.len();
        saturated += sw.rets.iter().filter(|q| q.intensity == 100).count();
        for l in &lasers {
            let arc: Vec<&Ret> = sw.rets.iter().filter(|q| q.laser == *l).collect();
            for w in arc.windows(2) {
                pairs += 1;
                jumps += usize::from(w[0].intensity.abs_diff(w[1].intensity) >= 20);
            }
            if arc.len() < 4 {
                continue;
            }
            arcs += 1;
            // The firing after the leading edge missing, and the first return weak (under
            // half the arc's median intensity).
            let mut i: Vec<u8> = arc.iter().map(|q| q.intensity).collect();
            i.sort_unstable();
            let median = f64::from(i[i.len() / 2]);
            let gap = arc[1].t_ns - arc[0].t_ns;
            if gap > period * 3 / 2 && f64::from(arc[0].intensity) < 0.5 * median {
                dropped_arcs += 1;
            }
        }
    }
    let rms = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len() as f64).sqrt()
    };
    let sig: Vec<f64> = by_range.iter().map(|v| rms(v)).collect();
    let sigma = rms(&all);
    let mean = all.iter().sum::<f64>() / all.len() as f64;
    let beyond3 = all
        .iter()
        .filter(|x| (*x - mean).abs() > 3.0 * sigma)
        .count();
    let beyond5cm = all.iter().filter(|x| (*x - mean).abs() > 0.05).count();
    let frac = |a: usize, b: usize| a as f64 / b.max(1) as f64;
    eprintln!(
        "{name}: {} sweeps; range scatter {:.1} / {:.1} / {:.1} mm at 5-12 / 12-22 / \
         22-35 m ({} / {} / {} central returns), all {:.1} mm; beyond 3 sigma {:.2} %, beyond 5 cm {} \
         of {}; saturated {:.1} % of {}; neighbour jumps >= 20: {:.1} % of {}; arcs with the \
         leading-edge dropout {:.1} % of {}; {} blooming returns",
        sweeps.len(),
        sig[0] * 1e3,
        sig[1] * 1e3,
        sig[2] * 1e3,
        by_range[0].len(),
        by_range[1].len(),
        by_range[2].len(),
        sigma * 1e3,
        100.0 * frac(beyond3, all.len()),
        beyond5cm,
        all.len(),
        100.0 * frac(saturated, total),
        total,
        100.0 * frac(jumps, pairs),
        pairs,
        100.0 * frac(dropped_arcs, arcs),
        arcs,
        blooming
    );
    Stats {
        scatter: [sig[0], sig[1], sig[2]],
        counts: by_range.each_ref().map(Vec::len),
        beyond3: frac(beyond3, all.len()),
        beyond5cm: frac(beyond5cm, all.len()),
        saturated: frac(saturated, total),
        jumps: frac(jumps, pairs),
        dropped_arcs: frac(dropped_arcs, arcs),
    }
}

#[test]
fn table1_real_has_the_real_surveys_sensor_statistics() {
    let bad = stats("table1-real").against_the_real_survey();
    assert!(bad.is_empty(), "table1-real: {bad:?}");
    // The measure tells: the earlier noisy quay (3 cm growing at grazing incidence, no
    // saturation, no dropout) is not the real survey.
    let bad = stats("table1-noisy").against_the_real_survey();
    for what in ["range scatter", "saturated", "arcs with the dropout"] {
        assert!(
            bad.iter().any(|b| b.contains(what)),
            "table1-noisy passes {what}: {bad:?}"
        );
    }
}

#[test]
fn table1_real_navigation_errors_are_the_smrmsgs_and_wander() {
    // Pooled over seeds (one ~55 s survey holds only a few correlation times).
    let mut s = Scenario::load("table1-real").unwrap();
    let (mut sum2, mut lag, mut n) = ([0.0f64; 6], [0.0f64; 6], 0usize);
    let step = 200; // 1 s at 200 Hz
    for seed in 0..40u64 {
        s.seed = 1000 + seed;
        let cfg = s.ins_config();
        let e: Vec<[f64; 6]> = s
            .with_world(|world| {
                let mut ins = InsSim::new(world, cfg);
                let mut out = Vec::new();
                while ins.next_pose().is_some() {
                    out.push(ins.last_error.0);
                }
                out
            })
            .unwrap();
        for (i, x) in e.iter().enumerate() {
            for k in 0..6 {
                sum2[k] += x[k] * x[k];
                if i + step < e.len() {
                    lag[k] += x[k] * e[i + step][k];
                }
            }
        }
        n += e.len();
    }
    let rms: Vec<f64> = sum2.iter().map(|s| (s / n as f64).sqrt()).collect();
    let rho: Vec<f64> = (0..6).map(|k| lag[k] / sum2[k]).collect();
    eprintln!("nav error RMS {rms:?}; correlation at 1 s {rho:?}");
    // The smrmsg: N/E/D 1.6/1.5/3.3 cm, roll/pitch 0.011 deg, heading 0.037 deg.
    let want = [
        0.0155,
        0.0155,
        0.033,
        0.011f64.to_radians(),
        0.011f64.to_radians(),
        0.037f64.to_radians(),
    ];
    for k in 0..6 {
        assert!(
            (0.75..1.25).contains(&(rms[k] / want[k])),
            "axis {k}: RMS {} against {}",
            rms[k],
            want[k]
        );
        // Slowly: nearly the same a second later (exp(-1/30) = 0.967); roll's and pitch's
        // less (0.87): the misalignment stays in the level frame, so at the turns the two
        // trade places.
        let floor = if k == 3 || k == 4 { 0.8 } else { 0.9 };
        assert!(rho[k] > floor, "axis {k}: correlation at 1 s {}", rho[k]);
    }
}

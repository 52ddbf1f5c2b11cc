//! z-scores over seeds (not part of the product).
use spherecal_tools::calibrate::{collect, site_targets, solve_report};
use spherecal_tools::pipeline::{Inputs, InsInput};
use spherecal_tools::scenario::{Scenario, BUILTIN};
use spherecal_tools::site::Site;
fn main() {
    let name = std::env::args().nth(1).unwrap();
    let n: u64 = std::env::args().nth(2).unwrap().parse().unwrap();
    let text = BUILTIN
        .iter()
        .find(|b| b.0 == name)
        .map(|b| b.1.to_string())
        .unwrap_or_else(|| std::fs::read_to_string(&name).unwrap());
    let seed_line = text
        .lines()
        .find(|l| l.starts_with("seed = "))
        .unwrap()
        .to_string();
    let results = std::sync::Mutex::new(Vec::new());
    let next = std::sync::atomic::AtomicU64::new(0);
    std::thread::scope(|sc| {
        for _ in 0..2 {
            sc.spawn(|| loop {
                let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if k >= n {
                    break;
                }
                let seed = 1000 + k;
                let s = Scenario::from_toml(&text.replace(&seed_line, &format!("seed = {seed}")))
                    .unwrap();
                let t = &s.mount.truth;
                let truth = [
                    t.boresight_deg[0].to_radians(),
                    t.boresight_deg[1].to_radians(),
                    t.boresight_deg[2].to_radians(),
                    t.lever_arm_m[0],
                    t.lever_arm_m[1],
                    t.lever_arm_m[2],
                ];
                let dir = std::env::temp_dir().join(format!("xseeds-{seed}"));
                spherecal_tools::synth::synth(&s, &dir).unwrap();
                let inp = Inputs::apriori(
                    dir.join("lidar.pcap"),
                    InsInput::Vn200(dir.join("ins.bin")),
                    Site::load(&dir.join("site.toml")).unwrap(),
                );
                let (_, mut obs) = collect(&inp).unwrap();
                let (tg, ids) = site_targets(&inp);
                let b0 = inp.mount.params();
                let (sol, rep) = solve_report(
                    &tg,
                    &ids,
                    &mut obs,
                    &b0,
                    &spherecal::calib::Settings::default(),
                );
                let mut z = [f64::NAN; 6];
                if let Some(lm) = sol.lm {
                    for i in 0..6 {
                        z[i] = (sol.b[i] - truth[i]) / lm.sigma[i];
                    }
                }
                eprintln!(
                    "seed {seed}: z {:?} conv {} kept {:?}",
                    z.map(|v| (v * 100.0).round() / 100.0),
                    rep.converged,
                    rep.points_per_sphere
                );
                results.lock().unwrap().push((seed, z, rep.converged));
                let _ = std::fs::remove_dir_all(&dir);
            });
        }
    });
    let r = results.into_inner().unwrap();
    for i in 0..6 {
        let inside = r.iter().filter(|x| x.1[i].abs() <= 3.0).count();
        let rms = (r.iter().map(|x| x.1[i] * x.1[i]).sum::<f64>() / r.len() as f64).sqrt();
        let mean = r.iter().map(|x| x.1[i]).sum::<f64>() / r.len() as f64;
        println!(
            "{}: {inside}/{} within 3 sigma, rms z {rms:.2}, mean z {mean:.2}",
            spherecal::calib::NAMES[i],
            r.len()
        );
    }
    println!("converged {}/{}", r.iter().filter(|x| x.2).count(), r.len());
}

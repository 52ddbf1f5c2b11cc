//! Debug harness for the sphere extraction (not part of the product).
use spherecal::calib::extract::{self, Directions, ExtractSettings, Verdict};
use spherecal::georef::Mount;
use spherecal_tools::pipeline::{Inputs, InsInput};
use std::collections::HashMap;
use std::path::PathBuf;

fn main() {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap());
    let bstr = std::env::args().nth(2);
    let site = spherecal_tools::site::Site::load(&dir.join("site.toml")).unwrap();
    let inp = Inputs::apriori(
        dir.join("lidar.pcap"),
        InsInput::Vn200(dir.join("ins.bin")),
        site,
    );
    let (_, mut obs) = spherecal_tools::calibrate::collect(&inp).unwrap();
    let (targets, _) = spherecal_tools::calibrate::site_targets(&inp);
    let labels = spherecal_tools::synth::read_labels(&dir.join("labels.bin")).unwrap();
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    let names: Vec<String> = truth["objects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["name"].as_str().unwrap().to_string())
        .collect();
    let lab: HashMap<(u32, u8, u8), (u16, u8)> = labels
        .iter()
        .map(|l| ((l.packet, l.block, l.channel), (l.object, l.purity)))
        .collect();
    let b = match bstr {
        Some(s) => {
            let v: Vec<f64> = s.split(',').map(|x| x.parse().unwrap()).collect();
            spherecal::calib::from_deg_m(&[v[0], v[1], v[2], v[3], v[4], v[5]])
        }
        None => inp.mount.params(),
    };
    let tau: f64 = std::env::var("TAU")
        .ok()
        .map(|s| s.parse().unwrap())
        .unwrap_or(0.05);
    let prior: Option<f64> = std::env::var("PRIOR").ok().map(|s| s.parse().unwrap());
    let mount = Mount::from_params(&b);
    let st = ExtractSettings::default();
    let dirs = Directions::default();
    let mut grid = vec![0u16; 64 * 64 * 64];
    if std::env::var("SOLVE").is_ok() {
        let mut o2 = obs.clone();
        let mut sl: Vec<&mut [spherecal::window::Observation]> =
            o2.iter_mut().map(|v| v.as_mut_slice()).collect();
        let t0 = std::time::Instant::now();
        let sol = spherecal::calib::solve(
            &targets,
            &mut sl,
            &b,
            &spherecal::calib::Settings::default(),
            &mut spherecal_tools::calibrate::Scratch::default().workspace(),
        );
        println!("solve {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
        for r in &sol.log {
            println!(
                "round tau {:.4} prior {:?} kept {} det {} b {:?}",
                r.tau,
                r.prior,
                r.kept,
                r.detected,
                spherecal::calib::to_deg_m(&r.b)
            );
        }
        let truth = [179.5, -44.9, 1.2, 1.5, -1.24, -1.36];
        let got = spherecal::calib::to_deg_m(&sol.b);
        println!(
            "err {:?} refusal {:?}",
            (0..6).map(|i| got[i] - truth[i]).collect::<Vec<_>>(),
            sol.refusal
        );
        if std::env::var("HEAD").is_ok() {
            let m = spherecal::georef::Mount::from_params(&sol.b);
            for (j, v) in o2.iter().enumerate() {
                let t = &targets[j];
                let mut rows = vec![];
                for o in v.iter() {
                    let l = lab
                        .get(&(o.packet, o.block, o.channel))
                        .copied()
                        .unwrap_or((9999, 0));
                    let nm = names.get(l.0 as usize).cloned().unwrap_or_default();
                    let x = o.georef(&m) - t.center;
                    let e = x.norm() - t.radius;
                    if e.abs() > 0.12 || x.norm() > 0.5 {
                        continue;
                    }
                    let ang = (x.z / x.norm()).acos().to_degrees(); // 0 = straight down (NED z down)
                    rows.push((nm, e, ang, o.work.verdict));
                }
                for (nm, e, ang, v) in &rows {
                    if nm.contains("head")
                        || nm.contains("spigot")
                        || (nm.starts_with('S') && nm.len() == 2 && *ang < 45.0)
                    {
                        println!("{nm:>18} e={:+.3} nadir_angle={:5.1} verdict={v}", e, ang);
                    }
                }
            }
        }
        for (j, v) in o2.iter().enumerate() {
            let (mut tp, mut fp, mut pos) = (0, 0, 0);
            let mut fpby: HashMap<String, usize> = HashMap::new();
            let mut fnby: HashMap<u8, usize> = HashMap::new();
            for o in v.iter() {
                let l = lab
                    .get(&(o.packet, o.block, o.channel))
                    .copied()
                    .unwrap_or((9999, 0));
                let is = l.0 as usize == j && l.1 >= 230;
                if is {
                    pos += 1;
                    if o.work.verdict != Verdict::Kept as u8 {
                        *fnby.entry(o.work.verdict).or_default() += 1;
                    }
                }
                if o.work.verdict == Verdict::Kept as u8 {
                    if is {
                        tp += 1
                    } else {
                        fp += 1;
                        *fpby
                            .entry(
                                names
                                    .get(l.0 as usize)
                                    .cloned()
                                    .unwrap_or(format!("{}", l.0)),
                            )
                            .or_default() += 1;
                    }
                }
            }
            println!("S{}: precision {:.4} recall {:.4} (tp {tp} fp {fp} pos {pos}) fp by {:?} missed by verdict {:?}", j + 1, tp as f64 / (tp + fp).max(1) as f64, tp as f64 / pos.max(1) as f64, fpby, fnby);
        }
        return;
    }
    for (j, t) in targets.iter().enumerate() {
        let v = &mut obs[j];
        v.sort_unstable_by_key(|o| (o.time, o.channel));
        extract::georeference(v, t, &mount);
        extract::runs(v, st.firing_ns, st.jump);
        extract::assign_slices(v, st.slice_ns, 32768);
        let ranges: Vec<_> = extract::slices(v).collect();
        let (mut tp, mut fp, mut total_sphere) = (0, 0, 0);
        for o in v.iter() {
            if lab
                .get(&(o.packet, o.block, o.channel))
                .map(|l| l.0 as usize)
                == Some(j)
            {
                total_sphere += 1;
            }
        }
        for sl in ranges {
            let s = &mut v[sl.clone()];
            let nsph = s
                .iter()
                .filter(|o| {
                    lab.get(&(o.packet, o.block, o.channel))
                        .map(|l| l.0 as usize)
                        == Some(j)
                })
                .count();
            let t0 = std::time::Instant::now();
            let mut keys = vec![(0f32, 0u32); 32768];
            let det = extract::detect(s, &mut keys, t.radius, tau, prior, &mut grid, &dirs, &st);
            let us = t0.elapsed().as_micros();
            match det {
                Some(d) => {
                    extract::keep(s, d.center, t.radius, tau);
                    let mut by: HashMap<String, usize> = HashMap::new();
                    for o in s.iter().filter(|o| o.work.verdict == Verdict::Kept as u8) {
                        let l = lab
                            .get(&(o.packet, o.block, o.channel))
                            .map(|l| l.0)
                            .unwrap_or(9999);
                        *by.entry(names.get(l as usize).cloned().unwrap_or(format!("{l}")))
                            .or_default() += 1;
                        if l as usize == j {
                            tp += 1
                        } else {
                            fp += 1
                        }
                    }
                    println!("S{} t={:.2} n={} sph={} det c=({:.3},{:.3},{:.3}) inl={} viol={} score={:.1} {}us kept {:?}", j+1, s[0].time.as_secs_f64() % 1000.0, s.len(), nsph, d.center[0], d.center[1], d.center[2], d.inliers, d.violations, d.score, us, by);
                }
                None => println!(
                    "S{} t={:.2} n={} sph={} none {}us",
                    j + 1,
                    s[0].time.as_secs_f64() % 1000.0,
                    s.len(),
                    nsph,
                    us
                ),
            }
        }
        println!(
            "S{}: kept sphere {tp} clutter {fp} of {total_sphere} sphere returns",
            j + 1
        );
    }
}

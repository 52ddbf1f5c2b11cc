//! Times the solve on a synth folder (not part of the product).
use spherecal_tools::pipeline::{Inputs, InsInput};
use std::path::PathBuf;
fn main() {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap());
    let n: usize = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(10);
    let site = spherecal_tools::site::Site::load(&dir.join("site.toml")).unwrap();
    let inp = Inputs::apriori(
        dir.join("lidar.pcap"),
        InsInput::Vn200(dir.join("ins.bin")),
        site,
    );
    let t0 = std::time::Instant::now();
    let (_, obs) = spherecal_tools::calibrate::collect(&inp).unwrap();
    eprintln!("collect {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
    let (targets, _) = spherecal_tools::calibrate::site_targets(&inp);
    let mut scratch = spherecal_tools::calibrate::Scratch::default();
    let b0 = inp.mount.params();
    for _ in 0..n {
        let mut o2 = obs.clone();
        let mut sl: Vec<&mut [spherecal::window::Observation]> =
            o2.iter_mut().map(|v| v.as_mut_slice()).collect();
        let mut st = spherecal::calib::Settings::default();
        if let Ok(r) = std::env::var("ROUNDS") {
            st.max_rounds = r.parse().unwrap();
        }
        let t0 = std::time::Instant::now();
        let sol = spherecal::calib::solve(&targets, &mut sl, &b0, &st, &mut scratch.workspace());
        eprintln!(
            "solve {:.1} ms rounds {} {:?}",
            t0.elapsed().as_secs_f64() * 1e3,
            sol.rounds,
            spherecal::calib::to_deg_m(&sol.b)
        );
    }
}
#[allow(dead_code)]
fn unused() {}

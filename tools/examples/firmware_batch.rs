//! Writes the stored batch the firmware's simplex stage solves on (`firmware/data/
//! table1-batch.bin`): table1 synthesised, its windows collected with the a-priori mounting,
//! and on each of its two spheres 200 returns (evenly spread over the survey) of those within
//! 2 cm of the sphere under the true mounting. Run from the repository's root:
//! `cargo run --release -p spherecal-tools --example firmware_batch -- firmware/data/table1-batch.bin`
//!
//! Layout (little-endian): b"SCB1", the count of spheres (u32), per sphere its centre (3 f64,
//! site NED [m]), radius (f64) and count of returns (u32); then the a-priori start (6 f64:
//! roll, pitch, heading [deg], lever arm [m]) and the truth (the same six); then each return:
//! time (i64 ns), q_l (3 f32), position (3 f64), r_ig (9 f32, column-major), velocity (3 f32),
//! omega (3 f32), range (f32).

use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::config::site::Site;
use spherecal_tools::pipeline::{Files, Inputs, InsInput};

const PER_SPHERE: usize = 200;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).ok_or("give the output path")?;
    let dir = std::env::temp_dir().join(format!("spherecal-firmware-batch-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let s = Scenario::load("table1").map_err(|e| format!("{e:?}"))?;
    let truth = spherecal_tools::synth::synth(&s, &dir)?;
    let site = Site::load(&dir.join("site.toml"))?;
    let start = site.apriori_deg_m();
    let inp = Inputs::apriori(
        Files(vec![dir.join("lidar.pcap")]),
        InsInput::Vn200(Files(vec![dir.join("ins.bin")])),
        site,
    );
    let (_, obs) = spherecal_tools::calibrate::collect(&inp)?;
    let (targets, _) = spherecal_tools::calibrate::site_targets(&inp);
    let b = |m: &std::collections::BTreeMap<String, f64>, k: &str| m.get(k).copied().unwrap_or(0.0);
    let true_deg_m = [
        b(&truth.boresight_deg, "roll"),
        b(&truth.boresight_deg, "pitch"),
        b(&truth.boresight_deg, "heading"),
        b(&truth.lever_arm_m, "x"),
        b(&truth.lever_arm_m, "y"),
        b(&truth.lever_arm_m, "z"),
    ];
    let mount =
        spherecal::georef::Mount::from_params(&spherecal::georef::DegM(true_deg_m).params());
    let mut bytes: Vec<u8> = b"SCB1".to_vec();
    bytes.extend((targets.len().min(2) as u32).to_le_bytes());
    let mut chosen = Vec::new();
    for (t, v) in targets.iter().zip(&obs).take(2) {
        let on: Vec<_> = v
            .iter()
            .filter(|o| ((o.georef(&mount) - t.center).norm() - t.radius).abs() < 0.02)
            .collect();
        let step = (on.len() / PER_SPHERE).max(1);
        let picked: Vec<_> = on.iter().step_by(step).take(PER_SPHERE).copied().collect();
        for c in t.center.iter().chain([t.radius].iter()) {
            bytes.extend(c.to_le_bytes());
        }
        bytes.extend((picked.len() as u32).to_le_bytes());
        chosen.push(picked);
    }
    for v in start.0.iter().chain(true_deg_m.iter()) {
        bytes.extend(v.to_le_bytes());
    }
    for o in chosen.iter().flatten() {
        bytes.extend(o.time.0.to_le_bytes());
        for v in o.q_l.iter() {
            bytes.extend(v.to_le_bytes());
        }
        for v in o.position.iter() {
            bytes.extend(v.to_le_bytes());
        }
        for v in o.r_ig.iter().chain(o.velocity.iter()).chain(o.omega.iter()) {
            bytes.extend(v.to_le_bytes());
        }
        bytes.extend(o.range.to_le_bytes());
    }
    std::fs::write(&out, &bytes)?;
    std::fs::remove_dir_all(&dir)?;
    println!(
        "{out}: {} bytes, {} + {} returns",
        bytes.len(),
        chosen.first().map_or(0, Vec::len),
        chosen.get(1).map_or(0, Vec::len)
    );
    Ok(())
}

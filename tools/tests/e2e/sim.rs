//! The simulator: traced points lie on what they hit (to 1e-6 m before quantization), the wire
//! carries them to ~1 mm, the files read back without a skip at the sensor's rates, and the
//! same seed gives the same bytes.

use crate::common;

use nalgebra::Vector3;
use spherecal::frames::rotation;
use spherecal::georef::{point, PlatformPose};
use spherecal::sim::{Frame, LidarSim, Shape, SimPacket, World};
use spherecal::time::{gps_to_unix_ns, GpsTime};
use spherecal::velodyne::{decode, DataPacket, PointBuf};
use spherecal_tools::config::scenario::Scenario;

/// Scenario `name` with no range or INS noise (its footprint kept).
fn without_noise(name: &str) -> Scenario {
    let mut s = Scenario::load(name).unwrap();
    s.lidar.range_sigma_m = 0.0;
    s.lidar.incidence_noise = false;
    s.ins.att_sigma_deg = 0.0;
    s.ins.pos_sigma_m = 0.0;
    s
}

fn truth_pose(w: &World<'_>, t: GpsTime) -> PlatformPose {
    let st = w.trajectory.state(w.t_of(t));
    PlatformPose {
        position: st.position,
        r_ig: rotation(st.rph[0], st.rph[1], st.rph[2]),
    }
}

/// Distance of a point from a shape's surface, written out here independently of the
/// simulator's own intersection code.
fn off_surface(shape: &Shape, x: &Vector3<f64>) -> f64 {
    match *shape {
        Shape::Sphere { c, r } => ((x - c).norm() - r).abs(),
        Shape::Cylinder { a, b, r } => {
            // Side: distance from the axis minus r; caps: distance from the end planes.
            let w = (b - a).normalize();
            let h = (x - a).dot(&w);
            let len = (b - a).norm();
            let rho = ((x - a) - w * h).norm();
            let side = if (-1e-9..=len + 1e-9).contains(&h) {
                (rho - r).abs()
            } else {
                f64::INFINITY
            };
            let cap = if rho <= r + 1e-9 {
                h.abs().min((h - len).abs())
            } else {
                f64::INFINITY
            };
            side.min(cap)
        }
        Shape::Box { c, half, rot } => {
            let q = rot.transpose() * (x - c);
            (0..3)
                .map(|i| (q[i].abs() - half[i]).abs())
                .fold(f64::INFINITY, f64::min)
        }
        Shape::Rect { p, u, v } => (x - p).dot(&u.cross(&v).normalize()).abs(),
    }
}

/// Distance of a traced return from the object it is labelled with, in the object's frame and
/// at the firing time (vessel parts in the body frame, walkers where they are then).
fn off_object(w: &World<'_>, obj: u16, t: GpsTime, x: &Vector3<f64>) -> f64 {
    if obj == spherecal::sim::lidar::LABEL_WATER {
        return (x.z - w.water.unwrap().down).abs();
    }
    let o = &w.objects[usize::from(obj)];
    match o.frame {
        Frame::Site => off_surface(&o.shape, &(x - o.velocity * w.t_of(t))),
        Frame::Body => {
            let pose = truth_pose(w, t);
            off_surface(&o.shape, &(pose.r_ig.transpose() * (x - pose.position)))
        }
    }
}

/// Every traced return of the quay (an ideal beam: no footprint) lies on what it is labelled
/// with, to 1e-6 m, for every kind of object: spheres, tripod legs, boxes, the walker, the
/// vessel's own parts.
#[test]
fn traced_points_lie_on_what_they_hit() {
    let s = Scenario::load("table1").unwrap();
    let scene = s.scene();
    let passes = s.passes();
    let w = s.world(&[], &passes, &scene.objects);
    let mut sim = LidarSim::new(&w, s.lidar_config());
    let mut buf = [0u8; 1206];
    let (mut n, mut worst) = (0u64, 0f64);
    let mut kinds = std::collections::BTreeMap::<&str, u64>::new();
    while let Some(p) = sim.next_packet(&mut buf) {
        if !matches!(p, SimPacket::Data { .. }) {
            continue;
        }
        for h in &sim.hits {
            let pose = truth_pose(&w, h.time);
            let laser = usize::from(h.channel) % 16;
            let x = point(
                &pose,
                &w.mount,
                h.range,
                spherecal::velodyne::Model::Vlp16.beam(laser),
                h.azimuth.sin(),
                h.azimuth.cos(),
            );
            let e = off_object(&w, h.object, h.time, &x);
            worst = worst.max(e);
            assert!(e < 1e-6, "hit off its surface by {e} m: {h:?}");
            assert_eq!(h.purity, 255, "an ideal beam has no mixed pixels");
            let kind = scene
                .kinds
                .get(usize::from(h.object))
                .copied()
                .unwrap_or("water");
            *kinds.entry(kind).or_default() += 1;
            n += 1;
        }
    }
    let st = sim.stats;
    assert_eq!(n, st.hits.iter().sum::<u64>() + st.clutter_hits);
    assert!(st.hits[0] > 800 && st.hits[1] > 800, "{:?}", &st.hits[..2]);
    for k in [
        "sphere", "stand", "box", "pole", "crate", "post", "bush", "vessel",
    ] {
        assert!(
            kinds.get(k).copied().unwrap_or(0) > 0,
            "no returns off a {k}: {kinds:?}"
        );
    }
    eprintln!("{n} traced returns, worst {worst:.2e} m off the surface; {} of {} rays passed the broad phase; by kind {kinds:?}", st.candidates, st.rays);
}

/// The VLP-16's footprint (3 x 1.5 mrad): a return the simulator labels as a sphere's lies off
/// that sphere's surface by at most the footprint's reach at its range (blooming at the
/// silhouette, the echo's range a weighted mean over the footprint), and some do measurably;
/// echoes from two surfaces less than 1 m apart merge into mixed pixels; with an ideal beam
/// none of this happens (the test above). Range walk lengthens dark returns more than bright.
#[test]
fn the_beam_footprint_blooms_and_mixes() {
    let s = without_noise("table1-noisy");
    let scene = s.scene();
    let passes = s.passes();
    let w = s.world(&[], &passes, &scene.objects);
    let mut sim = LidarSim::new(&w, s.lidar_config());
    let mut buf = [0u8; 1206];
    let (mut n, mut off, mut worst_ratio) = (0u64, 0u64, 0f64);
    while let Some(p) = sim.next_packet(&mut buf) {
        if !matches!(p, SimPacket::Data { .. }) {
            continue;
        }
        for h in &sim.hits {
            let Some(Shape::Sphere { .. }) =
                scene.objects.get(usize::from(h.object)).map(|o| o.shape)
            else {
                continue;
            };
            if h.purity < 255 {
                continue;
            }
            let pose = truth_pose(&w, h.time);
            let laser = usize::from(h.channel) % 16;
            let x = point(
                &pose,
                &w.mount,
                h.range,
                spherecal::velodyne::Model::Vlp16.beam(laser),
                h.azimuth.sin(),
                h.azimuth.cos(),
            );
            let e = off_object(&w, h.object, h.time, &x);
            // The footprint's widest sub-ray is 1.83 sigma = 1.83 x 0.75 mrad from the centre.
            let reach = h.range * 1.8257 * 0.75e-3;
            worst_ratio = worst_ratio.max(e / reach);
            off += u64::from(e > 2e-3);
            n += 1;
        }
    }
    eprintln!("{n} pure sphere returns, {off} more than 2 mm off the surface; worst {worst_ratio:.2} x the footprint's reach; {} mixed pixels", sim.stats.mixed);
    assert!(n > 2000);
    assert!(worst_ratio <= 1.0, "{worst_ratio}");
    assert!(off > 20, "blooming at the silhouettes: {off}");
    assert!(sim.stats.mixed > 100, "mixed pixels: {}", sim.stats.mixed);

    // Range walk: the same scene with 5 cm of walk; decoded ranges grow by 5 cm x (1 - I/100).
    let mut decode_all = |walk: f64| {
        let mut cfg = s.lidar_config();
        cfg.range_walk = walk;
        let mut sim = LidarSim::new(&w, cfg);
        let mut out = Vec::new();
        let mut pts = PointBuf::new();
        while let Some(p) = sim.next_packet(&mut buf) {
            if matches!(p, SimPacket::Data { .. }) {
                decode(&DataPacket::new_checked(&buf[..]).unwrap(), &mut pts).unwrap();
                out.extend(pts.as_slice().iter().map(|q| (q.distance_raw, q.intensity)));
            }
        }
        out
    };
    let (a, b) = (decode_all(0.0), decode_all(0.05));
    assert_eq!(a.len(), b.len());
    for ((ra, ia), (rb, _)) in a.iter().zip(&b).step_by(97) {
        let want = 0.05 * (1.0 - f64::from(*ia) / 100.0);
        let got = (f64::from(*rb) - f64::from(*ra)) * 0.002;
        assert!(
            (got - want).abs() <= 0.0021,
            "intensity {ia}: {got} vs {want}"
        );
    }
}

/// The broad phase only culls: a short pass traced with it and without it (every firing
/// against every object) gives the same bytes.
#[test]
fn the_broad_phase_misses_nothing() {
    let text = spherecal_tools::config::scenario::BUILTIN
        .iter()
        .find(|b| b.0 == "table1-noisy")
        .unwrap()
        .1;
    let i = text.find("[[trajectory.pass]]").unwrap();
    let j = i + text[i..].find("[water]").unwrap();
    let one = format!(
        "{}[[trajectory.pass]]\nstart_ne_m = [-1.0, 7.0]\nheading_deg = 20.0\nspeed_mps = 2.0\nduration_s = 1.5\n\n{}",
        &text[..i],
        &text[j..]
    );
    let s = Scenario::from_toml(&one).unwrap();
    let scene = s.scene();
    let passes = s.passes();
    let w = s.world(&[], &passes, &scene.objects);
    let trace = |cull: bool| {
        let mut cfg = s.lidar_config();
        cfg.cull = cull;
        let mut sim = LidarSim::new(&w, cfg);
        let mut buf = [0u8; 1206];
        let mut out = Vec::new();
        while sim.next_packet(&mut buf).is_some() {
            out.extend_from_slice(&buf);
        }
        (out, sim.stats)
    };
    let (a, sa) = trace(true);
    let (b, sb) = trace(false);
    assert!(sa.hits[0] + sa.clutter_hits > 10_000, "{sa:?}");
    assert_eq!(sa.hits, sb.hits);
    assert_eq!(sa.clutter_hits, sb.clutter_hits);
    assert!(a == b, "culling changed the packets");
    assert!(
        sa.tests * 5 < sb.tests,
        "{} vs {} tests",
        sa.tests,
        sb.tests
    );
}

/// Through the wire: decode the packets with the core decoder (integer-microsecond stamps,
/// 0.01 deg azimuths, 2 mm ranges, f32) and georeference with the truth trajectory: every
/// return lands within about 1 mm of the object it came from.
#[test]
fn decoded_points_lie_on_their_spheres() {
    let s = Scenario::load("table1").unwrap();
    let (passes, objects) = (s.passes(), s.objects());
    let w = s.world(&[], &passes, &objects);
    let mut sim = LidarSim::new(&w, s.lidar_config());
    let mut buf = [0u8; 1206];
    let mut pts = PointBuf::new();
    let hour0 = gps_to_unix_ns(w.start, w.leap_seconds).div_euclid(3_600_000_000_000);
    let (mut n, mut worst, mut last_stamp, mut rollovers) = (0u64, 0f64, 0u32, 0);
    let mut all = 0u64;
    while let Some(p) = sim.next_packet(&mut buf) {
        let SimPacket::Data { .. } = p else { continue };
        let pkt = DataPacket::new_checked(&buf[..]).unwrap();
        decode(&pkt, &mut pts).unwrap();
        // Unwrap the hour: microseconds past the hour fall back at the top of the hour.
        let stamp = pkt.timestamp_us();
        if stamp < last_stamp {
            rollovers += 1;
        }
        last_stamp = stamp;
        let unix_ns = (hour0 + rollovers) * 3_600_000_000_000 + i64::from(stamp) * 1000;
        for q in pts.as_slice() {
            let t = GpsTime(
                spherecal::time::unix_ns_to_gps(unix_ns, w.leap_seconds).0 + i64::from(q.offset_ns),
            );
            let pose = truth_pose(&w, t);
            let az = f64::from(q.azimuth);
            let x = point(
                &pose,
                &w.mount,
                f64::from(q.distance_raw) * 0.002,
                spherecal::velodyne::Model::Vlp16.beam(q.laser()),
                az.sin(),
                az.cos(),
            );
            // The object this return came from, by block and channel; every decoded return
            // lies on it (spheres to the wire's precision, everything else too).
            let hit = sim
                .hits
                .iter()
                .find(|h| h.block == q.block && h.channel == q.channel)
                .expect("every decoded return was traced");
            let e = off_object(&w, hit.object, t, &x);
            assert!(e < 1.2e-3, "decoded point {e} m off its object {hit:?}");
            if objects
                .get(usize::from(hit.object))
                .is_some_and(|o| o.target.is_some())
            {
                worst = worst.max(e);
                n += 1;
            }
            all += 1;
        }
    }
    assert_eq!(rollovers, 1, "table1 crosses the top of the hour");
    assert_eq!(n, sim.stats.hits.iter().sum::<u64>());
    assert_eq!(all, n + sim.stats.clutter_hits);
    eprintln!(
        "{n} decoded sphere returns, worst {:.3} mm off; {all} returns in all",
        worst * 1e3
    );
}

fn run(args: &[&str]) -> String {
    common::stdout_of(common::spherecal().args(args))
}

fn tmp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("spherecal-sim-{}-{name}", std::process::id()))
}

/// A short variant of a built-in scenario (one pass) for the file-level tests.
fn short(base: &str, edit: impl Fn(String) -> String) -> std::path::PathBuf {
    let text = spherecal_tools::config::scenario::BUILTIN
        .iter()
        .find(|b| b.0 == base)
        .unwrap()
        .1;
    let i = text.find("[[trajectory.pass]]").unwrap();
    let scenery = text[i..].find("[water]").map_or("", |j| &text[i + j..]);
    let one = format!("{}[[trajectory.pass]]\nstart_ne_m = [-2.0, 8.0]\nheading_deg = 0.0\nspeed_mps = 2.0\nduration_s = 6.0\n\n{scenery}", &text[..i]);
    let p = tmp(&format!("{base}.toml"));
    std::fs::write(&p, edit(one)).unwrap();
    p
}

#[test]
fn synthetic_files_read_back_at_the_sensor_rates() {
    let dir = tmp("table1");
    let out = run(&[
        "synth",
        "--scenario",
        "table1",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(out.contains("table1: 62.5 s of scanning"), "{out}");
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["boresight_deg"]["roll"], 179.5);
    assert_eq!(truth["lever_arm_m"]["z"], -1.36);
    assert_eq!(truth["leap_seconds"], 18);

    let dec = run(&["decode", dir.join("lidar.pcap").to_str().unwrap()]);
    assert!(dec.contains("skipped: 0"), "{dec}");
    assert!(dec.contains("(PPS locked: 62)"), "{dec}");
    assert!(
        dec.contains("(0 disagree with the packet timestamp)"),
        "{dec}"
    );
    // 754 packets a second (manual appendix B): 62.5 s -> 47,095.
    let packets = truth["data_packets"].as_u64().unwrap();
    assert_eq!(packets, (62.5 / (12.0 * 110.592e-6)) as u64);
    assert!(
        dec.contains(&format!("data packets: {packets} (strongest: {packets})")),
        "{dec}"
    );

    let ins = run(&["ins", dir.join("ins.bin").to_str().unwrap()]);
    assert!(
        ins.contains("CRC failures: 0") && ins.contains("skipped bytes: 0 "),
        "{ins}"
    );
    assert!(
        ins.contains(&format!("poses: {}", truth["ins_frames"])),
        "{ins}"
    );

    // The labels: one per decoded return, in file order; the spheres' counts are the truth's,
    // and every label names an object of truth.json (or the water).
    let labels = spherecal_tools::synth::read_labels(&dir.join("labels.bin")).unwrap();
    let points: u64 = dec
        .lines()
        .find_map(|l| l.strip_prefix("points: "))
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    assert_eq!(labels.len() as u64, points);
    let objects = truth["objects"].as_array().unwrap();
    for k in 0..2 {
        let on = labels.iter().filter(|l| usize::from(l.object) == k).count();
        assert_eq!(on as u64, truth["points_per_sphere"][k].as_u64().unwrap());
        assert_eq!(objects[k]["kind"], "sphere");
    }
    assert!(labels
        .iter()
        .all(|l| usize::from(l.object) < objects.len()
            || l.object == spherecal::sim::lidar::LABEL_WATER));
    assert!(labels.windows(2).all(|w| w[0].packet <= w[1].packet));

    // The site file reads back.
    let site = spherecal_tools::config::site::Site::load(&dir.join("site.toml")).unwrap();
    assert_eq!(site.sphere.len(), 2);
    assert_eq!(site.leap_seconds, 18);

    // Azimuth steps: 600 rpm is 3600 deg/s: 0.199 deg per 55.296 us firing sequence, 0.398 deg
    // per block, as in the real 10 Hz capture (lidarutils: block steps of 0.38-0.42 deg).
    let csv = dir.join("points.csv");
    let _ = run(&[
        "decode",
        dir.join("lidar.pcap").to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut per_packet: std::collections::BTreeMap<u64, Vec<(f64, f64)>> = Default::default();
    for l in text.lines().skip(1).take(5000) {
        let f: Vec<&str> = l.split(',').collect();
        per_packet
            .entry(f[0].parse().unwrap())
            .or_default()
            .push((f[5].parse().unwrap(), f[6].parse().unwrap()));
    }
    for pts in per_packet.values() {
        for pair in pts.windows(2) {
            let (dt, da) = (
                pair[1].0 - pair[0].0,
                (pair[1].1 - pair[0].1 + 360.0) % 360.0,
            );
            if dt > 1.0 {
                let rate = da / dt; // deg per us
                assert!((rate * 55.296 - 0.199).abs() < 0.006, "{rate} deg/us");
            }
        }
    }
    // The same statistic on the real 600 rpm capture: mean block-to-block azimuth step.
    let mean_step = |path: &std::path::Path| {
        use spherecal_hal::{PacketSource, Record};
        let mut src = spherecal_hal::pcap::PcapSource::open(path).unwrap();
        let (mut sum, mut n) = (0u64, 0u64);
        while let Some(Record::Udp(d)) = src.next_record().unwrap() {
            if let Ok(p) = DataPacket::new_checked(d.payload) {
                for b in 0..11 {
                    sum += (36_000 + u64::from(p.azimuth_raw(b + 1)) - u64::from(p.azimuth_raw(b)))
                        % 36_000;
                    n += 1;
                }
            }
        }
        sum as f64 / n as f64 / 100.0
    };
    let ours = mean_step(&dir.join("lidar.pcap"));
    let real = mean_step(&common::test_data("vlp16/lidarutils_vlp16_example.pcap"));
    assert!(
        (ours - 0.398).abs() < 0.002 && (ours - real).abs() < 0.01,
        "block step: synthetic {ours} deg, real {real} deg"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn same_seed_same_bytes_and_noise_and_faults() {
    let sc = short("table1-noisy", |t| {
        t.replace("drop_prob = 0.0", "drop_prob = 0.01")
            .replace("corrupt_prob = 0.0", "corrupt_prob = 0.0005")
    });
    let (a, b) = (tmp("a"), tmp("b"));
    run(&[
        "synth",
        "--scenario",
        sc.to_str().unwrap(),
        "--out",
        a.to_str().unwrap(),
    ]);
    run(&[
        "synth",
        "--scenario",
        sc.to_str().unwrap(),
        "--out",
        b.to_str().unwrap(),
    ]);
    for f in ["lidar.pcap", "ins.bin", "site.toml", "truth.json"] {
        assert!(
            std::fs::read(a.join(f)).unwrap() == std::fs::read(b.join(f)).unwrap(),
            "{f} differs between runs"
        );
    }
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("truth.json")).unwrap()).unwrap();
    assert!(truth["dropped_packets"].as_u64().unwrap() > 20);
    assert!(truth["corrupted_bytes"].as_u64().unwrap() > 5);
    let ins = run(&["ins", a.join("ins.bin").to_str().unwrap()]);
    assert!(
        !ins.contains("CRC failures: 0\n"),
        "corrupted bytes must show as CRC failures: {ins}"
    );
    let dec = run(&["decode", a.join("lidar.pcap").to_str().unwrap()]);
    assert!(
        dec.contains(&format!("data packets: {} ", truth["data_packets"])),
        "{dec}"
    );
    // A different seed gives different bytes.
    let sc2 = short("table1-noisy", |t| t.replace("seed = 7", "seed = 8"));
    let c = tmp("c");
    run(&[
        "synth",
        "--scenario",
        sc2.to_str().unwrap(),
        "--out",
        c.to_str().unwrap(),
    ]);
    assert!(
        std::fs::read(c.join("lidar.pcap")).unwrap()
            != std::fs::read(a.join("lidar.pcap")).unwrap()
    );
    for d in [a, b, c] {
        std::fs::remove_dir_all(d).unwrap();
    }
}

/// A trace replayed with a seed gives the same bytes as tracing with it (the scene's draws are
/// the scene's, the noise is the seed's), and another seed on the same trace other noise.
#[test]
fn a_trace_re_noised_equals_a_fresh_synthesis() {
    let sc = short("table1-noisy", |t| t);
    let s = Scenario::load(sc.to_str().unwrap()).unwrap();
    let cache = spherecal_tools::synth::trace(&s).unwrap();
    let (a, b) = (tmp("fresh"), tmp("replayed"));
    spherecal_tools::synth::synth(&s, &a).unwrap();
    spherecal_tools::synth::synth_traced(&s, &b, &cache).unwrap();
    for f in ["lidar.pcap", "ins.bin", "labels.bin", "truth.json"] {
        assert!(
            std::fs::read(a.join(f)).unwrap() == std::fs::read(b.join(f)).unwrap(),
            "{f} differs"
        );
    }
    let text = std::fs::read_to_string(&sc).unwrap();
    let s2 = Scenario::from_toml(&text.replace("seed = 7", "seed = 8")).unwrap();
    let c = tmp("replayed-8");
    spherecal_tools::synth::synth_traced(&s2, &c, &cache).unwrap();
    assert!(
        std::fs::read(c.join("lidar.pcap")).unwrap()
            != std::fs::read(a.join("lidar.pcap")).unwrap()
    );
    // The labels (which object each return came from) are the scene's: the same.
    assert!(
        std::fs::read(c.join("labels.bin")).unwrap()
            == std::fs::read(a.join("labels.bin")).unwrap()
    );
    // A trace of another scene is refused.
    let other = Scenario::load("pontoon").unwrap();
    assert!(spherecal_tools::synth::synth_traced(&other, &tmp("other"), &cache).is_err());
    for d in [a, b, c] {
        std::fs::remove_dir_all(d).unwrap();
    }
}

#[test]
fn dual_return_at_1200_rpm() {
    let sc = short("table1", |t| {
        t.replace("return_mode = \"strongest\"", "return_mode = \"dual\"")
            .replace("rpm = 600", "rpm = 1200")
    });
    let d = tmp("dual");
    run(&[
        "synth",
        "--scenario",
        sc.to_str().unwrap(),
        "--out",
        d.to_str().unwrap(),
    ]);
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("truth.json")).unwrap()).unwrap();
    // 1508 packets a second in dual mode.
    assert_eq!(
        truth["data_packets"].as_u64().unwrap(),
        (6.0 / (6.0 * 110.592e-6)) as u64
    );
    let dec = run(&["decode", d.join("lidar.pcap").to_str().unwrap()]);
    assert!(dec.contains("(dual: "), "{dec}");
    assert!(dec.contains("skipped: 0"), "{dec}");
    let pts: u64 = truth["points_per_sphere"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .sum::<u64>()
        + truth["clutter_points"].as_u64().unwrap();
    assert!(dec.contains(&format!("points: {pts}\n")), "{dec}");
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn print_scenario_round_trips_and_bad_scenarios_exit_2() {
    let text = run(&["synth", "--print-scenario", "table1"]);
    assert!(Scenario::from_toml(&text).is_ok());
    let bad = tmp("bad.toml");
    std::fs::write(&bad, text.replace("rpm = 600", "rpm = 600\nspin = 2")).unwrap();
    let out = common::spherecal()
        .args([
            "synth",
            "--scenario",
            bad.to_str().unwrap(),
            "--out",
            "/tmp/x",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown field `spin`"));
}

/// A recorded trajectory drives the simulator: table1's own path written as a 100 Hz CSV and as
/// an SBET, synthesised again from the files, gives the same survey; and the calibration
/// recovers the truth from it.
#[test]
fn recorded_trajectory_from_csv_and_sbet() {
    let s = Scenario::load("table1").unwrap();
    let (passes, objects) = (s.passes(), s.objects());
    let w = s.world(&[], &passes, &objects);
    let dir = tmp("recorded");
    std::fs::create_dir_all(&dir).unwrap();
    let mut csv = String::from("time_s,north_m,east_m,down_m,roll_deg,pitch_deg,heading_deg\n");
    let mut sbet = Vec::new();
    let (week, _) = s.start().week_tow_ns();
    for j in -100..=(62.5 * 100.0) as i64 + 100 {
        let t = j as f64 * 0.01;
        let st = w.trajectory.state(t);
        csv.push_str(&format!(
            "{t:.2},{:.6},{:.6},{:.6},{:.9},{:.9},{:.9}\n",
            st.position.x,
            st.position.y,
            st.position.z,
            st.rph[0].to_degrees(),
            st.rph[1].to_degrees(),
            st.rph[2].to_degrees()
        ));
        let g = w.site.to_geodetic(&st.position);
        let local = w.site.from_local_level(g.lat, g.lon).transpose()
            * rotation(st.rph[0], st.rph[1], st.rph[2]);
        let [r, p, h] = spherecal::frames::roll_pitch_heading(&local);
        let gps = s.start().0 + (t * 1e9).round() as i64;
        let rec = spherecal_hal::sbet::SbetRecord {
            tow_s: (gps - week * spherecal::time::WEEK_NS) as f64 * 1e-9,
            lat: g.lat,
            lon: g.lon,
            h: g.h,
            roll: r,
            pitch: p,
            platform_heading: h,
            wander: 0.0,
        };
        sbet.extend_from_slice(&rec.emit());
    }
    let text = spherecal_tools::config::scenario::BUILTIN[0].1;
    let i = text.find("[[trajectory.pass]]").unwrap();
    for (name, bytes) in [("traj.csv", csv.into_bytes()), ("traj.sbet", sbet)] {
        let f = dir.join(name);
        std::fs::write(&f, bytes).unwrap();
        let sc = format!("{}file = {:?}\n", &text[..i], f.to_str().unwrap())
            .replace("[trajectory]\n", "[trajectory]\n");
        let sc = Scenario::from_toml(&sc).unwrap();
        let out = dir.join(format!("out-{name}"));
        let truth = spherecal_tools::synth::synth(&sc, &out).unwrap();
        let want = spherecal_tools::synth::synth(&s, &dir.join("passes")).unwrap();
        for k in 0..2 {
            let (a, b) = (
                truth.points_per_sphere[k] as f64,
                want.points_per_sphere[k] as f64,
            );
            assert!(
                (a - b).abs() <= 0.01 * b + 3.0,
                "{name}: {a} vs {b} returns on sphere {k}"
            );
        }
        let c = spherecal_tools::survey::run_calibrate(
            spherecal_tools::survey::Survey::synth_dir(&out),
            None,
            Default::default(),
            &Default::default(),
            None,
        )
        .unwrap();
        let (text, ok) = (c.text, c.converged);
        assert!(ok, "{text}");
        let r: Vec<f64> = text
            .lines()
            .filter(|l| {
                ["roll", "pitch", "heading", "x ", "y ", "z "]
                    .iter()
                    .any(|p| l.starts_with(p))
            })
            .map(|l| l.split_whitespace().nth(2).unwrap().parse().unwrap())
            .collect();
        let truth6 = [179.5, -44.9, 1.2, 1.5, -1.24, -1.36];
        for k in 0..6 {
            assert!(
                (r[k] - truth6[k]).abs() < 2e-3,
                "{name}: parameter {k}: {} vs {}",
                r[k],
                truth6[k]
            );
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The simulator's footprint (a grid of sub-rays over the beam's Gaussian, `sim::lidar`)
/// against the solver's model of it (a quadrature and a table, `calib::footprint`): two
/// renderings of one beam written apart. table1-real with the grid footprint and every noise
/// off: each pure return
/// on a sphere (no other object within its footprint) binned by how far its beam's axis
/// passes outside the limb (`q`, in footprint widths), its distance from the surface against
/// the model's expected residual: within 1.5 mm in every bin of 30 or more, and near the limb
/// the bloom is centimetres (the check sees it).
#[test]
fn the_simulated_footprint_blooms_as_the_solver_models_it() {
    use spherecal::calib::footprint::{Footprint, Limb};
    let mut s = without_noise("table1-real");
    s.lidar.footprint_grid = true;
    s.lidar.range_walk_m = 0.0;
    s.lidar.edge_dropout = 0.0;
    let scene = s.scene();
    let passes = s.passes();
    let w = s.world(&[], &passes, &scene.objects);
    let mut sim = LidarSim::new(&w, s.lidar_config());
    let mut buf = [0u8; 1206];
    // (count, sum of distances from the surface, sum of the model's) per half width of q.
    let mut bins = [(0usize, 0.0f64, 0.0f64); 10];
    let sig = Footprint::VELODYNE.sigma;
    let model = s.model().unwrap();
    while let Some(p) = sim.next_packet(&mut buf) {
        if !matches!(p, SimPacket::Data { .. }) {
            continue;
        }
        for h in &sim.hits {
            let Some(Shape::Sphere { c, r }) =
                scene.objects.get(usize::from(h.object)).map(|o| o.shape)
            else {
                continue;
            };
            if h.purity != 255 {
                continue;
            }
            let pose = truth_pose(&w, h.time);
            let beam = model.beam(usize::from(h.channel) % model.lasers());
            let at = |rg: f64, az: f64| point(&pose, &w.mount, rg, beam, az.sin(), az.cos());
            let (x, o) = (at(h.range, h.azimuth), at(0.0, h.azimuth));
            let u = (x - o).normalize();
            let along = at(h.range, h.azimuth + 1e-6) - x;
            let along = (along - u * along.dot(&u)).normalize();
            let across = u.cross(&along);
            let mv = (c - o) - u * (c - o).dot(&u);
            let m = [mv.dot(&along), mv.dot(&across)];
            let sd = [sig[0] * h.range, sig[1] * h.range];
            let q = Limb::of(m, sd, r).q;
            let k = ((q + 4.5) * 2.0).floor();
            if (0.0..10.0).contains(&k) {
                let b = &mut bins[k as usize];
                b.0 += 1;
                b.1 += (x - c).norm() - r;
                b.2 += spherecal::calib::footprint::expected(m, sd, r);
            }
        }
    }
    let mut limb: f64 = 0.0;
    for (k, b) in bins.iter().enumerate() {
        let q = k as f64 * 0.5 - 4.5;
        let (sim_mm, model_mm) = (b.1 / b.0.max(1) as f64 * 1e3, b.2 / b.0.max(1) as f64 * 1e3);
        eprintln!(
            "q {q:+.1}: {:6} returns, simulated {sim_mm:+6.2} mm, model {model_mm:+6.2} mm",
            b.0
        );
        if b.0 >= 30 {
            assert!(
                (sim_mm - model_mm).abs() < 1.5,
                "q {q}: {sim_mm} vs {model_mm} mm"
            );
            if q >= -1.0 {
                limb = limb.max(sim_mm);
            }
        }
    }
    assert!(limb > 5.0, "no bloom near the limb: {limb} mm");
}

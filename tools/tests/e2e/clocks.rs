//! Clocks, sensor states and inputs as a broken rig delivers them (issue 12): the INS stream
//! late against the LiDAR (estimated as a seventh parameter, or refused when held), a LiDAR clock
//! without PPS (refused unless allowed; searched), a clock 1,500 s off with void RMCs (exit 2
//! naming the clock), and byte edits of the streams the way a faulty rig produces them: PPS
//! byte, packet timestamps, RMC status, VN-200 InsStatus mode bits, CRC damage, gaps, wrong files.
//! Consistency before "converged": an INS height jump in one pass, residuals beyond the noise
//! model. Expectations come from the edits themselves (counts and spans of what was edited), never from
//! the code's own output.

use crate::common;
use crate::common::vn200::{frame_time_s, frames, seal, set_status, FRAME, HEIGHT_AT, STATUS_AT};

use spherecal_tools::config::scenario::Scenario;
use spherecal_tools::report::Report;
use std::path::{Path, PathBuf};
use std::process::Output;

fn dir(name: &str) -> PathBuf {
    common::tmp("clocks", name)
}

/// Synthesise table1 (or `base`) with `edit` applied to its scenario.
fn synth(base: &str, name: &str, edit: impl FnOnce(&mut Scenario)) -> (PathBuf, Scenario) {
    let mut s = Scenario::load(base).unwrap();
    edit(&mut s);
    let d = dir(name);
    spherecal_tools::synth::synth(&s, &d).unwrap();
    (d, s)
}

fn calibrate(d: &Path, ins: &Path, extra: &[&str]) -> (Output, Option<Report>) {
    let report = d.join(format!(
        "report-{}.json",
        extra.join("").replace(['-', '.'], "")
    ));
    let _ = std::fs::remove_file(&report);
    let out = common::spherecal()
        .arg("calibrate")
        .arg("--pcap")
        .arg(d.join("lidar.pcap"))
        .arg("--ins")
        .arg(ins)
        .arg("--site")
        .arg(d.join("site.toml"))
        .arg("--report")
        .arg(&report)
        .args(extra)
        .output()
        .unwrap();
    let rep = std::fs::read_to_string(&report)
        .ok()
        .map(|t| Report::parse(&t).unwrap());
    (out, rep)
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn truth(s: &Scenario) -> [f64; 6] {
    s.mount.truth.deg_m().0
}

/// Every parameter within `tol` (deg, m) of the truth.
fn assert_mount(r: &Report, s: &Scenario, tol: f64, what: &str) {
    common::assert_within(&r.deg_m(), &truth(s), tol, what);
}

/// The INS stream 0.02 s, 0.1 s and 0.3 s late (noise-free): the offset is estimated within
/// 1 ms and the mount within 1e-3 deg / m. Held at 0, the 0.1 and 0.3 s cases are refused: the
/// data, free, move the offset towards the truth by many sigmas (the mount had absorbed it as a
/// lever-arm x of speed x the error; at 0.3 s the free fit stalls half-way, on the first-order
/// motion model, and still refutes the held value).
#[test]
fn ins_late_is_estimated_and_a_wrong_held_offset_is_refused() {
    let results: Vec<_> = std::thread::scope(|sc| {
        [0.02, 0.1, 0.3]
            .map(|late| {
                sc.spawn(move || {
                    let (d, s) = synth("table1", &format!("late{late}"), |s| {
                        s.ins.time_offset_s = late
                    });
                    let (out, r) = calibrate(&d, &d.join("ins.bin"), &[]);
                    (late, d, s, out, r)
                })
            })
            .map(|h| h.join().unwrap())
    })
    .into_iter()
    .collect();
    for (late, d, s, out, r) in results {
        assert!(common::claimed(&out), "{late}: {}", text(&out));
        let r = r.unwrap();
        assert!(
            (r.time_offset_s - late).abs() < 1e-3,
            "{late}: {}",
            r.time_offset_s
        );
        assert!(r.time_offset_s == s.true_time_offset_s() || r.sigma.time_offset_s > 0.0);
        assert_mount(&r, &s, 1e-3, &format!("INS {late} s late"));
        if late >= 0.1 {
            let (out, r) = calibrate(&d, &d.join("ins.bin"), &["--hold-time-offset"]);
            assert_eq!(out.status.code(), Some(1), "{}", text(&out));
            let r = r.unwrap();
            assert!(!r.converged);
            let reason = r.reason.unwrap();
            assert!(reason.contains("time offset held"), "{reason}");
            let [free, sigma] = r.consistency.free_time_offset_s.unwrap();
            assert!(
                free > 0.05 && free < late + 0.04 && free > 5.0 * sigma,
                "{late}: {free} +- {sigma}"
            );
            if late == 0.1 {
                assert!((free - 0.1).abs() < 0.04, "{free}");
            }
            // What it would have claimed: x off by speed x 0.1 s.
            assert!((r.lever_arm_m.x - s.mount.truth.lever_arm_m[0]).abs() > 0.05);
        }
        std::fs::remove_dir_all(d).unwrap();
    }
}

/// The noisy site with the INS 0.1 s late: the offset and the six within 3 sigma.
#[test]
fn noisy_ins_late_is_within_three_sigma() {
    let (d, s) = synth("table1-noisy", "noisy-late", |s| s.ins.time_offset_s = 0.1);
    let (out, r) = calibrate(&d, &d.join("ins.bin"), &[]);
    assert!(common::claimed(&out), "{}", text(&out));
    let r = r.unwrap();
    let z = (r.time_offset_s - 0.1) / r.sigma.time_offset_s;
    assert!(
        z.abs() <= 3.0,
        "dt {} +- {}",
        r.time_offset_s,
        r.sigma.time_offset_s
    );
    assert!(r.sigma.time_offset_s < 1e-3);
    let (got, want, sg) = (r.deg_m(), truth(&s), r.sigma.deg_m());
    for i in 0..6 {
        assert!(
            (got[i] - want[i]).abs() <= 3.0 * sg[i],
            "{}: {} vs {} sigma {}",
            spherecal::georef::NAMES[i],
            got[i],
            want[i],
            sg[i]
        );
    }
    std::fs::remove_dir_all(d).unwrap();
}

/// A VLP-16 without PPS whose clock runs 0.3 s and 1.0 s ahead (RMCs valid), and 1.0 s ahead
/// with void RMCs (nothing tells the offset: the coarse search must find it), on table1's two
/// fast passes (3.6 and 4.5 m/s: an offset of 1 s smears each sphere 4 m along the track).
/// Without the flag: exit 1 naming the PPS state (and with void RMCs and no search, the unknown
/// offset, not the smeared spheres' radius); with `--allow-unlocked-clock` the offset is
/// recovered within 1 ms and the mount within 1e-3, and where it is searched (void RMCs, and 1.0 s
/// ahead with valid ones asked to) each start costs one collection and one solve: a start's
/// refusal probes no radius and sets no stretch aside. Held at an offset its RMCs belie (0 s),
/// the refusal names where they put it.
#[test]
fn a_clock_without_pps_is_refused_unless_allowed_and_then_recovered() {
    let cases = [(0.3, true), (1.0, true), (1.0, false)];
    let results: Vec<_> = std::thread::scope(|sc| {
        cases
            .map(|(off, rmc)| {
                sc.spawn(move || {
                    let (d, s) = synth("table1", &format!("pps{off}{rmc}"), |s| {
                        s.lidar.clock_offset_s = off;
                        s.lidar.pps = "absent".into();
                        s.lidar.rmc_valid = rmc;
                        s.trajectory.pass.drain(..2);
                    });
                    // The refusal is the clock's state, whatever the offset: the search
                    // (17 solves) is left to the run that claims.
                    let refused = calibrate(&d, &d.join("ins.bin"), &["--search-time-offset", "0"]);
                    // 1.0 s ahead with valid RMCs: searched +-1 s around where they put it
                    // too (void RMCs are searched +-2 s by default).
                    let search: &[&str] = match (off, rmc) {
                        (1.0, true) => &["--search-time-offset", "1"],
                        _ => &[],
                    };
                    let args = [&["--allow-unlocked-clock"], search].concat();
                    let allowed = calibrate(&d, &d.join("ins.bin"), &args);
                    // ... and held at 0 s where valid RMCs put the offset a second away (the
                    // rule's tolerance is 0.55 s: at 0.3 s ahead 0 s is not belied).
                    let belied = (rmc && off > 0.55).then(|| {
                        calibrate(
                            &d,
                            &d.join("ins.bin"),
                            &["--time-offset", "0", "--hold-time-offset"],
                        )
                    });
                    (off, rmc, d, s, refused, allowed, belied)
                })
            })
            .map(|h| h.join().unwrap())
    })
    .into_iter()
    .collect();
    for (off, rmc, d, s, (out, r), (out2, r2), belied) in results {
        let what = format!("clock {off} s ahead, RMC valid {rmc}");
        if let Some((out3, r3)) = belied {
            // The offset the RMCs give is named, not the smeared spheres' radius.
            assert_eq!(out3.status.code(), Some(1), "{what}: {}", text(&out3));
            let why = r3.unwrap().reason.unwrap();
            assert!(
                why.contains("its RMC time puts the time offset between -")
                    && why.contains("not at the +0.000 s applied")
                    && !why.contains("radius"),
                "{what}: {why}"
            );
        }
        assert_eq!(out.status.code(), Some(1), "{what}: {}", text(&out));
        let r = r.unwrap();
        let reason = r.reason.clone().unwrap();
        assert!(
            reason.contains("not PPS-locked") && reason.contains("PPS absent"),
            "{reason}"
        );
        if !rmc {
            // Nothing tells the offset: it is named, not a radius or a stretch.
            assert!(
                reason.starts_with("the LiDAR clock is not PPS-locked and gives no RMC time")
                    && reason.contains("--time-offset")
                    && !reason.contains("radius")
                    && r.set_aside.is_empty(),
                "{reason}"
            );
        }
        let inputs = r.inputs.unwrap();
        assert!(!inputs.clock_trusted);
        // The two passes: 21 s of capture, one position packet a second, all "absent".
        assert_eq!(inputs.clock.pps[0], inputs.clock.packets(), "{what}");
        assert!(inputs.clock.packets() >= 19, "{what}");
        if rmc {
            assert_eq!(inputs.clock.rmc_valid, inputs.clock.packets());
        } else {
            assert_eq!(inputs.clock.rmc_void, inputs.clock.packets());
        }
        assert!(common::claimed(&out2), "{what}: {}", text(&out2));
        let r2 = r2.unwrap();
        assert!(
            (r2.time_offset_s - s.true_time_offset_s()).abs() < 1e-3,
            "{what}: {} vs {}",
            r2.time_offset_s,
            s.true_time_offset_s()
        );
        assert_mount(&r2, &s, 1e-3, &what);
        if !rmc || off == 1.0 {
            assert!(!r2.time_offset_search.is_empty(), "{what}: no search");
            // Each start one collection and one solve, its refusal left as it is (no radius
            // probed, no stretch set aside: those are for the offset the search picks).
            let e = r2.effort.unwrap();
            assert!(
                e.collections as usize >= r2.time_offset_search.len()
                    && e.solves == e.collections
                    && e.radius_probes == 0
                    && r2.set_aside.is_empty(),
                "{what}: {e:?}"
            );
        }
        std::fs::remove_dir_all(d).unwrap();
    }
}

/// A clock 1,500 s off with void RMCs: LiDAR and INS times do not overlap: exit 2, and the
/// sentence names the clock's state (PPS absent, RMC void).
#[test]
fn a_clock_1500_s_off_with_void_rmc_exits_2_naming_the_clock() {
    let (d, _) = synth("table1", "c1500", |s| {
        s.lidar.clock_offset_s = 1500.0;
        s.lidar.pps = "absent".into();
        s.lidar.rmc_valid = false;
    });
    let (out, _) = calibrate(&d, &d.join("ins.bin"), &[]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    let t = text(&out);
    assert!(
        t.contains("do not overlap") && t.contains("PPS absent") && t.contains("RMC void"),
        "{t}"
    );
    std::fs::remove_dir_all(d).unwrap();
}

/// The NMEA checksum: XOR of the bytes between '$' and '*'.
fn nmea_checksum(s: &[u8]) -> u8 {
    s.iter().fold(0, |a, b| a ^ b)
}

/// Walk a classic pcap (24-byte header, 16-byte record headers), calling `f` with each UDP
/// payload (Ethernet + IPv4 + UDP: 42 bytes of headers) and its destination port.
fn each_payload(pcap: &mut [u8], mut f: impl FnMut(u16, &mut [u8])) {
    let mut at = 24;
    while at + 16 <= pcap.len() {
        let incl = u32::from_le_bytes(pcap[at + 8..at + 12].try_into().unwrap()) as usize;
        let frame = &mut pcap[at + 16..at + 16 + incl];
        let port = u16::from_be_bytes([frame[36], frame[37]]);
        f(port, &mut frame[42..]);
        at += 16 + incl;
    }
}

/// The capture edited the way a LiDAR without PPS delivers it: every position packet's PPS
/// byte "absent", its RMC void ('A' -> 'V', checksum redone) and every data packet's timestamp
/// 0.7 s ahead (microseconds past the hour, wrapping). Refused without the flag, naming PPS and
/// RMC, with the counts of what was edited; with it, the offset -0.7 s is recovered.
#[test]
fn pcap_byte_edits_pps_rmc_and_stamps() {
    let (d, s) = synth("table1", "edit-pcap", |_| {});
    let mut pcap = std::fs::read(d.join("lidar.pcap")).unwrap();
    let (mut data, mut position) = (0u64, 0u64);
    each_payload(&mut pcap, |port, p| match (port, p.len()) {
        (2368, 1206) => {
            let us = u32::from_le_bytes(p[1200..1204].try_into().unwrap());
            let shifted = (us + 700_000) % 3_600_000_000;
            p[1200..1204].copy_from_slice(&shifted.to_le_bytes());
            data += 1;
        }
        (8308, 512) => {
            p[202] = 0; // PPS absent
            let us = u32::from_le_bytes(p[198..202].try_into().unwrap());
            p[198..202].copy_from_slice(&((us + 700_000) % 3_600_000_000).to_le_bytes());
            let nmea = &mut p[206..334];
            let star = nmea.iter().position(|&b| b == b'*').unwrap();
            let fields: Vec<usize> = (0..star).filter(|&i| nmea[i] == b',').collect();
            // $GPRMC,hhmmss,A,...: the status is the field after the second comma.
            assert_eq!(nmea[fields[1] + 1], b'A');
            nmea[fields[1] + 1] = b'V';
            let c = nmea_checksum(&nmea[1..star]);
            nmea[star + 1..star + 3].copy_from_slice(format!("{c:02X}").as_bytes());
            position += 1;
        }
        _ => panic!("unexpected record on port {port}"),
    });
    assert!(data > 40_000 && position >= 60);
    let edited = d.join("edited.pcap");
    std::fs::write(&edited, &pcap).unwrap();
    std::fs::copy(&edited, d.join("lidar.pcap")).unwrap();

    let (out, r) = calibrate(&d, &d.join("ins.bin"), &[]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let r = r.unwrap();
    let inputs = r.inputs.as_ref().unwrap();
    assert_eq!(inputs.clock.pps[0], position);
    assert_eq!(inputs.clock.rmc_void, position);
    assert_eq!(inputs.data_packets, data);
    let reason = r.reason.unwrap();
    assert!(
        reason.contains("PPS absent") && reason.contains("RMC void"),
        "{reason}"
    );
    let t = text(&out);
    assert!(t.contains("PPS absent") && t.contains("RMC void"), "{t}");

    let (out, r) = calibrate(&d, &d.join("ins.bin"), &["--allow-unlocked-clock"]);
    assert!(common::claimed(&out), "{}", text(&out));
    let r = r.unwrap();
    assert!((r.time_offset_s + 0.7).abs() < 1e-3, "{}", r.time_offset_s);
    assert_mount(&r, &s, 1e-3, "stamps 0.7 s ahead");
    std::fs::remove_dir_all(d).unwrap();
}

/// The VN-200 stream edited the way a real one misbehaves: 3 s of frames whose InsStatus
/// says "aligning" (mode 1) and 2 s saying "GNSS lost" (mode 3), CRC damage in every 10th frame
/// elsewhere, and a 2 s hole (cutting the frames either side). The report counts exactly what
/// was edited, it is a gap and not a clock step, the excluded spans
/// match, the calibration still holds (the edits miss the sphere passes only partly: the
/// solution must stay right), and `--keep-untracked-ins` keeps the untracked poses.
#[test]
fn ins_byte_edits_status_crc_and_gaps() {
    let (d, s) = synth("table1", "edit-ins", |_| {});
    let ins = std::fs::read(d.join("ins.bin")).unwrap();
    let at = frames(&ins);
    assert!(at.len() > 12_000, "{} frames", at.len());
    let t0 = frame_time_s(&ins, at[0]);
    let mut out = Vec::with_capacity(ins.len());
    let (mut aligning, mut lost, mut damaged, mut removed) = (0u64, 0u64, 0u64, 0u64);
    let (mut al_span, mut lost_span) = ((f64::MAX, 0.0f64), (f64::MAX, 0.0f64));
    let mut prev = 0;
    for (k, &i) in at.iter().enumerate() {
        out.extend_from_slice(&ins[prev..i]);
        prev = i + FRAME;
        let mut f = ins[i..i + FRAME].to_vec();
        let t = frame_time_s(&ins, i) - t0;
        let status = u16::from_le_bytes([f[STATUS_AT], f[STATUS_AT + 1]]);
        assert_eq!(status & 3, 2, "the synthetic INS tracks");
        if (20.0..22.0).contains(&t) {
            // The line dropped out for 2 s: it also cuts the frames either side of the hole
            // (a serial line does not fail at a frame's boundary).
            if removed == 0 {
                out.truncate(out.len() - 20);
            }
            removed += 1;
            continue;
        } else if removed > 0 && t < 22.01 {
            f.drain(..20);
            out.extend_from_slice(&f);
            continue;
        } else if (2.0..5.0).contains(&t) {
            set_status(&mut f, 0, (status & !3) | 1);
            aligning += 1;
            al_span = (al_span.0.min(t + t0), al_span.1.max(t + t0));
        } else if (40.0..42.0).contains(&t) {
            set_status(&mut f, 0, status | 3);
            lost += 1;
            lost_span = (lost_span.0.min(t + t0), lost_span.1.max(t + t0));
        } else if k % 10 == 5 {
            f[20] ^= 0x5A; // the CRC no longer holds
            damaged += 1;
        }
        out.extend_from_slice(&f);
    }
    out.extend_from_slice(&ins[prev..]);
    let edited = d.join("edited-ins.bin");
    std::fs::write(&edited, &out).unwrap();
    assert!(aligning > 500 && lost > 300 && removed > 300 && damaged > 1000);

    let (o, r) = calibrate(&d, &edited, &[]);
    assert!(common::claimed(&o), "{}", text(&o));
    let r = r.unwrap();
    let st = &r.inputs.as_ref().unwrap().ins_state;
    // Every damaged frame fails its CRC; a resynchronising framer may also try a false sync
    // byte inside one (an 80-byte frame: ~1 in 10).
    assert!(
        st.crc_failures >= damaged && st.crc_failures <= damaged + damaged / 8,
        "{} CRC failures for {damaged} damaged frames",
        st.crc_failures
    );
    assert_eq!(st.excluded[1], aligning, "aligning");
    assert_eq!(st.excluded[2], lost, "GNSS lost");
    assert_eq!(st.excluded[0] + st.excluded[3], 0);
    assert_eq!(st.kept_untracked, 0);
    // The spans excluded: the edited ones, to the frame.
    assert_eq!(st.excluded_spans.len(), 2, "{:?}", st.excluded_spans);
    for ((a, b), (x, y)) in st.excluded_spans.iter().zip([al_span, lost_span]) {
        assert!(
            (a - x).abs() < 1e-6 && (b - y).abs() < 1e-6,
            "{a}..{b} vs {x}..{y}"
        );
    }
    // The hole (2 s, plus the frames either side lost to exclusion or damage, at most a
    // few) and the exclusions are gaps in the poses used.
    assert!(st.gaps >= 3, "{st:?}");
    assert!(
        (st.longest_gap_s - 3.0).abs() < 0.05,
        "{}",
        st.longest_gap_s
    );
    assert_eq!(st.clock_step_count, 0, "{:?}", st.clock_steps);
    let t = text(&o);
    assert!(t.contains("CRC") && t.contains("aligning"), "{t}");
    assert_mount(&r, &s, 1e-3, "edited INS");

    let (o, r) = calibrate(&d, &edited, &["--keep-untracked-ins"]);
    assert!(common::claimed(&o), "{}", text(&o));
    let st = r.unwrap().inputs.unwrap().ins_state;
    assert_eq!(st.excluded, [0; 4]);
    assert_eq!(st.kept_untracked, aligning + lost);
    std::fs::remove_dir_all(d).unwrap();
}

/// Files that are not what the option says: exit 2 with a sentence naming the file and what
/// was found instead; no calibration is attempted.
#[test]
fn wrong_files_exit_2_naming_them() {
    let (d, _) = synth("table1", "wrong", |_| {});
    let empty = d.join("empty.bin");
    std::fs::write(&empty, b"").unwrap();
    let random = d.join("random.bin");
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    let bytes: Vec<u8> = (0..200_000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect();
    std::fs::write(&random, &bytes).unwrap();
    for (f, says) in [
        (d.join("lidar.pcap"), "pcap"),
        (empty.clone(), "no VN-200"),
        (random.clone(), "no VN-200"),
    ] {
        let (out, _) = calibrate(&d, &f, &[]);
        let t = text(&out);
        assert_eq!(out.status.code(), Some(2), "{}: {t}", f.display());
        assert!(
            t.contains(&f.display().to_string()) && t.contains(says),
            "{t}"
        );
    }
    // Not an SBET: random bytes (records of 17 doubles with times all over) and the VN-200
    // stream itself.
    for f in [random, d.join("ins.bin")] {
        let out = common::spherecal()
            .arg("calibrate")
            .arg("--pcap")
            .arg(d.join("lidar.pcap"))
            .arg("--sbet")
            .arg(&f)
            .args(["--trajectory-datum", "WGS84"])
            .arg("--site")
            .arg(d.join("site.toml"))
            .output()
            .unwrap();
        let t = text(&out);
        assert_eq!(out.status.code(), Some(2), "{}: {t}", f.display());
        assert!(
            t.contains(&f.display().to_string()) && t.contains("SBET"),
            "{t}"
        );
    }
    std::fs::remove_dir_all(d).unwrap();
}

/// The noisy site with an INS height jump of 8 cm for 9 s (a GNSS fix that went float during
/// one pass over S1): the solution with it absorbs part of it, so the pass consistency test
/// refuses it, naming the pass and the sphere; that pass is then set aside (issue 46: one bad
/// stretch must not refuse a whole survey), said with the refusal it explains, and the rest
/// claimed within 3 sigma. The same stream without the jump converges with nothing set aside.
#[test]
fn an_ins_jump_in_one_pass_is_inconsistent_and_set_aside() {
    let (d, s) = synth("table1-noisy", "jump", |_| {});
    let ins = std::fs::read(d.join("ins.bin")).unwrap();
    let mut out = ins.clone();
    let at = frames(&ins);
    let t0 = frame_time_s(&ins, at[0]);
    let mut n = 0;
    for &i in &at {
        if (31.0..=40.0).contains(&(frame_time_s(&ins, i) - t0)) {
            // Position: latitude, longitude (deg), height (m) as f64.
            let at = i + HEIGHT_AT;
            let h = f64::from_le_bytes(out[at..at + 8].try_into().unwrap());
            out[at..at + 8].copy_from_slice(&(h + 0.08).to_le_bytes());
            seal(&mut out, i);
            n += 1;
        }
    }
    assert!(n > 1700);
    let jumped = d.join("jumped.bin");
    std::fs::write(&jumped, &out).unwrap();
    let (o, r) = calibrate(&d, &jumped, &[]);
    let t = text(&o);
    assert!(common::claimed(&o), "{t}");
    let r = r.unwrap();
    assert_eq!(r.set_aside.len(), 1, "{:?}", r.set_aside);
    let sa = &r.set_aside[0];
    assert!(
        sa.why.contains("inconsistent") && sa.why.contains("S1"),
        "{sa:?}"
    );
    // The stretch set aside is the jump's (and not much more).
    assert!(
        sa.from_gps_s < t0 + 40.0 && sa.to_gps_s > t0 + 31.0,
        "{sa:?}"
    );
    assert!(sa.to_gps_s - sa.from_gps_s < 25.0, "{sa:?}");
    assert!(t.contains("SET ASIDE: GPS"), "{t}");
    let (got, want, sg) = (r.deg_m(), truth(&s), r.sigma.deg_m());
    for i in 0..6 {
        assert!(
            (got[i] - want[i]).abs() < 3.0 * sg[i],
            "{i}: {got:?} {sg:?}"
        );
    }

    let (o, r) = calibrate(&d, &d.join("ins.bin"), &[]);
    assert!(common::claimed(&o), "{}", text(&o));
    let r = r.unwrap();
    assert!(r.consistency.worst_pass_chi2 < 25.0);
    assert!(r.set_aside.is_empty(), "{:?}", r.set_aside);
    std::fs::remove_dir_all(d).unwrap();
}

/// Over-dispersion: the noisy site (3 cm range noise) with a site file that claims a 5 mm
/// LiDAR and a survey-grade INS: the residual RMS is several times what that model predicts,
/// and the solution is refused with both numbers; with the default (specified) noise it passes.
#[test]
fn residuals_beyond_the_noise_model_are_refused() {
    let (d, _) = synth("table1-noisy", "overdispersed", |_| {});
    let site = std::fs::read_to_string(d.join("site.toml")).unwrap();
    std::fs::write(
        d.join("site.toml"),
        format!("{site}\n[noise]\nrange_m = 0.005\nattitude_deg = 0.005\nposition_m = 0.005\n"),
    )
    .unwrap();
    let (o, r) = calibrate(&d, &d.join("ins.bin"), &[]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let r = r.unwrap();
    let reason = r.reason.unwrap();
    assert!(
        reason.contains("residual RMS") && reason.contains("predicts"),
        "{reason}"
    );
    let c = &r.consistency;
    // 3 cm of range noise against sqrt(5^2 + (r 0.005 deg)^2 + 5^2) mm: about 3.5x.
    assert!(c.dispersion > 2.5 && c.dispersion < 5.0, "{c:?}");
    assert!(
        c.predicted_rms_m > 0.006 && c.predicted_rms_m < 0.009,
        "{c:?}"
    );
    std::fs::write(d.join("site.toml"), site).unwrap();
    let (o, r) = calibrate(&d, &d.join("ins.bin"), &[]);
    assert!(common::claimed(&o), "{}", text(&o));
    let c = r.unwrap().consistency;
    assert!(c.dispersion > 0.4 && c.dispersion < 1.0, "{c:?}");
    std::fs::remove_dir_all(d).unwrap();
}

/// The INS clock stepping within the survey (a receiver's time jump), 31 s into table1-noisy:
/// +20 ms (within the interpolation limit, so no gap shows), +50 ms and -50 ms (time going
/// back). Each is found in the stream itself (a frame right after another, nothing lost
/// between, not one output period later), reported by `calibrate`, `georef` and `ins`, and the
/// calibration refused naming the step and its time. The same survey without a step converges
/// (`noisy_ins_late_is_within_three_sigma` and the planner's Monte Carlo).
#[test]
fn ins_clock_steps_are_found_reported_and_refused() {
    let cases = [(0.020, "+20.0"), (0.050, "+50.0"), (-0.050, "-50.0")];
    let made: Vec<_> = std::thread::scope(|sc| {
        cases
            .iter()
            .map(|&(step, _)| {
                sc.spawn(move || {
                    synth("table1-noisy", &format!("step{step}"), |s| {
                        s.ins.clock_steps = vec![[31.0, step]];
                    })
                })
            })
            .collect::<Vec<_>>()
            .into_iter()
            .map(|h| h.join().unwrap())
            .collect()
    });
    for ((d, _), (step, ms)) in made.iter().zip(cases) {
        let (o, r) = calibrate(d, &d.join("ins.bin"), &[]);
        let t = text(&o);
        assert_eq!(o.status.code(), Some(1), "{t}");
        let reason = r.unwrap().reason.unwrap();
        assert!(
            reason.starts_with(&format!(
                "the INS clock stepped by {ms} ms 31.0 s into the LiDAR data"
            )),
            "{reason}"
        );
        let line = format!("CLOCK STEPS: 1 ({:+.4} s at ", step);
        assert!(t.contains(&line), "{t}");
        // georef and ins say it too.
        let g = common::stdout_of(
            common::spherecal()
                .arg("georef")
                .args(common::survey_args(d)),
        );
        assert!(g.contains(&line), "{g}");
        let i = common::stdout_of(common::spherecal().arg("ins").arg(d.join("ins.bin")));
        assert!(
            i.contains(&format!("clock steps: 1 ({:+.4} s at ", step)),
            "{i}"
        );
        assert_eq!(i.contains("time went back 1 times"), step < 0.0, "{i}");
        std::fs::remove_dir_all(d).unwrap();
    }
}

/// A POS MV stream's groups say nothing of what was lost between them, so a step of its clock
/// is caught by the calibration itself: the passes' own time offsets disagree. +50 ms 31 s in:
/// refused, naming the clocks and the pass; every pass after the step sees the INS late.
#[test]
fn a_clock_step_the_stream_cannot_show_is_caught_by_the_passes() {
    let (d, _) = synth("table1-noisy", "posmv-step", |s| {
        s.ins.kind = "posmv".into();
        s.ins.clock_steps = vec![[31.0, 0.05]];
    });
    let out = common::spherecal()
        .arg("calibrate")
        .arg("--pcap")
        .arg(d.join("lidar.pcap"))
        .arg("--posmv")
        .arg(d.join("ins.posmv"))
        .arg("--site")
        .arg(d.join("site.toml"))
        .arg("--report")
        .arg(d.join("r.json"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let r: Report =
        serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
    let reason = r.reason.unwrap();
    // Named by one pass's own time offset, or by the passes after the step together (none
    // alone 5 sigma off: measured +34 / +31 / +18 ms after it, -4 / -3 / -18 / -21 before).
    assert!(
        reason.starts_with("the clocks are not steady: in pass ")
            || reason.starts_with("the clocks are not steady: the passes from "),
        "{reason}"
    );
    // Every pass wholly after the step sees the INS 50 ms late against the rest.
    let t0 = r
        .per_pass
        .iter()
        .map(|p| p.start_gps_s)
        .fold(f64::INFINITY, f64::min);
    let after: Vec<_> = r
        .per_pass
        .iter()
        .filter(|p| p.start_gps_s > t0 + 32.0 && p.time_offset_shift_sigma_s > 0.0)
        .collect();
    assert!(!after.is_empty());
    for p in after {
        assert!(p.time_offset_shift_s > 0.0, "{p:?}");
    }
    std::fs::remove_dir_all(d).unwrap();
}

/// A LiDAR without PPS whose crystal runs 200 ppm fast (its clock 12 ms ahead by the end of
/// table1's minute): the drift of the time offset is estimated with it (-200 ppm: INS minus
/// LiDAR falls), within 4 sigma, and every parameter within 4 sigma of the truth; claimed with
/// `--allow-unlocked-clock`.
#[test]
fn an_unlocked_lidar_clock_drifting_is_modelled() {
    let (d, s) = synth("table1-noisy", "drift", |s| {
        s.lidar.pps = "absent".into();
        s.lidar.clock_drift_ppm = 200.0;
    });
    let (o, r) = calibrate(&d, &d.join("ins.bin"), &["--allow-unlocked-clock"]);
    assert!(common::claimed(&o), "{}", text(&o));
    let r = r.unwrap();
    assert!(
        (r.time_drift_ppm + 200.0).abs() < 4.0 * r.time_drift_sigma_ppm,
        "{} +- {} ppm",
        r.time_drift_ppm,
        r.time_drift_sigma_ppm
    );
    let (got, want, sg) = (r.deg_m(), truth(&s), r.sigma.deg_m());
    for i in 0..6 {
        assert!(
            (got[i] - want[i]).abs() < 4.0 * sg[i],
            "{i}: {} vs {} (sigma {})",
            got[i],
            want[i],
            sg[i]
        );
    }
    std::fs::remove_dir_all(d).unwrap();
}

//! Several input files as one survey (a rig's rotated logs): the capture and the serial log of a
//! synthetic survey cut into parts at record boundaries (by hand, from the formats' record
//! headers), given as glob patterns or one by one, the capture's parts named out of time
//! order; the calibration equals the one from the single files, and `replay` of the parts'
//! folder sends every datagram and the serial bytes exactly.

use crate::common;

use spherecal_tools::config::scenario::Scenario;
use std::path::Path;

/// Cut a file of `head` header bytes then records (`rec_head` bytes, the payload length as a
/// little-endian u32 at `len_at`) into `parts` files holding the header and a run of records.
fn cut(src: &Path, head: usize, rec_head: usize, len_at: usize, names: &[&Path]) {
    let b = std::fs::read(src).unwrap();
    let mut bounds = vec![head];
    let mut at = head;
    while at + rec_head <= b.len() {
        let n = u32::from_le_bytes(b[at + len_at..at + len_at + 4].try_into().unwrap()) as usize;
        at += rec_head + n;
        bounds.push(at);
    }
    assert_eq!(
        at,
        b.len(),
        "{}: records end at the file's end",
        src.display()
    );
    let records = bounds.len() - 1;
    for (k, name) in names.iter().enumerate() {
        let (from, to) = (
            bounds[records * k / names.len()],
            bounds[records * (k + 1) / names.len()],
        );
        let mut part = b[..head].to_vec();
        part.extend_from_slice(&b[from..to]);
        std::fs::write(name, part).unwrap();
    }
}

fn calibrate(dir: &Path, pcap: &[&Path], ins: &[&Path], report: &Path) -> serde_json::Value {
    common::stdout_of(
        common::spherecal()
            .arg("calibrate")
            .arg("--pcap")
            .args(pcap)
            .arg("--ins")
            .args(ins)
            .arg("--site")
            .arg(dir.join("site.toml"))
            .arg("--report")
            .arg(report),
    );
    serde_json::from_str(&std::fs::read_to_string(report).unwrap()).unwrap()
}

#[test]
fn rotated_logs_give_the_single_files_result() {
    let dir = common::tmp("multi-file", "survey");
    let s = Scenario::load("table1-bare").unwrap();
    spherecal_tools::synth::synth(&s, &dir).unwrap();
    let parts = dir.join("parts");
    std::fs::create_dir_all(&parts).unwrap();
    // Classic pcap: 24-byte header; records of 16 bytes + incl_len (at 8).
    let (a, b, c) = (
        parts.join("lidar-b.pcap"),
        parts.join("lidar-a.pcap"),
        parts.join("lidar-c.pcap"),
    );
    cut(&dir.join("lidar.pcap"), 24, 16, 8, &[&a, &b, &c]);
    // Serial log: 16-byte header; records of 20 bytes + n (at 16).
    let logs = [parts.join("ins-000.vnlog"), parts.join("ins-001.vnlog")];
    cut(&dir.join("ins.vnlog"), 16, 20, 16, &[&logs[0], &logs[1]]);

    let one = calibrate(
        &dir,
        &[&dir.join("lidar.pcap")],
        &[&dir.join("ins.vnlog")],
        &dir.join("one.json"),
    );
    let many = calibrate(
        &dir,
        &[&parts.join("lidar-*.pcap")],
        &[&parts.join("ins-*.vnlog")],
        &dir.join("many.json"),
    );
    // The same parts named one by one, as an unquoted pattern reaches the command (the shell
    // expands it), in no particular order.
    let listed = calibrate(
        &dir,
        &[&c, &a, &b],
        &[&logs[0], &logs[1]],
        &dir.join("listed.json"),
    );
    assert_eq!(one["converged"], true);
    for key in [
        "boresight_deg",
        "lever_arm_m",
        "time_offset_s",
        "points_per_sphere",
    ] {
        assert_eq!(one[key], many[key], "{key}");
        assert_eq!(one[key], listed[key], "{key}");
    }
    assert_eq!(
        one["inputs"]["data_packets"], many["inputs"]["data_packets"],
        "every packet of the parts was read"
    );
    // A pattern that matches nothing is named.
    let out = common::spherecal()
        .arg("calibrate")
        .arg("--pcap")
        .arg(parts.join("nothing-*.pcap"))
        .arg("--ins")
        .arg(&logs[0])
        .arg("--site")
        .arg(dir.join("site.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("nothing-*.pcap: no file matches"));

    // The parts folder replayed as a rig's log folder: its captures in time order, its serial
    // logs in name order; every datagram sent, the serial bytes exactly the single log's.
    use spherecal_tools::pipeline::Files;
    use spherecal_tools::replay::{replay_both, Speed, Target};
    let sink = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = sink.local_addr().unwrap().port();
    let mut to = Target::host(std::net::Ipv4Addr::LOCALHOST);
    to.ports = [(2368, port), (8308, port), (5602, port)];
    let mut serial: Vec<u8> = Vec::new();
    let logs_pattern = Files::from(parts.join("*.vnlog"));
    let (udp, wrote) = replay_both(
        parts.clone(),
        to,
        Some((&logs_pattern, &mut serial, 921_600)),
        Speed::Max,
    )
    .unwrap();
    let (single, _) = spherecal_hal::serial::read_byte_file(&dir.join("ins.vnlog")).unwrap();
    assert_eq!(wrote, Some(single.len() as u64));
    assert!(serial == single, "the serial bytes in their order");
    let records = {
        let b = std::fs::read(dir.join("lidar.pcap")).unwrap();
        let (mut at, mut n) = (24, 0u64);
        while at + 16 <= b.len() {
            at += 16 + u32::from_le_bytes(b[at + 8..at + 12].try_into().unwrap()) as usize;
            n += 1;
        }
        n
    };
    assert_eq!(udp.sent + udp.skipped, records);
    assert_eq!(udp.sent, records);
}

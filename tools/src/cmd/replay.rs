//! `spherecal replay DIR | --pcap P --ins I ...`.

use super::{fail, parse_ports};
use crate::pipeline::Files;
use crate::replay::{replay_both, Speed, Target};
use std::path::PathBuf;
use std::process::ExitCode;

/// Play recorded files back: UDP datagrams to their ports, serial bytes to a device.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A folder: as `synth` writes it (lidar.pcap and ins.vnlog or ins.bin), or a rig's log
    /// folder (its `*.pcap` in time order and its `*.vnlog` in name order: the rotated pieces).
    pub dir: Option<PathBuf>,
    /// The capture(s) (instead of DIR): files, folders or patterns.
    #[arg(long, num_args = 1..)]
    pub pcap: Vec<PathBuf>,
    /// The serial bytes or logs (instead of DIR): files or patterns.
    #[arg(long, num_args = 1..)]
    pub ins: Vec<PathBuf>,
    /// A ROS 2 bag (instead of DIR): its VelodyneScan packets as datagrams, its VectorNav
    /// CommonGroups as the VN-200 binary frames they came from (to --serial).
    #[arg(long, conflicts_with_all = ["dir", "pcap", "ins"])]
    pub bag: Option<PathBuf>,
    /// The bag's topic of VelodyneScan messages (default: the only one).
    #[arg(long, requires = "bag")]
    pub lidar_topic: Option<String>,
    /// The bag's topic of CommonGroup messages (default: the only one).
    #[arg(long, requires = "bag")]
    pub ins_topic: Option<String>,
    /// Host to send the datagrams to.
    #[arg(long, default_value = "127.0.0.1")]
    pub udp: std::net::Ipv4Addr,
    /// Send the capture's data (2368) and position (8308) packets to these ports instead.
    #[arg(long, value_name = "DATA,POSITION", value_parser = parse_ports)]
    pub ports: Option<[u16; 2]>,
    /// Send a POS MV's groups (the capture's UDP 5602) to this port instead.
    #[arg(long, value_name = "PORT")]
    pub posmv_port: Option<u16>,
    /// Serial device to write the INS bytes to (none: the bytes are not replayed).
    #[arg(long)]
    pub serial: Option<String>,
    /// Baud rate of the serial device.
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// Speed: a factor of the recorded pacing (1 = real time) or max.
    #[arg(long, default_value = "1")]
    pub speed: Speed,
}

/// What a folder holds to replay: `synth`'s names, else a rig's logs.
fn folder(d: &std::path::Path) -> (Files, Option<Files>) {
    if d.join("lidar.pcap").exists() {
        // A serial log (with receive times) keeps the two streams in step; raw bytes go at the
        // baud rate's pace.
        let log = d.join("ins.vnlog");
        let ins = if log.exists() { log } else { d.join("ins.bin") };
        (d.join("lidar.pcap").into(), Some(ins.into()))
    } else {
        let logs = d.join("*.vnlog");
        let ins = crate::pipeline::expand_files(&logs)
            .ok()
            .map(|_| logs.into());
        (d.to_path_buf().into(), ins)
    }
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    let to = target(&a);
    if let Some(bag) = &a.bag {
        let mut port = match &a.serial {
            Some(dev) => match serialport::new(dev.as_str(), a.baud).open() {
                Ok(p) => Some(p),
                Err(e) => return fail("replay", format!("{dev}: {e}")),
            },
            None => None,
        };
        let topics = crate::replay::BagReplay {
            lidar_topic: a.lidar_topic.clone(),
            ins_topic: a.ins_topic.clone(),
        };
        let serial = port.as_mut().map(|p| p as &mut (dyn std::io::Write + Send));
        return match crate::replay::replay_bag(bag, &topics, to, serial, a.speed) {
            Ok((u, s)) => report(&a, u, s),
            Err(e) => fail("replay", e),
        };
    }
    let (pcap, ins) = match (&a.dir, a.pcap.is_empty()) {
        (_, false) => (
            Files::from(a.pcap.clone()),
            (!a.ins.is_empty()).then(|| Files::from(a.ins.clone())),
        ),
        (Some(d), true) => {
            let (p, i) = folder(d);
            (
                p,
                if a.ins.is_empty() {
                    i
                } else {
                    Some(Files::from(a.ins.clone()))
                },
            )
        }
        (None, true) => return fail("replay", "give DIR or --pcap"),
    };
    let mut port = match &a.serial {
        Some(dev) => match serialport::new(dev.as_str(), a.baud).open() {
            Ok(p) => Some(p),
            Err(e) => return fail("replay", format!("{dev}: {e}")),
        },
        None => None,
    };
    let serial_job = match (&mut port, &ins) {
        (Some(p), Some(i)) => Some((i, p as &mut (dyn std::io::Write + Send), a.baud)),
        _ => None,
    };
    match replay_both(&pcap, to, serial_job, a.speed) {
        Ok((u, s)) => report(&a, u, s),
        Err(e) => fail("replay", e),
    }
}

/// Where the datagrams go: the host, the ports mapped.
fn target(a: &Args) -> Target {
    let mut to = Target::host(a.udp);
    if let Some([d, p]) = a.ports {
        to.ports[0] = (2368, d);
        to.ports[1] = (8308, p);
    }
    if let Some(i) = a.posmv_port {
        to.ports[2] = (spherecal::posmv::REALTIME_PORT, i);
    }
    to
}

/// What was sent, said; exit 0.
fn report(a: &Args, u: crate::replay::UdpReplay, s: Option<u64>) -> ExitCode {
    sayln!(
        "sent {} datagrams to {} ({} records skipped)",
        u.sent,
        a.udp,
        u.skipped
    );
    if let Some(n) = s {
        sayln!(
            "wrote {n} bytes to {}",
            a.serial.as_deref().unwrap_or_default()
        );
    }
    ExitCode::SUCCESS
}

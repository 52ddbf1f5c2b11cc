//! `spherecal replay DIR | --pcap P --ins I ...`.

use super::{fail, parse_ports};
use crate::replay::{replay_both, Speed, Target};
use std::path::PathBuf;
use std::process::ExitCode;

/// Play recorded files back: UDP datagrams to their ports, serial bytes to a device.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A folder with lidar.pcap and ins.vnlog or ins.bin (as `synth` writes).
    pub dir: Option<PathBuf>,
    /// The capture (instead of DIR).
    #[arg(long)]
    pub pcap: Option<PathBuf>,
    /// The serial bytes or log (instead of DIR).
    #[arg(long)]
    pub ins: Option<PathBuf>,
    /// Host to send the datagrams to.
    #[arg(long, default_value = "127.0.0.1")]
    pub udp: std::net::Ipv4Addr,
    /// Send the capture's data (2368) and position (8308) packets to these ports instead.
    #[arg(long, value_name = "DATA,POSITION", value_parser = parse_ports)]
    pub ports: Option<[u16; 2]>,
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

/// Run it.
pub fn run(a: Args) -> ExitCode {
    let pcap = a
        .pcap
        .or_else(|| a.dir.as_ref().map(|d| d.join("lidar.pcap")));
    // A serial log (with receive times) keeps the two streams in step; raw bytes go at the
    // baud rate's pace.
    let ins = a.ins.or_else(|| {
        a.dir.as_ref().map(|d| {
            let log = d.join("ins.vnlog");
            if log.exists() {
                log
            } else {
                d.join("ins.bin")
            }
        })
    });
    let Some(pcap) = pcap else {
        return fail("replay", "give DIR or --pcap");
    };
    let mut to = Target::host(a.udp);
    if let Some([d, p]) = a.ports {
        to.ports = [(2368, d), (8308, p)];
    }
    let mut port = match &a.serial {
        Some(dev) => match serialport::new(dev.as_str(), a.baud).open() {
            Ok(p) => Some(p),
            Err(e) => return fail("replay", format!("{dev}: {e}")),
        },
        None => None,
    };
    let serial_job = match (&mut port, &ins) {
        (Some(p), Some(i)) => Some((i.as_path(), p as &mut (dyn std::io::Write + Send), a.baud)),
        _ => None,
    };
    match replay_both(&pcap, to, serial_job, a.speed) {
        Ok((u, s)) => {
            sayln!(
                "sent {} datagrams to {} ({} records skipped)",
                u.sent,
                a.udp,
                u.skipped
            );
            if let Some(n) = s {
                sayln!("wrote {n} bytes to {}", a.serial.unwrap_or_default());
            }
            ExitCode::SUCCESS
        }
        Err(e) => fail("replay", e),
    }
}

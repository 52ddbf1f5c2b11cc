//! `spherecal run --check`: for installation, whether the rig can start: the board (already
//! validated when loaded), its UDP ports free of other programs and bindable, the serial
//! device there and openable (with the permission fix in words), the log folder writable, the
//! console device openable. Nothing is acquired.

use super::RunOptions;
use spherecal_hal::udp::{bound_sockets, UdpSource};
use std::net::Ipv4Addr;
use std::time::Duration;

/// Each check in words: `Ok` lines passed, `Err` lines are problems.
pub fn check(opts: &RunOptions) -> Vec<Result<String, String>> {
    let b = &opts.board;
    let mut out = vec![Ok(format!("board {}: valid", b.name))];
    // The sensor's own file (a Hesai's corrections, an Ouster's metadata), read as `run` will.
    if let Some(p) = &b.lidar.metadata {
        out.push(match super::inputs::sensor_file(b) {
            Ok(Some(crate::pipeline::SensorFile::Ouster(m))) => Ok(format!(
                "lidar.metadata {p}: an Ouster {} (serial {}), {} beams, {}, lidar packets to UDP {}",
                m.product, m.serial, m.format.pixels, m.profile_name, m.lidar_port
            )),
            Ok(Some(crate::pipeline::SensorFile::Hesai(_))) => {
                Ok(format!("lidar.metadata {p}: a Hesai's angle corrections"))
            }
            Ok(None) => Ok(String::new()),
            Err(e) => Err(e.to_string()),
        });
    }
    let bind: Ipv4Addr = b.lidar.bind_addr.parse().unwrap_or(Ipv4Addr::UNSPECIFIED);
    let posmv = (b.ins.kind == "posmv").then_some(("POS MV", b.ins.udp_port));
    for (what, port) in [
        ("data", b.lidar.data_port),
        ("position", b.lidar.position_port),
    ]
    .into_iter()
    .chain(posmv)
    {
        // The rig binds with address reuse: another program on the port would share (and
        // take) the LiDAR's datagrams without an error, so look first.
        match bound_sockets(port) {
            Some(n) if n > 0 => out.push(Err(format!(
                "UDP {what} port {port}: already bound by another program ({n} socket{}): it would take the LiDAR's datagrams (close VeloView, another rig, or a second spherecal)",
                if n > 1 { "s" } else { "" }
            ))),
            _ => match UdpSource::bind(bind, port, Duration::from_millis(10)) {
                Ok(_) => out.push(Ok(format!("UDP {what} port {port} on {bind}: free, bound"))),
                Err(e) => out.push(Err(format!("UDP {what} port {port} on {bind}: {e}"))),
            },
        }
    }
    if b.ins.kind == "vn200" {
        let dev = opts
            .serial
            .clone()
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| b.ins.serial.clone());
        out.push(serial(&dev, b.ins.baud));
    }
    let dir = opts
        .log_dir
        .clone()
        .unwrap_or_else(|| std::path::PathBuf::from(&b.log.dir));
    out.push(log_folder(&dir));
    if b.console.device != "stdout" {
        out.push(
            serialport::new(b.console.device.as_str(), b.console.baud)
                .open()
                .map(|_| format!("console {}: opens", b.console.device))
                .map_err(|e| format!("console {}: {e}", b.console.device)),
        );
    }
    if let Some(s) = &opts.site {
        out.push(Ok(format!("site: {} spheres", s.sphere.len())));
    }
    out
}

/// The log folder can be written, creating nothing: an existing folder is tried with a probe
/// file (removed), a missing one is said to be created by the run if its nearest existing
/// ancestor takes a new folder (tried by creating and removing a probe file there).
fn log_folder(dir: &std::path::Path) -> Result<String, String> {
    let try_write = |d: &std::path::Path| {
        let probe = d.join(".spherecal-check");
        std::fs::write(&probe, b"check").and_then(|()| std::fs::remove_file(&probe))
    };
    if dir.is_dir() {
        return try_write(dir)
            .map(|()| format!("log folder {}: writable", dir.display()))
            .map_err(|e| format!("log folder {}: not writable: {e}", dir.display()));
    }
    if dir.exists() {
        return Err(format!(
            "log folder {}: exists and is not a folder",
            dir.display()
        ));
    }
    let mut up = dir.parent();
    while let Some(a) = up {
        let a = if a.as_os_str().is_empty() {
            std::path::Path::new(".")
        } else {
            a
        };
        if a.is_dir() {
            return try_write(a)
                .map(|()| {
                    format!(
                        "log folder {}: does not exist yet, the run will create it in {}",
                        dir.display(),
                        a.display()
                    )
                })
                .map_err(|e| {
                    format!(
                        "log folder {}: cannot be created, {} is not writable: {e}",
                        dir.display(),
                        a.display()
                    )
                });
        }
        if a.exists() {
            return Err(format!(
                "log folder {}: cannot be created: {} is not a folder",
                dir.display(),
                a.display()
            ));
        }
        up = a.parent();
    }
    Err(format!(
        "log folder {}: no existing folder above it",
        dir.display()
    ))
}

/// The serial device opens at `baud`; a permission problem says how to fix it.
fn serial(dev: &str, baud: u32) -> Result<String, String> {
    if dev.is_empty() {
        return Err("serial: the board's ins.serial is empty and no --serial given".into());
    }
    match serialport::new(dev, baud).open() {
        Ok(_) => Ok(format!("serial {dev}: opens at {baud} baud")),
        Err(e) => {
            let denied = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .open(dev)
                .err()
                .is_some_and(|e| e.kind() == std::io::ErrorKind::PermissionDenied);
            Err(if denied {
                format!(
                    "serial {dev}: permission denied: add the rig's user to the dialout group (sudo usermod -aG dialout USER, then log in again) or install deploy/99-spherecal-vn200.rules"
                )
            } else if !std::path::Path::new(dev).exists() {
                format!("serial {dev}: no such device (is the USB adapter plugged in? ls /dev/serial/by-id/)")
            } else {
                format!("serial {dev}: {e}")
            })
        }
    }
}

//! What the rig opens and plans before its threads start: the sockets, the serial port and
//! the raw logs from the board ([`RigIo`]), the site's targets and the solver's settings
//! ([`Plan`]), and the rings between the threads ([`Rings`]).

use super::logger::RawLog;
use super::{
    parse_addr, stamp_now, RunOptions, SerialChunk, UdpLogItem, DATA_LOG_RING, DATA_RING,
    POSITION_RING, POSMV_LOG_RING, READ_TIMEOUT, SERIAL_LOG_RING,
};
use crate::pipeline::{targets, Accept, InsItem, LidarItem, SensorFile, INS_RING};
use heapless::spsc::Queue;
use spherecal::align::window::Target;
use spherecal::calib::Settings;
use spherecal::frames::LocalFrame;
use spherecal::georef::Params;
use spherecal_hal::rawlog::{McapLog, PcapLog, SerialLog};
use spherecal_hal::serial::SerialSource;
use spherecal_hal::udp::UdpSource;
use spherecal_hal::velodyne::Ports;
use std::net::Ipv4Addr;
use std::path::PathBuf;

/// The rig's inputs and raw logs, opened from the board (and the command line's overrides).
pub(super) struct RigIo {
    pub(super) accept: Accept,
    pub(super) bind: Ipv4Addr,
    pub(super) data_sock: UdpSource,
    pub(super) pos_sock: UdpSource,
    pub(super) serial: Option<(String, SerialSource)>,
    /// A POS MV's Real-Time Data Port (`ins.kind = "posmv"`).
    pub(super) posmv: Option<UdpSource>,
    pub(super) log_dir: PathBuf,
    /// The UTC start stamp that names the run's files.
    pub(super) stamp: String,
    pub(super) raw_log: RawLog,
    /// Bytes that waited in the serial port from before the run (discarded at open).
    pub(super) stale_serial_bytes: u64,
    /// The board's sensor file (a Hesai's or an Ouster's).
    pub(super) sensor: Option<SensorFile>,
}

impl RigIo {
    pub(super) fn open(opts: &RunOptions) -> Result<Self, crate::Error> {
        let b = &opts.board;
        let sensor_file = sensor_file(b)?;
        let bind = parse_addr(&b.lidar.bind_addr, "lidar.bind_addr")?;
        // Only the sensor's datagrams are aligned (all are logged); 0.0.0.0 accepts any sender.
        let sensor = Some(parse_addr(&b.lidar.sensor_addr, "lidar.sensor_addr")?)
            .filter(|a| !a.is_unspecified());
        let ports = Ports {
            data: b.lidar.data_port,
            position: b.lidar.position_port,
        };
        let bind_port = |port: u16| {
            UdpSource::bind(bind, port, READ_TIMEOUT).map_err(|e| format!("UDP {bind}:{port}: {e}"))
        };
        let (data_sock, pos_sock) = (bind_port(ports.data)?, bind_port(ports.position)?);
        let mut stale = 0u32;
        let serial = match b.ins.kind.as_str() {
            "vn200" => {
                let dev = opts
                    .serial
                    .clone()
                    .filter(|s| !s.is_empty())
                    .or_else(|| Some(b.ins.serial.clone()).filter(|s| !s.is_empty()))
                    .ok_or("board: ins.serial is empty: give --serial DEV")?;
                let mut src = SerialSource::open(&dev, b.ins.baud, READ_TIMEOUT)
                    .map_err(|e| format!("serial {dev}: {e}"))?;
                // What an earlier session left in the port is not this run's stream.
                stale = src.discard_pending().unwrap_or(0);
                Some((dev, src))
            }
            _ => None,
        };
        let posmv = match b.ins.kind.as_str() {
            "posmv" => Some(bind_port(b.ins.udp_port)?),
            _ => None,
        };
        let log_dir = opts
            .log_dir
            .clone()
            .unwrap_or_else(|| PathBuf::from(&b.log.dir));
        std::fs::create_dir_all(&log_dir).map_err(|e| format!("{}: {e}", log_dir.display()))?;
        let stamp = stamp_now();
        let rotate = opts
            .rotate_bytes
            .unwrap_or(b.log.rotate_mb.saturating_mul(1 << 20));
        let raw = |e: std::io::Error| format!("raw log: {e}");
        let raw_log = match b.log.format {
            crate::config::board::LogFormat::Mcap => RawLog::Mcap(Box::new(
                McapLog::create(
                    &log_dir,
                    &format!("{stamp}-log"),
                    rotate,
                    b.lidar.data_port,
                    b.ins.baud,
                )
                .map_err(raw)?,
            )),
            crate::config::board::LogFormat::Pcap => RawLog::Files {
                pcap: Box::new(
                    PcapLog::create_pcap(&log_dir, &format!("{stamp}-lidar"), rotate)
                        .map_err(raw)?,
                ),
                serial: match &serial {
                    Some(_) => Some(Box::new(
                        SerialLog::create_vnlog(
                            &log_dir,
                            &format!("{stamp}-ins"),
                            rotate,
                            b.ins.baud,
                        )
                        .map_err(raw)?,
                    )),
                    None => None,
                },
            },
        };
        Ok(Self {
            accept: Accept {
                ports,
                sensor,
                hesai: matches!(sensor_file, Some(SensorFile::Hesai(_))),
            },
            bind,
            data_sock,
            pos_sock,
            serial,
            posmv,
            log_dir,
            stamp,
            raw_log,
            stale_serial_bytes: u64::from(stale),
            sensor: sensor_file,
        })
    }
}

/// What the aligner and the solver take from the site and the board.
pub(super) struct Plan {
    pub(super) frame: LocalFrame,
    pub(super) targets: Vec<Target>,
    pub(super) ids: Vec<String>,
    pub(super) margin: f64,
    /// The solver's settings: the site's noise and margin, the board's LiDAR model
    /// ([`crate::session::settings_for`], as `calibrate` builds them).
    pub(super) settings: Settings,
    /// Where the navigation model in `settings` came from.
    pub(super) nav_source: String,
    /// The board's a-priori mounting.
    pub(super) b0: Params,
    /// The board's expected VN-200 outputs as Common-group bits (the core's field table).
    pub(super) expected: Vec<(String, spherecal::vn200::Group, u8)>,
}

impl Plan {
    /// The plan for `opts` (`sensor`: the board's sensor file).
    pub(super) fn new(opts: &RunOptions, sensor: Option<&SensorFile>) -> Self {
        let b = &opts.board;
        let (frame, targets, ids, margin) = match &opts.site {
            Some(site) => {
                let (frame, t) = targets(site);
                let ids = site.sphere.iter().map(|s| s.id.clone()).collect();
                (frame, t, ids, site.apriori.window_margin_m)
            }
            None => (
                LocalFrame::new(spherecal::frames::Geodetic::from_deg(0.0, 0.0, 0.0)),
                Vec::new(),
                Vec::new(),
                0.0,
            ),
        };
        let expected: Vec<(String, spherecal::vn200::Group, u8)> = b
            .ins
            .output_bits()
            .into_iter()
            .map(|(n, g, bit)| (n.to_string(), g, bit))
            .collect();
        // The navigation model: the site's, else the board's, else the INS kind's default
        // (both checked when loaded).
        let site_spec = opts
            .site
            .as_ref()
            .and_then(|s| s.ins.as_ref())
            .map(|i| &i.correlated);
        let nav = crate::config::nav_source::choose(
            site_spec,
            Some(&b.ins.correlated),
            None,
            b.ins.nav_kind(),
        )
        .unwrap_or_else(|e| crate::config::nav_source::NavChoice {
            model: None,
            source: e.to_string(),
        });
        let settings = match &opts.site {
            Some(site) => crate::session::settings_under(
                site,
                sensor.map_or_else(
                    || {
                        b.lidar_model()
                            .map_or_else(Default::default, crate::config::lidar::Lidar::velodyne)
                    },
                    SensorFile::lidar,
                ),
                true,
                margin,
                nav.model,
            ),
            None => Settings::default(),
        };
        Self {
            frame,
            targets,
            ids,
            margin,
            settings,
            nav_source: nav.source,
            b0: b.mount.deg_m().params(),
            expected,
        }
    }
}

/// The rings between the threads (boxed: they are large).
pub(super) struct Rings {
    pub(super) data: Box<Queue<LidarItem, DATA_RING>>,
    pub(super) pos: Box<Queue<LidarItem, POSITION_RING>>,
    pub(super) ins: Box<Queue<InsItem, INS_RING>>,
    pub(super) data_log: Box<Queue<UdpLogItem, DATA_LOG_RING>>,
    pub(super) pos_log: Box<Queue<UdpLogItem, POSITION_RING>>,
    pub(super) posmv_log: Box<Queue<UdpLogItem, POSMV_LOG_RING>>,
    pub(super) serial_log: Box<Queue<SerialChunk, SERIAL_LOG_RING>>,
}

impl Rings {
    pub(super) fn new() -> Self {
        Self {
            data: Box::new(Queue::new()),
            pos: Box::new(Queue::new()),
            ins: Box::new(Queue::new()),
            data_log: Box::new(Queue::new()),
            pos_log: Box::new(Queue::new()),
            posmv_log: Box::new(Queue::new()),
            serial_log: Box::new(Queue::new()),
        }
    }
}

/// The sensor file a board names (`[lidar] metadata`: a Hesai's angle corrections or an
/// Ouster's metadata); `None` for a Velodyne. An Ouster's lidar port must be the board's data
/// port.
pub fn sensor_file(b: &crate::config::board::Board) -> Result<Option<SensorFile>, crate::Error> {
    let Some(p) = b.lidar.metadata.as_deref() else {
        return Ok(None);
    };
    let f = SensorFile::load(std::path::Path::new(p))
        .map_err(|e| crate::Error::bad_input(format!("board: lidar.metadata: {e}")))?;
    if let SensorFile::Ouster(m) = &f {
        if m.lidar_port != b.lidar.data_port {
            return Err(crate::Error::bad_input(format!(
                "board: lidar.data_port = {} but the Ouster's metadata ({p}) sends its lidar packets to UDP {}: set data_port = {}",
                b.lidar.data_port, m.lidar_port, m.lidar_port
            )));
        }
    }
    Ok(Some(f))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::board::Board;

    fn board_with(metadata: &str, data_port: u16) -> Board {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../boards/rig-os1-64.toml"
        ))
        .unwrap()
        .replace("\"os1-64.json\"", &format!("{metadata:?}"))
        .replace("data_port = 7502", &format!("data_port = {data_port}"));
        Board::from_toml(&text).unwrap()
    }

    /// An Ouster's board: its metadata read (the sensor file), the lidar port checked against
    /// the board's data port; a missing file and a broken one named.
    #[test]
    fn an_ousters_board_names_its_metadata_and_port() {
        let meta = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../tests/data/ouster/OS-0-32-U1_v2.2.0_1024x10.json"
        );
        let Ok(Some(SensorFile::Ouster(m))) = sensor_file(&board_with(meta, 7502)) else {
            panic!("not read as an Ouster's metadata");
        };
        assert_eq!((m.lidar_port, m.format.pixels), (7502, 32));
        let e = sensor_file(&board_with(meta, 2368))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("lidar.data_port = 2368") && e.contains("set data_port = 7502"),
            "{e}"
        );
        let e = sensor_file(&board_with("/nonexistent/os1.json", 7502))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("board: lidar.metadata: /nonexistent/os1.json"),
            "{e}"
        );
        let dir = std::env::temp_dir().join(format!("spherecal-inputs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let broken = dir.join("broken.json");
        std::fs::write(&broken, "{\"beam_intrinsics\": 3}").unwrap();
        let e = sensor_file(&board_with(broken.to_str().unwrap(), 7502))
            .err()
            .unwrap()
            .to_string();
        assert!(e.starts_with("board: lidar.metadata: "), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

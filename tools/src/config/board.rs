//! `boards/*.toml`: one file per rig (docs/REFERENCE.md "Boards"). Unknown keys and impossible values are
//! refused with the key's name.

use serde::{Deserialize, Serialize};
use std::net::Ipv4Addr;

/// LiDAR network settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LidarNet {
    /// Address to bind on this computer: `0.0.0.0` (the default) receives the LiDAR's
    /// broadcast (a factory VLP-16 sends to 255.255.255.255) and unicast datagrams alike; one
    /// unicast address receives only datagrams sent to it.
    #[serde(default = "any_address")]
    pub bind_addr: String,
    /// The sensor's address.
    pub sensor_addr: String,
    /// Data packets' UDP port.
    pub data_port: u16,
    /// Position packets' UDP port.
    pub position_port: u16,
    /// The sensor model (`vlp16`, `puck-hires`, `hdl32e`, `vlp32c`); absent: as its data
    /// packets' product byte says, checked against their period.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
    /// A Hesai's angle correction file (CSV; a path from the working directory): the sensor is
    /// that Hesai (PandarXT16 / XT32 / QT64 / QT128), its data packets on `data_port` and its
    /// GPS packets on `position_port` (the unit's defaults: 2368 and 10110); no `model` then.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metadata: Option<String>,
}

fn any_address() -> String {
    "0.0.0.0".into()
}

/// The INS link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InsLink {
    /// `vn200` (live serial), `posmv` (an Applanix POS MV's real-time groups over UDP) or
    /// `sbet` (trajectory processed afterwards).
    pub kind: String,
    /// Serial device (`vn200`; empty: given on the command line).
    #[serde(default)]
    pub serial: String,
    /// Baud rate (`vn200`).
    #[serde(default)]
    pub baud: u32,
    /// Output rate [Hz].
    pub rate_hz: f64,
    /// Binary output fields expected (Common group names).
    #[serde(default)]
    pub fields: Vec<String>,
    /// The rig configures the VN-200 at the start (binary output register 75 from `fields`
    /// and `rate_hz` on `port`, ASCII async output off); `false` leaves it as it is (a replay,
    /// or a unit configured by hand).
    #[serde(default = "yes")]
    pub configure: bool,
    /// The VN-200 serial port the rig is wired to (1 or 2).
    #[serde(default = "port_one")]
    pub port: u8,
    /// `posmv`: the UDP port its groups arrive on (the Real-Time Data Port, 5602, by default).
    #[serde(default = "posmv_port")]
    pub udp_port: u16,
    /// `posmv`: the group poses come from: 1 (vessel reference point), 102 or 103 (sensor 1/2).
    #[serde(default = "group_one")]
    pub posmv_group: u16,
    /// The datum of its positions (default WGS 84: a VN-200's, and a POS MV's unless its GNSS
    /// corrections come from another datum's base): the site is transformed into it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub datum: Option<String>,
    /// Its errors that wander (`[ins.correlated]`, as in the site; the site's wins): the
    /// rig's solves estimate under this model. Absent: the default for `kind`
    /// (`nav_source::InsKind::default_preset`).
    #[serde(default, skip_serializing_if = "is_undeclared")]
    pub correlated: super::nav_errors::CorrelatedSpec,
}

fn posmv_port() -> u16 {
    spherecal::posmv::REALTIME_PORT
}

fn group_one() -> u16 {
    1
}

impl InsLink {
    /// The board's `fields` as (name, group, bit) of the core's field table: a bare name is
    /// a Common-group field, `Group.Field` another group's (`Attitude.YprU`, `Ins.PosU`; the
    /// group names of [`spherecal::vn200::Group::name`]). Unknown names are left out: the
    /// board's validation refuses them ([`output_bit`]).
    pub fn output_bits(&self) -> Vec<(&str, spherecal::vn200::Group, u8)> {
        self.fields
            .iter()
            .filter_map(|f| output_bit(f).map(|(g, b)| (f.as_str(), g, b)))
            .collect()
    }
}

/// One `ins.fields` entry's group and bit: `Field` (Common) or `Group.Field`.
pub fn output_bit(name: &str) -> Option<(spherecal::vn200::Group, u8)> {
    use spherecal::vn200::Group;
    let (g, field) = match name.split_once('.') {
        Some((g, f)) => (*Group::ALL.iter().find(|x| x.name() == g)?, f),
        None => (Group::Common, name),
    };
    let bit = g
        .fields()
        .iter()
        .position(|d| d.as_ref().is_some_and(|d| d.name == field))?;
    Some((g, bit as u8))
}

fn yes() -> bool {
    true
}

fn port_one() -> u8 {
    1
}

/// Status console.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Console {
    /// A serial device or `stdout`.
    pub device: String,
    /// Baud rate for a serial console.
    #[serde(default)]
    pub baud: u32,
}

/// Raw logging.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Log {
    /// Folder.
    pub dir: String,
    /// Rotate files at this size [MB].
    pub rotate_mb: u64,
    /// `pcap` (default: a pcap of the datagrams and a serial log) or `mcap` (one rosbag2
    /// folder of MCAP files: the data packets as VelodyneScan, the other datagrams and the
    /// serial reads as spherecal_msgs; Foxglove and `spherecal --bag` open it).
    #[serde(default)]
    pub format: LogFormat,
}

/// The raw log's file format.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LogFormat {
    /// pcap + serial log.
    #[default]
    Pcap,
    /// A rosbag2 folder of MCAP files.
    Mcap,
}

/// A board file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Board {
    /// Name.
    pub name: String,
    /// The vessel (or vehicle, aircraft) carrying it, for the report's cover sheet.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vessel: Option<String>,
    /// Who runs the survey, for the report's cover sheet (`calibrate --operator` overrides).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub operator: Option<String>,
    /// GPS - UTC [s].
    pub leap_seconds: i64,
    /// LiDAR network.
    pub lidar: LidarNet,
    /// INS link.
    pub ins: InsLink,
    /// Status console.
    pub console: Console,
    /// Raw logging.
    pub log: Log,
    /// A-priori mounting.
    pub mount: super::MountDegM,
    /// The accuracy wanted: the live verdict says `ready` when every sigma is within it
    /// (`target_sigma_deg`, `target_sigma_m`; defaults 0.01 deg, 5 mm).
    #[serde(default)]
    pub calibration: crate::config::goal::Targets,
}

fn is_undeclared(c: &super::nav_errors::CorrelatedSpec) -> bool {
    !c.is_declared()
}

impl InsLink {
    /// The kind of INS, for its default navigation model.
    pub fn nav_kind(&self) -> crate::config::nav_source::InsKind {
        match self.kind.as_str() {
            "posmv" => crate::config::nav_source::InsKind::PosmvRealTime,
            "sbet" => crate::config::nav_source::InsKind::Sbet,
            _ => crate::config::nav_source::InsKind::Vn200,
        }
    }
}

/// Standard serial rates (VN-200 register 5 allows these).
pub const BAUDS: [u32; 9] = [
    9600, 19200, 38400, 57600, 115_200, 128_000, 230_400, 460_800, 921_600,
];

/// Field names the simulated and real VN-200 Common group can carry.
pub const COMMON_FIELDS: [&str; 15] = [
    "TimeStartup",
    "TimeGps",
    "TimeSyncIn",
    "YawPitchRoll",
    "Quaternion",
    "AngularRate",
    "Position",
    "VelNed",
    "Accel",
    "Imu",
    "MagPres",
    "DeltaThetaVel",
    "InsStatus",
    "SyncInCnt",
    "TimeGpsPps",
];

impl Board {
    /// The LiDAR model the board names (None: from the packets).
    pub fn lidar_model(&self) -> Option<spherecal::velodyne::Model> {
        self.lidar
            .model
            .as_deref()
            .and_then(spherecal::velodyne::Model::parse)
    }

    /// Parse and check; errors name the key.
    pub fn from_toml(text: &str) -> Result<Self, crate::Error> {
        let b: Board = toml::from_str(text).map_err(|e| e.to_string().trim().to_string())?;
        b.check()?;
        Ok(b)
    }

    /// Read a board file.
    pub fn load(path: &std::path::Path) -> Result<Self, crate::Error> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::from_toml(&text).map_err(|e| format!("{}: {e}", path.display()).into())
    }

    /// `text` (a board file) with its `[mount]` set to `m`, written in full (the shortest
    /// decimals that read back to the same f64): only the values of `boresight_deg` and
    /// `lever_arm_m` change (added under `[mount]` if missing), and the `# set-mount:` comment
    /// lines under `[mount]` are replaced by `notes` (where the values came from); every other
    /// line, comment and the keys' own comments stay. The result is parsed back and must give
    /// `m` exactly.
    pub fn with_mount(
        text: &str,
        m: &super::MountDegM,
        notes: &[String],
    ) -> Result<String, crate::Error> {
        if m.boresight_deg
            .iter()
            .chain(&m.lever_arm_m)
            .any(|v| !v.is_finite())
        {
            return Err("[mount]: a value is not a number".into());
        }
        let arr = |v: [f64; 3]| format!("[{:?}, {:?}, {:?}]", v[0], v[1], v[2]);
        let want = [
            ("boresight_deg", arr(m.boresight_deg)),
            ("lever_arm_m", arr(m.lever_arm_m)),
        ];
        const NOTE: &str = "# set-mount: ";
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        let header = |l: &str| l.split('#').next().unwrap_or("").trim().to_string();
        let start = lines
            .iter()
            .position(|l| header(l) == "[mount]")
            .ok_or("no [mount] section")?;
        // The notes of an earlier set-mount go; the new ones follow the section's header.
        let mut i = start + 1;
        while i < lines.len() && !header(&lines[i]).starts_with('[') {
            if lines[i].trim_start().starts_with(NOTE) {
                lines.remove(i);
            } else {
                i += 1;
            }
        }
        for (k, n) in notes.iter().enumerate() {
            lines.insert(start + 1 + k, format!("{NOTE}{}", n.replace('\n', " ")));
        }
        let end = lines[start + 1..]
            .iter()
            .position(|l| header(l).starts_with('['))
            .map_or(lines.len(), |k| start + 1 + k);
        let mut missing = Vec::new();
        for (key, value) in &want {
            let at = (start + 1..end).find(|&i| {
                let code = header(&lines[i]);
                code.split('=').next().map(str::trim) == Some(key)
            });
            match at {
                Some(i) => {
                    let line = &lines[i];
                    let code_len = line.find('#').unwrap_or(line.len());
                    if !line[..code_len].contains(']') {
                        return Err(format!(
                            "[mount] {key}: its array spans lines; write it on one line first"
                        )
                        .into());
                    }
                    let indent = &line[..line.len() - line.trim_start().len()];
                    let comment = line[code_len..].to_string();
                    let gap = if comment.is_empty() { "" } else { "  " };
                    lines[i] = format!("{indent}{key} = {value}{gap}{comment}");
                }
                None => missing.push(format!("{key} = {value}")),
            }
        }
        for (k, l) in missing.into_iter().enumerate() {
            lines.insert(start + 1 + k, l);
        }
        let mut out = lines.join("\n");
        if text.ends_with('\n') {
            out.push('\n');
        }
        let b = Self::from_toml(&out)?;
        let back = b.mount.deg_m().0;
        let want6 = m.deg_m().0;
        if back != want6 {
            return Err("[mount] did not read back as written".into());
        }
        Ok(out)
    }

    fn check(&self) -> Result<(), crate::Error> {
        let bad = |k: &str, why: &str| Err(format!("{k}: {why}").into());
        if !(0..=100).contains(&self.leap_seconds) {
            return bad("leap_seconds", "expected 0..=100");
        }
        self.calibration.check("calibration")?;
        for (k, v) in [
            ("lidar.bind_addr", &self.lidar.bind_addr),
            ("lidar.sensor_addr", &self.lidar.sensor_addr),
        ] {
            if v.parse::<Ipv4Addr>().is_err() {
                return bad(k, "expected an IPv4 address");
            }
        }
        if self.lidar.metadata.is_some() && self.lidar.model.is_some() {
            return bad(
                "lidar.model",
                "a Hesai's or an Ouster's board names its sensor file (lidar.metadata), not a model",
            );
        }
        if self.lidar.metadata.is_some() && self.log.format == LogFormat::Mcap {
            return bad(
                "log.format",
                "a Hesai's or an Ouster's datagrams are logged as pcap (format = \"pcap\")",
            );
        }
        if let Some(m) = &self.lidar.model {
            if spherecal::velodyne::Model::parse(m).is_none() {
                return bad(
                    "lidar.model",
                    "expected vlp16, puck-hires, hdl32e or vlp32c (or no key: from the packets)",
                );
            }
        }
        if self.lidar.data_port == 0
            || self.lidar.position_port == 0
            || self.lidar.data_port == self.lidar.position_port
        {
            return bad("lidar.data_port", "ports must be non-zero and differ");
        }
        match self.ins.kind.as_str() {
            "vn200" => {
                if !BAUDS.contains(&self.ins.baud) {
                    return bad("ins.baud", "expected a VN-200 rate (9600 .. 921600)");
                }
                if let Some(f) = self.ins.fields.iter().find(|f| {
                    output_bit(f).is_none()
                        || (!f.contains('.') && !COMMON_FIELDS.contains(&f.as_str()))
                }) {
                    return bad(
                        "ins.fields",
                        &format!("unknown field {f:?} (a Common-group name, or Group.Field: Attitude.YprU, Ins.PosU)"),
                    );
                }
                for need in ["YawPitchRoll", "Position"] {
                    if !self.ins.fields.iter().any(|f| f == need) {
                        return bad("ins.fields", &format!("{need} is needed for a pose"));
                    }
                }
                if !self.ins.fields.iter().any(|f| f == "TimeGps") {
                    return bad("ins.fields", "TimeGps is needed to time the poses");
                }
                if !(1..=2).contains(&self.ins.port) {
                    return bad("ins.port", "expected the VN-200's serial port 1 or 2");
                }
                if spherecal::vn200::command::BinaryOutput::divisor_for(self.ins.rate_hz).is_none()
                {
                    return bad(
                        "ins.rate_hz",
                        "the VN-200 divides its 800 Hz: expected 800 / an integer (400, 200, 100, 50, 40 ...)",
                    );
                }
            }
            "posmv" => {
                if self.ins.udp_port == 0
                    || self.ins.udp_port == self.lidar.data_port
                    || self.ins.udp_port == self.lidar.position_port
                {
                    return bad(
                        "ins.udp_port",
                        "expected the POS MV's UDP port (5602), not the LiDAR's",
                    );
                }
                if ![1, 102, 103].contains(&self.ins.posmv_group) {
                    return bad("ins.posmv_group", "expected 1, 102 or 103");
                }
            }
            "sbet" => {}
            _ => return bad("ins.kind", "expected vn200, posmv or sbet"),
        }
        if !(1.0..=400.0).contains(&self.ins.rate_hz) {
            return bad("ins.rate_hz", "expected 1..=400");
        }
        self.ins.correlated.resolve("ins.correlated")?;
        if self.console.device != "stdout" && !BAUDS.contains(&self.console.baud) {
            return bad(
                "console.baud",
                "expected a standard rate for a serial console",
            );
        }
        if self.log.rotate_mb == 0 {
            return bad("log.rotate_mb", "expected > 0");
        }
        if !self
            .mount
            .boresight_deg
            .iter()
            .chain(&self.mount.lever_arm_m)
            .all(|x| x.is_finite())
        {
            return bad("mount", "not finite");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn board(name: &str) -> String {
        std::fs::read_to_string(format!(
            "{}/../boards/{name}.toml",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap()
    }

    /// `ins.fields` entries: a Common name bare, another group's as `Group.Field`, at the bits
    /// of the VN-200 manual's tables (Attitude YprU bit 8, INS PosU bit 9).
    #[test]
    fn group_qualified_fields() {
        use spherecal::vn200::Group;
        assert_eq!(output_bit("TimeGps"), Some((Group::Common, 1)));
        assert_eq!(output_bit("Attitude.YprU"), Some((Group::Attitude, 8)));
        assert_eq!(output_bit("Ins.PosU"), Some((Group::Ins, 9)));
        assert_eq!(output_bit("YprU"), None);
        assert_eq!(output_bit("Attitude.PosU"), None);
        assert_eq!(output_bit("Nope.YprU"), None);
    }

    /// The names a board may list are the core's Common-group field names, in bit order.
    #[test]
    fn field_names_are_the_cores() {
        let core: Vec<&str> = spherecal::vn200::fields::Group::Common
            .fields()
            .iter()
            .map(|d| d.as_ref().map_or("", |d| d.name))
            .collect();
        assert_eq!(core[..COMMON_FIELDS.len()], COMMON_FIELDS[..]);
    }

    #[test]
    fn the_boards_parse() {
        for n in ["rig-vn200", "rig-xt32", "rig-os1-64", "vessel-posmv", "sim"] {
            let b = Board::from_toml(&board(n)).unwrap_or_else(|e| panic!("{n}: {e}"));
            assert_eq!(b.name, n);
        }
        // A Hesai's board: its corrections, no model, pcap logs.
        let t = board("rig-xt32");
        for (from, to, key) in [
            ("[lidar]\n", "[lidar]\nmodel = \"vlp16\"\n", "lidar.model"),
            ("format = \"pcap\"", "format = \"mcap\"", "log.format"),
        ] {
            let e = Board::from_toml(&t.replacen(from, to, 1))
                .unwrap_err()
                .to_string();
            assert!(e.starts_with(key), "{e}");
        }
        assert!(Board::from_toml(&t).is_ok());
    }

    /// The `[calibration]` targets: NaN, infinite, zero and negative sigmas are refused by key
    /// (TOML reads `nan` and `-inf` as floats).
    #[test]
    fn targets_that_are_not_sigmas_are_refused_by_key() {
        let t = board("rig-vn200");
        for (v, key) in [
            (
                "target_sigma_deg = nan",
                "calibration.target_sigma_deg = NaN",
            ),
            ("target_sigma_m = -inf", "calibration.target_sigma_m = -inf"),
            ("target_sigma_m = 0.0", "calibration.target_sigma_m = 0"),
            (
                "target_sigma_deg = -0.01",
                "calibration.target_sigma_deg = -0.01",
            ),
        ] {
            let e = Board::from_toml(&t.replace("[calibration]", &format!("[calibration]\n{v}")))
                .unwrap_err()
                .to_string();
            assert_eq!(e, format!("{key}: expected a positive, finite sigma"));
        }
        let ok =
            Board::from_toml(&t.replace("[calibration]", "[calibration]\ntarget_sigma_deg = 0.02"));
        assert!(ok.is_ok(), "{ok:?}");
    }

    #[test]
    fn invalid_boards_are_named() {
        let t = board("rig-vn200");
        assert!(
            Board::from_toml(&t.replace("baud = 921600", "baud = 921600\nparity = 1"))
                .unwrap_err()
                .to_string()
                .contains("unknown field `parity`")
        );
        assert_eq!(
            Board::from_toml(&t.replace("baud = 921600", "baud = 1000"))
                .unwrap_err()
                .to_string(),
            "ins.baud: expected a VN-200 rate (9600 .. 921600)"
        );
        assert_eq!(
            Board::from_toml(&t.replace("position_port = 8308", "position_port = 2368"))
                .unwrap_err()
                .to_string(),
            "lidar.data_port: ports must be non-zero and differ"
        );
        assert_eq!(
            Board::from_toml(&t.replace("\"Position\", ", ""))
                .unwrap_err()
                .to_string(),
            "ins.fields: Position is needed for a pose"
        );
        assert_eq!(
            Board::from_toml(&t.replace("bind_addr = \"0.0.0.0\"", "bind_addr = \"lidar-host\""))
                .unwrap_err()
                .to_string(),
            "lidar.bind_addr: expected an IPv4 address"
        );
        // Without a bind address: any (broadcast and unicast).
        let b = Board::from_toml(&t.replace("bind_addr = \"0.0.0.0\"", "")).unwrap();
        assert_eq!(b.lidar.bind_addr, "0.0.0.0");
        assert_eq!(
            Board::from_toml(&t.replace("rate_hz = 200", "rate_hz = 300")).unwrap_err().to_string(),
            "ins.rate_hz: the VN-200 divides its 800 Hz: expected 800 / an integer (400, 200, 100, 50, 40 ...)"
        );
        assert_eq!(
            Board::from_toml(&t.replace("port = 1 ", "port = 3 "))
                .unwrap_err()
                .to_string(),
            "ins.port: expected the VN-200's serial port 1 or 2"
        );
        assert_eq!(
            Board::from_toml(&t.replace("kind = \"vn200\"", "kind = \"novatel\""))
                .unwrap_err()
                .to_string(),
            "ins.kind: expected vn200, posmv or sbet"
        );
        // The navigation model: the vessel's board declares one; a bad one is named.
        let v = Board::from_toml(&board("vessel-posmv")).unwrap();
        assert!(v.ins.correlated.is_declared());
        let c = crate::config::nav_source::choose(
            None,
            Some(&v.ins.correlated),
            None,
            v.ins.nav_kind(),
        )
        .unwrap();
        assert_eq!(c.model.unwrap().correlation_s, 30.0);
        assert!(
            c.source.starts_with("board [ins.correlated]"),
            "{}",
            c.source
        );
        let bad = format!("{t}\n[ins.correlated]\npreset = \"posmv-rtk\"\ncorrelation_s = -3\n");
        assert_eq!(
            Board::from_toml(&bad).unwrap_err().to_string(),
            "ins.correlated.correlation_s: expected a correlation time > 0 s (at most a day) with any sigma"
        );
    }

    /// Only the two values change; comments, other sections and order stay.
    #[test]
    fn mount_written_back_keeping_the_file() {
        let text = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../boards/rig-vn200.toml"),
        )
        .unwrap();
        let text = text.replace(
            "lever_arm_m = [1.5, -1.2, -1.4]",
            "lever_arm_m = [1.5, -1.2, -1.4]   # tape-measured 2026-05",
        );
        let m = crate::config::MountDegM {
            boresight_deg: [181.787123, -42.4231, 2.431],
            lever_arm_m: [1.31234, -1.2051, -1.759],
        };
        let out = Board::with_mount(&text, &m, &[]).unwrap();
        let (a, b): (Vec<&str>, Vec<&str>) = (text.lines().collect(), out.lines().collect());
        assert_eq!(a.len(), b.len());
        let changed: Vec<(&str, &str)> = a
            .iter()
            .zip(&b)
            .filter(|(x, y)| x != y)
            .map(|(x, y)| (*x, *y))
            .collect();
        assert_eq!(
            changed,
            [
                (
                    "boresight_deg = [180.0, -45.0, 0.0]",
                    "boresight_deg = [181.787123, -42.4231, 2.431]"
                ),
                (
                    "lever_arm_m = [1.5, -1.2, -1.4]   # tape-measured 2026-05",
                    "lever_arm_m = [1.31234, -1.2051, -1.759]  # tape-measured 2026-05"
                ),
            ]
        );
        assert_eq!(Board::from_toml(&out).unwrap().mount, m);
        // Missing keys are added under [mount]; no [mount] is an error.
        let bare = text.replace("boresight_deg = [180.0, -45.0, 0.0]\n", "");
        let out = Board::with_mount(&bare, &m, &[]).unwrap();
        assert_eq!(Board::from_toml(&out).unwrap().mount, m);
        assert!(Board::with_mount("leap_seconds = 18\n", &m, &[]).is_err());
        // Every digit kept (a value 1 ulp off reads back exactly), whole numbers as floats;
        // the notes replace the last set-mount's, nothing else moves.
        let fine = crate::config::MountDegM {
            boresight_deg: [181.78712345678912, -42.0, 1e-7],
            lever_arm_m: [f64::from_bits(1.3f64.to_bits() + 1), -1.2, 0.0],
        };
        let once = Board::with_mount(&text, &fine, &["a".into(), "b".into()]).unwrap();
        assert_eq!(Board::from_toml(&once).unwrap().mount, fine);
        assert!(once.contains("# set-mount: a\n# set-mount: b\n"), "{once}");
        let twice = Board::with_mount(&once, &m, &["c".into()]).unwrap();
        assert_eq!(twice.matches("# set-mount:").count(), 1, "{twice}");
        assert_eq!(twice.lines().count(), text.lines().count() + 1);
        let nan = crate::config::MountDegM {
            boresight_deg: [f64::NAN, 0.0, 0.0],
            ..m
        };
        assert!(Board::with_mount(&text, &nan, &[]).is_err());
    }
}

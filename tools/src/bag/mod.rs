//! ROS 2 bags as a survey's input (`--bag`, `spherecal bag info`): which topics spherecal
//! reads and why, found by message type ([`choose`]), and the sources over them
//! (spherecal_hal::rosbag): the Velodyne driver's `VelodyneScan` packets as the LiDAR capture,
//! the VectorNav driver's `CommonGroup` (with `InsGroup` PosU and `AttitudeGroup` YprU) as the
//! VN-200 stream (DESIGN.md "ROS 2 bags").

mod ins;

pub use ins::BagIns;
use spherecal_hal::rosbag::{Bag, TopicStats};
use std::fmt::Write as _;
use std::path::Path;

/// The Velodyne driver's raw packets.
pub const SCAN: &str = "velodyne_msgs/msg/VelodyneScan";
/// velodyne_pointcloud's points (read when no raw packets were recorded).
pub const CLOUD: &str = "sensor_msgs/msg/PointCloud2";
/// A Hesai's scans (tier4/nebula's `pandar_msgs`): read with `--metadata CORRECTIONS.csv`.
pub const PANDAR: &str = "pandar_msgs/msg/PandarScan";
/// An Ouster's packets (ouster-ros's `*/lidar_packets`; its `*/imu_packets` are the same
/// type): read with `--metadata META.json`.
pub const OUSTER: &str = crate::ouster::decode::PACKET_MSG;
/// spherecal's MCAP raw log: the datagrams that are not data packets ...
pub const DATAGRAM: &str = spherecal_hal::rawlog::mcap_log::DATAGRAM_TYPE;
/// ... and the serial reads.
pub const SERIAL: &str = spherecal_hal::rawlog::mcap_log::SERIAL_TYPE;
/// The VectorNav driver's Common group.
pub const COMMON: &str = "vectornav_msgs/msg/CommonGroup";
/// ... its INS group (PosU).
pub const INS: &str = "vectornav_msgs/msg/InsGroup";
/// The standard messages the VectorNav driver also publishes: the attitude quaternion ...
pub const IMU: &str = "sensor_msgs/msg/Imu";
/// ... the INS position and GNSS fix ...
pub const NAVSATFIX: &str = "sensor_msgs/msg/NavSatFix";
/// ... and the GPS time (`vectornav/time_gps`).
pub const TIMEREF: &str = "sensor_msgs/msg/TimeReference";
/// ... its Attitude group (YprU).
pub const ATTITUDE: &str = "vectornav_msgs/msg/AttitudeGroup";

/// Why a topic of a known type is not read.
fn not_read(type_name: &str) -> Option<&'static str> {
    Some(match type_name {
        CLOUD => {
            "points computed by the driver: read only when no VelodyneScan topic was recorded (the raw packets keep the sensor's clock and full precision)"
        }
        IMU | NAVSATFIX | TIMEREF => {
            "read as the trajectory only as Imu + NavSatFix + a TimeReference of GPS time (the VectorNav driver's /vectornav/imu, /vectornav/gnss, /vectornav/time_gps) and no CommonGroup; without the time reference there is no GPS time of the solution: refused (record vectornav_msgs/msg/CommonGroup, e.g. /vectornav/raw/common, or the time reference)"
        }
        "geometry_msgs/msg/PoseWithCovarianceStamped" => {
            "no GPS time of the solution and no INS mode: refused as a trajectory (record the VectorNav driver's vectornav_msgs/msg/CommonGroup, e.g. /vectornav/raw/common)"
        }
        "vectornav_msgs/msg/TimeGroup" | "vectornav_msgs/msg/GpsGroup" | "vectornav_msgs/msg/ImuGroup" => {
            "not needed (the CommonGroup holds the GPS time, attitude, position and INS status)"
        }
        "velodyne_msgs/msg/VelodynePacket" => "single packets without their scan: not read",
        OUSTER => {
            "an Ouster's packets: its */lidar_packets topic read with --metadata META.json (the sensor's metadata) when no VelodyneScan or PandarScan topic is chosen"
        }
        PANDAR => {
            "a Hesai's packets: read with --metadata CORRECTIONS.csv (the unit's angle correction file) when no VelodyneScan topic is chosen"
        }
        _ => return None,
    })
}

/// The topics a calibration reads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Chosen {
    /// The LiDAR's scans (or point clouds), and why this topic.
    pub lidar: Option<(String, String)>,
    /// The LiDAR topic holds point clouds, not packets.
    pub lidar_cloud: bool,
    /// The LiDAR topic holds a Hesai's scans (`PandarScan`).
    pub lidar_pandar: bool,
    /// The LiDAR topic holds an Ouster's lidar packets (`PacketMsg`).
    pub lidar_ouster: bool,
    /// The INS's Common group, and why.
    pub common: Option<(String, String)>,
    /// Its INS group (PosU), if recorded.
    pub ins: Option<String>,
    /// Its Attitude group (YprU), if recorded.
    pub attitude: Option<String>,
    /// An MCAP raw log's other datagrams (position packets ...), read with the scans.
    pub datagrams: Option<String>,
    /// An MCAP raw log's serial reads (the VN-200's own bytes): the INS, before any group.
    pub serial: Option<String>,
    /// Without a CommonGroup: the Imu, NavSatFix and TimeReference topics, when all three are
    /// there (one of each, or the VectorNav driver's `*/imu`, `*/time_gps`).
    pub nav: Option<[String; 3]>,
}

/// The one topic of `ty`, or the one of that type whose name ends with `/suffix`.
fn one_of(topics: &[TopicStats], ty: &str, suffix: &str) -> Option<String> {
    let v: Vec<&str> = topics
        .iter()
        .filter(|t| t.topic.type_name == ty)
        .map(|t| t.topic.name.as_str())
        .collect();
    match v.as_slice() {
        [one] => Some(one.to_string()),
        many => many
            .iter()
            .find(|n| n.ends_with(&format!("/{suffix}")))
            .map(|n| n.to_string()),
    }
}

/// The topic of `type_name`: the one named (checked to be of that type), else the only one of
/// that type. Err names what is there.
fn pick(
    topics: &[TopicStats],
    type_name: &str,
    named: Option<&str>,
    flag: &str,
) -> Result<Option<(String, String)>, crate::Error> {
    let listing = || {
        topics
            .iter()
            .map(|t| format!("{} ({})", t.topic.name, t.topic.type_name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Some(n) = named {
        let Some(t) = topics.iter().find(|t| t.topic.name == n) else {
            return Err(
                format!("{flag} {n}: no such topic in the bag; it has {}", listing()).into(),
            );
        };
        if t.topic.type_name != type_name {
            return Err(format!(
                "{flag} {n}: its messages are {}, not {type_name}",
                t.topic.type_name
            )
            .into());
        }
        return Ok(Some((n.to_string(), format!("named with {flag}"))));
    }
    let of: Vec<&TopicStats> = topics
        .iter()
        .filter(|t| t.topic.type_name == type_name)
        .collect();
    match of.as_slice() {
        [] => Ok(None),
        [one] => Ok(Some((
            one.topic.name.clone(),
            format!("the only {type_name} topic"),
        ))),
        many => Err(format!(
            "{} topics are {type_name} ({}): say which with {flag}",
            many.len(),
            many.iter()
                .map(|t| t.topic.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )
        .into()),
    }
}

/// The topics to read from a bag's `topics`: by type, or as named.
pub fn choose(
    topics: &[TopicStats],
    lidar_topic: Option<&str>,
    ins_topic: Option<&str>,
) -> Result<Chosen, crate::Error> {
    let only = |ty: &str| {
        let v: Vec<&TopicStats> = topics.iter().filter(|t| t.topic.type_name == ty).collect();
        (v.len() == 1).then(|| v[0].topic.name.clone())
    };
    let type_of = |n: &str| {
        topics
            .iter()
            .find(|t| t.topic.name == n)
            .map(|t| t.topic.type_name.as_str())
    };
    // Raw packets first (a Velodyne's, a Hesai's, an Ouster's lidar packets); a named topic
    // may be any.
    let ouster_lidar = || {
        let of: Vec<&TopicStats> = topics
            .iter()
            .filter(|t| t.topic.type_name == OUSTER)
            .collect();
        match of.as_slice() {
            [one] => Some(one.topic.name.clone()),
            _ => of
                .iter()
                .find(|t| t.topic.name.ends_with("lidar_packets"))
                .map(|t| t.topic.name.clone()),
        }
    };
    let (lidar_type, ouster) = match lidar_topic {
        Some(n) => match type_of(n) {
            Some(OUSTER) => (OUSTER, Some(n.to_string())),
            Some(t @ (CLOUD | PANDAR)) => (t, None),
            _ => (SCAN, None),
        },
        None if pick(topics, SCAN, None, "--lidar-topic")?.is_some() => (SCAN, None),
        None if pick(topics, PANDAR, None, "--lidar-topic")?.is_some() => (PANDAR, None),
        None => match ouster_lidar() {
            Some(n) => (OUSTER, Some(n)),
            None => (CLOUD, None),
        },
    };
    let (lidar_cloud, lidar_pandar) = (lidar_type == CLOUD, lidar_type == PANDAR);
    let serial = match ins_topic {
        Some(n) => (type_of(n) == Some(SERIAL)).then(|| n.to_string()),
        None => only(SERIAL),
    };
    let common = match ins_topic.map(type_of) {
        _ if serial.is_some() => None,
        Some(Some(IMU)) => None,
        _ => pick(topics, COMMON, ins_topic, "--ins-topic")?,
    };
    let nav = match (&common, ins_topic) {
        _ if serial.is_some() => None,
        (Some(_), _) => None,
        (None, named) => {
            let imu = named
                .map(String::from)
                .or_else(|| one_of(topics, IMU, "imu"));
            match (
                imu,
                one_of(topics, NAVSATFIX, "gnss"),
                one_of(topics, TIMEREF, "time_gps"),
            ) {
                (Some(i), Some(f), Some(r)) => Some([i, f, r]),
                _ => None,
            }
        }
    };
    Ok(Chosen {
        lidar: match ouster {
            Some(n) => Some((n, "ouster-ros's lidar packets".into())),
            None => pick(topics, lidar_type, lidar_topic, "--lidar-topic")?,
        },
        lidar_cloud,
        lidar_pandar,
        lidar_ouster: lidar_type == OUSTER,
        datagrams: (!lidar_cloud).then(|| only(DATAGRAM)).flatten(),
        serial,
        common,
        ins: only(INS),
        attitude: only(ATTITUDE),
        nav,
    })
}

/// A bag, opened, with its topics counted and the choice made.
pub struct Opened {
    /// The bag.
    pub bag: Bag,
    /// Its topics.
    pub topics: Vec<TopicStats>,
    /// What is read.
    pub chosen: Chosen,
}

/// Open `path` and choose its topics; `full` counts every topic's messages and span by
/// reading the whole bag (`bag info`), else only what the storage says without reading them.
pub fn open(
    path: &Path,
    lidar_topic: Option<&str>,
    ins_topic: Option<&str>,
    full: bool,
) -> Result<Opened, crate::Error> {
    let bag = Bag::open(path).map_err(|e| e.to_string())?;
    let topics = if full { bag.topics() } else { bag.topic_list() }.map_err(|e| e.to_string())?;
    let chosen = choose(&topics, lidar_topic, ins_topic)?;
    Ok(Opened {
        bag,
        topics,
        chosen,
    })
}

impl Opened {
    /// What a surveyor should know of the bag's own account of itself: no metadata.yaml (the
    /// files read by name), or a metadata.yaml that promises more messages than the files
    /// hold (a recording cut short, files missing).
    pub fn notes(&self) -> Vec<String> {
        let mut v = Vec::new();
        if self.bag.path.is_dir() && self.bag.metadata.is_none() {
            v.push(format!(
                "{}: no metadata.yaml: its .mcap / .db3 files are read in name order (`ros2 bag reindex` writes one)",
                self.bag.path.display()
            ));
        }
        let held: u64 = self.topics.iter().map(|t| t.count).sum();
        if let Some(n) = self
            .bag
            .metadata
            .as_ref()
            .and_then(|m| m.message_count)
            .filter(|&n| n > held)
        {
            v.push(format!(
                "WARNING: {}: its metadata.yaml promises {n} messages, the files hold {held} ({} missing: a recording cut short, or a file gone)",
                self.bag.path.display(),
                n - held
            ));
        }
        v
    }

    /// The LiDAR topic, or why there is none.
    pub fn lidar(&self) -> Result<&str, crate::Error> {
        self.chosen
            .lidar
            .as_ref()
            .map(|l| l.0.as_str())
            .ok_or_else(|| self.missing("LiDAR", &format!("{SCAN} or {CLOUD}")).into())
    }

    /// Whether the LiDAR topic holds point clouds.
    pub fn lidar_is_cloud(&self) -> bool {
        self.chosen.lidar.is_some() && self.chosen.lidar_cloud
    }

    /// The LiDAR source of a topic of point clouds: their returns, the rings read as `model`'s.
    pub fn clouds(
        &self,
        model: spherecal::velodyne::Model,
    ) -> Result<spherecal_hal::rosbag::clouds::CloudChunks, crate::Error> {
        let t = self.lidar()?;
        Ok(spherecal_hal::rosbag::clouds::CloudChunks::new(
            self.bag.messages(&[t]),
            model,
        ))
    }

    /// The INS topic, or why there is none.
    pub fn common(&self) -> Result<&str, crate::Error> {
        self.chosen
            .common
            .as_ref()
            .map(|l| l.0.as_str())
            .ok_or_else(|| self.missing("INS", COMMON).into())
    }

    fn missing(&self, what: &str, ty: &str) -> String {
        let mut o = format!(
            "{}: no {what} topic: no {ty} message in the bag",
            self.bag.path.display()
        );
        let why: Vec<String> = self
            .topics
            .iter()
            .filter_map(|t| {
                not_read(&t.topic.type_name)
                    .map(|w| format!("{} is {}: {w}", t.topic.name, t.topic.type_name))
            })
            .collect();
        if self.topics.is_empty() {
            o.push_str(" (it has no topic at all)");
        } else if !why.is_empty() {
            let _ = write!(o, "; {}", why.join("; "));
        } else {
            let _ = write!(
                o,
                "; its topics: {}",
                self.topics
                    .iter()
                    .map(|t| format!("{} ({})", t.topic.name, t.topic.type_name))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        o
    }

    /// The LiDAR source: the scans' packets.
    pub fn packets(&self) -> Result<spherecal_hal::rosbag::sources::ScanPackets, crate::Error> {
        let t = self.lidar()?;
        if self.chosen.lidar_pandar {
            return Ok(spherecal_hal::rosbag::sources::ScanPackets::pandar(
                self.bag.messages(&[t]),
            ));
        }
        if self.chosen.lidar_ouster {
            return Ok(spherecal_hal::rosbag::sources::ScanPackets::ouster(
                self.bag.messages(&[t]),
                spherecal::ouster::LIDAR_PORT,
            ));
        }
        Ok(match &self.chosen.datagrams {
            Some(d) => spherecal_hal::rosbag::sources::ScanPackets::with_datagrams(
                self.bag.messages(&[t, d]),
                Some(d),
            ),
            None => spherecal_hal::rosbag::sources::ScanPackets::new(self.bag.messages(&[t])),
        })
    }

    /// The INS source: the VN-200 frames the groups (or the Imu + NavSatFix + TimeReference)
    /// came from; `leap_seconds` turns a UTC time reference into GPS time.
    pub fn ins(&self, leap_seconds: i64) -> Result<BagIns, crate::Error> {
        if let Some(t) = &self.chosen.serial {
            return Ok(BagIns::Serial(
                spherecal_hal::rosbag::sources::SerialBytes::new(self.bag.messages(&[t])),
            ));
        }
        if let (None, Some([i, f, r])) = (&self.chosen.common, &self.chosen.nav) {
            return Ok(BagIns::Nav(spherecal_hal::rosbag::nav::NavBytes::new(
                self.bag.messages(&[i, f, r]),
                i,
                f,
                r,
                leap_seconds,
            )));
        }
        Ok(BagIns::Groups(self.vn200()?))
    }

    /// The VectorNav groups' source: the VN-200 frames they came from.
    pub fn vn200(&self) -> Result<spherecal_hal::rosbag::sources::Vn200Bytes, crate::Error> {
        let c = self.common()?;
        let mut want = vec![c];
        want.extend(self.chosen.ins.as_deref());
        want.extend(self.chosen.attitude.as_deref());
        Ok(spherecal_hal::rosbag::sources::Vn200Bytes::new(
            self.bag.messages(&want),
            c,
            self.chosen.ins.as_deref(),
            self.chosen.attitude.as_deref(),
        ))
    }

    /// `spherecal bag info`: the storage and files, each topic (type, messages, span, rate)
    /// and what spherecal reads of it and why.
    pub fn describe(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(
            o,
            "{}: rosbag2, {} storage, {} file(s){}",
            self.bag.path.display(),
            self.bag.storage(),
            self.bag.files.len(),
            if self.bag.metadata.is_some() {
                " (from its metadata.yaml)"
            } else {
                ""
            }
        );
        for (f, _) in &self.bag.files {
            let _ = writeln!(o, "  {}", f.display());
        }
        for n in self.notes() {
            let _ = writeln!(o, "{n}");
        }
        let span = self
            .topics
            .iter()
            .filter_map(|t| t.span)
            .fold(None, |a: Option<(i64, i64)>, b| {
                Some(a.map_or(b, |a| (a.0.min(b.0), a.1.max(b.1))))
            });
        if let Some((a, b)) = span {
            let _ = writeln!(
                o,
                "span: {:.3} s, from {} (log time, the recorder's clock)",
                (b - a) as f64 * 1e-9,
                utc(a)
            );
        }
        let _ = writeln!(o, "topics:");
        for t in &self.topics {
            let rate = t.span.filter(|s| s.1 > s.0 && t.count > 1).map(|s| {
                format!(
                    ", {:.1} Hz",
                    (t.count - 1) as f64 / ((s.1 - s.0) as f64 * 1e-9)
                )
            });
            let role = self.role(&t.topic.name, &t.topic.type_name);
            let _ = writeln!(
                o,
                "  {} ({}): {} messages{}\n    -> {role}",
                t.topic.name,
                t.topic.type_name,
                t.count,
                rate.unwrap_or_default()
            );
        }
        let _ = writeln!(
            o,
            "LiDAR: {}",
            match &self.chosen.lidar {
                Some((t, why)) if self.chosen.lidar_cloud => format!("{t} ({why}), velodyne_pointcloud's returns (x y z ring time); clock: the host's (the cloud's stamp plus each point's time), mapped to GPS time by the INS messages' stamps, the time offset estimated; lost against packets: the sensor's clock, the azimuth's precision (0.01 deg), returns inside the driver's min_range"),
                Some((t, why)) if self.chosen.lidar_ouster => format!("{t} ({why}), an Ouster's lidar packets (with --metadata META.json); clock: the column timestamps by the metadata's timestamp_mode"),
                Some((t, why)) if self.chosen.lidar_pandar => format!("{t} ({why}), a Hesai's packets (with --metadata CORRECTIONS.csv); clock: each packet's date-time and microseconds, its PPS lock unknown (the driver records no GPS packet), the time offset estimated"),
                Some((t, why)) if self.chosen.datagrams.is_some() => format!("{t} ({why}) with {} (spherecal's MCAP raw log); clock: from the logged position packets (PPS, RMC), as a capture's", self.chosen.datagrams.as_deref().unwrap_or("")),
                Some((t, why)) => format!("{t} ({why}); clock: PPS unknown (ROS 2 bag: the driver does not record the position packets), the hour from the INS's GPS time, the time offset estimated"),
                None => "none".into(),
            }
        );
        let _ = writeln!(
            o,
            "INS: {}",
            match &self.chosen.common {
                _ if self.chosen.serial.is_some() => format!(
                    "{} (spherecal's MCAP raw log: the serial reads as received, read as a serial log)",
                    self.chosen.serial.as_deref().unwrap_or("")
                ),
                Some((t, why)) => format!(
                    "{t} ({why}), as VN-200 binary frames{}",
                    match (&self.chosen.ins, &self.chosen.attitude) {
                        (Some(i), Some(a)) => format!("; the filter's sigmas from {i} (PosU) and {a} (YprU)"),
                        _ => "; no InsGroup PosU with AttitudeGroup YprU: the navigation model is the site's, else the VN-200's default".into(),
                    }
                ),
                None => match &self.chosen.nav {
                    Some([i, f, r]) => format!("{i} + {f} + {r} (sensor_msgs Imu + NavSatFix + TimeReference of GPS time, no CommonGroup), as VN-200 frames: quaternion, position, GPS time; no INS mode (tracking taken as the GNSS fix), no filter sigmas"),
                    None => "none".into(),
                },
            }
        );
        o
    }

    fn role(&self, name: &str, type_name: &str) -> String {
        let is = |c: &Option<(String, String)>| c.as_ref().is_some_and(|c| c.0 == name);
        if is(&self.chosen.lidar) {
            return if self.chosen.lidar_cloud {
                "read: the LiDAR's returns (point clouds)".into()
            } else {
                "read: the LiDAR's packets".into()
            };
        }
        if is(&self.chosen.common) {
            return "read: the INS's time, attitude, position and status".into();
        }
        if self.chosen.ins.as_deref() == Some(name) {
            return "read: the filter's position sigma (PosU)".into();
        }
        if self.chosen.attitude.as_deref() == Some(name) {
            return "read: the filter's attitude sigmas (YprU)".into();
        }
        if self.chosen.serial.as_deref() == Some(name) {
            return "read: the INS's serial bytes (VN-200 frames)".into();
        }
        if self.chosen.datagrams.as_deref() == Some(name) {
            return "read: the LiDAR's other datagrams (position packets: PPS, RMC)".into();
        }
        if let Some(k) = self
            .chosen
            .nav
            .as_ref()
            .and_then(|n| n.iter().position(|t| t == name))
        {
            return [
                "read: the INS attitude (quaternion)",
                "read: the INS position and the GNSS fix",
                "read: the GPS time of each stamp",
            ][k]
                .into();
        }
        if type_name == SCAN
            || type_name == COMMON
            || (type_name == PANDAR && self.chosen.lidar_pandar)
            || (type_name == CLOUD && self.chosen.lidar_cloud)
        {
            return "not read: another topic of this type was chosen".into();
        }
        not_read(type_name).map_or_else(
            || "not read: not a sensor spherecal uses".into(),
            String::from,
        )
    }
}

/// A log time [ns since the Unix epoch] as UTC.
fn utc(ns: i64) -> String {
    chrono::DateTime::from_timestamp(
        ns.div_euclid(1_000_000_000),
        ns.rem_euclid(1_000_000_000) as u32,
    )
    .map_or_else(
        || format!("{ns} ns"),
        |t| t.format("%Y-%m-%d %H:%M:%S%.3f UTC").to_string(),
    )
}

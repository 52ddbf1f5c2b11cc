//! What each LiDAR port hears, before any filtering: who sends, and what the packets say of the
//! sensor (product, return mode, rotation rate from the azimuth advance; PPS and RMC from the
//! position packets; a Hesai's data and GPS packets likewise; an Ouster's lidar packets in the
//! format its metadata gives, and its IMU packets). The rig says it in words a few seconds after
//! the start, and warns when a port is silent or another sender is talking: a factory VLP-16
//! broadcasts to 255.255.255.255, which a socket bound to one unicast address never receives.

use super::pps_name;
use serde::Serialize;
use spherecal::velodyne::{Detector, Identity, Model, PositionPacket, PpsStatus, ReturnMode};
use spherecal_hal::packet::{Datagram, HostTime};
use spherecal_hal::velodyne::{classify, Ports, Vlp16Packet};
use std::net::Ipv4Addr;

/// Senders told apart per port (more are counted together).
const MAX_SENDERS: usize = 8;

/// One port's hearing.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct Heard {
    /// The port.
    pub port: u16,
    /// Datagrams received (any sender, any content).
    pub datagrams: u64,
    /// Datagrams per sender address.
    pub senders: Vec<(Ipv4Addr, u64)>,
    /// Datagrams from further senders.
    pub other_senders: u64,
    /// Of them, VLP-16 packets of this port's kind (length and flags checked).
    pub packets: u64,
    /// The data packets' product byte, last seen.
    pub product: Option<u8>,
    /// Their return-mode byte, last seen.
    pub return_mode: Option<u8>,
    /// The position packets' PPS state, last seen.
    pub pps: Option<u8>,
    /// Their NMEA sentence: RMC (or GGA) valid, last seen (None: no sentence parsed).
    pub nmea_valid: Option<bool>,
    /// Rotation rate from the data packets' azimuth advance over their receive times [rpm].
    pub rpm: Option<f64>,
    /// What the data packets say of the model: product byte checked against their period.
    #[serde(skip)]
    pub identity: Option<Identity>,
    /// A Hesai's data packets: their model and return mode, last seen.
    #[serde(skip)]
    pub hesai: Option<(spherecal::hesai::Model, spherecal::hesai::ReturnMode)>,
    /// The Ouster's packet format and columns per frame (its metadata's), to know its
    /// lidar packets by.
    #[serde(skip)]
    pub ouster_format: Option<(spherecal::ouster::Format, u32)>,
    /// Lidar packets of that format heard.
    #[serde(skip)]
    pub ouster_packets: u64,
    /// This port is an Ouster's IMU port (its metadata's `udp_port_imu`): every datagram is
    /// taken as its IMU packet.
    #[serde(skip)]
    pub ouster_imu: bool,
    #[serde(skip)]
    spin: Spin,
    #[serde(skip)]
    detector: Detector,
}

/// The azimuth advance of consecutive data packets (first block), over host time.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Spin {
    first: Option<HostTime>,
    last: Option<(HostTime, u16)>,
    /// Total advance [0.01 deg].
    advance: u64,
}

impl Heard {
    /// A port's hearing, empty.
    pub fn new(port: u16) -> Self {
        Self {
            port,
            ..Self::default()
        }
    }

    /// One datagram received on this port (`ports`: which is data, which is position).
    pub fn see(&mut self, d: &Datagram<'_>, ports: Ports) {
        self.datagrams += 1;
        let full = self.senders.len() >= MAX_SENDERS;
        match self.senders.iter_mut().find(|s| s.0 == d.src_addr) {
            Some(s) => s.1 += 1,
            None if !full => self.senders.push((d.src_addr, 1)),
            None => self.other_senders += 1,
        }
        match classify(d, ports) {
            Ok(Vlp16Packet::Data { packet, .. }) => {
                self.packets += 1;
                self.product = Some(packet.product_raw());
                self.return_mode = Some(packet.return_mode_raw());
                self.turn(d.time, packet.azimuth_raw(0));
                self.identity = Some(self.detector.push(
                    packet.timestamp_us(),
                    packet.return_mode_raw(),
                    packet.product_raw(),
                ));
            }
            Ok(Vlp16Packet::Position { packet, .. }) => {
                self.packets += 1;
                self.position(&packet);
            }
            Err(_) if self.ouster_imu => self.packets += 1,
            Err(_) => match self.ouster_format {
                Some(f) => self.see_ouster(d, f),
                None => self.see_hesai(d),
            },
        }
    }

    /// An Ouster's lidar packet in format `f` of `w` columns per frame: the rate from the
    /// measurement id of its first valid column.
    fn see_ouster(&mut self, d: &Datagram<'_>, (f, w): (spherecal::ouster::Format, u32)) {
        let Ok(p) = spherecal::ouster::LidarPacket::new_checked(d.payload, f) else {
            return;
        };
        self.packets += 1;
        self.ouster_packets += 1;
        let first = p.columns().find(|c| c.valid()).map(|c| c.measurement_id());
        if let Some(m) = first {
            let az = u64::from(m) * 36_000 / u64::from(w.max(1));
            self.turn(d.time, u16::try_from(az).unwrap_or(u16::MAX));
        }
    }

    /// A Hesai's data or GPS packet (PPS lock: locked, else absent; its NMEA sentence).
    fn see_hesai(&mut self, d: &Datagram<'_>) {
        if let Ok(p) = spherecal::hesai::DataPacket::new_checked(d.payload) {
            self.packets += 1;
            self.hesai = Some((p.model(), p.return_mode()));
            self.turn(d.time, p.azimuth(0));
        } else if let Ok(g) = spherecal::hesai::GpsPacket::new_checked(d.payload) {
            self.packets += 1;
            let pps = match g.pps_locked() {
                true => PpsStatus::Locked,
                false => PpsStatus::Absent,
            };
            self.pps = Some(pps.to_byte());
            self.nmea_valid = g.nmea_time().map(|t| t.valid);
        }
    }

    fn position(&mut self, p: &PositionPacket<&[u8]>) {
        self.pps = Some(p.pps().to_byte());
        self.nmea_valid = p.nmea_time().ok().map(|t| t.valid);
    }

    /// The azimuth of a data packet's first block at `t`: the rate from the advance.
    fn turn(&mut self, t: HostTime, azimuth: u16) {
        let s = &mut self.spin;
        if azimuth >= 36_000 {
            return;
        }
        if let Some((_, a)) = s.last {
            // Forward, modulo a turn (a dropped packet or two still counts right).
            s.advance += u64::from((u32::from(azimuth) + 36_000 - u32::from(a)) % 36_000);
        } else {
            s.first = Some(t);
        }
        s.last = Some((t, azimuth));
        if let (Some(t0), Some((t1, _))) = (s.first, s.last) {
            let secs = t1.since(t0) as f64 * 1e-9;
            if secs > 0.5 {
                self.rpm = Some(s.advance as f64 / 36_000.0 / secs * 60.0);
            }
        }
    }

    /// The datagrams from `a`.
    pub fn from(&self, a: Ipv4Addr) -> u64 {
        self.senders.iter().find(|s| s.0 == a).map_or(0, |s| s.1)
    }

    /// What the port heard, in words, and the warnings: `what` names the port ("data",
    /// "position"), `sensor` the board's sensor address (None: any), `secs` since the first
    /// datagram, `data_heard` whether the data port hears the LiDAR.
    pub fn describe(
        &self,
        what: &str,
        sensor: Option<Ipv4Addr>,
        secs: f64,
        data_heard: bool,
    ) -> (String, Vec<String>) {
        let mut warn = Vec::new();
        let head = format!("{what} port {}", self.port);
        if self.datagrams == 0 && what == "position" && data_heard {
            // The LiDAR is there: its position packets go to another port.
            warn.push(format!(
                "{head}: silent for {secs:.0} s while the data port hears the LiDAR: check the board's position_port (a VLP-16 sends them to 8308 unless its web page says otherwise) and the firewall"
            ));
            return (format!("{head}: silent"), warn);
        }
        if self.datagrams == 0 {
            warn.push(format!(
                "{head}: silent for {secs:.0} s: no datagram arrives (check the cable and link, that the LiDAR's destination (web page: Host IP; factory 255.255.255.255) reaches this computer, and that nothing else holds the port)"
            ));
            return (format!("{head}: silent"), warn);
        }
        let senders: Vec<String> = self
            .senders
            .iter()
            .map(|(a, n)| format!("{n} from {a}"))
            .chain((self.other_senders > 0).then(|| format!("{} from others", self.other_senders)))
            .collect();
        let mut o = format!(
            "{head}: {} datagrams in {secs:.0} s ({})",
            self.datagrams,
            senders.join(", ")
        );
        if let Some(p) = self.product {
            let _ = std::fmt::Write::write_fmt(&mut o, format_args!(", {}", product_name(p)));
        }
        if let Some(m) = self.return_mode {
            let _ = std::fmt::Write::write_fmt(&mut o, format_args!(", {}", return_name(m)));
        }
        if let Some((m, r)) = self.hesai {
            let _ = std::fmt::Write::write_fmt(
                &mut o,
                format_args!(", Hesai {}, {} return", m.name(), r.name()),
            );
        }
        if self.ouster_packets > 0 {
            o.push_str(", Ouster lidar packets of its metadata's format");
        }
        if self.ouster_imu && self.packets > 0 {
            o.push_str(", Ouster IMU packets");
        }
        if let Some(r) = self.rpm {
            let _ = std::fmt::Write::write_fmt(&mut o, format_args!(", {r:.0} rpm"));
        }
        if let Some(p) = self.pps {
            let _ = std::fmt::Write::write_fmt(&mut o, format_args!(", PPS {}", pps_name(p)));
        }
        match self.nmea_valid {
            Some(true) => o.push_str(", NMEA valid"),
            Some(false) => o.push_str(", NMEA void (no GNSS fix at the LiDAR)"),
            None if what == "position" && self.packets > 0 && !self.ouster_imu => {
                o.push_str(", no NMEA sentence")
            }
            None => {}
        }
        if self.packets == 0 {
            warn.push(format!(
                "{head}: {} datagrams but none is a VLP-16 or Hesai {what} packet{} (wrong port? another device?)",
                self.datagrams,
                match self.ouster_format {
                    Some((f, _)) => format!(" nor an Ouster lidar packet of {} bytes", f.packet_len()),
                    None => String::new(),
                }
            ));
        }
        if let Some(s) = sensor {
            let mine = self.from(s);
            if mine == 0 {
                warn.push(format!(
                    "{head}: nothing from the board's sensor_addr {s}; {}: they are logged, not aligned (set lidar.sensor_addr, or 0.0.0.0 for any sender)",
                    senders.join(", ")
                ));
            } else if mine < self.datagrams {
                warn.push(format!(
                    "{head}: another sender is talking: {} of {} datagrams are not from {s} (logged, not aligned)",
                    self.datagrams - mine,
                    self.datagrams
                ));
            }
        }
        if let Some(identity @ (Identity::Unknown { .. } | Identity::Disagrees { .. })) =
            self.identity
        {
            let why = crate::decode::ModelError {
                identity,
                offset: 0,
            }
            .to_string()
            .replace("data packet at byte 0: ", "")
            .replace("data packets from byte 0: ", "");
            warn.push(format!(
                "{head}: {why}: its packets are not aligned unless the board's [lidar] model (or run --model) names the sensor"
            ));
        }
        if let Some(PpsStatus::Absent | PpsStatus::Error) = self.pps.map(PpsStatus::from) {
            warn.push(format!(
                "{head}: PPS {}: the LiDAR clock is not disciplined (check the GNSS receiver's PPS and NMEA wiring to the interface box)",
                pps_name(self.pps.unwrap_or(0))
            ));
        }
        if self.nmea_valid == Some(false) {
            warn.push(format!(
                "{head}: the NMEA sentence is void: the GNSS receiver feeding the LiDAR has no fix"
            ));
        }
        (o, warn)
    }
}

/// The product byte in words (VLP-16 manual, 9.3.2.3).
pub fn product_name(b: u8) -> String {
    match Model::from_product(b) {
        Some(Model::Vlp16) => "VLP-16 / Puck LITE (0x22)".into(),
        Some(Model::Hdl32e) => "HDL-32E or an early VLP-16 (0x21)".into(),
        Some(m) => format!("{} (0x{b:02X})", m.name()),
        None => format!("unknown product 0x{b:02X}"),
    }
}

/// The return-mode byte in words.
pub fn return_name(b: u8) -> String {
    match ReturnMode::from_byte(b).ok() {
        Some(ReturnMode::Strongest) => "strongest return".into(),
        Some(ReturnMode::Last) => "last return".into(),
        Some(ReturnMode::Dual) => "dual return".into(),
        None => format!("return mode 0x{b:02X}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spherecal::velodyne::DataPacket;

    fn data(az: u16, product: u8) -> Vec<u8> {
        let mut b = vec![0u8; 1206];
        for k in 0..12 {
            b[k * 100] = 0xFF;
            b[k * 100 + 1] = 0xEE;
        }
        let mut p = DataPacket::new_unchecked(&mut b[..]);
        for k in 0..12 {
            p.set_azimuth_raw(k, az);
        }
        p.set_return_mode(ReturnMode::Strongest);
        p.set_product_raw(product);
        b
    }

    /// `payload` from the test sensor's `port` to the same port, received at `t_ns`.
    fn datagram(port: u16, t_ns: i64, payload: &[u8]) -> Datagram<'_> {
        Datagram {
            time: HostTime(t_ns),
            src_addr: SENSOR,
            src_port: port,
            dst_port: port,
            payload,
            offset: 0,
        }
    }

    const SENSOR: Ipv4Addr = Ipv4Addr::new(192, 168, 1, 201);

    /// By hand: at 600 rpm (3600 deg/s) a packet every 1.327 ms advances 4.777 deg; 478
    /// hundredths a packet is 600.4 rpm.
    #[test]
    fn rate_sender_and_product() {
        let mut h = Heard::new(2368);
        let ports = Ports::default();
        let sensor = SENSOR;
        let mut az = 35_000u16;
        for k in 0..1000i64 {
            let payload = data(az, 0x22);
            h.see(&datagram(2368, k * 1_327_000, &payload), ports);
            az = (az + 478) % 36_000;
        }
        let rpm = h.rpm.unwrap();
        // 478 / 36000 turns per 1.327 ms = 600.4 rpm.
        assert!((rpm - 600.4).abs() < 0.5, "{rpm}");
        let (text, warn) = h.describe("data", Some(sensor), 3.0, true);
        assert!(text.contains("1000 from 192.168.1.201"), "{text}");
        assert!(text.contains("VLP-16") && text.contains("strongest") && text.contains("600 rpm"));
        assert!(warn.is_empty(), "{warn:?}");
        // Another sender, and the board's sensor silent.
        let (_, warn) = h.describe("data", Some("192.168.1.55".parse().unwrap()), 3.0, true);
        assert!(
            warn[0].contains("nothing from the board's sensor_addr 192.168.1.55"),
            "{warn:?}"
        );
        // A silent port.
        let (_, warn) = Heard::new(8308).describe("position", None, 3.0, false);
        assert!(
            warn[0].contains("position port 8308: silent for 3 s"),
            "{warn:?}"
        );
    }

    /// A Hesai's data and GPS packets: counted, named, the rate and the PPS lock read.
    #[test]
    fn a_hesais_packets() {
        let (ports, sensor) = (Ports::default(), SENSOR);
        let mut h = Heard::new(2368);
        for k in 0..2000u32 {
            let mut b = vec![0u8; spherecal::hesai::Model::Xt32.emitted_len()];
            let mut p = spherecal::hesai::DataPacket::emit(
                &mut b[..],
                spherecal::hesai::Model::Xt32,
                spherecal::hesai::ReturnMode::Single(0x37),
                k,
            )
            .unwrap();
            // 1.44 deg (8 firings of 0.18 deg) every 400 us: 600 rpm.
            p.set_azimuth(0, (k * 144 % 36_000) as u16);
            h.see(&datagram(2368, i64::from(k) * 400_000, &b), ports);
        }
        let (text, warn) = h.describe("data", Some(sensor), 3.0, true);
        assert!(
            text.contains("Hesai PandarXT32, strongest return, 600 rpm"),
            "{text}"
        );
        assert!(warn.is_empty(), "{warn:?}");
        let mut g = [0u8; 512];
        let utc = spherecal::time::UtcDateTime::from_unix_ns(1_718_189_966_000_000_000);
        spherecal::hesai::GpsPacket::emit(&mut g[..], &utc, b"", b'V', false).unwrap();
        let mut h = Heard::new(10110);
        h.see(&datagram(10110, 0, &g), ports);
        let (_, warn) = h.describe("position", Some(sensor), 3.0, true);
        assert!(warn.iter().any(|w| w.contains("PPS absent")), "{warn:?}");
    }

    /// An Ouster's lidar packets in its metadata's format (16 columns of 64 pixels, 1024
    /// columns a frame): counted, named, the rate from the measurement ids; another length is
    /// no packet of it; its IMU port as the board's position port heard as such.
    #[test]
    fn an_ousters_packets() {
        let (ports, sensor) = (Ports::default(), SENSOR);
        let f = spherecal::ouster::Format {
            profile: spherecal::ouster::Profile::Single,
            header: spherecal::ouster::HeaderKind::Standard,
            columns: 16,
            pixels: 64,
        };
        let mut h = Heard::new(7502);
        h.ouster_format = Some((f, 1024));
        for k in 0..1000u32 {
            let mut b = vec![0u8; f.packet_len()];
            let mut p = spherecal::ouster::LidarPacket::emit(&mut b[..], f, 0, 1, 2).unwrap();
            for c in 0..16 {
                // 10,240 columns a second: a packet every 1.5625 ms.
                p.set_column(c, 0, ((k * 16 + c as u32) % 1024) as u16);
            }
            h.see(&datagram(7502, i64::from(k) * 1_562_500, &b), ports);
        }
        let d = datagram(7502, 0, &[0u8; 1206]);
        h.see(&d, ports);
        let (text, warn) = h.describe("data", Some(sensor), 3.0, true);
        assert_eq!((h.ouster_packets, h.datagrams), (1000, 1001));
        assert!(
            text.contains("Ouster lidar packets of its metadata's format, 600 rpm"),
            "{text}"
        );
        assert!(warn.is_empty(), "{warn:?}");
        let mut h = Heard::new(7502);
        h.ouster_format = Some((f, 1024));
        h.see(&d, ports);
        let (_, warn) = h.describe("data", Some(sensor), 3.0, true);
        assert!(
            warn[0].contains("nor an Ouster lidar packet of 12544 bytes"),
            "{warn:?}"
        );
        // Its IMU port as the board's position port: its 48-byte packets heard as such.
        let mut h = Heard::new(7503);
        h.ouster_imu = true;
        h.see(&datagram(7503, 0, &[0u8; 48]), ports);
        let (text, warn) = h.describe("position", Some(sensor), 3.0, true);
        assert!(text.ends_with("Ouster IMU packets"), "{text}");
        assert!(warn.is_empty(), "{warn:?}");
    }
}

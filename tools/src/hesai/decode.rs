//! `spherecal decode CAPTURE --metadata CORRECTIONS.csv [--csv OUT]` for a Hesai: every data
//! packet of a capture (or a bag's `pandar_msgs/msg/PandarScan` topic) checked, counted and
//! listed one row per return, and the GPS packets' time and PPS lock.

use crate::decode::{each_record, push_fixed, push_padded, push_u64, Step, CSV_HEADER};
use spherecal::hesai::{Corrections, DataPacket, GpsPacket, Model, ReturnMode};
use spherecal_hal::pcap::PcapSource;
use spherecal_hal::velodyne::SkipStats;
use spherecal_hal::{PacketSource, Record, SkipReason};
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// The ROS 2 message of a Hesai's raw packets.
pub const PANDAR_SCAN: &str = "pandar_msgs/msg/PandarScan";

/// What a Hesai decode found.
#[derive(Debug, Default, Clone)]
pub struct HesaiSummary {
    /// The model of the first data packet, and its return mode.
    pub model: Option<(Model, ReturnMode)>,
    /// Data packets decoded.
    pub data_packets: u64,
    /// Data packets of another model than the first (not decoded).
    pub other_model: u64,
    /// Returns (distance > 0) listed: the firing's first block, its second (dual modes).
    pub returns: [u64; 2],
    /// Dual-mode returns identical to the other block's (the manual: one echo sent twice),
    /// listed once.
    pub identical: u64,
    /// Data packets whose date-time is not a date (their returns have no time).
    pub undated: u64,
    /// QT128 packets whose body and tail CRC-32 agree (a packet that disagrees is skipped).
    pub crc_agreed: u64,
    /// First and last packet time [ns since 1970 on the unit's clock].
    pub span_ns: Option<(i64, i64)>,
    /// Motor speed of the first packet [rpm].
    pub rpm: Option<u16>,
    /// GPS packets: all, those with the PPS locked, the first one's UTC second.
    pub gps: [u64; 2],
    /// The first GPS packet's date and time.
    pub gps_first: Option<String>,
    /// Everything skipped.
    pub skips: SkipStats,
    /// A file that stopped early: where and why.
    pub stopped: Option<String>,
}

impl HesaiSummary {
    /// The summary as printed.
    pub fn render(&self, path: &str, corrections: usize) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "file: {path}");
        match self.model {
            Some((m, mode)) => {
                let _ = writeln!(
                    o,
                    "sensor: Hesai {} ({} channels, {} blocks per packet), return mode {}, {} rpm; angle corrections for {corrections} channels",
                    m.name(),
                    m.channels(),
                    m.blocks(),
                    mode.name(),
                    self.rpm.unwrap_or(0)
                );
            }
            None => {
                let _ = writeln!(o, "sensor: no Hesai data packet");
            }
        }
        let _ = writeln!(
            o,
            "data packets: {}{}; GPS packets: {} ({} with the PPS locked)",
            self.data_packets,
            if self.other_model > 0 {
                format!(" ({} of another model, not decoded)", self.other_model)
            } else {
                String::new()
            },
            self.gps[0],
            self.gps[1]
        );
        let _ = writeln!(
            o,
            "points: {} (the firing's first block {}, second {}; {} dual returns identical to the other block listed once)",
            self.returns[0] + self.returns[1],
            self.returns[0],
            self.returns[1],
            self.identical
        );
        if let Some((a, b)) = self.span_ns {
            let _ = writeln!(o, "packet times: {} to {}", utc(a), utc(b));
        }
        let _ = writeln!(o, "clock: {}", self.clock());
        if self.crc_agreed > 0 {
            let _ = writeln!(o, "body and tail CRC-32: {} packets agree", self.crc_agreed);
        }
        if self.undated > 0 {
            let _ = writeln!(o, "packets whose date-time is not a date: {}", self.undated);
        }
        crate::decode::render_skips(&mut o, &self.skips, self.stopped.as_deref());
        o
    }

    /// What the GPS packets say of the unit's clock.
    pub fn clock(&self) -> String {
        match (self.gps, &self.gps_first) {
            ([0, _], _) => "no GPS packet: the date-time is the unit's own (PTP, or free-running from power-on); the capture cannot tell it is locked".into(),
            ([n, l], first) if l == n => format!(
                "GPS packets with the PPS locked ({n}, the first at {}): synchronised to GPS time via NMEA + PPS",
                first.as_deref().unwrap_or("?")
            ),
            ([n, l], _) => format!(
                "{} of {n} GPS packets without the PPS locked: the unit's clock was not (always) synchronised - an unlocked clock",
                n - l
            ),
        }
    }

    /// Why the capture does not go with its corrections: another channel count.
    pub fn mismatch(&self, c: &Corrections) -> Option<String> {
        let (m, _) = self.model?;
        (m.channels() != c.channels()).then(|| {
            format!(
                "the packets are a {}'s ({} channels), the angle correction file lists {}: decode with that unit's own file",
                m.name(),
                m.channels(),
                c.channels()
            )
        })
    }
}

/// `ns` since 1970 as a UTC date-time.
fn utc(ns: i64) -> String {
    chrono::DateTime::from_timestamp(
        ns.div_euclid(1_000_000_000),
        ns.rem_euclid(1_000_000_000) as u32,
    )
    .map_or(String::from("?"), |t| {
        t.format("%Y-%m-%dT%H:%M:%S%.6fZ").to_string()
    })
}

/// Decode the capture or bag at `path` (`topic`: the bag's PandarScan topic, else its only
/// one) with the unit's corrections `c`, listing returns into `csv`.
pub fn decode_file(
    path: &Path,
    topic: Option<&str>,
    c: &Corrections,
    csv: Option<&mut dyn Write>,
) -> Result<HesaiSummary, crate::Error> {
    let at =
        |e: &dyn std::fmt::Display| crate::Error::bad_input(format!("{}: {e}", path.display()));
    if spherecal_hal::rosbag::is_bag(path) {
        let bag = spherecal_hal::rosbag::Bag::open(path).map_err(|e| at(&e))?;
        let topics = bag.topic_list().map_err(|e| at(&e))?;
        let of: Vec<&str> = topics
            .iter()
            .filter(|t| t.topic.type_name == PANDAR_SCAN)
            .map(|t| t.topic.name.as_str())
            .filter(|n| topic.is_none_or(|want| want == *n))
            .collect();
        let name = match of.as_slice() {
            [one] => one.to_string(),
            [] => {
                return Err(at(&format!(
                    "no {PANDAR_SCAN} topic{}",
                    topic.map_or(String::new(), |t| format!(" named {t}"))
                )))
            }
            many => {
                return Err(at(&format!(
                    "{} topics of {PANDAR_SCAN} ({}): say which with --lidar-topic",
                    many.len(),
                    many.join(", ")
                )))
            }
        };
        let src = spherecal_hal::rosbag::sources::ScanPackets::pandar(bag.messages(&[&name]));
        return decode_source(src, c, csv).map_err(|e| at(&e));
    }
    let src = PcapSource::open(path).map_err(|e| at(&e))?;
    decode_source(src, c, csv).map_err(|e| at(&e))
}

/// The model of the first Hesai data packet among a capture's datagrams (a capture given
/// without its corrections), looking no further than its first 10,000 records.
pub fn sniff(path: &Path) -> Option<Model> {
    let mut src = PcapSource::open(path).ok()?;
    for _ in 0..10_000 {
        match src.next_record() {
            Ok(Some(Record::Udp(d))) if d.dst_port == spherecal::hesai::DATA_PORT => {
                if let Ok(p) = DataPacket::new_checked(d.payload) {
                    return Some(p.model());
                }
            }
            Ok(Some(_)) => {}
            _ => return None,
        }
    }
    None
}

/// [`decode_file`] over any packet source.
pub fn decode_source<S: PacketSource>(
    mut src: S,
    c: &Corrections,
    mut csv: Option<&mut dyn Write>,
) -> Result<HesaiSummary, std::io::Error> {
    let mut s = HesaiSummary::default();
    let mut line: Vec<u8> = Vec::with_capacity(1 << 16);
    if let Some(w) = csv.as_deref_mut() {
        writeln!(w, "{CSV_HEADER}")?;
    }
    let end = each_record(&mut src, |step| {
        let d = match step {
            Step::Skipped(offset, reason) => {
                s.skips.count(offset, &reason);
                return Ok(());
            }
            Step::Udp(d) => d,
        };
        if d.dst_port == spherecal::hesai::GPS_PORT {
            s.gps_packet(&d);
            return Ok(());
        }
        if d.dst_port != spherecal::hesai::DATA_PORT {
            s.skips.count(d.offset, &SkipReason::OtherPort(d.dst_port));
            return Ok(());
        }
        let p = match DataPacket::new_checked(d.payload) {
            Ok(p) => p,
            Err(e) => {
                s.skips.count(d.offset, &SkipReason::Hesai(e));
                return Ok(());
            }
        };
        if let Some(crcs) = p.crc() {
            match crcs.iter().find(|(stored, computed)| stored != computed) {
                Some(&(stored, computed)) => {
                    let e = spherecal::hesai::Error::Crc { stored, computed };
                    s.skips.count(d.offset, &SkipReason::Hesai(e));
                    return Ok(());
                }
                None => s.crc_agreed += 1,
            }
        }
        let (model, _) = *s.model.get_or_insert((p.model(), p.return_mode()));
        if p.model() != model {
            s.other_model += 1;
            return Ok(());
        }
        s.data_packets += 1;
        line.clear();
        s.returns_of(&p, c, csv.is_some().then_some(&mut line));
        if let Some(w) = csv.as_deref_mut() {
            w.write_all(&line)?;
        }
        Ok::<(), std::io::Error>(())
    })?;
    s.stopped = end.map(|e| e.to_string());
    Ok(s)
}

impl HesaiSummary {
    fn gps_packet(&mut self, d: &spherecal_hal::Datagram<'_>) {
        match GpsPacket::new_checked(d.payload) {
            Ok(g) => {
                self.gps[0] += 1;
                self.gps[1] += u64::from(g.pps_locked());
                if self.gps_first.is_none() {
                    self.gps_first = g.utc().map(|t| {
                        format!(
                            "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}Z",
                            t.year, t.month, t.day, t.hour, t.minute, t.second
                        )
                    });
                }
            }
            Err(e) => self.skips.count(d.offset, &SkipReason::Hesai(e)),
        }
    }

    /// Count the returns of packet `p`, and list them into `line` if given: a dual mode's
    /// second block's return identical to the first's (distance and reflectivity) once.
    fn returns_of(
        &mut self,
        p: &DataPacket<&[u8]>,
        c: &Corrections,
        mut line: Option<&mut Vec<u8>>,
    ) {
        let (model, mode) = (p.model(), p.return_mode());
        let n = mode.returns();
        let t0 = p.unix_ns();
        match t0 {
            Some(t) => {
                self.span_ns = Some(self.span_ns.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            }
            None => self.undated += 1,
        }
        self.rpm.get_or_insert(p.motor_rpm());
        let unit_m = f64::from(p.distance_unit_mm()) * 1e-3;
        let seq = p.udp_sequence().unwrap_or(0);
        let names = return_names(model, mode);
        for b in 0..model.blocks() {
            let geo = c.block(p.azimuth(b));
            let k = b % n;
            for ch in 0..model.channels() {
                let (dist, refl) = p.unit(b, ch);
                if dist == 0 {
                    continue;
                }
                if k == 0 && n == 2 && p.unit(b + 1, ch) == (dist, refl) {
                    self.identical += 1;
                    continue;
                }
                self.returns[k] += 1;
                let Some(line) = line.as_deref_mut() else {
                    continue;
                };
                let t = t0.map(|t| t + p.firing_offset_ns(b, ch));
                for v in [self.data_packets - 1, b as u64, u64::from(seq), ch as u64] {
                    push_u64(line, v);
                    line.push(b',');
                }
                line.extend_from_slice(names[k].as_bytes());
                line.push(b',');
                match t {
                    Some(t) if t >= 0 => {
                        let t = t as u64;
                        push_u64(line, t / 1000);
                        line.push(b'.');
                        push_padded(line, t % 1000, 3);
                    }
                    _ => line.extend_from_slice(b"nan"),
                }
                let (az, el) = geo.angles_deg(ch);
                let m = f64::from(dist) * unit_m;
                line.push(b',');
                push_fixed(line, az, 4);
                line.push(b',');
                push_fixed(line, el, 3);
                line.push(b',');
                push_fixed(line, m, 3);
                line.push(b',');
                push_u64(line, u64::from(refl));
                for v in geo.xyz(ch, m) {
                    line.push(b',');
                    push_fixed(line, v, 6);
                }
                line.push(b'\n');
            }
        }
    }
}

/// The CSV's `return` of each block of a firing (manual 3.1.2: in the last-and-strongest mode
/// the odd block holds the last return, the even block the strongest; the XT sends a first-
/// and-last mode's last first).
fn return_names(model: Model, mode: ReturnMode) -> [&'static str; 2] {
    match mode {
        ReturnMode::Single(0x33) => ["first", ""],
        ReturnMode::Single(0x34) => ["second", ""],
        ReturnMode::Single(0x37) => ["strongest", ""],
        ReturnMode::Single(_) => ["last", ""],
        ReturnMode::Dual(0x39) => ["last", "strongest"],
        ReturnMode::Dual(0x3a) => ["first", "second"],
        ReturnMode::Dual(0x3b) if model != Model::Qt64 => ["last", "first"],
        ReturnMode::Dual(0x3b) => ["first", "last"],
        ReturnMode::Dual(0x3c) => ["first", "strongest"],
        ReturnMode::Dual(_) => ["strongest", "second_strongest"],
    }
}

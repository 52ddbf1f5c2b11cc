//! `spherecal decode CAPTURE --metadata META.json [--csv OUT]` for an Ouster: every lidar
//! packet of the capture checked against the metadata's format, counted, and listed one row per
//! return (the first, and in the dual profiles the second as its own row).

use super::{Metadata, TimestampMode};
use crate::decode::{each_record, push_fixed, push_padded, push_u64, Step, CSV_HEADER};
use spherecal::ouster::{LidarPacket, Pixel};
use spherecal_hal::pcap::PcapSource;
use spherecal_hal::velodyne::SkipStats;
use spherecal_hal::{PacketSource, SkipReason};
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// The Ouster CSV's columns: the Velodyne listing's, then where the return is in the frame.
pub fn csv_header() -> String {
    format!("{CSV_HEADER},frame_id,measurement_id,channel")
}

/// What an Ouster decode found.
#[derive(Debug, Default, Clone)]
pub struct OusterSummary {
    /// Lidar packets decoded.
    pub lidar_packets: u64,
    /// IMU packets seen (not decoded).
    pub imu_packets: u64,
    /// Frames (distinct frame ids).
    pub frames: u64,
    /// Columns with data, and those sent invalid (outside the column window, or blocked).
    pub columns: [u64; 2],
    /// Returns (range > 0): first and second.
    pub returns: [u64; 2],
    /// First and last column timestamp [ns].
    pub span_ns: Option<(u64, u64)>,
    /// Everything skipped.
    pub skips: SkipStats,
    /// Payload lengths seen on the lidar port that were not the format's, with counts.
    pub wrong_lengths: Vec<(usize, u64)>,
    /// Packets whose footer's CRC-64 agreed (firmware 3.x sends it; once one agrees, a packet
    /// that disagrees is skipped as damaged).
    pub crc_agreed: u64,
    /// Packets whose header's serial number is not the metadata's `prod_sn` (the first seen).
    pub other_serial: Option<(u64, u64)>,
    /// Columns whose measurement id is beyond the frame's columns.
    pub bad_measurement_ids: u64,
    /// A file that stopped early: where and why.
    pub stopped: Option<String>,
}

impl OusterSummary {
    /// The summary as printed.
    pub fn render(&self, path: &str, m: &Metadata) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "file: {path}");
        let _ = writeln!(
            o,
            "sensor: Ouster {} (serial {}, firmware {}), {} beams, {} columns per frame, profile {}{}",
            if m.product.is_empty() { "?" } else { &m.product },
            if m.serial.is_empty() { "?" } else { &m.serial },
            if m.firmware.is_empty() { "?" } else { &m.firmware },
            m.format.pixels,
            m.columns_per_frame,
            m.profile_name,
            m.timestamp_mode
                .as_ref()
                .map_or(String::new(), |t| format!(", timestamps {}", t.name()))
        );
        let _ = writeln!(
            o,
            "lidar packets: {} (UDP {}), frames: {}, columns: {} with data, {} invalid; IMU packets: {}",
            self.lidar_packets, m.lidar_port, self.frames, self.columns[0], self.columns[1], self.imu_packets
        );
        let _ = writeln!(
            o,
            "points: {} (first returns {}, second {})",
            self.returns[0] + self.returns[1],
            self.returns[0],
            self.returns[1]
        );
        if let Some((a, b)) = self.span_ns {
            let _ = writeln!(
                o,
                "column timestamps: {:.6} s to {:.6} s",
                a as f64 * 1e-9,
                b as f64 * 1e-9
            );
            let _ = writeln!(o, "clock: {}", clock(m.timestamp_mode.as_ref(), a));
        }
        if self.crc_agreed > 0 {
            let _ = writeln!(
                o,
                "footer CRC-64 (firmware 3.x): {} packets agree",
                self.crc_agreed
            );
        }
        if self.bad_measurement_ids > 0 {
            let _ = writeln!(
                o,
                "columns with a measurement id beyond the frame's {}: {}",
                m.columns_per_frame, self.bad_measurement_ids
            );
        }
        crate::decode::render_skips(&mut o, &self.skips, self.stopped.as_deref());
        o
    }

    /// Why the capture does not go with its metadata: packets on the lidar port, none of the
    /// metadata's format.
    pub fn mismatch(&self, m: &Metadata) -> Option<String> {
        if let Some((sn, n)) = self.other_serial {
            return Some(format!(
                "{n} lidar packets come from the sensor with serial number {sn}, the metadata describes {}: decode with that sensor's metadata (its beam angles are its own)",
                m.serial
            ));
        }
        if self.lidar_packets > 0 || self.wrong_lengths.is_empty() {
            return None;
        }
        let seen: Vec<String> = self
            .wrong_lengths
            .iter()
            .map(|(len, n)| format!("{n} of {len} bytes"))
            .collect();
        Some(format!(
            "the capture's packets on UDP {} ({}) are not the metadata's format: {} of {} pixels x {} columns is {} bytes; is this the capture's own metadata?",
            m.lidar_port,
            seen.join(", "),
            m.profile_name,
            m.format.pixels,
            m.format.columns,
            m.format.packet_len()
        ))
    }
}

/// TAI - UTC since 2017-01-01 [s] (GPS - UTC 18 + TAI - GPS 19).
const TAI_UTC_S: i64 = 37;
/// 2000-01-01 in seconds after 1970: a synchronised clock's times are later.
const YEAR_2000_S: u64 = 946_684_800;

/// What the column timestamps say of the sensor's clock (`timestamp_mode`, and the first
/// column's time [ns]): synchronised (the first column in UTC), or free-running - counting
/// from power-on (`TIME_FROM_INTERNAL_OSC`, or a PTP or sync-pulse mode whose source never
/// locked) - which a calibration treats as an unlocked clock.
pub fn clock(mode: Option<&TimestampMode>, first_ns: u64) -> String {
    let synced = first_ns / 1_000_000_000 >= YEAR_2000_S;
    let utc = |tai: bool| {
        let s = (first_ns / 1_000_000_000) as i64 - if tai { TAI_UTC_S } else { 0 };
        chrono::DateTime::from_timestamp(s, (first_ns % 1_000_000_000) as u32)
            .map_or(String::from("?"), |t| {
                t.format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string()
            })
    };
    let since_power_on = first_ns as f64 * 1e-9;
    match (mode, synced) {
        (Some(TimestampMode::Ptp), true) => {
            format!("synchronised by PTP: the first column at {} (TAI - 37 s)", utc(true))
        }
        (Some(TimestampMode::SyncPulseIn), true) => {
            format!("synchronised by the sync pulse and NMEA: the first column at {}", utc(false))
        }
        (Some(m @ (TimestampMode::Ptp | TimestampMode::SyncPulseIn)), false) => format!(
            "{}, but the times count from power-on ({since_power_on:.0} s): its source never locked - free-running, an unlocked clock",
            m.name()
        ),
        (Some(TimestampMode::InternalOsc), _) => {
            "the sensor's own oscillator, counting from power-on: free-running, an unlocked clock".into()
        }
        (_, true) => format!("times from 1970 (first column {} if UTC): a synchronised clock", utc(false)),
        (_, false) => format!(
            "{}; the times count from power-on ({since_power_on:.0} s): free-running, an unlocked clock",
            mode.map_or("no timestamp_mode in the metadata", TimestampMode::name)
        ),
    }
}

/// The ROS 2 message of ouster-ros's raw packets.
pub const PACKET_MSG: &str = "ouster_sensor_msgs/msg/PacketMsg";

/// Decode the capture at `path`, or the bag's `PacketMsg` lidar topic (`topic`, else the one
/// named `*lidar_packets`, else the only one), with its metadata `m`, listing returns into
/// `csv`.
pub fn decode_file(
    path: &Path,
    topic: Option<&str>,
    m: &Metadata,
    csv: Option<&mut dyn Write>,
) -> Result<OusterSummary, crate::Error> {
    let at =
        |e: &dyn std::fmt::Display| crate::Error::bad_input(format!("{}: {e}", path.display()));
    if !spherecal_hal::rosbag::is_bag(path) {
        let src = PcapSource::open(path).map_err(|e| at(&e))?;
        return decode_source(src, m, csv, false).map_err(|e| at(&e));
    }
    let bag = spherecal_hal::rosbag::Bag::open(path).map_err(|e| at(&e))?;
    let topics = bag.topic_list().map_err(|e| at(&e))?;
    let of: Vec<&spherecal_hal::rosbag::TopicStats> = topics
        .iter()
        .filter(|t| t.topic.type_name == PACKET_MSG)
        .collect();
    let named = |suffix: &str| {
        of.iter()
            .find(|t| t.topic.name.ends_with(suffix))
            .map(|t| t.topic.name.clone())
    };
    let lidar = match (topic, of.as_slice()) {
        (Some(t), _) => of
            .iter()
            .find(|s| s.topic.name == t)
            .map(|s| s.topic.name.clone())
            .ok_or_else(|| at(&format!("no {PACKET_MSG} topic named {t}")))?,
        (None, [one]) => one.topic.name.clone(),
        (None, []) => {
            return Err(at(&format!(
                "no {PACKET_MSG} topic (ouster-ros's /ouster/lidar_packets)"
            )))
        }
        (None, _) => named("lidar_packets").ok_or_else(|| {
            at(&format!(
                "{} topics of {PACKET_MSG}: say which is the lidar's with --lidar-topic",
                of.len()
            ))
        })?,
    };
    let imu = named("imu_packets").filter(|n| *n != lidar);
    let src =
        spherecal_hal::rosbag::sources::ScanPackets::ouster(bag.messages(&[&lidar]), m.lidar_port);
    let mut s = decode_source(src, m, csv, true).map_err(|e| at(&e))?;
    s.imu_packets = imu
        .and_then(|n| of.iter().find(|t| t.topic.name == n))
        .map_or(0, |t| t.count);
    Ok(s)
}

/// [`decode_file`] over any packet source; `trailing`: a packet may carry one byte past the
/// format's length (ouster-ros's `PacketMsg` does).
pub fn decode_source<S: PacketSource>(
    mut src: S,
    m: &Metadata,
    mut csv: Option<&mut dyn Write>,
    trailing: bool,
) -> Result<OusterSummary, std::io::Error> {
    let mut s = OusterSummary::default();
    let serial = m.serial.parse::<u64>().ok();
    let mut last_frame = None;
    let mut line: Vec<u8> = Vec::with_capacity(1 << 16);
    if let Some(w) = csv.as_deref_mut() {
        writeln!(w, "{}", csv_header())?;
    }
    let end = each_record(&mut src, |step| {
        let d = match step {
            Step::Skipped(offset, reason) => {
                s.skips.count(offset, &reason);
                return Ok(());
            }
            Step::Udp(d) => d,
        };
        let d = match trailing && d.payload.len() == m.format.packet_len() + 1 {
            true => spherecal_hal::Datagram {
                payload: &d.payload[..m.format.packet_len()],
                ..d
            },
            false => d,
        };
        let Some(p) = s.accept(&d, m, serial) else {
            return Ok(());
        };
        // Frames: where the frame id changes (it wraps at 65,536 in the standard header).
        if last_frame.replace(p.frame_id()) != Some(p.frame_id()) {
            s.frames += 1;
        }
        line.clear();
        s.count_columns(&p, m, csv.is_some().then_some(&mut line));
        if let Some(w) = csv.as_deref_mut() {
            w.write_all(&line)?;
        }
        Ok::<(), std::io::Error>(())
    })?;
    s.stopped = end.map(|e| e.to_string());
    Ok(s)
}

/// Where a row's return is: its packet (index among the lidar packets), column in the packet,
/// frame, measurement id and the column's time [ns].
struct At {
    packet: u64,
    block: usize,
    frame: u32,
    mid: u16,
    t: u64,
}

impl OusterSummary {
    /// The datagram `d` as a lidar packet of the metadata `m` (`serial`: its `prod_sn`), or
    /// counted as what it is: an IMU packet, another port, another format, another unit, a
    /// damaged packet (once the footer's CRC-64 has agreed).
    fn accept<'d>(
        &mut self,
        d: &spherecal_hal::Datagram<'d>,
        m: &Metadata,
        serial: Option<u64>,
    ) -> Option<LidarPacket<&'d [u8]>> {
        if d.dst_port == m.imu_port && d.dst_port != m.lidar_port {
            self.imu_packets += 1;
            return None;
        }
        if d.dst_port != m.lidar_port {
            self.skips
                .count(d.offset, &SkipReason::OtherPort(d.dst_port));
            return None;
        }
        let p = match LidarPacket::new_checked(d.payload, m.format) {
            Ok(p) => p,
            Err(e) => {
                if let spherecal::ouster::Error::Length { got, .. } = e {
                    match self.wrong_lengths.iter_mut().find(|(l, _)| *l == got) {
                        Some((_, n)) => *n += 1,
                        None => self.wrong_lengths.push((got, 1)),
                    }
                }
                self.skips.count(d.offset, &SkipReason::Ouster(e));
                return None;
            }
        };
        if let (Some(sn), Some(want)) = (p.serial(), serial) {
            if sn != want && sn != 0 {
                self.other_serial.get_or_insert((sn, 0)).1 += 1;
                return None;
            }
        }
        if let Some((stored, computed)) = p.crc() {
            if stored == computed {
                self.crc_agreed += 1;
            } else if self.crc_agreed > 0 {
                let e = spherecal::ouster::Error::Crc { stored, computed };
                self.skips.count(d.offset, &SkipReason::Ouster(e));
                return None;
            }
        }
        self.lidar_packets += 1;
        Some(p)
    }

    /// Count the columns and returns of packet `p`, and list them into `line` if given.
    fn count_columns(
        &mut self,
        p: &LidarPacket<&[u8]>,
        m: &Metadata,
        mut line: Option<&mut Vec<u8>>,
    ) {
        let (packet, frame) = (self.lidar_packets - 1, p.frame_id());
        for (block, c) in p.columns().enumerate() {
            if !c.valid() {
                self.columns[1] += 1;
                continue;
            }
            self.columns[0] += 1;
            let mid = c.measurement_id();
            if usize::from(mid) >= m.columns_per_frame {
                self.bad_measurement_ids += 1;
                continue;
            }
            let t = c.timestamp_ns();
            self.span_ns = Some(self.span_ns.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            let geo = m.intrinsics.column(mid);
            let at = At {
                packet,
                block,
                frame,
                mid,
                t,
            };
            let returns = &mut self.returns;
            c.for_each_return(|ch, r, _| {
                returns[r] += 1;
                if let Some(line) = line.as_deref_mut() {
                    row(line, &geo, &at, ch, r, &c.pixel(ch));
                }
            });
        }
    }
}

/// One CSV row: the return `r` of pixel `px` (beam `ch`) at `at`.
fn row(
    line: &mut Vec<u8>,
    geo: &spherecal::ouster::ColumnGeometry<'_>,
    at: &At,
    ch: usize,
    r: usize,
    px: &Pixel,
) {
    let mm = px.range_mm[r];
    let b = geo.point(ch, mm);
    for v in [at.packet, at.block as u64, 0, ch as u64] {
        push_u64(line, v);
        line.push(b',');
    }
    line.extend_from_slice(if r == 0 { b"first," } else { b"second," });
    push_u64(line, at.t / 1000);
    line.push(b'.');
    push_padded(line, at.t % 1000, 3);
    line.push(b',');
    push_fixed(line, b.azimuth_deg, 4);
    line.push(b',');
    push_fixed(line, b.elevation_deg, 3);
    line.push(b',');
    push_u64(line, u64::from(mm / 1000));
    line.push(b'.');
    push_padded(line, u64::from(mm % 1000), 3);
    line.push(b',');
    push_u64(line, u64::from(px.reflectivity[r]));
    for v in b.xyz {
        line.push(b',');
        push_fixed(line, v, 6);
    }
    for v in [u64::from(at.frame), u64::from(at.mid), ch as u64] {
        line.push(b',');
        push_u64(line, v);
    }
    line.push(b'\n');
}

#[cfg(test)]
mod tests {
    use super::{clock, TimestampMode};

    /// A PTP clock's TAI time is 37 s ahead of UTC; the sync pulse's NMEA gives UTC; a PTP or
    /// sync-pulse mode counting from power-on never locked.
    #[test]
    fn the_clock_is_read_from_the_mode_and_the_times() {
        // 2024-03-21T12:00:37 TAI = 12:00:00 UTC.
        let t = (1_711_022_400 + 37) * 1_000_000_000 + 250_000_000;
        assert!(clock(Some(&TimestampMode::Ptp), t).contains("2024-03-21T12:00:00.250Z"));
        let u = 1_711_022_400 * 1_000_000_000;
        assert!(clock(Some(&TimestampMode::SyncPulseIn), u).contains("2024-03-21T12:00:00.000Z"));
        assert!(clock(Some(&TimestampMode::Ptp), 866_100_516_000).contains("never locked"));
        assert!(clock(Some(&TimestampMode::InternalOsc), u).contains("unlocked"));
        assert!(clock(None, 3_577_133_606_620).contains("free-running"));
    }
}

//! `spherecal decode FILE [--csv OUT]`: VLP-16 packets from a capture, counted and listed.

use spherecal::time::UtcDateTime;
use spherecal::vlp16::{self, DataPacket, PointBuf, PpsStatus, ReturnMode, ELEVATION_DEG};
use spherecal_hal::pcap::{PcapError, PcapSource};
use spherecal_hal::vlp16::{classify, Ports, SkipStats, Vlp16Packet};
use spherecal_hal::{PacketSource, Record};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::{self, Read, Write};
use std::path::Path;

/// The CSV header of `--csv` (issue #2 contract).
pub const CSV_HEADER: &str =
    "packet,block,sequence,laser,return,time_us,azimuth_deg,elevation_deg,distance_m,intensity,x_m,y_m,z_m";

/// What a decode found.
#[derive(Debug, Default, Clone)]
pub struct DecodeSummary {
    /// Data packets decoded.
    pub data_packets: u64,
    /// Position packets read.
    pub position_packets: u64,
    /// Non-zero returns.
    pub points: u64,
    /// Data packets by return mode.
    pub return_modes: BTreeMap<&'static str, u64>,
    /// Data packets by product id byte.
    pub products: BTreeMap<u8, u64>,
    /// Position packets by PPS status.
    pub pps: BTreeMap<String, u64>,
    /// RMC sentences parsed.
    pub rmc_count: u64,
    /// First and last RMC date-time.
    pub rmc_first: Option<UtcDateTime>,
    /// Last RMC date-time.
    pub rmc_last: Option<UtcDateTime>,
    /// Position packets whose RMC minute:second disagrees with the packet timestamp.
    pub rmc_stamp_mismatches: u64,
    /// Everything skipped.
    pub skips: SkipStats,
    /// A file that stopped early: where and why.
    pub stopped: Option<String>,
}

/// Why decoding could not start.
#[derive(Debug)]
pub struct DecodeError {
    /// The file.
    pub path: String,
    /// What went wrong.
    pub error: PcapError,
}

impl std::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path, self.error)
    }
}

impl std::error::Error for DecodeError {}

fn mode_name(m: ReturnMode) -> &'static str {
    match m {
        ReturnMode::Strongest => "strongest",
        ReturnMode::Last => "last",
        ReturnMode::Dual => "dual",
    }
}

/// Decode a capture file; with `csv`, write one row per point.
pub fn decode_file(path: &Path, csv: Option<&mut dyn Write>) -> Result<DecodeSummary, DecodeError> {
    let err = |error| DecodeError {
        path: path.display().to_string(),
        error,
    };
    let src = PcapSource::open(path).map_err(err)?;
    decode_source(src, csv).map_err(|e| DecodeError {
        path: path.display().to_string(),
        error: e,
    })
}

/// Decode from any reader holding a capture.
pub fn decode_source<R: Read>(
    mut src: PcapSource<R>,
    mut csv: Option<&mut dyn Write>,
) -> Result<DecodeSummary, PcapError> {
    let mut s = DecodeSummary::default();
    let mut points = PointBuf::new();
    let mut line = String::with_capacity(128);
    if let Some(w) = csv.as_deref_mut() {
        writeln!(w, "{CSV_HEADER}")?;
    }
    let ports = Ports::default();
    loop {
        let rec = match src.next_record() {
            Ok(Some(r)) => r,
            Ok(None) => break,
            Err(e @ PcapError::Corrupt { .. }) => {
                s.stopped = Some(e.to_string());
                break;
            }
            Err(e) => return Err(e),
        };
        let d = match rec {
            Record::Skipped { offset, reason } => {
                s.skips.count(offset, &reason);
                continue;
            }
            Record::Udp(d) => d,
            Record::Idle => continue,
        };
        match classify(&d, ports) {
            Err(reason) => s.skips.count(d.offset, &reason),
            Ok(Vlp16Packet::Data { packet, offset, .. }) => {
                match vlp16::decode(&packet, &mut points) {
                    Err(e) => s.skips.count(offset, &spherecal_hal::SkipReason::Vlp16(e)),
                    Ok(n) => {
                        if let Some(w) = csv.as_deref_mut() {
                            write_rows(w, &mut line, s.data_packets, &packet, &points)?;
                        }
                        s.points += n as u64;
                        if let Ok(m) = packet.return_mode() {
                            *s.return_modes.entry(mode_name(m)).or_default() += 1;
                        }
                        *s.products.entry(packet.product_raw()).or_default() += 1;
                        s.data_packets += 1;
                    }
                }
            }
            Ok(Vlp16Packet::Position { packet, .. }) => {
                s.position_packets += 1;
                let pps = match packet.pps() {
                    PpsStatus::Absent => "none".to_string(),
                    PpsStatus::Synchronizing => "synchronizing".to_string(),
                    PpsStatus::Locked => "locked".to_string(),
                    PpsStatus::Error => "error".to_string(),
                    PpsStatus::Unknown(b) => format!("unknown(0x{b:02X})"),
                };
                *s.pps.entry(pps).or_default() += 1;
                if let Some(utc) = packet.nmea_time().ok().and_then(|t| t.utc()) {
                    s.rmc_count += 1;
                    s.rmc_first.get_or_insert(utc);
                    s.rmc_last = Some(utc);
                    // The RMC second is the last whole second at or before the packet's stamp.
                    let stamp_s = packet.timestamp_us() / 1_000_000;
                    let rmc_s = u32::from(utc.minute) * 60 + u32::from(utc.second);
                    if stamp_s != rmc_s {
                        s.rmc_stamp_mismatches += 1;
                    }
                }
            }
        }
    }
    if let Some(w) = csv {
        w.flush()?;
    }
    Ok(s)
}

fn write_rows(
    w: &mut dyn Write,
    line: &mut String,
    index: u64,
    packet: &DataPacket<&[u8]>,
    points: &PointBuf,
) -> io::Result<()> {
    let ts_ns = u64::from(packet.timestamp_us()) * 1000;
    for p in points.as_slice() {
        line.clear();
        let t = ts_ns + u64::from(p.offset_ns);
        let mm = u32::from(p.distance_raw) * 2;
        let _ = writeln!(
            line,
            "{index},{},{},{},{},{}.{:03},{:.4},{},{}.{:03},{},{:.6},{:.6},{:.6}",
            p.block,
            p.sequence(),
            p.laser(),
            p.ret.name(),
            t / 1000,
            t % 1000,
            f64::from(p.azimuth).to_degrees(),
            ELEVATION_DEG[p.laser()],
            mm / 1000,
            mm % 1000,
            p.intensity,
            p.x,
            p.y,
            p.z
        );
        w.write_all(line.as_bytes())?;
    }
    Ok(())
}

fn fmt_utc(t: &UtcDateTime) -> String {
    format!(
        "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:02}Z",
        t.year,
        t.month,
        t.day,
        t.hour,
        t.minute,
        t.second,
        t.nanos / 10_000_000
    )
}

impl DecodeSummary {
    /// The human summary `spherecal decode` prints.
    pub fn render(&self, path: &str) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "file: {path}");
        let _ = write!(o, "data packets: {}", self.data_packets);
        for (m, n) in &self.return_modes {
            let _ = write!(o, " ({m}: {n})");
        }
        for (p, n) in &self.products {
            let _ = write!(o, " [product 0x{p:02X}: {n}]");
        }
        let _ = writeln!(o);
        let _ = write!(o, "position packets: {}", self.position_packets);
        for (k, n) in &self.pps {
            let _ = write!(o, " (PPS {k}: {n})");
        }
        let _ = writeln!(o);
        let _ = writeln!(o, "points: {}", self.points);
        match (&self.rmc_first, &self.rmc_last) {
            (Some(a), Some(b)) => {
                let _ = writeln!(
                    o,
                    "RMC times: {} from {} to {} ({} disagree with the packet timestamp)",
                    self.rmc_count,
                    fmt_utc(a),
                    fmt_utc(b),
                    self.rmc_stamp_mismatches
                );
            }
            _ => {
                let _ = writeln!(o, "RMC times: none");
            }
        }
        let _ = writeln!(o, "skipped: {}", self.skips.total());
        for l in self.skips.lines() {
            let _ = writeln!(
                o,
                "  {}: {} (first at byte {}: {})",
                l.reason, l.count, l.first_offset, l.first
            );
        }
        if let Some(s) = &self.stopped {
            let _ = writeln!(o, "stopped early: {s}");
        }
        o
    }
}

//! `spherecal decode FILE [--csv OUT] [--model NAME]`: Velodyne packets from a capture,
//! counted and listed, decoded as the model the capture's product byte names (checked against
//! its packet period: [`identify_file`]) or as the one given.

use spherecal::time::UtcDateTime;
use spherecal::velodyne::{self, Detector, Identity, Model, PointBuf, PpsStatus, ReturnMode};
use spherecal_hal::pcap::{PcapError, PcapSource};
use spherecal_hal::velodyne::{classify, Ports, SkipStats, Vlp16Packet};
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
    /// The model the packets were decoded as, and how it was chosen.
    pub model: Option<(Model, String)>,
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
    /// A bag of point clouds: how many were read (its returns are not in packets).
    pub clouds: Option<u64>,
}

/// Why decoding could not start.
#[derive(Debug)]
pub struct DecodeError {
    /// The file.
    pub path: String,
    /// What went wrong.
    pub error: DecodeFailure,
}

/// What stopped a decode before it began.
#[derive(Debug)]
pub enum DecodeFailure {
    /// The capture could not be read.
    Pcap(PcapError),
    /// The LiDAR model is unknown or its product byte disagrees with the packet period.
    Model(ModelError),
    /// A ROS 2 bag could not be opened, or has no scans to read.
    Bag(String),
}

impl std::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.error {
            DecodeFailure::Pcap(e) => write!(f, "{}: {e}", self.path),
            DecodeFailure::Model(e) => write!(f, "{}: {e}", self.path),
            DecodeFailure::Bag(e) => f.write_str(e),
        }
    }
}

impl DecodeError {
    /// What failed with the file at `path`.
    pub(crate) fn at(path: &Path) -> impl Fn(DecodeFailure) -> DecodeError + '_ {
        move |error| DecodeError {
            path: path.display().to_string(),
            error,
        }
    }
}

/// An unreadable capture or an untrusted model is bad input.
impl From<DecodeError> for crate::Error {
    fn from(e: DecodeError) -> Self {
        Self::bad_input(e.to_string())
    }
}

/// The model of a capture could not be trusted: the product byte of the first data packet
/// (at `offset` in the file) is unknown, or it disagrees with the packet period.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelError {
    /// What the packets said.
    pub identity: Identity,
    /// Byte offset of the first data packet's record.
    pub offset: u64,
}

impl std::fmt::Display for ModelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let at = self.offset;
        match self.identity {
            Identity::Unknown { product } => write!(
                f,
                "data packet at byte {at}: product byte 0x{product:02X} is no model this tool \
                 knows (VLP-16 0x22, Puck Hi-Res 0x24, HDL-32E 0x21, VLP-32C 0x28); refused \
                 rather than decoded as another model's; if the sensor is one of these, say \
                 which with --model {}",
                model_keys()
            ),
            Identity::Disagrees {
                product,
                period_us,
                fits,
            } => {
                let named = Model::from_product(product).map_or("?", Model::name);
                let expect = Model::from_product(product)
                    .map_or(0.0, |m| f64::from(m.packet_period_ns(false)) / 1000.0);
                write!(
                    f,
                    "data packets from byte {at}: product byte 0x{product:02X} says {named} \
                     ({expect:.1} us between single-return packets) but they come every \
                     {period_us} us"
                )?;
                match fits {
                    Some(m) => {
                        let same: Vec<&str> = Model::ALL
                            .iter()
                            .filter(|o| o.same_timing(m))
                            .map(|o| o.key())
                            .collect();
                        write!(
                            f,
                            ", the period of a {} (early VLP-16 firmware writes 0x21); say \
                             which with --model {}",
                            m.name(),
                            same.join(" or --model ")
                        )
                    }
                    None => write!(f, ", the period of no known model; refused"),
                }
            }
            _ => write!(f, "model not known"),
        }
    }
}

/// The `--model` names, for messages.
pub fn model_keys() -> String {
    Model::ALL.map(Model::key).join("|")
}

/// What the first data packets of a capture say of its model ([`Detector`]): their product
/// byte checked against their period (a file with too few packets to check keeps the byte's
/// model). Err when the byte is unknown or disagrees.
pub fn identify_file(path: &Path, ports: Ports) -> Result<Option<(Model, String)>, DecodeError> {
    let err = DecodeError::at(path);
    let src = PcapSource::open(path).map_err(|e| err(DecodeFailure::Pcap(e)))?;
    identify_source(src, ports).map_err(|e| err(DecodeFailure::Model(e)))
}

/// [`identify_file`] over any packet source (a capture, a bag's scans).
pub fn identify_source<S: PacketSource>(
    mut src: S,
    ports: Ports,
) -> Result<Option<(Model, String)>, ModelError> {
    let mut det = Detector::new();
    let mut first: Option<u64> = None;
    let mut id = det.identity();
    loop {
        let rec = match src.next_record() {
            Ok(Some(Record::Udp(d))) => d,
            Ok(Some(_)) => continue,
            Ok(None) | Err(_) => break,
        };
        if let Ok(Vlp16Packet::Data { packet, offset, .. }) = classify(&rec, ports) {
            first.get_or_insert(offset);
            id = det.push(
                packet.timestamp_us(),
                packet.return_mode_raw(),
                packet.product_raw(),
            );
            if !matches!(id, Identity::Pending(_)) {
                break;
            }
        }
    }
    let offset = first.unwrap_or(0);
    match id {
        Identity::Agreed(m) => Ok(Some((
            m,
            format!("product byte 0x{:02X}, {AGREED}", m.product()),
        ))),
        Identity::Pending(Some(m)) => Ok(Some((
            m,
            format!(
                "product byte 0x{:02X} (too few packets to check the period)",
                m.product()
            ),
        ))),
        Identity::Pending(None) => Ok(None),
        identity => Err(ModelError { identity, offset }),
    }
}

/// The words of an identification whose product byte and packet period agree.
pub const AGREED: &str = "packet period agrees";

/// The model to decode a capture as: `given` (the user's `--model`, said so), else what its
/// packets say ([`identify_file`]).
pub fn choose_model(
    path: &Path,
    ports: Ports,
    given: Option<Model>,
) -> Result<Option<(Model, String)>, DecodeError> {
    match given {
        Some(m) => Ok(Some((m, "given with --model".into()))),
        None => identify_file(path, ports),
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

/// Decode a capture file as `model` (None: as its packets say, [`choose_model`]); with `csv`,
/// write one row per point.
pub fn decode_file(
    path: &Path,
    csv: Option<&mut dyn Write>,
    model: Option<Model>,
) -> Result<DecodeSummary, DecodeError> {
    let err = DecodeError::at(path);
    let chosen = choose_model(path, Ports::default(), model)?;
    let src = PcapSource::open(path).map_err(|e| err(DecodeFailure::Pcap(e)))?;
    decode_source(src, csv, chosen).map_err(|e| err(DecodeFailure::Pcap(e)))
}

/// Decode from any reader holding a capture, as `model` (with how it was chosen; None: no
/// data packet to judge by, so each is decoded as its product byte names, unknown ones
/// skipped and counted).
pub fn decode_source<R: Read>(
    src: PcapSource<R>,
    csv: Option<&mut dyn Write>,
    model: Option<(Model, String)>,
) -> Result<DecodeSummary, PcapError> {
    decode_packets(src, csv, model, |e| match e {
        e @ PcapError::Corrupt { .. } => Ok(e.to_string()),
        e => Err(e),
    })
}

/// What a capture's walk meets: a UDP datagram, or a record skipped (where, why).
pub(crate) enum Step<'a> {
    /// A datagram.
    Udp(spherecal_hal::Datagram<'a>),
    /// A record passed over: its offset and why.
    Skipped(u64, spherecal_hal::SkipReason),
}

/// Every record of `src` to `each`, in order (idle records passed over). A read error ends the
/// walk and is returned (`Ok(Some(e))`: what came before was walked); an error of `each` stops
/// it and is the result.
pub(crate) fn each_record<S: PacketSource, E>(
    src: &mut S,
    mut each: impl FnMut(Step<'_>) -> Result<(), E>,
) -> Result<Option<S::Error>, E> {
    loop {
        match src.next_record() {
            Ok(Some(Record::Udp(d))) => each(Step::Udp(d))?,
            Ok(Some(Record::Skipped { offset, reason })) => each(Step::Skipped(offset, reason))?,
            Ok(Some(Record::Idle)) => {}
            Ok(None) => return Ok(None),
            Err(e) => return Ok(Some(e)),
        }
    }
}

/// [`decode_source`] over any packet source: `soft` says which of its errors stop the
/// decoding with what was decoded so far (`Ok(why)`) and which fail it.
pub(crate) fn decode_packets<S: PacketSource, E: From<io::Error>>(
    mut src: S,
    mut csv: Option<&mut dyn Write>,
    model: Option<(Model, String)>,
    soft: impl Fn(S::Error) -> Result<String, E>,
) -> Result<DecodeSummary, E> {
    let mut s = DecodeSummary {
        model: model.clone(),
        ..Default::default()
    };
    let model = model.map(|m| m.0);
    let mut points = PointBuf::new();
    let mut line: Vec<u8> = Vec::with_capacity(384 * 96);
    if let Some(w) = csv.as_deref_mut() {
        writeln!(w, "{CSV_HEADER}")?;
    }
    let bar = crate::progress::counter("data packets decoded");
    let ports = Ports::default();
    let end = each_record(&mut src, |step| {
        let d = match step {
            Step::Skipped(offset, reason) => {
                s.skips.count(offset, &reason);
                return Ok::<(), E>(());
            }
            Step::Udp(d) => d,
        };
        match classify(&d, ports) {
            Err(reason) => s.skips.count(d.offset, &reason),
            Ok(Vlp16Packet::Data { packet, offset, .. }) => {
                let decoded = match model {
                    Some(m) => velodyne::decode_as(&packet, m, &mut points),
                    None => velodyne::decode(&packet, &mut points),
                };
                match decoded {
                    Err(e) => s.skips.count(offset, &spherecal_hal::SkipReason::Vlp16(e)),
                    Ok(n) => {
                        if let Some(w) = csv.as_deref_mut() {
                            let m = model.unwrap_or_default();
                            let ts_ns = u64::from(packet.timestamp_us()) * 1000;
                            write_rows(w, &mut line, s.data_packets, ts_ns, m, points.as_slice())?;
                        }
                        s.points += n as u64;
                        if let Ok(m) = packet.return_mode() {
                            *s.return_modes.entry(mode_name(m)).or_default() += 1;
                        }
                        *s.products.entry(packet.product_raw()).or_default() += 1;
                        s.data_packets += 1;
                        if s.data_packets.is_multiple_of(4096) {
                            bar.set_position(s.data_packets);
                        }
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
        Ok(())
    })?;
    if let Some(e) = end {
        s.stopped = Some(soft(e)?);
    }
    if let Some(w) = csv {
        w.flush()?;
    }
    bar.finish_and_clear();
    Ok(s)
}

/// One CSV row per point of packet (or cloud chunk) `index`, whose returns fired after
/// `ts_ns` [ns in the hour], written at once. Numbers are formatted by hand ([`push_u64`],
/// [`push_fixed`]): the float formatter costs ~100 ns a number, five times the budget of a row
/// at 5 M rows/s.
pub(crate) fn write_rows(
    w: &mut dyn Write,
    line: &mut Vec<u8>,
    index: u64,
    ts_ns: u64,
    model: Model,
    points: &[velodyne::Point],
) -> io::Result<()> {
    line.clear();
    for p in points {
        let t = ts_ns + u64::from(p.offset_ns);
        let mm = u64::from(p.distance_raw) * (model.distance_unit_m() * 1000.0) as u64;
        for v in [
            index,
            u64::from(p.block),
            p.sequence() as u64,
            p.laser() as u64,
        ] {
            push_u64(line, v);
            line.push(b',');
        }
        line.extend_from_slice(p.ret.name().as_bytes());
        line.push(b',');
        push_u64(line, t / 1000);
        line.push(b'.');
        push_padded(line, t % 1000, 3);
        line.push(b',');
        push_fixed(line, f64::from(p.azimuth).to_degrees(), 4);
        line.push(b',');
        // The table's value as the manual prints it: whole degrees without decimals.
        let start = line.len();
        push_fixed(line, model.beam(p.laser()).elevation_deg, 3);
        if line[start..].contains(&b'.') {
            while line.last() == Some(&b'0') {
                line.pop();
            }
            if line.last() == Some(&b'.') {
                line.pop();
            }
        }
        line.push(b',');
        push_u64(line, mm / 1000);
        line.push(b'.');
        push_padded(line, mm % 1000, 3);
        line.push(b',');
        push_u64(line, u64::from(p.intensity));
        for v in [p.x, p.y, p.z] {
            line.push(b',');
            push_fixed(line, f64::from(v), 6);
        }
        line.push(b'\n');
    }
    w.write_all(line)
}

/// `v` in decimal.
pub(crate) fn push_u64(out: &mut Vec<u8>, mut v: u64) {
    let mut digits = [0u8; 20];
    let mut i = digits.len();
    loop {
        i -= 1;
        digits[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    out.extend_from_slice(&digits[i..]);
}

/// `v` (below 10^width) with leading zeros to `width` digits.
pub(crate) fn push_padded(out: &mut Vec<u8>, v: u64, width: u32) {
    let mut p = 10u64.pow(width.saturating_sub(1));
    while p > 0 {
        out.push(b'0' + ((v / p) % 10) as u8);
        p /= 10;
    }
}

/// `v` with `decimals` (at most 9) digits after the point, rounded half away from zero (as
/// `{:.N}` but for exact decimal ties, where it may differ in the last digit); values beyond
/// +-9e9 and non-finite ones go through the float formatter.
pub(crate) fn push_fixed(out: &mut Vec<u8>, v: f64, decimals: u32) {
    let d = decimals.min(9);
    if !v.is_finite() || v.abs() >= 9e9 {
        out.extend_from_slice(format!("{v:.*}", d as usize).as_bytes());
        return;
    }
    let scale = 10u64.pow(d);
    let scaled = (v.abs() * scale as f64).round() as u64;
    // As the formatter: a negative value that rounds to zero keeps its sign.
    if v.is_sign_negative() {
        out.push(b'-');
    }
    push_u64(out, scaled / scale);
    if d > 0 {
        out.push(b'.');
        push_padded(out, scaled % scale, d);
    }
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
    /// A capture that ends inside a record, said loudly: where, and what it means.
    pub fn truncation(&self, path: &str) -> Option<String> {
        self.skips.truncated_file().map(|(at, what)| {
            format!(
                "WARNING: {path} is truncated: it ends inside the record at byte {at} ({what}): \
                 the capture was cut short (a recording interrupted, a copy not finished); \
                 only what comes before byte {at} is decoded"
            )
        })
    }

    /// The human summary `spherecal decode` prints.
    pub fn render(&self, path: &str) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "file: {path}");
        if let Some(w) = self.truncation(path) {
            let _ = writeln!(o, "{w}");
        }
        if let Some(n) = self.clouds {
            let _ = writeln!(
                o,
                "point clouds: {n} (returns the driver computed, timed on the host's clock; the packet column counts chunks of up to {} returns)",
                spherecal_hal::rosbag::clouds::CHUNK
            );
        }
        let _ = write!(o, "data packets: {}", self.data_packets);
        for (m, n) in &self.return_modes {
            let _ = write!(o, " ({m}: {n})");
        }
        for (p, n) in &self.products {
            let _ = write!(o, " [product 0x{p:02X}: {n}]");
        }
        let _ = writeln!(o);
        if let Some((m, how)) = &self.model {
            let _ = writeln!(o, "model: {} ({how})", m.name());
        }
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
        render_skips(&mut o, &self.skips, self.stopped.as_deref());
        o
    }
}

/// The summary's last lines: what was skipped, by reason with the first's byte offset, and
/// where a file stopped early.
pub(crate) fn render_skips(o: &mut String, skips: &SkipStats, stopped: Option<&str>) {
    let _ = writeln!(o, "skipped: {}", skips.total());
    for l in skips.lines() {
        let _ = writeln!(
            o,
            "  {}: {} (first at byte {}: {})",
            l.reason, l.count, l.first_offset, l.first
        );
    }
    if let Some(s) = stopped {
        let _ = writeln!(o, "stopped early: {s}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixed(v: f64, d: u32) -> String {
        let mut b = Vec::new();
        push_fixed(&mut b, v, d);
        String::from_utf8(b).unwrap()
    }

    /// Against the standard formatter over values of every magnitude a row holds: the same
    /// text, or (a decimal tie, or -0) one unit of the last digit apart.
    #[test]
    fn hand_formatting_matches_the_formatter() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut differ = 0;
        for i in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let u = (x >> 11) as f64 / (1u64 << 53) as f64;
            let v = (u - 0.5) * 10f64.powi(i % 7 - 1) * 2.0;
            for d in [0, 3, 4, 6] {
                let (a, b) = (fixed(v, d), format!("{v:.*}", d as usize));
                if a != b {
                    differ += 1;
                    let (pa, pb): (f64, f64) = (a.parse().unwrap(), b.parse().unwrap());
                    assert!(
                        (pa - pb).abs() <= 1.01 * 10f64.powi(-(d as i32)),
                        "{v}: {a} vs {b}"
                    );
                }
            }
        }
        assert!(differ < 800, "{differ} of 800000 differ");
        assert_eq!(fixed(-0.0000004, 6), "-0.000000");
        assert_eq!(fixed(-1.25, 1), "-1.3");
        assert_eq!(fixed(359.99996, 4), "360.0000");
        assert_eq!(fixed(f64::NAN, 3), "NaN");
        let mut b = Vec::new();
        push_u64(&mut b, 0);
        b.push(b' ');
        push_u64(&mut b, u64::MAX);
        b.push(b' ');
        push_padded(&mut b, 7, 3);
        assert_eq!(String::from_utf8(b).unwrap(), "0 18446744073709551615 007");
    }
}

//! `spherecal synth`: run a scenario through the simulator and write what a rig would have
//! recorded: `lidar.pcap`, `ins.bin` (and the same bytes as `ins.vnlog`, a serial log with
//! receive times, so that `replay` can pace both streams on one clock), plus `site.toml`,
//! `truth.json`, with `[ins.correlated]` `nav-errors.csv` (the wandering navigation errors the
//! INS stream carries), for a Hesai its angle correction file `corrections.csv` (what
//! `--metadata` takes) and, for tests only, `labels.bin`: which object each return came from.
//!
//! `labels.bin` (little-endian): a 16-byte header `SCLABELS`, u32 version = 1, u32 record size
//! = 12; then one record per return in file order: u32 data packet index (from 0, in file
//! order, lost packets not counted), u8 block, u8 channel, u16 object (its index in
//! `truth.json`'s `objects`; 0xFFFE a glint off the water), u8 purity (the object's share of the
//! echo's energy x 255: below 255 a mixed pixel), three zero bytes. The calibration never reads
//! it.

use crate::config::scenario::Scenario;
use crate::config::site::{Origin, Site, SiteApriori, SiteIns, SiteNoise, SiteSphere};
use crate::output::Staged;
use serde::{Deserialize, Serialize};
use spherecal::sim::ins::InsStats;
use spherecal::sim::lidar::{LidarStats, Traced};
use spherecal::sim::{InsSim, LidarSim, SimPacket, World};
use spherecal::time::gps_to_unix_ns;
use spherecal_hal::packet::HostTime;
use spherecal_hal::pcap::{build_udp_frame, PcapWriter, UdpEndpoints};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

pub mod cache;
mod ins;
use ins::write_ins;
pub use ins::{synth_ins, NAV_ERRORS, SBET, SMRMSG};

/// `truth.json`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Truth {
    /// Scenario name.
    pub scenario: String,
    /// Roll, pitch, heading [deg].
    pub boresight_deg: BTreeMap<String, f64>,
    /// x, y, z [m].
    pub lever_arm_m: BTreeMap<String, f64>,
    /// GPS - UTC [s].
    pub leap_seconds: i64,
    /// Returns on each sphere (in packets that were not lost).
    pub points_per_sphere: Vec<u64>,
    /// Returns on clutter.
    pub clutter_points: u64,
    /// Firings simulated.
    pub rays_traced: u64,
    /// Data packets written.
    pub data_packets: u64,
    /// Data packets lost on purpose.
    pub dropped_packets: u64,
    /// Position packets written.
    pub position_packets: u64,
    /// VN-200 frames written.
    pub ins_frames: u64,
    /// Serial bytes corrupted on purpose.
    pub corrupted_bytes: u64,
    /// Returns mixed from two or more objects (under 90 % from the main one).
    #[serde(default)]
    pub mixed_points: u64,
    /// The scene's objects: the labels' object index is the position in this list.
    #[serde(default)]
    pub objects: Vec<TruthObject>,
}

/// One object of the scene.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct TruthObject {
    /// Its name (a sphere's id for targets).
    pub name: String,
    /// `sphere`, `stand`, `box`, `pole`, `plane`, `crate`, `post`, `person`, `bush`, `vessel`.
    pub kind: String,
}

/// One record of `labels.bin`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Label {
    /// Data packet index in file order.
    pub packet: u32,
    /// Block (an Ouster's column in its packet).
    pub block: u8,
    /// Channel (an Ouster's pixel).
    pub channel: u8,
    /// Object index (0xFFFE: water).
    pub object: u16,
    /// The object's share of the echo's energy x 255.
    pub purity: u8,
}

/// `labels.bin`'s magic.
pub const LABELS_MAGIC: &[u8; 8] = b"SCLABELS";

/// Read a `labels.bin`.
pub fn read_labels(path: &Path) -> Result<Vec<Label>, crate::Error> {
    let b = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if b.len() < 16 || &b[..8] != LABELS_MAGIC || b[8..12] != 1u32.to_le_bytes() {
        return Err(format!("{}: not a labels.bin (version 1)", path.display()).into());
    }
    let body = &b[16..];
    if body.len() % 12 != 0 {
        return Err(format!(
            "{}: cut inside a record at byte {}",
            path.display(),
            16 + body.len() / 12 * 12
        )
        .into());
    }
    Ok(body
        .chunks_exact(12)
        .map(|r| Label {
            packet: u32::from_le_bytes([r[0], r[1], r[2], r[3]]),
            block: r[4],
            channel: r[5],
            object: u16::from_le_bytes([r[6], r[7]]),
            purity: r[8],
        })
        .collect())
}

fn named(keys: [&str; 3], v: [f64; 3]) -> BTreeMap<String, f64> {
    keys.iter()
        .zip(v)
        .map(|(k, x)| (k.to_string(), x))
        .collect()
}

/// Delay between the first firing of a packet and its capture on the rig's computer.
pub const NETWORK_DELAY_NS: i64 = 1_400_000;
/// A POS MV group's delay from its time of validity to its datagram's arrival (the ICD's
/// real-time port emphasises latency; a few milliseconds).
const POSMV_DELAY_NS: i64 = 3_000_000;
/// The POS MV Real-Time Data Port (ICD section 2).
const POSMV_PORT: u16 = spherecal::posmv::REALTIME_PORT;

/// The simulated VN-200's serial rate.
const SERIAL_BAUD: u32 = 921_600;
/// Delay between a VN-200 sample and the start of its frame on the wire.
const SERIAL_LATENCY_NS: i64 = 1_000_000;

/// Simulate and write the files into `dir` (created if needed); through the cache of
/// `SPHERECAL_SYNTH_CACHE` when it is set ([`cache`]).
pub fn synth(s: &Scenario, dir: &Path) -> Result<Truth, crate::Error> {
    let root = std::env::var_os(cache::VAR).map(std::path::PathBuf::from);
    synth_cached(s, dir, root.as_deref())
}

/// [`synth`] through the cache at `root` (none: no cache).
pub fn synth_cached(s: &Scenario, dir: &Path, root: Option<&Path>) -> Result<Truth, crate::Error> {
    let slot = root.and_then(|r| cache::slot(r, s));
    if let Some(t) = slot.as_deref().and_then(|p| cache::fetch(p, dir)) {
        return Ok(t);
    }
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (truth, _, files) = s
        .with_world(|world| write_files(s, world, dir, None))
        .map_err(|e| e.to_string())??;
    if let Some(p) = &slot {
        cache::store(p, &files);
    }
    Ok(truth)
}

/// A scene's trace: every data packet's echoes before noise ([`spherecal::sim::lidar::Traced`]),
/// so that the same scene can be synthesised with other noise seeds without tracing it again
/// (the noise-seed Monte Carlo of the tests).
#[derive(Debug, Clone, Default)]
pub struct TraceCache {
    offsets: Vec<usize>,
    echoes: Vec<Traced>,
    /// The data packets to simulate (`None`: all); the others are skipped, not written.
    keep: Option<Vec<bool>>,
}

impl TraceCache {
    /// Simulate only the data packets `keep` marks (by their index in the survey); the others
    /// are neither noised nor written (a Monte Carlo's trials need only the packets that hold
    /// windowed returns: [`crate::montecarlo::windowed_packets`]).
    pub fn keep_only(&mut self, keep: Vec<bool>) {
        self.keep = Some(keep);
    }

    /// Data packets in the survey.
    pub fn packets(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    fn skips(&self, k: usize) -> bool {
        self.keep
            .as_ref()
            .is_some_and(|m| !m.get(k).copied().unwrap_or(false))
    }

    fn packet(&self, k: usize) -> &[Traced] {
        match (self.offsets.get(k), self.offsets.get(k + 1)) {
            (Some(&a), Some(&b)) => &self.echoes[a..b],
            _ => &[],
        }
    }
}

/// Trace a scenario's scene once (no files).
pub fn trace(s: &Scenario) -> Result<TraceCache, crate::Error> {
    s.with_world(|world| {
        let mut lidar = LidarSim::new(world, s.lidar_config());
        let mut cache = TraceCache {
            offsets: vec![0],
            echoes: Vec::new(),
            keep: None,
        };
        let mut payload = [0u8; spherecal::sim::lidar::MAX_PACKET_LEN];
        while let Some(p) = lidar.next_packet(&mut payload) {
            if let SimPacket::Data { .. } = p {
                cache.echoes.extend_from_slice(&lidar.traced);
                cache.offsets.push(cache.echoes.len());
            }
        }
        cache
    })
    .map_err(crate::Error::from)
}

/// As [`synth`], with the LiDAR's echoes from `cache` (a [`trace`] of a scenario that differs
/// from `s` at most in its seed and noise settings); the noise is `s`'s.
pub fn synth_traced(s: &Scenario, dir: &Path, cache: &TraceCache) -> Result<Truth, crate::Error> {
    synth_traced_written(s, dir, cache).map(|(t, _)| t)
}

/// [`synth_traced`], with each written data packet's index in the survey (the pcap's data
/// packets in order; lost and skipped ones are not written).
pub fn synth_traced_written(
    s: &Scenario,
    dir: &Path,
    cache: &TraceCache,
) -> Result<(Truth, Vec<u32>), crate::Error> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    s.with_world(|world| write_files(s, world, dir, Some(cache)))
        .map_err(|e| e.to_string())?
        .map(|(t, w, _)| (t, w))
}

fn write_files(
    s: &Scenario,
    world: &World<'_>,
    dir: &Path,
    cache: Option<&TraceCache>,
) -> Result<(Truth, Vec<u32>, Vec<std::path::PathBuf>), crate::Error> {
    // Every file goes to its temporary first and all are renamed at the end: an interrupted
    // or failed synth leaves no file of this run, none half-written ([`crate::output`]).
    let mut files = Vec::new();
    let (lidar, written) = write_lidar(s, world, dir, cache, &mut files)?;
    let ins = write_ins(s, world, dir, &mut files)?;
    if let Some(csv) = corrections_csv(s) {
        files.push(staged_bytes(&dir.join(CORRECTIONS), csv.as_bytes())?);
    }
    if let Some(json) = ouster_metadata(s) {
        files.push(staged_bytes(&dir.join(OUSTER_METADATA), json.as_bytes())?);
    }
    let site_path = dir.join("site.toml");
    files.push(staged_bytes(&site_path, site_of(s).to_toml().as_bytes())?);
    let truth = truth_of(s, &lidar, &ins);
    let truth_path = dir.join("truth.json");
    let json = serde_json::to_string_pretty(&truth).map_err(|e| e.to_string())?;
    files.push(staged_bytes(&truth_path, (json + "\n").as_bytes())?);
    let paths = files.iter().map(|f| f.path().to_path_buf()).collect();
    crate::output::commit_all(files)?;
    Ok((truth, written, paths))
}

/// The files a scenario's [`synth`] writes, by name (the POS MV's log only with a POS MV).
pub fn file_names(s: &Scenario) -> Vec<&'static str> {
    let mut v = vec!["lidar.pcap", "labels.bin", "ins.bin", "ins.vnlog"];
    if corrections_csv(s).is_some() {
        v.push(CORRECTIONS);
    }
    if ouster_metadata(s).is_some() {
        v.push(OUSTER_METADATA);
    }
    if s.ins.kind == "posmv" {
        v.extend(["ins.posmv", SBET, SMRMSG]);
    }
    if s.ins_config().correlated.is_on() {
        v.push(NAV_ERRORS);
    }
    v.extend(["site.toml", "truth.json"]);
    v
}

/// A Hesai's angle correction file, as `synth` names it.
pub const CORRECTIONS: &str = "corrections.csv";

/// The simulated Hesai's angle correction file (`Channel,Elevation,Azimuth`, the header
/// tier4/nebula's and Hesai's XT files have); `None` for a Velodyne.
fn corrections_csv(s: &Scenario) -> Option<String> {
    let sc = s.scanner()?;
    let mut out = String::from("Channel,Elevation,Azimuth\n");
    let mut k = 0;
    while let Some((ch, el, az)) = sc.correction_row(k) {
        out += &format!("{ch},{el},{az}\n");
        k += 1;
    }
    (k > 0).then_some(out)
}

/// An Ouster's metadata JSON, as `synth` names it.
pub const OUSTER_METADATA: &str = "metadata.json";

/// The simulated Ouster's metadata JSON (firmware 2.4+/3.x's nested layout, as `ouster-cli`
/// saves it): its beam tables, beam origin and lidar-to-sensor transform, the data format
/// (RNG19_RFL8_SIG16_NIR16, 16 columns of the model's pixels), the lidar mode from the rotation rate
/// and the clock (TIME_FROM_PTP_1588; with `[lidar] pps` not locked
/// TIME_FROM_INTERNAL_OSC, counting from power-on); `None` for the others.
fn ouster_metadata(s: &Scenario) -> Option<String> {
    use spherecal::sim::lidar::scanner::{OUSTER_COLUMNS, OUSTER_SERIAL};
    let sc = s.scanner()?;
    let spherecal::sim::Scanner::Ouster(model) = sc else {
        return None;
    };
    let spec = model.spec();
    let w = sc.columns_per_frame(s.lidar.rpm);
    let hz = (s.lidar.rpm / 60.0).round() as u32;
    let n = sc.lasers();
    let beams: Vec<_> = (0..n).map(|k| sc.beam(k)).collect();
    let origin_mm = spec.beam_origin_m * 1e3;
    let v = serde_json::json!({
        "beam_intrinsics": {
            "beam_altitude_angles": beams.iter().map(|b| b.elevation_deg).collect::<Vec<_>>(),
            "beam_azimuth_angles": beams.iter().map(|b| b.azimuth_offset_deg).collect::<Vec<_>>(),
            "beam_to_lidar_transform": [1.0, 0.0, 0.0, origin_mm, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            "lidar_origin_to_beam_origin_mm": origin_mm,
        },
        "calibration_status": {
            "reflectivity": { "timestamp": "2024-01-01T00:00:00", "valid": true },
        },
        "config_params": {
            "columns_per_packet": OUSTER_COLUMNS,
            "lidar_mode": format!("{w}x{hz}"),
            "timestamp_mode": match s.pps() {
                Some(spherecal::velodyne::PpsStatus::Locked) => "TIME_FROM_PTP_1588",
                _ => "TIME_FROM_INTERNAL_OSC",
            },
            "udp_port_imu": spherecal::ouster::IMU_PORT,
            "udp_port_lidar": spherecal::ouster::LIDAR_PORT,
            "udp_profile_imu": "LEGACY",
            "udp_profile_lidar": "RNG19_RFL8_SIG16_NIR16",
        },
        "imu_intrinsics": {
            "imu_to_sensor_transform": [1.0, 0.0, 0.0, 6.253, 0.0, 1.0, 0.0, -11.775, 0.0, 0.0, 1.0, 7.645, 0.0, 0.0, 0.0, 1.0],
        },
        "lidar_data_format": {
            "column_window": [0, w - 1],
            "columns_per_frame": w,
            "columns_per_packet": OUSTER_COLUMNS,
            "pixel_shift_by_row": beams.iter().map(|b| (b.azimuth_offset_deg * f64::from(w) / 360.0).round() as i64).collect::<Vec<_>>(),
            "pixels_per_column": n,
            "udp_profile_imu": "LEGACY",
            "udp_profile_lidar": "RNG19_RFL8_SIG16_NIR16",
        },
        "lidar_intrinsics": {
            "lidar_to_sensor_transform": [-1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, spec.lidar_z_m * 1e3, 0.0, 0.0, 0.0, 1.0],
        },
        "sensor_info": {
            "build_rev": "v2.4.0",
            "image_rev": "ousteros-image-prod-aries-v2.4.0 (spherecal synth)",
            "initialization_id": 6_070_752,
            "prod_line": sc.name(),
            "prod_sn": OUSTER_SERIAL.to_string(),
            "status": "RUNNING",
        },
    });
    serde_json::to_string_pretty(&v).ok()
}

fn staged_bytes(p: &Path, bytes: &[u8]) -> Result<Staged, crate::Error> {
    let mut f = Staged::create(p)?;
    f.write_all(bytes).map_err(|e| io(p, e))?;
    Ok(f)
}

fn io(p: &Path, e: std::io::Error) -> String {
    format!("{}: {e}", p.display())
}

/// lidar.pcap (as the sensor sends it, at the host's receive times) and labels.bin (what each
/// return hit); the simulator's counts.
fn write_lidar(
    s: &Scenario,
    world: &World<'_>,
    dir: &Path,
    cache: Option<&TraceCache>,
    files: &mut Vec<Staged>,
) -> Result<(LidarStats, Vec<u32>), crate::Error> {
    let pcap_path = dir.join("lidar.pcap");
    let mut pcap = PcapWriter::new(Staged::create(&pcap_path)?)
        .map_err(|e| format!("{}: {e}", pcap_path.display()))?;
    let mut lidar = LidarSim::new(world, s.lidar_config());
    if let Some(c) = cache {
        if c.offsets.len() != lidar.packet_count() as usize + 1 {
            return Err(format!(
                "{}: the trace is of another scene ({} data packets, this one has {})",
                s.name,
                c.offsets.len().saturating_sub(1),
                lidar.packet_count()
            )
            .into());
        }
    }
    let mut data_k = 0usize;
    let bar = crate::progress::bar(lidar.packet_count(), "simulating data packets");
    let labels_path = dir.join("labels.bin");
    let mut labels = Staged::create(&labels_path)?;
    let mut head = [0u8; 16];
    head[..8].copy_from_slice(LABELS_MAGIC);
    head[8..12].copy_from_slice(&1u32.to_le_bytes());
    head[12..].copy_from_slice(&12u32.to_le_bytes());
    labels.write_all(&head).map_err(|e| io(&labels_path, e))?;
    let mut packet_index = 0u32;
    let ep = UdpEndpoints::default();
    let mut payload = [0u8; spherecal::sim::lidar::MAX_PACKET_LEN];
    let mut frame = Vec::with_capacity(1300);
    // A POS MV on the same network: its datagrams (one per sample, as the Real-Time Data Port
    // sends them) merged in receive order.
    let mut posmv = (s.ins.kind == "posmv").then(|| InsSim::new(world, s.ins_config()));
    let mut posmv_next: Option<(HostTime, Vec<u8>)> = None;
    let mut posmv_buf = [0u8; 1024];
    let mut pull_posmv = |posmv: &mut Option<InsSim<'_, '_>>| -> Option<(HostTime, Vec<u8>)> {
        let sim = posmv.as_mut()?;
        let (t, n) = sim.next_posmv(&mut posmv_buf)?;
        let host = HostTime(gps_to_unix_ns(t, s.leap_seconds) + POSMV_DELAY_NS);
        Some((host, posmv_buf[..n].to_vec()))
    };
    posmv_next = posmv_next.or_else(|| pull_posmv(&mut posmv));
    let mut write_posmv_until = |until: Option<HostTime>,
                                 posmv: &mut Option<InsSim<'_, '_>>,
                                 next: &mut Option<(HostTime, Vec<u8>)>,
                                 pcap: &mut PcapWriter<_>,
                                 frame: &mut Vec<u8>|
     -> Result<(), crate::Error> {
        while let Some((h, bytes)) = next.take() {
            if until.is_some_and(|u| h > u) {
                *next = Some((h, bytes));
                break;
            }
            build_udp_frame(frame, &ep, POSMV_PORT, POSMV_PORT, &bytes)
                .map_err(|e| io(&pcap_path, e))?;
            pcap.write_frame(h, frame)
                .map_err(|e| format!("{}: {e}", pcap_path.display()))?;
            *next = pull_posmv(posmv);
        }
        Ok(())
    };
    let mut written = Vec::new();
    loop {
        let next = match cache {
            Some(c) if c.skips(data_k) => lidar.skip_packet(&mut payload),
            Some(c) => lidar.next_packet_replayed(&mut payload, c.packet(data_k)),
            None => lidar.next_packet(&mut payload),
        };
        let Some(pkt) = next else { break };
        if let SimPacket::Data { .. } = pkt {
            data_k += 1;
            if data_k.is_multiple_of(1024) {
                bar.set_position(data_k as u64);
            }
        }
        let time = match pkt {
            SimPacket::Data { dropped: true, .. } => continue,
            SimPacket::Data { time, .. } => {
                for h in &lidar.hits {
                    let mut r = [0u8; 12];
                    r[..4].copy_from_slice(&packet_index.to_le_bytes());
                    r[4] = h.block;
                    r[5] = h.channel;
                    r[6..8].copy_from_slice(&h.object.to_le_bytes());
                    r[8] = h.purity;
                    labels.write_all(&r).map_err(|e| io(&labels_path, e))?;
                }
                packet_index += 1;
                written.push((data_k - 1) as u32);
                time
            }
            SimPacket::Position { time } => time,
        };
        let (port, len) = lidar.port_len(&pkt);
        build_udp_frame(&mut frame, &ep, port, port, &payload[..len])
            .map_err(|e| io(&pcap_path, e))?;
        let host = HostTime(gps_to_unix_ns(time, s.leap_seconds) + NETWORK_DELAY_NS);
        if posmv_next.is_some() {
            let mut f2 = Vec::with_capacity(1300);
            write_posmv_until(Some(host), &mut posmv, &mut posmv_next, &mut pcap, &mut f2)?;
        }
        pcap.write_frame(host, &frame)
            .map_err(|e| format!("{}: {e}", pcap_path.display()))?;
    }
    write_posmv_until(None, &mut posmv, &mut posmv_next, &mut pcap, &mut frame)?;
    files.push(pcap.into_inner());
    files.push(labels);

    bar.finish_and_clear();
    Ok((lidar.stats, written))
}

/// ins.bin, and the same bytes as a serial log with the times a rig would have received
/// them (sample time + output latency + transmission at the baud rate), for replay.
/// Fewer returns than this on a sphere and `synth` / `plan` say why.
pub const FEW_RETURNS: u64 = 30;

/// Why sphere `j` of a scenario gets few or no returns, in words (the survey sampled every
/// 0.25 s: range, the lasers' fan, what stands in the line of sight, the LiDAR inside an
/// object); `None` when nothing explains it.
pub fn why_unseen(s: &Scenario, j: usize) -> Option<String> {
    let scene = s.scene();
    let lidar = s.lidar_config();
    let v = s
        .with_world(|w| {
            spherecal::sim::visibility::visibility(w, lidar.scanner, lidar.max_range, j as u8, 0.25)
        })
        .ok()?;
    let name = |i: usize| {
        scene
            .names
            .get(i)
            .cloned()
            .unwrap_or_else(|| format!("object {i}"))
    };
    let id = s.sphere.get(j).map_or("?", |sp| sp.id.as_str());
    let pct = |n: u32, of: u32| 100.0 * f64::from(n) / f64::from(of.max(1));
    if let Some((i, n)) = v.lidar_inside {
        if n * 2 >= v.samples {
            return Some(format!(
                "{id}: the LiDAR is inside {} ({:.0} % of the survey): the mounting puts it there",
                name(i),
                pct(n, v.samples)
            ));
        }
    }
    if v.in_range == 0 {
        return Some(format!(
            "{id}: never within the LiDAR's range ({:.0} m) of the survey",
            lidar.max_range
        ));
    }
    if v.on_a_laser == 0 {
        let (a, b) = v.elevation_deg.unwrap_or((0.0, 0.0));
        let (lo, hi) = lidar.scanner.elevation_span_deg();
        return Some(format!(
            "{id}: never on a laser: it is {a:.1} to {b:.1} deg above the LiDAR's equator, its lasers {lo:.1} to {hi:.1} deg"
        ));
    }
    if let Some((i, n)) = v.blocker {
        if v.seen * 4 < v.on_a_laser {
            return Some(format!(
                "{id}: hidden by {} ({:.0} % of the times a laser points at it; in sight {:.0} %)",
                name(i),
                pct(n, v.on_a_laser),
                pct(v.seen, v.on_a_laser)
            ));
        }
    }
    None
}

/// The site file a surveyor would write for the scenario: the spheres' surveyed centres and
/// the a-priori mounting.
fn site_of(s: &Scenario) -> Site {
    let site_frame = s.site();
    let correlated = s
        .ins
        .correlated
        .resolve("ins.correlated")
        .is_ok_and(|c| c.is_on());
    Site {
        datum: None,
        geodetic: None,
        base: std::path::PathBuf::new(),
        leap_seconds: s.leap_seconds,
        crs: None,
        origin: Origin {
            lat_deg: s.site.lat_deg,
            lon_deg: s.site.lon_deg,
            h_m: s.site.h_m,
        },
        sphere: s
            .sphere
            .iter()
            .map(|sp| {
                let g = site_frame.to_geodetic(&nalgebra::Vector3::from(sp.ned_m));
                SiteSphere::wgs84(
                    &sp.id,
                    g.lat.to_degrees(),
                    g.lon.to_degrees(),
                    g.h,
                    sp.radius_m,
                )
            })
            .collect(),
        apriori: SiteApriori {
            boresight_deg: s.mount.apriori.boresight_deg,
            lever_arm_m: s.mount.apriori.lever_arm_m,
            window_margin_m: s.mount.apriori.window_margin_m,
            boresight_sigma_deg: None,
            lever_arm_sigma_m: None,
        },
        // A survey whose INS errors wander declares them, with the white noise on top (what
        // a surveyor reads off the INS's and the LiDAR's sheets).
        noise: correlated.then(|| SiteNoise {
            range_m: s.lidar.range_sigma_m.max(0.005),
            attitude_deg: s.ins.att_sigma_deg,
            position_m: s.ins.pos_sigma_m,
        }),
        // The beam whose bloom the calibration is to model: the simulated one where it is
        // rendered as the beam's Gaussian, else none (zeros: an ideal ray, or the five
        // sub-rays' staircase, which the model does not follow).
        lidar: Some(crate::config::lidar::SiteLidar {
            beam_divergence_mrad: if s.lidar.footprint_grid {
                s.lidar.beam_divergence_mrad
            } else {
                [0.0, 0.0]
            },
        }),
        // ... and one whose errors are white says so (else the calibration would take a model
        // from the INS's kind).
        ins: Some(SiteIns {
            correlated: if correlated {
                s.ins.correlated.clone()
            } else {
                crate::config::nav_errors::CorrelatedSpec::preset_only("white")
            },
        }),
        calibration: None,
    }
}

/// What the simulator knows and the files do not say.
fn truth_of(s: &Scenario, st: &LidarStats, ins: &InsStats) -> Truth {
    let scene = s.scene();
    Truth {
        scenario: s.name.clone(),
        boresight_deg: named(["roll", "pitch", "heading"], s.mount.truth.boresight_deg),
        lever_arm_m: named(["x", "y", "z"], s.mount.truth.lever_arm_m),
        leap_seconds: s.leap_seconds,
        points_per_sphere: st.hits[..s.sphere.len()].to_vec(),
        clutter_points: st.clutter_hits,
        rays_traced: st.rays,
        data_packets: st.data_packets - st.dropped,
        dropped_packets: st.dropped,
        position_packets: st.position_packets,
        ins_frames: ins.frames,
        corrupted_bytes: ins.corrupted_bytes,
        mixed_points: st.mixed,
        objects: scene
            .names
            .iter()
            .zip(&scene.kinds)
            .map(|(n, k)| TruthObject {
                name: n.clone(),
                kind: k.to_string(),
            })
            .collect(),
    }
}

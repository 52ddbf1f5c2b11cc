//! The sensor's metadata JSON (what `ouster-cli` or the sensor's `/api/v1/sensor/metadata`
//! writes beside a capture): the packet format, the beams' geometry, the ports and the
//! timestamp mode. Both layouts are read: the flat one of firmware 2.0-2.3 (`data_format`,
//! `beam_altitude_angles`, `lidar_origin_to_beam_origin_mm`, ... at the top) and the nested
//! one of firmware 2.4+ and 3.x (`lidar_data_format`, `beam_intrinsics`, `lidar_intrinsics`,
//! `config_params`, `sensor_info`).

use serde_json::Value;
use spherecal::ouster::{Format, Intrinsics, Profile};
use std::path::Path;

/// Where the column timestamps come from (`timestamp_mode`, firmware manual "Time Modes").
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TimestampMode {
    /// `TIME_FROM_INTERNAL_OSC`: the sensor's oscillator, from power-on.
    InternalOsc,
    /// `TIME_FROM_SYNC_PULSE_IN`: a pulse per second (with NMEA: UTC).
    SyncPulseIn,
    /// `TIME_FROM_PTP_1588`: a PTP grandmaster (TAI).
    Ptp,
    /// A mode spherecal does not know, by its name.
    Other(String),
}

impl TimestampMode {
    /// From the metadata's name.
    pub fn from_name(name: &str) -> Self {
        match name {
            "TIME_FROM_INTERNAL_OSC" => Self::InternalOsc,
            "TIME_FROM_SYNC_PULSE_IN" => Self::SyncPulseIn,
            "TIME_FROM_PTP_1588" => Self::Ptp,
            other => Self::Other(other.into()),
        }
    }

    /// The metadata's name.
    pub fn name(&self) -> &str {
        match self {
            Self::InternalOsc => "TIME_FROM_INTERNAL_OSC",
            Self::SyncPulseIn => "TIME_FROM_SYNC_PULSE_IN",
            Self::Ptp => "TIME_FROM_PTP_1588",
            Self::Other(n) => n,
        }
    }
}

/// What a capture's metadata says.
#[derive(Debug, Clone)]
pub struct Metadata {
    /// The lidar packets' layout.
    pub format: Format,
    /// The profile's name as the metadata gives it.
    pub profile_name: String,
    /// The beams' geometry.
    pub intrinsics: Intrinsics,
    /// Columns per frame (512, 1024, 2048, 4096).
    pub columns_per_frame: usize,
    /// UDP ports of lidar and IMU packets.
    pub lidar_port: u16,
    /// UDP port of IMU packets.
    pub imu_port: u16,
    /// `timestamp_mode`, when the metadata gives it.
    pub timestamp_mode: Option<TimestampMode>,
    /// `prod_line` (e.g. `OS-1-64`), the serial number and the firmware.
    pub product: String,
    /// `prod_sn`.
    pub serial: String,
    /// `build_rev`.
    pub firmware: String,
    /// Frames a second (`lidar_mode`'s second number: 1024x10 is 10; 10 when not said).
    pub frame_hz: u32,
}

/// Why a metadata file cannot be used.
fn bad(path: &Path, what: impl std::fmt::Display) -> crate::Error {
    crate::Error::bad_input(format!("{}: {what}", path.display()))
}

impl Metadata {
    /// Time from one column to the next [ns]: a frame's period over its columns.
    pub fn column_period_ns(&self) -> i64 {
        1_000_000_000 / (i64::from(self.frame_hz) * self.columns_per_frame as i64).max(1)
    }

    /// Read `path`.
    pub fn load(path: &Path) -> Result<Self, crate::Error> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| crate::Error::bad_input(format!("{}: {e}", path.display())))?;
        let v: Value =
            serde_json::from_str(&text).map_err(|e| bad(path, format!("not JSON: {e}")))?;
        Self::parse(&v).map_err(|e| bad(path, e))
    }

    /// From the parsed JSON; the error names the key that is missing or wrong.
    pub fn parse(v: &Value) -> Result<Self, String> {
        // The nested layout's sections; the flat one has the same keys at the top.
        let sec = |name: &str| v.get(name).filter(|s| s.is_object()).unwrap_or(v);
        let fmt = v
            .get("lidar_data_format")
            .or_else(|| v.get("data_format"))
            .ok_or("no `lidar_data_format` (or `data_format`): not an Ouster sensor's metadata")?;
        let config = sec("config_params");
        let info = sec("sensor_info");
        let (format, profile_name) = format_of(fmt, config)?;
        let per_frame = count(fmt, "columns_per_frame", spherecal::ouster::MAX_COLUMNS)?;
        let intrinsics = intrinsics_of(
            sec("beam_intrinsics"),
            sec("lidar_intrinsics"),
            format.pixels,
            per_frame,
        )?;
        let port = |k: &str, default: u16| -> Result<u16, String> {
            match config.get(k).or_else(|| v.get(k)) {
                None | Some(Value::Null) => Ok(default),
                Some(p) => p
                    .as_u64()
                    .and_then(|p| u16::try_from(p).ok())
                    .filter(|p| *p > 0)
                    .ok_or(format!("`{k}` = {p}: not a UDP port")),
            }
        };
        let text = |o: &Value, k: &str| o.get(k).and_then(Value::as_str).map(str::to_string);
        Ok(Self {
            format,
            profile_name,
            intrinsics,
            columns_per_frame: per_frame,
            lidar_port: port("udp_port_lidar", spherecal::ouster::LIDAR_PORT)?,
            imu_port: port("udp_port_imu", spherecal::ouster::IMU_PORT)?,
            timestamp_mode: text(config, "timestamp_mode").map(|t| TimestampMode::from_name(&t)),
            product: text(info, "prod_line").unwrap_or_default(),
            serial: text(info, "prod_sn").unwrap_or_default(),
            firmware: text(info, "build_rev").unwrap_or_default(),
            frame_hz: text(config, "lidar_mode")
                .and_then(|m| m.split_once('x').and_then(|(_, hz)| hz.parse().ok()))
                .filter(|hz| (1..=100).contains(hz))
                .unwrap_or(10),
        })
    }
}

/// Number `k` of `o`, finite.
fn num(o: &Value, k: &str) -> Result<f64, String> {
    o.get(k)
        .and_then(Value::as_f64)
        .filter(|x| x.is_finite())
        .ok_or(format!("`{k}` missing or not a number"))
}

/// List `k` of `o`, every value a finite number.
fn list(o: &Value, k: &str) -> Result<Vec<f64>, String> {
    let a = o
        .get(k)
        .and_then(Value::as_array)
        .ok_or(format!("`{k}` missing or not a list"))?;
    a.iter()
        .map(|x| x.as_f64().filter(|x| x.is_finite()))
        .collect::<Option<Vec<f64>>>()
        .ok_or(format!("`{k}` holds a value that is not a number"))
}

/// Whole number `k` of `o`, 1 to `hi`.
fn count(o: &Value, k: &str, hi: usize) -> Result<usize, String> {
    let x = num(o, k)?;
    if x.fract() != 0.0 || !(1.0..=hi as f64).contains(&x) {
        return Err(format!("`{k}` = {x}: expected a whole number 1-{hi}"));
    }
    Ok(x as usize)
}

/// The packet format the data format (`fmt`) and the configuration declare, and the profile's
/// name (no `udp_profile_lidar`: firmware 2.0-2.1's LEGACY).
fn format_of(fmt: &Value, config: &Value) -> Result<(Format, String), String> {
    let pixels = count(fmt, "pixels_per_column", spherecal::ouster::MAX_BEAMS)?;
    let columns = count(fmt, "columns_per_packet", 64)?;
    let name = fmt
        .get("udp_profile_lidar")
        .or_else(|| config.get("udp_profile_lidar"))
        .and_then(Value::as_str)
        .unwrap_or("LEGACY")
        .to_string();
    let (profile, header) = Profile::from_name(&name).ok_or(format!(
        "`udp_profile_lidar` = {name}: spherecal reads LEGACY, RNG19_RFL8_SIG16_NIR16(_DUAL) and RNG15_RFL8_NIR8(_DUAL)"
    ))?;
    let format = Format::new(profile, header, columns, pixels)
        .map_err(|e| format!("the data format: {e}"))?;
    Ok((format, name))
}

/// The beams' geometry (`beams`: their angles and origin; `lidar`: the lidar-to-sensor
/// transform) for `pixels` beams and `per_frame` columns.
fn intrinsics_of(
    beams: &Value,
    lidar: &Value,
    pixels: usize,
    per_frame: usize,
) -> Result<Intrinsics, String> {
    let alt = list(beams, "beam_altitude_angles")?;
    let az = list(beams, "beam_azimuth_angles")?;
    if alt.len() != pixels || az.len() != pixels {
        return Err(format!(
            "{} altitude and {} azimuth angles for {pixels} pixels per column",
            alt.len(),
            az.len()
        ));
    }
    // The beam origin: `beam_to_lidar_transform`'s translation (x, z), else the older
    // `lidar_origin_to_beam_origin_mm` along x.
    let origin = match list(beams, "beam_to_lidar_transform") {
        Ok(t) if t.len() == 16 => [t[3], t[11]],
        Ok(t) => {
            return Err(format!(
                "`beam_to_lidar_transform` has {} values, not 16",
                t.len()
            ))
        }
        Err(_) => [num(beams, "lidar_origin_to_beam_origin_mm")?, 0.0],
    };
    let l2s: [f64; 16] = list(lidar, "lidar_to_sensor_transform")?
        .try_into()
        .map_err(|t: Vec<f64>| {
            format!("`lidar_to_sensor_transform` has {} values, not 16", t.len())
        })?;
    Intrinsics::new(&alt, &az, per_frame, origin, &l2s)
        .ok_or("the beam tables are not a sensor's".into())
}

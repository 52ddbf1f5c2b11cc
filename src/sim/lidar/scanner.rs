//! What the simulator needs of a scanner, for each family it writes: the beams, the firing
//! schedule, the azimuth a decoder gives each firing, and the packets.
//!
//! - Velodyne (VLP-16, Puck Hi-Res, HDL-32E, VLP-32C): 12 blocks of 32 channels, the packet
//!   stamped at its first firing (microseconds past the hour), the azimuth interpolated within
//!   a block (manual 9.5); position packets with `$GPRMC` and the PPS state (UDP 8308).
//! - Hesai PandarXT16 / XT32: 8 blocks of 16 / 32 channels, a firing every 50 us, the packet's
//!   absolute time (UTC date-time + microseconds) the trigger of its last firing, a channel's
//!   azimuth its block's plus its correction, 4 mm distances (PandarXT-32 manual 3.1.2 and the
//!   appendix "Absolute Time and Laser Firing Time"); GPS packets once a second (UDP 10110).
//!   The beams are the manual's nominal channel table (elevation 15 deg down in 1 deg steps
//!   (XT32) or 2 deg steps (XT16), no azimuth correction), which [`Scanner::correction_row`]
//!   writes as the unit's correction file.
//! - Ouster OS0-128, OS1-64, OS1-128 and OS2-128 (firmware 2.2+, the RNG19_RFL8_SIG16_NIR16
//!   profile, 16 columns a packet, UDP 7502): a column of 64 or 128 pixels every 97.656 us (10,240 columns a second: 1024x10 at 600 rpm,
//!   512x20 at 1200), every beam of a column fired at the column's timestamp (PTP: TAI
//!   nanoseconds), measurement id `m` at the encoder angle `2 pi (1 - m / W)`; a beam's point
//!   per the firmware manual's "Lidar Range to XYZ" with the model's beam origin `n` (e.g. the
//!   OS1's 15.806 mm from the axis) and lidar-to-sensor transform (x and y turned over, z +
//!   `h`, e.g. 36.18 mm). In the sensor frame with the Velodyne's azimuth (clockwise from +y)
//!   that is: the column's azimuth `A = 2 pi m / W - pi / 2`, the beam's `A + azimuth_i`, the
//!   point `r u + n (sin A, cos A, 0) + (0, 0, h) - n u`. Nominal tables ([`OusterSpec`]):
//!   altitudes evenly over the model's vertical field of view, azimuths staggered in fours
//!   (the shape of the units' own tables), which `synth` writes into the metadata JSON.

use crate::time::{gps_to_unix_ns, micros_past_hour, GpsTime, UtcDateTime};
use crate::velodyne::position::{write_gprmc, POSITION_PACKET_LEN};
use crate::velodyne::{
    self, Beam, Model, PositionPacket, PpsStatus, ReturnMode, DATA_PORT, POSITION_PORT,
};
use crate::{hesai, ouster};

/// Most blocks a packet of any scanner has.
pub const MAX_BLOCKS: usize = 16;

/// The Hesai XT's time between firings [ns] (20 kHz).
const HESAI_FIRING_NS: u32 = 50_000;

/// Most lasers (pixels per column) of a scanner simulated.
pub const SIM_LASERS: usize = 128;

/// An Ouster's columns a second (1024x10, 512x20, 2048x5).
pub const OUSTER_COLUMN_HZ: u32 = 10_240;
/// ... columns per packet.
pub const OUSTER_COLUMNS: usize = 16;
/// An Ouster model simulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ouster {
    /// OS0-128 (90 deg vertical field).
    Os0_128,
    /// OS1-64 (Gen 1 beam layout).
    Os1_64,
    /// OS1-128 (45 deg).
    Os1_128,
    /// OS2-128 (22.5 deg).
    Os2_128,
}

/// What the simulator takes of an Ouster model: nominal figures of the kind its metadata
/// gives (the units' own tables differ by a few hundredths of a degree; the decoder and the
/// calibration read them from the metadata `synth` writes, never from here).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OusterSpec {
    /// `prod_line`.
    pub name: &'static str,
    /// `synth --model`'s key.
    pub key: &'static str,
    /// Pixels (beams) per column.
    pub pixels: usize,
    /// The top beam's altitude [deg]; the bottom one's is its negative.
    pub top_deg: f64,
    /// The beam azimuths [deg], by beam modulo 4.
    pub azimuths_deg: [f64; 4],
    /// `lidar_origin_to_beam_origin_mm` [m].
    pub beam_origin_m: f64,
    /// `lidar_to_sensor_transform`'s z [m].
    pub lidar_z_m: f64,
}

/// The Ouster models' figures, in [`Ouster`]'s order: `prod_line`, key, pixels, the top
/// altitude [deg], the azimuth stagger [deg] (its first two; the others their negatives), the
/// beam origin and the lidar-to-sensor z [m] ([`Ouster::spec`]).
#[rustfmt::skip]
#[allow(clippy::type_complexity)]
const OUSTER_SPECS: [(&str, &str, usize, f64, [f64; 2], f64, f64); 4] = [
    ("OS-0-128", "os0-128", 128, 45.0, [10.7, 3.6], 0.027_67, 0.036_18),
    ("OS-1-64", "os1-64", 64, 16.6, [3.1, 1.0], 0.015_806, 0.036_18),
    ("OS-1-128", "os1-128", 128, 22.5, [4.2, 1.4], 0.016_721, 0.038_195),
    ("OS-2-128", "os2-128", 128, 11.25, [2.1, 0.7], 0.013_762, 0.036_18),
];

impl Ouster {
    /// The simulated packet format: RNG19_RFL8_SIG16_NIR16, 16 columns of the model's pixels.
    pub fn format(self) -> ouster::Format {
        ouster::Format {
            profile: ouster::Profile::Single,
            header: ouster::HeaderKind::Standard,
            columns: OUSTER_COLUMNS,
            pixels: self.spec().pixels,
        }
    }

    /// Every Ouster model simulated.
    pub const ALL: [Ouster; 4] = [
        Ouster::Os0_128,
        Ouster::Os1_64,
        Ouster::Os1_128,
        Ouster::Os2_128,
    ];

    /// The model's figures: fields of view from the datasheets (OS0 90 deg, OS1 45 deg (the
    /// Gen 1 OS1-64 33.2 deg), OS2 22.5 deg), beam origins from the units' metadata (OS0
    /// 27.67 mm, OS1 Gen 1 15.806 mm, OS1 rev 7 16.721 mm, OS2 13.762 mm), the azimuth stagger
    /// scaled with the field as the vendored captures' tables are.
    pub const fn spec(self) -> OusterSpec {
        let (name, key, pixels, top_deg, a, beam_origin_m, lidar_z_m) = OUSTER_SPECS[self as usize];
        OusterSpec {
            name,
            key,
            pixels,
            top_deg,
            azimuths_deg: [a[0], a[1], -a[1], -a[0]],
            beam_origin_m,
            lidar_z_m,
        }
    }
}

/// A scanner the simulator writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scanner {
    /// A Velodyne.
    Velodyne(Model),
    /// A Hesai PandarXT16 or XT32 (the QT's are read, not simulated).
    Hesai(hesai::Model),
    /// An Ouster.
    Ouster(Ouster),
}

impl Default for Scanner {
    fn default() -> Self {
        Scanner::Velodyne(Model::Vlp16)
    }
}

impl From<Model> for Scanner {
    fn from(m: Model) -> Self {
        Scanner::Velodyne(m)
    }
}

impl Scanner {
    /// [`OUSTER_COLUMNS`] as a `u64`.
    pub(super) const OUSTER_COLUMNS_U64: u64 = OUSTER_COLUMNS as u64;

    /// Every scanner the simulator writes.
    pub const ALL: [Scanner; 10] = [
        Scanner::Velodyne(Model::Vlp16),
        Scanner::Velodyne(Model::PuckHiRes),
        Scanner::Velodyne(Model::Hdl32e),
        Scanner::Velodyne(Model::Vlp32c),
        Scanner::Hesai(hesai::Model::Xt16),
        Scanner::Hesai(hesai::Model::Xt32),
        Scanner::Ouster(Ouster::Os0_128),
        Scanner::Ouster(Ouster::Os1_64),
        Scanner::Ouster(Ouster::Os1_128),
        Scanner::Ouster(Ouster::Os2_128),
    ];

    /// The scanner of a scenario's key: a Velodyne model's (`vlp16` ...), `xt16`, `xt32` or an
    /// Ouster's (`os1-64`, or its `prod_line` `OS-1-64`).
    pub fn parse(s: &str) -> Option<Self> {
        let named = |names: &[&str]| names.iter().any(|n| n.eq_ignore_ascii_case(s));
        if named(&["xt16", "pandarxt16", "pandarxt-16"]) {
            Some(Scanner::Hesai(hesai::Model::Xt16))
        } else if named(&["xt32", "pandarxt32", "pandarxt-32"]) {
            Some(Scanner::Hesai(hesai::Model::Xt32))
        } else if let Some(o) = Ouster::ALL
            .into_iter()
            .find(|o| named(&[o.spec().key, o.spec().name]))
        {
            Some(Scanner::Ouster(o))
        } else {
            Model::parse(s).map(Scanner::Velodyne)
        }
    }

    /// The key [`Self::parse`] takes.
    pub fn key(self) -> &'static str {
        match self {
            Scanner::Velodyne(m) => m.key(),
            Scanner::Hesai(hesai::Model::Xt16) => "xt16",
            Scanner::Hesai(_) => "xt32",
            Scanner::Ouster(o) => o.spec().key,
        }
    }

    /// The maker's name of the model.
    pub fn name(self) -> &'static str {
        match self {
            Scanner::Velodyne(m) => m.name(),
            Scanner::Hesai(m) => m.name(),
            Scanner::Ouster(o) => o.spec().name,
        }
    }

    /// The Velodyne model, if it is one.
    pub fn velodyne(self) -> Option<Model> {
        match self {
            Scanner::Velodyne(m) => Some(m),
            _ => None,
        }
    }

    /// Lasers (Hesai: channels).
    pub fn lasers(self) -> usize {
        match self {
            Scanner::Velodyne(m) => m.lasers(),
            Scanner::Hesai(m) => m.channels(),
            Scanner::Ouster(o) => o.spec().pixels,
        }
    }

    /// Laser `laser`'s geometry.
    pub fn beam(self, laser: usize) -> Beam {
        match self {
            Scanner::Velodyne(m) => *m.beam(laser),
            Scanner::Hesai(m) => {
                let step = if m == hesai::Model::Xt16 { 2.0 } else { 1.0 };
                let el = 15.0 - step * (laser % m.channels()) as f64;
                let (sin_el, cos_el) = libm::sincos(el.to_radians());
                Beam {
                    elevation_deg: el,
                    azimuth_offset_deg: 0.0,
                    vertical_offset_m: 0.0,
                    cos_el,
                    sin_el,
                    cos_az: 1.0,
                    sin_az: 0.0,
                }
            }
            Scanner::Ouster(o) => {
                let o = o.spec();
                let i = laser % o.pixels;
                let el = o.top_deg - 2.0 * o.top_deg * i as f64 / (o.pixels - 1) as f64;
                let az = o.azimuths_deg[i % 4];
                let (sin_el, cos_el) = libm::sincos(el.to_radians());
                let (sin_az, cos_az) = libm::sincos(az.to_radians());
                Beam {
                    elevation_deg: el,
                    azimuth_offset_deg: az,
                    vertical_offset_m: o.lidar_z_m,
                    cos_el,
                    sin_el,
                    cos_az,
                    sin_az,
                }
            }
        }
    }

    /// The beam origin's distance from the spin axis [m]: an Ouster's origin turns with the
    /// column (`n (sin A, cos A, 0) - n u`); 0 for the others.
    pub fn beam_origin_radius_m(self) -> f64 {
        match self {
            Scanner::Ouster(o) => o.spec().beam_origin_m,
            _ => 0.0,
        }
    }

    /// Columns per frame at `rpm` (an Ouster's `columns_per_frame`; 0 for the others).
    pub fn columns_per_frame(self, rpm: f64) -> u32 {
        match self {
            Scanner::Ouster(_) => libm::round(f64::from(OUSTER_COLUMN_HZ) * 60.0 / rpm) as u32,
            _ => 0,
        }
    }

    /// Row `laser` of the unit's correction file (`channel,elevation,azimuth`, channel from
    /// 1), for the Hesai; `None` for a Velodyne or beyond the channels.
    pub fn correction_row(self, laser: usize) -> Option<(usize, f64, f64)> {
        match self {
            Scanner::Hesai(m) if laser < m.channels() => {
                let b = self.beam(laser);
                Some((laser + 1, b.elevation_deg, b.azimuth_offset_deg))
            }
            _ => None,
        }
    }

    /// The lowest and highest elevation [deg].
    pub fn elevation_span_deg(self) -> (f64, f64) {
        (0..self.lasers())
            .map(|k| self.beam(k).elevation_deg)
            .fold((f64::MAX, f64::MIN), |(lo, hi), e| (lo.min(e), hi.max(e)))
    }

    /// Blocks per packet.
    pub fn blocks(self) -> usize {
        match self {
            Scanner::Velodyne(_) => velodyne::data::field::BLOCKS,
            Scanner::Hesai(m) => m.blocks(),
            Scanner::Ouster(_) => OUSTER_COLUMNS,
        }
    }

    /// Channels per block.
    pub fn channels(self) -> usize {
        match self {
            Scanner::Velodyne(_) => velodyne::data::field::CHANNELS,
            Scanner::Hesai(m) => m.channels(),
            Scanner::Ouster(o) => o.spec().pixels,
        }
    }

    /// The laser of a block's channel `ch`.
    pub fn laser_of(self, ch: usize) -> usize {
        match self {
            Scanner::Velodyne(m) => usize::from(m.channels()[ch % 32].laser),
            Scanner::Hesai(m) => ch % m.channels(),
            Scanner::Ouster(o) => ch % o.spec().pixels,
        }
    }

    /// Time from one firing (block) to the next [ns].
    pub fn block_ns(self) -> u32 {
        match self {
            Scanner::Velodyne(m) => m.block_ns(),
            Scanner::Hesai(_) => HESAI_FIRING_NS,
            Scanner::Ouster(_) => 1_000_000_000 / OUSTER_COLUMN_HZ,
        }
    }

    /// Time between two firings of one laser [ns].
    pub fn laser_period_ns(self) -> u32 {
        match self {
            Scanner::Ouster(_) => self.block_ns(),
            Scanner::Velodyne(m) => m.laser_period_ns(),
            Scanner::Hesai(_) => HESAI_FIRING_NS,
        }
    }

    /// Time between two data packets [ns].
    pub fn packet_period_ns(self, mode: ReturnMode) -> i64 {
        let dual = mode == ReturnMode::Dual;
        match self {
            Scanner::Velodyne(m) => i64::from(m.packet_period_ns(dual)),
            Scanner::Hesai(m) => {
                i64::from(HESAI_FIRING_NS) * (m.blocks() / if dual { 2 } else { 1 }) as i64
            }
            Scanner::Ouster(_) => {
                OUSTER_COLUMNS as i64 * 1_000_000_000 / i64::from(OUSTER_COLUMN_HZ)
            }
        }
    }

    /// Firing time of channel `ch` in block `b` after the packet's first firing [ns].
    pub fn firing_offset_ns(self, mode: ReturnMode, b: usize, ch: usize) -> i64 {
        match self {
            Scanner::Velodyne(m) => i64::from(velodyne::firing::firing_offset_ns(m, mode, b, ch)),
            Scanner::Hesai(m) => {
                let n = if mode == ReturnMode::Dual { 2 } else { 1 };
                m.firing_offset_ns(b, ch, n, 1) - m.firing_offset_ns(0, 0, n, 1)
            }
            // Every beam of a column at its timestamp, the columns evenly in the packet.
            Scanner::Ouster(_) => {
                self.packet_period_ns(mode) * (b % OUSTER_COLUMNS) as i64 / OUSTER_COLUMNS as i64
            }
        }
    }

    /// Distance unit [m].
    pub fn distance_unit_m(self) -> f64 {
        match self {
            Scanner::Velodyne(m) => m.distance_unit_m(),
            Scanner::Hesai(_) => 0.004,
            Scanner::Ouster(_) => 0.001,
        }
    }

    /// The farthest range reported [m] (the XT's datasheet: 120 m at 80 % reflectivity).
    pub fn max_range_m(self) -> f64 {
        match self {
            Scanner::Velodyne(m) => m.max_range_m(),
            Scanner::Hesai(_) | Scanner::Ouster(_) => 120.0,
        }
    }

    /// The datasheet's range accuracy, taken as one sigma [m]: VLP-16, VLP-32C and Puck
    /// Hi-Res +-3 cm typical, HDL-32E < 2 cm (1 sigma at 25 m), Hesai XT +-1 cm typical, Ouster
    /// OS +-3 cm (the OS1 datasheet's 1-sigma repeatability at an SNR of 100).
    pub fn range_sigma_m(self) -> f64 {
        match self {
            Scanner::Velodyne(Model::Hdl32e) => 0.02,
            Scanner::Hesai(_) => 0.01,
            Scanner::Velodyne(_) | Scanner::Ouster(_) => 0.03,
        }
    }

    /// A data packet's UDP port and length.
    pub fn data_port_len(self) -> (u16, usize) {
        match self {
            Scanner::Velodyne(_) => (DATA_PORT, velodyne::data::DATA_PACKET_LEN),
            Scanner::Hesai(m) => (hesai::DATA_PORT, m.emitted_len()),
            Scanner::Ouster(o) => (ouster::LIDAR_PORT, o.format().packet_len()),
        }
    }

    /// The once-a-second time packet's UDP port and length (Velodyne position, Hesai GPS).
    pub fn time_port_len(self) -> (u16, usize) {
        match self {
            Scanner::Velodyne(_) => (POSITION_PORT, POSITION_PACKET_LEN),
            Scanner::Hesai(_) => (hesai::GPS_PORT, hesai::gps::GPS_PACKET_LEN),
            // (An Ouster sends none: its clock is in its metadata's timestamp mode.)
            Scanner::Ouster(_) => (ouster::IMU_PORT, 0),
        }
    }

    /// The Hesai's return mode byte of a simulated mode (dual: last and strongest, the even
    /// block the last as a Velodyne's).
    fn hesai_mode(mode: ReturnMode) -> hesai::ReturnMode {
        match mode {
            ReturnMode::Strongest => hesai::ReturnMode::Single(0x37),
            ReturnMode::Last => hesai::ReturnMode::Single(0x38),
            ReturnMode::Dual => hesai::ReturnMode::Dual(0x39),
        }
    }
}

/// What the sensor's clock says at a firing, for the packet's time fields.
#[derive(Debug, Clone, Copy)]
pub(super) struct Stamp {
    /// The packet's first firing on the sensor's clock.
    pub first: GpsTime,
    /// The site's leap seconds (GPS - UTC).
    pub leap_seconds: i64,
    /// Sequence number of the packet.
    pub sequence: u32,
    /// Motor speed [rpm].
    pub rpm: u16,
    /// An Ouster's frame id.
    pub frame_id: u16,
    /// An Ouster whose clock is not synchronised (its PPS state is not locked): its column
    /// timestamps count from its power-on, this GPS time ([`OUSTER_POWER_ON_S`] before the
    /// survey), in `TIME_FROM_INTERNAL_OSC`.
    pub power_on: Option<GpsTime>,
}

/// How long before the survey's start a free-running Ouster was powered on [s].
pub const OUSTER_POWER_ON_S: i64 = 516;

/// A data packet being written.
pub(super) enum Writer<'b> {
    Velodyne(velodyne::DataPacket<&'b mut [u8]>),
    Hesai(hesai::DataPacket<&'b mut [u8]>),
    Ouster(ouster::LidarPacket<&'b mut [u8]>, Option<GpsTime>),
}

/// The simulated Ouster's serial number and initialisation id.
pub const OUSTER_SERIAL: u64 = 992_345_000_064;
const OUSTER_INIT_ID: u32 = 0x5C_A1E0;

impl<'b> Writer<'b> {
    /// An empty packet of `scanner` in `buf` (its length exactly), stamped.
    pub fn new(scanner: Scanner, mode: ReturnMode, buf: &'b mut [u8], s: Stamp) -> Option<Self> {
        match scanner {
            Scanner::Velodyne(m) => {
                buf.fill(0);
                let mut p = velodyne::DataPacket::new_unchecked(buf);
                p.set_timestamp_us(micros_past_hour(s.first, s.leap_seconds));
                p.set_return_mode(mode);
                p.set_product_raw(m.product());
                Some(Writer::Velodyne(p))
            }
            Scanner::Hesai(m) => {
                let hm = Scanner::hesai_mode(mode);
                let mut p = hesai::DataPacket::emit(buf, m, hm, s.sequence)?;
                // The absolute time is the trigger of the packet's last firing.
                let abs = s.first.0 - m.firing_offset_ns(0, 0, hm.returns(), 1);
                let utc = UtcDateTime::from_unix_ns(gps_to_unix_ns(GpsTime(abs), s.leap_seconds));
                let date = [
                    (utc.year - 1900).clamp(0, 255) as u8,
                    utc.month,
                    utc.day,
                    utc.hour,
                    utc.minute,
                    utc.second,
                ];
                p.set_time(s.rpm, date, utc.nanos / 1000);
                Some(Writer::Hesai(p))
            }
            Scanner::Ouster(o) => ouster::LidarPacket::emit(
                buf,
                o.format(),
                s.frame_id,
                OUSTER_INIT_ID,
                OUSTER_SERIAL,
            )
            .map(|p| Writer::Ouster(p, s.power_on)),
        }
    }

    /// Block `b`: its azimuth [0.01 deg] (an Ouster's column: its measurement id, and its
    /// timestamp from `t` on the sensor's clock: PTP's TAI nanoseconds, GPS + 19 s).
    pub fn set_block(&mut self, b: usize, code: u16, t: GpsTime) {
        match self {
            Writer::Velodyne(p) => {
                p.set_flag(b);
                p.set_azimuth_raw(b, code);
            }
            Writer::Hesai(p) => p.set_azimuth(b, code),
            Writer::Ouster(p, power_on) => {
                let ns = match power_on {
                    Some(on) => t.0 - on.0,
                    None => gps_to_unix_ns(t, 0) + 19_000_000_000,
                };
                p.set_column(b, u64::try_from(ns).unwrap_or(0), code);
            }
        }
    }

    /// Channel `ch`'s return in block `b`: distance [the unit] and intensity.
    pub fn set_channel(&mut self, b: usize, ch: usize, raw: u16, intensity: u8) {
        match self {
            Writer::Velodyne(p) => p.set_channel(b, ch, raw, intensity),
            Writer::Hesai(p) => p.set_unit(b, ch, raw, intensity),
            Writer::Ouster(p, _) => p.set_return(b, ch, u32::from(raw), intensity),
        }
    }

    /// Done: the checksums, where the layout has any.
    pub fn finish(self) {
        match self {
            Writer::Hesai(mut p) => p.seal(),
            Writer::Ouster(mut p, _) => p.seal(),
            Writer::Velodyne(_) => {}
        }
    }
}

/// Write the once-a-second time packet of `scanner` into `out`: the UTC second `whole`, the
/// `$GPRMC` at `lat`/`lon` [deg], the stamp `stamp_us` (Velodyne: microseconds past the hour on
/// its clock) and the PPS state. Returns its length.
pub(super) fn write_time_packet(
    scanner: Scanner,
    out: &mut [u8],
    whole: &UtcDateTime,
    lat_lon: (f64, f64),
    rmc_valid: bool,
    stamp_us: u32,
    pps: PpsStatus,
) -> usize {
    let mut s = [0u8; 96];
    let n = write_gprmc(&mut s, whole, lat_lon.0, lat_lon.1, rmc_valid).unwrap_or(0);
    let (_, len) = scanner.time_port_len();
    let buf = &mut out[..len];
    match scanner {
        Scanner::Velodyne(_) => {
            buf.fill(0);
            let mut p = PositionPacket::new_unchecked(buf);
            p.set_timestamp_us(stamp_us);
            p.set_pps(pps);
            p.set_nmea(&s[..n]);
        }
        Scanner::Hesai(_) => {
            let status = if rmc_valid { b'A' } else { b'V' };
            let _ = hesai::GpsPacket::emit(buf, whole, &s[..n], status, pps == PpsStatus::Locked);
        }
        Scanner::Ouster(_) => {}
    }
    len
}

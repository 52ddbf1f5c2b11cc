//! Velodyne models: which lasers a data block holds, when each fires, and where each points.
//!
//! All four models share the 1206-byte data packet (12 blocks of 32 channels); they differ in
//! what a channel is:
//!
//! | model | product byte | lasers | block | channel `c` fires at | laser of `c` | range unit |
//! |---|---|---|---|---|---|---|
//! | VLP-16 / Puck LITE | 0x22 | 16 | 110.592 us | 55.296 (c / 16) + 2.304 (c % 16) | c % 16 | 2 mm |
//! | Puck Hi-Res | 0x24 | 16 | 110.592 us | as the VLP-16 | c % 16 | 2 mm |
//! | HDL-32E | 0x21 | 32 | 46.08 us | 1.152 c | c | 2 mm |
//! | VLP-32C | 0x28 | 32 | 55.296 us | 2.304 floor(c / 2) (lasers fire in pairs) | c | 4 mm |
//!
//! Sources: VLP-16 manual 63-9243 Rev. E appendix B; Puck Hi-Res manual 63-9318 appendix B
//! (same timing as the VLP-16); HDL-32E manual 63-9113 appendix A ("1.152 us per firing, 32
//! firings per 46.08 us cycle"); VLP-32C manual 63-9325 section 9.5 and appendix B (16 firing
//! groups of 2 lasers, 2.304 us apart, 55.296 us per cycle; 4 mm distance granularity). Dual
//! return: blocks in pairs on every model (manual 9.3.2). The laser tables are in
//! [`super::tables`] (generated from the values and citations of `scripts/velodyne_tables.py`).
//!
//! A point's azimuth is the block's azimuth interpolated to the firing time (its fraction of
//! the block) plus the laser's azimuth offset (VLP-32C table 9-2; zero on the others).

use super::beam::Beam;
use super::tables;

/// Most lasers of any model (the channel count of a block).
pub const MAX_LASERS: usize = 32;

/// A Velodyne model the decoder knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Model {
    /// VLP-16 and Puck LITE (product byte 0x22).
    #[default]
    Vlp16,
    /// Puck Hi-Res (0x24).
    PuckHiRes,
    /// HDL-32E (0x21; early VLP-16 firmware writes it too).
    Hdl32e,
    /// VLP-32C (0x28).
    Vlp32c,
}

/// One channel of a data block: its laser and firing time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Channel {
    /// Laser id (index into [`Model::beams`]).
    pub laser: u8,
    /// Firing time after the block's first firing [ns].
    pub offset_ns: u32,
    /// That time as a fraction of the block (the azimuth interpolation's weight).
    pub fraction: f32,
}

const fn channels(block_ns: u32, timing: u8) -> [Channel; MAX_LASERS] {
    let mut out = [Channel {
        laser: 0,
        offset_ns: 0,
        fraction: 0.0,
    }; MAX_LASERS];
    let mut c = 0;
    while c < MAX_LASERS {
        let (laser, offset_ns) = match timing {
            // VLP-16 / Hi-Res: two sequences of 16 firings 2.304 us apart, 55.296 us each.
            0 => (c % 16, (c / 16) as u32 * 55_296 + (c % 16) as u32 * 2_304),
            // HDL-32E: 32 single firings 1.152 us apart.
            1 => (c, c as u32 * 1_152),
            // VLP-32C: 16 groups of two simultaneous firings 2.304 us apart.
            _ => (c, (c / 2) as u32 * 2_304),
        };
        out[c] = Channel {
            laser: laser as u8,
            offset_ns,
            fraction: offset_ns as f32 / block_ns as f32,
        };
        c += 1;
    }
    out
}

const PUCK_CHANNELS: [Channel; MAX_LASERS] = channels(110_592, 0);
const HDL32E_CHANNELS: [Channel; MAX_LASERS] = channels(46_080, 1);
const VLP32C_CHANNELS: [Channel; MAX_LASERS] = channels(55_296, 2);

impl Model {
    /// Every model, in the order `--model` lists them.
    pub const ALL: [Model; 4] = [Model::Vlp16, Model::PuckHiRes, Model::Hdl32e, Model::Vlp32c];

    /// The model a product-id byte (data-packet offset 1205) names; `None` for any other byte.
    pub fn from_product(b: u8) -> Option<Model> {
        match b {
            0x21 => Some(Model::Hdl32e),
            0x22 => Some(Model::Vlp16),
            0x24 => Some(Model::PuckHiRes),
            0x28 => Some(Model::Vlp32c),
            _ => None,
        }
    }

    /// Its product-id byte.
    pub fn product(self) -> u8 {
        match self {
            Model::Hdl32e => 0x21,
            Model::Vlp16 => 0x22,
            Model::PuckHiRes => 0x24,
            Model::Vlp32c => 0x28,
        }
    }

    /// The name Velodyne gives it.
    pub fn name(self) -> &'static str {
        match self {
            Model::Vlp16 => "VLP-16",
            Model::PuckHiRes => "Puck Hi-Res",
            Model::Hdl32e => "HDL-32E",
            Model::Vlp32c => "VLP-32C",
        }
    }

    /// The name `--model` and the board's `[lidar] model` take.
    pub fn key(self) -> &'static str {
        match self {
            Model::Vlp16 => "vlp16",
            Model::PuckHiRes => "puck-hires",
            Model::Hdl32e => "hdl32e",
            Model::Vlp32c => "vlp32c",
        }
    }

    /// A model from its key or name, ignoring case, '-', '_' and spaces ("VLP-16", "vlp16",
    /// "puck lite" and "Puck Hi-Res" all work).
    pub fn parse(s: &str) -> Option<Model> {
        let mut buf = [0u8; 16];
        let mut n = 0;
        for b in s.bytes() {
            if matches!(b, b'-' | b'_' | b' ') {
                continue;
            }
            *buf.get_mut(n)? = b.to_ascii_lowercase();
            n += 1;
        }
        match &buf[..n] {
            b"vlp16" | b"puck" | b"pucklite" | b"vlp16lite" => Some(Model::Vlp16),
            b"puckhires" | b"vlp16hires" | b"hires" => Some(Model::PuckHiRes),
            b"hdl32e" | b"hdl32" => Some(Model::Hdl32e),
            b"vlp32c" | b"vlp32" => Some(Model::Vlp32c),
            _ => None,
        }
    }

    /// Lasers per firing cycle (16 or 32).
    pub fn lasers(self) -> usize {
        self.beams().len()
    }

    /// Each laser's geometry, by laser id.
    pub fn beams(self) -> &'static [Beam] {
        match self {
            Model::Vlp16 => &tables::VLP16,
            Model::PuckHiRes => &tables::PUCK_HIRES,
            Model::Hdl32e => &tables::HDL32E,
            Model::Vlp32c => &tables::VLP32C,
        }
    }

    /// One laser's geometry (the id reduced modulo the laser count).
    #[inline]
    pub fn beam(self, laser: usize) -> &'static Beam {
        let b = self.beams();
        &b[laser % b.len()]
    }

    /// The 32 channels of a block: laser and firing time of each.
    #[inline]
    pub fn channels(self) -> &'static [Channel; MAX_LASERS] {
        match self {
            Model::Vlp16 | Model::PuckHiRes => &PUCK_CHANNELS,
            Model::Hdl32e => &HDL32E_CHANNELS,
            Model::Vlp32c => &VLP32C_CHANNELS,
        }
    }

    /// Duration of one block (one firing cycle) [ns].
    pub fn block_ns(self) -> u32 {
        match self {
            Model::Vlp16 | Model::PuckHiRes => 110_592,
            Model::Hdl32e => 46_080,
            Model::Vlp32c => 55_296,
        }
    }

    /// Time between two firings of one laser [ns]: the VLP-16's two sequences per block make it
    /// half a block; the 32-laser models fire each laser once per block.
    pub fn laser_period_ns(self) -> u32 {
        match self {
            Model::Vlp16 | Model::PuckHiRes => 55_296,
            m => m.block_ns(),
        }
    }

    /// Range unit of the distance field [m].
    pub fn distance_unit_m(self) -> f64 {
        match self {
            Model::Vlp32c => 0.004,
            _ => 0.002,
        }
    }

    /// Farthest range the manual specifies [m].
    pub fn max_range_m(self) -> f64 {
        match self {
            Model::Vlp32c => 200.0,
            _ => 100.0,
        }
    }

    /// The lowest and highest elevation [deg].
    pub fn elevation_span_deg(self) -> (f64, f64) {
        self.beams()
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), b| {
                (lo.min(b.elevation_deg), hi.max(b.elevation_deg))
            })
    }

    /// Time between two data packets [ns]: 12 firing cycles, 6 in dual-return mode.
    pub fn packet_period_ns(self, dual: bool) -> u32 {
        self.block_ns() * if dual { 6 } else { 12 }
    }

    /// Whether two models share their firing timing (then a packet period cannot tell them apart).
    pub fn same_timing(self, other: Model) -> bool {
        self.block_ns() == other.block_ns() && self.lasers() == other.lasers()
    }
}

impl core::fmt::Display for Model {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// What the first packets of a stream say about the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Identity {
    /// Not enough packets yet; the product byte's model so far.
    Pending(Option<Model>),
    /// The product byte's model, and the packet period agrees with it.
    Agreed(Model),
    /// A product byte no known model writes.
    Unknown {
        /// The byte.
        product: u8,
    },
    /// The product byte names a model whose packet period is not what the stream shows.
    Disagrees {
        /// The byte.
        product: u8,
        /// The median time between consecutive packets [us].
        period_us: u32,
        /// A model whose period fits (the first of those with the same timing), if any.
        fits: Option<Model>,
    },
}

/// Packet-to-packet intervals the [`Detector`] takes its median over.
pub const DETECT_INTERVALS: usize = 16;

/// Identifies the model from the product byte and checks it against the packet period, which
/// the timing fixes (`Model::packet_period_ns`): early VLP-16 firmware writes 0x21, the
/// HDL-32E's byte, and its 1327 us period then shows it (PROTOCOLS.md). Streaming: push each
/// data packet's timestamp, return-mode and product bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Detector {
    product: Option<u8>,
    dual: bool,
    last_us: Option<u32>,
    intervals: [u32; DETECT_INTERVALS],
    n: usize,
    verdict: Option<Identity>,
}

impl Default for Detector {
    fn default() -> Self {
        Self::new()
    }
}

impl Detector {
    /// A detector that has seen nothing.
    pub const fn new() -> Self {
        Self {
            product: None,
            dual: false,
            last_us: None,
            intervals: [0; DETECT_INTERVALS],
            n: 0,
            verdict: None,
        }
    }

    /// The verdict so far.
    pub fn identity(&self) -> Identity {
        self.verdict.unwrap_or(Identity::Pending(
            self.product.and_then(Model::from_product),
        ))
    }

    /// One data packet: its timestamp [us past the hour], return-mode byte and product byte.
    /// The first packet's product byte is the one judged (a stream does not change model).
    pub fn push(&mut self, timestamp_us: u32, return_mode: u8, product: u8) -> Identity {
        if self.verdict.is_some() {
            return self.identity();
        }
        let p = *self.product.get_or_insert(product);
        self.dual = return_mode == 0x39;
        let Some(model) = Model::from_product(p) else {
            self.verdict = Some(Identity::Unknown { product: p });
            return self.identity();
        };
        if let Some(last) = self.last_us.replace(timestamp_us) {
            // A gap of more than 10 periods (drops, the hour's wrap) is not an interval.
            let d = timestamp_us.wrapping_sub(last);
            if d > 0 && d < 20_000 && self.n < DETECT_INTERVALS {
                self.intervals[self.n] = d;
                self.n += 1;
            }
        }
        if self.n == DETECT_INTERVALS {
            let mut v = self.intervals;
            v.sort_unstable();
            let period_us = v[DETECT_INTERVALS / 2];
            let fits = |m: Model| {
                let e = f64::from(m.packet_period_ns(self.dual)) / 1000.0;
                (f64::from(period_us) - e).abs() <= 0.02 * e
            };
            self.verdict = Some(if fits(model) {
                Identity::Agreed(model)
            } else {
                Identity::Disagrees {
                    product: p,
                    period_us,
                    fits: Model::ALL.into_iter().find(|&m| fits(m)),
                }
            });
        }
        self.identity()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trig_tables_match_the_elevations() {
        for m in Model::ALL {
            for (l, b) in m.beams().iter().enumerate() {
                let w = b.elevation_deg.to_radians();
                let a = b.azimuth_offset_rad();
                assert!((b.cos_el - libm::cos(w)).abs() < 1e-15, "{m} {l}");
                assert!((b.sin_el - libm::sin(w)).abs() < 1e-15, "{m} {l}");
                assert!((b.cos_az - libm::cos(a)).abs() < 1e-15, "{m} {l}");
                assert!((b.sin_az - libm::sin(a)).abs() < 1e-15, "{m} {l}");
            }
        }
    }

    #[test]
    fn vertical_offsets_follow_the_beam_crossing() {
        // Every offset is the beams' crossing point seen along the laser: d tan(-w), with
        // d = 41.91 mm (VLP-16: manual 9.3.1.3), 28.83 mm (HDL-32E envelope drawing) and
        // 42.4 mm (VLP-32C); the manuals print them rounded (0.1 mm, 0.01 mm). The Hi-Res
        // drawing's values step 0.9 mm per 1.33 deg from 7.4 mm: within 0.45 mm of the formula.
        for (m, d, tol) in [
            (Model::Vlp16, 0.04191, 6e-5),
            (Model::PuckHiRes, 0.04191, 4.5e-4),
            (Model::Hdl32e, 0.02883, 8e-5),
            (Model::Vlp32c, 0.0424, 1e-7),
        ] {
            for (l, b) in m.beams().iter().enumerate() {
                let v = d * libm::tan(-b.elevation_deg.to_radians());
                assert!((b.vertical_offset_m - v).abs() < tol, "{m} laser {l}");
            }
        }
    }

    #[test]
    fn timing_follows_the_manuals() {
        // VLP-16 appendix B: block 0, sequence 1, laser 15 at 55.296 + 34.56 us.
        assert_eq!(Model::Vlp16.channels()[31].offset_ns, 89_856);
        assert_eq!(Model::Vlp16.channels()[31].laser, 15);
        // HDL-32E: laser 31 fires 31 * 1.152 = 35.712 us into the cycle.
        assert_eq!(Model::Hdl32e.channels()[31].offset_ns, 35_712);
        // VLP-32C: lasers 30 and 31 fire together, group 15 at 34.56 us.
        assert_eq!(Model::Vlp32c.channels()[30].offset_ns, 34_560);
        assert_eq!(Model::Vlp32c.channels()[31].offset_ns, 34_560);
        // Packet periods: 1327.104, 552.96, 663.552 us; half that in dual mode.
        assert_eq!(Model::Vlp16.packet_period_ns(false), 1_327_104);
        assert_eq!(Model::Hdl32e.packet_period_ns(false), 552_960);
        assert_eq!(Model::Vlp32c.packet_period_ns(false), 663_552);
        assert_eq!(Model::Vlp16.packet_period_ns(true), 663_552);
    }

    #[test]
    fn names_parse_back() {
        for m in Model::ALL {
            assert_eq!(Model::parse(m.key()), Some(m));
            assert_eq!(Model::parse(m.name()), Some(m));
            assert_eq!(Model::from_product(m.product()), Some(m));
        }
        assert_eq!(Model::parse("Puck LITE"), Some(Model::Vlp16));
        assert_eq!(Model::parse("vlp-64"), None);
        assert_eq!(Model::parse("a very long name that overflows"), None);
        assert_eq!(Model::from_product(0x23), None);
    }

    fn feed(product: u8, mode: u8, period_us: u32, n: u32) -> Identity {
        let mut d = Detector::new();
        let mut id = d.identity();
        for k in 0..n {
            id = d.push(
                3_599_990_000u32.wrapping_add(k * period_us) % 3_600_000_000,
                mode,
                product,
            );
        }
        id
    }

    #[test]
    fn detector_checks_the_byte_against_the_period() {
        assert_eq!(feed(0x22, 0x37, 1327, 40), Identity::Agreed(Model::Vlp16));
        assert_eq!(feed(0x22, 0x39, 664, 40), Identity::Agreed(Model::Vlp16));
        assert_eq!(feed(0x21, 0x37, 553, 40), Identity::Agreed(Model::Hdl32e));
        assert_eq!(feed(0x28, 0x37, 664, 40), Identity::Agreed(Model::Vlp32c));
        assert_eq!(
            feed(0x24, 0x38, 1327, 40),
            Identity::Agreed(Model::PuckHiRes)
        );
        assert_eq!(
            feed(0x28, 0x37, 664, 5),
            Identity::Pending(Some(Model::Vlp32c))
        );
        // Early VLP-16 firmware: 0x21 at the VLP-16's period.
        assert_eq!(
            feed(0x21, 0x37, 1327, 40),
            Identity::Disagrees {
                product: 0x21,
                period_us: 1327,
                fits: Some(Model::Vlp16)
            }
        );
        assert_eq!(
            feed(0x22, 0x37, 997, 40),
            Identity::Disagrees {
                product: 0x22,
                period_us: 997,
                fits: None
            }
        );
        assert_eq!(
            feed(0x99, 0x37, 1327, 1),
            Identity::Unknown { product: 0x99 }
        );
    }
}

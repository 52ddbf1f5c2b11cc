//! The lidar packet view: a checked [`LidarPacket`] over the UDP payload, its [`Column`]s and
//! their [`Pixel`]s, every field little-endian (firmware manual, "Lidar Data Packet Format"
//! and "Lidar Data Profiles").
//!
//! ```text
//! packet header (32 B, not in LEGACY)
//!   standard: 0 packet type u16 (1) | 2 frame id u16 | 4 init id u24 | 7 serial u40
//!   FuSa:     0 packet type u8  | 1 init id u24 | 4 frame id u32 | 11 serial u40
//! column header
//!   LEGACY:   0 timestamp u64 [ns] | 8 measurement id u16 | 10 frame id u16 | 12 encoder u32
//!   others:   0 timestamp u64 [ns] | 8 measurement id u16 | 10 status u16 (bit 0: valid)
//! pixel (bits of the little-endian words)
//!   LEGACY      12 B: range 0..20 [mm] | reflectivity 32..40 | signal 48..64 | NIR 64..80
//!   RNG19..     12 B: range 0..19 [mm] | reflectivity 32..40 | signal 48..64 | NIR 64..80
//!   RNG19.._DUAL 16 B: range 0..19 | refl 24..32 | range2 32..51 | refl2 56..64 |
//!                      signal 64..80 | signal2 80..96 | NIR 96..112
//!   RNG15_RFL8_NIR8 4 B: range 0..15 [8 mm] | refl 16..24 | NIR 24..32 [x16]
//!   RNG15_RFL8_NIR8_DUAL 8 B: as above, then range2 32..47 [8 mm] | refl2 48..56
//! column footer (LEGACY only): status u32, 0xFFFFFFFF valid
//! packet footer (32 B, not in LEGACY)
//! ```

use super::profile::{Format, HeaderKind, Profile};
use super::Error;
use crate::le::{le16, le32, le_n};

/// A range's bits in its little-endian word (the bits above them are flags).
mod range {
    /// LEGACY: 20 bits [mm].
    pub const LEGACY: u32 = 0x000F_FFFF;
    /// RNG19 profiles: 19 bits [mm].
    pub const RNG19: u32 = 0x0007_FFFF;
    /// RNG15 profiles: 15 bits of 8 mm ...
    pub const RNG15: u32 = 0x7FFF;
    /// ... shifted by this into mm.
    pub const RNG15_SHIFT: u32 = 3;
}

/// The footer's CRC (firmware 3.x): CRC-64/XZ.
const CRC64: crc::Crc<u64, crc::Table<16>> = crc::Crc::<u64, crc::Table<16>>::new(&crc::CRC_64_XZ);

/// The ranges of pixels of `N` bytes: the first return's word at 0 and (`SECOND` > 0) the
/// second's at `SECOND`, 16 or 32 bits, masked and shifted into mm; `f` for each non-zero.
#[inline(always)]
fn scan<const N: usize, const W16: bool, const SECOND: usize>(
    px: &[u8],
    mask: u32,
    shift: u32,
    f: &mut impl FnMut(usize, usize, u32),
) {
    let word = |b: &[u8; N], at: usize| {
        if W16 {
            u32::from(le16(b, at))
        } else {
            le32(b, at)
        }
    };
    let (pixels, _) = px.as_chunks::<N>();
    for (ch, b) in pixels.iter().enumerate() {
        let r = (word(b, 0) & mask) << shift;
        if r != 0 {
            f(ch, 0, r);
        }
        if SECOND > 0 {
            let r = (word(b, SECOND) & mask) << shift;
            if r != 0 {
                f(ch, 1, r);
            }
        }
    }
}

/// A lidar packet of a known [`Format`]. Built with [`LidarPacket::new_checked`], every
/// accessor is infallible: column and pixel indices are reduced modulo the format's counts.
#[derive(Debug, Clone, Copy)]
pub struct LidarPacket<T: AsRef<[u8]>> {
    buffer: T,
    format: Format,
}

impl<T: AsRef<[u8]>> LidarPacket<T> {
    /// Wrap `buffer` as a packet of `format`: exactly the format's length, and (with a packet
    /// header) a lidar packet type.
    pub fn new_checked(buffer: T, format: Format) -> Result<Self, Error> {
        let got = buffer.as_ref().len();
        let expected = format.packet_len();
        if got != expected {
            return Err(Error::Length { expected, got });
        }
        let p = Self { buffer, format };
        match p.packet_type() {
            Some(1) | None => Ok(p),
            Some(found) => Err(Error::PacketType { found }),
        }
    }

    /// The header's packet type (`None` in LEGACY, which has no header).
    pub fn packet_type(&self) -> Option<u16> {
        let b = self.buffer.as_ref();
        match self.format.header {
            HeaderKind::Legacy => None,
            HeaderKind::Standard => Some(le16(b, 0)),
            HeaderKind::Fusa => Some(u16::from(b[0])),
        }
    }

    /// The frame (one rotation) the packet belongs to; in LEGACY, the first column's.
    pub fn frame_id(&self) -> u32 {
        let b = self.buffer.as_ref();
        match self.format.header {
            HeaderKind::Legacy => u32::from(le16(b, 10)),
            HeaderKind::Standard => u32::from(le16(b, 2)),
            HeaderKind::Fusa => le32(b, 4),
        }
    }

    /// The sensor's initialisation id (changes on a reset; `None` in LEGACY).
    pub fn init_id(&self) -> Option<u32> {
        let b = self.buffer.as_ref();
        match self.format.header {
            HeaderKind::Legacy => None,
            HeaderKind::Standard => Some(le_n(b, 4, 3) as u32),
            HeaderKind::Fusa => Some(le_n(b, 1, 3) as u32),
        }
    }

    /// The sensor's serial number (`None` in LEGACY).
    pub fn serial(&self) -> Option<u64> {
        let b = self.buffer.as_ref();
        match self.format.header {
            HeaderKind::Legacy => None,
            HeaderKind::Standard => Some(le_n(b, 7, 5)),
            HeaderKind::Fusa => Some(le_n(b, 11, 5)),
        }
    }

    /// The footer's last eight bytes and the CRC-64/XZ (ECMA-182, reflected) of the bytes
    /// before them: firmware 3.x sends the CRC there; older firmware zeros or other bytes.
    /// `None` in LEGACY (no footer).
    pub fn crc(&self) -> Option<(u64, u64)> {
        if self.format.header == HeaderKind::Legacy {
            return None;
        }
        let b = self.buffer.as_ref();
        let n = b.len() - 8;
        Some((le_n(b, n, 8), CRC64.checksum(&b[..n])))
    }

    /// Column `i` (modulo the format's columns).
    #[inline]
    pub fn column(&self, i: usize) -> Column<'_> {
        let f = &self.format;
        let at = f.header_len() + (i % f.columns) * f.column_len();
        Column {
            bytes: &self.buffer.as_ref()[at..at + f.column_len()],
            format: *f,
        }
    }

    /// The columns in packet order.
    pub fn columns(&self) -> impl Iterator<Item = Column<'_>> + '_ {
        (0..self.format.columns).map(move |i| self.column(i))
    }
}

/// The emit side (the simulator): a packet of the standard header and the single-return
/// RNG19_RFL8_SIG16_NIR16 profile, as firmware 2.2+ sends it.
impl<T: AsRef<[u8]> + AsMut<[u8]>> LidarPacket<T> {
    /// Write an empty packet of `format` into `buffer` (exactly its length; `None` for
    /// another length or a format other than the standard header's single-return profile):
    /// packet type 1, `frame_id`, `init_id` (24 bits), `serial` (40 bits); every column
    /// invalid until [`Self::set_column`].
    pub fn emit(
        mut buffer: T,
        format: Format,
        frame_id: u16,
        init_id: u32,
        serial: u64,
    ) -> Option<Self> {
        let b = buffer.as_mut();
        if b.len() != format.packet_len()
            || format.header != HeaderKind::Standard
            || format.profile != Profile::Single
        {
            return None;
        }
        b.fill(0);
        b[..2].copy_from_slice(&1u16.to_le_bytes());
        b[2..4].copy_from_slice(&frame_id.to_le_bytes());
        b[4..7].copy_from_slice(&init_id.to_le_bytes()[..3]);
        b[7..12].copy_from_slice(&serial.to_le_bytes()[..5]);
        Some(Self { buffer, format })
    }

    fn column_at(&self, i: usize) -> usize {
        self.format.header_len() + (i % self.format.columns) * self.format.column_len()
    }

    /// Column `i`'s timestamp [ns], measurement id and status (valid).
    pub fn set_column(&mut self, i: usize, timestamp_ns: u64, measurement_id: u16) {
        let at = self.column_at(i);
        let b = self.buffer.as_mut();
        b[at..at + 8].copy_from_slice(&timestamp_ns.to_le_bytes());
        b[at + 8..at + 10].copy_from_slice(&measurement_id.to_le_bytes());
        b[at + 10..at + 12].copy_from_slice(&1u16.to_le_bytes());
    }

    /// Pixel `px` of column `i`: its range [mm, 19 bits] and reflectivity.
    pub fn set_return(&mut self, i: usize, px: usize, range_mm: u32, reflectivity: u8) {
        let f = self.format;
        let at =
            self.column_at(i) + f.column_header_len() + (px % f.pixels) * f.profile.pixel_len();
        let b = self.buffer.as_mut();
        b[at..at + 4].copy_from_slice(&(range_mm & range::RNG19).to_le_bytes());
        b[at + 4] = reflectivity;
    }

    /// The footer's CRC-64/XZ (firmware 3.x): call last.
    pub fn seal(&mut self) {
        let b = self.buffer.as_mut();
        let n = b.len() - 8;
        let c = CRC64.checksum(&b[..n]);
        b[n..].copy_from_slice(&c.to_le_bytes());
    }
}

/// One column: one azimuth step of every beam, fired at one time.
#[derive(Debug, Clone, Copy)]
pub struct Column<'a> {
    bytes: &'a [u8],
    format: Format,
}

impl Column<'_> {
    /// The column's timestamp [ns] (in the sensor's `timestamp_mode`'s clock).
    #[inline]
    pub fn timestamp_ns(&self) -> u64 {
        le_n(self.bytes, 0, 8)
    }

    /// Its index within the frame (0 .. columns per frame - 1).
    #[inline]
    pub fn measurement_id(&self) -> u16 {
        le16(self.bytes, 8)
    }

    /// Whether the column holds data (LEGACY: its status word is 0xFFFFFFFF; others: status
    /// bit 0). A column outside the sensor's `column_window` is sent invalid, zero-filled.
    #[inline]
    pub fn valid(&self) -> bool {
        match self.format.header {
            HeaderKind::Legacy => le32(self.bytes, self.bytes.len() - 4) == 0xFFFF_FFFF,
            _ => le16(self.bytes, 10) & 1 == 1,
        }
    }

    /// LEGACY's encoder count (90,112 ticks a turn; `None` in the other profiles).
    pub fn encoder_count(&self) -> Option<u32> {
        (self.format.header == HeaderKind::Legacy).then(|| le32(self.bytes, 12))
    }

    /// Every return of the column, in beam order: `f(beam, return 0 or 1, range_mm)` for each
    /// range that is not 0 (the profile decided once for the column, not per pixel).
    #[inline]
    pub fn for_each_return(&self, mut f: impl FnMut(usize, usize, u32)) {
        let fm = &self.format;
        let n = fm.profile.pixel_len();
        let at = fm.column_header_len();
        let px = &self.bytes[at..at + fm.pixels * n];
        match fm.profile {
            Profile::Legacy => scan::<12, false, 0>(px, range::LEGACY, 0, &mut f),
            Profile::Single => scan::<12, false, 0>(px, range::RNG19, 0, &mut f),
            Profile::Dual => scan::<16, false, 4>(px, range::RNG19, 0, &mut f),
            Profile::LowRate => scan::<4, true, 0>(px, range::RNG15, range::RNG15_SHIFT, &mut f),
            Profile::LowRateDual => {
                scan::<8, true, 4>(px, range::RNG15, range::RNG15_SHIFT, &mut f)
            }
        }
    }

    /// Pixel `ch` (the beam, modulo the column's pixels).
    #[inline]
    pub fn pixel(&self, ch: usize) -> Pixel {
        let f = &self.format;
        let n = f.profile.pixel_len();
        let at = f.column_header_len() + (ch % f.pixels) * n;
        let b = &self.bytes[at..at + n];
        let rng15 = |at: usize| (u32::from(le16(b, at)) & range::RNG15) << range::RNG15_SHIFT;
        match f.profile {
            Profile::Legacy => Pixel {
                range_mm: [le32(b, 0) & range::LEGACY, 0],
                reflectivity: [b[4], 0],
                signal: [le16(b, 6), 0],
                nir: le16(b, 8),
            },
            Profile::Single => Pixel {
                range_mm: [le32(b, 0) & range::RNG19, 0],
                reflectivity: [b[4], 0],
                signal: [le16(b, 6), 0],
                nir: le16(b, 8),
            },
            Profile::Dual => Pixel {
                range_mm: [le32(b, 0) & range::RNG19, le32(b, 4) & range::RNG19],
                reflectivity: [b[3], b[7]],
                signal: [le16(b, 8), le16(b, 10)],
                nir: le16(b, 12),
            },
            Profile::LowRate => Pixel {
                range_mm: [rng15(0), 0],
                reflectivity: [b[2], 0],
                signal: [0, 0],
                nir: u16::from(b[3]) << 4,
            },
            Profile::LowRateDual => Pixel {
                range_mm: [rng15(0), rng15(4)],
                reflectivity: [b[2], b[6]],
                signal: [0, 0],
                nir: u16::from(b[3]) << 4,
            },
        }
    }
}

/// One beam's measurement in a column: up to two returns (the second zero in single-return
/// profiles, and where there was none).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Pixel {
    /// Range of the first and second return [mm]; 0: no return.
    pub range_mm: [u32; 2],
    /// Calibrated reflectivity of each return (0-255).
    pub reflectivity: [u8; 2],
    /// Signal photons of each return (0 in the low-data-rate profiles).
    pub signal: [u16; 2],
    /// Near-infrared ambient photons.
    pub nir: u16,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn legacy32() -> Format {
        Format::new(Profile::Legacy, HeaderKind::Legacy, 16, 32).unwrap()
    }

    /// A packet of another length or type is refused naming both, and indices wrap: no
    /// input panics.
    #[test]
    fn wrong_lengths_and_types_are_refused() {
        let f = legacy32();
        let short = [0u8; 100];
        assert_eq!(
            LidarPacket::new_checked(&short[..], f).unwrap_err(),
            Error::Length {
                expected: 6464,
                got: 100
            }
        );
        let g = Format::new(Profile::LowRate, HeaderKind::Standard, 16, 16).unwrap();
        let mut b = std::vec![0u8; g.packet_len()];
        b[0] = 2;
        assert_eq!(
            LidarPacket::new_checked(&b[..], g).unwrap_err(),
            Error::PacketType { found: 2 }
        );
        b[0] = 1;
        let p = LidarPacket::new_checked(&b[..], g).unwrap();
        let c = p.column(1000);
        assert_eq!(c.pixel(999), Pixel::default());
        assert!(!c.valid());
    }

    /// `for_each_return` (the profile decided once a column) gives exactly the non-zero ranges
    /// `pixel` gives, in every profile, on packets of pseudo-random bytes.
    #[test]
    fn every_return_is_each_pixels() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for (p, h) in [
            (Profile::Legacy, HeaderKind::Legacy),
            (Profile::Single, HeaderKind::Standard),
            (Profile::Dual, HeaderKind::Standard),
            (Profile::LowRate, HeaderKind::Standard),
            (Profile::LowRateDual, HeaderKind::Fusa),
        ] {
            let f = Format::new(p, h, 16, 64).unwrap();
            let mut b: std::vec::Vec<u8> = (0..f.packet_len())
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    // Some zero ranges: a quarter of the bytes zero.
                    if x.is_multiple_of(4) {
                        0
                    } else {
                        (x >> 24) as u8
                    }
                })
                .collect();
            b[0] = 1;
            b[1] = 0;
            let pk = LidarPacket::new_checked(&b[..], f).unwrap();
            for c in pk.columns() {
                let mut want = std::vec::Vec::new();
                for ch in 0..64 {
                    let px = c.pixel(ch);
                    for r in 0..p.returns() {
                        if px.range_mm[r] != 0 {
                            want.push((ch, r, px.range_mm[r]));
                        }
                    }
                }
                let mut got = std::vec::Vec::new();
                c.for_each_return(|ch, r, mm| got.push((ch, r, mm)));
                assert_eq!(got, want, "{p:?}");
            }
        }
    }

    /// The emit side writes the standard header and the single-return profile where the
    /// manual puts them (hand-packed here), and a CRC-64/XZ its reader agrees with.
    #[test]
    fn an_emitted_packet_is_the_manuals_layout() {
        let f = Format::new(Profile::Single, HeaderKind::Standard, 16, 64).unwrap();
        let mut out = std::vec![0u8; f.packet_len()];
        let mut p = LidarPacket::emit(&mut out[..], f, 700, 0x12_3456, 0x55_4433_2211).unwrap();
        p.set_column(2, 987_654_321_000, 513);
        p.set_return(2, 7, 0x7_ABCD, 77);
        p.seal();
        let mut want = std::vec![0u8; f.packet_len()];
        want[..12].copy_from_slice(&[
            1, 0, 0xBC, 0x02, 0x56, 0x34, 0x12, 0x11, 0x22, 0x33, 0x44, 0x55,
        ]);
        let col = 32 + 2 * (12 + 64 * 12);
        want[col..col + 8].copy_from_slice(&987_654_321_000u64.to_le_bytes());
        want[col + 8..col + 12].copy_from_slice(&[0x01, 0x02, 1, 0]);
        let px = col + 12 + 7 * 12;
        want[px..px + 5].copy_from_slice(&[0xCD, 0xAB, 0x07, 0, 77]);
        let n = want.len() - 8;
        assert_eq!(out[..n], want[..n]);
        let p = LidarPacket::new_checked(&out[..], f).unwrap();
        let (sent, computed) = p.crc().unwrap();
        assert_eq!(sent, computed);
        assert_eq!(
            (p.frame_id(), p.init_id(), p.serial()),
            (700, Some(0x12_3456), Some(0x55_4433_2211))
        );
        let c = p.column(2);
        assert!(c.valid() && !p.column(1).valid());
        assert_eq!(
            (c.pixel(7).range_mm[0], c.pixel(7).reflectivity[0]),
            (0x7_ABCD, 77)
        );
        let legacy = Format::new(Profile::Legacy, HeaderKind::Legacy, 16, 64).unwrap();
        assert!(LidarPacket::emit(&mut out[..], legacy, 0, 0, 0).is_none());
    }

    /// Each profile's fields at their bits, hand-packed: LEGACY's 20-bit range beside its
    /// flag bits, the low-data-rate range in 8 mm units and NIR in 16s, the dual's second
    /// return.
    #[test]
    fn fields_sit_at_their_bits() {
        // LEGACY: range 0xABCDE mm with the flag nibble set above it.
        let f = legacy32();
        let mut b = std::vec![0u8; f.packet_len()];
        let col = f.column_len();
        let at = col + 16 + 3 * 12; // column 1, pixel 3
        b[at..at + 4].copy_from_slice(&(0xF00A_BCDEu32).to_le_bytes());
        b[at + 4] = 77;
        b[at + 6..at + 8].copy_from_slice(&1234u16.to_le_bytes());
        b[at + 8..at + 10].copy_from_slice(&555u16.to_le_bytes());
        b[col..col + 8].copy_from_slice(&123_456_789u64.to_le_bytes());
        b[col + 8..col + 10].copy_from_slice(&513u16.to_le_bytes());
        b[10..12].copy_from_slice(&42u16.to_le_bytes());
        b[2 * col - 4..2 * col].copy_from_slice(&[0xFF; 4]);
        let p = LidarPacket::new_checked(&b[..], f).unwrap();
        assert_eq!(p.frame_id(), 42);
        let c = p.column(1);
        assert!(c.valid() && !p.column(0).valid());
        assert_eq!((c.timestamp_ns(), c.measurement_id()), (123_456_789, 513));
        assert_eq!(
            c.pixel(3),
            Pixel {
                range_mm: [0xABCDE, 0],
                reflectivity: [77, 0],
                signal: [1234, 0],
                nir: 555
            }
        );
        // RNG15_RFL8_NIR8_DUAL: 15-bit ranges in 8 mm units under their flag bits.
        let g = Format::new(Profile::LowRateDual, HeaderKind::Standard, 16, 16).unwrap();
        let mut b = std::vec![0u8; g.packet_len()];
        b[0] = 1;
        b[2..4].copy_from_slice(&700u16.to_le_bytes());
        b[7..12].copy_from_slice(&[0x11, 0x22, 0x33, 0x44, 0x55]);
        let at = 32 + 12 + 8 * 5; // column 0, pixel 5
        b[at..at + 2].copy_from_slice(&(0x8000u16 | 1000).to_le_bytes());
        b[at + 2] = 9;
        b[at + 3] = 3;
        b[at + 4..at + 6].copy_from_slice(&(0x8000u16 | 2000).to_le_bytes());
        b[at + 6] = 10;
        b[32 + 10] = 1;
        let p = LidarPacket::new_checked(&b[..], g).unwrap();
        assert_eq!((p.frame_id(), p.serial()), (700, Some(0x55_4433_2211)));
        let c = p.column(0);
        assert!(c.valid());
        assert_eq!(
            c.pixel(5),
            Pixel {
                range_mm: [8000, 16000],
                reflectivity: [9, 10],
                signal: [0, 0],
                nir: 48
            }
        );
    }
}

//! The layout of a lidar packet: its profile (`udp_profile_lidar`), its header kind and the
//! metadata's `columns_per_packet` and `pixels_per_column` (firmware manual, "Lidar Data
//! Profiles").
//!
//! ```text
//! LEGACY:     column = 16-byte header + pixels x 12 bytes + 4-byte status; no packet header
//! the others: 32-byte packet header + columns (12-byte header + pixels x size) + 32-byte footer
//! ```

use super::Error;

/// The per-pixel layout (`udp_profile_lidar`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Profile {
    /// `LEGACY` (firmware before 2.2; 20-bit range in mm, reflectivity, signal, NIR).
    Legacy,
    /// `RNG19_RFL8_SIG16_NIR16`: single return, 12 bytes.
    Single,
    /// `RNG19_RFL8_SIG16_NIR16_DUAL`: two returns, 16 bytes.
    Dual,
    /// `RNG15_RFL8_NIR8`: low data rate, 4 bytes (range in 8 mm units).
    LowRate,
    /// `RNG15_RFL8_NIR8_DUAL` (and its `FUSA_` form): low data rate, two returns, 8 bytes.
    LowRateDual,
}

impl Profile {
    /// The profile a metadata name gives, and the header kind it implies (`FUSA_` names
    /// carry the FuSa packet header); `None` for a profile spherecal does not read.
    pub fn from_name(name: &str) -> Option<(Self, HeaderKind)> {
        let (fusa, bare) = match name.strip_prefix("FUSA_") {
            Some(b) => (true, b),
            None => (false, name),
        };
        let p = match bare {
            "LEGACY" if !fusa => Self::Legacy,
            "RNG19_RFL8_SIG16_NIR16" => Self::Single,
            "RNG19_RFL8_SIG16_NIR16_DUAL" => Self::Dual,
            "RNG15_RFL8_NIR8" => Self::LowRate,
            "RNG15_RFL8_NIR8_DUAL" => Self::LowRateDual,
            _ => return None,
        };
        let h = match (p, fusa) {
            (Self::Legacy, _) => HeaderKind::Legacy,
            (_, true) => HeaderKind::Fusa,
            (_, false) => HeaderKind::Standard,
        };
        Some((p, h))
    }

    /// The metadata's name (the plain, not the `FUSA_`, form).
    pub fn name(self) -> &'static str {
        match self {
            Self::Legacy => "LEGACY",
            Self::Single => "RNG19_RFL8_SIG16_NIR16",
            Self::Dual => "RNG19_RFL8_SIG16_NIR16_DUAL",
            Self::LowRate => "RNG15_RFL8_NIR8",
            Self::LowRateDual => "RNG15_RFL8_NIR8_DUAL",
        }
    }

    /// Bytes per pixel.
    pub const fn pixel_len(self) -> usize {
        match self {
            Self::Legacy | Self::Single => 12,
            Self::Dual => 16,
            Self::LowRate => 4,
            Self::LowRateDual => 8,
        }
    }

    /// Returns per pixel.
    pub const fn returns(self) -> usize {
        match self {
            Self::Dual | Self::LowRateDual => 2,
            _ => 1,
        }
    }
}

/// The packet header's layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HeaderKind {
    /// No packet header: the frame id is in each column's header.
    Legacy,
    /// The 32-byte header of firmware 2.2+: packet type u16, frame id u16, init id u24,
    /// serial number u40.
    Standard,
    /// The FuSa header: packet type u8, init id u24, frame id u32, alert flags, serial u40.
    Fusa,
}

/// A lidar packet's layout: what the metadata declares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Format {
    /// The pixel layout.
    pub profile: Profile,
    /// The packet header's layout.
    pub header: HeaderKind,
    /// Columns (azimuth steps) per packet (`columns_per_packet`: 16 on every sensor so far).
    pub columns: usize,
    /// Pixels per column: the beams (`pixels_per_column`: 16, 32, 64 or 128).
    pub pixels: usize,
}

/// Largest UDP payload.
const MAX_PACKET: usize = 65_535;

impl Format {
    /// A format, checked: 1-128 pixels, 1-64 columns, a packet within a UDP datagram.
    pub fn new(
        profile: Profile,
        header: HeaderKind,
        columns: usize,
        pixels: usize,
    ) -> Result<Self, Error> {
        let f = Self {
            profile,
            header,
            columns,
            pixels,
        };
        if !(1..=super::MAX_BEAMS).contains(&pixels)
            || !(1..=64).contains(&columns)
            || f.packet_len() > MAX_PACKET
        {
            return Err(Error::Format);
        }
        Ok(f)
    }

    /// The packet header's length (0 or 32).
    pub const fn header_len(&self) -> usize {
        match self.header {
            HeaderKind::Legacy => 0,
            _ => 32,
        }
    }

    /// A column header's length (16 legacy, else 12).
    pub const fn column_header_len(&self) -> usize {
        match self.header {
            HeaderKind::Legacy => 16,
            _ => 12,
        }
    }

    /// A column's status footer (4 legacy, else 0).
    pub const fn column_footer_len(&self) -> usize {
        match self.header {
            HeaderKind::Legacy => 4,
            _ => 0,
        }
    }

    /// A column's length.
    pub const fn column_len(&self) -> usize {
        self.column_header_len() + self.pixels * self.profile.pixel_len() + self.column_footer_len()
    }

    /// The packet footer's length (0 legacy, else 32).
    pub const fn footer_len(&self) -> usize {
        self.header_len()
    }

    /// The whole packet's length: the UDP payload.
    pub const fn packet_len(&self) -> usize {
        self.header_len() + self.columns * self.column_len() + self.footer_len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sizes the firmware manual gives: a 16-column LEGACY packet of 64 beams is 12,608
    /// bytes (its table "Lidar Data Packet Format"), 32 beams 6,464 (the OS-1-32-G capture's
    /// UDP payload); RNG19_RFL8_SIG16_NIR16 of 128 beams 24,896 ...
    #[test]
    fn packet_lengths_are_the_manuals() {
        let f = |p: &str, cols, px| {
            let (p, h) = Profile::from_name(p).unwrap();
            Format::new(p, h, cols, px).unwrap().packet_len()
        };
        assert_eq!(f("LEGACY", 16, 64), 12_608);
        assert_eq!(f("LEGACY", 16, 32), 6_464);
        assert_eq!(
            f("RNG19_RFL8_SIG16_NIR16", 16, 128),
            32 + 16 * (12 + 128 * 12) + 32
        );
        assert_eq!(
            f("RNG19_RFL8_SIG16_NIR16_DUAL", 16, 32),
            32 + 16 * (12 + 32 * 16) + 32
        );
        assert_eq!(f("RNG15_RFL8_NIR8", 16, 128), 32 + 16 * (12 + 128 * 4) + 32);
        assert_eq!(
            f("FUSA_RNG15_RFL8_NIR8_DUAL", 16, 128),
            32 + 16 * (12 + 128 * 8) + 32
        );
        assert_eq!(
            Profile::from_name("FUSA_RNG15_RFL8_NIR8_DUAL").unwrap().1,
            HeaderKind::Fusa
        );
        assert_eq!(Profile::from_name("FUSA_LEGACY"), None);
        assert_eq!(Profile::from_name("FIVE_WORD_PIXEL"), None);
        assert_eq!(
            Format::new(Profile::Single, HeaderKind::Standard, 16, 129),
            Err(Error::Format)
        );
        assert_eq!(
            Format::new(Profile::Single, HeaderKind::Standard, 0, 64),
            Err(Error::Format)
        );
    }
}

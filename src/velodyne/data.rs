//! The VLP-16 data packet: a checked view over the 1206-byte UDP payload (manual 9.3.1,
//! figure 9-3) and its emit side.
//!
//! ```text
//! offset  size  field
//!  0+100b    2  block flag 0xFF 0xEE                     (b = block 0..11)
//!  2+100b    2  azimuth, u16 LE, 0.01 deg, 0..35999 (36000 is sent too: it is 0)
//!  4+100b   96  32 channels x { distance u16 LE [2 mm], reflectivity u8 }
//!   1200     4  timestamp, u32 LE, microseconds past the top of the hour
//!   1204     1  return mode 0x37 / 0x38 / 0x39
//!   1205     1  product id
//! ```

use super::{Error, Model, ReturnMode};
use crate::le::le16;

/// Byte layout of a data packet (manual figure 9-3).
pub mod field {
    use core::ops::Range;
    /// Blocks per packet.
    pub const BLOCKS: usize = 12;
    /// Bytes per block.
    pub const BLOCK_LEN: usize = 100;
    /// Channels per block (two firing sequences of 16 lasers).
    pub const CHANNELS: usize = 32;
    /// Bytes per channel: distance u16 LE + reflectivity u8.
    pub const CHANNEL_LEN: usize = 3;
    /// Within a block: the flag bytes.
    pub const FLAG: Range<usize> = 0..2;
    /// Within a block: the azimuth.
    pub const AZIMUTH: Range<usize> = 2..4;
    /// Within a block: first channel.
    pub const CHANNEL0: usize = 4;
    /// The block flag value as it appears on the wire.
    pub const FLAG_BYTES: [u8; 2] = [0xFF, 0xEE];
    /// Packet timestamp.
    pub const TIMESTAMP: Range<usize> = 1200..1204;
    /// Return mode byte.
    pub const RETURN_MODE: usize = 1204;
    /// Product id byte.
    pub const PRODUCT: usize = 1205;
    /// Payload length.
    pub const LEN: usize = 1206;
}

/// Length of a data packet's UDP payload.
pub const DATA_PACKET_LEN: usize = field::LEN;

/// A raw view over the bytes of a data packet.
///
/// Built with [`DataPacket::new_checked`], every accessor is infallible: block and channel
/// indices are reduced modulo 12 and 32, so no index can panic.
#[derive(Debug, Clone, Copy)]
pub struct DataPacket<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> DataPacket<T> {
    /// Wrap a buffer without checking it. Accessors may panic on a short buffer; use
    /// [`Self::new_checked`] on anything from the outside.
    pub const fn new_unchecked(buffer: T) -> Self {
        Self { buffer }
    }

    /// Wrap a buffer after [`Self::check_len`] and [`Self::check_flags`].
    pub fn new_checked(buffer: T) -> Result<Self, Error> {
        let p = Self::new_unchecked(buffer);
        p.check_len()?;
        p.check_flags()?;
        Ok(p)
    }

    /// At least 1206 bytes (a longer buffer is accepted; bytes past 1206 are ignored).
    pub fn check_len(&self) -> Result<(), Error> {
        let got = self.buffer.as_ref().len();
        if got < field::LEN {
            Err(Error::Truncated {
                expected: field::LEN,
                got,
            })
        } else {
            Ok(())
        }
    }

    /// Every block starts with 0xFF 0xEE.
    pub fn check_flags(&self) -> Result<(), Error> {
        for (b, block) in self.blocks().enumerate() {
            if block[field::FLAG] != field::FLAG_BYTES {
                return Err(Error::BadBlockFlag {
                    block: b as u8,
                    found: u16::from_be_bytes([block[0], block[1]]),
                });
            }
        }
        Ok(())
    }

    /// The 12 blocks as fixed-size arrays.
    #[inline]
    pub fn blocks(&self) -> impl Iterator<Item = &[u8; field::BLOCK_LEN]> + '_ {
        let (blocks, _) = self.buffer.as_ref()[..field::BLOCKS * field::BLOCK_LEN].as_chunks();
        blocks.iter()
    }

    #[inline(always)]
    fn block(&self, block: usize) -> &[u8] {
        let start = (block % field::BLOCKS) * field::BLOCK_LEN;
        &self.buffer.as_ref()[start..start + field::BLOCK_LEN]
    }

    /// Block azimuth in hundredths of a degree (raw; 0..=36000 on a valid packet, 36000 = 0).
    #[inline]
    pub fn azimuth_raw(&self, block: usize) -> u16 {
        le16(self.block(block), field::AZIMUTH.start)
    }

    /// Raw distance of a channel (0..31) in 2 mm units; 0 = no return.
    #[inline]
    pub fn distance_raw(&self, block: usize, channel: usize) -> u16 {
        let at = field::CHANNEL0 + (channel % field::CHANNELS) * field::CHANNEL_LEN;
        le16(self.block(block), at)
    }

    /// How many of a block's 32 channels hold a return (a distance other than 0).
    #[inline]
    pub fn returns_in_block(&self, block: usize) -> usize {
        let ch = &self.block(block)[field::CHANNEL0..];
        let Ok(ch) = <&[u8; field::CHANNELS * field::CHANNEL_LEN]>::try_from(ch) else {
            return 0;
        };
        let mut n = 0;
        for c in 0..field::CHANNELS {
            n += usize::from(ch[3 * c] | ch[3 * c + 1] != 0);
        }
        n
    }

    /// Distance of a channel in metres.
    #[inline]
    pub fn distance_m(&self, block: usize, channel: usize) -> f32 {
        f32::from(self.distance_raw(block, channel)) * 0.002
    }

    /// Calibrated reflectivity of a channel (0..100 diffuse, 101..255 retro-reflective).
    #[inline]
    pub fn reflectivity(&self, block: usize, channel: usize) -> u8 {
        let at = field::CHANNEL0 + (channel % field::CHANNELS) * field::CHANNEL_LEN + 2;
        self.block(block)[at]
    }

    /// Microseconds past the top of the UTC hour at the first firing of the packet.
    #[inline]
    pub fn timestamp_us(&self) -> u32 {
        let b = self.buffer.as_ref();
        u32::from_le_bytes([b[1200], b[1201], b[1202], b[1203]])
    }

    /// The raw return-mode byte.
    #[inline]
    pub fn return_mode_raw(&self) -> u8 {
        self.buffer.as_ref()[field::RETURN_MODE]
    }

    /// The return mode, or the unknown byte as an error.
    #[inline]
    pub fn return_mode(&self) -> Result<ReturnMode, Error> {
        ReturnMode::from_byte(self.return_mode_raw())
    }

    /// The raw product-id byte.
    #[inline]
    pub fn product_raw(&self) -> u8 {
        self.buffer.as_ref()[field::PRODUCT]
    }

    /// The model the product-id byte names, if any (see [`super::Detector`] on why it is not
    /// to be trusted alone).
    #[inline]
    pub fn model(&self) -> Option<Model> {
        Model::from_product(self.product_raw())
    }

    /// The underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> DataPacket<T> {
    #[inline(always)]
    fn block_mut(&mut self, block: usize) -> &mut [u8] {
        let start = (block % field::BLOCKS) * field::BLOCK_LEN;
        &mut self.buffer.as_mut()[start..start + field::BLOCK_LEN]
    }

    /// Write the 0xFF 0xEE flag of a block.
    pub fn set_flag(&mut self, block: usize) {
        self.block_mut(block)[field::FLAG].copy_from_slice(&field::FLAG_BYTES);
    }

    /// Write a block azimuth (0.01 deg).
    pub fn set_azimuth_raw(&mut self, block: usize, value: u16) {
        self.block_mut(block)[field::AZIMUTH].copy_from_slice(&value.to_le_bytes());
    }

    /// Write one channel's distance (2 mm units) and reflectivity.
    pub fn set_channel(
        &mut self,
        block: usize,
        channel: usize,
        distance_raw: u16,
        reflectivity: u8,
    ) {
        let at = field::CHANNEL0 + (channel % field::CHANNELS) * field::CHANNEL_LEN;
        let b = self.block_mut(block);
        b[at..at + 2].copy_from_slice(&distance_raw.to_le_bytes());
        b[at + 2] = reflectivity;
    }

    /// Write the packet timestamp (microseconds past the hour).
    pub fn set_timestamp_us(&mut self, value: u32) {
        self.buffer.as_mut()[field::TIMESTAMP].copy_from_slice(&value.to_le_bytes());
    }

    /// Write the return-mode byte.
    pub fn set_return_mode(&mut self, mode: ReturnMode) {
        self.buffer.as_mut()[field::RETURN_MODE] = mode.to_byte();
    }

    /// Write the product-id byte.
    pub fn set_product_raw(&mut self, value: u8) {
        self.buffer.as_mut()[field::PRODUCT] = value;
    }
}

/// One data block in real units.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockRepr {
    /// Azimuth, 0.01 deg, 0..=36000 (36000 = 0, as real units send it).
    pub azimuth: u16,
    /// Per channel: raw distance (2 mm units) and reflectivity.
    pub channels: [(u16, u8); field::CHANNELS],
}

/// A whole data packet, validated: every flag right, every azimuth in range, a known mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DataRepr {
    /// The 12 blocks.
    pub blocks: [BlockRepr; field::BLOCKS],
    /// Microseconds past the top of the hour.
    pub timestamp_us: u32,
    /// Return mode.
    pub return_mode: ReturnMode,
    /// Product id byte.
    pub product: u8,
}

impl DataRepr {
    /// Parse and validate a packet view.
    pub fn parse<T: AsRef<[u8]>>(packet: &DataPacket<T>) -> Result<Self, Error> {
        packet.check_len()?;
        packet.check_flags()?;
        let return_mode = packet.return_mode()?;
        let mut blocks = [BlockRepr {
            azimuth: 0,
            channels: [(0, 0); field::CHANNELS],
        }; field::BLOCKS];
        for (b, repr) in blocks.iter_mut().enumerate() {
            repr.azimuth = packet.azimuth_raw(b);
            if repr.azimuth > 36_000 {
                return Err(Error::BadAzimuth {
                    block: b as u8,
                    found: repr.azimuth,
                });
            }
            for (c, ch) in repr.channels.iter_mut().enumerate() {
                *ch = (packet.distance_raw(b, c), packet.reflectivity(b, c));
            }
        }
        Ok(Self {
            blocks,
            timestamp_us: packet.timestamp_us(),
            return_mode,
            product: packet.product_raw(),
        })
    }

    /// Write this packet into a view of at least 1206 bytes (check the length first).
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, packet: &mut DataPacket<T>) {
        for (b, repr) in self.blocks.iter().enumerate() {
            packet.set_flag(b);
            packet.set_azimuth_raw(b, repr.azimuth);
            for (c, &(d, r)) in repr.channels.iter().enumerate() {
                packet.set_channel(b, c, d, r);
            }
        }
        packet.set_timestamp_us(self.timestamp_us);
        packet.set_return_mode(self.return_mode);
        packet.set_product_raw(self.product);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blank() -> [u8; DATA_PACKET_LEN] {
        let mut buf = [0u8; DATA_PACKET_LEN];
        let mut p = DataPacket::new_unchecked(&mut buf[..]);
        for b in 0..12 {
            p.set_flag(b);
        }
        p.set_return_mode(ReturnMode::Strongest);
        p.set_product_raw(0x22);
        buf
    }

    #[test]
    fn field_offsets_match_the_manual() {
        // Manual figure 9-3: block b starts at 100 b; channel c at 4 + 3 c; stamp at 1200.
        let mut buf = blank();
        let mut p = DataPacket::new_unchecked(&mut buf[..]);
        p.set_azimuth_raw(3, 0x1234);
        p.set_channel(3, 31, 0xABCD, 0x77);
        p.set_timestamp_us(0x0102_0304);
        assert_eq!(&buf[302..304], &[0x34, 0x12]);
        assert_eq!(&buf[300 + 4 + 93..300 + 4 + 96], &[0xCD, 0xAB, 0x77]);
        assert_eq!(&buf[1200..1206], &[0x04, 0x03, 0x02, 0x01, 0x37, 0x22]);
    }

    #[test]
    fn short_buffer_is_refused() {
        let buf = blank();
        assert_eq!(
            DataPacket::new_checked(&buf[..1205]).unwrap_err(),
            Error::Truncated {
                expected: 1206,
                got: 1205
            }
        );
        assert_eq!(
            DataPacket::new_checked(&[][..]).unwrap_err(),
            Error::Truncated {
                expected: 1206,
                got: 0
            }
        );
    }

    #[test]
    fn broken_flag_is_named() {
        let mut buf = blank();
        buf[700] = 0xFE;
        assert_eq!(
            DataPacket::new_checked(&buf[..]).unwrap_err(),
            Error::BadBlockFlag {
                block: 7,
                found: 0xFEEE
            }
        );
    }

    #[test]
    fn repr_rejects_bad_azimuth_and_mode() {
        let mut buf = blank();
        DataPacket::new_unchecked(&mut buf[..]).set_azimuth_raw(5, 36_001);
        let p = DataPacket::new_checked(&buf[..]).unwrap();
        assert_eq!(
            DataRepr::parse(&p).unwrap_err(),
            Error::BadAzimuth {
                block: 5,
                found: 36_001
            }
        );
        let mut buf = blank();
        buf[1204] = 0x40;
        let p = DataPacket::new_checked(&buf[..]).unwrap();
        assert_eq!(
            DataRepr::parse(&p).unwrap_err(),
            Error::UnknownReturnMode { found: 0x40 }
        );
    }
}

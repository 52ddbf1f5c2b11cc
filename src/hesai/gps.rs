//! The GPS packet view (UDP 10110, 512 bytes; PandarXT-32 manual 3.2, PandarQT manual 3.2.2).
//!
//! ```text
//! 0   header 0xFF 0xEE
//! 2   date: year (since 2000), month, day - two ASCII digits each, the ones digit first
//! 8   time: second, minute, hour - the same
//! 14  microseconds u32 (reserved on the XT)
//! 18  the NMEA sentence ($GPRMC or $GPGGA) the unit took its time from, 84 bytes
//! 102 reserved (0xDF)
//! 506 positioning status: 'A' valid, 'V' invalid, 0 no GPS (from $GPRMC)
//! 507 PPS lock: 1 locked, 0 not
//! 508 reserved
//! ```

use super::Error;
use crate::time::UtcDateTime;

/// The packet's length.
pub const GPS_PACKET_LEN: usize = 512;

mod field {
    pub const DATE: usize = 2;
    pub const TIME: usize = 8;
    pub const NMEA: core::ops::Range<usize> = 18..102;
    pub const STATUS: usize = 506;
    pub const PPS: usize = 507;
}

/// A checked GPS packet.
#[derive(Debug, Clone, Copy)]
pub struct GpsPacket<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> GpsPacket<T> {
    /// Wrap `buffer`: 512 bytes starting 0xFF 0xEE.
    pub fn new_checked(buffer: T) -> Result<Self, Error> {
        let b = buffer.as_ref();
        if b.len() != GPS_PACKET_LEN {
            return Err(Error::Length {
                expected: GPS_PACKET_LEN,
                got: b.len(),
            });
        }
        if b[0] != 0xFF || b[1] != 0xEE {
            return Err(Error::Start {
                found: [b[0], b[1]],
            });
        }
        Ok(Self { buffer })
    }

    /// The packet's bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.buffer.as_ref()
    }

    /// Three two-digit ASCII numbers from `at`, each its ones digit first; `None` when a byte
    /// is not a digit.
    fn digits(&self, at: usize) -> Option<[u8; 3]> {
        let b = self.buffer.as_ref();
        let mut v = [0u8; 3];
        for (k, x) in v.iter_mut().enumerate() {
            let (ones, tens) = (b[at + 2 * k], b[at + 2 * k + 1]);
            if !ones.is_ascii_digit() || !tens.is_ascii_digit() {
                return None;
            }
            *x = (tens - b'0') * 10 + (ones - b'0');
        }
        Some(v)
    }

    /// The UTC date and time to the second the unit holds (its PPS's second); `None` when the
    /// fields are not digits or not a date.
    pub fn utc(&self) -> Option<UtcDateTime> {
        let [y, mo, d] = self.digits(field::DATE)?;
        let [s, mi, h] = self.digits(field::TIME)?;
        super::date_time(2000 + i32::from(y), [mo, d, h, mi, s])
    }

    /// The NMEA sentence, up to the two checksum digits after `*` (the rest is padding).
    pub fn nmea(&self) -> &[u8] {
        let n = &self.buffer.as_ref()[field::NMEA];
        match n.iter().position(|&c| c == b'*') {
            Some(star) => &n[..(star + 3).min(n.len())],
            None => n,
        }
    }

    /// The time of its NMEA sentence; `None` when it is not a readable `$GPRMC` or `$GPGGA`
    /// with a good checksum.
    pub fn nmea_time(&self) -> Option<crate::velodyne::NmeaTime> {
        let s = core::str::from_utf8(self.nmea()).ok()?;
        crate::velodyne::position::nmea_time(s).ok()
    }

    /// The positioning status byte: `b'A'` valid, `b'V'` invalid, 0 no GPS.
    pub fn positioning(&self) -> u8 {
        self.buffer.as_ref()[field::STATUS]
    }

    /// Whether the unit's clock is locked to the PPS.
    pub fn pps_locked(&self) -> bool {
        self.buffer.as_ref()[field::PPS] == 1
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> GpsPacket<T> {
    /// Write a GPS packet into `buffer` (512 bytes, else `None`): the UTC second `utc` (years
    /// 2000-2099), the NMEA sentence it came from (cut to 84 bytes), the positioning status
    /// (`b'A'`, `b'V'` or 0) and the PPS lock.
    pub fn emit(
        mut buffer: T,
        utc: &UtcDateTime,
        nmea: &[u8],
        status: u8,
        pps_locked: bool,
    ) -> Option<Self> {
        let b = buffer.as_mut();
        if b.len() != GPS_PACKET_LEN || !(2000..2100).contains(&utc.year) {
            return None;
        }
        b.fill(0xDF);
        b[..field::NMEA.end].fill(0);
        b[..2].copy_from_slice(&[0xFF, 0xEE]);
        let two = |v: u8| [b'0' + v % 10, b'0' + v / 10 % 10];
        let fields = [
            (utc.year - 2000) as u8,
            utc.month,
            utc.day,
            utc.second,
            utc.minute,
            utc.hour,
        ];
        for (k, v) in fields.into_iter().enumerate() {
            b[field::DATE + 2 * k..field::DATE + 2 * k + 2].copy_from_slice(&two(v));
        }
        let n = nmea.len().min(field::NMEA.len());
        b[field::NMEA.start..field::NMEA.start + n].copy_from_slice(&nmea[..n]);
        b[field::STATUS] = status;
        b[field::PPS] = u8::from(pps_locked);
        Some(Self { buffer })
    }
}

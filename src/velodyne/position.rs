//! The VLP-16 position packet: a checked view over the 512-byte UDP payload (manual 9.4,
//! table 9-5; the manual gives frame offsets, 42 more than these payload offsets).
//!
//! ```text
//! offset  size  field
//!    198     4  timestamp, u32 LE, microseconds past the top of the hour
//!    202     1  PPS status: 0 none, 1 synchronizing, 2 locked, 3 error
//!    206   128  NMEA sentence ($GPRMC, or $GPGGA on newer firmware), CR/LF, NUL padded
//! ```

use super::Error;
use crate::time::UtcDateTime;
use chrono::{Datelike, Timelike};

/// Byte layout of a position packet (manual table 9-5, as payload offsets).
pub mod field {
    use core::ops::Range;
    /// Timestamp, microseconds past the hour.
    pub const TIMESTAMP: Range<usize> = 198..202;
    /// PPS status byte.
    pub const PPS: usize = 202;
    /// The NMEA sentence, CR/LF terminated, NUL padded.
    pub const NMEA: Range<usize> = 206..334;
    /// Payload length.
    pub const LEN: usize = 512;
}

/// Length of a position packet's UDP payload.
pub const POSITION_PACKET_LEN: usize = field::LEN;

/// PPS status byte (manual table 9-5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PpsStatus {
    /// 0: no PPS detected.
    Absent,
    /// 1: synchronizing to PPS.
    Synchronizing,
    /// 2: PPS locked.
    Locked,
    /// 3: error.
    Error,
    /// Any other byte.
    Unknown(u8),
}

impl From<u8> for PpsStatus {
    fn from(b: u8) -> Self {
        match b {
            0 => Self::Absent,
            1 => Self::Synchronizing,
            2 => Self::Locked,
            3 => Self::Error,
            other => Self::Unknown(other),
        }
    }
}

impl PpsStatus {
    /// The wire byte.
    pub fn to_byte(self) -> u8 {
        match self {
            Self::Absent => 0,
            Self::Synchronizing => 1,
            Self::Locked => 2,
            Self::Error => 3,
            Self::Unknown(b) => b,
        }
    }
}

/// The time an NMEA sentence in a position packet carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NmeaTime {
    /// `true` for $xxRMC (date and time), `false` for $xxGGA (time of day only).
    pub is_rmc: bool,
    /// RMC status A (valid) or GGA fix quality > 0.
    pub valid: bool,
    /// Date (year, month, day) from RMC.
    pub date: Option<(i32, u8, u8)>,
    /// Hour of the day, UTC.
    pub hour: u8,
    /// Minute.
    pub minute: u8,
    /// Second.
    pub second: u8,
    /// Nanoseconds within the second.
    pub nanos: u32,
}

impl NmeaTime {
    /// Full UTC date-time (RMC only; GGA has no date).
    pub fn utc(&self) -> Option<UtcDateTime> {
        let (year, month, day) = self.date?;
        Some(UtcDateTime {
            year,
            month,
            day,
            hour: self.hour,
            minute: self.minute,
            second: self.second,
            nanos: self.nanos,
        })
    }
}

/// A raw view over the bytes of a position packet.
#[derive(Debug, Clone, Copy)]
pub struct PositionPacket<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> PositionPacket<T> {
    /// Wrap without checking.
    pub const fn new_unchecked(buffer: T) -> Self {
        Self { buffer }
    }

    /// Wrap after checking the length.
    pub fn new_checked(buffer: T) -> Result<Self, Error> {
        let p = Self::new_unchecked(buffer);
        p.check_len()?;
        Ok(p)
    }

    /// At least 512 bytes.
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

    /// The underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Microseconds past the top of the hour when the packet was made.
    pub fn timestamp_us(&self) -> u32 {
        let b = self.buffer.as_ref();
        u32::from_le_bytes([b[198], b[199], b[200], b[201]])
    }

    /// PPS status.
    pub fn pps(&self) -> PpsStatus {
        PpsStatus::from(self.buffer.as_ref()[field::PPS])
    }

    /// The NMEA sentence bytes, without CR/LF and NUL padding (may be empty).
    pub fn nmea_bytes(&self) -> &[u8] {
        let f = &self.buffer.as_ref()[field::NMEA];
        let end = f
            .iter()
            .position(|&c| c == b'\r' || c == b'\n' || c == 0)
            .unwrap_or(f.len());
        &f[..end]
    }

    /// The sentence as text, if it is ASCII.
    pub fn nmea_str(&self) -> Option<&str> {
        let b = self.nmea_bytes();
        if b.is_ascii() {
            core::str::from_utf8(b).ok()
        } else {
            None
        }
    }

    /// Parse the sentence (checksum verified by the `nmea` crate): RMC gives date and time,
    /// GGA time of day only.
    pub fn nmea_time(&self) -> Result<NmeaTime, Error> {
        nmea_time(self.nmea_str().ok_or(Error::BadNmea)?)
    }
}

/// The time of an NMEA sentence (checksum verified by the `nmea` crate): RMC gives date and
/// time, GGA time of day only.
pub fn nmea_time(s: &str) -> Result<NmeaTime, Error> {
    match nmea::parse_str(s).map_err(|_| Error::BadNmea)? {
        nmea::ParseResult::RMC(rmc) => {
            let t = rmc.fix_time.ok_or(Error::BadNmea)?;
            let date = rmc
                .fix_date
                .map(|d| (d.year(), d.month() as u8, d.day() as u8));
            Ok(NmeaTime {
                is_rmc: true,
                valid: !matches!(
                    rmc.status_of_fix,
                    nmea::sentences::rmc::RmcStatusOfFix::Invalid
                ),
                date,
                hour: t.hour() as u8,
                minute: t.minute() as u8,
                second: t.second() as u8,
                nanos: t.nanosecond(),
            })
        }
        nmea::ParseResult::GGA(gga) => {
            let t = gga.fix_time.ok_or(Error::BadNmea)?;
            Ok(NmeaTime {
                is_rmc: false,
                valid: gga.fix_type.is_some_and(|f| f.is_valid()),
                date: None,
                hour: t.hour() as u8,
                minute: t.minute() as u8,
                second: t.second() as u8,
                nanos: t.nanosecond(),
            })
        }
        _ => Err(Error::BadNmea),
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> PositionPacket<T> {
    /// Write the timestamp.
    pub fn set_timestamp_us(&mut self, value: u32) {
        self.buffer.as_mut()[field::TIMESTAMP].copy_from_slice(&value.to_le_bytes());
    }
    /// Write the PPS status.
    pub fn set_pps(&mut self, pps: PpsStatus) {
        self.buffer.as_mut()[field::PPS] = pps.to_byte();
    }
    /// Write an NMEA sentence (without CR/LF; they are added), NUL padded; returns `false` and
    /// writes nothing if it does not fit in 126 bytes.
    pub fn set_nmea(&mut self, sentence: &[u8]) -> bool {
        let f = &mut self.buffer.as_mut()[field::NMEA];
        if sentence.len() + 2 > f.len() {
            return false;
        }
        f.fill(0);
        f[..sentence.len()].copy_from_slice(sentence);
        f[sentence.len()..sentence.len() + 2].copy_from_slice(b"\r\n");
        true
    }
}

/// A position packet in real units.
#[derive(Debug, Clone, PartialEq)]
pub struct PositionRepr<'a> {
    /// Microseconds past the hour.
    pub timestamp_us: u32,
    /// PPS status.
    pub pps: PpsStatus,
    /// NMEA sentence without CR/LF.
    pub nmea: &'a [u8],
}

impl<'a> PositionRepr<'a> {
    /// Parse a checked view.
    pub fn parse<T: AsRef<[u8]> + ?Sized>(
        packet: &'a PositionPacket<&'a T>,
    ) -> Result<Self, Error> {
        packet.check_len()?;
        Ok(Self {
            timestamp_us: packet.timestamp_us(),
            pps: packet.pps(),
            nmea: packet.nmea_bytes(),
        })
    }

    /// Write into a view of at least 512 bytes; `false` if the sentence is too long.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, packet: &mut PositionPacket<T>) -> bool {
        packet.set_timestamp_us(self.timestamp_us);
        packet.set_pps(self.pps);
        packet.set_nmea(self.nmea)
    }
}

/// Write `$GPRMC` for a UTC instant into `out` with its XOR checksum (NMEA 0183 4.10, 10.3.x);
/// returns the sentence length (no CR/LF), or `None` if `out` is too small (needs 80 bytes).
/// Position fields are the simulator's: latitude/longitude in degrees, speed in knots.
pub fn write_gprmc(
    out: &mut [u8],
    t: &UtcDateTime,
    lat_deg: f64,
    lon_deg: f64,
    valid: bool,
) -> Option<usize> {
    use core::fmt::Write;
    struct W<'b> {
        buf: &'b mut [u8],
        n: usize,
    }
    impl Write for W<'_> {
        fn write_str(&mut self, s: &str) -> core::fmt::Result {
            let end = self.n + s.len();
            let dst = self.buf.get_mut(self.n..end).ok_or(core::fmt::Error)?;
            dst.copy_from_slice(s.as_bytes());
            self.n = end;
            Ok(())
        }
    }
    let mut w = W { buf: out, n: 0 };
    let (ns, lat) = if lat_deg < 0.0 {
        ('S', -lat_deg)
    } else {
        ('N', lat_deg)
    };
    let (ew, lon) = if lon_deg < 0.0 {
        ('W', -lon_deg)
    } else {
        ('E', lon_deg)
    };
    let lat_d = lat as u32;
    let lon_d = lon as u32;
    let lat_m = (lat - f64::from(lat_d)) * 60.0;
    let lon_m = (lon - f64::from(lon_d)) * 60.0;
    write!(
        w,
        "$GPRMC,{:02}{:02}{:02}.{:02},{},{:02}{:010.7},{},{:03}{:010.7},{},0.000,0.0,{:02}{:02}{:02},0.0,E,{}",
        t.hour,
        t.minute,
        t.second,
        t.nanos / 10_000_000,
        if valid { 'A' } else { 'V' },
        lat_d,
        lat_m,
        ns,
        lon_d,
        lon_m,
        ew,
        t.day,
        t.month,
        t.year.rem_euclid(100),
        if valid { 'A' } else { 'N' }
    )
    .ok()?;
    let cs = w.buf.get(1..w.n)?.iter().fold(0u8, |a, &c| a ^ c);
    write!(w, "*{cs:02X}").ok()?;
    Some(w.n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn packet_with(sentence: &[u8]) -> [u8; POSITION_PACKET_LEN] {
        let mut buf = [0u8; POSITION_PACKET_LEN];
        let mut p = PositionPacket::new_unchecked(&mut buf[..]);
        p.set_timestamp_us(1_082_342_001);
        p.set_pps(PpsStatus::Locked);
        assert!(p.set_nmea(sentence));
        buf
    }

    #[test]
    fn real_rmc_sentence_gives_utc() {
        // The sentence of the MRPT capture's first position packet.
        let buf = packet_with(
            b"$GPRMC,081802.00,A,3649.7478558,N,00224.4542928,W,0.034,212.5,210116,0.0,E,A*2E",
        );
        let p = PositionPacket::new_checked(&buf[..]).unwrap();
        assert_eq!(p.pps(), PpsStatus::Locked);
        assert_eq!(&buf[198..203], &[0x71, 0x3A, 0x83, 0x40, 2]);
        let t = p.nmea_time().unwrap();
        assert!(t.is_rmc && t.valid);
        let utc = t.utc().unwrap();
        assert_eq!(
            (utc.year, utc.month, utc.day, utc.hour, utc.minute, utc.second),
            (2016, 1, 21, 8, 18, 2)
        );
    }

    #[test]
    fn bad_checksum_is_refused() {
        let buf = packet_with(
            b"$GPRMC,081802.00,A,3649.7478558,N,00224.4542928,W,0.034,212.5,210116,0.0,E,A*2F",
        );
        let p = PositionPacket::new_checked(&buf[..]).unwrap();
        assert_eq!(p.nmea_time(), Err(Error::BadNmea));
    }

    #[test]
    fn written_rmc_parses_back() {
        let t = UtcDateTime {
            year: 2026,
            month: 11,
            day: 22,
            hour: 23,
            minute: 59,
            second: 59,
            nanos: 0,
        };
        let mut s = [0u8; 96];
        let n = write_gprmc(&mut s, &t, -36.829_13, 2.407_57, true).unwrap();
        let buf = packet_with(&s[..n]);
        let back = PositionPacket::new_checked(&buf[..])
            .unwrap()
            .nmea_time()
            .unwrap();
        assert_eq!(back.utc(), Some(t));
        assert!(write_gprmc(&mut [0u8; 20], &t, 0.0, 0.0, true).is_none());
        // A void fix: status V, mode N, read back as not valid.
        let n = write_gprmc(&mut s, &t, -36.829_13, 2.407_57, false).unwrap();
        let line = core::str::from_utf8(&s[..n]).unwrap();
        assert!(line.contains(",V,") && line.contains(",E,N*"), "{line}");
    }

    #[test]
    fn short_and_empty() {
        assert_eq!(
            PositionPacket::new_checked(&[0u8; 511][..]).unwrap_err(),
            Error::Truncated {
                expected: 512,
                got: 511
            }
        );
        let p = PositionPacket::new_checked(&[0u8; 512][..]).unwrap();
        assert_eq!(p.nmea_bytes(), b"");
        assert_eq!(p.pps(), PpsStatus::Absent);
        assert_eq!(p.nmea_time(), Err(Error::BadNmea));
    }
}

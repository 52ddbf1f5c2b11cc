//! Applanix SBET files (POSPac "smoothed best estimate of trajectory"; PROTOCOLS.md): records of
//! 17 f64 little-endian: GPS seconds of week, latitude, longitude [rad], ellipsoidal height [m],
//! velocity x/y/z [m/s], roll, pitch, platform heading, wander angle [rad], acceleration
//! x/y/z, angular rate x/y/z. True heading = platform heading - wander angle.

use spherecal::time::GpsTime;
use std::io::{self, Read};

/// Bytes per record.
pub const RECORD: usize = 17 * 8;

/// One SBET record, in the units of the file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SbetRecord {
    /// GPS seconds of week.
    pub tow_s: f64,
    /// Latitude [rad].
    pub lat: f64,
    /// Longitude [rad].
    pub lon: f64,
    /// Ellipsoidal height [m].
    pub h: f64,
    /// Roll [rad].
    pub roll: f64,
    /// Pitch [rad].
    pub pitch: f64,
    /// Platform heading [rad].
    pub platform_heading: f64,
    /// Wander angle [rad].
    pub wander: f64,
}

impl SbetRecord {
    /// Parse one 136-byte record.
    pub fn parse(b: &[u8; RECORD]) -> Self {
        let f = |i: usize| {
            f64::from_le_bytes([
                b[8 * i],
                b[8 * i + 1],
                b[8 * i + 2],
                b[8 * i + 3],
                b[8 * i + 4],
                b[8 * i + 5],
                b[8 * i + 6],
                b[8 * i + 7],
            ])
        };
        Self {
            tow_s: f(0),
            lat: f(1),
            lon: f(2),
            h: f(3),
            roll: f(7),
            pitch: f(8),
            platform_heading: f(9),
            wander: f(10),
        }
    }

    /// Write as a 136-byte record (velocities, accelerations and rates zero).
    pub fn emit(&self) -> [u8; RECORD] {
        let mut out = [0u8; RECORD];
        for (i, v) in [
            (0, self.tow_s),
            (1, self.lat),
            (2, self.lon),
            (3, self.h),
            (7, self.roll),
            (8, self.pitch),
            (9, self.platform_heading),
            (10, self.wander),
        ] {
            out[8 * i..8 * i + 8].copy_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// True heading [rad].
    pub fn heading(&self) -> f64 {
        self.platform_heading - self.wander
    }

    /// GPS time, given the GPS week (SBET times are seconds of week only).
    pub fn time(&self, week: u16) -> Option<GpsTime> {
        GpsTime::from_week_tow_s(week, self.tow_s)
    }

    /// Finite, in range.
    pub fn is_valid(&self) -> bool {
        [
            self.tow_s,
            self.lat,
            self.lon,
            self.h,
            self.roll,
            self.pitch,
            self.platform_heading,
            self.wander,
        ]
        .iter()
        .all(|x| x.is_finite())
            && self.lat.abs() <= core::f64::consts::FRAC_PI_2
            && (0.0..=604_800.0).contains(&self.tow_s)
    }
}

/// Reads SBET records from any reader; a trailing partial record is reported.
pub struct SbetReader<R: Read> {
    inner: R,
    /// Records read.
    pub records: u64,
    /// Records skipped as invalid (NaN, out of range).
    pub invalid: u64,
    /// Bytes of a partial record at the end, if any.
    pub trailing: usize,
}

impl<R: Read> SbetReader<R> {
    /// Wrap a reader.
    pub fn new(inner: R) -> Self {
        Self {
            inner,
            records: 0,
            invalid: 0,
            trailing: 0,
        }
    }

    /// The next valid record, or `None` at the end.
    pub fn next_record(&mut self) -> io::Result<Option<SbetRecord>> {
        loop {
            let mut b = [0u8; RECORD];
            let mut n = 0;
            while n < RECORD {
                match self.inner.read(&mut b[n..]) {
                    Ok(0) => break,
                    Ok(k) => n += k,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(e),
                }
            }
            if n < RECORD {
                self.trailing = n;
                return Ok(None);
            }
            let r = SbetRecord::parse(&b);
            self.records += 1;
            if r.is_valid() {
                return Ok(Some(r));
            }
            self.invalid += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn record_layout() {
        let r = SbetRecord {
            tow_s: 200_632.5,
            lat: 0.8,
            lon: -0.07,
            h: 52.0,
            roll: 0.01,
            pitch: -0.02,
            platform_heading: 1.0,
            wander: 0.25,
        };
        let b = r.emit();
        // Field 9 (platform heading) at bytes 72..80, wander at 80..88.
        assert_eq!(f64::from_le_bytes(b[72..80].try_into().unwrap()), 1.0);
        assert_eq!(f64::from_le_bytes(b[80..88].try_into().unwrap()), 0.25);
        assert_eq!(SbetRecord::parse(&b), r);
        assert_eq!(r.heading(), 0.75);
        let mut bytes = b.to_vec();
        bytes.extend_from_slice(&[1, 2, 3]);
        let mut rd = SbetReader::new(&bytes[..]);
        assert_eq!(rd.next_record().unwrap(), Some(r));
        assert_eq!(rd.next_record().unwrap(), None);
        assert_eq!(rd.trailing, 3);
    }
}

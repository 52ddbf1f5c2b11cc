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

/// Why reading an SBET stopped.
#[derive(Debug)]
pub enum SbetError {
    /// The reader failed.
    Io(io::Error),
    /// A record's time of week does not follow the one before: SBET times increase (a week
    /// rollover aside), so the file is not an SBET.
    TimeOrder {
        /// Record number (1-based).
        record: u64,
        /// Byte offset of the record.
        byte: u64,
        /// Its time of week [s].
        tow_s: f64,
        /// The previous valid record's [s].
        previous_s: f64,
    },
    /// More than one record in ten is out of range or not finite: not an SBET.
    Implausible {
        /// Records out of range or not finite.
        invalid: u64,
        /// Records read.
        records: u64,
    },
}

/// Seconds with millisecond digits, or in exponent form when garbage makes them huge or tiny.
fn seconds(t: f64) -> String {
    if (1e-3..1e7).contains(&t.abs()) || t == 0.0 {
        format!("{t:.3}")
    } else {
        format!("{t:.3e}")
    }
}

impl core::fmt::Display for SbetError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "{e}"),
            Self::TimeOrder {
                record,
                byte,
                tow_s,
                previous_s,
            } => write!(
                f,
                "not an SBET file: record {record} (byte {byte}): GPS time of week {} s after {} s (SBET times increase)",
                seconds(*tow_s),
                seconds(*previous_s)
            ),
            Self::Implausible { invalid, records } => write!(
                f,
                "not an SBET file: {invalid} of {records} records out of range or not finite"
            ),
        }
    }
}

impl std::error::Error for SbetError {}

impl From<io::Error> for SbetError {
    fn from(e: io::Error) -> Self {
        Self::Io(e)
    }
}

/// Reads SBET records from any reader and checks the file is one: valid records' times of week
/// increase (a rollover from the week's end to its start aside), and at most one record in ten
/// is out of range or not finite. A trailing partial record is reported, not an error.
pub struct SbetReader<R: Read> {
    inner: R,
    last_tow: Option<f64>,
    /// Records read.
    pub records: u64,
    /// Records skipped as invalid (NaN, out of range).
    pub invalid: u64,
    /// Bytes of a partial record at the end, if any.
    pub trailing: usize,
}

/// Invalid records tolerated before the one-in-ten rule is applied while reading (at the end it
/// applies to any count).
const EARLY_INVALID: u64 = 64;

impl<R: Read> SbetReader<R> {
    /// Wrap a reader.
    pub fn new(inner: R) -> Self {
        Self {
            inner,
            last_tow: None,
            records: 0,
            invalid: 0,
            trailing: 0,
        }
    }

    fn implausible(&self) -> bool {
        self.invalid * 10 > self.records
    }

    /// The next valid record, `None` at the end, or why the file is not an SBET.
    pub fn next_record(&mut self) -> Result<Option<SbetRecord>, SbetError> {
        loop {
            let mut b = [0u8; RECORD];
            let mut n = 0;
            while n < RECORD {
                match self.inner.read(&mut b[n..]) {
                    Ok(0) => break,
                    Ok(k) => n += k,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(e.into()),
                }
            }
            if n < RECORD {
                self.trailing = n;
                if self.records > 0 && self.implausible() {
                    return Err(self.implausible_error());
                }
                return Ok(None);
            }
            let r = SbetRecord::parse(&b);
            self.records += 1;
            if !r.is_valid() {
                self.invalid += 1;
                if self.invalid >= EARLY_INVALID && self.implausible() {
                    return Err(self.implausible_error());
                }
                continue;
            }
            if let Some(l) = self.last_tow {
                let rollover = l > 600_000.0 && r.tow_s < 4_800.0;
                if r.tow_s <= l && !rollover {
                    return Err(SbetError::TimeOrder {
                        record: self.records,
                        byte: (self.records - 1) * RECORD as u64,
                        tow_s: r.tow_s,
                        previous_s: l,
                    });
                }
            }
            self.last_tow = Some(r.tow_s);
            return Ok(Some(r));
        }
    }

    fn implausible_error(&self) -> SbetError {
        SbetError::Implausible {
            invalid: self.invalid,
            records: self.records,
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

    fn rec(tow_s: f64) -> [u8; RECORD] {
        SbetRecord {
            tow_s,
            lat: 0.8,
            lon: -0.07,
            h: 52.0,
            roll: 0.0,
            pitch: 0.0,
            platform_heading: 1.0,
            wander: 0.0,
        }
        .emit()
    }

    #[test]
    fn times_must_increase() {
        let mut bytes = Vec::new();
        for t in [604_799.0, 604_799.5, 0.0, 0.5, 0.25] {
            bytes.extend_from_slice(&rec(t));
        }
        let mut rd = SbetReader::new(&bytes[..]);
        // The week rollover is accepted, a step back is not: record 5 at byte 4 * 136.
        for _ in 0..4 {
            assert!(rd.next_record().unwrap().is_some());
        }
        match rd.next_record() {
            Err(
                e @ SbetError::TimeOrder {
                    record: 5,
                    byte: 544,
                    ..
                },
            ) => {
                assert!(e.to_string().contains("0.250 s after 0.500 s"), "{e}")
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn mostly_invalid_is_not_an_sbet() {
        // 1 bad record in 10 is tolerated, 2 in 10 are not (at the end of a short file).
        for (bad, ok) in [(1, true), (2, false)] {
            let mut bytes = Vec::new();
            for i in 0..10 {
                bytes.extend_from_slice(&rec(if i < bad { f64::NAN } else { f64::from(i) }));
            }
            let mut rd = SbetReader::new(&bytes[..]);
            let mut n = 0;
            let end = loop {
                match rd.next_record() {
                    Ok(Some(_)) => n += 1,
                    Ok(None) => break Ok(()),
                    Err(e) => break Err(e),
                }
            };
            assert_eq!(end.is_ok(), ok, "{end:?}");
            assert_eq!(n, 10 - bad);
        }
        // Random-looking data stops early, before the whole file is read.
        let bytes: Vec<u8> = (0..RECORD * 1000).map(|i| (i * 7919 % 251) as u8).collect();
        let mut rd = SbetReader::new(&bytes[..]);
        let e = loop {
            match rd.next_record() {
                Ok(Some(_)) => {}
                Ok(None) => panic!("accepted"),
                Err(e) => break e,
            }
        };
        assert!(
            matches!(
                e,
                SbetError::Implausible { .. } | SbetError::TimeOrder { .. }
            ),
            "{e}"
        );
        assert!(rd.records < 1000);
    }
}

//! Applanix POSPac files (PROTOCOLS.md), headerless records of little-endian f64:
//! - SBET ("smoothed best estimate of trajectory"), 17 per record: GPS seconds of week,
//!   latitude, longitude [rad], ellipsoidal height [m], velocity x/y/z [m/s], roll, pitch,
//!   platform heading, wander angle [rad], acceleration x/y/z, angular rate x/y/z. True heading
//!   = platform heading - wander angle.
//! - smrmsg (the SBET's accuracy, "smoothed RMS"), 10 per record: GPS seconds of week, north,
//!   east, down position RMS [m], north, east, down velocity RMS [m/s], roll, pitch, heading RMS
//!   [arc minutes] (POSPac MMS; the same layout as PDAL's `readers.smrmsg`).
//!
//! One reader, [`PospacReader`], serves both: it checks that a file is what it claims (times
//! increase, few records out of range).

use spherecal::time::GpsTime;
use std::io::{self, Read};

/// Bytes per SBET record.
pub const RECORD: usize = 17 * 8;

/// Bytes per smrmsg record.
pub const SMRMSG_RECORD: usize = 10 * 8;

/// A POSPac record type.
pub trait PospacRecord: Sized {
    /// Bytes per record.
    const LEN: usize;
    /// The file kind, for messages ("SBET", "smrmsg").
    const KIND: &'static str;
    /// Parse one record of `LEN` bytes.
    fn parse(b: &[u8]) -> Self;
    /// GPS seconds of week.
    fn tow_s(&self) -> f64;
    /// Finite and in range.
    fn is_valid(&self) -> bool;
}

/// Field `i` (f64, little-endian) of a record.
fn field(b: &[u8], i: usize) -> f64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[8 * i..8 * i + 8]);
    f64::from_le_bytes(a)
}

/// A time of week within the week (a leap-second-long last second allowed).
fn tow_in_range(t: f64) -> bool {
    (0.0..=604_800.0).contains(&t)
}

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
        <Self as PospacRecord>::parse(b)
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
        <Self as PospacRecord>::is_valid(self)
    }
}

impl PospacRecord for SbetRecord {
    const LEN: usize = RECORD;
    const KIND: &'static str = "SBET";

    fn parse(b: &[u8]) -> Self {
        let f = |i| field(b, i);
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

    fn tow_s(&self) -> f64 {
        self.tow_s
    }

    fn is_valid(&self) -> bool {
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
            && tow_in_range(self.tow_s)
    }
}

/// One smrmsg record: the SBET's 1-sigma (RMS) at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmrmsgRecord {
    /// GPS seconds of week.
    pub tow_s: f64,
    /// North, east, down position RMS [m].
    pub position_m: [f64; 3],
    /// North, east, down velocity RMS [m/s].
    pub velocity_mps: [f64; 3],
    /// Roll, pitch, heading RMS [arc minutes].
    pub attitude_arcmin: [f64; 3],
}

impl SmrmsgRecord {
    /// Write as an 80-byte record.
    pub fn emit(&self) -> [u8; SMRMSG_RECORD] {
        let mut out = [0u8; SMRMSG_RECORD];
        let v = [self.tow_s]
            .into_iter()
            .chain(self.position_m)
            .chain(self.velocity_mps)
            .chain(self.attitude_arcmin);
        for (i, x) in v.enumerate() {
            out[8 * i..8 * i + 8].copy_from_slice(&x.to_le_bytes());
        }
        out
    }

    /// The position sigma along any one direction [m]: the RMS of the three axes (the residual
    /// of a sphere return lies along its surface normal, in no fixed axis).
    pub fn position_sigma_m(&self) -> f64 {
        let [n, e, d] = self.position_m;
        ((n * n + e * e + d * d) / 3.0).sqrt()
    }

    /// The attitude sigma about any one axis [rad]: the RMS of roll, pitch and heading.
    pub fn attitude_sigma_rad(&self) -> f64 {
        let [r, p, h] = self.attitude_arcmin;
        ((r * r + p * p + h * h) / 3.0).sqrt() / 60.0 * core::f64::consts::PI / 180.0
    }
}

impl PospacRecord for SmrmsgRecord {
    const LEN: usize = SMRMSG_RECORD;
    const KIND: &'static str = "smrmsg";

    fn parse(b: &[u8]) -> Self {
        let f = |i| field(b, i);
        Self {
            tow_s: f(0),
            position_m: [f(1), f(2), f(3)],
            velocity_mps: [f(4), f(5), f(6)],
            attitude_arcmin: [f(7), f(8), f(9)],
        }
    }

    fn tow_s(&self) -> f64 {
        self.tow_s
    }

    /// Finite, the time within the week, every RMS non-negative and below 10 km, 100 m/s and
    /// 60 degrees (beyond, the record is not an accuracy).
    fn is_valid(&self) -> bool {
        tow_in_range(self.tow_s)
            && self.position_m.iter().all(|x| (0.0..1e4).contains(x))
            && self.velocity_mps.iter().all(|x| (0.0..100.0).contains(x))
            && self
                .attitude_arcmin
                .iter()
                .all(|x| (0.0..3600.0).contains(x))
    }
}

/// Why reading a POSPac file stopped.
#[derive(Debug)]
pub enum PospacError {
    /// The reader failed.
    Io(io::Error),
    /// A record's time of week does not follow the one before: POSPac times increase (a week
    /// rollover aside), so the file is not of the kind it was read as.
    TimeOrder {
        /// The kind read ("SBET", "smrmsg").
        kind: &'static str,
        /// Record number (1-based).
        record: u64,
        /// Byte offset of the record.
        byte: u64,
        /// Its time of week [s].
        tow_s: f64,
        /// The previous valid record's [s].
        previous_s: f64,
    },
    /// More than one record in ten is out of range or not finite: not of the kind read.
    Implausible {
        /// The kind read.
        kind: &'static str,
        /// Records out of range or not finite.
        invalid: u64,
        /// Records read.
        records: u64,
    },
}

/// The SBET reader's error (the same for both kinds).
pub type SbetError = PospacError;

/// Seconds with millisecond digits, or in exponent form when garbage makes them huge or tiny.
fn seconds(t: f64) -> String {
    if (1e-3..1e7).contains(&t.abs()) || t == 0.0 {
        format!("{t:.3}")
    } else {
        format!("{t:.3e}")
    }
}

impl core::fmt::Display for PospacError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "{e}"),
            Self::TimeOrder {
                kind,
                record,
                byte,
                tow_s,
                previous_s,
            } => write!(
                f,
                "not an {kind} file: record {record} (byte {byte}): GPS time of week {} s after {} s ({kind} times increase)",
                seconds(*tow_s),
                seconds(*previous_s)
            ),
            Self::Implausible {
                kind,
                invalid,
                records,
            } => write!(
                f,
                "not an {kind} file: {invalid} of {records} records out of range or not finite"
            ),
        }
    }
}

impl std::error::Error for PospacError {}

impl From<io::Error> for PospacError {
    fn from(e: io::Error) -> Self {
        Self::Io(e)
    }
}

/// Reads POSPac records of one kind from any reader and checks the file is one: valid records'
/// times of week increase (a rollover from the week's end to its start aside), and at most one
/// record in ten is out of range or not finite. A trailing partial record is reported, not an
/// error.
pub struct PospacReader<R: Read, T: PospacRecord> {
    inner: R,
    last_tow: Option<f64>,
    /// Records read.
    pub records: u64,
    /// Records skipped as invalid (NaN, out of range).
    pub invalid: u64,
    /// Bytes of a partial record at the end, if any.
    pub trailing: usize,
    kind: core::marker::PhantomData<T>,
}

/// The SBET reader.
pub type SbetReader<R> = PospacReader<R, SbetRecord>;

/// The smrmsg reader.
pub type SmrmsgReader<R> = PospacReader<R, SmrmsgRecord>;

/// Invalid records tolerated before the one-in-ten rule is applied while reading (at the end it
/// applies to any count).
const EARLY_INVALID: u64 = 64;

/// The longest record.
const MAX_RECORD: usize = RECORD;

impl<R: Read, T: PospacRecord> PospacReader<R, T> {
    /// Wrap a reader.
    pub fn new(inner: R) -> Self {
        Self {
            inner,
            last_tow: None,
            records: 0,
            invalid: 0,
            trailing: 0,
            kind: core::marker::PhantomData,
        }
    }

    fn implausible(&self) -> bool {
        self.invalid * 10 > self.records
    }

    /// The next valid record, `None` at the end, or why the file is not of its kind.
    pub fn next_record(&mut self) -> Result<Option<T>, PospacError> {
        loop {
            let mut buf = [0u8; MAX_RECORD];
            let b = &mut buf[..T::LEN];
            let mut n = 0;
            while n < T::LEN {
                match self.inner.read(&mut b[n..]) {
                    Ok(0) => break,
                    Ok(k) => n += k,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(e.into()),
                }
            }
            if n < T::LEN {
                self.trailing = n;
                if self.records > 0 && self.implausible() {
                    return Err(self.implausible_error());
                }
                return Ok(None);
            }
            let r = T::parse(b);
            self.records += 1;
            if !r.is_valid() {
                self.invalid += 1;
                if self.invalid >= EARLY_INVALID && self.implausible() {
                    return Err(self.implausible_error());
                }
                continue;
            }
            let tow = r.tow_s();
            if let Some(l) = self.last_tow {
                let rollover = l > 600_000.0 && tow < 4_800.0;
                if tow <= l && !rollover {
                    return Err(PospacError::TimeOrder {
                        kind: T::KIND,
                        record: self.records,
                        byte: (self.records - 1) * T::LEN as u64,
                        tow_s: tow,
                        previous_s: l,
                    });
                }
            }
            self.last_tow = Some(tow);
            return Ok(Some(r));
        }
    }

    fn implausible_error(&self) -> PospacError {
        PospacError::Implausible {
            kind: T::KIND,
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

    /// An smrmsg record by hand: field 7 (roll RMS) at bytes 56..64; 60 arc minutes on each axis
    /// is 1 degree; 3, 4, 12 cm on the axes are 7.5 cm RMS per axis.
    #[test]
    fn smrmsg_layout_and_sigmas() {
        let r = SmrmsgRecord {
            tow_s: 200_000.0,
            position_m: [0.03, 0.04, 0.12],
            velocity_mps: [0.01, 0.01, 0.02],
            attitude_arcmin: [60.0, 60.0, 60.0],
        };
        let b = r.emit();
        assert_eq!(b.len(), 80);
        assert_eq!(f64::from_le_bytes(b[56..64].try_into().unwrap()), 60.0);
        assert_eq!(f64::from_le_bytes(b[24..32].try_into().unwrap()), 0.12);
        let mut two = b.to_vec();
        two.extend_from_slice(
            &SmrmsgRecord {
                tow_s: 200_001.0,
                ..r
            }
            .emit(),
        );
        let mut rd = SmrmsgReader::new(&two[..]);
        let got = rd.next_record().unwrap().unwrap();
        assert_eq!(got, r);
        assert!((got.attitude_sigma_rad() - 1f64.to_radians()).abs() < 1e-15);
        assert!((got.position_sigma_m() - (0.0169f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(rd.next_record().unwrap().unwrap().tow_s, 200_001.0);
        assert!(rd.next_record().unwrap().is_none());
        // An SBET read as an smrmsg: its latitude and longitude as RMS, its times out of
        // order at 80-byte strides; refused by name.
        let mut sbet = Vec::new();
        for t in 0..40 {
            sbet.extend_from_slice(&rec(1000.0 + f64::from(t)));
        }
        let mut rd = SmrmsgReader::new(&sbet[..]);
        let e = loop {
            match rd.next_record() {
                Ok(Some(_)) => {}
                Ok(None) => panic!("an SBET accepted as smrmsg"),
                Err(e) => break e,
            }
        };
        assert!(e.to_string().starts_with("not an smrmsg file"), "{e}");
    }
}

//! Time scales: civil UTC dates, the top of the UTC hour, GPS time.
//!
//! DESIGN.md conventions: `GpsTime` is nanoseconds since the GPS epoch 1980-01-06T00:00:00;
//! VLP-16 stamps are microseconds past the top of the UTC hour; UTC = GPS - leap seconds.

/// Seconds from the Unix epoch (1970-01-01) to the GPS epoch (1980-01-06), both UTC.
pub const GPS_EPOCH_UNIX_S: i64 = 315_964_800;

/// A UTC calendar date and time of day, as a GNSS receiver reports it (e.g. in `$GPRMC`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UtcDateTime {
    /// Full year, e.g. 2016.
    pub year: i32,
    /// Month 1..=12.
    pub month: u8,
    /// Day of month 1..=31.
    pub day: u8,
    /// Hour 0..=23.
    pub hour: u8,
    /// Minute 0..=59.
    pub minute: u8,
    /// Second 0..=60 (60 only during a leap second).
    pub second: u8,
    /// Nanoseconds within the second.
    pub nanos: u32,
}

impl UtcDateTime {
    /// Seconds since the Unix epoch (UTC, leap seconds not counted, as POSIX time).
    pub fn unix_seconds(&self) -> i64 {
        days_from_civil(self.year, self.month, self.day) * 86_400
            + i64::from(self.hour) * 3600
            + i64::from(self.minute) * 60
            + i64::from(self.second)
    }

    /// The top of the UTC hour that contains this instant, in Unix seconds.
    pub fn top_of_hour_unix_s(&self) -> i64 {
        days_from_civil(self.year, self.month, self.day) * 86_400 + i64::from(self.hour) * 3600
    }

    /// Microseconds past the top of the hour (the VLP-16's timestamp scale).
    pub fn micros_past_hour(&self) -> u64 {
        (u64::from(self.minute) * 60 + u64::from(self.second)) * 1_000_000
            + u64::from(self.nanos / 1000)
    }
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's `days_from_civil`).
///
/// ```
/// use spherecal::time::{civil_from_days, days_from_civil};
/// // The GPS epoch, 1980-01-06, is Unix time 315 964 800 s (IS-GPS-200, 20.3.3.5.2.4).
/// assert_eq!(days_from_civil(1980, 1, 6) * 86_400, 315_964_800);
/// assert_eq!(civil_from_days(3657), (1980, 1, 6));
/// // 2000 was a leap year, 1900 was not.
/// assert_eq!(days_from_civil(2000, 3, 1) - days_from_civil(2000, 2, 28), 2);
/// assert_eq!(days_from_civil(1900, 3, 1) - days_from_civil(1900, 2, 28), 1);
/// ```
pub fn days_from_civil(year: i32, month: u8, day: u8) -> i64 {
    let y = i64::from(year) - i64::from(month <= 2);
    let era = y.div_euclid(400);
    let yoe = y - era * 400; // [0, 399]
    let m = i64::from(month);
    let mp = (m + 9) % 12; // March = 0
    let doy = (153 * mp + 2) / 5 + i64::from(day) - 1; // [0, 365]
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy; // [0, 146096]
    era * 146_097 + doe - 719_468
}

/// Proleptic Gregorian date of a day count since 1970-01-01 (inverse of [`days_from_civil`]).
pub fn civil_from_days(z: i64) -> (i32, u8, u8) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u8;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u8;
    let year = (yoe + era * 400 + i64::from(month <= 2)) as i32;
    (year, month, day)
}

impl UtcDateTime {
    /// From nanoseconds since the Unix epoch (UTC, POSIX: no leap seconds counted).
    pub fn from_unix_ns(ns: i64) -> Self {
        let secs = ns.div_euclid(1_000_000_000);
        let nanos = ns.rem_euclid(1_000_000_000) as u32;
        let (year, month, day) = civil_from_days(secs.div_euclid(86_400));
        let sod = secs.rem_euclid(86_400);
        Self {
            year,
            month,
            day,
            hour: (sod / 3600) as u8,
            minute: (sod / 60 % 60) as u8,
            second: (sod % 60) as u8,
            nanos,
        }
    }
}

/// GPS time -> nanoseconds since the Unix epoch in UTC (UTC = GPS - leap seconds). Saturates
/// instead of overflowing (a [`GpsTime::is_valid`] time never comes near).
///
/// ```
/// use spherecal::time::{gps_to_unix_ns, micros_past_hour, unix_ns_to_gps, GpsTime, UtcDateTime};
/// // GPS week 2000, second 0 (2018-05-06) is 2018-05-05 23:59:42 UTC with 18 leap seconds.
/// let t = GpsTime(2000 * 604_800 * 1_000_000_000);
/// let u = UtcDateTime::from_unix_ns(gps_to_unix_ns(t, 18));
/// assert_eq!((u.year, u.month, u.day, u.hour, u.minute, u.second), (2018, 5, 5, 23, 59, 42));
/// assert_eq!(unix_ns_to_gps(gps_to_unix_ns(t, 18), 18), t);
/// // The VLP-16's timestamp: microseconds past that UTC hour, 59 min 42 s.
/// assert_eq!(micros_past_hour(t, 18), (59 * 60 + 42) * 1_000_000);
/// ```
pub fn gps_to_unix_ns(t: GpsTime, leap_seconds: i64) -> i64 {
    t.0.saturating_sub(leap_seconds.saturating_mul(1_000_000_000))
        .saturating_add(GPS_EPOCH_UNIX_S * 1_000_000_000)
}

/// Unix UTC nanoseconds -> GPS time (saturating).
pub fn unix_ns_to_gps(unix_ns: i64, leap_seconds: i64) -> GpsTime {
    GpsTime(
        unix_ns
            .saturating_add(leap_seconds.saturating_mul(1_000_000_000))
            .saturating_sub(GPS_EPOCH_UNIX_S * 1_000_000_000),
    )
}

/// The VLP-16's clock: microseconds past the top of the UTC hour of a GPS time.
pub fn micros_past_hour(t: GpsTime, leap_seconds: i64) -> u32 {
    (gps_to_unix_ns(t, leap_seconds)
        .div_euclid(1000)
        .rem_euclid(3_600_000_000)) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A u16 week from the wire times a week's nanoseconds overflows an i64 from week 15,251:
    /// such times are invalid, never a panic or a wrapped value; so are times of week beyond a
    /// week and TimeGps values past week 6000.
    #[test]
    fn wire_times_are_checked() {
        assert_eq!(GpsTime::from_week_tow_ns(65_535, 0), None);
        assert_eq!(GpsTime::from_week_tow_ns(15_251, 0), None);
        assert_eq!(GpsTime::from_week_tow_s(65_535, 1.0), None);
        assert_eq!(GpsTime::from_week_tow_ns(2300, u64::MAX), None);
        assert_eq!(GpsTime::from_week_tow_ns(2300, 604_800_000_000_001), None);
        assert_eq!(
            GpsTime::from_week_tow_ns(2300, 5),
            Some(GpsTime(2300 * WEEK_NS + 5))
        );
        assert_eq!(GpsTime::checked(i64::MAX), None);
        assert_eq!(GpsTime::checked(-1), None);
        // Conversions saturate instead of overflowing.
        assert_eq!(
            gps_to_unix_ns(GpsTime(i64::MIN), 18),
            i64::MIN + GPS_EPOCH_UNIX_S * 1_000_000_000
        );
        assert_eq!(
            unix_ns_to_gps(i64::MAX, 18),
            GpsTime(i64::MAX - GPS_EPOCH_UNIX_S * 1_000_000_000)
        );
    }

    #[test]
    fn civil_days_known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        // GPS epoch 1980-01-06 = 315964800 s after the Unix epoch (IS-GPS-200, POSIX).
        assert_eq!(days_from_civil(1980, 1, 6) * 86_400, GPS_EPOCH_UNIX_S);
        // 2000-03-01 is day 11017 (leap-year February handled).
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
        assert_eq!(days_from_civil(1969, 12, 31), -1);
    }

    #[test]
    fn civil_round_trip_and_gps_utc() {
        for d in [-800_000i64, -1, 0, 1, 10_957, 16_821, 20_000, 2_932_896] {
            let (y, m, dd) = civil_from_days(d);
            assert_eq!(days_from_civil(y, m, dd), d);
        }
        assert_eq!(civil_from_days(16_821), (2016, 1, 21));
        // GPS week 2165, tow 200632.599585647 s (vn310_gnss.bin), leap 18 s:
        // 2021-07-06 07:43:34.599 UTC, as its own TimeUtc field says.
        let t = GpsTime::from_week_tow_ns(2165, 200_632_599_585_647).unwrap();
        let u = UtcDateTime::from_unix_ns(gps_to_unix_ns(t, 18));
        assert_eq!(
            (u.year, u.month, u.day, u.hour, u.minute, u.second),
            (2021, 7, 6, 7, 43, 34)
        );
        assert_eq!(u.nanos / 1_000_000, 599);
        assert_eq!(unix_ns_to_gps(gps_to_unix_ns(t, 18), 18), t);
        assert_eq!(
            micros_past_hour(t, 18),
            (43 * 60 + 34) * 1_000_000 + 599_585
        );
    }

    #[test]
    fn top_of_hour_of_the_mrpt_rmc() {
        // $GPRMC,081802.00,...,210116: 2016-01-21 08:18:02 UTC.
        let t = UtcDateTime {
            year: 2016,
            month: 1,
            day: 21,
            hour: 8,
            minute: 18,
            second: 2,
            nanos: 0,
        };
        // 2016-01-21 is day 16821 since 1970; 16821*86400 + 8*3600.
        assert_eq!(t.top_of_hour_unix_s(), 16_821 * 86_400 + 8 * 3600);
        assert_eq!(t.micros_past_hour(), 1_082_000_000);
    }
}

/// GPS time: nanoseconds since the GPS epoch 1980-01-06T00:00:00, no leap seconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct GpsTime(pub i64);

/// Nanoseconds in a GPS week.
pub const WEEK_NS: i64 = 604_800 * 1_000_000_000;

impl GpsTime {
    /// The last GPS time accepted from the wire: week 6000 (year 2095). A u16 week times
    /// [`WEEK_NS`] overflows an i64 from week 15,251, and a u64 `TimeGps` can be anything.
    pub const LAST_VALID: GpsTime = GpsTime(6000 * WEEK_NS);

    /// Between the GPS epoch and [`Self::LAST_VALID`].
    pub fn is_valid(self) -> bool {
        (0..=Self::LAST_VALID.0).contains(&self.0)
    }

    /// A time from the wire, if valid.
    pub fn checked(ns: i64) -> Option<Self> {
        Some(Self(ns)).filter(|t| t.is_valid())
    }

    /// From GPS week and time of week in nanoseconds (PROTOCOLS.md: week * 604800e9 + tow);
    /// `None` unless the time is valid (the time of week may not exceed a week).
    pub fn from_week_tow_ns(week: u16, tow_ns: u64) -> Option<Self> {
        let tow = i64::try_from(tow_ns).ok().filter(|&t| t <= WEEK_NS)?;
        Self::checked(i64::from(week).checked_mul(WEEK_NS)?.checked_add(tow)?)
    }

    /// From GPS week and time of week in seconds (as $VNINS and SBET files give it).
    pub fn from_week_tow_s(week: u16, tow_s: f64) -> Option<Self> {
        if !tow_s.is_finite() || !(0.0..=604_800.0).contains(&tow_s) {
            return None;
        }
        let tow = libm::round(tow_s * 1e9) as i64;
        Self::checked(i64::from(week).checked_mul(WEEK_NS)?.checked_add(tow)?)
    }

    /// Seconds since the GPS epoch.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }

    /// Time of week in nanoseconds and the week number.
    pub fn week_tow_ns(self) -> (i64, i64) {
        (self.0.div_euclid(WEEK_NS), self.0.rem_euclid(WEEK_NS))
    }
}

/// Host time: nanoseconds since the Unix epoch on the receiving computer's wall clock (a pcap
/// record's time, a socket's kernel receive time, a serial log record's stamp). A clock of its
/// own, with its own offset and drift: it says when data arrived, never when it was measured,
/// and is compared with sensor time only through a measured offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct HostTime(pub i64);

impl HostTime {
    /// From whole seconds and nanoseconds since the Unix epoch (saturating).
    pub fn from_secs_nanos(secs: i64, nanos: u32) -> Self {
        Self(
            secs.saturating_mul(1_000_000_000)
                .saturating_add(i64::from(nanos)),
        )
    }

    /// Seconds since the Unix epoch (for printing).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }

    /// Nanoseconds from `earlier` to `self` (saturating).
    pub fn since(self, earlier: HostTime) -> i64 {
        self.0.saturating_sub(earlier.0)
    }
}

/// Half an hour in microseconds: how far a stamp may move before it counts as a new hour.
const HALF_HOUR_US: i64 = 1_800_000_000;
/// An hour in nanoseconds.
const HOUR_NS: i64 = 3_600_000_000_000;

/// The VLP-16 clock: microseconds past the top of the UTC hour -> GPS time, with the hour taken
/// from the position packets' RMC or from the nearest INS time, and the hour rollover unwrapped
/// (a stamp that falls back by more than half an hour starts the next hour).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LidarClock {
    leap_seconds: i64,
    /// Unix ns of the top of the current hour.
    hour_unix_ns: Option<i64>,
    last_us: i64,
    /// Hours rolled over so far.
    pub rollovers: u32,
}

impl LidarClock {
    /// A clock that does not know the hour yet.
    pub const fn new(leap_seconds: i64) -> Self {
        Self {
            leap_seconds,
            hour_unix_ns: None,
            last_us: 0,
            rollovers: 0,
        }
    }

    /// Is the hour known?
    pub fn has_hour(&self) -> bool {
        self.hour_unix_ns.is_some()
    }

    /// Take the hour from an RMC date-time received with a position packet stamped `stamp_us`
    /// (the RMC second is the last whole second at or before the stamp).
    pub fn set_from_rmc(&mut self, utc: &UtcDateTime, stamp_us: u32) {
        let mut hour = utc.top_of_hour_unix_s().saturating_mul(1_000_000_000);
        // The RMC may name 10:59:59 while the stamp already wrapped to 00:00.5 of the next hour.
        let rmc_us = i64::try_from(utc.micros_past_hour()).unwrap_or(0);
        let d = i64::from(stamp_us) - rmc_us;
        if d < -HALF_HOUR_US {
            hour += HOUR_NS;
        } else if d > HALF_HOUR_US {
            hour -= HOUR_NS;
        }
        self.hour_unix_ns = Some(hour);
        self.last_us = i64::from(stamp_us);
    }

    /// Take the hour from a nearby GPS time (the INS), choosing the hour that puts the stamp
    /// nearest to it.
    pub fn set_from_gps(&mut self, near: GpsTime, stamp_us: u32) {
        let u = gps_to_unix_ns(near, self.leap_seconds);
        let h = u.div_euclid(HOUR_NS) * HOUR_NS;
        let s = i64::from(stamp_us) * 1000;
        let best = [h - HOUR_NS, h, h + HOUR_NS]
            .into_iter()
            .min_by_key(|c| (c + s - u).abs())
            .unwrap_or(h);
        self.hour_unix_ns = Some(best);
        self.last_us = i64::from(stamp_us);
    }

    /// GPS time of a stamp (None until the hour is known). Stamps must come roughly in order:
    /// a fall of more than half an hour is the next hour, a rise of more than half an hour the
    /// previous one (a late packet from before the rollover).
    pub fn to_gps(&mut self, stamp_us: u32) -> Option<GpsTime> {
        let mut hour = self.hour_unix_ns?;
        let s = i64::from(stamp_us);
        let d = s - self.last_us;
        if d < -HALF_HOUR_US {
            hour += HOUR_NS;
            self.hour_unix_ns = Some(hour);
            self.rollovers += 1;
            self.last_us = s;
        } else if d > HALF_HOUR_US {
            // Before the rollover: do not move the clock back.
            return Some(unix_ns_to_gps(hour - HOUR_NS + s * 1000, self.leap_seconds));
        } else {
            self.last_us = s;
        }
        Some(unix_ns_to_gps(hour + s * 1000, self.leap_seconds))
    }
}

#[cfg(test)]
mod clock_tests {
    use super::*;

    /// 2024-06-12 10:59:59 UTC: the last whole second before a top of the hour.
    const LAST_SECOND: UtcDateTime = UtcDateTime {
        year: 2024,
        month: 6,
        day: 12,
        hour: 10,
        minute: 59,
        second: 59,
        nanos: 0,
    };

    #[test]
    fn hour_rollover_is_unwrapped() {
        // 2024-06-12 10:59:59.9 UTC -> 11:00:00.1: stamps 3_599_900_000 then 100_000.
        let mut c = LidarClock::new(18);
        let rmc = LAST_SECOND;
        c.set_from_rmc(&rmc, 3_599_900_000);
        let a = c.to_gps(3_599_900_000).unwrap();
        let b = c.to_gps(100_000).unwrap();
        assert_eq!(b.0 - a.0, 200_000_000, "0.2 s apart across the hour");
        assert_eq!(c.rollovers, 1);
        // A late packet from before the rollover keeps its own hour.
        let late = c.to_gps(3_599_950_000).unwrap();
        assert_eq!(late.0 - a.0, 50_000_000);
        // And the clock goes on in the new hour.
        assert_eq!(c.to_gps(200_000).unwrap().0 - b.0, 100_000_000);
        // UTC of the result: 11:00:00.1, GPS = UTC + 18 s.
        let u = UtcDateTime::from_unix_ns(gps_to_unix_ns(b, 18));
        assert_eq!(
            (u.hour, u.minute, u.second, u.nanos),
            (11, 0, 0, 100_000_000)
        );
    }

    #[test]
    fn hour_from_ins_time() {
        // INS says 11:00:00.3 (GPS = UTC + 18 s); a stamp of 59:59.95 belongs to 10:00's hour.
        let ins = unix_ns_to_gps(
            (days_from_civil(2024, 6, 12) * 86_400 + 11 * 3600) * 1_000_000_000 + 300_000_000,
            18,
        );
        let mut c = LidarClock::new(18);
        c.set_from_gps(ins, 3_599_950_000);
        let t = c.to_gps(3_599_950_000).unwrap();
        assert_eq!(ins.0 - t.0, 350_000_000);
        // The RMC names 10:59:59 but the stamp (0.4 s past the hour) already wrapped: hour 11.
        let mut c = LidarClock::new(18);
        let rmc = LAST_SECOND;
        c.set_from_rmc(&rmc, 400_000); // RMC second before the wrap, stamp after it
        let u = UtcDateTime::from_unix_ns(gps_to_unix_ns(c.to_gps(400_000).unwrap(), 18));
        assert_eq!((u.hour, u.minute, u.second), (11, 0, 0));
    }
}

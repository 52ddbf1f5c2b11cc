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

#[cfg(test)]
mod tests {
    use super::*;

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
    /// From GPS week and time of week in nanoseconds (PROTOCOLS.md: week * 604800e9 + tow).
    pub fn from_week_tow_ns(week: u16, tow_ns: u64) -> Option<Self> {
        let tow = i64::try_from(tow_ns).ok()?;
        Some(Self(i64::from(week) * WEEK_NS + tow))
    }

    /// From GPS week and time of week in seconds (as $VNINS and SBET files give it).
    pub fn from_week_tow_s(week: u16, tow_s: f64) -> Option<Self> {
        if !tow_s.is_finite() || !(0.0..=1.0e6).contains(&tow_s) {
            return None;
        }
        Some(Self(
            i64::from(week) * WEEK_NS + libm::round(tow_s * 1e9) as i64,
        ))
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

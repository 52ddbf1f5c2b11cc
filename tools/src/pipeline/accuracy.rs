//! The trajectory's accuracy: a POSPac smrmsg file (the SBET's position and attitude RMS over
//! time, `hal::sbet`) gives each windowed return the INS 1-sigmas at its time
//! ([`Observation::ins_sigma`]), which the solver's noise model uses in place of the site's
//! constant ones: the least squares weigh each return by its variance and the dispersion test
//! predicts the RMS from them.
//!
//! The sigmas are interpolated linearly between records at most [`MAX_GAP_S`] apart (POSPac
//! writes them at 1 Hz or faster; accuracy changes over seconds, with the satellites), else taken
//! from a record within that time; a return further from every record keeps the site's values
//! and is counted.

use serde::{Deserialize, Serialize};
use spherecal::align::window::Observation;
use spherecal::time::GpsTime;
use spherecal_hal::sbet::SmrmsgReader;
use std::path::{Path, PathBuf};

/// The longest stretch between two records to interpolate over, and how far beyond the first
/// and last record a return may be [s].
pub const MAX_GAP_S: f64 = 10.0;

/// An smrmsg file in memory: per record its time and the one-axis position [m] and attitude
/// [rad] sigmas (`SmrmsgRecord::position_sigma_m`, `attitude_sigma_rad`).
#[derive(Debug, Clone, Default)]
pub struct Accuracy {
    /// The file.
    pub path: PathBuf,
    time: Vec<i64>,
    sigma: Vec<[f32; 2]>,
    /// Records read.
    pub records: u64,
    /// Records skipped as invalid.
    pub invalid: u64,
    /// The file's sigmas per axis over all its records: the navigation model's source when
    /// the site declares none (`nav_source`).
    pub stated: crate::config::nav_source::Stated,
}

/// What the accuracy file gave a calibration, in the report.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct AccuracyReport {
    /// The file.
    pub file: String,
    /// Its records, and those skipped as invalid.
    pub records: u64,
    /// ...
    pub invalid: u64,
    /// Windowed returns given their INS sigmas.
    pub returns_given: u64,
    /// Windowed returns outside the file's time span or in its gaps (the site's sigmas).
    pub returns_outside: u64,
    /// The smallest and largest position sigma given [m] ...
    pub position_sigma_m: [f64; 2],
    /// ... and attitude sigma [deg].
    pub attitude_sigma_deg: [f64; 2],
}

impl Accuracy {
    /// Read an smrmsg file whose times are seconds of GPS week `week` (a rollover to the next
    /// week within the file is followed).
    pub fn load(path: &Path, week: u16) -> Result<Self, crate::Error> {
        let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
        let f = std::fs::File::open(path).map_err(|e| err(&e))?;
        let mut rd = SmrmsgReader::new(std::io::BufReader::new(f));
        let mut out = Self {
            path: path.to_path_buf(),
            ..Self::default()
        };
        let mut week = week;
        let mut last = f64::NEG_INFINITY;
        while let Some(r) = rd.next_record().map_err(|e| err(&e))? {
            if r.tow_s < last {
                week = week.saturating_add(1);
            }
            last = r.tow_s;
            let Some(t) = GpsTime::from_week_tow_s(week, r.tow_s) else {
                continue;
            };
            out.time.push(t.0);
            out.stated.add(
                "POSPac smrmsg",
                r.position_m,
                r.attitude_arcmin.map(|a| a / 60.0),
            );
            out.sigma
                .push([r.position_sigma_m() as f32, r.attitude_sigma_rad() as f32]);
        }
        out.records = rd.records;
        out.invalid = rd.invalid;
        if out.time.is_empty() {
            return Err(err(&format_args!(
                "no valid smrmsg record in {} records ({} bytes left over)",
                rd.records, rd.trailing
            ))
            .into());
        }
        Ok(out)
    }

    /// The sigmas (position [m], attitude [rad]) at `t`, if the file covers it.
    pub fn at(&self, t: GpsTime) -> Option<[f32; 2]> {
        let gap = (MAX_GAP_S * 1e9) as i64;
        let i = self.time.partition_point(|&x| x <= t.0);
        match (i.checked_sub(1), self.time.get(i)) {
            (Some(a), Some(&tb)) => {
                let ta = self.time[a];
                if tb - ta > gap {
                    // A long gap: the nearer record's, if within the limit.
                    return if t.0 - ta <= gap {
                        Some(self.sigma[a])
                    } else {
                        (tb - t.0 <= gap).then_some(self.sigma[i])
                    };
                }
                let f = (t.0 - ta) as f64 / (tb - ta).max(1) as f64;
                let (sa, sb) = (self.sigma[a], self.sigma[i]);
                Some(core::array::from_fn(|k| {
                    (f64::from(sa[k]) + f * (f64::from(sb[k]) - f64::from(sa[k]))) as f32
                }))
            }
            (Some(a), None) => (t.0 - self.time[a] <= gap).then_some(self.sigma[a]),
            (None, Some(&tb)) => (tb - t.0 <= gap).then_some(self.sigma[0]),
            (None, None) => None,
        }
    }

    /// The tally when no return takes the file's sigmas (a navigation model holds them).
    pub fn unapplied(&self) -> AccuracyReport {
        AccuracyReport {
            file: self.path.display().to_string(),
            records: self.records,
            invalid: self.invalid,
            ..AccuracyReport::default()
        }
    }

    /// Give every return its INS sigmas where the file covers its time (on the INS clock, as
    /// the observations' times are); the rest keep 0 (the site's values). Returns the tally.
    pub fn apply(&self, obs: &mut [Vec<Observation>]) -> AccuracyReport {
        let mut rep = AccuracyReport {
            file: self.path.display().to_string(),
            records: self.records,
            invalid: self.invalid,
            position_sigma_m: [f64::INFINITY, 0.0],
            attitude_sigma_deg: [f64::INFINITY, 0.0],
            ..AccuracyReport::default()
        };
        for o in obs.iter_mut().flatten() {
            match self.at(o.time) {
                Some(s) => {
                    o.ins_sigma = s;
                    rep.returns_given += 1;
                    let (p, a) = (f64::from(s[0]), f64::from(s[1]).to_degrees());
                    rep.position_sigma_m = [
                        rep.position_sigma_m[0].min(p),
                        rep.position_sigma_m[1].max(p),
                    ];
                    rep.attitude_sigma_deg = [
                        rep.attitude_sigma_deg[0].min(a),
                        rep.attitude_sigma_deg[1].max(a),
                    ];
                }
                None => {
                    o.ins_sigma = [0.0; 2];
                    rep.returns_outside += 1;
                }
            }
        }
        if rep.returns_given == 0 {
            rep.position_sigma_m = [0.0; 2];
            rep.attitude_sigma_deg = [0.0; 2];
        }
        rep
    }
}

/// The smrmsg file POSPac writes beside an SBET: `sbet_NAME.out` -> `smrmsg_NAME.out` in the
/// same folder (any case of the prefix), if it exists.
pub fn beside_sbet(sbet: &Path) -> Option<PathBuf> {
    let name = sbet.file_name()?.to_str()?;
    let rest = name.get(..5).filter(|p| p.eq_ignore_ascii_case("sbet_"))?;
    let upper = rest.starts_with('S');
    let candidate = sbet.with_file_name(format!(
        "{}{}",
        if upper { "SMRMSG_" } else { "smrmsg_" },
        &name[5..]
    ));
    candidate.is_file().then_some(candidate)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn acc(points: &[(i64, [f32; 2])]) -> Accuracy {
        Accuracy {
            time: points.iter().map(|p| p.0 * 1_000_000_000).collect(),
            sigma: points.iter().map(|p| p.1).collect(),
            ..Accuracy::default()
        }
    }

    /// Hand values: halfway between 2 and 4 cm is 3 cm; beyond 10 s of the records, none.
    #[test]
    fn interpolates_within_the_records_only() {
        let a = acc(&[(100, [0.02, 1e-4]), (102, [0.04, 3e-4]), (200, [0.1, 1e-3])]);
        let at = |s: f64| a.at(GpsTime((s * 1e9) as i64));
        let m = at(101.0).unwrap();
        assert!(
            (m[0] - 0.03).abs() < 1e-7 && (m[1] - 2e-4).abs() < 1e-9,
            "{m:?}"
        );
        assert_eq!(at(102.0), Some([0.04, 3e-4]));
        // 98 s between records 2 and 3: a gap, not interpolated; near its ends, the record's.
        assert_eq!(at(150.0), None);
        assert_eq!(at(105.0), Some([0.04, 3e-4]));
        assert_eq!(at(195.0), Some([0.1, 1e-3]));
        // Up to 10 s before the first and after the last record: the nearest record's.
        assert_eq!(at(95.0), Some([0.02, 1e-4]));
        assert_eq!(at(89.0), None);
        assert_eq!(at(209.0), Some([0.1, 1e-3]));
        assert_eq!(at(211.0), None);
    }

    #[test]
    fn found_beside_the_sbet() {
        let dir = std::env::temp_dir().join(format!("spherecal-acc-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let sbet = dir.join("sbet_Mission 1.out");
        assert_eq!(beside_sbet(&sbet), None);
        std::fs::write(dir.join("smrmsg_Mission 1.out"), b"").unwrap();
        assert_eq!(beside_sbet(&sbet), Some(dir.join("smrmsg_Mission 1.out")));
        assert_eq!(beside_sbet(&dir.join("trajectory.out")), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

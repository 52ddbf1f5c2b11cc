//! Where the calibration's navigation error model comes from (DESIGN.md "Navigation errors
//! that wander", its source): the site's `[ins.correlated]`, else the board's (the rig), else
//! what the INS itself states of its errors in the data read (a POSPac smrmsg, the POS MV's
//! Group 2, the VN-200's Ins.PosU and Attitude.YprU), else the documented default for the
//! INS's kind. The stated figures are sigmas only: the correlation time is the INS kind's
//! (no output states one). `preset = "white"` declares errors independent per sample (the
//! simulator's idealisation; no real INS): no model.

use crate::config::nav_errors::{preset, CorrelatedSpec};
use serde::{Deserialize, Serialize};
use spherecal::calib::nav::NavModel;

/// What the INS stated of its own errors over the samples read: the mean of each sigma's
/// square (RMS), per the source that stated them.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Stated {
    /// What stated them.
    pub from: String,
    /// Samples (or records) that stated them.
    pub samples: u64,
    /// Sums of squares: north/east (each), down [m^2]; roll/pitch (each), heading [deg^2].
    sum_sq: [f64; 4],
}

impl Stated {
    /// One sample's statement: north, east, down [m]; roll, pitch, heading [deg]. Values not
    /// finite and >= 0 are ignored.
    pub fn add(&mut self, from: &str, ned_m: [f64; 3], rph_deg: [f64; 3]) {
        if !ned_m
            .iter()
            .chain(&rph_deg)
            .all(|v| v.is_finite() && *v >= 0.0)
        {
            return;
        }
        if self.from.is_empty() {
            self.from = from.to_string();
        }
        let sq = [
            (ned_m[0] * ned_m[0] + ned_m[1] * ned_m[1]) / 2.0,
            ned_m[2] * ned_m[2],
            (rph_deg[0] * rph_deg[0] + rph_deg[1] * rph_deg[1]) / 2.0,
            rph_deg[2] * rph_deg[2],
        ];
        for (s, v) in self.sum_sq.iter_mut().zip(sq) {
            *s += v;
        }
        self.samples += 1;
    }

    /// The RMS statement: horizontal (each axis), vertical [m]; roll/pitch (each), heading
    /// [deg]; `None` before any sample.
    pub fn rms(&self) -> Option<([f64; 2], [f64; 2])> {
        (self.samples > 0).then(|| {
            let m = self.sum_sq.map(|s| (s / self.samples as f64).sqrt());
            ([m[0], m[1]], [m[2], m[3]])
        })
    }
}

/// The INS a calibration reads, for its default model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InsKind {
    /// A VectorNav VN-200 stream.
    Vn200,
    /// A POS MV's real-time groups.
    PosmvRealTime,
    /// A post-processed SBET.
    Sbet,
}

impl InsKind {
    /// In words.
    pub fn name(self) -> &'static str {
        match self {
            InsKind::Vn200 => "VN-200",
            InsKind::PosmvRealTime => "POS MV in real time",
            InsKind::Sbet => "POS MV post-processed (SBET)",
        }
    }

    /// The preset taken when nothing else says (`config::nav_errors::PRESETS`): a VN-200 with
    /// its own GNSS (metre level: nothing says it is RTK-aided), a POS MV in real time with
    /// RTK, an SBET post-processed.
    pub fn default_preset(self) -> &'static str {
        match self {
            InsKind::Vn200 => "vn200-gnss",
            InsKind::PosmvRealTime => "posmv-rtk",
            InsKind::Sbet => "posmv-pp",
        }
    }

    /// The correlation time for sigmas an output stated [s]: the default preset's, except a
    /// VN-200 stating RTK-level positions (under 0.1 m), whose is `vn200-rtk`'s.
    pub fn correlation_s(self, horizontal_m: f64) -> f64 {
        let key = match self {
            InsKind::Vn200 if horizontal_m < 0.1 => "vn200-rtk",
            k => k.default_preset(),
        };
        preset(key).map_or(60.0, |p| p.correlation_s)
    }
}

/// The model a calibration uses and where it came from (the report's `navigation.source`).
#[derive(Debug, Clone, PartialEq)]
pub struct NavChoice {
    /// The model (`None`: errors declared white).
    pub model: Option<NavModel>,
    /// Where it came from, in words.
    pub source: String,
}

/// A declared `[ins.correlated]` as a model (`None` inside: declared white or all zero).
fn declared(spec: &CorrelatedSpec, key: &str) -> Result<Option<NavModel>, crate::Error> {
    let c = spec.resolve(key)?;
    Ok(c.is_on().then_some(NavModel {
        position_sigma: c.position_sigma,
        attitude_sigma: c.attitude_sigma,
        correlation_s: c.correlation_s,
    }))
}

/// The words for a declared spec.
fn declared_words(spec: &CorrelatedSpec, owner: &str) -> String {
    match &spec.preset {
        Some(p) if *spec == CorrelatedSpec::preset_only(p) => {
            format!("{owner} [ins.correlated] preset \"{p}\"")
        }
        Some(p) => format!("{owner} [ins.correlated] (preset \"{p}\", changed)"),
        None => format!("{owner} [ins.correlated]"),
    }
}

/// The model: the site's declaration, else the board's, else what the INS stated, else the
/// default for its kind.
pub fn choose(
    site: Option<&CorrelatedSpec>,
    board: Option<&CorrelatedSpec>,
    stated: Option<&Stated>,
    kind: InsKind,
) -> Result<NavChoice, crate::Error> {
    for (spec, owner, key) in [
        (site, "site", "ins.correlated"),
        (board, "board", "ins.correlated"),
    ] {
        if let Some(spec) = spec.filter(|s| s.is_declared()) {
            return Ok(NavChoice {
                model: declared(spec, key)?,
                source: declared_words(spec, owner),
            });
        }
    }
    let stated = stated.and_then(|s| s.rms().map(|r| (s, r)));
    if let Some((s, (pos, att))) = stated.filter(|(_, (p, a))| p.iter().chain(a).any(|v| *v > 0.0))
    {
        let tau = kind.correlation_s(pos[0]);
        return Ok(NavChoice {
            model: Some(NavModel {
                position_sigma: pos,
                attitude_sigma: att.map(f64::to_radians),
                correlation_s: tau,
            }),
            source: format!(
                "stated by the INS ({}, RMS over {} samples; correlation {tau:.0} s as for a {})",
                s.from,
                s.samples,
                kind.name()
            ),
        });
    }
    let key = kind.default_preset();
    let c = declared(&CorrelatedSpec::preset_only(key), "ins.correlated")?;
    Ok(NavChoice {
        model: c,
        source: format!(
            "default for the INS (preset \"{key}\": nothing declared or stated; declare \
             [ins.correlated] in the site)"
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(text: &str) -> CorrelatedSpec {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn the_order_of_the_sources() {
        let mut st = Stated::default();
        st.add("POS MV Group 2", [0.03, 0.04, 0.06], [0.01, 0.01, 0.02]);
        st.add("POS MV Group 2", [0.03, 0.04, 0.06], [0.01, 0.01, 0.02]);
        let site = spec("preset = \"posmv-quebec\"");
        let board = spec("preset = \"posmv-rtk\"");
        let c = choose(Some(&site), Some(&board), Some(&st), InsKind::PosmvRealTime).unwrap();
        assert_eq!(c.source, "site [ins.correlated] preset \"posmv-quebec\"");
        assert_eq!(c.model.unwrap().position_sigma, [0.016, 0.033]);
        let c = choose(None, Some(&board), Some(&st), InsKind::PosmvRealTime).unwrap();
        assert!(c.source.starts_with("board"), "{}", c.source);
        // Undeclared (an empty table is no declaration): what the INS stated, N/E pooled.
        let c = choose(Some(&spec("")), None, Some(&st), InsKind::PosmvRealTime).unwrap();
        let m = c.model.unwrap();
        assert!((m.position_sigma[0] - (0.0025f64 / 2.0).sqrt()).abs() < 1e-12);
        assert!((m.position_sigma[1] - 0.06).abs() < 1e-12);
        assert!((m.attitude_sigma[1].to_degrees() - 0.02).abs() < 1e-12);
        assert_eq!(m.correlation_s, 30.0);
        assert!(
            c.source.contains("POS MV Group 2, RMS over 2 samples"),
            "{}",
            c.source
        );
        // Nothing at all: the kind's default, said so.
        let c = choose(None, None, None, InsKind::Vn200).unwrap();
        assert_eq!(c.model.unwrap().position_sigma, [2.5, 5.0]);
        assert!(c.source.contains("vn200-gnss"), "{}", c.source);
        // A VN-200 stating RTK-level positions wanders like an RTK-aided one.
        let mut v = Stated::default();
        v.add("VN-200", [0.02; 3], [0.03, 0.03, 0.2]);
        let c = choose(None, None, Some(&v), InsKind::Vn200).unwrap();
        assert_eq!(c.model.unwrap().correlation_s, 60.0);
        // Declared white: no model, whatever was stated.
        let c = choose(
            Some(&spec("preset = \"white\"")),
            None,
            Some(&st),
            InsKind::Sbet,
        )
        .unwrap();
        assert_eq!(c.model, None);
        assert!(c.source.contains("white"));
    }

    #[test]
    fn bad_statements_are_ignored() {
        let mut st = Stated::default();
        st.add("x", [f64::NAN, 0.0, 0.0], [0.0; 3]);
        st.add("x", [0.0; 3], [-1.0, 0.0, 0.0]);
        assert_eq!(st.rms(), None);
        // All zero stated: not a model; the default instead.
        st.add("x", [0.0; 3], [0.0; 3]);
        let c = choose(None, None, Some(&st), InsKind::Sbet).unwrap();
        assert!(c.source.starts_with("default"), "{}", c.source);
    }
}

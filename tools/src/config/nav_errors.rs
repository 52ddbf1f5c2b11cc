//! What a GNSS/INS solution's errors are like over time: the `[ins.correlated]` table (scenario
//! now; site and board next) and the named presets behind its `preset` key. The model is the
//! simulator's and (to come) the solver's: per axis a first-order Gauss-Markov process
//! (`spherecal::sim::nav_error`).
//!
//! The presets' sigmas are the performance tables of the makers' data sheets, 1 sigma (RMS);
//! the sheets state no correlation time, so each preset's is an engineering figure for the
//! kind of aiding (RTK or post-processed: tens of seconds; single-point GNSS: minutes), to be
//! replaced by what a unit's own solution shows (its smrmsg, or Group 2's RMS over time).

use serde::{Deserialize, Serialize};
use spherecal::sim::nav_error::Correlated;

/// One named INS class.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Preset {
    /// The key `preset = "..."` takes.
    pub key: &'static str,
    /// The product and the solution it describes.
    pub name: &'static str,
    /// Horizontal (per axis), vertical [m].
    pub position_sigma_m: [f64; 2],
    /// Roll and pitch (each), heading [deg].
    pub attitude_sigma_deg: [f64; 2],
    /// Correlation time [s].
    pub correlation_s: f64,
    /// Where the sigmas come from.
    pub source: &'static str,
}

/// The presets. Sigmas per the data sheets named in `source`.
pub const PRESETS: [Preset; 8] = [
    Preset {
        key: "posmv-rtk",
        name: "Applanix POS MV (OceanMaster class), real time with RTK",
        position_sigma_m: [0.03, 0.06],
        attitude_sigma_deg: [0.01, 0.02],
        correlation_s: 30.0,
        source: "POS MV data sheet, real-time RTK: roll/pitch 0.01 deg, heading 0.02 deg \
                 (2 m antenna baseline); position ~2-3 cm horizontal, ~5-6 cm vertical",
    },
    Preset {
        key: "posmv-pp",
        name: "Applanix POS MV, post-processed (POSPac SBET)",
        position_sigma_m: [0.02, 0.05],
        attitude_sigma_deg: [0.008, 0.02],
        correlation_s: 60.0,
        source: "POS MV data sheet, post-processed: roll/pitch 0.008 deg, heading 0.02 deg \
                 (2 m baseline); position ~2 cm horizontal, ~5 cm vertical",
    },
    Preset {
        key: "posmv-quebec",
        name: "The paper's POS MV survey at the Port of Quebec (its smrmsg)",
        position_sigma_m: [0.016, 0.033],
        attitude_sigma_deg: [0.011, 0.037],
        correlation_s: 30.0,
        source: "the smrmsg published with the seed paper's VLP-16 + POS MV survey: N/E/D \
                 1.6/1.5/3.3 cm, roll/pitch 0.011 deg, heading 0.037 deg, nearly constant",
    },
    Preset {
        key: "apx15",
        name: "Applanix APX-15 UAV, post-processed",
        position_sigma_m: [0.05, 0.10],
        attitude_sigma_deg: [0.025, 0.08],
        correlation_s: 30.0,
        source: "APX-15 UAV data sheet, post-processed: position 0.02-0.05 m horizontal, \
                 0.03-0.10 m vertical (upper ends taken); roll/pitch 0.025 deg, heading 0.08 deg",
    },
    Preset {
        key: "apx18",
        name: "Applanix APX-18 UAV (dual antenna), post-processed",
        position_sigma_m: [0.05, 0.10],
        attitude_sigma_deg: [0.025, 0.08],
        correlation_s: 30.0,
        source: "APX-18 UAV data sheet, post-processed: as the APX-15's (its second antenna \
                 improves real-time heading, not the post-processed figures)",
    },
    Preset {
        key: "vn200-rtk",
        name: "VectorNav VN-200 aided by RTK positions",
        position_sigma_m: [0.02, 0.04],
        attitude_sigma_deg: [0.03, 0.2],
        correlation_s: 60.0,
        source: "VN-200 data sheet: pitch/roll 0.03 deg, heading 0.2 deg RMS (dynamic); \
                 position at RTK level (~2 cm horizontal, ~4 cm vertical)",
    },
    Preset {
        key: "vn200-gnss",
        name: "VectorNav VN-200 with its own single-point GNSS (metre level)",
        position_sigma_m: [2.5, 5.0],
        attitude_sigma_deg: [0.03, 0.2],
        correlation_s: 300.0,
        source: "VN-200 data sheet: position 2.5 m horizontal (vertical taken as 2x), \
                 pitch/roll 0.03 deg, heading 0.2 deg RMS",
    },
    Preset {
        key: "white",
        name: "No wandering errors: each sample's error independent (no real INS)",
        position_sigma_m: [0.0, 0.0],
        attitude_sigma_deg: [0.0, 0.0],
        correlation_s: 0.0,
        source: "the simulator's idealisation (its [ins] pos_sigma_m / att_sigma_deg alone): \
                 declares that the solver is to treat the INS's errors as white",
    },
];

/// The preset of `key`.
pub fn preset(key: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.key == key)
}

/// `[ins.correlated]`: a preset, or the three numbers, or a preset with some of them replaced.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CorrelatedSpec {
    /// One of [`PRESETS`]' keys.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// Horizontal (north and east each), vertical [m], 1 sigma.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_sigma_m: Option<[f64; 2]>,
    /// Roll and pitch (each), heading [deg], 1 sigma.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attitude_sigma_deg: Option<[f64; 2]>,
    /// Correlation time [s].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub correlation_s: Option<f64>,
}

impl CorrelatedSpec {
    /// `preset = "key"` alone.
    pub fn preset_only(key: &str) -> Self {
        Self {
            preset: Some(key.to_string()),
            ..Self::default()
        }
    }

    /// Whether the table says anything (an empty or absent table declares nothing: the
    /// calibration then takes the model from elsewhere, `nav_source`).
    pub fn is_declared(&self) -> bool {
        *self != Self::default()
    }

    /// The model in the core's units, checked: `Err(key: why)`. `key` is the table's path
    /// (`ins.correlated`).
    pub fn resolve(&self, key: &str) -> Result<Correlated, crate::Error> {
        let base = match &self.preset {
            Some(k) => Some(*preset(k).ok_or_else(|| {
                let known: Vec<&str> = PRESETS.iter().map(|p| p.key).collect();
                format!("{key}.preset: \"{k}\" is not one of {}", known.join(", "))
            })?),
            None => None,
        };
        let pos = self
            .position_sigma_m
            .or(base.map(|b| b.position_sigma_m))
            .unwrap_or([0.0; 2]);
        let att = self
            .attitude_sigma_deg
            .or(base.map(|b| b.attitude_sigma_deg))
            .unwrap_or([0.0; 2]);
        let tau = self
            .correlation_s
            .or(base.map(|b| b.correlation_s))
            .unwrap_or(0.0);
        let bad = |k: &str, why: &str| Err(format!("{key}.{k}: {why}").into());
        if !pos
            .iter()
            .all(|v| v.is_finite() && (0.0..100.0).contains(v))
        {
            return bad(
                "position_sigma_m",
                "expected [horizontal, vertical], each 0..100 m",
            );
        }
        if !att.iter().all(|v| v.is_finite() && (0.0..10.0).contains(v)) {
            return bad(
                "attitude_sigma_deg",
                "expected [roll_pitch, heading], each 0..10 deg",
            );
        }
        let any = pos.iter().chain(&att).any(|v| *v > 0.0);
        if !(tau.is_finite() && (0.0..=86_400.0).contains(&tau)) || (any && tau <= 0.0) {
            return bad(
                "correlation_s",
                "expected a correlation time > 0 s (at most a day) with any sigma",
            );
        }
        Ok(Correlated {
            position_sigma: pos,
            attitude_sigma: [att[0].to_radians(), att[1].to_radians()],
            correlation_s: tau,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(text: &str) -> CorrelatedSpec {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn a_preset_and_its_overrides() {
        let c = spec("preset = \"posmv-rtk\"")
            .resolve("ins.correlated")
            .unwrap();
        assert_eq!(c.position_sigma, [0.03, 0.06]);
        assert!((c.attitude_sigma[1].to_degrees() - 0.02).abs() < 1e-12);
        assert_eq!(c.correlation_s, 30.0);
        let c = spec("preset = \"posmv-rtk\"\ncorrelation_s = 15")
            .resolve("ins.correlated")
            .unwrap();
        assert_eq!((c.position_sigma, c.correlation_s), ([0.03, 0.06], 15.0));
        let c = spec("position_sigma_m = [0.01, 0.02]\ncorrelation_s = 5")
            .resolve("ins.correlated")
            .unwrap();
        assert_eq!(c.attitude_sigma, [0.0; 2]);
        assert!(c.is_on());
        assert!(!CorrelatedSpec::default().resolve("x").unwrap().is_on());
    }

    #[test]
    fn bad_tables_name_the_key() {
        for (text, says) in [
            (
                "preset = \"posmv\"",
                "ins.correlated.preset: \"posmv\" is not one of posmv-rtk",
            ),
            (
                "position_sigma_m = [0.02, nan]\ncorrelation_s = 1",
                "position_sigma_m",
            ),
            (
                "attitude_sigma_deg = [-0.01, 0.02]\ncorrelation_s = 1",
                "attitude_sigma_deg",
            ),
            ("position_sigma_m = [0.02, 0.05]", "correlation_s"),
            ("preset = \"apx15\"\ncorrelation_s = 0", "correlation_s"),
        ] {
            let e = spec(text)
                .resolve("ins.correlated")
                .unwrap_err()
                .to_string();
            assert!(e.contains(says), "{text}: {e}");
        }
        assert!(toml::from_str::<CorrelatedSpec>("sigma = 1").is_err());
    }

    #[test]
    fn every_preset_resolves_with_its_source() {
        for p in PRESETS {
            let c = CorrelatedSpec {
                preset: Some(p.key.into()),
                ..Default::default()
            }
            .resolve("ins.correlated")
            .unwrap();
            // Every preset a model, but "white", which declares none.
            assert_eq!(c.is_on(), p.key != "white", "{}", p.key);
            assert!(!p.source.is_empty(), "{}", p.key);
        }
    }
}

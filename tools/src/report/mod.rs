//! The reports: a calibration's (`calibrate`, the rig after every solve, the demo) and a Monte
//! Carlo run's, and writing a report file atomically (a reader never sees half of one); their
//! human summaries are in [`text`].

mod text;
pub use text::{render, render_montecarlo, termination_words, utc};
pub mod conventions;
pub mod lenient;
mod nav;
mod of;
pub mod prior;
pub mod provenance;
pub mod solved;

use crate::pipeline::{Inputs, RunStats};
use serde::{Deserialize, Serialize};
use spherecal::georef::P;
use std::collections::BTreeMap;
use std::path::Path;

/// The report's three-angle / three-axis groups.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Angles {
    /// Roll.
    pub roll: f64,
    /// Pitch.
    pub pitch: f64,
    /// Heading.
    pub heading: f64,
}

/// x, y, z.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Xyz {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// 1-sigma of each parameter.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Sigma {
    /// [deg].
    pub boresight_deg: Angles,
    /// [m].
    pub lever_arm_m: Xyz,
    /// [s] (0 when the time offset is not estimated).
    #[serde(default)]
    pub time_offset_s: f64,
}

/// Roll, pitch, heading [deg], x, y, z [m]: the solver's order.
fn deg_m(b: &Angles, l: &Xyz) -> [f64; 6] {
    [b.roll, b.pitch, b.heading, l.x, l.y, l.z]
}

impl Sigma {
    /// The six 1-sigmas [deg, m] in the solver's order.
    pub fn deg_m(&self) -> [f64; 6] {
        deg_m(&self.boresight_deg, &self.lever_arm_m)
    }
}

/// Windowed returns by the extraction's verdict.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Verdicts {
    /// On the sphere: used.
    pub kept: u32,
    /// In slices of time where the sphere was not detected.
    pub undetected: u32,
    /// Off the sphere's shell.
    pub outside_shell: u32,
    /// On the far side of the sphere as seen from the sensor.
    pub hidden_side: u32,
    /// On a plane that continues beyond the sphere.
    pub plane: u32,
    /// On a pole that continues beyond the sphere.
    pub pole: u32,
    /// The sphere was not found.
    pub sphere_not_found: u32,
}

impl Verdicts {
    pub(crate) fn from_tally(t: &spherecal::calib::solve::Tally) -> Self {
        use spherecal::calib::extract::ReturnClass as V;
        let g = |v: V| t[v as usize];
        Self {
            kept: g(V::Kept),
            undetected: g(V::Undetected),
            outside_shell: g(V::OutsideShell),
            hidden_side: g(V::Hidden),
            plane: g(V::Plane),
            pole: g(V::Pole),
            sphere_not_found: g(V::NotFound) + g(V::Unclassified),
        }
    }

    /// Returns rejected (everything but the kept ones).
    pub fn rejected(&self) -> u32 {
        self.undetected
            + self.outside_shell
            + self.hidden_side
            + self.plane
            + self.pole
            + self.sphere_not_found
    }
}

/// One pass over one sphere.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PerPass {
    /// Sphere id.
    pub sphere: String,
    /// GPS seconds of its first and last windowed return.
    pub start_gps_s: f64,
    /// ...
    pub end_gps_s: f64,
    /// Slices of time (0.4 s) with windowed returns.
    pub slices: u32,
    /// Slices where the sphere was detected.
    pub detected: u32,
    /// Mean inliers per detection (the detection score).
    pub mean_inliers: f32,
    /// Windowed returns.
    pub windowed: u32,
    /// By verdict.
    pub verdicts: Verdicts,
    /// The sphere re-fitted to this pass's calibrated returns, minus the surveyed centre [m,
    /// NED] (zeros with fewer than 10 returns).
    pub centre_offset_m: [f32; 3],
    /// Its component along the track [m] (a time offset between the clocks shows here).
    pub along_track_m: f32,
    /// Its chi-square against the pass's own uncertainty (3 degrees of freedom; the solution is
    /// refused as inconsistent above 25 with more than 3 mm).
    pub chi2: f32,
    /// The time offset this pass's returns give, minus the solution's at its time [s] (the
    /// solution is refused when a pass is off by more than 5 sigma and 1 ms: the clocks step
    /// or drift).
    #[serde(default)]
    pub time_offset_shift_s: f32,
    /// Its 1-sigma [s] (0: too few returns).
    #[serde(default)]
    pub time_offset_shift_sigma_s: f32,
}

/// Per sphere.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PerSphere {
    /// Sphere id.
    pub id: String,
    /// Found among the clutter (else left out of the solution).
    pub found: bool,
    /// Returns in the a-priori window.
    pub windowed: usize,
    /// Returns used.
    pub points: usize,
    /// Returns the rounds kept (around where the returns put the sphere) before the last
    /// extraction kept `points` around its surveyed centre.
    #[serde(default)]
    pub rounds_kept: usize,
    /// Slices of time with windowed returns, and those where the sphere was detected.
    pub slices: u32,
    /// ...
    pub detected: u32,
    /// Windowed returns by verdict.
    pub verdicts: Verdicts,
    /// RMS with the starting values [m].
    pub rms_before_m: f64,
    /// RMS with the solution [m].
    pub rms_after_m: f64,
    /// Fitted minus surveyed centre, NED [m].
    pub centre_offset_m: Option<[f64; 3]>,
    /// Slices where the first round's consensus (the mounting all spheres agree on) found it.
    #[serde(default)]
    pub agreed_slices: u32,
    /// Why it was not found: `no_returns` (empty window), `not_detected` (nothing sphere-like
    /// in it), `disagrees` (sphere-like things, none where the others' mounting puts it:
    /// clutter, a decoy, or the sphere hidden), `too_few_returns`, `stopped` (the solve stopped
    /// before keeping returns: the report's reason says why).
    #[serde(default)]
    pub lost: Option<String>,
    /// On a refusal, the radius its returns show (`crate::session::radius`; null: not looked
    /// for, or no slice showed a sphere) [m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub apparent_radius_m: Option<f64>,
}

/// The tests a solution passed (or failed) before it is claimed.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Consistency {
    /// The residual RMS the noise model predicts (range, INS attitude x range, INS position) [m].
    pub predicted_rms_m: f64,
    /// The residual RMS over that (refused above 2).
    pub dispersion: f64,
    /// The largest chi-square of a pass's sphere centre against its uncertainty (refused above
    /// 25 with more than 3 mm).
    pub worst_pass_chi2: f64,
    /// With the time offset held: what the data give when free (offset on top of the held one,
    /// sigma) [s]; refused when it differs by more than 5 sigma and 1 ms.
    pub free_time_offset_s: Option<[f64; 2]>,
    /// Kept returns set aside after the fit, [returns, pieces]: pieces whose few returns the
    /// navigation model could not join to their neighbours (a step beyond the jump limit that
    /// goes with them).
    #[serde(default)]
    pub misfit_pieces_set_aside: [u32; 2],
    /// [returns, stretches]: isolated stretches of few returns that alone moved the answer
    /// beyond 5 times what their information can.
    #[serde(default)]
    pub influential_set_aside: [u32; 2],
    /// The rounds started again from the a-priori mounting because the first start lost a
    /// sphere: [slices the first start's spheres were detected in, the second's, 1 when the
    /// second start's answer was taken else 0].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub second_start: Option<[u32; 3]>,
}

/// `report.json` (DESIGN.md contract plus the keys).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Report {
    /// [deg].
    pub boresight_deg: Angles,
    /// [m].
    pub lever_arm_m: Xyz,
    /// The time offset between the clocks: INS time = LiDAR time + this [s] (DESIGN.md).
    #[serde(default)]
    pub time_offset_s: f64,
    /// The time offset was estimated (else held at the value the pipeline applied).
    #[serde(default)]
    pub time_offset_estimated: bool,
    /// Its drift [ppm]: the offset at GPS time t is `time_offset_s + drift 1e-6 (t -
    /// time_offset_reference_gps_s)` (estimated for a LiDAR clock without PPS; else 0).
    #[serde(default)]
    pub time_drift_ppm: f64,
    /// Its 1-sigma [ppm] (0 when not estimated).
    #[serde(default)]
    pub time_drift_sigma_ppm: f64,
    /// The GPS time [s] the offset refers to (the middle of the windowed returns).
    #[serde(default)]
    pub time_offset_reference_gps_s: f64,
    /// 1-sigma.
    pub sigma: Sigma,
    /// RMS of the residuals [m].
    pub rms_m: f64,
    /// Eq. 6 over the used returns [m].
    pub objective_l1_m: f64,
    /// Returns used per sphere.
    pub points_per_sphere: Vec<usize>,
    /// Objective evaluations by Nelder-Mead.
    pub evaluations: usize,
    /// Nelder-Mead iterations.
    pub nm_iterations: usize,
    /// LM iterations (last round).
    pub lm_iterations: usize,
    /// Re-windowing rounds.
    pub rounds: usize,
    /// How the rounds ended (`settled`, `cycle`, `too_few_spheres`, `stopped`, `max_rounds`,
    /// `not_started`: [`spherecal::calib::Termination`]).
    #[serde(default)]
    pub termination: String,
    /// A solution is claimed.
    pub converged: bool,
    /// Why not, if not.
    pub reason: Option<String>,
    /// Correlation matrix, order roll, pitch, heading, x, y, z, time_offset (the last row and
    /// column 0 when the time offset is not estimated).
    pub correlation: Vec<Vec<f64>>,
    /// The rows' and columns' names of `correlation`, in order.
    #[serde(default)]
    pub correlation_labels: Vec<String>,
    /// The program that wrote the report (`spherecal` and its version).
    #[serde(default)]
    pub version: String,
    /// Condition number of the unit-diagonal normal matrix.
    pub condition_number: f64,
    /// Parameters the data determine poorly.
    pub weak_parameters: Vec<String>,
    /// RMS of fitted minus surveyed centres [m].
    pub sphere_centre_rms_m: Option<f64>,
    /// Per sphere.
    pub per_sphere: Vec<PerSphere>,
    /// Per pass over each sphere.
    pub per_pass: Vec<PerPass>,
    /// The final shell: kept returns are within this of their sphere's surface [m].
    pub shell_m: f64,
    /// Windowed returns rejected as clutter, all spheres.
    pub clutter_rejected: u64,
    /// Windowed returns lost because a fixed-capacity batch was full (never expected; counted
    /// so that a truncated window cannot pass unnoticed).
    #[serde(default)]
    pub batch_overflow: u64,
    /// The consistency tests.
    pub consistency: Consistency,
    /// What the inputs held (files, clock, INS state, spans, skips).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inputs: Option<InputsReport>,
    /// Time of the solve [ms].
    pub solve_ms: f64,
    /// Starting values.
    pub start: BTreeMap<String, f64>,
    /// The coarse search of the time offset, when one ran: each start tried.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub time_offset_search: Vec<SearchCandidate>,
    /// What the calibration ran to get here (`calibrate`'s collections and solves).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub effort: Option<Effort>,
    /// The navigation model the least squares estimated under, when one was declared.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub navigation: Option<NavigationReport>,
    /// Stretches of the survey whose returns were left out: by hand (`--exclude`), or set
    /// aside because the survey was refused with them and every check passes without.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub set_aside: Vec<crate::stretches::SetAsideSpan>,
    /// The accuracy targets and whether the sigmas meet them (a converged calibration that
    /// misses them exits 3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub targets: Option<TargetsReport>,
    /// Parameters the data could not determine, held at their a-priori values
    /// (`crate::undetermined`): their sigmas are the hold's.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub held: Vec<String>,
    /// The mounting as measured (`[apriori]`'s sigmas) against the calibration ([`prior`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mounting_prior: Vec<prior::MeasuredParameter>,
    /// The mounting in the conventions other software takes ([`conventions`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub conventions: Option<conventions::Conventions>,
    /// Where the calibration came from ([`provenance`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<provenance::Provenance>,
}

/// `report.json` `targets`: each sigma's target, whether all are met, which are missed.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct TargetsReport {
    /// Each boresight angle's 1-sigma at most [deg] (null: not targeted).
    pub sigma_deg: Option<f64>,
    /// Each lever-arm component's 1-sigma at most [m] (null: not targeted).
    pub sigma_m: Option<f64>,
    /// Every sigma within its target (false when not converged).
    pub met: bool,
    /// The parameters that miss (roll, pitch, heading, x, y, z).
    pub missed: Vec<String>,
    /// Where the targets came from.
    pub source: String,
}

impl TargetsReport {
    /// The report's sigmas against `t`.
    pub fn of(r: &Report, t: &crate::config::goal::TargetChoice) -> Self {
        let missed: Vec<String> = t
            .missed(&r.sigma.deg_m())
            .into_iter()
            .map(String::from)
            .collect();
        let fin = |v: f64| v.is_finite().then_some(v);
        Self {
            sigma_deg: fin(t.sigma_deg),
            sigma_m: fin(t.sigma_m),
            met: r.converged && missed.is_empty(),
            missed,
            source: t.source.clone(),
        }
    }

    /// The verdict line: met, or what is missed by how much.
    pub fn words(&self, r: &Report) -> String {
        let t = |v: Option<f64>, scale: f64, unit: &str| {
            v.map_or("-".to_string(), |v| format!("{} {unit}", v * scale))
        };
        let targets = format!(
            "targets ({}, {}: {})",
            t(self.sigma_deg, 1.0, "deg"),
            t(self.sigma_m, 1e3, "mm"),
            self.source
        );
        if self.met {
            return format!("every sigma within the {targets}");
        }
        let sig = r.sigma.deg_m();
        let names = ["roll", "pitch", "heading", "x", "y", "z"];
        let missed: Vec<String> = self
            .missed
            .iter()
            .filter_map(|m| names.iter().position(|n| n == m).map(|i| (m, i)))
            .map(|(m, i)| {
                if i < 3 {
                    format!("{m} {:.4} deg", sig[i])
                } else {
                    format!("{m} {:.1} mm", sig[i] * 1e3)
                }
            })
            .collect();
        format!("the sigmas miss the {targets}: {}", missed.join(", "))
    }
}

/// The navigation errors' model and what the solve found under it (DESIGN.md "Navigation
/// errors that wander").
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct NavigationReport {
    /// Where the model came from (`site [ins.correlated]`).
    pub source: String,
    /// Position 1 sigma: horizontal, vertical [m].
    pub position_sigma_m: [f64; 2],
    /// Attitude 1 sigma: roll and pitch, heading [deg].
    pub attitude_sigma_deg: [f64; 2],
    /// Correlation time [s].
    pub correlation_s: f64,
    /// Pieces of the time line, each with its own error.
    pub pieces: usize,
    /// The white noise's variance found against the declared one.
    pub white_noise_factor: f64,
    /// The share of the footprint's range spread at grazing incidence the weights took (1:
    /// as the beam's divergence says; 0: the residuals did not show it, or no divergence is
    /// known).
    #[serde(default)]
    pub footprint_spread: f64,
    /// Each sphere's centre correction from its surveyed one with its 1 sigma.
    pub centres: Vec<CentreCorrection>,
    /// The navigation corrections found: each piece of the time line's error (reported minus
    /// true) with its 1 sigma, in time order.
    #[serde(default)]
    pub corrections: Vec<NavCorrectionReport>,
    /// The largest step between consecutive pieces in the model's sigmas (an INS jump shows
    /// as tens), and when [GPS s].
    #[serde(default)]
    pub worst_step_sigmas: f64,
    /// See `worst_step_sigmas`.
    #[serde(default)]
    pub worst_step_gps_s: f64,
}

/// One piece's navigation error as the calibration estimated it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct NavCorrectionReport {
    /// Its first and last return [GPS s].
    pub start_gps_s: f64,
    /// See `start_gps_s`.
    pub end_gps_s: f64,
    /// Returns in it.
    pub returns: usize,
    /// Position error north, east, down [m] (subtract it from the INS's position).
    pub position_m: [f64; 3],
    /// Its 1 sigma [m].
    pub position_sigma_m: [f64; 3],
    /// Attitude error as a small rotation about north, east, down [deg] (about down: the
    /// heading's).
    pub rotation_deg: [f64; 3],
    /// Its 1 sigma [deg].
    pub rotation_sigma_deg: [f64; 3],
}

/// A sphere centre under the navigation model.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct CentreCorrection {
    /// The sphere.
    pub sphere: String,
    /// Its survey's 1 sigma (the prior) [m].
    pub prior_sigma_m: f64,
    /// Estimated minus surveyed centre, north, east, down [m].
    pub correction_m: [f64; 3],
    /// Its 1 sigma [m].
    pub sigma_m: [f64; 3],
}

impl Report {
    /// A report.json's text, whatever it holds: a refused run's numbers that are not numbers
    /// (written as `null`) read as NaN ([`lenient`]).
    pub fn parse(text: &str) -> Result<Self, serde_json::Error> {
        lenient::from_str(text)
    }

    /// Read a report.json (for `--init-from`); its six and time offset must be finite.
    pub fn load(path: &std::path::Path) -> Result<Self, crate::Error> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let r = Report::parse(&text)
            .map_err(|e| format!("{}: not a spherecal report: {e}", path.display()))?;
        if !r
            .deg_m()
            .iter()
            .chain([&r.time_offset_s])
            .all(|v| v.is_finite())
        {
            return Err(format!(
                "{}: its boresight, lever arm or time offset is not a number",
                path.display()
            )
            .into());
        }
        Ok(r)
    }

    /// The solution [deg, m] in the solver's order.
    pub fn deg_m(&self) -> [f64; 6] {
        deg_m(&self.boresight_deg, &self.lever_arm_m)
    }
}

/// What one calibration ran: a time-offset search's starts and the offsets found each cost a
/// collection and a solve; a refusal looked into costs radius probes and, for a stretch set
/// aside, a solve per candidate.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq, Eq)]
pub struct Effort {
    /// The windows collected (the pipeline over the files).
    pub collections: u32,
    /// Least-squares solves (the detect-and-solve rounds and the last fit).
    pub solves: u32,
    /// Refusals whose spheres' radii were probed ([`crate::session::radius`]).
    pub radius_probes: u32,
}

/// One start of the time offset search.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct SearchCandidate {
    /// The offset the windows were collected at [s].
    pub start_s: f64,
    /// The offset the joint solve moved it to [s] (none without a converged least squares).
    pub found_s: Option<f64>,
    /// Returns kept on the spheres.
    pub kept: usize,
    /// Their residual RMS [m].
    pub rms_m: Option<f64>,
}

/// What the inputs held, in the report.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct InputsReport {
    /// The capture.
    pub pcap: String,
    /// The LiDAR model its packets were decoded as.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lidar_model: Option<String>,
    /// The trajectory's file.
    pub ins: String,
    /// Data packets timed.
    pub data_packets: u64,
    /// Capture records skipped, by reason.
    pub skipped: BTreeMap<String, u64>,
    /// GPS seconds of the first and last data packet (LiDAR clock).
    pub lidar_span_gps_s: Option<(f64, f64)>,
    /// The same in UTC (`YYYY-MM-DD hh:mm:ss UTC`, the site's leap seconds).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lidar_span_utc: Option<(String, String)>,
    /// The LiDAR clock as its position packets tell it.
    pub clock: crate::state::ClockState,
    /// The LiDAR clock is PPS-locked with valid RMCs that agree with its stamps.
    pub clock_trusted: bool,
    /// The INS stream.
    pub ins_state: crate::state::InsState,
    /// Returns not georeferenced: before the INS data, after it, in INS gaps.
    pub not_georeferenced: [u64; 3],
    /// Data packets without a time.
    pub packets_without_time: u64,
    /// The time offset the windows were collected at [s].
    pub time_offset_applied_s: f64,
    /// Windowed returns let go as they came, farther than 1 m from every sphere under a solve
    /// of the first ones (the collection's memory bound; 0 for a survey that fits).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub pruned_returns: u64,
    /// The trajectory's accuracy file and what it gave the returns (the noise model's INS
    /// sigmas), when one was read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accuracy: Option<crate::pipeline::accuracy::AccuracyReport>,
}

impl InputsReport {
    /// From a run's counts.
    pub fn of(inp: &Inputs, stats: &RunStats) -> Self {
        let w = &stats.align.window;
        Self {
            pcap: inp.pcap.display(),
            lidar_model: stats.lidar_name().map(str::to_string),
            ins: inp.ins_files().display(),
            data_packets: stats.align.data_packets,
            skipped: stats
                .skips
                .lines()
                .iter()
                .map(|l| (l.reason.to_string(), l.count))
                .collect(),
            lidar_span_gps_s: stats.align.lidar_span,
            lidar_span_utc: stats.align.lidar_span.map(|(a, b)| {
                let leap = inp.site.leap_seconds;
                (utc(a, leap), utc(b, leap))
            }),
            clock: stats.clock.clone(),
            clock_trusted: stats.clock.trusted(),
            ins_state: stats.ins.clone(),
            not_georeferenced: [w.before_history, w.after_history, w.in_gap],
            packets_without_time: stats.align.packets_without_time,
            time_offset_applied_s: inp.time_offset_ns as f64 * 1e-9,
            pruned_returns: stats.pruned,
            accuracy: None,
        }
    }
}

/// Monte Carlo: one trial.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Trial {
    /// Start [deg, m].
    pub start: [f64; P],
    /// Solution [deg, m].
    pub solution: [f64; P],
    /// Solution minus truth [deg, m].
    pub error: [f64; P],
    /// A solution was claimed.
    pub converged: bool,
    /// Within 1e-3 deg / 1e-3 m on every parameter.
    pub within: bool,
    /// Solve time [ms].
    pub ms: f64,
}

/// The Monte Carlo report.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct McReport {
    /// Scenario.
    pub scenario: String,
    /// Trials.
    pub trials: usize,
    /// Start spread [deg].
    pub angle_noise_deg: f64,
    /// Start spread [m].
    pub lever_noise_m: f64,
    /// Seed.
    pub seed: u64,
    /// Fraction within 1e-3 deg / 1e-3 m.
    pub fraction_within: f64,
    /// Fraction claimed converged.
    pub fraction_converged: f64,
    /// Worst |error| per parameter [deg, m], order roll, pitch, heading, x, y, z.
    pub worst_error: [f64; P],
    /// Mean solve time per trial [ms].
    pub ms_per_trial: f64,
    /// Every trial.
    pub runs: Vec<Trial>,
}

/// Write `value` as pretty JSON to `p` through a temporary file and a rename, so that a reader
/// (a surveyor's viewer polling the rig's report) never sees half of one.
pub fn write_json_atomically<T: Serialize>(p: &Path, value: &T) -> Result<(), crate::Error> {
    let json = serde_json::to_string_pretty(value).map_err(|e| e.to_string())?;
    write_atomically(p, (json + "\n").as_bytes())
}

/// Write `bytes` to `p` whole or not at all ([`crate::output::write`]).
pub fn write_atomically(p: &Path, bytes: &[u8]) -> Result<(), crate::Error> {
    crate::output::write(p, bytes).map_err(|e| format!("cannot write the report: {e}").into())
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

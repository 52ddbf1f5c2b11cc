//! What the solve is told: its limits, its noise model and its stopping rules.

use super::outcome::Refusal;
use crate::align::window::MAX_TARGETS;
use crate::calib::consensus::ConsensusSettings;
use crate::calib::extract::ExtractSettings;
use crate::calib::footprint::Footprint;
use crate::calib::lm::Clock;
use crate::calib::nav::NavModel;
use crate::calib::nelder_mead::NmSettings;
use crate::calib::noise::Noise;
use crate::georef::P;

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Nelder-Mead settings (coordinates in degrees and metres).
    pub nm: NmSettings,
    /// Initial simplex step per parameter (deg, deg, deg, m, m, m).
    pub step: [f64; P],
    /// LM iteration cap.
    pub lm_iter: usize,
    /// Fewest returns per sphere.
    pub min_points: usize,
    /// Largest acceptable condition number.
    pub max_condition: f64,
    /// Condition number above which the geometry counts as weak and the parameters with a
    /// large share of its weakest direction are named (below it every parameter is well
    /// determined, whatever that direction is).
    pub weak_condition: f64,
    /// The range noise the sensor is specified for, 1 sigma [m] (VLP-16: 3 cm).
    pub range_noise: f64,
    /// The INS attitude noise, 1 sigma [rad].
    pub attitude_noise: f64,
    /// The INS position noise, 1 sigma [m].
    pub position_noise: f64,
    /// Over-dispersion: the residual RMS may be at most this many times what the noise model
    /// predicts.
    pub max_dispersion: f64,
    /// A sphere's last extraction (around its surveyed centre) must keep at least this
    /// fraction of what the rounds kept (around where its returns put it). The lowest sphere's
    /// share over the planner's Monte Carlo: table1-real 0.90-0.98 (120 seeds), table1-noisy
    /// 0.79-0.9, drone-noisy 0.36-1 (grass spheres; 100 seeds); 0.13-0.16 where a silent GNSS
    /// outage moved the spheres for 40 s of table1-real.
    pub min_kept_fraction: f64,
    /// Under a navigation model that wanders, the white noise found may be at most this many
    /// times the declared (the variance factor's square root): table1-real 0.7-0.97,
    /// drone-noisy 1.3-1.82 over the same Monte Carlo; 2.6-3.1 under that outage.
    pub max_white_noise_factor: f64,
    /// A pass's sphere centre offset fails the consistency test beyond this chi-square (3
    /// degrees of freedom; 25: p = 1.4e-5) ...
    pub max_pass_chi2: f64,
    /// ... and this many metres.
    pub pass_offset_floor: f64,
    /// A held time offset is contradicted when the data, free to estimate it, move it by more
    /// than this many of its sigmas ...
    pub held_dt_sigmas: f64,
    /// ... and this many seconds.
    pub held_dt_floor: f64,
    /// The shell: this many robust sigmas ...
    pub shell_sigmas: f64,
    /// ... but at least this [m].
    pub shell_floor: f64,
    /// Detect-and-solve rounds at most.
    pub max_rounds: usize,
    /// Returns of one sphere this close in time share INS errors: one cluster for the
    /// covariance [ns].
    pub cluster_ns: i64,
    /// Returns per sphere Nelder-Mead evaluates (evenly spread; LM uses all).
    pub nm_points: usize,
    /// Sphere extraction.
    pub extract: ExtractSettings,
    /// Estimate the time offset between the clocks with the six.
    pub estimate_dt: bool,
    /// Estimate its drift too (a LiDAR clock without PPS: its crystal runs fast or slow by
    /// tens of ppm).
    pub estimate_drift: bool,
    /// The first round's consensus over the slices' candidates.
    pub consensus: ConsensusSettings,
    /// The margin the windows were made with around the start mounting [m]: the mounting may
    /// move at most this far in each lever-arm component, and each angle at most as far as moves
    /// the nearest windowed return by twice this (at most 45 deg): a mounting beyond would have
    /// left the spheres outside their windows.
    pub margin: f64,
    /// What the streams say of the clocks (the core sees no packets): the checks refuse on
    /// it as on the returns.
    pub clocks: ClockFacts,
    /// The navigation errors that wander ([`crate::calib::nav`]): with a model the least
    /// squares estimate them with the mounting, the sphere centres become parameters with
    /// their survey's sigma, and the passes are tested against both; `None`: white per sample
    /// (the paper's model).
    pub nav: Option<NavModel>,
    /// The LiDAR beam's footprint: the least squares take each return's expected bloom out of
    /// its residual, with its gradient ([`crate::calib::footprint`]); `None`: an ideal ray.
    pub footprint: Option<Footprint>,
    /// Each sphere's surveyed centre's 1 sigma [m] under the navigation model (0: held).
    pub centre_sigma: [f64; MAX_TARGETS],
    /// A prior on the mounting (a measured lever arm; a parameter held at its a-priori value):
    /// under a navigation model (use [`NavModel::WHITE`] for white errors) the least squares
    /// take it as a pseudo-observation.
    pub mount_prior: crate::calib::nav::MountPrior,
    /// Under the navigation model, the largest step between consecutive pieces, in the
    /// model's sigmas, that is not a jump (surveys with the declared errors: 1.7-2.3; a 5 cm
    /// jump within a pass: 10).
    pub max_nav_step_sigmas: f64,
    /// An isolated stretch of few kept returns is set aside when it alone moves a parameter by
    /// more than this many times what its information can move it by (`solve::last`).
    pub max_influence_sigmas: f64,
    /// When the rounds end with a sphere lost, start them again from the a-priori, close, and
    /// keep the start that explains more (`solve::restart`).
    pub second_start: bool,
}

/// What the caller read of the clocks in the streams.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ClockFacts {
    /// The LiDAR clock is not PPS-locked with a valid RMC (`None`: it is).
    pub lidar_untrusted: Option<UntrustedLidar>,
    /// The INS clock stepped within the LiDAR data (`None`: it did not).
    pub ins_step: Option<InsStep>,
}

/// A LiDAR clock without PPS and a valid RMC: a solution is claimed only when allowed and the
/// time offset found explains the stamps' disagreement with the RMC (within 1.5 s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UntrustedLidar {
    /// The stamps minus the RMC time, if the RMCs give it [s].
    pub rmc_offset_s: Option<f64>,
    /// The offset the caller applied before the solve; the solution's `dt` is on top [s].
    pub applied_s: f64,
    /// The user allows an unlocked clock (`--allow-unlocked-clock`).
    pub allowed: bool,
}

/// The first INS clock step within the LiDAR data: every pose after it is off by the step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InsStep {
    /// When, GPS seconds of week [s].
    pub at_s: f64,
    /// When, after the first LiDAR data [s].
    pub into_s: f64,
    /// By how much [s].
    pub step_s: f64,
    /// How many steps within the data.
    pub count: usize,
}

impl Settings {
    /// The refusal of a time offset held at `held` [s] when the data, free to estimate it,
    /// put it at `found` with its `sigma` [s]: beyond [`Self::held_dt_sigmas`] and
    /// [`Self::held_dt_floor`].
    pub fn held_contradicted(&self, held: f64, found: f64, sigma: f64) -> Option<Refusal> {
        self.offsets_apart(found - held, sigma)
            .then_some(Refusal::TimeOffsetContradicted { held, found, sigma })
    }

    /// Whether two time offsets `d` [s] apart, the difference's 1 sigma `sigma`, are
    /// different clocks: beyond [`Self::held_dt_sigmas`] sigmas and [`Self::held_dt_floor`]
    /// (a held offset against the data's, a pass against the rest, the passes either side of
    /// a step).
    pub fn offsets_apart(&self, d: f64, sigma: f64) -> bool {
        let d = d.abs();
        d > self.held_dt_floor && d > self.held_dt_sigmas * sigma
    }

    /// The clock parameters estimated with the six.
    pub fn clock(&self) -> Clock {
        Clock {
            dt: self.estimate_dt,
            drift: self.estimate_dt && self.estimate_drift,
        }
    }

    /// The noise model of the residuals.
    pub fn noise(&self) -> Noise {
        Noise {
            range: self.range_noise,
            attitude: self.attitude_noise,
            position: self.position_noise,
            spread: self.footprint.map_or(0.0, |f| f.sigma[0]),
        }
    }
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            nm: NmSettings::default(),
            step: [1.0, 1.0, 1.0, 0.1, 0.1, 0.1],
            lm_iter: 100,
            min_points: 30,
            max_condition: 1e3,
            weak_condition: 100.0,
            range_noise: 0.03,
            attitude_noise: 0.05f64.to_radians(),
            position_noise: 0.03,
            max_dispersion: 2.0,
            min_kept_fraction: 0.25,
            max_white_noise_factor: 2.5,
            max_pass_chi2: 25.0,
            pass_offset_floor: 0.003,
            held_dt_sigmas: 5.0,
            held_dt_floor: 0.001,
            shell_sigmas: 3.5,
            shell_floor: 0.004,
            max_rounds: 12,
            cluster_ns: 20_000_000,
            nm_points: 100,
            extract: ExtractSettings::default(),
            estimate_dt: true,
            estimate_drift: false,
            consensus: ConsensusSettings::default(),
            margin: 3.0,
            clocks: ClockFacts::default(),
            nav: None,
            footprint: None,
            centre_sigma: [0.0; MAX_TARGETS],
            mount_prior: crate::calib::nav::MountPrior {
                centre: [0.0; P],
                info: [0.0; P],
            },
            max_nav_step_sigmas: 5.0,
            max_influence_sigmas: 5.0,
            second_start: true,
        }
    }
}

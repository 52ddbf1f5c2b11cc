//! What the solve gives: the solution, its rounds, spheres and passes, how the rounds ended
//! ([`Termination`]) and why a solution is not claimed ([`Refusal`]).

use super::settings::InsStep;
use super::{Tally, MAX_PASSES};
use crate::align::window::MAX_TARGETS;
use crate::calib::consensus::{Ambiguity, Bounds, Consensus};
use crate::calib::lm::LmResult;
use crate::calib::nav::NavFit;
use crate::calib::nelder_mead::NmResult;
use crate::calib::objective::TimeOffset;
use crate::georef::{Params, P};
use crate::time::GpsTime;
use nalgebra::Vector3;

/// Why a solution is not claimed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Refusal {
    /// Fewer than two spheres given (the site's).
    TooFewTargets {
        /// Spheres given.
        given: usize,
    },
    /// Fewer than two spheres found among the clutter.
    TooFewSpheres {
        /// Spheres found.
        have: usize,
    },
    /// A sphere with too few returns.
    TooFewPoints {
        /// Sphere index.
        sphere: usize,
        /// Returns used.
        have: usize,
        /// Needed.
        need: usize,
    },
    /// The data cannot determine all six parameters well.
    IllConditioned {
        /// Condition number.
        condition: f64,
        /// Limit.
        limit: f64,
    },
    /// The least squares did not converge (stalled, or non-finite).
    NotConverged {
        /// Iterations taken.
        iterations: usize,
    },
    /// The residuals are far above what the sensors' noise explains.
    OverDispersed {
        /// RMS [m].
        rms: f64,
        /// What the noise model predicts [m].
        predicted: f64,
    },
    /// In one pass the calibrated returns leave a sphere off its surveyed centre, beyond its
    /// uncertainty: the model does not fit (along the track: a time offset or a lever-arm x
    /// error; across it: the boresight).
    Inconsistent {
        /// Sphere index.
        sphere: usize,
        /// Index of the pass in [`Solution::passes`].
        pass: usize,
        /// The fitted minus surveyed centre [m, NED].
        offset: [f64; 3],
        /// Its component along the track [m].
        along_track: f64,
        /// Its chi-square (3 degrees of freedom).
        chi2: f64,
    },
    /// Two mountings put different candidates on a sphere and explain the survey nearly as well
    /// (a buoy or a fender of the sphere's size beside it, at the same place relative to every
    /// sphere, or passes that cannot tell them apart).
    Ambiguous(Ambiguity),
    /// The solve left the box the start values and the windows' margin allow.
    OutOfBounds {
        /// Parameter index (0-2 angles, 3-5 lever arm).
        parameter: usize,
        /// Its change from the start [rad or m].
        change: f64,
        /// The allowance [rad or m].
        limit: f64,
    },
    /// The time offset is not the same over the survey: one pass's returns put it elsewhere,
    /// beyond its uncertainty (an INS clock step, a LiDAR clock drifting without PPS).
    ClockInconsistent {
        /// Sphere index.
        sphere: usize,
        /// Index of the pass in [`Solution::passes`].
        pass: usize,
        /// The pass's first and last return.
        start: GpsTime,
        /// ...
        end: GpsTime,
        /// Them in seconds after the first windowed return.
        into: [f64; 2],
        /// The offset its returns give minus the solution's there [s].
        shift: f64,
        /// Its sigma [s].
        sigma: f64,
    },
    /// The time offset steps between passes: the passes from one on put it elsewhere than
    /// those before, together beyond their uncertainty though none alone is (an INS clock
    /// step the stream cannot show, a POS MV's).
    ClockStep {
        /// The first return of the first pass after the step.
        at: GpsTime,
        /// It in seconds after the first windowed return.
        into: f64,
        /// The passes' offset after minus before (weighted means) [s].
        step: f64,
        /// Its sigma [s].
        sigma: f64,
        /// The passes after the step, of those judged.
        after: u16,
        /// The passes judged.
        passes: u16,
    },
    /// The INS clock stepped within the LiDAR data (found in the stream): the poses after it
    /// are off those before, whatever the returns say.
    InsClockStep(InsStep),
    /// The LiDAR clock is not PPS-locked with a valid RMC, and either an unlocked clock is not
    /// allowed or the time offset found does not explain the stamps' disagreement with the RMC.
    LidarClockUntrusted {
        /// The time offset found, the applied one included [s].
        offset_s: f64,
        /// Whether it explains the stamps' RMC disagreement (`None`: no RMC to tell).
        explained: Option<bool>,
        /// The user allowed an unlocked clock.
        allowed: bool,
        /// The stamps minus the RMC time [s], if known.
        rmc_offset_s: Option<f64>,
    },
    /// Under the navigation model: the navigation error steps between two consecutive pieces
    /// of the survey far beyond what the declared model lets it move (an INS that lost its fix
    /// and jumped, a trajectory edited by hand).
    NavigationJump {
        /// The first return after the step.
        at: GpsTime,
        /// The step: N, E, D [m], rotation about N, E, D [rad].
        step: [f64; 6],
        /// Its size in the model's sigmas on its worst axis.
        sigmas: f64,
    },
    /// Under the navigation model: the returns move one sphere's centre from its surveyed one
    /// beyond what its survey's sigma allows, against the other spheres (a centre surveyed
    /// wrong, a sphere moved or swapped since).
    SurveyDisagrees {
        /// Sphere index.
        sphere: usize,
        /// The estimated minus surveyed centre [m, NED].
        moved: [f64; 3],
        /// Its chi-square (3 degrees of freedom) against what the prior leaves unexplained.
        chi2: f64,
        /// The survey's sigma [m].
        sigma: f64,
    },
    /// The last extraction, around a sphere's surveyed centre, kept only a remnant of what the
    /// rounds kept around where its returns put it: somewhere the navigation (or the survey)
    /// puts the sphere elsewhere than its returns do (a GNSS outage the INS status did not
    /// show), and a claim would stand on the few returns that happened to lie on the shell.
    Remnant {
        /// Sphere index.
        sphere: usize,
        /// Returns the last extraction kept.
        kept: usize,
        /// Returns the rounds kept.
        rounds: usize,
    },
    /// The data move a parameter of the mounting from its measured (a-priori) value beyond
    /// what the measurement's sigma allows: the measurement, or the data, is wrong.
    PriorDisagrees {
        /// Parameter index (0-2 angles, 3-5 lever arm).
        parameter: usize,
        /// The solution minus the measured value [rad or m].
        moved: f64,
        /// The measurement's sigma [rad or m].
        sigma: f64,
        /// `moved` over what the prior leaves unexplained (see [`Refusal::SurveyDisagrees`]); the
        /// angles' or the lever arm's chi-square over theirs beyond the consistency threshold.
        z: f64,
    },
    /// The residuals scatter far more than the noise model's white noise (the least squares'
    /// variance factor under the navigation model): somewhere the errors are not the declared
    /// ones.
    Noisier {
        /// The white noise found over the declared (the variance factor's square root).
        factor: f64,
        /// The limit.
        limit: f64,
    },
    /// Neither start of the rounds settled: the first lost a sphere (`lost`, the first of
    /// them) and ended without settling (`first`: a round found fewer than two spheres, or
    /// the rounds reached their limit), and the second, from the a-priori mounting, could not
    /// go on (it left the bounds): no mounting was confirmed by the rounds, whatever the last
    /// extraction around the first start's finds ([`SecondStart`]; a drone's spheres resting
    /// on the grass, whose ground a wrong mounting lifts into their shells).
    Unsettled {
        /// The first sphere the first start lost.
        lost: usize,
        /// How the first start's rounds ended.
        first: Unfinished,
        /// The slices each start's last round detected the spheres in.
        slices: [u32; 2],
    },
    /// The time offset was held, and the data, free to estimate it, put it elsewhere: the
    /// mounting has absorbed the clock error (a lever-arm x of speed x offset).
    TimeOffsetContradicted {
        /// The offset held [s] (on top of what the pipeline applied).
        held: f64,
        /// The offset the data give [s].
        found: f64,
        /// Its sigma [s].
        sigma: f64,
    },
}

/// Per sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereReport {
    /// Returns in the a-priori window.
    pub windowed: usize,
    /// Returns kept (used by the solution).
    pub used: usize,
    /// Returns the rounds' last extraction kept (around where the returns put the sphere);
    /// far more than `used` means the last extraction, around the surveyed centre, found most
    /// of them elsewhere (a navigation the returns contradict).
    pub rounds_kept: usize,
    /// The sphere was found among the clutter (enough returns in detected slices).
    pub found: bool,
    /// Slices of time with window returns, and those where the sphere was detected.
    pub slices: u32,
    /// ...
    pub detected: u32,
    /// Windowed returns by verdict.
    pub verdicts: Tally,
    /// RMS of the kept returns' residuals with the starting values [m].
    pub rms_before: f64,
    /// ... with the solution [m].
    pub rms_after: f64,
    /// Fitted minus surveyed centre [m, NED].
    pub center_offset: Option<Vector3<f64>>,
    /// Slices of its window the first round's consensus explains (with the mounting all
    /// spheres agree on).
    pub agreed: u32,
    /// Why it was not found.
    pub lost: Option<Lost>,
}

/// Why a sphere was not found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lost {
    /// No returns in its window.
    NoReturns,
    /// Nothing sphere-like detected in its window.
    NotDetected,
    /// Sphere-like things detected, none where the mounting the other spheres agree on puts it
    /// (clutter, a decoy, or the sphere hidden).
    Disagrees,
    /// Detected, but fewer returns kept than a sphere needs.
    TooFewReturns,
    /// The solve stopped before any returns were kept (the refusal says why).
    Stopped,
}

/// One pass over one sphere: its window's returns on one course ([`PassFinder`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassReport {
    /// Sphere index.
    pub sphere: u8,
    /// First and last windowed return.
    pub start: GpsTime,
    /// ...
    pub end: GpsTime,
    /// Slices of time, and those where the sphere was detected.
    pub slices: u32,
    /// ...
    pub detected: u32,
    /// Mean inliers of its detections (the detection score).
    pub mean_inliers: f32,
    /// Windowed returns by verdict.
    pub verdicts: Tally,
    /// The sphere's centre fitted (radius fixed) to the pass's kept returns with the solution,
    /// minus the surveyed one [m, NED] (zero with fewer than 10 returns).
    pub centre_offset: [f32; 3],
    /// Its component along the track (the platform's mean horizontal velocity) [m].
    pub along_track: f32,
    /// Its chi-square against its uncertainty (3 degrees of freedom).
    pub chi2: f32,
    /// The time offset the pass's own returns give, minus the solution's at its time [s]
    /// (with the mounting held; 0 with fewer than 10 returns).
    pub dt_shift: f32,
    /// Its 1-sigma [s] (0: not estimated).
    pub dt_sigma: f32,
    /// The platform's course over the pass's kept returns: their mean horizontal velocity's
    /// direction (unit north, east; zero when none was kept or it stood still).
    pub course: [f32; 2],
}

impl PassReport {
    /// A pass over sphere `sphere` starting (and so far ending) at `t`, nothing judged yet.
    pub fn starting(sphere: u8, t: GpsTime) -> Self {
        Self {
            sphere,
            start: t,
            end: t,
            slices: 0,
            detected: 0,
            mean_inliers: 0.0,
            verdicts: [0; 8],
            centre_offset: [0.0; 3],
            along_track: 0.0,
            chi2: 0.0,
            dt_shift: 0.0,
            dt_sigma: 0.0,
            course: [0.0; 2],
        }
    }
}

/// One detect-and-solve round.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Round {
    /// The shell (inlier band) used [m].
    pub tau: f64,
    /// The prior radius used (`None`: the whole window) [m].
    pub prior: Option<f64>,
    /// Returns kept, all spheres.
    pub kept: usize,
    /// Slices where a sphere was detected, all spheres.
    pub detected: u32,
    /// The parameters after the round's solve.
    pub b: Params,
    /// The time offset after the round's solve [s].
    pub dt: f64,
}

/// How the detect-and-solve rounds ended (argmin's `TerminationReason`, for these rounds).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Termination {
    /// No round ran: fewer than two spheres were given.
    #[default]
    NotStarted,
    /// The kept sets barely changed and the parameters stood still.
    Settled,
    /// The kept sets came back to an earlier round's (a few returns at the shell's edge going
    /// in and out).
    Cycle,
    /// A round found fewer than two spheres.
    TooFewSpheres,
    /// The rounds could not go on, for this reason: the spheres are ambiguous, the mounting
    /// left its bounds, or neither start settled.
    Stopped(Refusal),
    /// `Settings::max_rounds` rounds ran without settling.
    MaxRounds,
}

/// Every way the rounds end, in [`Termination`]'s order: its stable name (the report's
/// `termination` key) and its words.
pub const TERMINATIONS: [(&str, &str); 6] = [
    ("not_started", "no round ran (fewer than two spheres given)"),
    ("settled", "the kept returns and the mounting settled"),
    (
        "cycle",
        "the kept returns went round a cycle (returns at the shell's edge in and out)",
    ),
    ("too_few_spheres", "a round found fewer than two spheres"),
    (
        "stopped",
        "the rounds could not go on (ambiguous spheres or a mounting out of bounds)",
    ),
    (
        "max_rounds",
        "the rounds reached their limit without settling",
    ),
];

impl Termination {
    /// Its row of [`TERMINATIONS`].
    fn index(self) -> usize {
        match self {
            Termination::NotStarted => 0,
            Termination::Settled => 1,
            Termination::Cycle => 2,
            Termination::TooFewSpheres => 3,
            Termination::Stopped(_) => 4,
            Termination::MaxRounds => 5,
        }
    }

    /// A stable name (the report's `termination` key).
    pub fn name(self) -> &'static str {
        TERMINATIONS[self.index()].0
    }

    /// In words.
    pub fn words(self) -> &'static str {
        TERMINATIONS[self.index()].1
    }

    /// The words of the termination named `name` (a report's `termination`).
    pub fn words_of(name: &str) -> Option<&'static str> {
        TERMINATIONS.iter().find(|t| t.0 == name).map(|t| t.1)
    }

    /// Why the rounds could not go on, when they were stopped.
    pub fn refusal(self) -> Option<Refusal> {
        match self {
            Termination::Stopped(r) => Some(r),
            _ => None,
        }
    }
}

/// How a start's rounds ended without settling and without being stopped (the first start of
/// a [`Refusal::Unsettled`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unfinished {
    /// A round found fewer than two spheres.
    TooFewSpheres,
    /// The rounds reached their limit.
    MaxRounds,
}

impl Unfinished {
    /// The termination it is.
    pub fn termination(self) -> Termination {
        match self {
            Unfinished::TooFewSpheres => Termination::TooFewSpheres,
            Unfinished::MaxRounds => Termination::MaxRounds,
        }
    }
}

/// The answer and everything known about it.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// The mounting parameters.
    pub b: Params,
    /// The time offset between the clocks on top of what the pipeline applied [s] (INS minus
    /// LiDAR) at `t_ref`; 0 when not estimated.
    pub dt: f64,
    /// Its drift [s/s] (0 when not estimated).
    pub drift: f64,
    /// The time `dt` refers to (the middle of the windowed returns).
    pub t_ref: GpsTime,
    /// The Nelder-Mead stage.
    pub nm: NmResult<P>,
    /// The LM stage (covariance, correlation, conditioning).
    pub lm: Option<LmResult>,
    /// Under the navigation model: the centres and pieces it estimated.
    pub nav: Option<NavFit>,
    /// Eq. 6 at the solution over the kept returns [m].
    pub l1: f64,
    /// Detect-and-solve rounds (both starts' when there was a [`SecondStart`]).
    pub rounds: usize,
    /// How they ended (the answer's start's).
    pub termination: Termination,
    /// What each round did (both starts', in order).
    pub log: heapless::Vec<Round, 32>,
    /// The final shell half-width [m].
    pub shell: f64,
    /// Per sphere.
    pub spheres: heapless::Vec<SphereReport, MAX_TARGETS>,
    /// Per pass over each sphere.
    pub passes: heapless::Vec<PassReport, MAX_PASSES>,
    /// RMS of fitted minus surveyed centres [m].
    pub center_rms: Option<f64>,
    /// Parameters the data determine poorly: with a condition number above
    /// [`Settings::weak_condition`], those with a share above 0.3 of the weakest direction
    /// (the eigenvector of the scaled normal matrix's smallest eigenvalue); the six, then the
    /// time offset. None on a well-conditioned solution.
    pub weak: [bool; P + 1],
    /// With the time offset held: what the data give when free to estimate it (offset, sigma
    /// [s]), the test of the held value.
    pub dt_free: Option<(f64, f64)>,
    /// The residual RMS the noise model predicts [m].
    pub predicted_rms: f64,
    /// The first round's consensus over the slices' candidates.
    pub consensus: Option<Consensus>,
    /// The box the mounting had to stay in.
    pub bounds: Bounds,
    /// Kept returns set aside after the final fit ([`SetAside`]).
    pub set_aside: SetAside,
    /// The rounds' second start, when the first lost a sphere ([`SecondStart`]).
    pub second_start: Option<SecondStart>,
    /// Why the solution is not claimed, if it is not.
    pub refusal: Option<Refusal>,
}

/// Kept returns the final fit set aside (tagged `Undetected`: the slice's detection was not
/// the sphere), each as (returns, stretches of time).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SetAside {
    /// Pieces whose few returns the navigation model could not join to their neighbours (a
    /// step between pieces beyond `max_nav_step_sigmas` that goes with them).
    pub misfit_pieces: (u32, u32),
    /// Isolated stretches (a gap of 2 s either side) of few returns that alone moved the
    /// answer beyond `max_influence_sigmas` of what they can move it by.
    pub influential: (u32, u32),
}

/// The rounds started again from the a-priori mounting, close (each sphere looked for around
/// where it puts it, the widest shell) instead of from the first round's consensus, because
/// the first start's rounds ended with a sphere lost: the slices in which each start's last
/// round detected a sphere, all spheres, and whether the second start's rounds were taken
/// (they detect the spheres in at least 5/4 the slices, and as many spheres).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SecondStart {
    /// The first start's detected slices.
    pub first: u32,
    /// The second's.
    pub second: u32,
    /// The second start's rounds are the answer's.
    pub taken: bool,
}

impl Solution {
    /// The time offset model of the answer.
    pub fn time(&self) -> TimeOffset {
        TimeOffset {
            dt: self.dt,
            drift: self.drift,
            t_ref: self.t_ref,
        }
    }

    /// Nothing solved yet: the start `b0`, the first shell `tau0`.
    pub(super) fn start(b0: &Params, tau0: f64) -> Self {
        Self {
            b: *b0,
            dt: 0.0,
            drift: 0.0,
            t_ref: GpsTime(0),
            nm: NmResult {
                x: b0.deg_m().0,
                f: f64::INFINITY,
                iterations: 0,
                evaluations: 0,
                converged: false,
            },
            lm: None,
            nav: None,
            l1: f64::INFINITY,
            rounds: 0,
            termination: Termination::NotStarted,
            log: heapless::Vec::new(),
            shell: tau0,
            spheres: heapless::Vec::new(),
            passes: heapless::Vec::new(),
            center_rms: None,
            weak: [false; P + 1],
            dt_free: None,
            predicted_rms: 0.0,
            consensus: None,
            bounds: Bounds::none(b0),
            set_aside: SetAside::default(),
            second_start: None,
            refusal: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Termination as T;

    /// The names are the report's contract: distinct, stable, and each has words.
    #[test]
    fn termination_names_are_distinct_and_said() {
        let names: Vec<&str> = super::TERMINATIONS.iter().map(|t| t.0).collect();
        assert_eq!(
            names,
            [
                "not_started",
                "settled",
                "cycle",
                "too_few_spheres",
                "stopped",
                "max_rounds"
            ]
        );
        let stopped = T::Stopped(super::Refusal::TooFewTargets { given: 1 });
        let all = [
            T::NotStarted,
            T::Settled,
            T::Cycle,
            T::TooFewSpheres,
            stopped,
            T::MaxRounds,
        ];
        for (i, a) in all.iter().enumerate() {
            assert_eq!(a.name(), names[i]);
            assert!(!a.words().is_empty());
            assert!(all[i + 1..].iter().all(|b| b.words() != a.words()));
            assert_eq!(T::words_of(a.name()), Some(a.words()));
        }
        assert_eq!(T::default(), T::NotStarted);
        assert_eq!(T::words_of("converged"), None);
        assert_eq!(
            stopped.refusal(),
            Some(super::Refusal::TooFewTargets { given: 1 })
        );
        assert_eq!(T::Settled.refusal(), None);
    }
}

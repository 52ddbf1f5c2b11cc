//! One calibration session, driven the same way by `calibrate` (to convergence, collecting the
//! files again at each time offset) and by the rig (step by step, as batches come): the
//! solver's settings (built here only), the core's workspace kept between solves, the store of
//! windowed returns with the time offset it was aligned at, and one claim rule.

pub mod radius;
mod refusal;
pub mod scratch;

use crate::config::lidar::Lidar;
use crate::config::site::{Site, SiteNoise, DEFAULT_CENTRE_SIGMA_M};
use crate::report::Report;
use scratch::Scratch;
use spherecal::align::window::{Observation, Target};
use spherecal::calib::nav::NavModel;
use spherecal::calib::solve::{ClockFacts, Observe};
use spherecal::calib::{Settings, Solution};
use spherecal::georef::Params;

/// After a converged solve, a store keeps only the windowed returns this close to a sphere's
/// surface (with that solution) [m]: the clutter farther out cannot matter any more, and a
/// long survey's store stays small (the rig's live store, `calibrate`'s collections).
pub const KEEP_NEAR_M: f64 = 1.0;

/// Whether `o` is within [`KEEP_NEAR_M`] of sphere `t`'s surface with the mounting `mount` and
/// the time offset `dt` beyond the store's.
pub fn near(o: &Observation, t: &Target, mount: &spherecal::georef::Mount, dt: f64) -> bool {
    ((o.georef_dt(mount, dt) - t.center).norm() - t.radius).abs() < KEEP_NEAR_M
}

/// What the streams say of the clocks, for the core's checks (one rule for `calibrate` and
/// the rig): the LiDAR clock's trust as its position packets tell it (with the offset
/// `applied_s` the windows were aligned at; `allowed`: `--allow-unlocked-clock`), and the first
/// of the INS clock's `steps` (GPS s, step s) within the LiDAR data's `span` (GPS s; live,
/// from the first data on; all of them without a span).
pub fn clock_facts(
    clock: &crate::state::ClockState,
    steps: &[(f64, f64)],
    span: Option<(f64, f64)>,
    applied_s: f64,
    allowed: bool,
) -> ClockFacts {
    let span = span.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    let mut within = steps
        .iter()
        .filter(move |(t, _)| *t >= span.0 && *t <= span.1);
    let count = within.clone().count();
    ClockFacts {
        lidar_untrusted: (!clock.trusted()).then(|| spherecal::calib::solve::UntrustedLidar {
            rmc_offset_s: clock.rmc_offset_s(),
            applied_s,
            allowed,
        }),
        ins_step: within
            .next()
            .map(|&(at, step)| spherecal::calib::solve::InsStep {
                at_s: at,
                into_s: at - span.0,
                step_s: step,
                count,
            }),
    }
}

/// The time offset moves the windows again when the solve moved it by more than this [s]
/// (the solver's estimate is first order in the offset the poses were taken at).
pub const OFFSET_STEP_S: f64 = 5e-4;
/// ... and while it stays within this of where the session started [s]: beyond, the first
/// order is no guide.
pub const OFFSET_REACH_S: f64 = 2.0;

/// The solver's settings for a survey under the site's own navigation model (its `[ins]`, if
/// it declares one): [`settings_under`].
pub fn settings_for(site: &Site, lidar: Lidar, estimate_dt: bool, margin: f64) -> Settings {
    settings_under(
        site,
        lidar,
        estimate_dt,
        margin,
        site.nav_model().ok().flatten(),
    )
}

/// The solver's settings for a survey under the navigation model `nav` (`None`: white INS
/// errors): the site's noise model (`[noise]`, else the sensors' specified values), the window
/// margin (the bounds the mounting must stay in), the LiDAR's laser period and beam
/// ([`crate::pipeline::Inputs::lidar`]), and whether the time offset is estimated.
///
/// The white noise: the site's `[noise]` if it has one; else, under a model, the INS's errors
/// are in the model and the white noise left is the LiDAR's; without one, the sensors'
/// specified values. The centres: each sphere's declared `sigma_m` under every model; one that
/// declares none, [`DEFAULT_CENTRE_SIGMA_M`] under a model and held at its survey under white
/// errors (the paper's model). White errors with a declared survey sigma solve with the centres
/// as parameters ([`NavModel::WHITE`]).
pub fn settings_under(
    site: &Site,
    lidar: Lidar,
    estimate_dt: bool,
    margin: f64,
    nav: Option<NavModel>,
) -> Settings {
    let mut s = Settings {
        estimate_dt,
        margin,
        footprint: lidar.under(site.lidar.as_ref()).footprint,
        ..Default::default()
    };
    if let Some(f) = lidar.firing_ns {
        s.extract.firing_ns = f;
    }
    let declared = |j: usize| site.sphere.get(j).and_then(|sp| sp.sigma_m);
    s.mount_prior = site.apriori.prior();
    // A declared survey or mounting sigma: the joint least squares carry the priors.
    let surveyed =
        (0..site.sphere.len()).any(|j| declared(j).is_some_and(|v| v > 0.0)) || s.mount_prior.any();
    let wanders = nav.is_some_and(|m| !m.is_white());
    let noise = site.noise.unwrap_or(if wanders {
        SiteNoise {
            attitude_deg: 0.0,
            position_m: 0.0,
            ..SiteNoise::default()
        }
    } else {
        SiteNoise::default()
    });
    s.range_noise = noise.range_m;
    s.attitude_noise = noise.attitude_deg.to_radians();
    s.position_noise = noise.position_m;
    s.nav = match nav {
        Some(m) if wanders => Some(m),
        _ if surveyed => Some(NavModel::WHITE),
        _ => None,
    };
    for (j, c) in s.centre_sigma.iter_mut().enumerate() {
        *c = declared(j).unwrap_or(if wanders { DEFAULT_CENTRE_SIGMA_M } else { 0.0 });
    }
    s
}

/// A calibration under way.
pub struct Session {
    targets: Vec<Target>,
    ids: Vec<String>,
    settings: Settings,
    scratch: Scratch,
    store: Vec<Vec<Observation>>,
    /// The time offset the store was aligned at [ns].
    offset_ns: i64,
    /// Most returns kept per sphere (`add` drops the rest, counted).
    capacity: usize,
    /// Where the navigation model came from (the report's `navigation.source`).
    nav_source: String,
    /// Spans left out [GPS ns], with the returns each took out of the store and why: by hand
    /// (`--exclude`), or set aside by a solve ([`Session::solve`]); every later collection and
    /// batch leaves them out too.
    excluded: Vec<((i64, i64), usize, String)>,
    /// The last solve was refused naming a radius the returns do not show.
    radius_named: bool,
    /// The time offset is known apart from the clocks' words ([`Session::know_offset`]).
    offset_known: bool,
    /// Solves run and radius probes made ([`Session::effort`]).
    solves: u32,
    radius_probes: u32,
}

impl Session {
    /// A session solving with `settings` ([`settings_under`]: made once, never patched), its
    /// navigation model from `nav_source` (the report's `navigation.source`).
    pub fn new(
        targets: Vec<Target>,
        ids: Vec<String>,
        settings: Settings,
        nav_source: &str,
    ) -> Self {
        let n = targets.len();
        Self {
            targets,
            ids,
            settings,
            scratch: Scratch::for_settings(&settings),
            store: vec![Vec::new(); n],
            offset_ns: 0,
            capacity: usize::MAX,
            nav_source: nav_source.into(),
            excluded: Vec::new(),
            radius_named: false,
            offset_known: false,
            solves: 0,
            radius_probes: 0,
        }
    }

    /// Its solves' per-sphere work on two cores ([`Scratch::with_helper`]): for the file
    /// command, whose solve has the machine to itself (the rig's live threads keep theirs).
    pub fn on_two_cores(mut self) -> Self {
        self.scratch = self.scratch.with_helper();
        self
    }

    /// The solves run and the radius probes made so far: `(solves, probes)`.
    pub fn effort(&self) -> (u32, u32) {
        (self.solves, self.radius_probes)
    }

    /// The time offset the store is aligned at is known apart from what the clocks say: given
    /// by the user, or found by a search of the data. Until then a LiDAR clock that is neither
    /// PPS-locked nor gives RMC time leaves the offset unknown, and a refusal names that first.
    pub fn know_offset(&mut self) {
        self.offset_known = true;
    }

    /// The last solve was refused naming a sphere's radius (a site's slip: collecting again at
    /// another time offset cannot mend it).
    pub fn radius_named(&self) -> bool {
        self.radius_named
    }

    /// Leave out the returns within these spans [GPS ns] (`--exclude`), from the store and from
    /// every batch added.
    pub fn exclude(&mut self, spans: &[(i64, i64)]) {
        for &s in spans {
            if !self.excluded.iter().any(|e| e.0 == s) {
                let why = "excluded by hand (--exclude)".to_string();
                self.excluded.push((s, 0, why));
            }
        }
        for (span, n, _) in &mut self.excluded {
            *n += crate::stretches::remove(&mut self.store, *span);
        }
    }

    /// The settings its solves take.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The navigation model the session solves under (`None`: white INS errors).
    pub fn nav(&self) -> Option<NavModel> {
        self.settings.nav
    }

    /// At most `n` returns kept per sphere.
    pub fn with_capacity(mut self, n: usize) -> Self {
        self.capacity = n;
        self
    }

    /// The returns kept so far, per sphere.
    pub fn store(&self) -> &[Vec<Observation>] {
        &self.store
    }

    /// The store, to prune or hand on.
    pub fn store_mut(&mut self) -> &mut [Vec<Observation>] {
        &mut self.store
    }

    /// The time offset the store is aligned at [ns].
    pub fn offset_ns(&self) -> i64 {
        self.offset_ns
    }

    /// A fresh collection, aligned at `offset_ns` (the file command collects the files again
    /// at each offset).
    pub fn replace(&mut self, obs: Vec<Vec<Observation>>, offset_ns: i64) {
        self.store = obs;
        self.store.resize(self.targets.len(), Vec::new());
        self.offset_ns = offset_ns;
        for (span, n, _) in &mut self.excluded {
            *n = crate::stretches::remove(&mut self.store, *span);
        }
    }

    /// One sphere's batch aligned at `offset_ns`, moved to the store's offset first; returns
    /// how many were dropped (the sphere's store full, or the sphere unknown).
    pub fn add(&mut self, sphere: usize, obs: &[Observation], offset_ns: i64) -> usize {
        let d = (self.offset_ns - offset_ns) as f64 * 1e-9;
        let Some(v) = self.store.get_mut(sphere) else {
            return obs.len();
        };
        if d.abs() > OFFSET_REACH_S {
            return obs.len();
        }
        let k = obs.len().min(self.capacity.saturating_sub(v.len()));
        let at = v.len();
        v.extend_from_slice(&obs[..k]);
        for (span, n, _) in &mut self.excluded {
            let before = v.len();
            v.retain(|o| o.time.0 < span.0 || o.time.0 > span.1);
            *n += before - v.len();
        }
        let at = at.min(v.len());
        if d != 0.0 {
            v[at..].iter_mut().for_each(|o| o.rebase(d));
        }
        obs.len() - k
    }

    /// Move the store to the offset `to_ns` without collecting again (the rig): first order in
    /// the platform's velocity and turn rate, as the solver's own estimate is.
    pub fn rebase(&mut self, to_ns: i64) {
        rebase_or_clear(&mut self.store, to_ns - self.offset_ns);
        self.offset_ns = to_ns;
    }

    /// Solve on the store from `b0` with what the streams say of the clocks (`clocks`, their
    /// times relative to the store's offset), telling `watch` of the rounds. The report's time
    /// offset includes the store's.
    pub fn solve(
        &mut self,
        b0: &Params,
        clocks: ClockFacts,
        watch: &mut impl Observe,
    ) -> (Solution, Report) {
        self.solve_for(b0, clocks, true, watch)
    }

    /// As [`Session::solve`] for one start of a time-offset search
    /// ([`crate::calibrate::search`]): only where it converged, what it kept and its RMS are
    /// read, so a refusal is left as it is (no radius named, no stretch set aside: those are
    /// for the collection the search picks, at up to 13 more solves for each start refused).
    pub fn solve_start(
        &mut self,
        b0: &Params,
        clocks: ClockFacts,
        watch: &mut impl Observe,
    ) -> (Solution, Report) {
        self.solve_for(b0, clocks, false, watch)
    }

    /// The solve; a refusal looked into (a radius, then a stretch set aside) when `mend`.
    fn solve_for(
        &mut self,
        b0: &Params,
        clocks: ClockFacts,
        mend: bool,
        watch: &mut impl Observe,
    ) -> (Solution, Report) {
        // A LiDAR clock without PPS runs on its own crystal: its drift is estimated with the
        // offset (one rule for `calibrate` and the rig).
        let mut s = self.settings;
        s.estimate_drift = s.estimate_dt && clocks.lidar_untrusted.is_some();
        s.clocks = clocks;
        // A held offset is tested against a free solve first (the store is left as the held
        // solve leaves it): the held solve's own extraction keeps what agrees with the held
        // value, and the free fit on those returns alone may not see what the rest show.
        let free = (mend && !s.estimate_dt)
            .then(|| self.free_offset(b0, &s))
            .flatten();
        self.solves += 1;
        let (mut sol, mut rep) = solve_report_in(
            &self.targets,
            &self.ids,
            &mut self.store,
            b0,
            &s,
            &mut self.scratch,
            watch,
        );
        if let Some((found, sigma)) = free.filter(|_| sol.refusal.is_none()) {
            sol.refusal = s.held_contradicted(sol.dt, found, sigma);
            if sol.refusal.is_some() {
                sol.dt_free = Some((found, sigma));
                let ms = rep.solve_ms;
                rep = Report::of(&sol, &self.ids, b0, &s, self.scratch.nav_pieces(), ms);
            }
        }
        self.radius_named = false;
        if !rep.converged && mend {
            (sol, rep) = self.look_into(b0, &s, sol, rep);
        }
        rep.set_aside = self
            .excluded
            .iter()
            .map(|((a, b), n, why)| crate::stretches::SetAsideSpan {
                from_gps_s: *a as f64 * 1e-9,
                to_gps_s: *b as f64 * 1e-9,
                returns: *n,
                why: why.clone(),
            })
            .collect();
        rep.time_offset_s += self.offset_ns as f64 * 1e-9;
        if let Some(n) = rep.navigation.as_mut() {
            n.source = self.nav_source.clone();
        }
        (sol, rep)
    }

    /// The time offset a free solve of the store finds and its sigma [s] (None: it did not
    /// converge, or was refused).
    fn free_offset(&mut self, b0: &Params, held: &Settings) -> Option<(f64, f64)> {
        let mut s = *held;
        s.estimate_dt = true;
        s.estimate_drift = s.clocks.lidar_untrusted.is_some();
        self.solves += 1;
        let mut slices: Vec<&mut [Observation]> =
            self.store.iter_mut().map(|v| v.as_mut_slice()).collect();
        let ws = &mut self.scratch.workspace();
        let sol =
            spherecal::calib::solve::solve_watched(&self.targets, &mut slices, b0, &s, ws, &mut ());
        let lm = sol.lm.filter(|l| l.converged && sol.refusal.is_none())?;
        (lm.sigma_dt > 0.0 && sol.dt.is_finite()).then_some((sol.dt, lm.sigma_dt))
    }

    /// The offset the windows should be aligned at next [ns], when the solve moved it enough to
    /// matter ([`OFFSET_STEP_S`]) with the least squares converged, within [`OFFSET_REACH_S`]
    /// of zero (where a session starts; `calibrate`, which starts where its search put it, asks
    /// [`next_offset`] itself); `None` when the offset is held or settled.
    pub fn wants_offset(&self, sol: &Solution) -> Option<i64> {
        self.offset_after(sol.dt, sol.lm.is_some_and(|l| l.converged))
    }

    /// [`Session::wants_offset`] for a solve that moved the offset by `dt` [s].
    fn offset_after(&self, dt: f64, converged: bool) -> Option<i64> {
        next_offset(
            self.offset_ns as f64 * 1e-9,
            0.0,
            self.settings.estimate_dt,
            dt,
            converged,
        )
        .map(|t| (t * 1e9).round() as i64)
    }

    /// The store, taken out (the file command's last collection, for its outputs).
    pub fn take_store(&mut self) -> Vec<Vec<Observation>> {
        let n = self.targets.len();
        std::mem::replace(&mut self.store, vec![Vec::new(); n])
    }

    /// The one claim rule: the report is claimed when the core's checks (the clocks' among
    /// them) passed; it is enough when, besides, every sphere was seen in passes both ways and
    /// the goal is met ([`crate::verdict::assess`]).
    pub fn claim(
        &self,
        sol: &Solution,
        rep: &Report,
        goal: Option<&crate::config::goal::Goal>,
        predicted: Option<&[f64; 7]>,
        advice: Option<&crate::plan::live::LiveAdvice>,
    ) -> crate::verdict::Verdict {
        let cov = crate::verdict::coverage(&self.ids, &self.store, sol);
        crate::verdict::assess(rep, &cov, goal, predicted, advice)
    }
}

/// The one rule for moving the windows' time offset [s]: from `aligned` (what the windows
/// were made at) by the solve's `dt` when it was estimated, the least squares converged, the
/// move exceeds [`OFFSET_STEP_S`] and the result stays within [`OFFSET_REACH_S`] of `start`.
pub fn next_offset(
    aligned: f64,
    start: f64,
    estimated: bool,
    dt: f64,
    converged: bool,
) -> Option<f64> {
    let next = aligned + dt;
    (estimated
        && converged
        && dt.is_finite()
        && dt.abs() > OFFSET_STEP_S
        && (next - start).abs() <= OFFSET_REACH_S)
        .then_some(next)
}

/// Observations aligned at one time offset, moved to one larger by `d_ns`
/// ([`Observation::rebase`]); beyond [`OFFSET_REACH_S`] the first order is no guide and they
/// are dropped.
fn rebase_or_clear(store: &mut [Vec<Observation>], d_ns: i64) {
    let d = d_ns as f64 * 1e-9;
    for v in store {
        if d.abs() > OFFSET_REACH_S {
            v.clear();
        } else {
            v.iter_mut().for_each(|o| o.rebase(d));
        }
    }
}

/// Solve and build the report from collected observations (with a scratch of its own: see
/// [`solve_report_in`] to keep one between solves).
pub fn solve_report(
    targets: &[Target],
    ids: &[String],
    obs: &mut [Vec<Observation>],
    b0: &Params,
    s: &Settings,
) -> (Solution, Report) {
    solve_report_in(
        targets,
        ids,
        obs,
        b0,
        s,
        &mut Scratch::for_settings(s),
        &mut (),
    )
}

/// [`solve_report`] in a lent scratch (the core's workspace, ~9 MB: the rig keeps one for all
/// its solves), telling `watch` of the rounds.
pub fn solve_report_in(
    targets: &[Target],
    ids: &[String],
    obs: &mut [Vec<Observation>],
    b0: &Params,
    s: &Settings,
    scratch: &mut Scratch,
    watch: &mut impl spherecal::calib::solve::Observe,
) -> (Solution, Report) {
    let mut slices: Vec<&mut [Observation]> = obs.iter_mut().map(|v| v.as_mut_slice()).collect();
    let t0 = std::time::Instant::now();
    let sol = spherecal::calib::solve::solve_watched(
        targets,
        &mut slices,
        b0,
        s,
        &mut scratch.workspace(),
        watch,
    );
    let solve_ms = t0.elapsed().as_secs_f64() * 1e3;
    let report = Report::of(&sol, ids, b0, s, scratch.nav_pieces(), solve_ms);
    (sol, report)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn session() -> Session {
        let t = Target {
            center: nalgebra::Vector3::zeros(),
            radius: 0.2,
        };
        Session::new(
            vec![t, t],
            vec!["S1".into(), "S2".into()],
            Settings::default(),
            "white",
        )
        .with_capacity(3)
    }

    #[test]
    fn add_keeps_the_capacity_and_counts_the_rest() {
        let mut s = session();
        let o = Observation::default();
        assert_eq!(s.add(0, &[o; 2], 0), 0);
        assert_eq!(s.add(0, &[o; 2], 0), 1);
        assert_eq!(s.add(7, &[o; 2], 0), 2, "an unknown sphere");
        assert_eq!(s.store()[0].len(), 3);
        // A batch aligned elsewhere beyond the first order's reach is dropped and counted.
        assert_eq!(s.add(1, &[o; 2], 3_000_000_000), 2);
        assert!(s.store()[1].is_empty());
    }

    #[test]
    fn the_offset_moves_when_it_matters_and_within_reach() {
        let mut s = session();
        s.replace(vec![Vec::new(), Vec::new()], 100_000_000);
        assert_eq!(s.offset_after(0.0004, true), None, "settled");
        assert_eq!(s.offset_after(0.02, false), None, "not converged");
        assert_eq!(s.offset_after(0.02, true), Some(120_000_000));
        assert_eq!(s.offset_after(1.95, true), None, "beyond reach of zero");
        assert_eq!(s.offset_after(1.85, true), Some(1_950_000_000));
        s.rebase(120_000_000);
        assert_eq!(s.offset_ns(), 120_000_000);
        assert_eq!(s.offset_after(-0.001, true), Some(119_000_000));
        let mut held = session();
        held.settings.estimate_dt = false;
        assert_eq!(held.offset_after(0.02, true), None, "held");
    }
}

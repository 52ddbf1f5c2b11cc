//! After the rounds: the last extraction around the surveyed spheres and the final least
//! squares (the answer, its uncertainty, the held offset tested).

#[allow(unused_imports)]
use super::*;
use crate::calib::nav::{cut_for, refine as refine_nav, Piece};

impl Rounds {
    /// The last extraction: around the surveyed spheres, in the slices where the sphere is
    /// detected near them, attachments (a stand, a deck) rejected; spheres with too few returns
    /// are not found. Returns each sphere's kept count (the kept ones first in `obs`) and its
    /// verdict tallies; the passes get theirs.
    pub(super) fn last_extraction(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        passes: &mut [PassReport],
    ) -> ([usize; MAX_TARGETS], [[u32; 8]; MAX_TARGETS]) {
        let (targets, s) = (d.targets, d.s);
        let (obs, ws) = (&mut *d.obs, &mut *d.ws);
        let dirs = Directions::default();
        let tau = self.tau;
        let mount = Mount::from_params(&Params(self.b));
        let mut used = [0usize; MAX_TARGETS];
        let mut tallies = [[0u32; 8]; MAX_TARGETS];
        for j in 0..targets.len() {
            let v = &mut obs[j][..self.active[j]];
            extract::georeference(v, &targets[j], &mount, &self.time);
            let mine = {
                let a = passes.partition_point(|p| usize::from(p.sphere) < j);
                let b = passes.partition_point(|p| usize::from(p.sphere) <= j);
                &mut passes[a..b]
            };
            let (_, sl, det) = extract_sphere(
                v,
                &targets[j],
                tau,
                Some(self.prior.unwrap_or(3.0 * tau).max(3.0 * tau)),
                true,
                ws.grid,
                ws.keys,
                &dirs,
                &s.extract,
                &s.noise(),
                Some(&mut *mine),
            );
            self.counts[j] = (sl, det);
            // What meets the sphere (its stand, a deck) is recognised around the surveyed centre.
            let kept = v
                .iter()
                .filter(|o| o.work.verdict == ReturnClass::Kept as u8)
                .count() as u32;
            extract::reject_attachments(v, targets[j].radius, tau, &dirs, (kept / 33).max(8));
            extract::reject_touching_plane(v, targets[j].radius, tau, (kept / 10).max(12));
            used[j] = partition(obs[j]);
            if used[j] < s.min_points {
                extract::tag(obs[j], ReturnClass::NotFound);
                used[j] = 0;
            }
            for o in obs[j].iter() {
                let k = usize::from(o.work.verdict).min(7);
                tallies[j][k] += 1;
                if let Some(p) = pass_of(mine, o.time) {
                    p.verdicts[k] += 1;
                    if k == ReturnClass::Kept as usize {
                        p.course[0] += o.velocity.x;
                        p.course[1] += o.velocity.y;
                    }
                }
            }
            for p in mine.iter_mut() {
                if p.detected > 0 {
                    p.mean_inliers /= p.detected as f32;
                }
                let [n, e] = p.course;
                let speed = libm::sqrtf(n * n + e * e);
                p.course = if speed > 0.0 {
                    [n / speed, e / speed]
                } else {
                    [0.0; 2]
                };
            }
        }
        (used, tallies)
    }

    /// Least squares on the kept returns (with at least two spheres found); with the offset held,
    /// the same returns with it free test the held value. Sets the answer and eq. 6 at it.
    pub(super) fn final_fit(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        used: &[usize],
        found: usize,
        sol: &mut Solution,
    ) {
        let (targets, s, obs) = (d.targets, d.s, &*d.obs);
        let nav = &mut *d.ws.nav;
        // Under the navigation model the weights are the white noise's, absolute (the priors
        // are in metres and radians).
        let w = match s.nav {
            Some(_) => Some(s.noise()),
            None => weights(obs, used, s),
        };
        let fit =
            |pb: &Problem<'_>, b: &[f64; P], iter: usize, clock: Clock, nav: &mut [Piece]| match &s
                .nav
            {
                Some(model) => {
                    let m = cut_for(pb, model, nav);
                    let (l, f) = refine_nav(
                        pb,
                        b,
                        model,
                        &s.centre_sigma,
                        &mut nav[..m],
                        iter,
                        s.cluster_ns,
                        clock,
                    );
                    (l, Some(f))
                }
                None => (refine(pb, b, iter, s.cluster_ns, clock), None),
            };
        let lm = (found >= 2).then(|| {
            with_problem(targets, obs, used, 1, self.time, w, |pb| {
                fit(pb, &self.b, s.lm_iter, s.clock(), nav)
            })
        });
        let lm = lm.map(|(l, f)| {
            sol.nav = f;
            l
        });
        if let Some(l) = &lm {
            self.b = l.b;
            self.time.dt = l.dt;
            self.time.drift = l.drift;
        }
        if let (false, Some(l)) = (s.estimate_dt, &lm) {
            // Where the data move the offset, and its sigma at the held solution (no iteration:
            // the motion model is first order in the offset, exact at the held value and not far
            // from it). The free fit need not converge: far from the truth it stalls on the way (a
            // 0.3 s error stops after 0.14 s, its own sigma inflated by the misfit), which is
            // evidence enough against the held value.
            let free_clock = Clock {
                dt: true,
                drift: s.estimate_drift,
            };
            let (free, at_held) = with_problem(targets, obs, used, 1, self.time, w, |pb| {
                (
                    fit(pb, &l.b, s.lm_iter, free_clock, nav).0,
                    fit(pb, &l.b, 0, free_clock, nav).0,
                )
            });
            let sigma = at_held.sigma_dt;
            if free.dt.is_finite() && sigma.is_finite() && sigma > 0.0 {
                sol.dt_free = Some((free.dt, sigma));
            }
        }
        sol.b = Params(self.b);
        sol.dt = self.time.dt;
        sol.drift = self.time.drift;
        sol.t_ref = self.time.t_ref;
        sol.lm = lm;
        sol.l1 = with_problem(targets, obs, used, 1, self.time, None, |pb| pb.l1(&self.b));
    }
}

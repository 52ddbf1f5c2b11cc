//! The first round, from afar: every sphere-like candidate of every slice, the consensus over
//! them for the mounting and the candidates that are the spheres.

use super::outcome::{PassReport, Refusal, Termination};
use super::rounds::{Data, Rounds};
use super::settings::Settings;
use super::{groups, side_by_side, Lane};
use crate::align::window::{Observation, Target, MAX_TARGETS};
use crate::calib::consensus::{consensus, Candidate, Consensus, Search};
use crate::calib::extract::{self, Directions, ReturnClass};
use crate::calib::objective::TimeOffset;
use crate::georef::{Mount, Params};

impl Rounds {
    /// The first round: every sphere-like candidate of every slice ([`extract::detect_all`]), the
    /// consensus over them ([`consensus`]) for the mounting and the candidates that are the spheres,
    /// and the returns within `tau` of those kept. The consensus mounting becomes the rounds'
    /// parameters; an ambiguous sphere ends the rounds. `None` when fewer than two spheres are
    /// agreed on.
    pub(super) fn first_extract(
        &mut self,
        d: &mut Data<'_, '_, '_>,
        passes: &[PassReport],
    ) -> Option<[usize; MAX_TARGETS]> {
        let (targets, s) = (d.targets, d.s);
        let n = targets.len();
        let nc = self.candidates(d, passes);
        let ws = &mut *d.ws;
        let mut search = Search {
            cands: ws.cands.room(nc),
            targets,
            time: self.time,
            bounds: self.bounds,
            settings: s.consensus,
        };
        let Some(c) = consensus(&mut search, &self.b, ws.idx.room(nc)) else {
            // Not three candidates apart, or no mounting within the bounds explains any.
            self.consensus = Some(Consensus {
                b: self.b,
                score: 0.0,
                support: [0; MAX_TARGETS],
                slices: core::array::from_fn(|j| self.counts[j].1),
                rms: f64::NAN,
                hypotheses: 0,
                ambiguous: None,
            });
            return None;
        };
        self.consensus = Some(c);
        if let Some(a) = c.ambiguous {
            self.ended = Some(Termination::Stopped(Refusal::Ambiguous(a)));
            return None;
        }
        let mut kept = self.keep_chosen(d, nc);
        self.b = c.b;
        if (0..n).filter(|&j| kept[j] >= s.min_points).count() < 2 {
            return None;
        }
        for (j, v) in d.obs.iter_mut().enumerate() {
            if kept[j] < s.min_points {
                kept[j] = 0;
                extract::tag(&mut v[..self.active[j]], ReturnClass::Undetected);
            }
        }
        Some(kept)
    }

    /// Every sphere-like candidate of every slice ([`extract::detect_all`]) into the scratch, in
    /// the order of their spheres and slices, each with its slice's pass and range; each
    /// sphere's slices and those with a candidate counted. Returns how many. Two groups of
    /// spheres side by side with a helper, the second's candidates then after the first's.
    fn candidates(&mut self, d: &mut Data<'_, '_, '_>, passes: &[PassReport]) -> usize {
        let n = d.targets.len();
        let g = Gather {
            targets: d.targets,
            s: d.s,
            dirs: Directions::default(),
            mount: Mount::from_params(&Params(self.b)),
            time: self.time,
            tau: self.tau,
            placed: self.placed,
            passes,
        };
        let k = groups(d.ws, &self.active[..n]);
        let (oa, ob) = d.obs.split_at_mut(k);
        let (aa, ab) = self.active[..n].split_at(k);
        let (ca, cb) = self.counts[..n].split_at_mut(k);
        let (mut na, mut nb) = (0, 0);
        side_by_side(
            d.ws,
            |lane| na = g.spheres(0, oa, aa, ca, lane),
            |lane| nb = g.spheres(k, ob, ab, cb, lane),
        );
        let ws = &mut *d.ws;
        match ws.helper.as_mut() {
            Some(h) if nb > 0 => {
                let theirs = h.cands.room(nb);
                let all = ws.cands.room(na + theirs.len());
                let fit = all.len().saturating_sub(na);
                if let (Some(to), Some(from)) = (all.get_mut(na..), theirs.get(..fit)) {
                    to.copy_from_slice(from);
                }
                all.len()
            }
            _ => na,
        }
    }

    /// Each sphere's returns within `tau` of its chosen candidates (the first `nc` of the
    /// scratch, in the order of their spheres and slices; of a slice's, the last chosen): the
    /// count kept.
    fn keep_chosen(&self, d: &mut Data<'_, '_, '_>, nc: usize) -> [usize; MAX_TARGETS] {
        let (targets, noise) = (d.targets, d.s.noise());
        let cands = &*d.ws.cands.room(nc);
        let mut kept = [0usize; MAX_TARGETS];
        let mut k = 0;
        while let Some(first) = cands.get(k) {
            let mut chosen = None;
            while let Some(c) = cands
                .get(k)
                .filter(|c| c.sphere == first.sphere && c.slice == first.slice)
            {
                if c.chosen {
                    chosen = Some(c.detected);
                }
                k += 1;
            }
            let j = usize::from(first.sphere);
            let slice = (first.at as usize)..(first.at + first.len) as usize;
            let (Some(at), Some(t)) = (chosen, targets.get(j)) else {
                continue;
            };
            if let Some(v) = d.obs.get_mut(j).and_then(|v| v.get_mut(slice)) {
                kept[j] += extract::keep(v, at, t.radius, self.tau, &noise);
            }
        }
        kept
    }
}

/// What the first round gathers its candidates with.
struct Gather<'g> {
    targets: &'g [Target],
    s: &'g Settings,
    dirs: Directions,
    mount: Mount,
    time: TimeOffset,
    tau: f64,
    /// The returns are georeferenced at `mount` already.
    placed: bool,
    passes: &'g [PassReport],
}

impl Gather<'_> {
    /// The candidates of spheres `first..` (`obs`, with `active` returns taking part) into
    /// `lane`'s room; each one's slices and those with a candidate into `counts`. Returns how
    /// many.
    fn spheres(
        &self,
        first: usize,
        obs: &mut [&mut [Observation]],
        active: &[usize],
        counts: &mut [(u32, u32)],
        lane: &mut Lane<'_>,
    ) -> usize {
        let mut nc = 0;
        let mut found = extract::Candidates::new();
        for (i, v) in obs.iter_mut().enumerate() {
            let j = first + i;
            let (Some(t), Some(&n)) = (self.targets.get(j), active.get(i)) else {
                continue;
            };
            let v = &mut v[..n];
            if !self.placed {
                extract::georeference(v, t, &self.mount, &self.time);
            }
            let (mut slices, mut detected) = (0, 0);
            let mut cursor = extract::SliceCursor::default();
            while let Some(sl) = cursor.next(v) {
                slices += 1;
                // Tagged slice by slice, while it is at hand.
                extract::tag(&mut v[sl.clone()], ReturnClass::Undetected);
                let slice = &v[sl.clone()];
                extract::detect_all(
                    slice,
                    lane.keys,
                    t.radius,
                    self.tau,
                    None,
                    lane.grid,
                    &self.dirs,
                    &self.s.extract,
                    extract::MAX_CANDIDATES,
                    &mut found,
                );
                detected += u32::from(!found.is_empty());
                // The pose of the slice's middle return carries its candidates.
                let rep = &slice[slice.len() / 2];
                let group = self
                    .passes
                    .iter()
                    .rposition(|p| usize::from(p.sphere) == j && p.start <= rep.time)
                    .unwrap_or(0);
                for d in &found {
                    let Some(c) = Candidate::new(d.center, rep, t, &self.mount, &self.time) else {
                        continue;
                    };
                    if let Some(slot) = lane.cands.room(nc + 1).get_mut(nc) {
                        *slot = Candidate {
                            sphere: j as u8,
                            group: group as u16,
                            slice: rep.work.slice,
                            at: sl.start as u32,
                            len: sl.len() as u32,
                            inliers: d.inliers,
                            ..c
                        };
                        nc += 1;
                    }
                }
            }
            if let Some(c) = counts.get_mut(i) {
                *c = (slices, detected);
            }
        }
        nc
    }
}

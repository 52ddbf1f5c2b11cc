//! The first round, from afar: every sphere-like candidate of every slice, the consensus over
//! them for the mounting and the candidates that are the spheres.

use super::outcome::{PassReport, Refusal, Termination};
use super::rounds::{Data, Rounds};
use crate::align::window::MAX_TARGETS;
use crate::calib::consensus::{consensus, Candidate, Consensus, Search};
use crate::calib::extract::{self, Directions, ReturnClass};
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
        let (obs, ws) = (&mut *d.obs, &mut *d.ws);
        let n = targets.len();
        let dirs = Directions::default();
        let mount = Mount::from_params(&Params(self.b));
        let mut nc = 0;
        let mut found = extract::Candidates::new();
        for j in 0..n {
            let v = &mut obs[j][..self.active[j]];
            if !self.placed {
                extract::georeference(v, &targets[j], &mount, &self.time);
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
                    ws.keys,
                    targets[j].radius,
                    self.tau,
                    None,
                    ws.grid,
                    &dirs,
                    &s.extract,
                    extract::MAX_CANDIDATES,
                    &mut found,
                );
                detected += u32::from(!found.is_empty());
                // The pose of the slice's middle return carries its candidates.
                let rep = &slice[slice.len() / 2];
                let group = passes
                    .iter()
                    .rposition(|p| usize::from(p.sphere) == j && p.start <= rep.time)
                    .unwrap_or(0);
                for d in &found {
                    let Some(c) = Candidate::new(d.center, rep, &targets[j], &mount, &self.time)
                    else {
                        continue;
                    };
                    if let Some(slot) = ws.cands.get_mut(nc) {
                        *slot = Candidate {
                            sphere: j as u8,
                            group: group as u16,
                            slice: rep.work.slice,
                            inliers: d.inliers,
                            ..c
                        };
                        nc += 1;
                    }
                }
            }
            self.counts[j] = (slices, detected);
        }
        let mut search = Search {
            cands: &mut ws.cands[..nc],
            targets,
            time: self.time,
            bounds: self.bounds,
            settings: s.consensus,
        };
        let Some(c) = consensus(&mut search, &self.b, ws.idx) else {
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

    /// Each sphere's returns within `tau` of its chosen candidates (the first `nc` of the
    /// scratch; slices and candidates are in one order): the count kept.
    fn keep_chosen(&self, d: &mut Data<'_, '_, '_>, nc: usize) -> [usize; MAX_TARGETS] {
        let (targets, noise) = (d.targets, d.s.noise());
        let cands = &d.ws.cands[..nc];
        let mut kept = [0usize; MAX_TARGETS];
        let mut k = 0;
        for (j, t) in targets.iter().enumerate() {
            let v = &mut d.obs[j][..self.active[j]];
            let mut cursor = extract::SliceCursor::default();
            while let Some(sl) = cursor.next(v) {
                let id = v[sl.start + sl.len() / 2].work.slice;
                while k < nc
                    && (usize::from(cands[k].sphere) < j
                        || (usize::from(cands[k].sphere) == j && cands[k].slice < id))
                {
                    k += 1;
                }
                let mut chosen = None;
                while k < nc && usize::from(cands[k].sphere) == j && cands[k].slice == id {
                    if cands[k].chosen {
                        chosen = Some(cands[k].detected);
                    }
                    k += 1;
                }
                if let Some(at) = chosen {
                    kept[j] += extract::keep(&mut v[sl], at, t.radius, self.tau, &noise);
                }
            }
        }
        kept
    }
}

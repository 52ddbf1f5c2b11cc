//! The rounds' second start. From afar the first round trusts the consensus of the slices'
//! sphere-like candidates; where the spheres are seen by a few returns per slice (a drone's
//! VLP-16 from 40 m) that consensus can rest on a handful of slices of two or three spheres
//! and pick a mounting tenths of a metre and a degree off whose rounds then keep only what
//! fits it: the other spheres are lost and the answer, though self-consistent, explains a
//! fraction of the data (a drone-noisy trial: 23 slices against the 72 the truth's mounting
//! explains, pitch 5 sigma off, "converged"). When a sphere is lost, the rounds start again
//! from the a-priori mounting, close: each sphere looked for around where it puts it (the
//! widest shell, three times it as the prior); the start whose last round detects the spheres
//! in more slices is the answer's.

use super::outcome::{PassReport, Refusal, Round, SecondStart, Termination, Unfinished};
use super::rounds::{run_rounds, Data, Rounds};
use super::{reach, time_order};
use crate::align::window::MAX_TARGETS;
use crate::calib::extract;
use crate::calib::solve::rounds::Observe;
use crate::georef::{Mount, Params};

/// The second start's rounds are taken when they detect the spheres in at least this share
/// of the first start's slices (and find as many spheres).
const BETTER: (u32, u32) = (5, 4);

/// Run the rounds again from `b0`, close; keep in `r` the start that explains more, its log
/// and count holding both starts' rounds (and the first start's Nelder-Mead work). The
/// returns are left as the kept start's rounds see them (its active set again at its last
/// mounting when the first start stays). Both starts, and when neither settled the refusal
/// ([`Refusal::Unsettled`]: the first start's termination stays the answer's).
pub(super) fn second_start(
    d: &mut Data<'_, '_, '_>,
    passes: &[PassReport],
    r: &mut Rounds,
    b0: &Params,
    windowed: [usize; MAX_TARGETS],
    watch: &mut impl Observe,
) -> (SecondStart, Option<Refusal>) {
    let n = d.targets.len();
    let widest =
        d.s.extract
            .tau0
            .max(0.5 * d.targets.iter().map(|t| t.radius).fold(0.0, f64::max));
    in_time_order(d, &windowed);
    let mut again = Rounds::init(b0, windowed, widest, r.bounds, r.time.t_ref);
    again.prior = Some(3.0 * widest);
    let after = r.round;
    run_rounds(
        d,
        passes,
        &mut again,
        &mut Continued {
            inner: watch,
            after,
        },
    );
    let mut log = r.log.clone();
    for entry in &again.log {
        let _ = log.push(*entry);
    }
    let rounds = r.round + again.round;
    let slices = |r: &Rounds| r.counts[..n].iter().map(|c| c.1).sum::<u32>();
    let found = |r: &Rounds| r.kept[..n].iter().filter(|&&k| k > 0).count();
    let (first, second) = (slices(r), slices(&again));
    let taken = again.stopped().is_none()
        && second * BETTER.1 >= first * BETTER.0
        && found(&again) >= found(r);
    let both = SecondStart {
        first,
        second,
        taken,
    };
    let first_settled = matches!(r.ended, Some(Termination::Settled | Termination::Cycle));
    let mut unsettled = None;
    if taken {
        again.nm = r.nm;
        *r = again;
    } else if again.stopped().is_some() && !first_settled {
        // Neither start settled: nothing confirms the first start's mounting. (Not settled
        // and not stopped: a round found fewer than two spheres, or the limit.)
        let first_end = match r.ended {
            Some(Termination::TooFewSpheres) => Unfinished::TooFewSpheres,
            _ => Unfinished::MaxRounds,
        };
        unsettled = Some(Refusal::Unsettled {
            lost: (0..n)
                .find(|&j| windowed[j] > 0 && r.kept[j] == 0)
                .unwrap_or(0),
            first: first_end,
            slices: [first, second],
        });
    }
    r.log = log;
    r.round = rounds;
    watch.ended(r.ended.unwrap_or_default(), r.round);
    if taken {
        return (both, unsettled);
    }
    // The first start's returns as its rounds left them: every windowed return in time order
    // at its last mounting, then its rule for the returns still taking part.
    in_time_order(d, &windowed);
    let mount = Mount::from_params(&Params(r.b));
    for (j, (&w, t)) in windowed.iter().zip(d.targets).enumerate() {
        let v = &mut d.obs[j][..w];
        let far = r.prior.map(|p| reach(p, r.tau));
        r.active[j] = extract::place_and_compact(v, t, &mount, &r.time, far);
    }
    (both, unsettled)
}

/// Every windowed return back in time order (as [`prepare`] sorted them: a slice's returns
/// together), whatever the rounds' compaction left past the returns taking part.
fn in_time_order(d: &mut Data<'_, '_, '_>, windowed: &[usize; MAX_TARGETS]) {
    for (v, &w) in d.obs.iter_mut().zip(windowed) {
        v[..w].sort_unstable_by_key(time_order);
    }
}

/// The watch over the second start: its rounds numbered on from the first start's, its end
/// told once the start is chosen.
struct Continued<'w, W: Observe> {
    inner: &'w mut W,
    after: usize,
}

impl<W: Observe> Observe for Continued<'_, W> {
    fn round(&mut self, n: usize, r: &Round) {
        self.inner.round(self.after + n, r);
    }
    fn ended(&mut self, _: Termination, _: usize) {}
}

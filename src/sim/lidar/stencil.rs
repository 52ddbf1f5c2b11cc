//! The footprint's sub-rays: where a beam is traced as more than its axis.

/// Five sub-rays of the footprint: offsets in units of the 1-sigma beam half-angle (along,
/// across) and weights.
pub(super) const FIVE: [(f64, f64, f64); 5] = [
    (0.0, 0.0, 0.4),
    (1.8257, 0.0, 0.15),
    (-1.8257, 0.0, 0.15),
    (0.0, 1.8257, 0.15),
    (0.0, -1.8257, 0.15),
];

/// Spacing of the footprint's sub-rays [1-sigma beam half-angles].
const STEP: f64 = 0.5;
/// The footprint's sub-rays reach this many steps from the centre.
const REACH: i32 = 5;
/// Sub-rays of the footprint: the grid points within `REACH` steps.
pub(crate) const MAX_SUBS: usize = 81;

/// Sub-rays of the footprint where it touches a sphere and straddles an edge ([`FIVE`] at other
/// edges): [`FIVE`], or on the grid the points of a square grid `STEP` apart within `REACH`
/// steps of the centre, as (along, across) offsets in units of the 1-sigma beam half-angle, each weighted by the Gaussian there (the weights sum to 1). An edge cuts
/// the footprint anywhere, so the rule must resolve where it falls: the lit share moves in steps
/// of at most a few per cent and the echo's range follows the cut continuously.
pub(super) fn stencil(grid: bool) -> heapless::Vec<(f64, f64, f64), MAX_SUBS> {
    let mut v = heapless::Vec::new();
    if !grid {
        let _ = v.extend_from_slice(&FIVE);
        return v;
    }
    let mut total = 0.0;
    for i in -REACH..=REACH {
        for j in -REACH..=REACH {
            if i * i + j * j <= REACH * REACH {
                let (ka, kc) = (f64::from(i) * STEP, f64::from(j) * STEP);
                let w = libm::exp(-(ka * ka + kc * kc) / 2.0);
                total += w;
                let _ = v.push((ka, kc, w));
            }
        }
    }
    for x in v.iter_mut() {
        x.2 /= total;
    }
    v
}

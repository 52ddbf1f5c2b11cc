//! The radius a sphere's returns show: each slice's detection ([`super::detect`]) tried at
//! several radii, the slices detected at each counted. A sphere whose site radius is its
//! diameter (or feet read as metres) is detected at the radius it has, seldom at the one the
//! site says.

use super::detect::detect;
use super::scan::{assign_slices, runs, slices};
use super::score::Key;
use super::{georeference, Directions, ExtractSettings};
use crate::align::window::{Observation, Target};
use crate::calib::objective::TimeOffset;
use crate::georef::Mount;

/// Georeference one sphere's windowed returns `v` with `mount` (no time offset on top), cut
/// them into scan lines and slices as the rounds do, and count into `out[i]` the slices in
/// which a sphere of radius `radii[i]` is detected (shell `tau` scaled with the radius, from
/// the settings' first shell at the surveyed radius `t.radius`), in at most `max_slices`
/// slices spread over the survey. `keys` and `grid` are [`detect`]'s scratch. `v` is
/// reordered (time order) and its work fields overwritten.
#[allow(clippy::too_many_arguments)]
pub fn detections_at_radii(
    v: &mut [Observation],
    t: &Target,
    mount: &Mount,
    st: &ExtractSettings,
    keys: &mut [Key],
    grid: &mut [u16],
    radii: &[f64],
    max_slices: usize,
    out: &mut [u32],
) {
    v.sort_unstable_by_key(|o| (o.time, o.channel, o.block));
    georeference(v, t, mount, &TimeOffset::default());
    runs(v, st.firing_ns, st.jump);
    assign_slices(v, st.slice_ns, keys.len());
    let dirs = Directions::default();
    for o in out.iter_mut() {
        *o = 0;
    }
    let every = slices(v).count().div_ceil(max_slices.max(1)).max(1);
    for sl in slices(v).step_by(every) {
        for (r, n) in radii.iter().zip(out.iter_mut()) {
            let tau = st.tau0 * (r / t.radius).clamp(0.5, 2.0);
            if detect(&v[sl.clone()], keys, *r, tau, None, grid, &dirs, st).is_some() {
                *n += 1;
            }
        }
    }
}

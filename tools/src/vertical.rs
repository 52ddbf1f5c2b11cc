//! The surveyed heights checked before the mounting is blamed (issue 47 item 4): when no
//! sphere's window caught a return, the returns in a column around each sphere (within its
//! window's radius horizontally, at any height) say where the ground and the sphere are. When
//! every sphere's column sits at one height off its surveyed centre, beyond the window, the
//! heights are wrong (a datum: ellipsoidal against orthometric; a unit: feet against metres),
//! not the mounting.

use crate::pipeline::{run, Inputs};
use spherecal::align::window::Target;

/// The histogram's bins [m] and its half-span [m]: heights 0.25 m apart up to 500 m off.
const BIN_M: f64 = 0.25;
const SPAN_M: f64 = 500.0;
const BINS: usize = (2.0 * SPAN_M / BIN_M) as usize;
/// Returns a sphere's column needs for its median to count.
const MIN_RETURNS: u64 = 50;

/// Each sphere's column: returns counted by their height above the surveyed centre.
struct Column {
    bins: Vec<u32>,
    n: u64,
}

impl Column {
    fn median_m(&self) -> Option<f64> {
        if self.n < MIN_RETURNS {
            return None;
        }
        let half = self.n.div_ceil(2);
        let mut seen = 0u64;
        for (i, b) in self.bins.iter().enumerate() {
            seen += u64::from(*b);
            if seen >= half {
                return Some((i as f64 + 0.5) * BIN_M - SPAN_M);
            }
        }
        None
    }
}

/// The median height of the returns around each sphere above its surveyed centre [m] (None:
/// fewer than [`MIN_RETURNS`] in its column), from one more pass over the inputs.
pub fn columns(inp: &Inputs, targets: &[Target]) -> Result<Vec<Option<f64>>, crate::Error> {
    let mut cols: Vec<Column> = targets
        .iter()
        .map(|_| Column {
            bins: vec![0; BINS],
            n: 0,
        })
        .collect();
    let margin = inp.margin;
    let mut each = |p: &spherecal::align::window::GeoPoint| {
        for (t, c) in targets.iter().zip(cols.iter_mut()) {
            let d = p.ned - t.center;
            if d.x.hypot(d.y) > t.radius + margin {
                continue;
            }
            // NED: up is -z.
            let above = -d.z;
            let i = ((above + SPAN_M) / BIN_M).floor();
            if (0.0..BINS as f64).contains(&i) {
                c.bins[i as usize] += 1;
                c.n += 1;
            }
        }
    };
    run(inp, Some(&mut each), |rx| for _ in rx {})?;
    Ok(cols.iter().map(Column::median_m).collect())
}

/// The heights' refusal in words when every sphere with returns around it has them at one
/// height off its surveyed centre, beyond its window (`medians` from [`columns`]).
pub fn heights_off(
    medians: &[Option<f64>],
    targets: &[Target],
    ids: &[String],
    margin: f64,
) -> Option<String> {
    let seen: Vec<(usize, f64)> = medians
        .iter()
        .enumerate()
        .filter_map(|(j, m)| m.map(|m| (j, m)))
        .collect();
    if seen.is_empty() {
        return None;
    }
    let outside = seen
        .iter()
        .all(|&(j, m)| m.abs() > targets[j].radius + margin);
    let one_way = seen.iter().all(|s| s.1 > 0.0) || seen.iter().all(|s| s.1 < 0.0);
    let (lo, hi) = seen
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, s| {
            (a.0.min(s.1), a.1.max(s.1))
        });
    let mean = seen.iter().map(|s| s.1).sum::<f64>() / seen.len() as f64;
    if !(outside && one_way && hi - lo <= (0.25 * mean.abs()).max(3.0)) {
        return None;
    }
    let list: Vec<String> = seen
        .iter()
        .map(|&(j, m)| format!("{} {m:+.1} m", ids[j]))
        .collect();
    Some(format!(
        "the returns near every sphere (within its window's radius horizontally) are ~{:.0} m {} the surveyed centres ({}): the heights are off, not the mounting - check the heights' datum and unit (site import --height ellipsoidal|orthometric with --geoid-n or --geoid, --height-unit)",
        mean.abs(),
        if mean < 0.0 { "below" } else { "above" },
        list.join(", ")
    ))
}

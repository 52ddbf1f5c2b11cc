//! The vessel's own parts (fixed in the body frame, so fixed for the sensor): which firings
//! can touch each, tabulated once.

use super::*;

impl LidarSim<'_, '_> {
    /// Tabulate, for each vessel part (fixed in the body frame, so fixed for the sensor), the
    /// (laser, 0.25 deg azimuth bin) firings whose footprint can touch it: the bin's centre ray
    /// against the part grown by half a bin at its far side plus the footprint's radius (any
    /// ray of the bin that hits the part is that close to the centre ray).
    pub(super) fn with_body_tables(mut self) -> Self {
        let mount = self.world.mount;
        let bin = TAU / BODY_BINS as f64;
        for (i, obj) in self.world.objects.iter().enumerate() {
            if obj.frame != Frame::Body || self.body.is_full() {
                continue;
            }
            let (c, r) = obj.bound();
            let far = (mount.r_li.tr_mul(&(c - mount.lever))).norm() + r;
            // (An origin that turns with the column moves by up to twice its radius.)
            let grow = far * (bin * 0.75 + self.spread * 1.2)
                + 1e-3
                + 2.0 * self.cfg.scanner.beam_origin_radius_m();
            let Some(grown) = obj.shape.offset(grow) else {
                continue;
            };
            let mut table = [[0u64; BODY_WORDS]; MAX_LASERS];
            let lasers = self.cfg.scanner.lasers();
            for (laser, row) in table.iter_mut().enumerate().take(lasers) {
                let beam = &self.beams[laser];
                let o = mount.lever + mount.r_li * beam_origin_l(beam);
                for k in 0..BODY_BINS {
                    // The bin is in the laser's own azimuth (its offset included).
                    let (sa, ca) = libm::sincos((k as f64 + 0.5) * bin);
                    let d = mount.r_li * beam_unit(beam, sa, ca);
                    if grown.intersect(&o, &d).is_some() {
                        row[k / 64] |= 1 << (k % 64);
                    }
                }
            }
            let _ = self.body.push((i as u16, table));
        }
        self
    }

    /// The tables' azimuth bin of an azimuth [rad].
    pub(super) fn body_bin(a: f64) -> usize {
        let turns = a / TAU - libm::floor(a / TAU);
        ((turns * BODY_BINS as f64) as usize).min(BODY_BINS - 1)
    }

    /// A vessel part (its table `table`) cannot be touched by a firing of `laser` in azimuth
    /// bin `k`.
    pub(super) fn body_misses(&self, table: u8, laser: usize, k: usize) -> bool {
        self.body
            .get(usize::from(table))
            .is_some_and(|(_, t)| t[laser % MAX_LASERS][k / 64] & (1 << (k % 64)) == 0)
    }
}

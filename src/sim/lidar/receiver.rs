//! The receiver: a firing's sub-ray hits merged into echoes, the echo(es) the return mode
//! reports, and each written with its range noise and intensity.

use super::*;

impl LidarSim<'_, '_> {
    /// The footprint's sub-ray hits as echoes: nearest first, those within the merge distance
    /// one echo at their energy-weighted range, labelled with the object of most energy; an
    /// echo too weak for the receiver is counted, not reported.
    pub(super) fn merge(&mut self, subs: &mut [SubHit], echoes: &mut heapless::Vec<Echo, 5>) {
        subs.sort_unstable_by(|x, y| x.t.total_cmp(&y.t));
        let mut i = 0;
        while i < subs.len() {
            let first = subs[i].t;
            let mut j = i;
            let (mut e, mut et) = (0.0, 0.0);
            let mut shares: heapless::Vec<(u16, f64, f64), 5> = heapless::Vec::new();
            while j < subs.len() && subs[j].t - first < self.cfg.merge_distance {
                let sh = subs[j];
                e += sh.energy;
                et += sh.energy * sh.t;
                match shares.iter_mut().find(|x| x.0 == sh.obj) {
                    Some(x) => x.1 += sh.energy,
                    None => {
                        let _ = shares.push((sh.obj, sh.energy, sh.cos));
                    }
                }
                j += 1;
            }
            if e > 0.0 {
                let (obj, main, cos) =
                    shares
                        .iter()
                        .copied()
                        .fold((0, -1.0, 1.0), |a, x| if x.1 > a.1 { x } else { a });
                let range = et / e;
                if range >= self.cfg.min_range {
                    if e * (R_REF / range) * (R_REF / range) >= P_MIN {
                        let _ = echoes.push(Echo {
                            range,
                            energy: e,
                            obj,
                            purity: main / e,
                            cos,
                        });
                    } else {
                        self.stats.too_weak += 1;
                    }
                }
            }
            i = j;
        }
    }

    /// The echo(es) a firing reports by the return mode, into `self.traced`.
    pub(super) fn pick(&mut self, b: usize, ch: usize, mode: ReturnMode, echoes: &[Echo]) {
        if echoes.is_empty() {
            return;
        }
        let power = |e: &Echo| e.energy / (e.range * e.range);
        let strongest = (0..echoes.len())
            .max_by(|&i, &j| power(&echoes[i]).total_cmp(&power(&echoes[j])))
            .unwrap_or(0);
        let last = echoes.len() - 1;
        let picks: [(usize, usize); 2] = match mode {
            ReturnMode::Strongest => [(b, strongest), (usize::MAX, 0)],
            ReturnMode::Last => [(b, last), (usize::MAX, 0)],
            ReturnMode::Dual => {
                // Odd block: the strongest, or the second strongest when that is the last.
                let second = if strongest == last && echoes.len() > 1 {
                    (0..last)
                        .max_by(|&i, &j| power(&echoes[i]).total_cmp(&power(&echoes[j])))
                        .unwrap_or(last)
                } else {
                    strongest
                };
                [(b, last), (b + 1, second)]
            }
        };
        for (block, i) in picks {
            if block >= self.cfg.scanner.blocks() {
                continue;
            }
            let e = echoes[i];
            let _ = self.traced.push(Traced {
                range: e.range,
                energy: e.energy as f32,
                cos: e.cos as f32,
                obj: e.obj,
                purity: libm::round(e.purity * 255.0) as u8,
                block: block as u8,
                channel: ch as u8,
            });
        }
    }

    /// Write the packet's echoes (`self.traced`) with their noise into the packet and the hit
    /// list.
    pub(super) fn emit(
        &mut self,
        p: &mut Writer<'_>,
        t: GpsTime,
        az: &[u16; MAX_BLOCKS],
        stride: usize,
    ) {
        let (scanner, mode) = (self.cfg.scanner, self.cfg.mode);
        let unit = scanner.distance_unit_m();
        for k in 0..self.traced.len() {
            let e = self.traced[k];
            let target = self
                .world
                .objects
                .get(usize::from(e.obj))
                .and_then(|o| o.target);
            if target.is_none()
                && self.cfg.clutter_keep < 1.0
                && !self.rng.chance(self.cfg.clutter_keep)
            {
                continue;
            }
            let (block, ch) = (usize::from(e.block), usize::from(e.channel));
            // The firing's block: in dual mode the pair's even one.
            let fb = block - block % stride;
            let (a, _) = self.firing_azimuth(az, fb, stride, ch);
            let tf = GpsTime(t.0 + scanner.firing_offset_ns(mode, fb, ch));
            let energy = f64::from(e.energy);
            let cos = f64::from(e.cos);
            let mut weak = 1.0;
            if target.is_some() {
                let laser = scanner.laser_of(ch);
                match self.arc_step(laser, e.obj, tf.0) {
                    ArcStep::Lost => continue,
                    ArcStep::Leading
                        if self.cfg.edge_dropout > 0.0
                            && self.rng.chance(self.cfg.edge_dropout) =>
                    {
                        self.arcs[laser].drop_ns = tf.0 + i64::from(scanner.laser_period_ns());
                        weak = self.rng.range(0.1, 0.35);
                        self.stats.edge_dropouts += 1;
                    }
                    _ => {}
                }
            }
            let mut intensity = 100.0 * energy * self.cfg.intensity_gain * weak;
            if self.cfg.intensity_scatter > 0.0 {
                let s = self.cfg.intensity_scatter;
                intensity *= libm::exp(s * self.rng.normal() - 0.5 * s * s);
            }
            let intensity = intensity.clamp(0.0, 100.0);
            let mut sigma = self.cfg.range_sigma;
            if self.cfg.incidence_noise {
                let tan = (libm::sqrt((1.0 - cos * cos).max(0.0)) / cos.max(1e-6)).min(10.0);
                let spread = e.range * self.cfg.divergence[0] / 4.0 * tan;
                sigma = libm::sqrt(sigma * sigma + spread * spread);
            }
            let walk = self.cfg.range_walk * (1.0 - intensity / 100.0);
            let d = e.range + walk + self.rng.gauss(sigma);
            let raw = libm::round(d / unit).clamp(1.0, 65_535.0) as u16;
            p.set_channel(block, ch, raw, libm::round(intensity) as u8);
            let _ = self.hits.push(Hit {
                block: e.block,
                channel: e.channel,
                time: tf,
                azimuth: a,
                range: e.range,
                object: e.obj,
                purity: e.purity,
            });
            match target {
                Some(tg) if usize::from(tg) < MAX_TARGETS => self.stats.hits[usize::from(tg)] += 1,
                _ => self.stats.clutter_hits += 1,
            }
            if e.purity < 230 {
                self.stats.mixed += 1;
            }
        }
    }

    /// Where a target return of `laser` on `obj` fired at `t_ns` stands in its arc: its
    /// leading edge (the laser's previous firing was not on it), a firing the arc loses, or
    /// on along it.
    fn arc_step(&mut self, laser: usize, obj: u16, t_ns: i64) -> ArcStep {
        let period = i64::from(self.cfg.scanner.laser_period_ns());
        let arc = &mut self.arcs[laser % MAX_LASERS];
        let along = arc.obj == obj && t_ns.saturating_sub(arc.last_ns) <= period + period / 2;
        (arc.obj, arc.last_ns) = (obj, t_ns);
        if !along {
            arc.drop_ns = i64::MIN;
            return ArcStep::Leading;
        }
        if arc.drop_ns != i64::MIN && (t_ns - arc.drop_ns).abs() <= period / 2 {
            arc.drop_ns = i64::MIN;
            return ArcStep::Lost;
        }
        ArcStep::Along
    }
}

/// See [`LidarSim::arc_step`].
enum ArcStep {
    Leading,
    Lost,
    Along,
}

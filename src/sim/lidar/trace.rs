//! Tracing a packet's firings: the broad phase (each object's azimuth window, cached over
//! [`CACHE_PACKETS`] packets) and each firing's footprint against the objects left.

use super::*;

/// One firing as [`LidarSim::trace`] takes it: its time, azimuth (sin, cos), laser, and the
/// shift of its origin in the LiDAR frame where that turns with the column (an Ouster's).
#[derive(Debug, Clone, Copy)]
pub(super) struct Firing {
    t: GpsTime,
    sin_cos: (f64, f64),
    laser: usize,
    shift: Option<Vector3<f64>>,
}

impl LidarSim<'_, '_> {
    /// The broad-phase windows for the packets from `t` on: each object's bounding sphere in
    /// the LiDAR frame at the span's middle, widened by how far the platform turns and moves
    /// (and the object moves) in half the span.
    pub(super) fn cache_windows(&mut self, t: GpsTime) {
        self.windows.clear();
        let span =
            self.period_ns * CACHE_PACKETS as i64 + 2 * i64::from(self.cfg.scanner.block_ns());
        let (p0, p1) = (self.pose(t), self.pose(GpsTime(t.0 + span)));
        let mid = GpsTime(t.0 + span / 2);
        let pose = self.pose(mid);
        let mount = &self.world.mount;
        let turn = angle_between(&(p0.r_ig * mount.r_li), &(p1.r_ig * mount.r_li));
        let travel = (p1.position - p0.position).norm();
        let half_span_s = span as f64 * 0.5e-9;
        let origin = pose.position + pose.r_ig * mount.lever;
        let to_l = (pose.r_ig * mount.r_li).transpose();
        let t_mid = self.world.t_of(mid);
        // (From the beams tabulated once, no trigonometry per cache span.)
        let (lo, hi) = self.beams[..self.cfg.scanner.lasers().min(MAX_LASERS)]
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), b| {
                (lo.min(b.elevation_deg), hi.max(b.elevation_deg))
            });
        let (lo, hi) = ((lo - 1.0).to_radians(), (hi + 1.0).to_radians());
        let all = !self.cfg.cull;
        for (i, obj) in self.world.objects.iter().enumerate().take(MAX_OBJECTS) {
            let (c, r) = obj.bound();
            // The bound in the LiDAR frame, and how far it can drift in half the span.
            let (v, turn, drift) = match obj.frame {
                Frame::Site => {
                    let c = c + obj.velocity * t_mid;
                    let drift = travel / 2.0 + obj.velocity.norm() * half_span_s;
                    (to_l * (c - origin), turn, drift)
                }
                // Fixed to the vessel: it does not move in the LiDAR frame.
                Frame::Body => (mount.r_li.tr_mul(&(c - mount.lever)), 0.0, 0.0),
            };
            let dist = v.norm();
            let rr = r + 0.05 + drift;
            if !all && dist - rr > self.cfg.max_range {
                continue;
            }
            let full = all || dist <= rr * 1.05;
            let (center, half) = if full {
                (0.0, 4.0)
            } else {
                let alpha = libm::asin(rr / dist) + turn * 0.75 + 0.01;
                let elev = libm::asin((v.z / dist).clamp(-1.0, 1.0));
                if elev - alpha > hi || elev + alpha < lo {
                    continue;
                }
                let ce = libm::cos(elev.abs() + alpha);
                let half = if ce <= 0.05 { 4.0 } else { alpha / ce + 0.01 };
                (libm::atan2(v.x, v.y), half)
            };
            let _ = self.windows.push(Window {
                obj: i as u16,
                center,
                half,
                rho: (dist + rr) * self.spread * 1.2,
                table: self
                    .body
                    .iter()
                    .position(|(k, _)| usize::from(*k) == i)
                    .map_or(u8::MAX, |k| k as u8),
            });
        }
    }

    /// Trace every firing of the packet at `t` (block azimuths `az`) into `self.traced`.
    pub(super) fn trace_packet(&mut self, t: GpsTime, az: &[u16; MAX_BLOCKS], stride: usize) {
        let (scanner, mode) = (self.cfg.scanner, self.cfg.mode);
        let blocks = scanner.blocks();

        // The windows over this packet's azimuth span (12 blocks, ~2.4 deg at 600 rpm), their
        // centres made relative to the first block's azimuth (no wrapping per firing).
        let a0 = self.block_azimuth(az[0]);
        let a1 = self.block_azimuth(az[blocks - 1]);
        let span_half = wrap_pi(a1 - a0).abs() / 2.0 + 0.01;
        let mid = a0 + wrap_pi(a1 - a0) / 2.0;
        self.live.clear();
        for w in &self.windows {
            if w.half >= PI || wrap_pi(w.center - mid).abs() <= w.half + span_half {
                let _ = self.live.push(Window {
                    center: wrap_pi(w.center - a0),
                    ..*w
                });
            }
        }
        let objects = self.world.objects;
        let is_target = |w: &Window| {
            objects
                .get(usize::from(w.obj))
                .is_some_and(|o| o.target.is_some())
        };
        if self.cfg.targets_only && !self.live.iter().any(is_target) {
            return;
        }
        let glints = !self.cfg.targets_only
            && self
                .world
                .water
                .is_some_and(|w| w.specular_prob > 0.0 && w.specular > 0.0);
        if self.live.is_empty() && !glints {
            return;
        }

        // Poses at the block boundaries, interpolated to each firing (within a block the
        // attitude turns by at most a few 1e-4 rad: the linear blend errs by < 1e-8 rad).
        let mut pose_a: Option<(GpsTime, PlatformPose, PlatformPose)> = None;
        let mut near: heapless::Vec<u16, MAX_OBJECTS> = heapless::Vec::new();
        let mut b = 0;
        while b < blocks {
            let tb = GpsTime(t.0 + scanner.firing_offset_ns(mode, b, 0));
            let (ta, pa, pe) = match pose_a {
                Some((ta, pa, pe)) if ta == tb => (ta, pa, pe),
                _ => {
                    let pa = self.pose(tb);
                    let pe = self.pose(GpsTime(tb.0 + i64::from(scanner.block_ns())));
                    pose_a = Some((tb, pa, pe));
                    (tb, pa, pe)
                }
            };
            // Nadir in the LiDAR frame (for the water's glints).
            let nadir_l = (pa.r_ig * self.world.mount.r_li).tr_mul(&Vector3::z());
            for ch in 0..scanner.channels() {
                let laser = scanner.laser_of(ch);
                let (a, rel) = self.firing_azimuth(az, b, stride, ch);
                // The objects whose windows hold this firing (vessel parts by their tables).
                near.clear();
                let bin = Self::body_bin(a);
                for (k, w) in self.live.iter().enumerate() {
                    if w.half < PI && (rel - w.center).abs() > w.half {
                        continue;
                    }
                    if w.table != u8::MAX && self.body_misses(w.table, laser, bin) {
                        continue;
                    }
                    let _ = near.push(k as u16);
                }
                if near.is_empty() && !glints {
                    continue;
                }
                if self.cfg.targets_only
                    && !near.iter().any(|&k| is_target(&self.live[usize::from(k)]))
                {
                    continue;
                }
                let (sa, ca) = libm::sincos(a);
                let u = beam_unit(&self.beams[laser], sa, ca);
                let glint = glints && u.dot(&nadir_l) >= self.glint_cos;
                if near.is_empty() && !glint {
                    continue;
                }
                self.stats.candidates += 1;
                let tf = GpsTime(t.0 + scanner.firing_offset_ns(mode, b, ch));
                let f = (tf.0 - ta.0) as f64 / f64::from(scanner.block_ns());
                let pf = PlatformPose {
                    position: pa.position + (pe.position - pa.position) * f,
                    r_ig: pa.r_ig + (pe.r_ig - pa.r_ig) * f,
                };
                let mut echoes: heapless::Vec<Echo, 5> = heapless::Vec::new();
                let radius = scanner.beam_origin_radius_m();
                let shift = (radius > 0.0).then(|| {
                    let (sb, cb) = libm::sincos(self.block_azimuth(az[b]));
                    Vector3::new(sb, cb, 0.0) * radius - u * radius
                });
                let firing = Firing {
                    t: tf,
                    sin_cos: (sa, ca),
                    laser,
                    shift,
                };
                self.trace(&pf, firing, &near, &mut echoes);
                self.pick(b, ch, mode, &echoes);
            }
            b += stride;
        }
    }

    /// Trace one firing's footprint (the platform at `pf`, azimuth (sin, cos), the live
    /// windows `cand` that hold it) and form its echoes (nearest first). The five sub-rays are
    /// traced only where the footprint straddles an edge: each candidate is first tested with
    /// the centre ray against itself grown by the footprint's radius at its far side (a miss:
    /// no sub-ray can hit it) and shrunk by it (a hit: every sub-ray hits it); if no object's
    /// edge is in between, the centre ray stands for the whole footprint.
    pub(super) fn trace(
        &mut self,
        pf: &PlatformPose,
        firing: Firing,
        cand: &[u16],
        echoes: &mut heapless::Vec<Echo, 5>,
    ) {
        let Firing {
            t: tf,
            sin_cos: (s, c),
            laser,
            shift,
        } = firing;
        let mount = &self.world.mount;
        let beam = self.beams[laser % MAX_LASERS];
        let u = beam_unit(&beam, s, c);
        let sig = [self.cfg.divergence[0] / 4.0, self.cfg.divergence[1] / 4.0];
        let mut in_l = Beam {
            o: beam_origin_l(&beam),
            d: u,
            along: Vector3::zeros(),
            across: Vector3::zeros(),
        };
        let mut o_body = self.origins[laser % MAX_LASERS];
        // An origin that turns with the column (an Ouster's).
        if let Some(v) = shift {
            in_l.o += v;
            o_body += mount.r_li * v;
        }
        let d_body = mount.r_li * u;
        let mut body = Beam::centre(o_body, d_body);
        // (The interpolated attitude is orthonormal to 1e-8: the direction is renormalised.)
        let d_site = pf.r_ig * d_body;
        let mut site = Beam::centre(pf.position + pf.r_ig * o_body, d_site / d_site.norm());
        let t_rel = self.world.t_of(tf);
        // The ray in an object's own frame.
        let frame_ray = |obj: &super::super::Object, site: &Beam, body: &Beam, ka: f64, kc: f64| {
            match obj.frame {
                Frame::Site if obj.moves() => (site.o - obj.velocity * t_rel, site.sub(ka, kc)),
                Frame::Site => (site.o, site.sub(ka, kc)),
                Frame::Body => (body.o, body.sub(ka, kc)),
            }
        };
        // The objects the footprint can touch, and whether any edge is inside it.
        let mut near: heapless::Vec<u16, MAX_OBJECTS> = heapless::Vec::new();
        let (mut edge, mut sphere_near) = (false, false);
        for &k in cand {
            let Window { obj: i, rho, .. } = self.live[usize::from(k)];
            let obj = &self.world.objects[usize::from(i)];
            let (o, d) = frame_ray(obj, &site, &body, 0.0, 0.0);
            self.stats.tests += 1;
            if self.spread > 0.0 {
                let Some(grown) = obj.shape.offset(rho) else {
                    continue;
                };
                if grown.intersect(&o, &d).is_none() {
                    continue;
                }
                // On the grid, a sphere's curvature moves the footprint's mean range anywhere
                // on it (the lit cap's energy-weighted height): never deep.
                let sphere = matches!(obj.shape, super::super::Shape::Sphere { .. });
                sphere_near |= sphere;
                let deep = !(sphere && self.cfg.footprint_grid)
                    && obj
                        .shape
                        .offset(-rho)
                        .is_some_and(|sh| sh.intersect(&o, &d).is_some());
                edge |= !deep;
            }
            let _ = near.push(i);
        }
        // The grid where the footprint touches a sphere (its returns and what mixes into
        // them: the calibration models their bloom), five sub-rays at other edges.
        let stencil: &[(f64, f64, f64)] = if sphere_near { &self.stencil } else { &FIVE };
        let rays: &[(f64, f64, f64)] = if self.spread <= 0.0 || !edge {
            &[(0.0, 0.0, 1.0)]
        } else {
            // The footprint's axes: along the scan (horizontal in the LiDAR frame), across it.
            let along = Vector3::new(c, -s, 0.0);
            let in_l = Beam {
                along: along * sig[0],
                across: u.cross(&along) * sig[1],
                ..in_l
            };
            body = in_l.rotated(&mount.r_li, &mount.lever);
            site = body.rotated(&pf.r_ig, &pf.position);
            stencil
        };
        let mut subs: heapless::Vec<SubHit, MAX_SUBS> = heapless::Vec::new();
        for &(ka, kc, w) in rays {
            let ds = site.sub(ka, kc);
            let mut best: Option<(f64, u16)> = None;
            for &i in &near {
                let obj = &self.world.objects[usize::from(i)];
                let (o, d) = frame_ray(obj, &site, &body, ka, kc);
                self.stats.tests += 1;
                if let Some(th) = obj.shape.intersect(&o, &d) {
                    if th <= self.cfg.max_range && best.is_none_or(|(h, _)| th < h) {
                        best = Some((th, i));
                    }
                }
            }
            // The water stops the beam where it is nearer than any object.
            let water = self.world.water.and_then(|wt: Water| {
                let tw = wt.intersect(&site.o, &ds)?;
                Some((tw, wt))
            });
            let sub = match (best, water) {
                (_, Some((tw, wt))) if best.is_none_or(|(h, _)| tw < h) => {
                    self.stats.water += u64::from(ka == 0.0 && kc == 0.0);
                    let glint = ds.z >= self.glint_cos && self.trace_rng.chance(wt.specular_prob);
                    SubHit {
                        t: tw,
                        energy: if glint { w } else { 0.0 },
                        obj: LABEL_WATER,
                        cos: 1.0,
                    }
                }
                (Some((th, i)), _) => {
                    let obj = &self.world.objects[usize::from(i)];
                    let (o, d) = frame_ray(obj, &site, &body, ka, kc);
                    let cos = obj.shape.normal(&(o + d * th)).dot(&d).abs();
                    SubHit {
                        t: th,
                        energy: w * obj.reflectivity * cos,
                        obj: i,
                        cos,
                    }
                }
                (None, _) => continue,
            };
            let _ = subs.push(sub);
        }
        self.merge(&mut subs, echoes);
    }
}

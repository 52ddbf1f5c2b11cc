//! Vessel trajectories: straight passes at a speed and heading joined by smooth turns, with
//! wave motion (roll, pitch, yaw and heave as sines). All in the site's NED frame; the attitude
//! is body -> site NED in the DESIGN.md convention.

use crate::frames::rotation;
use core::f64::consts::TAU;
use nalgebra::{Matrix3, Vector3};

/// One straight pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pass {
    /// Start, north and east of the site origin [m].
    pub start: [f64; 2],
    /// Course over ground [rad] (0 = north, pi/2 = east).
    pub heading: f64,
    /// Speed [m/s].
    pub speed: f64,
    /// Duration [s].
    pub duration: f64,
    /// Down of this pass relative to the trajectory's [m] (negative: higher; a drone's second
    /// flight height). Turns climb or descend between passes on the same Hermite curve.
    pub down: f64,
}

impl Pass {
    fn velocity(&self) -> Vector3<f64> {
        let (s, c) = libm::sincos(self.heading);
        Vector3::new(self.speed * c, self.speed * s, 0.0)
    }
    fn at(&self, tau: f64) -> Vector3<f64> {
        Vector3::new(self.start[0], self.start[1], self.down) + self.velocity() * tau
    }
}

/// Wave motion: amplitudes [rad, m] and periods [s]. Zero amplitude = none.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Motion {
    /// Roll amplitude [rad] and period [s].
    pub roll: (f64, f64),
    /// Pitch amplitude [rad] and period [s].
    pub pitch: (f64, f64),
    /// Yaw amplitude [rad] and period [s] (about the course).
    pub yaw: (f64, f64),
    /// Heave amplitude [m] and period [s] (positive down).
    pub heave: (f64, f64),
}

fn wave((amp, period): (f64, f64), t: f64, phase: f64) -> f64 {
    if amp == 0.0 || period <= 0.0 {
        0.0
    } else {
        amp * libm::sin(TAU * t / period + phase)
    }
}

/// The truth at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State {
    /// INS reference point in site NED [m].
    pub position: Vector3<f64>,
    /// Roll, pitch, heading [rad], body -> site NED.
    pub rph: [f64; 3],
}

impl State {
    /// `R_ig` of this state.
    pub fn r_ig(&self) -> Matrix3<f64> {
        rotation(self.rph[0], self.rph[1], self.rph[2])
    }
}

/// A recorded trajectory sample (from an SBET or CSV file, turned into the site frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Seconds after the start.
    pub t: f64,
    /// INS position, site NED [m].
    pub position: Vector3<f64>,
    /// Roll, pitch, heading [rad], body -> site NED.
    pub rph: [f64; 3],
}

/// Passes joined by cubic Hermite turns of a fixed duration, or, when `samples` is not empty,
/// a recorded trajectory interpolated between its samples (position linear, attitude by
/// quaternion slerp; held before the first and after the last); waves are not added to recorded
/// samples. A recorded trajectory's scan lasts until its last sample.
#[derive(Debug, Clone, Copy)]
pub struct Trajectory<'a> {
    /// Recorded samples in time order (empty: use the passes).
    pub samples: &'a [Sample],
    /// The passes, in order.
    pub passes: &'a [Pass],
    /// Duration of each turn between passes [s].
    pub turn: f64,
    /// NED down of the INS at rest [m] (negative: above the origin's height).
    pub down: f64,
    /// Wave motion.
    pub motion: Motion,
}

impl Trajectory<'_> {
    /// Total duration [s].
    pub fn duration(&self) -> f64 {
        if let Some(b) = self.samples.last() {
            return b.t.max(0.0);
        }
        let n = self.passes.len();
        self.passes.iter().map(|p| p.duration).sum::<f64>() + self.turn * n.saturating_sub(1) as f64
    }

    /// Position, velocity and course of the path (no waves) at `t` [s]; before the start and
    /// after the end the first and last pass are extended. In a turn the position follows a
    /// cubic Hermite curve and the course swings from one pass's to the next's with a smoothstep
    /// in time (the shorter way round), as a helmsman's would: no spin where the curve is slow.
    pub fn path(&self, t: f64) -> (Vector3<f64>, Vector3<f64>, f64) {
        let Some(first) = self.passes.first() else {
            return (Vector3::zeros(), Vector3::zeros(), 0.0);
        };
        if t <= 0.0 {
            return (first.at(t), first.velocity(), first.heading);
        }
        let mut t0 = 0.0;
        for (i, p) in self.passes.iter().enumerate() {
            if t <= t0 + p.duration {
                return (p.at(t - t0), p.velocity(), p.heading);
            }
            t0 += p.duration;
            match self.passes.get(i + 1) {
                Some(next) if t <= t0 + self.turn => {
                    let tt = self.turn;
                    let s = (t - t0) / tt;
                    let (p0, v0, p1, v1) = (
                        p.at(p.duration),
                        p.velocity() * tt,
                        next.at(0.0),
                        next.velocity() * tt,
                    );
                    let (s2, s3) = (s * s, s * s * s);
                    let pos = p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                        + v0 * (s3 - 2.0 * s2 + s)
                        + p1 * (-2.0 * s3 + 3.0 * s2)
                        + v1 * (s3 - s2);
                    let vel = (p0 * (6.0 * s2 - 6.0 * s)
                        + v0 * (3.0 * s2 - 4.0 * s + 1.0)
                        + p1 * (-6.0 * s2 + 6.0 * s)
                        + v1 * (3.0 * s2 - 2.0 * s))
                        / tt;
                    let dh = next.heading - p.heading;
                    let dh = dh - TAU * libm::floor((dh + core::f64::consts::PI) / TAU);
                    let course = p.heading + dh * (3.0 * s2 - 2.0 * s3);
                    return (pos, vel, course);
                }
                Some(_) => t0 += self.turn,
                None => {}
            }
        }
        let last = &self.passes[self.passes.len() - 1];
        (
            last.at(t - (self.duration() - last.duration)),
            last.velocity(),
            last.heading,
        )
    }

    /// A recorded trajectory at `t` (held at its ends).
    fn sampled(&self, t: f64) -> State {
        let s = self.samples;
        let i = s.partition_point(|x| x.t <= t);
        let (a, b) = match i {
            0 => (&s[0], &s[0]),
            i if i >= s.len() => (&s[s.len() - 1], &s[s.len() - 1]),
            i => (&s[i - 1], &s[i]),
        };
        let f = if b.t > a.t {
            ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let qa = nalgebra::UnitQuaternion::from_euler_angles(a.rph[0], a.rph[1], a.rph[2]);
        let qb = nalgebra::UnitQuaternion::from_euler_angles(b.rph[0], b.rph[1], b.rph[2]);
        let q = qa.try_slerp(&qb, f, 1e-12).unwrap_or(qa);
        let (roll, pitch, heading) = q.euler_angles();
        State {
            position: a.position.lerp(&b.position, f),
            rph: [roll, pitch, heading],
        }
    }

    /// The truth at `t` [s after the start].
    pub fn state(&self, t: f64) -> State {
        if !self.samples.is_empty() {
            return self.sampled(t);
        }
        let (mut p, _, course) = self.path(t);
        p.z += self.down + wave(self.motion.heave, t, 0.3);
        let roll = wave(self.motion.roll, t, 0.0);
        let pitch = wave(self.motion.pitch, t, 1.0);
        let heading = course + wave(self.motion.yaw, t, 2.0);
        State {
            position: p,
            rph: [roll, pitch, heading],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recorded_samples_are_interpolated_through_north() {
        // nalgebra's from_euler_angles(r, p, y) is Rz(y) Ry(p) Rx(r): the DESIGN.md convention.
        let r = nalgebra::UnitQuaternion::from_euler_angles(0.1, -0.2, 2.0)
            .to_rotation_matrix()
            .into_inner();
        assert!((r - crate::frames::rotation(0.1, -0.2, 2.0)).norm() < 1e-14);
        let s = [
            Sample {
                t: 10.0,
                position: Vector3::new(0.0, 0.0, 0.0),
                rph: [0.0, 0.0, 359f64.to_radians()],
            },
            Sample {
                t: 11.0,
                position: Vector3::new(2.0, 0.0, 0.0),
                rph: [0.0, 0.0, 1f64.to_radians()],
            },
        ];
        let tr = Trajectory {
            samples: &s,
            passes: &[],
            turn: 0.0,
            down: 0.0,
            motion: Motion::default(),
        };
        assert_eq!(tr.duration(), 11.0);
        let st = tr.state(10.5);
        assert!((st.position.x - 1.0).abs() < 1e-12);
        assert!(st.rph[2].abs() < 1e-9, "{}", st.rph[2]);
    }

    #[test]
    fn passes_and_turns_are_continuous() {
        let passes = [
            Pass {
                start: [-10.0, 15.0],
                heading: 0.0,
                speed: 2.0,
                duration: 10.0,
                down: 0.0,
            },
            Pass {
                start: [10.0, 25.0],
                heading: core::f64::consts::PI,
                speed: 2.0,
                duration: 10.0,
                down: 0.0,
            },
        ];
        let tr = Trajectory {
            samples: &[],
            passes: &passes,
            turn: 5.0,
            down: -1.0,
            motion: Motion::default(),
        };
        assert_eq!(tr.duration(), 25.0);
        // Pass 1 by hand: 2 m/s north from (-10, 15).
        let s = tr.state(4.0);
        assert!((s.position - Vector3::new(-2.0, 15.0, -1.0)).norm() < 1e-12);
        assert!(s.rph[2].abs() < 1e-12);
        // Continuity through both turn joints.
        for t in [10.0, 15.0] {
            let a = tr.path(t - 1e-6).0;
            let b = tr.path(t + 1e-6).0;
            assert!((a - b).norm() < 1e-4, "{t}");
        }
        // Second pass heads south.
        let s = tr.state(20.0);
        assert!((s.position - Vector3::new(0.0, 25.0, -1.0)).norm() < 1e-12);
        assert!((s.rph[2].abs() - core::f64::consts::PI).abs() < 1e-12);
    }

    /// A drone's second flight height: the pass flies at its own down, the turn climbs on the
    /// same smooth curve (no jump in height or in its rate at either joint).
    #[test]
    fn a_pass_at_another_height_is_reached_smoothly() {
        let passes = [
            Pass {
                start: [0.0, 0.0],
                heading: 0.0,
                speed: 5.0,
                duration: 10.0,
                down: 0.0,
            },
            Pass {
                start: [50.0, 20.0],
                heading: core::f64::consts::PI,
                speed: 5.0,
                duration: 10.0,
                down: -15.0,
            },
        ];
        let tr = Trajectory {
            samples: &[],
            passes: &passes,
            turn: 8.0,
            down: -30.0,
            motion: Motion::default(),
        };
        assert!((tr.state(5.0).position.z + 30.0).abs() < 1e-12);
        assert!((tr.state(23.0).position.z + 45.0).abs() < 1e-12);
        let mid = tr.state(14.0).position.z;
        assert!(mid < -30.0 && mid > -45.0, "{mid}");
        for t in [10.0, 18.0] {
            let (a, va, _) = tr.path(t - 1e-6);
            let (b, vb, _) = tr.path(t + 1e-6);
            assert!(
                (a - b).norm() < 1e-4 && (va.z - vb.z).abs() < 1e-3,
                "{t}: {va} {vb}"
            );
        }
    }
}

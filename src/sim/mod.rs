//! The simulator (the paper's synthetic experiment, done on the wire): trajectories, scenes,
//! the VLP-16 firing schedule with ray tracing, and the VN-200 output stream, all deterministic
//! for a seed. Outputs go through the same emit sides the decoders read.

pub mod ins;
pub mod lidar;
pub mod nav_error;
pub mod rng;
pub mod scene;
pub mod trajectory;
pub mod visibility;

pub use ins::{InsConfig, InsSim};
pub use lidar::{LidarConfig, LidarSim, Scanner, SimPacket};
pub use rng::Rng;
pub use scene::{Frame, Object, Shape, Water};
pub use trajectory::{Motion, Pass, State, Trajectory};

use crate::frames::LocalFrame;
use crate::georef::Mount;
use crate::time::GpsTime;

/// Everything a simulation needs, borrowed (no heap).
#[derive(Debug, Clone, Copy)]
pub struct World<'a> {
    /// The site's local frame.
    pub site: LocalFrame,
    /// The vessel's path and motion.
    pub trajectory: Trajectory<'a>,
    /// Targets, scenery and the vessel's own parts.
    pub objects: &'a [Object],
    /// The water surface, if any.
    pub water: Option<Water>,
    /// The true mounting.
    pub mount: Mount,
    /// GPS time of trajectory time 0.
    pub start: GpsTime,
    /// GPS - UTC [s].
    pub leap_seconds: i64,
}

impl World<'_> {
    /// Trajectory time [s] of a GPS time.
    pub fn t_of(&self, t: GpsTime) -> f64 {
        (t.0 - self.start.0) as f64 * 1e-9
    }
}

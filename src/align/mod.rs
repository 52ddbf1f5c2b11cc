//! The align stage (DESIGN.md data flow): INS poses into a fixed history, LiDAR packets timed on
//! the LiDAR clock, every return georeferenced at its firing's pose and kept when it falls in a
//! sphere window, in fixed-capacity batches handed on by a callback.
//!
//! - [`history`]: the pose ring and interpolation between samples;
//! - [`aligner`]: the stage itself, with storage lent by the caller (static on a board, boxed
//!   on a host) and no waiting of its own: the file pipeline and the rig feed it poses until
//!   [`Aligner::wants_poses`] says a packet is covered, each with its own waiting policy.

pub mod aligner;
pub mod history;
pub mod window;

pub use aligner::{AlignStats, Aligner, HourFrom};
pub use history::{AlignError, Motion, PoseHistory, PoseSample};

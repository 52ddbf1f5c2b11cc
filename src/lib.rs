//! spherecal core: decoding, alignment, georeferencing and calibration of a mobile LiDAR rig
//! (Velodyne VLP-16 / Puck Hi-Res / HDL-32E / VLP-32C + VectorNav VN-200 or Applanix POS MV).
//!
//! `#![no_std]`, no heap, no I/O, no clocks: every function here is pure logic over borrowed
//! bytes and fixed-capacity buffers, and no input makes it panic. See `docs/DESIGN.md`
//! (layout, data flow, normative conventions) and `docs/PROTOCOLS.md` (wire formats).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(feature = "std")]
extern crate std;

pub mod align;
pub mod calib;
pub mod frames;
pub mod framing;
pub mod georef;
pub mod hesai;
mod le;
pub mod ouster;
pub mod posmv;
pub mod ros2;
#[cfg(any(test, feature = "sim"))]
pub mod sim;
pub mod time;
pub mod velodyne;

pub mod vn200;

//! Ouster OS0/OS1/OS2 captures: the sensor's metadata JSON ([`metadata`]) and the decoding of
//! a capture's lidar packets with it ([`decode`]).

pub mod decode;
pub mod metadata;

pub use metadata::{Metadata, TimestampMode};

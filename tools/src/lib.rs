//! spherecal-tools: the `spherecal` command's subcommands as library functions, so that tests
//! and benchmarks call exactly what the command runs.
#![forbid(unsafe_code)]

pub mod bag;
pub mod calibrate;
pub mod cli;
pub mod cmd;
pub mod config;
pub mod decode;
pub mod error;
pub mod fixtures;
pub mod georef;
pub mod hesai;
pub mod html;
pub mod ins;
pub mod montecarlo;
pub mod ouster;
pub mod output;
pub mod pipeline;
pub mod plan;
pub mod plot;
pub mod progress;
pub mod reasons;
pub mod replay;
pub mod report;
pub mod rig;
pub mod session;
pub mod state;
pub mod stretches;
pub mod survey;
pub mod synth;
pub mod undetermined;
pub mod verdict;
pub mod vertical;
pub mod vn200;

pub use error::{Error, ErrorKind};

//! spherecal-tools: the `spherecal` command's subcommands as library functions, so that tests
//! and benchmarks call exactly what the command runs.
#![forbid(unsafe_code)]

pub mod decode;
pub mod georef;
pub mod ins;
pub mod pipeline;
pub mod scenario;
pub mod site;
pub mod synth;

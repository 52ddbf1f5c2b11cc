//! The end-to-end tests of the tools: one binary (one link) for every file below; each module
//! is one subject, named as the file. `alloc` is its own binary (it counts allocations).

#[allow(dead_code)]
mod common;

mod accuracy;
mod calibrate;
mod cli_decode;
mod cli_errors;
mod cli_ins;
mod clocks;
mod datums;
mod drone;
mod extraction;
mod faults;
mod georef;
mod hesai;
mod layers;
mod multi_file;
mod nav_errors;
mod ouster;
mod plan;
mod plan_site;
mod posmv;
mod priors;
mod progress;
mod replay;
mod report_html;
mod rig;
mod ros2_bags;
mod scanners_sim;
mod sensor_stats;
mod sim;
mod site_errors;
mod site_import;
mod velodyne_models;
mod verdict;
mod vn200_configure;
mod vn200_real_files;

//! `spherecal bag info BAG [--lidar-topic T] [--ins-topic T]`.

use super::print_or_fail;
use std::path::PathBuf;
use std::process::ExitCode;

/// ROS 2 bags (rosbag2: MCAP or sqlite3).
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

/// What to do.
#[derive(clap::Subcommand, Debug)]
pub enum What {
    /// List a bag's storage, files and topics (type, messages, span, rate) and what
    /// `calibrate --bag` / `georef --bag` read of it and why.
    Info(InfoArgs),
}

/// `bag info`.
#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The bag: a rosbag2 folder (with its metadata.yaml), a `.mcap` or a `.db3`.
    pub bag: PathBuf,
    /// The topic of VelodyneScan messages to read (default: the only one).
    #[arg(long)]
    pub lidar_topic: Option<String>,
    /// The topic of CommonGroup messages to read (default: the only one).
    #[arg(long)]
    pub ins_topic: Option<String>,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    match a.what {
        What::Info(i) => print_or_fail(
            "bag info",
            crate::bag::open(
                &i.bag,
                i.lidar_topic.as_deref(),
                i.ins_topic.as_deref(),
                true,
            )
            .map(|b| b.describe()),
        ),
    }
}

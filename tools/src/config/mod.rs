//! The TOML files people write: a rig's board, a survey's site, a simulated scenario. Every
//! file is read strictly (unknown keys refused) and checked (non-finite or impossible values
//! refused with the key's name).

use serde::{Deserialize, Serialize};
use spherecal::georef::DegM;

pub mod board;
pub mod checks;
pub mod crs;
pub mod datum;
#[allow(clippy::all, missing_docs)]
#[rustfmt::skip]
pub mod epsg_tables;
pub mod geoid;
pub mod goal;
pub mod lidar;
pub mod nav_errors;
pub mod nav_source;
pub mod scenario;
pub mod scenery;
pub mod site;
pub mod survey;

/// A mounting as the files write it: boresight roll, pitch, heading [deg] (R_li) and lever arm
/// x, y, z [m] in the INS body frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountDegM {
    /// Roll, pitch, heading [deg].
    pub boresight_deg: [f64; 3],
    /// x, y, z [m].
    pub lever_arm_m: [f64; 3],
}

impl MountDegM {
    /// Roll, pitch, heading [deg], x, y, z [m]: the order the solver takes.
    pub fn deg_m(&self) -> DegM {
        let (b, l) = (self.boresight_deg, self.lever_arm_m);
        DegM([b[0], b[1], b[2], l[0], l[1], l[2]])
    }
}

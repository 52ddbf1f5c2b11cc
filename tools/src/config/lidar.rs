//! What the solver takes from the LiDAR: the time between two firings of one laser (the
//! extraction's scan lines) and its beam's footprint (the bloom the least squares take out of
//! each residual, `spherecal::calib::footprint`), with the site's `[lidar]` over the model's.

use serde::{Deserialize, Serialize};
use spherecal::calib::footprint::Footprint;

/// The site's `[lidar]` (optional): what the LiDAR's model does not say for this unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteLidar {
    /// Full-angle beam divergence along and across the scan [mrad] (the manual's beam
    /// divergence table; the Velodynes' 3.0, 1.5 when not given). `[0, 0]`: an ideal ray.
    pub beam_divergence_mrad: [f64; 2],
}

impl SiteLidar {
    /// Its footprint (`None` for an ideal ray).
    pub fn footprint(&self) -> Option<Footprint> {
        let [a, c] = self.beam_divergence_mrad;
        (a > 0.0 && c > 0.0).then(|| Footprint::of_divergence([a * 1e-3, c * 1e-3]))
    }

    /// Whether the values can be a beam's: finite, both zero or both positive, under 20 mrad.
    pub fn valid(&self) -> bool {
        let d = self.beam_divergence_mrad;
        d.iter().all(|x| x.is_finite() && (0.0..20.0).contains(x)) && ((d[0] > 0.0) == (d[1] > 0.0))
    }
}

/// What the solver takes from the LiDAR.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Lidar {
    /// The time between two firings of one laser [ns]; `None` while unknown.
    pub firing_ns: Option<i64>,
    /// The beam's footprint; `None`: no divergence known (an ideal ray).
    pub footprint: Option<Footprint>,
}

impl Lidar {
    /// A Velodyne: its laser period and the manuals' 3.0 x 1.5 mrad beam
    /// ([`Footprint::VELODYNE`]).
    pub fn velodyne(m: spherecal::velodyne::Model) -> Self {
        Self {
            firing_ns: Some(i64::from(m.laser_period_ns())),
            footprint: Some(Footprint::VELODYNE),
        }
    }

    /// Another LiDAR (a Hesai, an Ouster): its laser period; its beam's divergence unknown
    /// until a manual gives it (a site's `[lidar]` can).
    pub fn other(firing_ns: Option<i64>) -> Self {
        Self {
            firing_ns,
            footprint: None,
        }
    }

    /// The simulator's scanner.
    pub fn of_scanner(s: spherecal::sim::Scanner) -> Self {
        match s.velodyne() {
            Some(m) => Self::velodyne(m),
            None => Self::other(Some(i64::from(s.laser_period_ns()))),
        }
    }

    /// The same with the site's `[lidar]` over the model's beam.
    pub fn under(self, site: Option<&SiteLidar>) -> Self {
        match site {
            Some(l) => Self {
                footprint: l.footprint(),
                ..self
            },
            None => self,
        }
    }
}

//! Simulation scenarios: the TOML a surveyor edits (`spherecal synth --print-scenario table1`),
//! its validation (unknown keys and impossible values are rejected by name), and the built-ins.

pub use crate::config::checks::ScenarioError;
use crate::config::scenery::{
    BallSpec, BoxSpec, PlaneSpec, PoleSpec, ScatterSpec, Scene, SceneSpec, Stand, VesselSpec,
    WaterSpec,
};
mod validate;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use spherecal::frames::{Geodetic, LocalFrame};
use spherecal::georef::Mount;
use spherecal::sim::ins::{AttitudeOutput, Outage};
use spherecal::sim::trajectory::Sample;
use spherecal::sim::{InsConfig, LidarConfig, Motion, Object, Pass, Shape};
use spherecal::time::{days_from_civil, unix_ns_to_gps, GpsTime};
use spherecal::velodyne::ReturnMode;

/// The built-in scenarios: name and TOML text.
pub const BUILTIN: &[(&str, &str)] = &[
    ("table1", include_str!("../../../scenarios/table1.toml")),
    (
        "table1-bare",
        include_str!("../../../scenarios/table1-bare.toml"),
    ),
    ("pontoon", include_str!("../../../scenarios/pontoon.toml")),
    (
        "pontoon-noisy",
        include_str!("../../../scenarios/pontoon-noisy.toml"),
    ),
    (
        "table1-noisy",
        include_str!("../../../scenarios/table1-noisy.toml"),
    ),
    (
        "table1-real",
        include_str!("../../../scenarios/table1-real.toml"),
    ),
    ("drone", include_str!("../../../scenarios/drone.toml")),
    (
        "drone-noisy",
        include_str!("../../../scenarios/drone-noisy.toml"),
    ),
];

/// A scenario file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Name, for reports.
    pub name: String,
    /// Seed of every random draw.
    pub seed: u64,
    /// UTC start of the scan, `YYYY-MM-DDTHH:MM:SSZ`.
    pub start_utc: String,
    /// GPS - UTC [s].
    pub leap_seconds: i64,
    /// Site origin.
    pub site: SiteOrigin,
    /// Target spheres.
    pub sphere: Vec<SphereSpec>,
    /// True and a-priori mounting.
    pub mount: MountSpec,
    /// LiDAR settings.
    pub lidar: LidarSpec,
    /// INS settings.
    pub ins: InsSpec,
    /// Vessel path.
    pub trajectory: TrajectorySpec,
    /// Boxes: deck slabs, quay walls, buildings, vehicles, crates.
    #[serde(default, rename = "box", skip_serializing_if = "Vec::is_empty")]
    pub boxes: Vec<BoxSpec>,
    /// Cylinders: bollards, lamp posts, people (with `velocity_ned_mps`: walking).
    #[serde(default, rename = "pole", skip_serializing_if = "Vec::is_empty")]
    pub poles: Vec<PoleSpec>,
    /// Flat rectangles.
    #[serde(default, rename = "plane", skip_serializing_if = "Vec::is_empty")]
    pub planes: Vec<PlaneSpec>,
    /// Balls that are not targets: buoys, fenders (decoys).
    #[serde(default, rename = "ball", skip_serializing_if = "Vec::is_empty")]
    pub balls: Vec<BallSpec>,
    /// Random clutter regions.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub scatter: Vec<ScatterSpec>,
    /// The water surface.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub water: Option<WaterSpec>,
    /// The vessel's own structure.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vessel: Option<VesselSpec>,
}

/// Site origin (WGS84).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteOrigin {
    /// Latitude [deg].
    pub lat_deg: f64,
    /// Longitude [deg].
    pub lon_deg: f64,
    /// Ellipsoidal height [m].
    pub h_m: f64,
}

/// A target sphere.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereSpec {
    /// Name.
    pub id: String,
    /// Centre, NED from the origin [m].
    pub ned_m: [f64; 3],
    /// Radius [m].
    pub radius_m: f64,
    /// What it stands on: `none`, `pole` (one 25 mm pole) or `tripod` (three legs, a head and
    /// a spigot).
    #[serde(default = "default_stand")]
    pub stand: String,
    /// NED down of the floor the stand stands on [m] (default: 1.2 m below the sphere).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stand_down_m: Option<f64>,
    /// Diffuse reflectivity (default 0.8: a white painted sphere).
    #[serde(default = "default_sphere_rho")]
    pub reflectivity: f64,
}

impl SphereSpec {
    /// NED down of the floor under it [m]: `stand_down_m`, else the sphere's bottom when it
    /// stands on nothing (it rests on the floor), else 1.2 m below its bottom.
    pub fn floor_down_m(&self) -> f64 {
        let bottom = self.ned_m[2] + self.radius_m;
        self.stand_down_m.unwrap_or(if self.stand == "none" {
            bottom
        } else {
            bottom + 1.2
        })
    }
}

fn default_stand() -> String {
    "none".into()
}

fn default_sphere_rho() -> f64 {
    0.8
}

/// A-priori mounting and the window margin.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Apriori {
    /// Roll, pitch, heading [deg].
    pub boresight_deg: [f64; 3],
    /// x, y, z [m].
    pub lever_arm_m: [f64; 3],
    /// Returns within radius + this of a centre are kept [m].
    pub window_margin_m: f64,
}

/// True and a-priori mounting.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountSpec {
    /// The truth.
    pub truth: super::MountDegM,
    /// What the surveyor believes before calibrating.
    pub apriori: Apriori,
}

/// LiDAR settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LidarSpec {
    /// The model: `vlp16` (default), `puck-hires`, `hdl32e`, `vlp32c`.
    #[serde(default = "default_model")]
    pub model: String,
    /// 300..=1200.
    pub rpm: f64,
    /// `strongest`, `last` or `dual`.
    pub return_mode: String,
    /// Range noise, 1 sigma [m].
    pub range_sigma_m: f64,
    /// Probability of a lost data packet.
    pub drop_prob: f64,
    /// Full-angle beam divergence along / across the scan [mrad] (VLP-16: 3.0, 1.5); zero: an
    /// ideal ray (no footprint, no mixed pixels).
    #[serde(default)]
    pub beam_divergence_mrad: [f64; 2],
    /// Echoes closer than this merge into a mixed pixel [m] (default 1.0).
    #[serde(default = "default_merge")]
    pub merge_distance_m: f64,
    /// Range noise grows at grazing incidence (needs a beam divergence).
    #[serde(default)]
    pub incidence_noise: bool,
    /// The footprint rendered as the beam's Gaussian on a grid of sub-rays where it touches a
    /// sphere, five sub-rays at other edges (default); `false`: five sub-rays at every edge (a
    /// staircase the calibration's model of the bloom does not follow; the seeded fault
    /// tests' world).
    #[serde(default = "default_grid")]
    pub footprint_grid: bool,
    /// Range walk: the bias of a zero-intensity return [m] (default 0).
    #[serde(default)]
    pub range_walk_m: f64,
    /// The receiver's gain on the calibrated intensity (default 1: a white surface at normal
    /// incidence reads its reflectivity x 100; more saturates bright returns at 100).
    #[serde(default = "default_one", skip_serializing_if = "is_one")]
    pub intensity_gain: f64,
    /// Per-return intensity scatter, the sigma of a log-normal factor (default 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub intensity_scatter: f64,
    /// Probability that an arc over a sphere starts weak and loses its second firing (the
    /// leading-edge dropout of real VLP-16 returns; default 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub edge_dropout: f64,
    /// Probability that a return off the scenery (anything but the target spheres) is
    /// reported (default 1); less thins the scene uniformly, for clutter-density sweeps.
    #[serde(default = "default_keep")]
    pub clutter_keep: f64,
    /// The sensor's clock error [s]: its timestamps are the true time plus this (default 0).
    #[serde(default)]
    pub clock_offset_s: f64,
    /// The PPS state its position packets report: `locked` (default), `absent`, `syncing`,
    /// `error`.
    #[serde(default = "default_pps")]
    pub pps: String,
    /// Its GPS has a fix: `$GPRMC` status A (default), else V.
    #[serde(default = "default_true")]
    pub rmc_valid: bool,
    /// Its clock's rate error without PPS [ppm]: the error grows by this from the scan's start
    /// (default 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub clock_drift_ppm: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn default_one() -> f64 {
    1.0
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

fn default_ins_kind() -> String {
    "vn200".into()
}

fn default_model() -> String {
    "vlp16".into()
}

fn default_pps() -> String {
    "locked".into()
}

fn default_true() -> bool {
    true
}

fn default_keep() -> f64 {
    1.0
}

fn default_merge() -> f64 {
    1.0
}

fn default_grid() -> bool {
    true
}

/// INS settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InsSpec {
    /// `vn200` (default: ins.bin and ins.vnlog only) or `posmv`: also an Applanix POS MV's
    /// real-time groups, as its UDP datagrams (port 5602) in lidar.pcap and as a logged
    /// stream, ins.posmv.
    #[serde(default = "default_ins_kind")]
    pub kind: String,
    /// Output rate [Hz].
    pub rate_hz: f64,
    /// Attitude noise, 1 sigma [deg].
    pub att_sigma_deg: f64,
    /// Position noise, 1 sigma [m].
    pub pos_sigma_m: f64,
    /// Errors that wander, on top of the white noise above (a real GNSS/INS solution's):
    /// `[ins.correlated]`, a preset and/or the sigmas and correlation time.
    #[serde(default, skip_serializing_if = "is_default_correlated")]
    pub correlated: crate::config::nav_errors::CorrelatedSpec,
    /// INS clock error [s].
    pub time_offset_s: f64,
    /// Probability of a corrupted serial byte.
    pub corrupt_prob: f64,
    /// The VN-200 states its own accuracy in every frame (Attitude.YprU, Ins.PosU: what the
    /// boards configure; default true); false: the Common group only, as a unit configured
    /// by hand often sends.
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub states_accuracy: bool,
    /// The attitude field the VN-200 sends: `yaw_pitch_roll` (default) or `quaternion`.
    #[serde(
        default = "default_attitude",
        skip_serializing_if = "is_default_attitude"
    )]
    pub attitude: String,
    /// Steps of the INS clock: `[[at_s, step_s], ...]`, at most four: from `at_s` seconds after
    /// the scan's start on, its time is off by a further `step_s` (negative: it goes back).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub clock_steps: Vec<[f64; 2]>,
    /// Jumps of the reported position: `[[at_s, north_m, east_m, down_m], ...]`, at most four:
    /// from `at_s` seconds after the scan's start on, the INS's position is off by a further
    /// (north, east, down) (a lost fix: a fault, not noise).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub position_jumps: Vec<[f64; 4]>,
    /// Silent GNSS outages: `[[at_s, duration_s, north_m, east_m, down_m, roll_deg, pitch_deg,
    /// heading_deg], ...]`, at most four: from `at_s` seconds after the scan's start the INS
    /// coasts, its error growing as the square of the time to the given peak at `duration_s`,
    /// then snapping back when the fix returns; the status word says nothing (an RTK loss).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outages: Vec<[f64; 8]>,
}

fn is_default_correlated(c: &crate::config::nav_errors::CorrelatedSpec) -> bool {
    *c == crate::config::nav_errors::CorrelatedSpec::default()
}

fn yes() -> bool {
    true
}

fn is_true(b: &bool) -> bool {
    *b
}

fn default_attitude() -> String {
    "yaw_pitch_roll".into()
}

fn is_default_attitude(s: &String) -> bool {
    s == "yaw_pitch_roll"
}

/// One pass.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PassSpec {
    /// Start north, east [m].
    pub start_ne_m: [f64; 2],
    /// Course [deg].
    pub heading_deg: f64,
    /// Speed [m/s].
    pub speed_mps: f64,
    /// Duration [s].
    pub duration_s: f64,
    /// The INS's down on this pass [m] (default `trajectory.ins_down_m`): a drone's second
    /// flight height.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub down_m: Option<f64>,
}

/// The vessel's path and motion.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectorySpec {
    /// NED down of the INS at rest [m].
    pub ins_down_m: f64,
    /// Turn duration between passes [s].
    pub turn_s: f64,
    /// Roll amplitude [deg], period [s].
    pub roll: [f64; 2],
    /// Pitch amplitude [deg], period [s].
    pub pitch: [f64; 2],
    /// Yaw amplitude [deg], period [s].
    pub yaw: [f64; 2],
    /// Heave amplitude [m], period [s].
    pub heave: [f64; 2],
    /// The passes (none when `file` is given).
    #[serde(default)]
    pub pass: Vec<PassSpec>,
    /// A recorded trajectory instead of the passes: an SBET file (`.sbet`, `.out`; dated by
    /// `start_utc`'s GPS week) or a CSV `time_s,north_m,east_m,down_m,roll_deg,pitch_deg,heading_deg`
    /// (seconds after `start_utc`, site NED, body -> site NED attitude).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
}

/// Parse `YYYY-MM-DDTHH:MM:SS[.fff]Z` to Unix nanoseconds.
pub fn parse_utc(s: &str) -> Option<i64> {
    let s = s.strip_suffix('Z')?;
    let (date, time) = s.split_once('T')?;
    let mut d = date.split('-');
    let (y, mo, da): (i32, u8, u8) = (
        d.next()?.parse().ok()?,
        d.next()?.parse().ok()?,
        d.next()?.parse().ok()?,
    );
    let mut t = time.split(':');
    let (h, mi): (i64, i64) = (t.next()?.parse().ok()?, t.next()?.parse().ok()?);
    let sec: f64 = t.next()?.parse().ok()?;
    if !(1..=12).contains(&mo)
        || !(1..=31).contains(&da)
        || !(0..24).contains(&h)
        || !(0..60).contains(&mi)
        || !(0.0..61.0).contains(&sec)
    {
        return None;
    }
    let days = days_from_civil(y, mo, da);
    Some((days * 86_400 + h * 3600 + mi * 60) * 1_000_000_000 + (sec * 1e9).round() as i64)
}

impl Scenario {
    /// A built-in scenario by name, or a TOML file by path.
    pub fn load(name_or_path: &str) -> Result<Self, ScenarioError> {
        if let Some((_, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
            return Self::from_toml(text);
        }
        let text = std::fs::read_to_string(name_or_path).map_err(|e| {
            let names: Vec<&str> = BUILTIN.iter().map(|b| b.0).collect();
            ScenarioError(format!(
                "{name_or_path}: not a built-in scenario ({}) and not readable: {e}",
                names.join(", ")
            ))
        })?;
        Self::from_toml(&text).map_err(|e| ScenarioError(format!("{name_or_path}: {e}")))
    }

    /// Parse and validate.
    pub fn from_toml(text: &str) -> Result<Self, ScenarioError> {
        let s: Scenario =
            toml::from_str(text).map_err(|e| ScenarioError(e.to_string().trim().to_string()))?;
        s.validate()?;
        Ok(s)
    }

    /// Total scanning time [s] (of the passes; a recorded trajectory's is its span).
    pub fn duration_s(&self) -> f64 {
        let tr = &self.trajectory;
        tr.pass.iter().map(|p| p.duration_s).sum::<f64>()
            + tr.turn_s * tr.pass.len().saturating_sub(1) as f64
    }

    /// The scanner simulated (`lidar.model`: a Velodyne's key, `xt16` or `xt32`).
    pub fn scanner(&self) -> Option<spherecal::sim::Scanner> {
        spherecal::sim::Scanner::parse(&self.lidar.model)
    }

    /// The Velodyne model, when the scanner is one.
    pub fn model(&self) -> Option<spherecal::velodyne::Model> {
        self.scanner().and_then(|s| s.velodyne())
    }

    /// The return mode.
    pub fn return_mode(&self) -> Option<ReturnMode> {
        match self.lidar.return_mode.as_str() {
            "strongest" => Some(ReturnMode::Strongest),
            "last" => Some(ReturnMode::Last),
            "dual" => Some(ReturnMode::Dual),
            _ => None,
        }
    }

    /// The site frame.
    pub fn site(&self) -> LocalFrame {
        LocalFrame::new(Geodetic::from_deg(
            self.site.lat_deg,
            self.site.lon_deg,
            self.site.h_m,
        ))
    }

    /// GPS time of the scan start.
    pub fn start(&self) -> GpsTime {
        unix_ns_to_gps(parse_utc(&self.start_utc).unwrap_or(0), self.leap_seconds)
    }

    /// The true time offset between the clocks [s]: INS time = LiDAR time + this (the INS
    /// clock's error minus the LiDAR clock's).
    pub fn true_time_offset_s(&self) -> f64 {
        self.ins.time_offset_s - self.lidar.clock_offset_s
    }

    /// The PPS state of the position packets.
    pub fn pps(&self) -> Option<spherecal::velodyne::PpsStatus> {
        use spherecal::velodyne::PpsStatus;
        match self.lidar.pps.as_str() {
            "absent" => Some(PpsStatus::Absent),
            "syncing" => Some(PpsStatus::Synchronizing),
            "locked" => Some(PpsStatus::Locked),
            "error" => Some(PpsStatus::Error),
            _ => None,
        }
    }

    /// The true mount.
    pub fn truth_mount(&self) -> Mount {
        let t = &self.mount.truth;
        Mount::new(t.boresight_deg.map(f64::to_radians), t.lever_arm_m)
    }

    /// The passes.
    pub fn passes(&self) -> Vec<Pass> {
        self.trajectory
            .pass
            .iter()
            .map(|p| Pass {
                start: p.start_ne_m,
                heading: p.heading_deg.to_radians(),
                speed: p.speed_mps,
                duration: p.duration_s,
                down: p.down_m.map_or(0.0, |d| d - self.trajectory.ins_down_m),
            })
            .collect()
    }

    /// Wave motion.
    pub fn motion(&self) -> Motion {
        let tr = &self.trajectory;
        let deg = |w: [f64; 2]| (w[0].to_radians(), w[1]);
        Motion {
            roll: deg(tr.roll),
            pitch: deg(tr.pitch),
            yaw: deg(tr.yaw),
            heave: (tr.heave[0], tr.heave[1]),
        }
    }

    /// The scenery keys as one spec.
    pub fn scene_spec(&self) -> SceneSpec<'_> {
        SceneSpec {
            boxes: &self.boxes,
            poles: &self.poles,
            planes: &self.planes,
            balls: &self.balls,
            scatter: &self.scatter,
            water: self.water.as_ref(),
            vessel: self.vessel.as_ref(),
        }
    }

    /// The scene: the target spheres first (object i is sphere i), then their stands, then
    /// the scenery, each object with its name and kind.
    pub fn scene(&self) -> Scene {
        let mut sc = Scene::default();
        for (i, s) in self.sphere.iter().enumerate() {
            let shape = Shape::Sphere {
                c: Vector3::from(s.ned_m),
                r: s.radius_m,
            };
            sc.objects
                .push(Object::new(shape, Some(i as u8)).with_reflectivity(s.reflectivity));
            sc.names.push(s.id.clone());
            sc.kinds.push("sphere");
        }
        for s in &self.sphere {
            let stand = Stand::parse(&s.stand).unwrap_or(Stand::None);
            sc.add_stand(
                &s.id,
                stand,
                Vector3::from(s.ned_m),
                s.radius_m,
                s.floor_down_m(),
            );
        }
        let centres: Vec<Vector3<f64>> =
            self.sphere.iter().map(|s| Vector3::from(s.ned_m)).collect();
        sc.add_scenery(&self.scene_spec(), &centres);
        sc
    }

    /// The scene's objects.
    pub fn objects(&self) -> Vec<Object> {
        self.scene().objects
    }

    /// The simulated world of this scenario over its `passes()` and `objects()`.
    pub fn world<'a>(
        &self,
        samples: &'a [Sample],
        passes: &'a [Pass],
        objects: &'a [Object],
    ) -> spherecal::sim::World<'a> {
        spherecal::sim::World {
            site: self.site(),
            trajectory: spherecal::sim::Trajectory {
                samples,
                passes,
                turn: self.trajectory.turn_s,
                down: self.trajectory.ins_down_m,
                motion: self.motion(),
            },
            objects,
            water: self.water.as_ref().map(WaterSpec::water),
            mount: self.truth_mount(),
            start: self.start(),
            leap_seconds: self.leap_seconds,
        }
    }

    /// Run `f` with the simulated world of this scenario.
    pub fn with_world<R>(
        &self,
        f: impl FnOnce(&spherecal::sim::World<'_>) -> R,
    ) -> Result<R, ScenarioError> {
        let (samples, passes, objects) = (self.samples()?, self.passes(), self.objects());
        Ok(f(&self.world(&samples, &passes, &objects)))
    }

    /// The recorded trajectory of `trajectory.file`, in the site frame (empty without one).
    pub fn samples(&self) -> Result<Vec<Sample>, ScenarioError> {
        let Some(path) = &self.trajectory.file else {
            return Ok(Vec::new());
        };
        let err = |e: String| ScenarioError(format!("trajectory.file {path}: {e}"));
        let site = self.site();
        let start = self.start();
        let mut out = Vec::new();
        if path.ends_with(".csv") {
            let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
            let mut lines = text.lines();
            let head = lines.next().unwrap_or("");
            if head.trim() != "time_s,north_m,east_m,down_m,roll_deg,pitch_deg,heading_deg" {
                return Err(err("line 1: expected the header time_s,north_m,east_m,down_m,roll_deg,pitch_deg,heading_deg".into()));
            }
            for (i, l) in lines.enumerate() {
                let v: Vec<f64> = l
                    .split(',')
                    .map(|x| x.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|e| err(format!("line {}: {e}", i + 2)))?;
                if v.len() != 7 || v.iter().any(|x| !x.is_finite()) {
                    return Err(err(format!("line {}: expected 7 finite numbers", i + 2)));
                }
                out.push(Sample {
                    t: v[0],
                    position: Vector3::new(v[1], v[2], v[3]),
                    rph: [v[4].to_radians(), v[5].to_radians(), v[6].to_radians()],
                });
            }
        } else {
            let f = std::fs::File::open(path).map_err(|e| err(e.to_string()))?;
            let mut rd = spherecal_hal::sbet::SbetReader::new(std::io::BufReader::new(f));
            let week = start.week_tow_ns().0 as u16;
            while let Some(r) = rd.next_record().map_err(|e| err(e.to_string()))? {
                let Some(t) = r.time(week) else { continue };
                let g = spherecal::frames::Geodetic {
                    lat: r.lat,
                    lon: r.lon,
                    h: r.h,
                };
                let rot = site.from_local_level(g.lat, g.lon)
                    * spherecal::frames::rotation(r.roll, r.pitch, r.heading());
                out.push(Sample {
                    t: (t.0 - start.0) as f64 * 1e-9,
                    position: site.to_ned(&g),
                    rph: spherecal::frames::roll_pitch_heading(&rot),
                });
            }
        }
        if out.len() < 2 || out.windows(2).any(|w| w[1].t <= w[0].t) {
            return Err(err("needs two or more samples in increasing time".into()));
        }
        Ok(out)
    }

    /// LiDAR configuration.
    pub fn lidar_config(&self) -> LidarConfig {
        let scanner = self.scanner().unwrap_or_default();
        LidarConfig {
            scanner,
            max_range: scanner.max_range_m(),
            rpm: self.lidar.rpm,
            mode: self.return_mode().unwrap_or(ReturnMode::Strongest),
            range_sigma: self.lidar.range_sigma_m,
            drop_prob: self.lidar.drop_prob,
            divergence: self.lidar.beam_divergence_mrad.map(|x| x * 1e-3),
            merge_distance: self.lidar.merge_distance_m,
            incidence_noise: self.lidar.incidence_noise,
            footprint_grid: self.lidar.footprint_grid,
            range_walk: self.lidar.range_walk_m,
            intensity_gain: self.lidar.intensity_gain,
            intensity_scatter: self.lidar.intensity_scatter,
            edge_dropout: self.lidar.edge_dropout,
            clutter_keep: self.lidar.clutter_keep,
            clock_offset_ns: (self.lidar.clock_offset_s * 1e9).round() as i64,
            clock_drift_ppm: self.lidar.clock_drift_ppm,
            pps: self.pps().unwrap_or(spherecal::velodyne::PpsStatus::Locked),
            rmc_valid: self.lidar.rmc_valid,
            seed: self.seed.wrapping_mul(2).wrapping_add(1),
            ..LidarConfig::default()
        }
    }

    /// INS configuration.
    pub fn ins_config(&self) -> InsConfig {
        InsConfig {
            rate_hz: self.ins.rate_hz,
            att_sigma: self.ins.att_sigma_deg.to_radians(),
            pos_sigma: self.ins.pos_sigma_m,
            // Checked by `validate`; a scenario built in code with a bad table gets none.
            correlated: self
                .ins
                .correlated
                .resolve("ins.correlated")
                .unwrap_or_default(),
            time_offset_ns: (self.ins.time_offset_s * 1e9).round() as i64,
            corrupt_prob: self.ins.corrupt_prob,
            seed: self.seed.wrapping_mul(2).wrapping_add(2),
            attitude: if self.ins.attitude == "quaternion" {
                AttitudeOutput::Quaternion
            } else {
                AttitudeOutput::YawPitchRoll
            },
            stated: self.ins.states_accuracy,
            time_steps: {
                let mut steps = [(i64::MAX, 0); 4];
                for (k, [at, d]) in self.ins.clock_steps.iter().take(4).enumerate() {
                    steps[k] = (
                        self.start().0 + (at * 1e9).round() as i64,
                        (d * 1e9).round() as i64,
                    );
                }
                steps
            },
            outages: {
                let mut o = [Outage::NONE; 4];
                for (k, v) in self.ins.outages.iter().take(4).enumerate() {
                    o[k] = Outage {
                        start: self.start().0 + (v[0] * 1e9).round() as i64,
                        duration_ns: (v[1] * 1e9).round() as i64,
                        peak: [
                            v[2],
                            v[3],
                            v[4],
                            v[5].to_radians(),
                            v[6].to_radians(),
                            v[7].to_radians(),
                        ],
                    };
                }
                o
            },
            position_jumps: {
                let mut jumps = [(i64::MAX, [0.0; 3]); 4];
                for (k, [at, n, e, d]) in self.ins.position_jumps.iter().take(4).enumerate() {
                    jumps[k] = (self.start().0 + (at * 1e9).round() as i64, [*n, *e, *d]);
                }
                jumps
            },
            ..InsConfig::default()
        }
    }
}

#[cfg(test)]
mod tests;

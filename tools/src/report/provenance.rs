//! Where a calibration came from (`report.json` `provenance`): the command line, the build, each
//! input file (bytes, SHA-256, the GPS span its data cover), the site (its file, CRS, heights,
//! datums and the transformation applied between them) and each sphere's surveyed coordinates
//! as the site gives them: what a report filed with a survey must let a checker redo.

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::Path;

/// The build: the crate's version and, built from a checkout, its git commit.
pub fn version() -> String {
    match option_env!("SPHERECAL_GIT") {
        Some(g) if !g.is_empty() => format!("{} ({g})", env!("CARGO_PKG_VERSION")),
        _ => env!("CARGO_PKG_VERSION").to_string(),
    }
}

/// One input file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct InputFile {
    /// What it is: `lidar`, `ins`, `accuracy`.
    pub role: String,
    /// Its path as given.
    pub path: String,
    /// Its size.
    pub bytes: u64,
    /// Its SHA-256, hex.
    pub sha256: String,
    /// The GPS seconds its role's data cover (first, last), when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gps_span_s: Option<(f64, f64)>,
}

impl InputFile {
    /// `path` read whole for its hash (a folder: each file in it, in name order, into one hash);
    /// no span (the caller adds it where the role has one).
    pub fn of(role: &str, path: &Path) -> Result<Self, String> {
        let mut h = Sha256::new();
        let mut bytes = 0u64;
        let mut files: Vec<std::path::PathBuf> = if path.is_dir() {
            std::fs::read_dir(path)
                .map_err(|e| format!("{}: {e}", path.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect()
        } else {
            vec![path.to_path_buf()]
        };
        files.sort();
        let mut buf = vec![0u8; 1 << 16];
        for f in files {
            let mut r = std::fs::File::open(&f).map_err(|e| format!("{}: {e}", f.display()))?;
            loop {
                let n = r
                    .read(&mut buf)
                    .map_err(|e| format!("{}: {e}", f.display()))?;
                if n == 0 {
                    break;
                }
                h.update(&buf[..n]);
                bytes += n as u64;
            }
        }
        Ok(Self {
            role: role.into(),
            path: path.display().to_string(),
            bytes,
            sha256: h.finalize().iter().map(|b| format!("{b:02x}")).collect(),
            gps_span_s: None,
        })
    }
}

/// The input files hashed on a thread of their own. Hashing reads every byte again (62 MB of
/// pcap: ~45 ms of SHA-256); started once the data are collected, it runs on the core the
/// single-threaded solve leaves idle, and is joined when the report is written.
#[derive(Debug)]
pub struct Hashing {
    /// (role, path) in the report's order, before the thread starts.
    files: Vec<(String, std::path::PathBuf)>,
    running: Option<std::thread::JoinHandle<Result<Vec<InputFile>, String>>>,
}

impl Hashing {
    /// The files to hash, `(role, path)`, not yet started.
    pub fn new(files: Vec<(String, std::path::PathBuf)>) -> Self {
        Self {
            files,
            running: None,
        }
    }

    /// Start hashing (again: nothing).
    pub fn start(&mut self) {
        if self.running.is_none() {
            let files = std::mem::take(&mut self.files);
            self.running = Some(std::thread::spawn(move || {
                // The solve's own work goes first; the hashing takes what the cores leave.
                #[cfg(target_os = "linux")]
                let _ = rustix::process::setpriority_process(Some(rustix::thread::gettid()), 19);
                files
                    .iter()
                    .map(|(role, path)| InputFile::of(role, path))
                    .collect()
            }));
        }
    }

    /// Each file's size and hash (hashed now if never started), without spans.
    pub fn finish(mut self) -> Result<Vec<InputFile>, String> {
        self.start();
        match self.running.take().map(std::thread::JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) | None => Err("the inputs' hashing thread failed".into()),
        }
    }
}

/// A sphere as the site gives it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SurveyedSphere {
    /// Its id.
    pub id: String,
    /// Easting, northing in the site's CRS (its units), when the site gives them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub easting_northing: Option<(f64, f64)>,
    /// The height as surveyed, in metres (ellipsoidal or orthometric: the site's `height`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_m: Option<f64>,
    /// Latitude, longitude [deg], ellipsoidal height [m] on the site's datum.
    pub lat_lon_h: (f64, f64, f64),
    /// Radius [m].
    pub radius_m: f64,
    /// The survey's 1 sigma [m], when given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_m: Option<f64>,
}

/// The site.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SiteProvenance {
    /// The site file.
    pub file: InputFile,
    /// The horizontal CRS (`EPSG:n`), when the site gives its spheres in one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crs: Option<String>,
    /// What its heights are, their unit and the geoid or vertical CRS.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heights: Option<String>,
    /// The survey's datum.
    pub survey_datum: String,
    /// The datums line as printed: the trajectory's datum and the transformation applied.
    pub transformation: String,
    /// How far the transformation moved the site's origin [m] (0: none applied).
    pub transformation_m: f64,
    /// The spheres.
    pub spheres: Vec<SurveyedSphere>,
}

/// `report.json` `provenance`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Provenance {
    /// The command line.
    pub command: Vec<String>,
    /// The build ([`version`]).
    pub version: String,
    /// When the report was made (UTC, ISO 8601).
    pub made_utc: String,
    /// The input files.
    pub inputs: Vec<InputFile>,
    /// The site.
    pub site: SiteProvenance,
    /// The rig's board, its vessel and the operator (`calibrate --board`, `--operator`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub platform: Option<Platform>,
}

/// `provenance.platform`: what carried the sensors and who ran the survey.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Platform {
    /// The board file, its bytes and SHA-256 (`None`: no `--board`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board: Option<InputFile>,
    /// The board's `name`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board_name: Option<String>,
    /// The board's `vessel`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vessel: Option<String>,
    /// `--operator`, else the board's `operator`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub operator: Option<String>,
}

impl Platform {
    /// From the board file (path, as loaded) and the operator given; `None` without either.
    pub fn of(
        board: Option<&(std::path::PathBuf, crate::config::board::Board)>,
        operator: Option<&str>,
    ) -> Result<Option<Self>, String> {
        if board.is_none() && operator.is_none() {
            return Ok(None);
        }
        Ok(Some(Self {
            board: board.map(|(p, _)| InputFile::of("board", p)).transpose()?,
            board_name: board.map(|b| b.1.name.clone()),
            vessel: board.and_then(|b| b.1.vessel.clone()),
            operator: operator
                .map(str::to_string)
                .or_else(|| board.and_then(|b| b.1.operator.clone())),
        }))
    }
}

impl SiteProvenance {
    /// The site file at `path`, loaded as `site` (its own datum) and taken to the trajectory's
    /// as `moved` (`line`: the datums line printed).
    pub fn of(
        path: &Path,
        site: &crate::config::site::Site,
        moved: &crate::config::site::Site,
        line: &str,
    ) -> Result<Self, String> {
        let crs = site.crs.as_ref();
        let heights = crs.map(|c| {
            let unit = c.height_unit.unwrap_or_default();
            let mut w = format!("{:?} heights", c.height).to_lowercase();
            if unit != crate::config::crs::HeightUnit::Metre {
                w.push_str(&format!(
                    ", surveyed in {} (converted to metres at import)",
                    unit.key()
                ));
            }
            if let Some(n) = c.geoid_undulation_m {
                w.push_str(&format!(", N = {n} m"));
            }
            if let Some(g) = &c.geoid_grid {
                w.push_str(&format!(", N from the grid {g}"));
            }
            if let Some(v) = c.vertical_epsg {
                w.push_str(&format!(", vertical CRS EPSG:{v}"));
            }
            w
        });
        let a = spherecal::frames::LocalFrame::new(spherecal::frames::Geodetic::from_deg(
            site.origin.lat_deg,
            site.origin.lon_deg,
            site.origin.h_m,
        ));
        let shift = a.to_ned(&spherecal::frames::Geodetic::from_deg(
            moved.origin.lat_deg,
            moved.origin.lon_deg,
            moved.origin.h_m,
        ));
        Ok(Self {
            file: InputFile::of("site", path)?,
            crs: crs.map(|c| format!("EPSG:{}", c.epsg)),
            heights,
            survey_datum: site.datum().label(),
            transformation: line.to_string(),
            transformation_m: shift.norm(),
            spheres: site
                .sphere
                .iter()
                .map(|s| SurveyedSphere {
                    id: s.id.clone(),
                    easting_northing: s.easting.zip(s.northing),
                    height_m: s.height_m,
                    lat_lon_h: (s.lat_deg, s.lon_deg, s.h_m),
                    radius_m: s.radius_m,
                    sigma_m: s.sigma_m,
                })
                .collect(),
        })
    }
}

//! A report.json read back for what `board set-mount` and `--init-from` take from it.

/// What `board set-mount` and `--init-from` take from a report.json: the solution, its sigmas
/// and whether it was claimed. Read leniently: a refused report's numbers that are not numbers
/// (written as null) are NaN here, and only the six and the time offset must be finite.
#[derive(Debug, Clone, PartialEq)]
pub struct Solved {
    /// Roll, pitch, heading [deg], x, y, z [m].
    pub deg_m: [f64; 6],
    /// Their 1-sigmas (NaN where the report has none).
    pub sigma: [f64; 6],
    /// INS time = LiDAR time + this [s].
    pub time_offset_s: f64,
    /// Its 1-sigma [s] (NaN where none; 0 when it was held).
    pub time_offset_sigma_s: f64,
    /// A solution was claimed.
    pub converged: bool,
    /// Why not, if not.
    pub reason: Option<String>,
    /// The program that wrote it.
    pub version: String,
}

impl Solved {
    /// Read `path`.
    pub fn load(path: &std::path::Path) -> Result<Self, crate::Error> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let v: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| format!("{}: not a spherecal report: {e}", path.display()))?;
        let num = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
        let six = |v: &serde_json::Value| {
            let (b, l) = (&v["boresight_deg"], &v["lever_arm_m"]);
            [
                num(&b["roll"]),
                num(&b["pitch"]),
                num(&b["heading"]),
                num(&l["x"]),
                num(&l["y"]),
                num(&l["z"]),
            ]
        };
        let s = Self {
            deg_m: six(&v),
            sigma: six(&v["sigma"]),
            time_offset_s: v["time_offset_s"].as_f64().unwrap_or(0.0),
            time_offset_sigma_s: num(&v["sigma"]["time_offset_s"]),
            converged: v["converged"].as_bool().unwrap_or(false),
            reason: v["reason"].as_str().map(str::to_string),
            version: v["version"].as_str().unwrap_or_default().to_string(),
        };
        if v.get("boresight_deg").is_none() || v.get("lever_arm_m").is_none() {
            return Err(format!(
                "{}: not a spherecal report: no boresight_deg and lever_arm_m",
                path.display()
            )
            .into());
        }
        if !s
            .deg_m
            .iter()
            .chain([&s.time_offset_s])
            .all(|v| v.is_finite())
        {
            return Err(format!(
                "{}: its boresight, lever arm or time offset is not a number",
                path.display()
            )
            .into());
        }
        Ok(s)
    }
}

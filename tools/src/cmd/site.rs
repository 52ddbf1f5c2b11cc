//! `spherecal site import SURVEY.csv --crs EPSG:n [--height ...] -o site.toml`.

use super::{parse6, print_or_fail};
use crate::config::crs::{Crs, HeightSystem, SiteCrs};
use crate::config::site::SiteApriori;
use crate::config::survey::{import_csv, ImportOptions};
use std::path::PathBuf;
use std::process::ExitCode;

/// Site files from a surveyor's data.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

/// What to do.
#[derive(clap::Subcommand, Debug)]
pub enum What {
    /// Turn a CSV of surveyed sphere centres (`id,easting,northing,height[,radius]`; a header
    /// row and `#` comments allowed) into a site.toml, checked.
    Import(ImportArgs),
}

/// `site import`.
#[derive(clap::Args, Debug)]
pub struct ImportArgs {
    /// The survey CSV.
    pub csv: PathBuf,
    /// CRS of easting, northing (`EPSG:n`; a geographic CRS takes longitude, latitude [deg]).
    #[arg(long)]
    pub crs: String,
    /// What the heights are (required: a wrong guess puts every sphere tens of metres off):
    /// `ellipsoidal` (above the CRS datum's ellipsoid, as GNSS gives them) or `orthometric`
    /// (above the geoid: levelled heights, a chart's land datum; then --geoid-n or --geoid).
    #[arg(long)]
    pub height: HeightSystem,
    /// The unit of the heights: `m`, `us-ft` (US survey foot) or `ft` (international foot).
    /// Required when the CRS's unit is not the metre (e.g. EPSG:2248, US survey feet), unless
    /// the CSV's header names it (`Elevation (ft)`, `Z_usft`, `Height [m]`).
    #[arg(long)]
    pub height_unit: Option<crate::config::crs::HeightUnit>,
    /// Geoid undulation N [m] for orthometric heights (h = H + N), one for the site ...
    #[arg(long, allow_negative_numbers = true, value_parser = super::finite, conflicts_with = "geoid")]
    pub geoid_n: Option<f64>,
    /// ... or a geoid grid (GTX: CGG2013, EGM2008, GEOID18 ... on the CRS's datum).
    #[arg(long)]
    pub geoid: Option<PathBuf>,
    /// The vertical CRS of orthometric heights (`EPSG:n`, e.g. EPSG:6647 for CGVD2013, 5703
    /// NAVD88, 3855 EGM2008): LAS files name it.
    #[arg(long)]
    pub vertical_crs: Option<String>,
    /// Radius [m] of spheres whose row has none.
    #[arg(long, allow_hyphen_values = true, value_parser = super::positive)]
    pub radius: Option<f64>,
    /// GPS - UTC [s].
    #[arg(long, default_value_t = 18)]
    pub leap_seconds: i64,
    /// A-priori mounting `r,p,h,x,y,z` [deg, m].
    #[arg(long, value_parser = parse6, allow_hyphen_values = true, default_value = "0,0,0,0,0,0")]
    pub apriori: [f64; 6],
    /// Window margin beyond the radius [m] (how far the a-priori mounting may be off there).
    #[arg(long, default_value_t = 2.5, allow_hyphen_values = true, value_parser = super::positive)]
    pub margin: f64,
    /// The INS's errors that wander, as a preset: posmv-rtk, posmv-pp, posmv-quebec, apx15,
    /// apx18, vn200-rtk, vn200-gnss, or white (`[ins.correlated]` in the site). Without it the
    /// calibration takes what the INS states of its own accuracy (a VN-200 configured to send
    /// PosU/YprU, a POS MV's Group 2, an SBET's smrmsg), else its kind's default: a VN-200's is
    /// its own GNSS's, metre-level, and the lever arm's height then goes undetermined.
    #[arg(long, value_parser = ins_preset)]
    pub ins: Option<String>,
    /// The site file to write.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Replace `--out` if it exists.
    #[arg(long)]
    pub force: bool,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    match a.what {
        What::Import(a) => print_or_fail("site import", import(&a)),
    }
}

fn import(a: &ImportArgs) -> Result<String, crate::Error> {
    if a.out.exists() && !a.force {
        return Err(format!("{}: exists (give --force to replace it)", a.out.display()).into());
    }
    let crs = Crs::parse(&a.crs)?;
    let base = a
        .out
        .parent()
        .map(std::path::Path::to_path_buf)
        .unwrap_or_default();
    // The grid's path as the site file will give it: relative to its folder when it is in it.
    let geoid_grid = a.geoid.as_ref().map(|g| {
        let abs = |p: &std::path::Path| std::fs::canonicalize(p).unwrap_or(p.to_path_buf());
        let (g_abs, b_abs) = (
            abs(g),
            abs(if base.as_os_str().is_empty() {
                std::path::Path::new(".")
            } else {
                &base
            }),
        );
        g_abs
            .strip_prefix(&b_abs)
            .map(|r| r.display().to_string())
            .unwrap_or_else(|_| g_abs.display().to_string())
    });
    let vertical_epsg = match &a.vertical_crs {
        Some(v) => Some(vertical_code(v)?),
        None => None,
    };
    let text = std::fs::read_to_string(&a.csv).map_err(|e| format!("{}: {e}", a.csv.display()))?;
    let [r, p, h, x, y, z] = a.apriori;
    let o = ImportOptions {
        crs: SiteCrs {
            epsg: crs.code,
            height: a.height,
            geoid_undulation_m: a.geoid_n,
            geoid_grid,
            vertical_epsg,
            height_unit: a.height_unit,
        },
        radius_m: a.radius,
        leap_seconds: a.leap_seconds,
        apriori: SiteApriori {
            boresight_deg: [r, p, h],
            lever_arm_m: [x, y, z],
            window_margin_m: a.margin,
            boresight_sigma_deg: None,
            lever_arm_sigma_m: None,
        },
        base,
    };
    let (mut site, columns) = import_csv(&text, &a.csv.display().to_string(), &o)?;
    if let Some(p) = &a.ins {
        site.ins = Some(crate::config::site::SiteIns {
            correlated: crate::config::nav_errors::CorrelatedSpec::preset_only(p),
        });
    }
    let datum = site.datum();
    let heights = match (a.height, a.geoid_n, &a.geoid) {
        (HeightSystem::Ellipsoidal, _, _) => "ellipsoidal heights".to_string(),
        (_, Some(n), _) => format!("orthometric heights, N = {n} m"),
        (_, _, Some(g)) => format!("orthometric heights, N from {}", g.display()),
        _ => "orthometric heights".into(),
    };
    let head = format!(
        "# Written by spherecal site import from {} (columns {columns}; {} {heights}).\n# lat_deg/lon_deg/h_m are on the CRS's datum, {}, computed from easting/northing/height_m.\n",
        a.csv.display(),
        a.crs,
        datum.label()
    );
    crate::report::write_atomically(&a.out, (head + &site.to_toml()).as_bytes())?;
    let mut out = format!(
        "{} spheres from {} (EPSG:{}; columns {columns}) -> {}\ndatum: {}: the trajectory's datum must be it, or calibrate applies (and names) the transformation to it\n",
        site.sphere.len(),
        a.csv.display(),
        crs.code,
        a.out.display(),
        datum.label()
    );
    let unit = site
        .crs
        .as_ref()
        .and_then(|c| c.height_unit)
        .unwrap_or_default();
    for s in &site.sphere {
        let given = match (unit, s.height_m) {
            (crate::config::crs::HeightUnit::Metre, _) | (_, None) => String::new(),
            (u, Some(m)) => format!(
                " (surveyed {:.4} {}: x {})",
                m / u.metres(),
                u.key(),
                u.metres()
            ),
        };
        out += &format!(
            "  {:<8} lat {:>14.9} lon {:>14.9} h {:>9.4} m{given}  r {} m\n",
            s.id, s.lat_deg, s.lon_deg, s.h_m, s.radius_m
        );
    }
    out += &match &a.ins {
        Some(p) => format!("navigation errors: [ins.correlated] preset \"{p}\" (--ins)\n"),
        None => "navigation errors: none declared: calibrate takes what the INS states of its own accuracy (a VN-200 sending PosU/YprU, a POS MV's Group 2, an SBET's smrmsg), else its kind's default, for a VN-200 its own GNSS's, metre-level (the lever arm's height is then not determined); declare yours with --ins PRESET (vn200-rtk, posmv-rtk, ...)\n".into(),
    };
    Ok(out)
}

/// `EPSG:n` of a vertical CRS this build knows.
fn vertical_code(v: &str) -> Result<u16, String> {
    let code = v
        .trim()
        .trim_start_matches("EPSG:")
        .trim_start_matches("epsg:")
        .parse::<u32>()
        .map_err(|_| {
            format!("--vertical-crs {v:?}: expected EPSG:<code> (digits), e.g. EPSG:6647")
        })?;
    let code = u16::try_from(code).unwrap_or(u16::MAX);
    if crate::config::epsg_tables::VERTICAL
        .binary_search_by_key(&code, |v| v.0)
        .is_err()
    {
        return Err(format!(
            "--vertical-crs EPSG:{code}: not a vertical CRS in metres that this build knows (e.g. 6647 CGVD2013, 5703 NAVD88, 3855 EGM2008, 5701 ODN, 5720 NGF-IGN69)"
        ));
    }
    Ok(code)
}

/// A preset of `[ins.correlated]` by its key.
fn ins_preset(s: &str) -> Result<String, String> {
    let keys: Vec<&str> = crate::config::nav_errors::PRESETS
        .iter()
        .map(|p| p.key)
        .collect();
    if keys.contains(&s) {
        Ok(s.to_string())
    } else {
        Err(format!("{s:?}: expected one of {}", keys.join(", ")))
    }
}

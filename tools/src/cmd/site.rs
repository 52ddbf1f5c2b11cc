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
    /// What the heights are: `ellipsoidal` (on the CRS's datum) or `orthometric`.
    #[arg(long, default_value = "ellipsoidal")]
    pub height: HeightSystem,
    /// Geoid undulation N [m] for orthometric heights (h = H + N).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = super::finite)]
    pub geoid_n: f64,
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

fn import(a: &ImportArgs) -> Result<String, String> {
    if a.out.exists() && !a.force {
        return Err(format!(
            "{}: exists (give --force to replace it)",
            a.out.display()
        ));
    }
    let crs = Crs::parse(&a.crs)?;
    if a.height == HeightSystem::Ellipsoidal && a.geoid_n != 0.0 {
        return Err("--geoid-n is for orthometric heights: give --height orthometric".into());
    }
    let text = std::fs::read_to_string(&a.csv).map_err(|e| format!("{}: {e}", a.csv.display()))?;
    let [r, p, h, x, y, z] = a.apriori;
    let o = ImportOptions {
        crs: SiteCrs {
            epsg: crs.code,
            height: a.height,
            geoid_undulation_m: a.geoid_n,
        },
        radius_m: a.radius,
        leap_seconds: a.leap_seconds,
        apriori: SiteApriori {
            boresight_deg: [r, p, h],
            lever_arm_m: [x, y, z],
            window_margin_m: a.margin,
        },
    };
    let site = import_csv(&text, &a.csv.display().to_string(), &o)?;
    let head = format!(
        "# Written by spherecal site import from {} ({} {:?} heights{}).\n# lat_deg/lon_deg/h_m are WGS84, computed from easting/northing/height_m.\n",
        a.csv.display(),
        a.crs,
        a.height,
        if a.height == HeightSystem::Orthometric {
            format!(", N = {} m", a.geoid_n)
        } else {
            String::new()
        }
    );
    std::fs::write(&a.out, head + &site.to_toml())
        .map_err(|e| format!("{}: {e}", a.out.display()))?;
    let mut out = format!(
        "{} spheres from {} (EPSG:{}) -> {}\n",
        site.sphere.len(),
        a.csv.display(),
        crs.code,
        a.out.display()
    );
    for s in &site.sphere {
        out += &format!(
            "  {:<8} lat {:>14.9} lon {:>14.9} h {:>9.4} m  r {} m\n",
            s.id, s.lat_deg, s.lon_deg, s.h_m, s.radius_m
        );
    }
    Ok(out)
}

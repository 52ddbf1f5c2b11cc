//! The surveyor's CSV as written: its dialect (separator, decimal comma, quotes) and its header
//! (which column holds what, and the heights' unit if the header names one).

use crate::config::crs::{Crs, HeightUnit};

/// What a column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Col {
    Id,
    /// Easting, or longitude.
    X,
    /// Northing, or latitude.
    Y,
    Height,
    Radius,
    /// The centre's 1 sigma [m] (optional: the navigation model's prior on it).
    Sigma,
}

/// A header word's column, whether it names a geographic coordinate, and the unit it names
/// (`Elevation (ft)`, `Z [m]`, `Height_usft`).
pub(super) fn column_of(word: &str) -> Option<(Col, bool, Option<HeightUnit>)> {
    let raw = word.trim();
    // A unit in brackets after the name.
    let (name, mut unit) = match raw.find(['(', '[']) {
        Some(i) => {
            let u = raw[i + 1..].trim_end_matches([')', ']']);
            (raw[..i].trim(), Some(HeightUnit::parse(u)?))
        }
        None => (raw, None),
    };
    let mut w = name.to_ascii_lowercase().replace([' ', '-', '.'], "_");
    // ... or as a suffix (`z_ft`, `elevation_usft`); `_m` is taken as metres below.
    for (suffix, u) in [
        ("_usft", HeightUnit::UsFoot),
        ("_sft", HeightUnit::UsFoot),
        ("_ftus", HeightUnit::UsFoot),
        ("_ft", HeightUnit::Foot),
        ("_feet", HeightUnit::Foot),
    ] {
        if unit.is_none() {
            if let Some(stem) = w.strip_suffix(suffix) {
                w = stem.to_string();
                unit = Some(u);
            }
        }
    }
    let (c, geo) = column_name(&w)?;
    if unit.is_none() && matches!(c, Col::Height) && w.ends_with("_m") {
        unit = Some(HeightUnit::Metre);
    }
    Some((c, geo, unit))
}

/// A header name's column (lower case, `_` for spaces), and whether it is geographic.
pub(super) fn column_name(w: &str) -> Option<(Col, bool)> {
    Some(match w {
        "id" | "name" | "point" | "pt" | "sphere" | "target" | "point_id" | "pointid"
        | "point_name" | "station" | "stn" => (Col::Id, false),
        "easting" | "east" | "e" | "x" | "easting_m" | "x_m" => (Col::X, false),
        "northing" | "north" | "n" | "y" | "northing_m" | "y_m" => (Col::Y, false),
        "lon" | "long" | "longitude" | "lng" | "lon_deg" => (Col::X, true),
        "lat" | "latitude" | "lat_deg" => (Col::Y, true),
        "height" | "h" | "z" | "elevation" | "elev" | "alt" | "altitude" | "height_m" | "h_m"
        | "z_m" | "elevation_m" | "elev_m" | "ellipsoidal_height" | "orthometric_height" | "ht" => {
            (Col::Height, false)
        }
        "radius" | "r" | "radius_m" => (Col::Radius, false),
        "sigma" | "sigma_m" | "sd" | "std" | "precision" | "accuracy" => (Col::Sigma, false),
        _ => return None,
    })
}

/// The columns a header names, in order, and the heights' unit if it names one; `None` when
/// the line is not a header (its second field is a number).
#[allow(clippy::type_complexity)]
pub(super) fn header(
    fields: &[String],
    geographic: bool,
    epsg: u16,
) -> Option<Result<(Vec<Col>, Option<HeightUnit>), crate::Error>> {
    if fields.get(1).is_some_and(|s| number(s).is_some()) {
        return None;
    }
    let mut cols = Vec::new();
    let mut height_unit = None;
    for f in fields {
        match column_of(f) {
            Some((c, geo, unit)) => {
                if c == Col::Height {
                    height_unit = unit;
                }
                if geo && !geographic {
                    return Some(Err(format!(
                        "the header says {f:?} but EPSG:{epsg} is projected (easting, northing): give the geographic CRS of the survey (e.g. EPSG:4326) or its projected coordinates"
                    ).into()));
                }
                if cols.contains(&c) {
                    return Some(Err(format!("the header names {f:?}'s column twice").into()));
                }
                cols.push(c);
            }
            None => {
                return Some(Err(format!(
                "header column {f:?}: expected one of: Point/Name/ID; E/Easting/X (or Lon); N/Northing/Y (or Lat); Z/H/Elev/Height/Elevation (a unit in brackets, e.g. Elevation (ft)); Radius; Sigma (any case)"
            )
                .into()))
            }
        }
    }
    for need in [Col::Id, Col::X, Col::Y, Col::Height] {
        if !cols.contains(&need) {
            return Some(Err(format!(
                "the header has no {} column",
                match need {
                    Col::Id => "id",
                    Col::X => "easting (or longitude)",
                    Col::Y => "northing (or latitude)",
                    _ => "height",
                }
            )
            .into()));
        }
    }
    Some(Ok((cols, height_unit)))
}

/// The unit of the heights: the header's, else `--height-unit`'s (they must agree when both
/// say); else metres, but for a CRS in feet, which must say (a height in feet read as metres
/// puts a sphere tens of metres off).
pub(super) fn height_unit(
    crs: &Crs,
    header: Option<HeightUnit>,
    given: Option<HeightUnit>,
) -> Result<HeightUnit, String> {
    match (header, given) {
        (Some(h), Some(g)) if h != g => Err(format!(
            "the header gives the heights in {}, --height-unit in {}: which?",
            h.key(),
            g.key()
        )),
        (Some(u), _) | (None, Some(u)) => Ok(u),
        (None, None) => match crs.linear_unit() {
            HeightUnit::Metre => Ok(HeightUnit::Metre),
            u => Err(format!(
                "EPSG:{}'s coordinates are in {}: say the heights' unit, --height-unit m|us-ft|ft (or in the header: Elevation (ft))",
                crs.code,
                match u {
                    HeightUnit::UsFoot => "US survey feet",
                    _ => "feet",
                }
            )),
        },
    }
}

/// A number as a surveyor's CSV writes it (a decimal comma already made a point).
pub(super) fn number(s: &str) -> Option<f64> {
    s.trim().parse::<f64>().ok()
}

/// How a CSV is written: its separator, and whether its numbers use a decimal comma. A
/// spreadsheet's export in a locale with a decimal comma separates with `;`; a tab-separated
/// export is read too.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Dialect {
    sep: char,
    decimal_comma: bool,
}

impl Dialect {
    /// From the first line that holds data or a header.
    pub(super) fn of(text: &str) -> Self {
        let first = text
            .lines()
            .map(|l| l.trim())
            .find(|l| !l.is_empty() && !l.starts_with('#'))
            .unwrap_or("");
        let sep = if first.contains(';') {
            ';'
        } else if first.contains('\t') {
            '\t'
        } else {
            ','
        };
        Self {
            sep,
            decimal_comma: sep != ',',
        }
    }

    /// A line's fields: separated, quotes (`"..."`, `""` inside) removed, trimmed; a decimal
    /// comma read as a point.
    pub(super) fn fields(&self, line: &str) -> Vec<String> {
        let mut out = Vec::new();
        let mut cur = String::new();
        let mut quoted = false;
        let mut chars = line.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '"' if quoted && chars.peek() == Some(&'"') => {
                    cur.push('"');
                    chars.next();
                }
                '"' => quoted = !quoted,
                c if c == self.sep && !quoted => out.push(std::mem::take(&mut cur)),
                c => cur.push(c),
            }
        }
        out.push(cur);
        out.into_iter()
            .map(|f| {
                let f = f.trim().to_string();
                if self.decimal_comma && f.contains(',') && number(&f.replace(',', ".")).is_some() {
                    f.replace(',', ".")
                } else {
                    f
                }
            })
            .collect()
    }
}

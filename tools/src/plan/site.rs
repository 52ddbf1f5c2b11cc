//! `plan --site SITE.toml`: a plan for a surveyor's own site (issue 47). The site's surveyed
//! spheres, a-priori mounting, sensors' noise and navigation model become a scenario with the
//! passes of a first calibration survey (a vessel's lines along the spheres, or a drone's
//! pattern of airborne boresight practice over them), which [`super::plan`] predicts and
//! improves as it does any scenario. The lines come back in the site's own grid (to stake out,
//! or to load into a survey-line planner) and as GeoJSON (RFC 7946: WGS 84 longitude,
//! latitude).

use super::recommend::{line, Change};
use crate::config::crs::Crs;
use crate::config::scenario::{PassSpec, Scenario, SphereSpec};
use crate::config::site::Site;
use serde::Serialize;
use spherecal::frames::{Geodetic, LocalFrame};

/// What carries the LiDAR.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Platform {
    /// A vessel along a quay: lines along the spheres at 8, 12, 20 and 30 m, both ways.
    Vessel,
    /// A drone: two opposing lines over the spheres, one lower, one crossing.
    Drone,
}

/// The vessel's lines' distances from the spheres' line [m]: the ranges of a VLP-16 survey's
/// spheres, near (many returns) to far (the angles' leverage), as the paper's quay survey.
pub const VESSEL_OFFSETS_M: [f64; 4] = [8.0, 12.0, 20.0, 30.0];
/// The vessel's INS below the spheres' mean centre when not given [m]: a quay's spheres on
/// tripods over a small survey vessel's deck.
pub const VESSEL_BELOW_M: f64 = 1.5;
/// A vessel's speed along the lines when not given [m/s] (2 m/s: 4 knots).
pub const VESSEL_MPS: f64 = 2.0;
/// A drone's working height above the ground when not given [m].
pub const DRONE_HEIGHT_M: f64 = 40.0;
/// A drone's speed when not given [m/s].
pub const DRONE_MPS: f64 = 5.0;

/// The choices `plan --site` takes besides the site.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// The platform.
    pub platform: Platform,
    /// The LiDAR model.
    pub model: spherecal::sim::Scanner,
    /// Vessel: the INS's height above the spheres' mean centre (negative: below); drone: the
    /// working height above the ground under the spheres [m].
    pub height_m: Option<f64>,
    /// Speed along the lines [m/s].
    pub speed_mps: Option<f64>,
    /// The side of the spheres' line the vessel runs on, as a compass bearing from the spheres
    /// [deg] (`None`: the side the prediction favours).
    pub side_deg: Option<f64>,
}

/// The spheres of `site` as a scenario's (NED from its origin), on tripods 1.55 m tall.
fn spheres(site: &Site) -> Vec<SphereSpec> {
    let o = &site.origin;
    let f = LocalFrame::new(Geodetic::from_deg(o.lat_deg, o.lon_deg, o.h_m));
    site.sphere
        .iter()
        .map(|sp| {
            let n = f.to_ned(&Geodetic::from_deg(sp.lat_deg, sp.lon_deg, sp.h_m));
            let ned = [n.x, n.y, n.z].map(|v| (v * 1e4).round() / 1e4);
            SphereSpec {
                id: sp.id.clone(),
                ned_m: ned,
                radius_m: sp.radius_m,
                stand: "tripod".into(),
                stand_down_m: Some(ned[2] + super::design::TRIPOD_M),
                reflectivity: 0.8,
            }
        })
        .collect()
}

/// The scenario of `site` without passes: its spheres, its a-priori mounting (also taken as
/// the truth: a plan predicts sigmas, not errors), the sensors' noise (`[noise]`, else the
/// specified: [`super::PlanNoise::specified`] for its scanner) and the navigation model.
fn base(site: &Site, o: &Options) -> Result<Scenario, crate::Error> {
    let a = &site.apriori;
    let noise = site.noise.as_ref();
    let [range, att, pos] = super::PlanNoise::specified(Some(o.model));
    let (vessel, drone) = (
        "roll = [1.5, 6.0]\npitch = [0.8, 4.5]\nyaw = [0.5, 9.0]\nheave = [0.05, 5.0]\nturn_s = 30.0",
        "roll = [0.8, 3.0]\npitch = [0.6, 4.0]\nyaw = [0.5, 6.0]\nheave = [0.1, 5.0]\nturn_s = 8.0",
    );
    let text = format!(
        "name = \"site-plan\"\nseed = 1\nstart_utc = \"2026-01-01T12:00:00Z\"\nleap_seconds = {leap}\n\
         [site]\nlat_deg = {lat}\nlon_deg = {lon}\nh_m = {h}\n\
         [mount.truth]\nboresight_deg = {b:?}\nlever_arm_m = {l:?}\n\
         [mount.apriori]\nboresight_deg = {b:?}\nlever_arm_m = {l:?}\nwindow_margin_m = {w}\n\
         [lidar]\nmodel = \"{model}\"\nrpm = 600\nreturn_mode = \"strongest\"\nrange_sigma_m = {range}\ndrop_prob = 0.0\n\
         [ins]\nrate_hz = 200\natt_sigma_deg = {att}\npos_sigma_m = {pos}\ntime_offset_s = 0.0\ncorrupt_prob = 0.0\n\
         [trajectory]\nins_down_m = 0.0\n{motion}\n",
        leap = site.leap_seconds,
        lat = site.origin.lat_deg,
        lon = site.origin.lon_deg,
        h = site.origin.h_m,
        b = a.boresight_deg,
        l = a.lever_arm_m,
        w = a.window_margin_m,
        model = o.model.key(),
        range = noise.map_or(range, |n| n.range_m),
        att = noise.map_or(att, |n| n.attitude_deg),
        pos = noise.map_or(pos, |n| n.position_m),
        motion = if o.platform == Platform::Vessel {
            vessel
        } else {
            drone
        },
    );
    let internal = |e: String| crate::Error::internal(format!("the site's scenario: {e}"));
    let mut t: toml::Table = toml::from_str(&text).map_err(|e| internal(e.to_string()))?;
    let sp = toml::Value::try_from(spheres(site)).map_err(|e| internal(e.to_string()))?;
    t.insert("sphere".into(), sp);
    if let Some(toml::Value::Table(tr)) = t.get_mut("trajectory") {
        tr.insert("pass".into(), toml::Value::Array(Vec::new()));
    }
    let mut s: Scenario = t
        .try_into()
        .map_err(|e: toml::de::Error| internal(e.to_string()))?;
    if let Some(ins) = &site.ins {
        s.ins.correlated = ins.correlated.clone();
    }
    Ok(s)
}

/// The vessel's lines on the side `normal` of the spheres' line: along it at each of
/// [`VESSEL_OFFSETS_M`], alternately both ways, each running past the spheres far enough
/// that every laser sees every sphere (0.6 x the offset + 5 m beyond the ends).
fn vessel_passes(
    c: [f64; 2],
    d: [f64; 2],
    normal: [f64; 2],
    ext: [f64; 2],
    speed: f64,
) -> Vec<PassSpec> {
    VESSEL_OFFSETS_M
        .iter()
        .enumerate()
        .map(|(k, &o)| {
            let run = 0.6 * o + 5.0;
            let (a, b) = (ext[0] - run, ext[1] + run);
            let at = |t: f64| {
                [
                    c[0] + d[0] * t + normal[0] * o,
                    c[1] + d[1] * t + normal[1] * o,
                ]
            };
            let course = d[1].atan2(d[0]).to_degrees();
            let (start, heading) = if k % 2 == 0 {
                (at(a), course)
            } else {
                (at(b), course + 180.0)
            };
            PassSpec {
                start_ne_m: start.map(|x| (x * 1000.0).round() / 1000.0),
                heading_deg: (heading.rem_euclid(360.0) * 10.0).round() / 10.0,
                speed_mps: speed,
                duration_s: ((b - a) / speed * 10.0).round() / 10.0,
                down_m: None,
            }
        })
        .collect()
}

/// The scenario for a first calibration survey of `site` by `o.platform`, and the side of the
/// spheres' line a vessel runs on (a compass bearing [deg]; `None` for a drone). Without
/// `o.side_deg` both sides are predicted and the better taken.
pub fn scenario(site: &Site, o: &Options) -> Result<(Scenario, Option<f64>), crate::Error> {
    if site.sphere.is_empty() {
        return Err("the site has no spheres to plan for".into());
    }
    let mut s = base(site, o)?;
    s.name = format!(
        "site-{}",
        match o.platform {
            Platform::Vessel => "vessel",
            Platform::Drone => "drone",
        }
    );
    let (c, d, normal, ext) = line(&s);
    let mean_down = s.sphere.iter().map(|x| x.ned_m[2]).sum::<f64>() / s.sphere.len() as f64;
    match o.platform {
        Platform::Drone => {
            let h = o.height_m.unwrap_or(DRONE_HEIGHT_M);
            let speed = o.speed_mps.unwrap_or(DRONE_MPS);
            let ground = super::design::ground(&s);
            let reach = ((ext[1] - ext[0]) / 2.0).max(10.0) + 25.0;
            let course = d[1].atan2(d[0]).to_degrees();
            s.trajectory.pass = super::design::aerial_passes(c, course, ground, h, speed, reach);
            s.trajectory.ins_down_m = ground - h;
            s.validate().map_err(|e| e.to_string())?;
            Ok((s, None))
        }
        Platform::Vessel => {
            let speed = o.speed_mps.unwrap_or(VESSEL_MPS);
            s.trajectory.ins_down_m = mean_down - o.height_m.unwrap_or(-VESSEL_BELOW_M);
            // The side given, else the one whose plan predicts the smaller worst sigma.
            let sides = match o.side_deg {
                Some(b) => {
                    let (sn, se) = (b.to_radians().cos(), b.to_radians().sin());
                    let n = if normal[0] * sn + normal[1] * se >= 0.0 {
                        normal
                    } else {
                        [-normal[0], -normal[1]]
                    };
                    vec![n]
                }
                None => vec![normal, [-normal[0], -normal[1]]],
            };
            let goal = crate::config::goal::Goal::default();
            let mut best: Option<(f64, Scenario, [f64; 2])> = None;
            for n in sides {
                let mut t = s.clone();
                t.trajectory.pass = vessel_passes(c, d, n, ext, speed);
                t.validate().map_err(|e| e.to_string())?;
                let score = if o.side_deg.is_some() {
                    0.0
                } else {
                    super::plan(&t, &goal, false)?.predicted.worst_ratio(&goal)
                };
                if best.as_ref().is_none_or(|b| score < b.0) {
                    best = Some((score, t, n));
                }
            }
            let (_, t, n) = best.ok_or("no side to plan on")?;
            let side = n[1].atan2(n[0]).to_degrees().rem_euclid(360.0);
            Ok((t, Some(side)))
        }
    }
}

/// One line to run, in the site's grid.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Line {
    /// `L1`, `L2`, ... (the plan's passes in order), `R1`, ... (the first recommendation's).
    pub name: String,
    /// Start and end in the site's grid: easting, northing in its unit (longitude, latitude
    /// [deg] for a geographic CRS or a site without `[crs]`).
    pub start: [f64; 2],
    /// See `start`.
    pub end: [f64; 2],
    /// Start and end, WGS 84 longitude, latitude [deg].
    pub start_wgs84: [f64; 2],
    /// See `start_wgs84`.
    pub end_wgs84: [f64; 2],
    /// Course, true [deg].
    pub course_deg: f64,
    /// Speed [m/s].
    pub speed_mps: f64,
    /// Time along it [s].
    pub duration_s: f64,
    /// The INS's height above the spheres' mean centre (vessel) or the ground (drone) [m].
    pub height_m: f64,
}

/// The grid the lines are given in.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Lines {
    /// `EPSG:n`, or `WGS 84` without `[crs]`.
    pub crs: String,
    /// The coordinates' names and unit, in words.
    pub axes: String,
    /// The side of the spheres' line a vessel runs on, a compass bearing from them [deg].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub side_deg: Option<f64>,
    /// The lines.
    pub lines: Vec<Line>,
}

/// The plan's passes of `s` (and the added passes of `recommended`) as lines in the site's
/// grid.
pub fn lines(
    site: &Site,
    s: &Scenario,
    side_deg: Option<f64>,
    recommended: &[Change],
    drone: bool,
) -> Result<Lines, crate::Error> {
    let crs = match &site.crs {
        Some(c) => Some(Crs::epsg(c.epsg)?),
        None => None,
    };
    let shift = crate::config::datum::DatumShift::between(
        &site.datum(),
        &crate::config::datum::Datum::wgs84(),
    )?;
    let f = s.site();
    let reference = if drone {
        super::design::ground(s)
    } else {
        s.sphere.iter().map(|x| x.ned_m[2]).sum::<f64>() / s.sphere.len().max(1) as f64
    };
    let point = |ne: [f64; 2], down: f64| -> Result<([f64; 2], [f64; 2]), crate::Error> {
        let g = f.to_geodetic(&nalgebra::Vector3::new(ne[0], ne[1], down));
        let (lat, lon, h) = (g.lat.to_degrees(), g.lon.to_degrees(), g.h);
        let grid = match &crs {
            Some(c) => {
                let (x, y, _) = c.from_geographic(lat, lon, h)?;
                [x, y]
            }
            None => [lon, lat],
        };
        let (wlat, wlon, _) = shift.apply(lat, lon, h)?;
        Ok((grid, [wlon, wlat]))
    };
    let added = recommended.iter().filter_map(|c| match c {
        Change::AddPass(p) => Some(p),
        _ => None,
    });
    let mut out = Vec::new();
    let passes = s.trajectory.pass.iter().map(|p| ("L", p));
    for (k, (tag, p)) in passes.chain(added.map(|p| ("R", p))).enumerate() {
        let down = p.down_m.unwrap_or(s.trajectory.ins_down_m);
        let h = p.heading_deg.to_radians();
        let run = p.speed_mps * p.duration_s;
        let end = [
            p.start_ne_m[0] + h.cos() * run,
            p.start_ne_m[1] + h.sin() * run,
        ];
        let (a, aw) = point(p.start_ne_m, down)?;
        let (b, bw) = point(end, down)?;
        let n = if tag == "L" {
            k + 1
        } else {
            k + 1 - s.trajectory.pass.len()
        };
        out.push(Line {
            name: format!("{tag}{n}"),
            start: a,
            end: b,
            start_wgs84: aw,
            end_wgs84: bw,
            course_deg: p.heading_deg,
            speed_mps: p.speed_mps,
            duration_s: p.duration_s,
            height_m: reference - down,
        });
    }
    let (crs_name, axes) = match (&site.crs, &crs) {
        (Some(c), Some(k)) if !k.is_geographic() => (
            format!("EPSG:{}", c.epsg),
            format!("easting, northing [{}]", k.linear_unit().key()),
        ),
        (Some(c), _) => (
            format!("EPSG:{}", c.epsg),
            "longitude, latitude [deg]".into(),
        ),
        (None, _) => (
            format!("{} (the site has no [crs])", site.datum().label()),
            "longitude, latitude [deg]".into(),
        ),
    };
    Ok(Lines {
        crs: crs_name,
        axes,
        side_deg,
        lines: out,
    })
}

/// The lines in words, one a row.
pub fn render(l: &Lines, drone: bool) -> String {
    let geographic = l.axes.starts_with("longitude");
    let xy = |p: [f64; 2]| {
        if geographic {
            format!("lon {:.7} lat {:.7}", p[0], p[1])
        } else {
            format!("E {:.2} N {:.2}", p[0], p[1])
        }
    };
    let mut t = format!("lines to run ({}, {}; courses true", l.crs, l.axes);
    if let Some(b) = l.side_deg {
        t += &format!(
            "; on the {} side of the spheres, `--side` for the other",
            super::bound(b)
                .trim_end_matches("bound")
                .trim_end_matches('-')
        );
    }
    t += "):\n";
    for x in &l.lines {
        t += &format!(
            "  {:<3} {} -> {}  course {:>5.1} deg  {:.1} m/s  {:>4.0} s  INS {:.1} m {}{}\n",
            x.name,
            xy(x.start),
            xy(x.end),
            x.course_deg,
            x.speed_mps,
            x.duration_s,
            x.height_m.abs(),
            match (drone, x.height_m >= 0.0) {
                (true, _) => "above the ground",
                (false, true) => "above the spheres' centres",
                (false, false) => "below the spheres' centres",
            },
            if x.name.starts_with('R') {
                "  (recommended)"
            } else {
                ""
            }
        );
    }
    t
}

/// The lines as an HTML section.
pub fn html(l: &Lines) -> String {
    use crate::html::escape;
    let geographic = l.axes.starts_with("longitude");
    let xy = |p: [f64; 2]| {
        if geographic {
            format!("{:.7}</td><td>{:.7}", p[0], p[1])
        } else {
            format!("{:.2}</td><td>{:.2}", p[0], p[1])
        }
    };
    let mut o = format!(
        "<h2>Lines to run</h2><p class=\"note\">{}, {}; courses true{}. R: the first recommendation's.</p>\n<table><tr><th class=\"l\">line</th><th>start x</th><th>start y</th><th>end x</th><th>end y</th><th>course [deg]</th><th>speed [m/s]</th><th>time [s]</th><th>INS height [m]</th></tr>\n",
        escape(&l.crs),
        escape(&l.axes),
        l.side_deg.map_or(String::new(), |b| format!("; the spheres' side at a bearing of {b:.0} deg"))
    );
    for x in &l.lines {
        o += &format!(
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{:.1}</td><td>{:.1}</td><td>{:.0}</td><td>{:+.1}</td></tr>\n",
            escape(&x.name),
            xy(x.start),
            xy(x.end),
            x.course_deg,
            x.speed_mps,
            x.duration_s,
            x.height_m
        );
    }
    o + "</table>\n"
}

/// The lines (and the spheres) as GeoJSON (RFC 7946: WGS 84 longitude, latitude).
pub fn geojson(site: &Site, l: &Lines) -> Result<serde_json::Value, crate::Error> {
    let shift = crate::config::datum::DatumShift::between(
        &site.datum(),
        &crate::config::datum::Datum::wgs84(),
    )?;
    let mut features: Vec<serde_json::Value> = l
        .lines
        .iter()
        .map(|x| {
            serde_json::json!({
                "type": "Feature",
                "geometry": { "type": "LineString", "coordinates": [x.start_wgs84, x.end_wgs84] },
                "properties": { "name": x.name, "course_deg": x.course_deg, "speed_mps": x.speed_mps,
                    "duration_s": x.duration_s, "height_m": x.height_m,
                    "recommended": x.name.starts_with('R'),
                    "start_grid": x.start, "end_grid": x.end, "grid": l.crs },
            })
        })
        .collect();
    for sp in &site.sphere {
        let (lat, lon, _) = shift.apply(sp.lat_deg, sp.lon_deg, sp.h_m)?;
        features.push(serde_json::json!({
            "type": "Feature",
            "geometry": { "type": "Point", "coordinates": [lon, lat] },
            "properties": { "name": sp.id, "radius_m": sp.radius_m, "sphere": true },
        }));
    }
    Ok(serde_json::json!({ "type": "FeatureCollection", "features": features }))
}

//! `spherecal georef`: the pipeline over files, a LAS point cloud and the sphere windows as CSV.

use crate::config::crs::Crs;
use crate::config::site::Site;
use crate::pipeline::{run, BatchMsg, Inputs, RunStats};
use spherecal::align::window::GeoPoint;
use spherecal::georef::Mount;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// The windows CSV header.
pub const WINDOWS_HEADER: &str = "sphere,time_gps_s,x_m,y_m,z_m,range_m,laser,packet,block,channel";

/// Where a LAS file's coordinates are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum LasFrame {
    /// In the site's projected CRS (its `[crs]`; else the WGS84 UTM zone of the origin), with
    /// the WKT CRS record; heights as the site's (ellipsoidal, or orthometric with its N).
    #[default]
    Projected,
    /// East-north-up metres from the site origin (no CRS).
    Local,
}

/// Site NED -> the map: the site's CRS (or the origin's UTM zone) and its height system.
struct ToMap {
    crs: Crs,
    frame: spherecal::frames::LocalFrame,
    /// From the site frame's datum (the trajectory's) to the CRS's.
    shift: crate::config::datum::DatumShift,
    /// Subtracted from ellipsoidal heights (the geoid undulation for orthometric heights).
    undulation: crate::config::crs::Undulation,
    /// The compound CRS (horizontal + vertical) the LAS file records, as WKT1.
    wkt: String,
}

impl ToMap {
    fn for_site(site: &Site, frame: spherecal::frames::LocalFrame) -> Result<Self, crate::Error> {
        use crate::config::crs::Undulation;
        let own = match &site.crs {
            Some(c) => Some((Crs::epsg(c.epsg)?, c)).filter(|(crs, _)| !crs.is_geographic()),
            None => None,
        };
        let (crs, undulation, vertical) = match own {
            Some((crs, c)) => (crs, c.undulation(&site.base)?, c.vertical_epsg),
            None => {
                let (lat, lon) = (site.origin.lat_deg, site.origin.lon_deg);
                let zone = (((lon + 180.0) / 6.0).floor() as i32).clamp(0, 59) as u16 + 1;
                (
                    Crs::epsg(if lat >= 0.0 { 32600 } else { 32700 } + zone)?,
                    Undulation::None,
                    None,
                )
            }
        };
        let shift = crate::config::datum::DatumShift::between(
            &site.datum(),
            &crate::config::datum::Datum::of_crs(crs.code)?,
        )?;
        let wkt = compound_wkt(&crs, &undulation, vertical);
        Ok(Self {
            crs,
            frame,
            shift,
            undulation,
            wkt,
        })
    }

    fn xyz(&self, ned: &nalgebra::Vector3<f64>) -> Result<(f64, f64, f64), crate::Error> {
        let g = self.frame.to_geodetic(ned);
        let (lat, lon, h) = self
            .shift
            .apply(g.lat.to_degrees(), g.lon.to_degrees(), g.h)?;
        let (x, y, h) = self.crs.from_geographic(lat, lon, h)?;
        Ok((x, y, h - self.undulation.at(lat, lon)?))
    }
}

/// A LAS file's compound CRS (LAS 1.4 R15 2.4: WKT in an OGC coordinate system VLR): the
/// horizontal CRS's WKT1 without its `TOWGS84` (with it, readers do not see the EPSG code) and
/// the heights' vertical CRS: the EPSG one given, else an orthometric height on a geoid, or
/// ellipsoidal heights (`VERT_DATUM` type 2002: pyproj reads the whole as a 3D CRS).
pub fn compound_wkt(
    crs: &Crs,
    undulation: &crate::config::crs::Undulation,
    vertical_epsg: Option<u16>,
) -> String {
    use crate::config::crs::Undulation;
    let mut h = crs.wkt.to_string();
    while let Some(i) = h.find(",TOWGS84[") {
        let end = h[i + 1..].find(']').map_or(h.len(), |j| i + 2 + j);
        h.replace_range(i..end, "");
    }
    let name = h.split('"').nth(1).unwrap_or("horizontal").to_string();
    let known = vertical_epsg.and_then(|v| {
        crate::config::epsg_tables::VERTICAL
            .binary_search_by_key(&v, |x| x.0)
            .ok()
            .map(|i| crate::config::epsg_tables::VERTICAL[i].1)
    });
    let metre = "UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]]";
    let v = match (known, undulation) {
        (Some(w), _) => w.to_string(),
        (None, Undulation::None) => format!(
            "VERT_CS[\"ellipsoidal height\",VERT_DATUM[\"Ellipsoid\",2002],{metre},AXIS[\"Up\",UP]]"
        ),
        (None, Undulation::Constant(n)) => format!(
            "VERT_CS[\"orthometric height (geoid N = {n} m)\",VERT_DATUM[\"geoid N = {n} m\",2005],{metre},AXIS[\"Gravity-related height\",UP]]"
        ),
        (None, Undulation::Grid(g)) => {
            let f = g
                .path
                .file_name()
                .map_or("a geoid grid".into(), |f| f.to_string_lossy().to_string());
            format!(
                "VERT_CS[\"orthometric height ({f})\",VERT_DATUM[\"{f}\",2005],{metre},AXIS[\"Gravity-related height\",UP]]"
            )
        }
    };
    let vname = v.split('"').nth(1).unwrap_or("vertical").to_string();
    format!("COMPD_CS[\"{name} + {vname}\",{h},{v}]")
}

/// Extra bytes per point: laser (u8), window (u8: sphere index + 1, 0 none), residual to the
/// window's sphere (f32 metres, NaN outside every window).
const EXTRA: [(&str, u8, &str); 3] = [
    ("laser", 1, "VLP-16 laser id 0-15"),
    ("window", 1, "sphere window + 1 (0: none)"),
    ("residual", 9, "to the sphere surface [m]"),
];

/// The Extra Bytes VLR (LAS 1.4 R15 section 2.5: one 192-byte descriptor per field).
fn extra_bytes_vlr() -> las::Vlr {
    let mut data = Vec::with_capacity(192 * EXTRA.len());
    for (name, ty, description) in EXTRA {
        let mut d = [0u8; 192];
        d[2] = ty;
        // Names and descriptions are 32-byte fields, NUL-padded.
        let (name, description) = (
            &name.as_bytes()[..name.len().min(31)],
            description.as_bytes(),
        );
        d[4..4 + name.len()].copy_from_slice(name);
        let description = &description[..description.len().min(31)];
        d[160..160 + description.len()].copy_from_slice(description);
        data.extend_from_slice(&d);
    }
    las::Vlr {
        user_id: "LASF_Spec".into(),
        record_id: 4,
        description: "spherecal extra bytes".into(),
        data,
    }
}

/// A LAS 1.4 writer (point format 6 + extra bytes: GPS time, intensity, classification 1 in a
/// window, laser, window, residual), in the site's CRS or local east-north-up metres.
pub struct LasOut {
    w: las::Writer<crate::output::Staged>,
    abandon: crate::output::Abandon,
    path: std::path::PathBuf,
    to_map: Option<ToMap>,
    targets: Vec<spherecal::align::window::Target>,
    /// Points written.
    pub points: u64,
    /// First write error.
    pub error: Option<String>,
}

impl LasOut {
    /// The LAS of `site`'s points can be made in `frame` (its CRS and the datum shift to it
    /// are known): checked before a long run.
    pub fn check(site: &Site, frame: LasFrame) -> Result<(), crate::Error> {
        if frame == LasFrame::Projected {
            let (local, _) = crate::pipeline::targets(site);
            ToMap::for_site(site, local).map_err(|e| format!("--las: {e}"))?;
        }
        Ok(())
    }

    /// Create the file for `site`'s points, in `frame`.
    pub fn create(path: &Path, site: &Site, frame: LasFrame) -> Result<Self, crate::Error> {
        let (local, targets) = crate::pipeline::targets(site);
        let to_map = match frame {
            LasFrame::Projected => Some(ToMap::for_site(site, local)?),
            LasFrame::Local => None,
        };
        let mut b = las::Builder::from((1, 4));
        b.point_format = las::point::Format::new(6).map_err(|e| e.to_string())?;
        b.point_format.extra_bytes = 6;
        b.gps_time_type = las::GpsTimeType::Standard;
        b.generating_software = format!("spherecal {}", env!("CARGO_PKG_VERSION"));
        b.system_identifier = "spherecal georef".into();
        let now = spherecal_hal::clock::wall();
        let t = spherecal::time::UtcDateTime::from_unix_ns(now.0);
        b.date = chrono::NaiveDate::from_ymd_opt(t.year, u32::from(t.month), u32::from(t.day));
        // A GUID from the file's name and the time it was written (FNV-1a, 128 bits).
        let mut h = 0x6c62_272e_07bb_0142_62b8_2175_6295_c58du128;
        for byte in path
            .display()
            .to_string()
            .bytes()
            .chain(now.0.to_le_bytes())
        {
            h = (h ^ u128::from(byte)).wrapping_mul(0x0000_0000_0100_0000_0000_0000_0000_013b);
        }
        b.guid = uuid::Uuid::from_u128(h);
        b.vlrs.push(extra_bytes_vlr());
        // Offsets at the origin (to the kilometre): 0.1 mm steps reach 214 km from it.
        let origin = match &to_map {
            Some(m) => m.xyz(&nalgebra::Vector3::zeros())?,
            None => (0.0, 0.0, 0.0),
        };
        let km = |v: f64| (v / 1000.0).round() * 1000.0;
        let tr = |offset: f64| las::Transform {
            scale: 0.0001,
            offset,
        };
        b.transforms = las::Vector {
            x: tr(km(origin.0)),
            y: tr(km(origin.1)),
            z: tr(0.0),
        };
        let mut header = b.into_header().map_err(|e| e.to_string())?;
        if let Some(m) = &to_map {
            header
                .set_wkt_crs(m.wkt.as_bytes().to_vec())
                .map_err(|e| e.to_string())?;
        }
        let staged = crate::output::Staged::create(path)?;
        let abandon = staged.abandon_handle();
        let w = las::Writer::new(staged, header).map_err(|e| {
            abandon.abandon();
            format!("{}: {e}", path.display())
        })?;
        Ok(Self {
            w,
            abandon,
            path: path.to_path_buf(),
            to_map,
            targets,
            points: 0,
            error: None,
        })
    }

    /// Add one return.
    pub fn add(&mut self, p: &GeoPoint) {
        if self.error.is_some() {
            return;
        }
        let (x, y, z) = match &self.to_map {
            Some(m) => match m.xyz(&p.ned) {
                Ok(v) => v,
                Err(e) => {
                    self.error = Some(e.to_string());
                    return;
                }
            },
            None => (p.ned.y, p.ned.x, -p.ned.z),
        };
        let residual = p
            .window
            .and_then(|w| self.targets.get(usize::from(w)))
            .map_or(f32::NAN, |t| ((p.ned - t.center).norm() - t.radius) as f32);
        let mut extra = Vec::with_capacity(6);
        extra.push(p.laser);
        extra.push(p.window.map_or(0, |w| w + 1));
        extra.extend_from_slice(&residual.to_le_bytes());
        let pt = las::Point {
            x,
            y,
            z,
            intensity: u16::from(p.intensity),
            gps_time: Some(p.time.as_secs_f64() - 1e9),
            user_data: p.window.map_or(0, |w| w + 1),
            classification: if p.window.is_some() {
                las::point::Classification::Unclassified
            } else {
                las::point::Classification::CreatedNeverClassified
            },
            return_number: 1,
            number_of_returns: 1,
            extra_bytes: extra,
            ..Default::default()
        };
        match self.w.write_point(pt) {
            Ok(()) => self.points += 1,
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// Finish the file (written whole under its name only now; on an error nothing is left).
    pub fn close(self) -> Result<u64, crate::Error> {
        if let Some(e) = self.error {
            // The writer finishes the file as it drops: into nothing.
            self.abandon.abandon();
            return Err(format!("{}: {e}", self.path.display()).into());
        }
        self.w
            .into_inner()
            .map_err(|e| format!("{}: {e}", self.path.display()))?
            .commit()?;
        Ok(self.points)
    }
}

/// Run georef: returns the counts and the rendered summary.
pub fn georef(
    inp: &Inputs,
    las: Option<(&Path, LasFrame)>,
    windows: Option<&Path>,
) -> Result<(RunStats, Vec<u64>, String), crate::Error> {
    let mut las_out = las
        .map(|(p, f)| LasOut::create(p, &inp.site, f))
        .transpose()?;
    let mut wfile = windows.map(crate::output::Staged::create).transpose()?;
    let ids: Vec<String> = inp.site.sphere.iter().map(|s| s.id.clone()).collect();
    let mount: Mount = inp.mount;
    let mut add = |p: &GeoPoint| {
        if let Some(l) = las_out.as_mut() {
            l.add(p)
        }
    };
    let each: Option<&mut dyn FnMut(&GeoPoint)> = if las.is_some() { Some(&mut add) } else { None };
    let (stats, (counts, werr)) = run(inp, each, |rx: crossbeam_channel::Receiver<BatchMsg>| {
        let mut counts = vec![0u64; ids.len()];
        let mut err = None;
        let mut line = String::new();
        if let Some(w) = wfile.as_mut() {
            if let Err(e) = writeln!(w, "{WINDOWS_HEADER}") {
                err = Some(e.to_string());
            }
        }
        for msg in rx {
            counts[msg.sphere] += msg.obs.len() as u64;
            if let Some(w) = wfile.as_mut() {
                for o in &msg.obs {
                    let x = o.georef(&mount);
                    line.clear();
                    let _ = writeln!(
                        line,
                        "{},{:.9},{:.5},{:.5},{:.5},{:.3},{},{},{},{}",
                        ids[msg.sphere],
                        o.time.as_secs_f64(),
                        x.x,
                        x.y,
                        x.z,
                        o.range,
                        o.laser,
                        o.packet,
                        o.block,
                        o.channel
                    );
                    if let Err(e) = w.write_all(line.as_bytes()) {
                        err.get_or_insert(e.to_string());
                    }
                }
            }
        }
        if let Some(w) = wfile.as_mut() {
            if let Err(e) = w.flush() {
                err.get_or_insert(e.to_string());
            }
        }
        (counts, err)
    })?;
    if let Some(e) = werr {
        return Err(format!("windows CSV: {e}").into());
    }
    if let Some(w) = wfile {
        w.commit()?;
    }
    let las_points = match las_out {
        Some(l) => Some(l.close().map_err(|e| format!("LAS: {e}"))?),
        None => None,
    };
    let mut o = String::new();
    let w = &stats.align.window;
    let _ = writeln!(
        o,
        "data packets: {} (position packets: {}, hour rollovers: {})",
        stats.align.data_packets, stats.align.position_packets, stats.align.rollovers
    );
    o.push_str(&stats.describe_inputs(&inp.pcap, inp.ins_files()));
    let _ = writeln!(o, "points: {} georeferenced: {}", w.points, w.georeferenced);
    for (i, id) in ids.iter().enumerate() {
        let _ = writeln!(o, "window {id}: {} points", counts[i]);
    }
    if stats.align.batch_overflow > 0 {
        let _ = writeln!(
            o,
            "WARNING: {} windowed returns lost: a window's fixed-capacity batch was full",
            stats.align.batch_overflow
        );
    }
    if let Some(n) = las_points {
        let _ = writeln!(o, "LAS points written: {n}");
    }
    Ok((stats, counts, o))
}

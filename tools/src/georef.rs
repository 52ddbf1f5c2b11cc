//! `spherecal georef`: the pipeline over files, a LAS point cloud and the sphere windows as CSV.

use crate::pipeline::{run, BatchMsg, Inputs, RunStats};
use spherecal::georef::Mount;
use spherecal::window::GeoPoint;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// The windows CSV header.
pub const WINDOWS_HEADER: &str = "sphere,time_gps_s,x_m,y_m,z_m,range_m,laser,packet,block,channel";

/// A LAS 1.4 writer (point format 6: GPS time, intensity, user data = window + 1), local
/// east-north-up metres from the site origin.
pub struct LasOut {
    w: las::Writer<std::io::BufWriter<std::fs::File>>,
    /// Points written.
    pub points: u64,
    /// First write error.
    pub error: Option<String>,
}

impl LasOut {
    /// Create the file.
    pub fn create(path: &Path) -> Result<Self, String> {
        let mut b = las::Builder::from((1, 4));
        b.point_format = las::point::Format::new(6).map_err(|e| e.to_string())?;
        b.gps_time_type = las::GpsTimeType::Standard;
        b.generating_software = "spherecal".into();
        b.system_identifier = "spherecal georef".into();
        let t = las::Transform {
            scale: 0.0001,
            offset: 0.0,
        };
        b.transforms = las::Vector { x: t, y: t, z: t };
        let header = b.into_header().map_err(|e| e.to_string())?;
        let w =
            las::Writer::from_path(path, header).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Self {
            w,
            points: 0,
            error: None,
        })
    }

    /// Add one return.
    pub fn add(&mut self, p: &GeoPoint) {
        if self.error.is_some() {
            return;
        }
        let pt = las::Point {
            x: p.ned.y,
            y: p.ned.x,
            z: -p.ned.z,
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
            ..Default::default()
        };
        match self.w.write_point(pt) {
            Ok(()) => self.points += 1,
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// Finish the file.
    pub fn close(mut self) -> Result<u64, String> {
        if let Some(e) = self.error {
            return Err(e);
        }
        self.w.close().map_err(|e| e.to_string())?;
        Ok(self.points)
    }
}

/// Run georef: returns the counts and the rendered summary.
pub fn georef(
    inp: &Inputs,
    las: Option<&Path>,
    windows: Option<&Path>,
) -> Result<(RunStats, Vec<u64>, String), String> {
    let mut las_out = las.map(LasOut::create).transpose()?;
    let mut wfile = match windows {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| format!("{}: {e}", p.display()))?,
        )),
        None => None,
    };
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
        return Err(format!("windows CSV: {e}"));
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
    o.push_str(&stats.describe_inputs(&inp.pcap, inp.ins_path()));
    let _ = writeln!(o, "points: {} georeferenced: {}", w.points, w.georeferenced);
    for (i, id) in ids.iter().enumerate() {
        let _ = writeln!(o, "window {id}: {} points", counts[i]);
    }
    let _ = writeln!(
        o,
        "readers waited for room in the rings (files: nothing is lost): LiDAR {}, INS {}; windowed returns lost to full batches: {}",
        stats.ring_full[0], stats.ring_full[1], stats.align.batch_overflow
    );
    if let Some(n) = las_points {
        let _ = writeln!(o, "LAS points written: {n}");
    }
    Ok((stats, counts, o))
}

//! Geoid models as grid files (GTX, the NOAA/PROJ vertical grid format in which CGG2013,
//! EGM2008, GEOID18 and others are published): the undulation N above the ellipsoid, by
//! bilinear interpolation, so that an orthometric height H becomes h = H + N.
//!
//! GTX (big-endian): south latitude, west longitude, latitude step, longitude step [deg] as
//! f64; rows, columns as i32; then rows x columns f32 undulations [m], row by row from the
//! south, each row from the west; -88.8888 marks no data.

use std::path::{Path, PathBuf};

/// A loaded geoid grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Geoid {
    /// The file it came from.
    pub path: PathBuf,
    south: f64,
    west: f64,
    dlat: f64,
    dlon: f64,
    rows: usize,
    cols: usize,
    n: Vec<f32>,
}

/// GTX's no-data value.
const NO_DATA: f32 = -88.8888;

impl Geoid {
    /// Read a GTX file; errors name the file and what is wrong.
    pub fn load(path: &Path) -> Result<Self, crate::Error> {
        let b = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::parse(&b)
            .map_err(|e| format!("{}: {e}", path.display()).into())
            .map(|mut g| {
                g.path = path.to_path_buf();
                g
            })
    }

    /// A GTX file's bytes.
    pub fn parse(b: &[u8]) -> Result<Self, crate::Error> {
        if b.len() < 40 {
            return Err(
                format!("{} bytes: not a GTX geoid grid (its header is 40)", b.len()).into(),
            );
        }
        let f = |i: usize| f64::from_be_bytes(b[i..i + 8].try_into().unwrap_or([0; 8]));
        let n = |i: usize| i32::from_be_bytes(b[i..i + 4].try_into().unwrap_or([0; 4]));
        let (south, west, dlat, dlon) = (f(0), f(8), f(16), f(24));
        let (rows, cols) = (n(32), n(36));
        let ok = [south, west, dlat, dlon].iter().all(|v| v.is_finite())
            && south.abs() <= 90.0
            && dlat > 0.0
            && dlon > 0.0
            && rows > 1
            && cols > 1
            && (rows as i64) * (cols as i64) <= 100_000_000;
        if !ok {
            return Err(format!(
                "not a GTX geoid grid (header: south {south}, west {west}, steps {dlat} x {dlon} deg, {rows} x {cols})"
            ).into());
        }
        let (rows, cols) = (rows as usize, cols as usize);
        let need = 40 + 4 * rows * cols;
        if b.len() != need {
            return Err(format!(
                "a GTX header for {rows} x {cols} values needs {need} bytes, the file has {}",
                b.len()
            )
            .into());
        }
        let n = b[40..]
            .chunks_exact(4)
            .map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        Ok(Self {
            path: PathBuf::new(),
            south,
            west,
            dlat,
            dlon,
            rows,
            cols,
            n,
        })
    }

    /// N [m] at latitude, longitude [deg] (bilinear between the four grid points around it);
    /// `None` outside the grid or next to no data.
    pub fn undulation(&self, lat: f64, lon: f64) -> Option<f64> {
        let y = (lat - self.south) / self.dlat;
        // Longitudes east of the grid's west edge, whatever convention (-180..180, 0..360).
        let x = (lon - self.west).rem_euclid(360.0) / self.dlon;
        if !(y >= 0.0 && x >= 0.0) {
            return None;
        }
        let (i, j) = (y.floor() as usize, x.floor() as usize);
        if i + 1 >= self.rows || j + 1 >= self.cols {
            // On the last row or column exactly.
            let (i, j) = (i.min(self.rows - 1), j.min(self.cols - 1));
            return ((y - i as f64).abs() < 1e-9 && (x - j as f64).abs() < 1e-9)
                .then(|| self.at(i, j))
                .flatten();
        }
        let (fy, fx) = (y - i as f64, x - j as f64);
        let v = [
            self.at(i, j)?,
            self.at(i, j + 1)?,
            self.at(i + 1, j)?,
            self.at(i + 1, j + 1)?,
        ];
        Some(
            v[0] * (1.0 - fx) * (1.0 - fy)
                + v[1] * fx * (1.0 - fy)
                + v[2] * (1.0 - fx) * fy
                + v[3] * fx * fy,
        )
    }

    fn at(&self, i: usize, j: usize) -> Option<f64> {
        let v = *self.n.get(i * self.cols + j)?;
        ((v - NO_DATA).abs() > 1e-3 && v.is_finite()).then_some(f64::from(v))
    }
}

/// A GTX file's bytes for a grid (tests, and a surveyor's hand-made constant grid).
pub fn gtx_bytes(south: f64, west: f64, step: [f64; 2], rows: usize, n: &[f32]) -> Vec<u8> {
    let cols = n.len() / rows.max(1);
    let mut b = Vec::with_capacity(40 + 4 * n.len());
    for v in [south, west, step[0], step[1]] {
        b.extend_from_slice(&v.to_be_bytes());
    }
    b.extend_from_slice(&(rows as i32).to_be_bytes());
    b.extend_from_slice(&(cols as i32).to_be_bytes());
    for v in n {
        b.extend_from_slice(&v.to_be_bytes());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 x 4 grid by hand: the corners exactly, the middle of a cell the mean of its four,
    /// a point a quarter of the way the weighted mean; longitudes given 0..360 or -180..180
    /// alike; outside the grid and next to no data, nothing; bad files refused.
    #[test]
    fn bilinear_by_hand() {
        // South 46, west -72 (288 E), steps 0.5 x 1 deg.
        let n = [
            -28.0, -27.0, -26.0, -25.0, //
            -30.0, -29.0, -28.0, NO_DATA, //
            -32.0, -31.0, -30.0, -29.0,
        ];
        let g = Geoid::parse(&gtx_bytes(46.0, 288.0, [0.5, 1.0], 3, &n)).unwrap();
        assert_eq!(g.undulation(46.0, -72.0), Some(-28.0));
        assert_eq!(g.undulation(46.0, 288.0), Some(-28.0));
        assert_eq!(g.undulation(47.0, -72.0), Some(-32.0));
        assert!((g.undulation(46.25, -71.5).unwrap() - (-28.5)).abs() < 1e-9);
        let q = g.undulation(46.125, -71.75).unwrap();
        let want = -28.0 * 0.75 * 0.75 + -27.0 * 0.25 * 0.75 + -30.0 * 0.75 * 0.25 + -29.0 * 0.0625;
        assert!((q - want).abs() < 1e-9, "{q} {want}");
        assert_eq!(g.undulation(45.9, -71.5), None);
        assert_eq!(g.undulation(46.25, -69.5), None); // beside the hole
        assert!(Geoid::parse(&[0u8; 12]).is_err());
        let mut bad = gtx_bytes(46.0, 288.0, [0.5, 1.0], 3, &n);
        bad.pop();
        assert!(Geoid::parse(&bad)
            .unwrap_err()
            .to_string()
            .contains("needs 88 bytes"));
    }
}

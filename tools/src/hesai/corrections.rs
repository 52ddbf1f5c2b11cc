//! A Hesai unit's angle correction file (the CSV the sensor's web page, PandarView or the PTC
//! command 0x05 gives, and tier4/nebula ships per model): a header line (`Channel,Elevation,
//! Azimuth` or `Laser id,Elevation,Azimuth`), then one row per channel from 1: the channel, its
//! elevation and its azimuth offset [deg].

use spherecal::hesai::{Corrections, MAX_CHANNELS};
use std::path::Path;

/// Read the correction file at `path`.
pub fn load(path: &Path) -> Result<Corrections, crate::Error> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| crate::Error::bad_input(format!("{}: {e}", path.display())))?;
    parse(&text).map_err(|e| crate::Error::bad_input(format!("{}: {e}", path.display())))
}

/// Parse a correction file's text; the error names the line and what it should hold.
pub fn parse(text: &str) -> Result<Corrections, String> {
    let (mut el, mut az) = (Vec::new(), Vec::new());
    for (n, line) in text.lines().enumerate() {
        let line = line.trim().trim_start_matches('\u{feff}');
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let Ok(id) = f[0].parse::<usize>() else {
            if el.is_empty() {
                continue; // the header, or blank lines before the rows
            }
            if line.is_empty() {
                continue;
            }
            return Err(format!(
                "line {}: {line:?} where channel {}'s row (channel,elevation,azimuth) was expected",
                n + 1,
                el.len() + 1
            ));
        };
        if id != el.len() + 1 {
            return Err(format!(
                "line {}: channel {id} where channel {} was expected (rows from 1, in order)",
                n + 1,
                el.len() + 1
            ));
        }
        let num = |k: usize, what: &str| {
            f.get(k)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("line {}: channel {id}'s {what} is not a number", n + 1))
        };
        el.push(num(1, "elevation")?);
        az.push(num(2, "azimuth")?);
    }
    if el.is_empty() || el.len() > MAX_CHANNELS {
        return Err(format!(
            "{} channel rows: an angle correction file has 1-{MAX_CHANNELS} (channel,elevation,azimuth)",
            el.len()
        ));
    }
    Corrections::new(&el, &az).ok_or_else(|| {
        "an elevation beyond +-90 deg or an azimuth offset beyond +-180 deg: not a correction file"
            .to_string()
    })
}

#[cfg(test)]
mod tests {
    use super::parse;

    #[test]
    fn rows_are_read_in_channel_order_and_a_bad_row_is_named() {
        let c = parse("Channel,Elevation,Azimuth\n1,14.97,0.08\n2,13.95,-0.07\n").unwrap();
        assert_eq!(c.channels(), 2);
        let (az, el) = c.block(0).angles_deg(1);
        assert!((el - 13.95).abs() < 1e-12 && (az - 359.93).abs() < 1e-9);
        assert!(parse("Laser id,Elevation,Azimuth\n1,1,0\n3,2,0\n")
            .unwrap_err()
            .contains("line 3: channel 3 where channel 2"));
        assert!(parse("Channel,Elevation,Azimuth\n1,x,0\n")
            .unwrap_err()
            .contains("elevation is not a number"));
        assert!(parse("Channel,Elevation,Azimuth\n1,95,0\n").is_err());
        assert!(parse("nothing here")
            .unwrap_err()
            .contains("0 channel rows"));
    }
}

//! VectorNav ASCII sentences: `$VN` + 3 letters + `,fields` + `*` + checksum (VN-200 user
//! manual, "ASCII Output Messages" and "Checksum / CRC"; PROTOCOLS.md): 2 hex digits = XOR of
//! the bytes between `$` and `*`, 4 hex digits = CRC-16/XMODEM of the same bytes.
//!
//! `$VN` sentences are longer than NMEA allows, so the `nmea` crate is for the other devices'
//! sentences only ([`parse_nmea`]).

use super::binary::{xor8, CRC16};
use super::Error;
use crate::time::GpsTime;

/// Longest sentence accepted (VectorNav's longest register replies are under 256 bytes).
pub const MAX_SENTENCE: usize = 256;

/// The checksum a sentence carried.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Checksum {
    /// 8-bit XOR, two hex digits.
    Xor8(u8),
    /// CRC-16/XMODEM, four hex digits.
    Crc16(u16),
}

/// A checksum-verified ASCII sentence (`$` to the checksum, no CR/LF).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sentence<'a> {
    line: &'a str,
    star: usize,
    /// The checksum it carried (verified).
    pub checksum: Checksum,
}

fn hex_value(s: &[u8]) -> Option<u16> {
    let mut v = 0u16;
    for &c in s {
        let d = match c {
            b'0'..=b'9' => c - b'0',
            b'A'..=b'F' => c - b'A' + 10,
            b'a'..=b'f' => c - b'a' + 10,
            _ => return None,
        };
        v = (v << 4) | u16::from(d);
    }
    Some(v)
}

/// Parse and verify one sentence (`$...*CS`, CR/LF already removed).
pub fn parse(line: &[u8]) -> Result<Sentence<'_>, Error> {
    if line.first() != Some(&b'$')
        || line.len() > MAX_SENTENCE
        || !line.iter().all(|&c| (0x20..0x7F).contains(&c))
    {
        return Err(Error::BadSentence);
    }
    let star = line
        .iter()
        .rposition(|&c| c == b'*')
        .ok_or(Error::BadSentence)?;
    let digits = &line[star + 1..];
    let body = &line[1..star];
    let sent = hex_value(digits).ok_or(Error::BadSentence)?;
    let checksum = match digits.len() {
        2 => {
            let computed = u16::from(xor8(body));
            if computed != sent {
                return Err(Error::AsciiChecksum { computed, sent });
            }
            Checksum::Xor8(sent as u8)
        }
        4 => {
            let computed = CRC16.checksum(body);
            if computed != sent {
                return Err(Error::AsciiChecksum { computed, sent });
            }
            Checksum::Crc16(sent)
        }
        _ => return Err(Error::BadSentence),
    };
    let line = core::str::from_utf8(line).map_err(|_| Error::BadSentence)?;
    Ok(Sentence {
        line,
        star,
        checksum,
    })
}

impl<'a> Sentence<'a> {
    /// The talker and type, e.g. `VNINS` or `GPRMC`.
    pub fn name(&self) -> &'a str {
        let body = &self.line[1..self.star];
        body.split(',').next().unwrap_or("")
    }

    /// Is this a VectorNav sentence (`$VN...`)?
    pub fn is_vn(&self) -> bool {
        self.name().starts_with("VN")
    }

    /// The whole line, `$` to the checksum.
    pub fn line(&self) -> &'a str {
        self.line
    }

    /// The data fields after the name.
    pub fn fields(&self) -> impl Iterator<Item = &'a str> + 'a {
        let body: &'a str = &self.line[1..self.star];
        body.split(',').skip(1)
    }

    /// Decode a `$VN` sentence's fields into a typed value.
    pub fn decode(&self) -> Result<Vn<'a>, Error> {
        let mut f = Fields {
            it: self.fields(),
            index: 0,
        };
        let out = match self.name() {
            "VNINS" => {
                let tow_s = f.num()?;
                let week = f.num::<u16>()?;
                let status = f.hex()?;
                let ypr = f.arr()?;
                let lla = f.arr()?;
                let vel_ned = f.arr()?;
                Vn::Ins(Ins {
                    tow_s,
                    week,
                    status,
                    ypr_deg: ypr,
                    lla,
                    vel_ned,
                    att_u: f.num()?,
                    pos_u: f.num()?,
                    vel_u: f.num()?,
                })
            }
            "VNYMR" => Vn::Ymr(Ymr {
                ypr_deg: f.arr()?,
                mag: f.arr()?,
                accel: f.arr()?,
                gyro: f.arr()?,
            }),
            "VNYPR" => Vn::Ypr(f.arr()?),
            "VNQTN" => Vn::Qtn(f.arr()?),
            "VNGPS" => Vn::Gps(Gps {
                tow_s: f.num()?,
                week: f.num()?,
                fix: f.num()?,
                num_sats: f.num()?,
                lla: f.arr()?,
                vel_ned: f.arr()?,
                pos_u: f.arr()?,
                vel_u: f.num()?,
                time_u: f.num()?,
            }),
            "VNRRG" | "VNWRG" => {
                let id = f.num()?;
                let start = self.line.find(',').unwrap_or(self.star);
                let rest = &self.line[start..self.star];
                let values = rest.splitn(3, ',').nth(2).unwrap_or("");
                Vn::Register {
                    write: self.name() == "VNWRG",
                    id,
                    values,
                }
            }
            // The code is hex (`$VNERR,0C`: insufficient baud rate).
            "VNERR" => Vn::Error(u8::try_from(f.hex()?).map_err(|_| Error::BadField { index: 1 })?),
            _ => Vn::Other,
        };
        if f.it.next().is_some() && !matches!(out, Vn::Register { .. } | Vn::Other) {
            return Err(Error::BadField { index: f.index });
        }
        Ok(out)
    }
}

struct Fields<'a, I: Iterator<Item = &'a str>> {
    it: I,
    index: u8,
}

impl<'a, I: Iterator<Item = &'a str>> Fields<'a, I> {
    fn next(&mut self) -> Result<&'a str, Error> {
        let s = self
            .it
            .next()
            .ok_or(Error::BadField { index: self.index })?;
        self.index = self.index.saturating_add(1);
        Ok(s)
    }
    fn num<T: core::str::FromStr>(&mut self) -> Result<T, Error> {
        let i = self.index;
        let s = self.next()?;
        s.trim_start_matches('+')
            .parse()
            .map_err(|_| Error::BadField { index: i })
    }
    fn hex(&mut self) -> Result<u16, Error> {
        let i = self.index;
        let s = self.next()?;
        if s.is_empty() || s.len() > 4 {
            return Err(Error::BadField { index: i });
        }
        hex_value(s.as_bytes()).ok_or(Error::BadField { index: i })
    }
    fn arr<const N: usize>(&mut self) -> Result<[f64; N], Error> {
        let mut out = [0.0; N];
        for o in out.iter_mut() {
            *o = self.num()?;
        }
        Ok(out)
    }
}

/// `$VNINS`: INS solution, LLA (VN-200 manual, INS Solution - LLA register 63).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ins {
    /// GPS time of week [s].
    pub tow_s: f64,
    /// GPS week.
    pub week: u16,
    /// INS status word (hex on the wire).
    pub status: u16,
    /// Yaw, pitch, roll [deg].
    pub ypr_deg: [f64; 3],
    /// Latitude, longitude [deg], altitude [m].
    pub lla: [f64; 3],
    /// Velocity north, east, down [m/s].
    pub vel_ned: [f64; 3],
    /// Attitude uncertainty [deg].
    pub att_u: f64,
    /// Position uncertainty [m].
    pub pos_u: f64,
    /// Velocity uncertainty [m/s].
    pub vel_u: f64,
}

impl Ins {
    /// GPS time of the solution.
    pub fn gps_time(&self) -> Option<GpsTime> {
        GpsTime::from_week_tow_s(self.week, self.tow_s)
    }
}

/// `$VNYMR`: yaw, pitch, roll, magnetic, acceleration and angular rates (register 27).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ymr {
    /// Yaw, pitch, roll [deg].
    pub ypr_deg: [f64; 3],
    /// Magnetic field [gauss].
    pub mag: [f64; 3],
    /// Acceleration [m/s^2].
    pub accel: [f64; 3],
    /// Angular rate [rad/s].
    pub gyro: [f64; 3],
}

/// `$VNGPS`: GNSS solution, LLA (register 58).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gps {
    /// GPS time of week [s].
    pub tow_s: f64,
    /// GPS week.
    pub week: u16,
    /// Fix type (0 none, 2 2D, 3 3D).
    pub fix: u8,
    /// Satellites used.
    pub num_sats: u8,
    /// Latitude, longitude [deg], altitude [m].
    pub lla: [f64; 3],
    /// Velocity north, east, down [m/s].
    pub vel_ned: [f64; 3],
    /// Position uncertainty north, east, down [m].
    pub pos_u: [f64; 3],
    /// Velocity uncertainty [m/s].
    pub vel_u: f64,
    /// Time uncertainty [s].
    pub time_u: f64,
}

/// A decoded `$VN` sentence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Vn<'a> {
    /// `$VNINS`.
    Ins(Ins),
    /// `$VNYMR`.
    Ymr(Ymr),
    /// `$VNYPR`: yaw, pitch, roll [deg].
    Ypr([f64; 3]),
    /// `$VNQTN`: quaternion x, y, z, w.
    Qtn([f64; 4]),
    /// `$VNGPS`.
    Gps(Gps),
    /// `$VNRRG` / `$VNWRG`: a register reply.
    Register {
        /// `true` for a write reply (WRG).
        write: bool,
        /// Register id.
        id: u8,
        /// The register's values, comma separated, as sent.
        values: &'a str,
    },
    /// `$VNERR`: error code (sent in hex; [`super::command::error_name`]).
    Error(u8),
    /// Any other `$VN` sentence (checksum verified, fields not decoded).
    Other,
}

/// Hand a non-VectorNav sentence to the `nmea` crate (which verifies its XOR checksum again).
pub fn parse_nmea(line: &str) -> Option<nmea::ParseResult> {
    nmea::parse_str(line).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xor_checksum_by_hand() {
        // $VNERR,12*72: 'V'^'N'^'E'^'R'^'R'^','^'1'^'2' = 0x72; the code is hex: 0x12.
        let s = parse(b"$VNERR,12*72").unwrap();
        assert_eq!(s.checksum, Checksum::Xor8(0x72));
        assert_eq!(s.decode(), Ok(Vn::Error(0x12)));
        // $VNERR,0C*02: insufficient baud rate (12).
        assert_eq!(parse(b"$VNERR,0C*02").unwrap().decode(), Ok(Vn::Error(12)));
        assert_eq!(
            parse(b"$VNERR,12*73"),
            Err(Error::AsciiChecksum {
                computed: 0x72,
                sent: 0x73
            })
        );
        assert_eq!(parse(b"$VNERR,12*7"), Err(Error::BadSentence));
        assert_eq!(parse(b"VNERR,12*72"), Err(Error::BadSentence));
    }

    #[test]
    fn crc16_checksum() {
        let body = b"VNYPR,+010.000,-005.000,+001.000";
        let crc = CRC16.checksum(body);
        let mut line = heapless::Vec::<u8, 64>::new();
        line.push(b'$').unwrap();
        line.extend_from_slice(body).unwrap();
        line.push(b'*').unwrap();
        for sh in [12, 8, 4, 0] {
            line.push(b"0123456789ABCDEF"[usize::from((crc >> sh) & 0xF)])
                .unwrap();
        }
        let s = parse(&line).unwrap();
        assert_eq!(s.checksum, Checksum::Crc16(crc));
        assert_eq!(s.decode(), Ok(Vn::Ypr([10.0, -5.0, 1.0])));
    }

    #[test]
    fn register_replies() {
        let s = parse(b"$VNRRG,35,1,1,1,1*75").unwrap();
        assert_eq!(
            s.decode(),
            Ok(Vn::Register {
                write: false,
                id: 35,
                values: "1,1,1,1"
            })
        );
        let s = parse(b"$VNRRG,01,VN-200T-CR*31").unwrap();
        assert_eq!(
            s.decode(),
            Ok(Vn::Register {
                write: false,
                id: 1,
                values: "VN-200T-CR"
            })
        );
    }
}

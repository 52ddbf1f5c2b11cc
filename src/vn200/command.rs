//! Commands to a VectorNav unit, the emit side of [`super::ascii`] (VN-200 user manual, "Serial
//! Command Prompt" and the configuration registers; PROTOCOLS.md): `$` + body + `*` + the 8-bit
//! XOR checksum (two hex digits) + CR LF, written into the caller's buffer.
//!
//! - `$VNWRG,06,0`: Async Data Output Type register (6) off: no ASCII async output.
//! - `$VNWRG,05,921600`: Serial Baud Rate register (5).
//! - `$VNWRG,75,mode,divisor,groups,mask...`: Binary Output register 1 (75; 76 and 77 are 2 and
//!   3): the serial port(s) it goes to (`AsyncMode`: 1, 2, or 3 for both), the divisor of the
//!   800 Hz IMU rate, the group byte and one field mask per group (hex).
//! - `$VNRRG,75`: read a register. `$VNWNV`: write the settings to flash.
//!
//! The unit echoes a write as `$VNWRG,id,values*XX`, or answers `$VNERR,code` (hex);
//! [`BinaryOutput::parse`] reads the echoed values back for comparison.

use super::binary::Masks;
use super::fields::{Group, GROUPS};
use super::Error;

/// The VN-200's IMU rate, which the binary output's rate divisor divides [Hz].
pub const IMU_RATE_HZ: u32 = 800;

/// Binary Output register 1 (id 75), 2 (76) or 3 (77).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BinaryOutput {
    /// Serial port(s): 0 none, 1, 2, 3 both.
    pub async_mode: u16,
    /// Output rate = 800 Hz / this.
    pub rate_divisor: u16,
    /// The fields (16-bit masks only: the register write has no extension words).
    pub masks: Masks,
}

impl BinaryOutput {
    /// The output rate [Hz].
    pub fn rate_hz(&self) -> f64 {
        f64::from(IMU_RATE_HZ) / f64::from(self.rate_divisor.max(1))
    }

    /// The divisor for `rate_hz` if 800 Hz divides into it exactly (200 Hz: 4).
    pub fn divisor_for(rate_hz: f64) -> Option<u16> {
        let d = f64::from(IMU_RATE_HZ) / rate_hz;
        let r = libm::round(d);
        (rate_hz > 0.0 && (d - r).abs() < 1e-9 && (1.0..=65535.0).contains(&r)).then_some(r as u16)
    }

    /// The group byte: bit g set when group g has fields.
    pub fn group_byte(&self) -> u8 {
        let mut b = 0u8;
        for g in 0..GROUPS {
            if self.masks.0[g] != 0 {
                b |= 1 << g;
            }
        }
        b
    }

    /// Parse the register's values as a unit echoes them: `mode,divisor,groups(hex),mask(hex)...`
    /// (one mask per group bit set, in bit order).
    pub fn parse(values: &str) -> Result<Self, Error> {
        let mut it = values.split(',').map(str::trim);
        let mut index = 0u8;
        let mut next = |hex: bool| -> Result<u32, Error> {
            index += 1;
            let s = it.next().ok_or(Error::BadField { index })?;
            let v = if hex {
                u32::from_str_radix(s, 16)
            } else {
                s.parse()
            };
            v.map_err(|_| Error::BadField { index })
        };
        let async_mode = next(false)?;
        let rate_divisor = next(false)?;
        let groups = next(true)?;
        if async_mode > 3 || rate_divisor > 0xFFFF || groups > 0x7F {
            return Err(Error::BadField { index: 1 });
        }
        let mut masks = Masks::default();
        for g in 0..GROUPS {
            if groups & (1 << g) != 0 {
                let m = next(true)?;
                if m > 0xFFFF || m & 0x8000 != 0 {
                    return Err(Error::BadField { index: 3 + g as u8 });
                }
                masks.0[g] = m;
            }
        }
        Ok(Self {
            async_mode: async_mode as u16,
            rate_divisor: rate_divisor as u16,
            masks,
        })
    }
}

/// A bounded writer into the caller's buffer.
struct Out<'a> {
    buf: &'a mut [u8],
    n: usize,
}

impl Out<'_> {
    fn push(&mut self, b: &[u8]) -> Result<(), Error> {
        let end = self.n + b.len();
        if end > self.buf.len() {
            return Err(Error::BadSentence);
        }
        self.buf[self.n..end].copy_from_slice(b);
        self.n = end;
        Ok(())
    }

    fn dec(&mut self, v: u32) -> Result<(), Error> {
        let mut d = [0u8; 10];
        let mut i = d.len();
        let mut v = v;
        loop {
            i -= 1;
            d[i] = b'0' + (v % 10) as u8;
            v /= 10;
            if v == 0 {
                break;
            }
        }
        self.push(&d[i..])
    }

    fn hex(&mut self, v: u32, digits: usize) -> Result<(), Error> {
        for k in (0..digits).rev() {
            self.push(&[b"0123456789ABCDEF"[((v >> (4 * k)) & 0xF) as usize]])?;
        }
        Ok(())
    }
}

/// `$` + `body` + `*` + XOR checksum + CR LF into `out`; returns the length.
fn finish(
    out: &mut [u8],
    body: impl FnOnce(&mut Out<'_>) -> Result<(), Error>,
) -> Result<usize, Error> {
    let mut o = Out { buf: out, n: 0 };
    o.push(b"$")?;
    body(&mut o)?;
    let sum = super::binary::xor8(&o.buf[1..o.n]);
    o.push(b"*")?;
    o.hex(u32::from(sum), 2)?;
    o.push(b"\r\n")?;
    Ok(o.n)
}

/// Any sentence: `$` + `body` + `*` + its XOR checksum + CR LF (a unit's replies, in the
/// emulator and tests).
pub fn sentence(out: &mut [u8], body: &[u8]) -> Result<usize, Error> {
    finish(out, |o| o.push(body))
}

/// `$VNRRG,id`: read register `id`.
pub fn read_register(out: &mut [u8], id: u8) -> Result<usize, Error> {
    finish(out, |o| {
        o.push(b"VNRRG,")?;
        o.dec(u32::from(id))
    })
}

/// `$VNWRG,06,0`: the Async Data Output Type register (6) set to `kind` (0: off).
pub fn write_async_output_type(out: &mut [u8], kind: u32) -> Result<usize, Error> {
    finish(out, |o| {
        o.push(b"VNWRG,06,")?;
        o.dec(kind)
    })
}

/// `$VNWRG,05,baud`: the Serial Baud Rate register (5) of the port the command arrives on.
pub fn write_baud(out: &mut [u8], baud: u32) -> Result<usize, Error> {
    finish(out, |o| {
        o.push(b"VNWRG,05,")?;
        o.dec(baud)
    })
}

/// `$VNWRG,id,...`: Binary Output register `id` (75, 76 or 77). Masks beyond 16 bits cannot be
/// written this way and are refused.
pub fn write_binary_output(out: &mut [u8], id: u8, b: &BinaryOutput) -> Result<usize, Error> {
    if !(75..=77).contains(&id) || b.masks.0.iter().any(|&m| m > 0x7FFF) {
        return Err(Error::BadSentence);
    }
    finish(out, |o| {
        o.push(b"VNWRG,")?;
        o.dec(u32::from(id))?;
        o.push(b",")?;
        o.dec(u32::from(b.async_mode))?;
        o.push(b",")?;
        o.dec(u32::from(b.rate_divisor))?;
        o.push(b",")?;
        o.hex(u32::from(b.group_byte()), 2)?;
        for g in Group::ALL {
            let m = b.masks.0[g as usize];
            if m != 0 {
                o.push(b",")?;
                o.hex(m, 4)?;
            }
        }
        Ok(())
    })
}

/// `$VNWNV`: write the current settings to non-volatile memory.
pub fn write_settings(out: &mut [u8]) -> Result<usize, Error> {
    finish(out, |o| o.push(b"VNWNV"))
}

/// A `$VNERR` code in words (VN-200 user manual, "Error Codes").
pub fn error_name(code: u8) -> &'static str {
    match code {
        1 => "hard fault",
        2 => "serial buffer overflow",
        3 => "invalid checksum",
        4 => "invalid command",
        5 => "not enough parameters",
        6 => "too many parameters",
        7 => "invalid parameter",
        8 => "invalid register",
        9 => "unauthorized access",
        10 => "watchdog reset",
        11 => "output buffer overflow",
        12 => "insufficient baud rate for the output asked for",
        255 => "error buffer overflow",
        _ => "unknown error",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vn200::ascii::{parse, Vn};

    fn text(f: impl FnOnce(&mut [u8]) -> Result<usize, Error>) -> std::string::String {
        let mut b = [0u8; 128];
        let n = f(&mut b).unwrap();
        std::string::String::from_utf8(b[..n].to_vec()).unwrap()
    }

    /// Checksums by hand ('V'^'N'^'W'^'R'^'G'^','^'0'^'6'^','^'0' = 0x6C; "VNRRG,1": 0x42);
    /// `$VNWNV*57` as published in users' setup notes; the write read back by our parser.
    #[test]
    fn commands_by_hand() {
        assert_eq!(
            text(|b| write_async_output_type(b, 0)),
            "$VNWRG,06,0*6C\r\n"
        );
        assert_eq!(text(write_settings), "$VNWNV*57\r\n");
        assert_eq!(text(|b| read_register(b, 1)), "$VNRRG,1*42\r\n");
        // TimeGps (1), YawPitchRoll (3), Position (6), InsStatus (12): 0x104A; 200 Hz = 800/4.
        let cfg = BinaryOutput {
            async_mode: 1,
            rate_divisor: BinaryOutput::divisor_for(200.0).unwrap(),
            masks: Masks::default()
                .with(Group::Common, 1)
                .with(Group::Common, 3)
                .with(Group::Common, 6)
                .with(Group::Common, 12),
        };
        let s = text(|b| write_binary_output(b, 75, &cfg));
        assert!(s.starts_with("$VNWRG,75,1,4,01,104A*"), "{s}");
        // Our parser accepts it; the values read back are the same register.
        let line = s.trim_end();
        match parse(line.as_bytes()).unwrap().decode().unwrap() {
            Vn::Register { write, id, values } => {
                assert!(write);
                assert_eq!(id, 75);
                assert_eq!(BinaryOutput::parse(values), Ok(cfg));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(cfg.rate_hz(), 200.0);
        assert_eq!(BinaryOutput::divisor_for(300.0), None);
        // A unit's echo with other spacing and case.
        assert_eq!(BinaryOutput::parse("1,4,01,104a").unwrap(), cfg);
        assert!(BinaryOutput::parse("1,4,01").is_err());
        assert!(BinaryOutput::parse("9,4,01,104A").is_err());
        // Too small a buffer: an error, not a panic.
        let mut tiny = [0u8; 8];
        assert!(write_binary_output(&mut tiny, 75, &cfg).is_err());
        assert!(write_binary_output(&mut [0u8; 64], 74, &cfg).is_err());
    }
}

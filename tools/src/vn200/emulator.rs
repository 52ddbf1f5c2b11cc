//! A VN-200 on the other end of a serial line, for tests and for trying the rig without one:
//! it answers commands as the unit does (VN-200 user manual, "Serial Command Prompt") and
//! sends what its registers say.
//!
//! - Out of the box (factory settings): ASCII async output `$VNYMR` at 40 Hz, no binary output.
//! - `$VNWRG,06,n`, `$VNWRG,05,baud`, `$VNWRG,75..77,...`: checked and echoed as `$VNWRG,id,
//!   values*XX` with its own formatting; `$VNRRG,id` answered; `$VNWNV` acknowledged.
//! - Errors as `$VNERR,code` (hex): 03 a bad checksum (`*XX` skips the check, as on the unit),
//!   04 an unknown command, 05/07 missing or bad parameters, 08 an unknown register, 0C a
//!   binary output the baud cannot carry (10 bits a byte).
//! - A baud write is answered at the old baud, then the line changes.
//! - Binary frames at 800 Hz / divisor with the registered fields: TimeStartup, TimeGps,
//!   YawPitchRoll, Position and InsStatus (tracking) filled, other fields zero.

use spherecal::vn200::ascii::{self, Vn};
use spherecal::vn200::command::{BinaryOutput, IMU_RATE_HZ};
use spherecal::vn200::fields::Size;
use spherecal::vn200::{emit, Group, Masks};
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Bauds the unit takes (register 5): the boards' list.
use crate::config::board::BAUDS;

/// The emulated unit's registers and faults to inject.
#[derive(Debug, Clone)]
pub struct Unit {
    /// Register 6 (0: off; else `$VNYMR` at 40 Hz here).
    pub async_type: u32,
    /// Register 5.
    pub baud: u32,
    /// Registers 75, 76, 77.
    pub binary: [BinaryOutput; 3],
    /// The port this emulates (1 or 2): binary outputs whose async mode excludes it are silent.
    pub port: u16,
    /// Answer the first this many commands with `$VNERR,03` (a line that garbles them).
    pub garble_first: u32,
    /// Answer nothing at all (a unit that is off).
    pub mute: bool,
    /// Commands received (any).
    pub commands: u32,
    /// `$VNWNV` received.
    pub saved: bool,
}

impl Unit {
    /// A unit as it leaves the factory, at `baud`.
    pub fn factory(baud: u32) -> Self {
        let off = BinaryOutput {
            async_mode: 0,
            rate_divisor: 0,
            masks: Masks::default(),
        };
        Self {
            async_type: 14, // YMR
            baud,
            binary: [off; 3],
            port: 1,
            garble_first: 0,
            mute: false,
            commands: 0,
            saved: false,
        }
    }
}

/// A sentence `$body*XX\r\n` with its checksum (the core's emit side; a body too long for
/// a sentence gives nothing).
fn sentence(body: &str) -> Vec<u8> {
    let mut out = vec![0u8; body.len() + 8];
    let n = spherecal::vn200::command::sentence(&mut out, body.as_bytes()).unwrap_or(0);
    out.truncate(n);
    out
}

/// Register 75..77's values as the unit formats them.
fn binary_values(b: &BinaryOutput) -> String {
    let mut s = format!("{},{},{:02X}", b.async_mode, b.rate_divisor, b.group_byte());
    for g in Group::ALL {
        let m = b.masks.0[g as usize];
        if m != 0 {
            s.push_str(&format!(",{m:04X}"));
        }
    }
    s
}

/// Payload bytes of a frame with `masks` (None: a field whose size we cannot give).
fn payload_len(masks: &Masks) -> Option<usize> {
    masks
        .fields()
        .try_fold(0usize, |n, (g, b)| match g.field(b)?.size {
            Size::Fixed(k) => Some(n + usize::from(k)),
            _ => None,
        })
}

impl Unit {
    /// Answer one command line (without CR LF); returns the reply bytes and, for a baud write,
    /// the baud to change to after sending it.
    pub fn answer(&mut self, line: &[u8]) -> (Vec<u8>, Option<u32>) {
        self.commands += 1;
        if self.mute {
            return (Vec::new(), None);
        }
        if self.garble_first > 0 {
            self.garble_first -= 1;
            return (sentence("VNERR,03"), None);
        }
        let err = |c: u8| (sentence(&format!("VNERR,{c:02X}")), None);
        // `*XX` skips the checksum, as on the unit.
        let checked;
        let line = match line.strip_suffix(b"*XX") {
            Some(body) => {
                let sum = spherecal::vn200::binary::xor8(&body[1.min(body.len())..]);
                checked = [body, format!("*{sum:02X}").as_bytes()].concat();
                &checked[..]
            }
            None => line,
        };
        let s = match ascii::parse(line) {
            Ok(s) => s,
            Err(spherecal::vn200::Error::AsciiChecksum { .. }) => return err(3),
            Err(_) => return err(4),
        };
        match (s.name(), s.decode()) {
            ("VNWNV", _) => {
                self.saved = true;
                (sentence("VNWNV"), None)
            }
            ("VNRRG", Ok(Vn::Register { id, .. })) => match self.values(id) {
                Some(v) => (sentence(&format!("VNRRG,{id:02},{v}")), None),
                None => err(8),
            },
            ("VNWRG", Ok(Vn::Register { id, values, .. })) => self.write(id, values),
            ("VNWRG" | "VNRRG", _) => err(5),
            _ => err(4),
        }
    }

    fn values(&self, id: u8) -> Option<String> {
        match id {
            5 => Some(self.baud.to_string()),
            6 => Some(self.async_type.to_string()),
            75..=77 => Some(binary_values(&self.binary[usize::from(id - 75)])),
            _ => None,
        }
    }

    fn write(&mut self, id: u8, values: &str) -> (Vec<u8>, Option<u32>) {
        let err = |c: u8| (sentence(&format!("VNERR,{c:02X}")), None);
        let first = values.split(',').next().unwrap_or("").trim();
        let echo = |u: &Self| {
            sentence(&format!(
                "VNWRG,{id:02},{}",
                u.values(id).unwrap_or_default()
            ))
        };
        match id {
            5 => match first.parse::<u32>() {
                Ok(b) if BAUDS.contains(&b) => {
                    let old = self.baud;
                    self.baud = b;
                    let reply = echo(self);
                    (reply, (b != old).then_some(b))
                }
                _ => err(7),
            },
            6 => match first.parse::<u32>() {
                Ok(v) if v <= 30 || v == 253 => {
                    self.async_type = v;
                    (echo(self), None)
                }
                _ => err(7),
            },
            75..=77 => {
                let Ok(b) = BinaryOutput::parse(values) else {
                    return err(7);
                };
                if b.async_mode != 0 && b.rate_divisor == 0 {
                    return err(7);
                }
                let Some(len) = payload_len(&b.masks) else {
                    return err(7);
                };
                // 10 bits a byte on the line: the output must fit the baud.
                let frame = (b.masks.header_len() + len + 2) as f64;
                if b.async_mode != 0 && frame * 10.0 * b.rate_hz() > f64::from(self.baud) {
                    return err(12);
                }
                self.binary[usize::from(id - 75)] = b;
                (echo(self), None)
            }
            _ => err(8),
        }
    }

    /// The binary frames due now from register `k` at time `t` (seconds since the start).
    fn frame(&self, k: usize, t: f64) -> Option<Vec<u8>> {
        let b = &self.binary[k];
        if b.async_mode == 0 || b.async_mode & self.port == 0 || b.masks == Masks::default() {
            return None;
        }
        let mut payload = Vec::new();
        for (g, bit) in b.masks.fields() {
            let Size::Fixed(n) = g.field(bit)?.size else {
                return None;
            };
            let mut f = vec![0u8; usize::from(n)];
            if g == Group::Common {
                match bit {
                    // TimeStartup: powered on a minute before.
                    0 => f.copy_from_slice(&(((60.0 + t) * 1e9) as u64).to_le_bytes()),
                    // TimeGps: a GPS time in 2024, moving with t.
                    1 => f.copy_from_slice(&(((1_400_000_000.0 + t) * 1e9) as u64).to_le_bytes()),
                    // YawPitchRoll [deg].
                    3 => {
                        for (i, v) in [10.0f32, 1.0, -0.5].iter().enumerate() {
                            f[4 * i..4 * i + 4].copy_from_slice(&v.to_le_bytes());
                        }
                    }
                    // Position: lat, lon [deg], alt [m].
                    6 => {
                        for (i, v) in [48.38f64, -4.49, 52.0].iter().enumerate() {
                            f[8 * i..8 * i + 8].copy_from_slice(&v.to_le_bytes());
                        }
                    }
                    // InsStatus: tracking, GNSS fix.
                    12 => f.copy_from_slice(&0x0006u16.to_le_bytes()),
                    _ => {}
                }
            }
            // The unit's own accuracy: Attitude.YprU [deg] (yaw, pitch, roll), Ins.PosU [m]
            // (an RTK-aided unit's).
            if g == Group::Attitude && bit == 8 {
                for (i, v) in [0.3f32, 0.03, 0.03].iter().enumerate() {
                    f[4 * i..4 * i + 4].copy_from_slice(&v.to_le_bytes());
                }
            }
            if g == Group::Ins && bit == 9 {
                f.copy_from_slice(&0.02f32.to_le_bytes());
            }
            payload.extend_from_slice(&f);
        }
        let mut out = vec![0u8; payload.len() + 64];
        let n = emit(&mut out, &b.masks, &payload).ok()?;
        out.truncate(n);
        Some(out)
    }
}

/// Run the unit on `port` until `stop`: answer commands, send its outputs. `set_baud` changes
/// the line's baud after a baud write was answered.
pub fn run<P: Read + Write>(
    unit: &std::sync::Mutex<Unit>,
    port: &mut P,
    set_baud: &mut dyn FnMut(u32),
    stop: &AtomicBool,
) {
    let start = Instant::now();
    let mut line: Vec<u8> = Vec::new();
    let mut buf = [0u8; 256];
    let mut next_ascii = 0.0f64;
    let mut next_bin = [0.0f64; 3];
    while !stop.load(Ordering::Relaxed) {
        let n = port.read(&mut buf).unwrap_or(0);
        for &c in &buf[..n] {
            match c {
                b'$' => line = vec![c],
                b'\r' | b'\n' if !line.is_empty() => {
                    let (reply, baud) =
                        unit.lock().map(|mut u| u.answer(&line)).unwrap_or_default();
                    line.clear();
                    let _ = port.write_all(&reply).and_then(|()| port.flush());
                    if let Some(b) = baud {
                        set_baud(b);
                    }
                }
                _ if !line.is_empty() && line.len() < 256 => line.push(c),
                _ => {}
            }
        }
        let t = start.elapsed().as_secs_f64();
        let Ok(u) = unit.lock().map(|u| u.clone()) else {
            return;
        };
        if u.mute {
            std::thread::sleep(Duration::from_millis(2));
            continue;
        }
        let mut out = Vec::new();
        if u.async_type != 0 && t >= next_ascii {
            out.extend(sentence(
                "VNYMR,+010.000,+001.000,-000.500,+0.2000,-0.1000,+0.4000,-00.010,+00.020,-09.810,+0.000100,-0.000200,+0.000300",
            ));
            next_ascii = t + 1.0 / 40.0;
        }
        for (k, next) in next_bin.iter_mut().enumerate() {
            let b = u.binary[k];
            if b.rate_divisor > 0 && t >= *next {
                if let Some(f) = u.frame(k, t) {
                    out.extend(f);
                }
                *next = t + f64::from(b.rate_divisor) / f64::from(IMU_RATE_HZ);
            }
        }
        if !out.is_empty() {
            let _ = port.write_all(&out);
        }
        if n == 0 {
            std::thread::sleep(Duration::from_micros(500));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(b: &[u8]) -> String {
        String::from_utf8(b.to_vec()).unwrap()
    }

    /// Replies as the manual has them: echo, hex error codes, the baud change after the reply
    /// (checksums computed by hand with Python's XOR over the body).
    #[test]
    fn answers_like_the_unit() {
        let mut u = Unit::factory(115_200);
        assert_eq!(text(&u.answer(b"$VNWRG,06,0*6C").0), "$VNWRG,06,0*6C\r\n");
        assert_eq!(u.async_type, 0);
        assert_eq!(text(&u.answer(b"$VNWRG,06,0*6D").0), "$VNERR,03*72\r\n");
        assert_eq!(text(&u.answer(b"$VNWRG,06,0*XX").0), "$VNWRG,06,0*6C\r\n");
        assert_eq!(text(&u.answer(b"$VNWRG,99,0*XX").0), "$VNERR,08*79\r\n");
        assert_eq!(text(&u.answer(b"$VNFOO*XX").0), "$VNERR,04*75\r\n");
        // 200 Hz of 52-byte frames (520 bits each) needs 104 kbit/s: too much for 9600.
        let mut slow = Unit::factory(9600);
        assert_eq!(
            text(&slow.answer(b"$VNWRG,75,1,4,01,104A*XX").0),
            "$VNERR,0C*02\r\n"
        );
        let (r, baud) = u.answer(b"$VNWRG,05,921600*XX");
        assert_eq!(text(&r), "$VNWRG,05,921600*53\r\n");
        assert_eq!(baud, Some(921_600));
        let (r, _) = u.answer(b"$VNWRG,75,1,4,01,104A*XX");
        assert!(
            text(&r).starts_with("$VNWRG,75,1,4,01,104A*"),
            "{}",
            text(&r)
        );
        let f = u.frame(0, 1.0).unwrap();
        let fr = spherecal::vn200::Frame::parse(&f).unwrap();
        assert_eq!(fr.yaw_pitch_roll_deg(), Some([10.0, 1.0, -0.5]));
        assert_eq!(fr.ins_status(), Some(6));
    }
}

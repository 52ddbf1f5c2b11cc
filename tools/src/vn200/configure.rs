//! Configure a VN-200 from a board's `[ins]` section over its serial port: ASCII async output
//! off (register 6), optionally the baud (register 5), the binary output (register 75: the
//! board's `fields` at `rate_hz` on `port`: Common-group outputs, and the Attitude group's
//! YprU and the INS group's PosU by which the unit states its own accuracy), each write checked against the unit's
//! `$VNWRG` echo (checksums both ways; `$VNERR` codes in words; retried), optionally saved to
//! flash (`$VNWNV`); then the first binary frames are checked against the board.

use spherecal::vn200::ascii::Vn;
use spherecal::vn200::command::{self, BinaryOutput};
use spherecal::vn200::{Framer, Item, Masks};
use std::io::{Read, Write};
use std::time::{Duration, Instant};

use crate::config::board::InsLink;

/// How a configuration runs.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// The unit's baud now, if not the board's (the rig then sets the board's and follows).
    pub current_baud: Option<u32>,
    /// Write the settings to flash at the end (`$VNWNV`).
    pub save: bool,
    /// Tries per command.
    pub tries: u32,
    /// Wait for each reply.
    pub timeout: Duration,
    /// Wait for the first binary frames.
    pub frames_timeout: Duration,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            current_baud: None,
            save: false,
            tries: 3,
            timeout: Duration::from_millis(500),
            frames_timeout: Duration::from_secs(3),
        }
    }
}

/// What a configuration did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Configured {
    /// Each step, verified, in words.
    pub steps: Vec<String>,
    /// Commands sent again (no reply, a checksum or transport error).
    pub retries: u32,
    /// The binary frames seen at the end: their rate [Hz] and count.
    pub frames: (f64, u32),
}

/// The binary output register 75 the board asks for.
pub fn binary_output(ins: &InsLink) -> Result<BinaryOutput, crate::Error> {
    let bits = ins.output_bits();
    if bits.len() != ins.fields.len() {
        return Err(format!(
            "ins.fields {:?}: not all are VN-200 output fields (Common-group names, or Group.Field)",
            ins.fields
        )
        .into());
    }
    let masks = bits
        .iter()
        .fold(Masks::default(), |m, &(_, g, bit)| m.with(g, bit));
    let rate_divisor = BinaryOutput::divisor_for(ins.rate_hz)
        .ok_or_else(|| format!("ins.rate_hz {}: not 800 Hz / an integer", ins.rate_hz))?;
    Ok(BinaryOutput {
        async_mode: u16::from(ins.port),
        rate_divisor,
        masks,
    })
}

/// The port's side of a configuration: bytes both ways and the baud.
pub trait Port: Read + Write {
    /// Change the local baud.
    fn set_baud(&mut self, baud: u32) -> Result<(), crate::Error>;
}

impl Port for Box<dyn serialport::SerialPort> {
    fn set_baud(&mut self, baud: u32) -> Result<(), crate::Error> {
        self.set_baud_rate(baud).map_err(|e| e.to_string().into())
    }
}

impl Port for serialport::TTYPort {
    fn set_baud(&mut self, baud: u32) -> Result<(), crate::Error> {
        serialport::SerialPort::set_baud_rate(self, baud).map_err(|e| e.to_string().into())
    }
}

/// What a reply says.
enum Reply {
    /// The register's values as echoed.
    Register(String),
    /// `$VNWNV` acknowledged.
    Saved,
    /// `$VNERR`.
    Error(u8),
}

/// A session with the unit: the framer over everything it sends.
struct Session<'p, P: Port> {
    port: &'p mut P,
    dev: &'p str,
    framer: Box<Framer<4096>>,
    opts: Options,
    retries: u32,
}

impl<P: Port> Session<'_, P> {
    /// Send `cmd` (`what` in words) and wait for the reply to `name` (`VNWRG`, `VNWNV`) and
    /// register `id`, skipping the unit's other output.
    fn ask(
        &mut self,
        what: &str,
        cmd: &[u8],
        name: &str,
        id: Option<u8>,
    ) -> Result<Reply, crate::Error> {
        let mut last = String::from("no answer");
        for attempt in 0..self.opts.tries.max(1) {
            if attempt > 0 {
                self.retries += 1;
            }
            self.port
                .write_all(cmd)
                .and_then(|()| self.port.flush())
                .map_err(|e| format!("serial {}: writing {what}: {e}", self.dev))?;
            match self.reply(name, id)? {
                Some(Reply::Error(code)) if [2, 3, 4, 11, 255].contains(&code) => {
                    // The link garbled it: send again.
                    last = format!("$VNERR,{code:02X} ({})", command::error_name(code));
                }
                Some(r) => return Ok(r),
                None => last = "no answer".into(),
            }
        }
        Err(format!(
            "serial {}: {what}: {last} after {} tries{}",
            self.dev,
            self.opts.tries.max(1),
            if last == "no answer" {
                " (is the VN-200 powered and wired to this port, at this baud?)"
            } else {
                ""
            }
        )
        .into())
    }

    /// The reply to `name`/`id`, or `None` after the timeout.
    fn reply(&mut self, name: &str, id: Option<u8>) -> Result<Option<Reply>, crate::Error> {
        let end = Instant::now() + self.opts.timeout;
        let mut buf = [0u8; 512];
        while Instant::now() < end {
            let n = match self.port.read(&mut buf) {
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::Interrupted
                    ) =>
                {
                    0
                }
                Err(e) => return Err(format!("serial {}: {e}", self.dev).into()),
            };
            let mut data = &buf[..n];
            loop {
                let k = self.framer.push(data);
                data = &data[k..];
                while let Some(f) = self.framer.next() {
                    let Item::Ascii(s) = f.item else { continue };
                    match s.decode() {
                        Ok(Vn::Error(code)) => return Ok(Some(Reply::Error(code))),
                        Ok(Vn::Register {
                            write: true,
                            id: got,
                            values,
                        }) if name == "VNWRG" && Some(got) == id => {
                            return Ok(Some(Reply::Register(values.to_string())))
                        }
                        _ if name == "VNWNV" && s.name() == "VNWNV" => {
                            return Ok(Some(Reply::Saved))
                        }
                        _ => {}
                    }
                }
                if data.is_empty() {
                    break;
                }
            }
            if n == 0 {
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        Ok(None)
    }

    /// Write register `id` with `cmd` and check the echo with `same`.
    fn write(
        &mut self,
        what: &str,
        cmd: &[u8],
        id: u8,
        same: impl Fn(&str) -> bool,
    ) -> Result<String, crate::Error> {
        match self.ask(what, cmd, "VNWRG", Some(id))? {
            Reply::Register(v) if same(&v) => Ok(v),
            Reply::Register(v) => Err(format!(
                "serial {}: {what}: the VN-200 echoed {v:?}, not what was written",
                self.dev
            )
            .into()),
            Reply::Error(code) => Err(format!(
                "serial {}: {what}: the VN-200 refused it: $VNERR,{code:02X} ({})",
                self.dev,
                command::error_name(code)
            )
            .into()),
            Reply::Saved => Err(format!("serial {}: {what}: unexpected reply", self.dev).into()),
        }
    }
}

/// Configure the unit on `port` (`dev` names it in messages) for the board's `[ins]`.
pub fn configure<P: Port>(
    port: &mut P,
    dev: &str,
    ins: &InsLink,
    opts: Options,
) -> Result<Configured, crate::Error> {
    let want = binary_output(ins)?;
    let mut s = Session {
        port,
        dev,
        framer: Box::new(Framer::new()),
        opts,
        retries: 0,
    };
    let mut out = Configured::default();
    let mut cmd = [0u8; 128];
    let first = |v: &str| v.split(',').next().map(str::trim).map(str::to_string);
    // 1. Quiet the line: no ASCII async output.
    let n = command::write_async_output_type(&mut cmd, 0).map_err(|e| format!("{e:?}"))?;
    s.write("ASCII async output off (register 6)", &cmd[..n], 6, |v| {
        first(v).as_deref() == Some("0")
    })?;
    out.steps
        .push("ASCII async output off (register 6 = 0)".into());
    // 2. The baud, when the unit runs at another one.
    if let Some(cur) = opts.current_baud.filter(|&b| b != ins.baud) {
        let n = command::write_baud(&mut cmd, ins.baud).map_err(|e| format!("{e:?}"))?;
        let baud = ins.baud.to_string();
        s.write("the baud (register 5)", &cmd[..n], 5, |v| {
            first(v).as_deref() == Some(baud.as_str())
        })?;
        s.port.set_baud(ins.baud)?;
        out.steps.push(format!(
            "baud {cur} -> {} (register 5), this side followed",
            ins.baud
        ));
    }
    // 3. The binary output.
    let n = command::write_binary_output(&mut cmd, 75, &want).map_err(|e| format!("{e:?}"))?;
    s.write("the binary output (register 75)", &cmd[..n], 75, |v| {
        BinaryOutput::parse(v).is_ok_and(|b| b == want)
    })?;
    out.steps.push(format!(
        "binary output (register 75): {} at {} Hz on serial port {}",
        ins.fields.join(", "),
        want.rate_hz(),
        want.async_mode
    ));
    // 4. Saved, if asked.
    if opts.save {
        let n = command::write_settings(&mut cmd).map_err(|e| format!("{e:?}"))?;
        match s.ask("saving to flash ($VNWNV)", &cmd[..n], "VNWNV", None)? {
            Reply::Saved => out.steps.push("saved to flash ($VNWNV)".into()),
            Reply::Error(code) => {
                return Err(format!(
                    "serial {dev}: saving to flash: $VNERR,{code:02X} ({})",
                    command::error_name(code)
                )
                .into())
            }
            Reply::Register(_) => {}
        }
    }
    out.frames = first_frames(&mut s, &want)?;
    out.steps.push(format!(
        "first binary frames match the board: {} frames at {:.1} Hz",
        out.frames.1, out.frames.0
    ));
    out.retries = s.retries;
    Ok(out)
}

/// Watch the binary frames: they must carry exactly the board's fields, at its rate (within
/// 10 %). Returns the rate [Hz] and the frames counted.
fn first_frames<P: Port>(
    s: &mut Session<'_, P>,
    want: &BinaryOutput,
) -> Result<(f64, u32), crate::Error> {
    let end = Instant::now() + s.opts.frames_timeout;
    let mut buf = [0u8; 1024];
    let (mut n, mut t0, mut t1) = (0u32, None, None);
    let enough = (want.rate_hz() * 0.5).clamp(5.0, 200.0) as u32;
    while Instant::now() < end && n < enough {
        let k = s.port.read(&mut buf).unwrap_or(0);
        let mut data = &buf[..k];
        loop {
            let taken = s.framer.push(data);
            data = &data[taken..];
            while let Some(f) = s.framer.next() {
                let Item::Binary(fr) = f.item else { continue };
                if *fr.masks() != want.masks {
                    let names: Vec<&str> = fr
                        .masks()
                        .fields()
                        .filter_map(|(g, b)| g.field(b).map(|d| d.name))
                        .collect();
                    return Err(format!(
                        "serial {}: the VN-200 sends binary frames with {} after the configuration, not the board's fields (another binary output register is on?)",
                        s.dev,
                        names.join(", ")
                    ).into());
                }
                let now = Instant::now();
                t0.get_or_insert(now);
                t1 = Some(now);
                n += 1;
            }
            if data.is_empty() {
                break;
            }
        }
        if k == 0 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    if n < 2 {
        return Err(format!(
            "serial {}: no binary frame within {:.1} s of the configuration",
            s.dev,
            s.opts.frames_timeout.as_secs_f64()
        )
        .into());
    }
    let secs = t1
        .zip(t0)
        .map_or(0.0, |(b, a)| b.duration_since(a).as_secs_f64());
    let rate = f64::from(n - 1) / secs.max(1e-6);
    // A pseudo-terminal delivers in bursts: only a gross mismatch is an error.
    if n >= enough && (rate < 0.5 * want.rate_hz() || rate > 2.0 * want.rate_hz()) {
        return Err(format!(
            "serial {}: binary frames at {rate:.1} Hz, the board asks {} Hz",
            s.dev,
            want.rate_hz()
        )
        .into());
    }
    Ok((rate, n))
}

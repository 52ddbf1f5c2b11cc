//! The rig's status line, one a second on the console (a serial port or stdout).
//!
//! ```text
//! t=12s rx/s=754 al/s=754 drop=0/0/0 kdrop=0 pps=locked ins=tracking nopose=0 lag_ms=+1.4 win=S1:812,S2:790 cal=179.500,-44.900,1.200,1.500,-1.240,-1.360 sig=0.0003,0.0004,0.0002,0.0001,0.0001,0.0001
//! ```
//! Fields, space separated, `key=value`: `t` seconds since start; `rx/s` datagrams received on
//! the data port in the last second (any sender: a working LiDAR shows here even while the INS
//! is silent); `al/s` data packets aligned with the INS in the last second; `drop` ring drops so far, LiDAR/INS/raw log; `kdrop` datagrams the kernel
//! dropped (socket buffer full) so far; `pps` the position packets' PPS state;
//! `ins` the INS mode, or `silent:3.2s` (no usable pose and no bytes for that long) or
//! `unusable:3.2s` (bytes, but no usable pose: not tracking, no pose fields) after a second,
//! or `lost:3.2s` (the serial device went away: the reader is opening it again);
//! `nopose` the returns that got no pose so far; `lag_ms` LiDAR clock minus INS time, each
//! against the host receive
//! clock, at the last aligned packet [ms];
//! `win` returns per sphere window; `cal` the latest calibration (roll, pitch, heading [deg],
//! x, y, z [m]) or `-`; `sig` its 1-sigma in the same units or `-`; `dt_ms` the time offset
//! between the clocks and its 1-sigma [ms] or `-`; `verdict` `collecting` or `ready` after the
//! first solve (`-` before); `cov` per sphere `id:returns/passes/directions/min-max range [m]`
//! of the kept returns at the last solve; `solve` the solve under way (`r3`: its third round)
//! or how the last one's rounds ended (`settled:4`) or `-`. When the verdict's missing items change, a line
//! `verdict: collecting: ...` (or `verdict: ready`) says them in words.
//!
//! [`status_loop`] writes it once a second from a snapshot of the rig's shared counters.

use super::shared::{ins_name, pps_name, Shared};
use spherecal_hal::console::Console;
use std::fmt::Write as _;
use std::net::Ipv4Addr;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// What the status line shows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Status {
    /// Seconds since start.
    pub t_s: u64,
    /// Datagrams received on the data port in the last second (any sender).
    pub received_per_s: u64,
    /// Data packets aligned with the INS in the last second.
    pub aligned_per_s: u64,
    /// Ring drops: LiDAR, INS, raw log.
    pub drops: [u64; 3],
    /// Datagrams the kernel dropped.
    pub kernel_drops: u64,
    /// PPS state name.
    pub pps: String,
    /// INS mode name, or `silent:<s>s` / `unusable:<s>s` when no usable pose came for more
    /// than a second, `lost:<s>s` while the serial device is gone.
    pub ins: String,
    /// Returns that got no pose so far (before or after the INS's history, or in its gaps).
    pub without_pose: u64,
    /// LiDAR minus INS time [ms], if known.
    pub lag_ms: Option<f64>,
    /// (sphere id, returns in its window).
    pub windows: Vec<(String, u64)>,
    /// Latest calibration [deg, m] and its 1-sigma.
    pub calibration: Option<([f64; 6], [f64; 6])>,
    /// Latest time offset between the clocks and its 1-sigma [ms] (INS time = LiDAR time +
    /// this).
    pub time_offset_ms: Option<(f64, f64)>,
    /// `collecting` or `ready` after the first solve.
    pub verdict: Option<String>,
    /// Coverage per sphere ([`crate::verdict::status_field`]).
    pub coverage: Option<String>,
    /// The solve under way (`r3`: in its third round) or how the last one's rounds ended
    /// (`settled:4`, [`spherecal::calib::Termination::name`]); `None` before the first.
    pub solve: Option<String>,
}

impl Status {
    /// The line, without a newline.
    pub fn line(&self) -> String {
        let mut o = String::with_capacity(160);
        let _ = write!(
            o,
            "t={}s rx/s={} al/s={} drop={}/{}/{} kdrop={} pps={} ins={} nopose={}",
            self.t_s,
            self.received_per_s,
            self.aligned_per_s,
            self.drops[0],
            self.drops[1],
            self.drops[2],
            self.kernel_drops,
            self.pps,
            self.ins,
            self.without_pose
        );
        match self.lag_ms {
            Some(l) => {
                let _ = write!(o, " lag_ms={l:+.1}");
            }
            None => o.push_str(" lag_ms=-"),
        }
        o.push_str(" win=");
        if self.windows.is_empty() {
            o.push('-');
        }
        for (i, (id, n)) in self.windows.iter().enumerate() {
            let _ = write!(o, "{}{id}:{n}", if i > 0 { "," } else { "" });
        }
        match &self.calibration {
            Some((b, s)) => {
                let _ = write!(
                    o,
                    " cal={:.3},{:.3},{:.3},{:.3},{:.3},{:.3}",
                    b[0], b[1], b[2], b[3], b[4], b[5]
                );
                let _ = write!(
                    o,
                    " sig={:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
                    s[0], s[1], s[2], s[3], s[4], s[5]
                );
            }
            None => o.push_str(" cal=- sig=-"),
        }
        match self.time_offset_ms {
            Some((d, s)) => {
                let _ = write!(o, " dt_ms={d:+.3},{s:.3}");
            }
            None => o.push_str(" dt_ms=-"),
        }
        let _ = write!(
            o,
            " verdict={} cov={}",
            self.verdict.as_deref().unwrap_or("-"),
            self.coverage
                .as_deref()
                .filter(|c| !c.is_empty())
                .unwrap_or("-")
        );
        let _ = write!(o, " solve={}", self.solve.as_deref().unwrap_or("-"));
        o
    }

    /// Parse a line back (for tests and for tools that watch the console).
    pub fn parse(line: &str) -> Option<Self> {
        let mut s = Status::default();
        for kv in line.split_whitespace() {
            let (k, v) = kv.split_once('=')?;
            match k {
                "t" => s.t_s = v.strip_suffix('s')?.parse().ok()?,
                "rx/s" => s.received_per_s = v.parse().ok()?,
                "al/s" => s.aligned_per_s = v.parse().ok()?,
                "drop" => {
                    let d: Vec<u64> = v
                        .split('/')
                        .map(|x| x.parse().ok())
                        .collect::<Option<_>>()?;
                    s.drops = d.try_into().ok()?;
                }
                "kdrop" => s.kernel_drops = v.parse().ok()?,
                "pps" => s.pps = v.to_string(),
                "ins" => s.ins = v.to_string(),
                "nopose" => s.without_pose = v.parse().ok()?,
                "lag_ms" => {
                    s.lag_ms = if v == "-" {
                        None
                    } else {
                        Some(v.parse().ok()?)
                    }
                }
                "win" if v != "-" => {
                    for w in v.split(',') {
                        let (id, n) = w.split_once(':')?;
                        s.windows.push((id.to_string(), n.parse().ok()?));
                    }
                }
                "win" => {}
                "dt_ms" if v == "-" => {}
                "dt_ms" => {
                    let (d, sg) = v.split_once(',')?;
                    s.time_offset_ms = Some((d.parse().ok()?, sg.parse().ok()?));
                }
                "verdict" => s.verdict = (v != "-").then(|| v.to_string()),
                "cov" => s.coverage = (v != "-").then(|| v.to_string()),
                "solve" => s.solve = (v != "-").then(|| v.to_string()),
                "cal" | "sig" if v == "-" => {}
                "cal" | "sig" => {
                    let vals: Vec<f64> = v
                        .split(',')
                        .map(|x| x.parse().ok())
                        .collect::<Option<_>>()?;
                    let a: [f64; 6] = vals.try_into().ok()?;
                    let c = s.calibration.get_or_insert(([0.0; 6], [0.0; 6]));
                    if k == "cal" {
                        c.0 = a;
                    } else {
                        c.1 = a;
                    }
                }
                _ => return None,
            }
        }
        Some(s)
    }
}

/// The status line from the shared counters; `last` holds the received and aligned counts at
/// the previous line.
pub(super) fn snapshot(
    sh: &Shared<'_>,
    ids: &[String],
    started: Instant,
    last: &mut [u64; 2],
) -> Status {
    let aligned = sh.aligner.aligned.load(Ordering::Relaxed);
    let received = sh.readers.received[0].load(Ordering::Relaxed);
    let lag = sh.aligner.lag_ns.load(Ordering::Relaxed);
    let (verdict, coverage) = sh
        .solver
        .verdict
        .lock()
        .ok()
        .and_then(|v| v.clone())
        .map(|v| {
            (
                Some(if v.ready { "ready" } else { "collecting" }.to_string()),
                Some(crate::verdict::status_field(&v.coverage)),
            )
        })
        .unwrap_or_default();
    let s = Status {
        t_s: started.elapsed().as_secs(),
        received_per_s: received.saturating_sub(last[0]),
        aligned_per_s: aligned.saturating_sub(last[1]),
        drops: [
            sh.ring_drops.data.load(Ordering::Relaxed)
                + sh.ring_drops.position.load(Ordering::Relaxed),
            sh.ring_drops.ins.load(Ordering::Relaxed),
            sh.ring_drops.datagram_log.load(Ordering::Relaxed)
                + sh.ring_drops.serial_log.load(Ordering::Relaxed),
        ],
        kernel_drops: sh.readers.kernel_drops[0].load(Ordering::Relaxed)
            + sh.readers.kernel_drops[1].load(Ordering::Relaxed),
        pps: pps_name(sh.aligner.pps.load(Ordering::Relaxed)).into(),
        ins: match sh.readers.ins_watch.speaking() {
            super::ins_watch::Speaking::Yes => {
                ins_name(sh.readers.ins_mode.load(Ordering::Relaxed)).into()
            }
            super::ins_watch::Speaking::Silent(s) => format!("silent:{s:.1}s"),
            super::ins_watch::Speaking::Unusable(s) => format!("unusable:{s:.1}s"),
            super::ins_watch::Speaking::Lost(s) => format!("lost:{s:.1}s"),
        },
        without_pose: sh.aligner.without_pose.load(Ordering::Relaxed),
        lag_ms: (lag != i64::MIN).then_some(lag as f64 * 1e-6),
        windows: ids
            .iter()
            .zip(&sh.aligner.windowed)
            .map(|(id, n)| (id.clone(), n.load(Ordering::Relaxed)))
            .collect(),
        calibration: sh.solver.calibration.lock().ok().and_then(|c| *c),
        time_offset_ms: sh
            .solver
            .time_offset
            .lock()
            .ok()
            .and_then(|c| *c)
            .map(|(d, s)| (d * 1e3, s * 1e3)),
        verdict,
        coverage,
        solve: sh
            .solver
            .solve_state
            .lock()
            .ok()
            .map(|s| s.clone())
            .filter(|s| !s.is_empty()),
    };
    *last = [received, aligned];
    s
}

/// Seconds after the first datagram (on either port; after the start if none comes) when the
/// rig says what each port hears.
pub const HEAR_S: u64 = 3;
/// A port still silent is named again this often [s].
pub const SILENT_AGAIN_S: u64 = 30;

/// What the ports heard, on the console: at [`HEAR_S`], then for a port that was silent, when
/// it starts to hear (or every [`SILENT_AGAIN_S`] while it does not). `(bind, sensor)`: the
/// board's addresses.
struct Hearing {
    bind: Ipv4Addr,
    sensor: Option<Ipv4Addr>,
    /// Per port: was silent at its last report (None: not reported yet).
    silent: [Option<bool>; 2],
    /// When the first datagram arrived (either port) [s since the start].
    first: Option<u64>,
}

impl Hearing {
    fn lines(&mut self, sh: &Shared<'_>, t: u64) -> Vec<String> {
        let mut out = Vec::new();
        if self.first.is_none()
            && sh
                .readers
                .received
                .iter()
                .any(|r| r.load(Ordering::Relaxed) > 0)
        {
            self.first = Some(t);
        }
        // A few seconds of what arrives (or of silence).
        let due_at = self.first.unwrap_or(0) + HEAR_S;
        if t < due_at {
            return out;
        }
        for (k, what) in ["data", "position"].into_iter().enumerate() {
            let Ok(h) = sh.readers.heard[k].lock().map(|h| h.clone()) else {
                continue;
            };
            let due = match self.silent[k] {
                None => true,
                Some(true) => h.datagrams > 0 || (t - due_at).is_multiple_of(SILENT_AGAIN_S),
                Some(false) => false,
            };
            if !due {
                continue;
            }
            // An Ouster sends nothing to the position port (its IMU packets, if it is 7503).
            let ouster = k == 1
                && sh.readers.heard[0]
                    .lock()
                    .is_ok_and(|d| d.ouster_format.is_some());
            if ouster && h.datagrams == 0 {
                continue;
            }
            self.silent[k] = Some(h.datagrams == 0);
            let secs = (t - self.first.unwrap_or(0).min(t)) as f64;
            let data_heard = sh.readers.received[0].load(Ordering::Relaxed) > 0;
            let (text, warnings) = h.describe(what, self.sensor, secs, data_heard);
            out.push(format!("heard: {text}"));
            out.extend(warnings.into_iter().map(|w| format!("WARNING: {w}")));
            // Loopback is a replay or simulator on this computer: no broadcast to miss.
            if h.datagrams == 0 && !self.bind.is_unspecified() && !self.bind.is_loopback() {
                out.push(format!(
                    "WARNING: lidar.bind_addr is {}: datagrams broadcast to 255.255.255.255 (a factory VLP-16's destination) are not delivered to a socket bound to one address; bind 0.0.0.0 (the default)",
                    self.bind
                ));
            }
        }
        out
    }
}

/// One status line a second until the stop; sets the stop when the duration has passed.
/// Hands the console back for the last line.
pub(super) fn status_loop<'c>(
    console: &'c mut Console,
    ids: &[String],
    duration: Option<Duration>,
    started: Instant,
    sh: &Shared<'_>,
    (bind, sensor): (Ipv4Addr, Option<Ipv4Addr>),
) -> &'c mut Console {
    let mut last = [0u64; 2];
    let mut said_verdict: Option<Vec<String>> = None;
    let mut said_margin: Option<f64> = None;
    let mut hearing = Hearing {
        bind,
        sensor,
        silent: [None; 2],
        first: None,
    };
    let mut tick = 1u64;
    let mut silence = super::ins_watch::SilenceTalk::default();
    let over = || duration.is_some_and(|d| started.elapsed() >= d);
    loop {
        let next = started + Duration::from_secs(tick);
        while Instant::now() < next && !sh.stop.load(Ordering::Relaxed) && !over() {
            std::thread::sleep(
                Duration::from_millis(20).min(next.saturating_duration_since(Instant::now())),
            );
        }
        if over() {
            sh.stop.store(true, Ordering::Relaxed);
        }
        if sh.stop.load(Ordering::Relaxed) {
            silence.close(&sh.readers.ins_watch);
            // The caller shows the last line once everything has stopped.
            return console;
        }
        tick += 1;
        sh.readers.poll_kernel_drops();
        let s = snapshot(sh, ids, started, &mut last);
        let mut said = hearing.lines(sh, s.t_s);
        said.extend(sh.readers.ins_watch.take_said());
        // The INS: silent or unusable for a second is said, and again while it lasts (not
        // before the ports have had the time to be heard).
        let now = sh.readers.ins_watch.speaking();
        if s.t_s > HEAR_S {
            if let Some(l) = silence.tick(
                &sh.readers.ins_watch,
                now,
                sh.aligner.without_pose.load(Ordering::Relaxed),
            ) {
                said.push(l);
            }
        }
        for l in said {
            if l.starts_with("WARNING") {
                sh.said.warn(format!("t={}s {l}", s.t_s));
            }
            if let Err(e) = console.write_line(&l) {
                sh.said.error(format!("console: {e}"));
            }
        }
        // The windows moved around the calibration: said when their margin changes.
        if let Some((_, m)) = sh.solver.steer.get().windows {
            if said_margin.is_none_or(|s| (s - m).abs() > 0.05) {
                let line = format!(
                    "windows: around the calibration now, {m:.2} m beyond the spheres (less clutter in them)"
                );
                if let Err(e) = console.write_line(&line) {
                    sh.said.error(format!("console: {e}"));
                }
                said_margin = Some(m);
            }
        }
        // The verdict in words, when what is missing changes.
        if let Some(v) = sh.solver.verdict.lock().ok().and_then(|v| v.clone()) {
            if said_verdict.as_ref() != Some(&v.missing) {
                let line = if v.ready {
                    format!("verdict: ready: {}", v.ready_because)
                } else {
                    format!("verdict: collecting: {}", v.missing.join("; "))
                };
                if let Err(e) = console.write_line(&line) {
                    sh.said.error(format!("console: {e}"));
                }
                said_verdict = Some(v.missing);
            }
        }
        if let Err(e) = show(console, &s) {
            sh.said.error(format!("console: {e}"));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_format_and_round_trip() {
        let s = Status {
            t_s: 12,
            received_per_s: 760,
            aligned_per_s: 754,
            drops: [0, 3, 1],
            kernel_drops: 7,
            pps: "locked".into(),
            ins: "tracking".into(),
            without_pose: 0,
            lag_ms: Some(1.4),
            windows: vec![("S1".into(), 812), ("S2".into(), 790)],
            calibration: Some((
                [179.5, -44.9, 1.2, 1.5, -1.24, -1.36],
                [0.0003, 0.0004, 0.0002, 0.0001, 0.0001, 0.0001],
            )),
            time_offset_ms: Some((100.125, 0.004)),
            verdict: Some("collecting".into()),
            coverage: Some("S1:1185/3/2/9-30,S2:1271/2/1/9-21".into()),
            solve: Some("settled:4".into()),
        };
        assert_eq!(
            s.line(),
            "t=12s rx/s=760 al/s=754 drop=0/3/1 kdrop=7 pps=locked ins=tracking nopose=0 lag_ms=+1.4 win=S1:812,S2:790 cal=179.500,-44.900,1.200,1.500,-1.240,-1.360 sig=0.0003,0.0004,0.0002,0.0001,0.0001,0.0001 dt_ms=+100.125,0.004 verdict=collecting cov=S1:1185/3/2/9-30,S2:1271/2/1/9-21 solve=settled:4"
        );
        assert_eq!(Status::parse(&s.line()), Some(s));
        let empty = Status {
            pps: "none".into(),
            ins: "aligning".into(),
            ..Status::default()
        };
        assert_eq!(
            empty.line(),
            "t=0s rx/s=0 al/s=0 drop=0/0/0 kdrop=0 pps=none ins=aligning nopose=0 lag_ms=- win=- cal=- sig=- dt_ms=- verdict=- cov=- solve=-"
        );
        assert_eq!(Status::parse(&empty.line()), Some(empty));
        assert_eq!(Status::parse("t=1s bogus=3"), None);
        assert_eq!(Status::parse("t=1s drop=1/2"), None);
    }
}

/// Show a status line on a console (the hal's sink: a serial port or stdout).
pub fn show(console: &mut Console, s: &Status) -> std::io::Result<()> {
    console.write_line(&s.line())
}

#[cfg(test)]
mod console_tests {
    use super::*;
    use serialport::{SerialPort, TTYPort};
    use std::io::Read;

    /// Status lines written to one end of a pseudo-terminal pair arrive whole at the other.
    #[test]
    fn console_on_a_pseudo_terminal() {
        let (mut master, slave) = TTYPort::pair().expect("a pseudo-terminal pair");
        master
            .set_timeout(std::time::Duration::from_millis(200))
            .unwrap();
        let mut console = Console::new(Box::new(slave));
        let lines: Vec<Status> = (0..5)
            .map(|i| Status {
                t_s: i,
                received_per_s: 754,
                aligned_per_s: 754,
                pps: "locked".into(),
                ins: "tracking".into(),
                ..Status::default()
            })
            .collect();
        for s in &lines {
            show(&mut console, s).unwrap();
        }
        assert_eq!(console.lines, 5);
        let mut got = Vec::new();
        let mut buf = [0u8; 512];
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        while got.iter().filter(|&&c| c == b'\n').count() < 5
            && std::time::Instant::now() < deadline
        {
            if let Ok(n) = master.read(&mut buf) {
                got.extend_from_slice(&buf[..n]);
            }
        }
        let text = String::from_utf8(got).unwrap();
        let back: Vec<Status> = text
            .split("\r\n")
            .filter(|l| !l.is_empty())
            .map(|l| Status::parse(l).unwrap())
            .collect();
        assert_eq!(back, lines);
    }
}

//! `spherecal replay`: recorded files back through the rig's own inputs, both streams on one
//! [`Pacer`]: the capture's UDP datagrams to their ports on a host (loopback in tests) at
//! their record times, the serial bytes to a device at a serial log's receive times (raw
//! bytes: at the baud rate's pace), the recorded spacing scaled by the speed.

use crate::pipeline::Files;
use spherecal_hal::clock::{Clock, HostTime, SystemClock};
use spherecal_hal::{PacketSource, Record};
use std::io::Write;
use std::net::{Ipv4Addr, SocketAddrV4, UdpSocket};
use std::path::Path;
use std::time::Duration;

mod bag;
pub use bag::{replay_bag, BagReplay};

/// How fast.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speed {
    /// As fast as the socket or device takes it.
    Max,
    /// The recorded pacing divided by this factor (1 = real time).
    Factor(f64),
}

impl std::str::FromStr for Speed {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "max" {
            return Ok(Speed::Max);
        }
        match s.parse::<f64>() {
            Ok(x) if x > 0.0 && x.is_finite() => Ok(Speed::Factor(x)),
            _ => Err(format!("{s:?}: expected a positive factor or max")),
        }
    }
}

/// The replay's pacing: a recording time (host wall clock, ns since 1970) is due at
/// `start + (t - t0) / speed` on a [`Clock`]'s monotonic time, so that several streams replayed
/// on threads keep their recorded order and spacing.
#[derive(Clone, Copy)]
pub struct Pacer<'c> {
    /// The clock waited on.
    pub clock: &'c dyn Clock,
    /// Its monotonic time when the replay started [ns].
    pub start_ns: u64,
    /// The recording time that is due at `start`.
    pub t0: HostTime,
    /// How fast.
    pub speed: Speed,
}

impl<'c> Pacer<'c> {
    /// Pacing from now on `clock`, at recording time `t0`.
    pub fn new(clock: &'c dyn Clock, t0: HostTime, speed: Speed) -> Self {
        Self {
            clock,
            start_ns: clock.mono_ns(),
            t0,
            speed,
        }
    }

    /// Time since the start.
    pub fn elapsed(&self) -> Duration {
        Duration::from_nanos(self.clock.mono_ns().saturating_sub(self.start_ns))
    }

    /// Wait until `due` after the start (at once if it has passed).
    pub fn wait_until(&self, due: Duration) {
        let now = self.elapsed();
        if due > now {
            self.clock.sleep(due - now);
        }
    }

    /// Wait until recording time `t` is due (at once for `max` or a time before `t0`).
    pub fn wait_for(&self, t: HostTime) {
        if let Speed::Factor(f) = self.speed {
            self.wait_until(Duration::from_secs_f64(
                (t.since(self.t0).max(0) as f64 * 1e-9) / f,
            ));
        }
    }
}

/// Where datagrams go: a host, and the capture's data/position ports (and a POS MV's
/// Real-Time Data Port) mapped to others.
#[derive(Debug, Clone, Copy)]
pub struct Target {
    /// Host.
    pub host: Ipv4Addr,
    /// (capture port, port to send to) for data and position packets, and POS MV groups.
    pub ports: [(u16, u16); 3],
}

impl Target {
    /// Each datagram to its own port on `host`.
    pub fn host(host: Ipv4Addr) -> Self {
        Self {
            host,
            ports: [(2368, 2368), (8308, 8308), (5602, 5602)],
        }
    }

    fn port(&self, p: u16) -> u16 {
        self.ports.iter().find(|m| m.0 == p).map_or(p, |m| m.1)
    }
}

/// The first record time of a capture and of a serial log (host wall clock), for a [`Pacer`].
pub fn first_times(
    pcap: impl Into<Files>,
    ins: Option<&Files>,
) -> Result<(Option<HostTime>, Option<HostTime>), crate::Error> {
    let mut src = crate::pipeline::open_captures(&pcap.into(), None, None)?;
    let mut first_udp = None;
    while let Some(rec) = src.next_record().map_err(|e| e.to_string())? {
        if let Record::Udp(d) = rec {
            first_udp = Some(d.time);
            break;
        }
    }
    let first_log = match ins {
        Some(p) => first_log_time(&p.expand()?[0])?,
        None => None,
    };
    Ok((first_udp, first_log))
}

/// What a UDP replay sent.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UdpReplay {
    /// Datagrams sent.
    pub sent: u64,
    /// Records skipped (not UDP/IPv4).
    pub skipped: u64,
}

/// Send every UDP datagram of a capture to `host` at its destination port, paced from its
/// first record.
pub fn replay_udp(
    pcap: impl Into<Files>,
    host: Ipv4Addr,
    speed: Speed,
) -> Result<UdpReplay, crate::Error> {
    let pcap = pcap.into();
    let (first, _) = first_times(&pcap, None)?;
    replay_udp_on(
        pcap,
        Target::host(host),
        &Pacer::new(&SystemClock, first.unwrap_or_default(), speed),
    )
}

/// Send every UDP datagram of a capture to `to`, each when `clock` says its record time is due.
pub fn replay_udp_on(
    pcap: impl Into<Files>,
    to: Target,
    clock: &Pacer<'_>,
) -> Result<UdpReplay, crate::Error> {
    send_all(
        crate::pipeline::open_captures(&pcap.into(), None, None)?,
        to,
        clock,
    )
}

/// Every datagram of `src` to `to`, each when `clock` says its time is due.
fn send_all<S: PacketSource>(
    mut src: S,
    to: Target,
    clock: &Pacer<'_>,
) -> Result<UdpReplay, crate::Error> {
    let sock =
        UdpSocket::bind((Ipv4Addr::UNSPECIFIED, 0)).map_err(|e| format!("UDP socket: {e}"))?;
    let host = to.host;
    let mut out = UdpReplay::default();
    while let Some(rec) = src.next_record().map_err(|e| e.to_string())? {
        let d = match rec {
            Record::Udp(d) => d,
            Record::Idle => continue,
            Record::Skipped { .. } => {
                out.skipped += 1;
                continue;
            }
        };
        clock.wait_for(d.time);
        let port = to.port(d.dst_port);
        sock.send_to(d.payload, SocketAddrV4::new(host, port))
            .map_err(|e| format!("send to {host}:{port}: {e}"))?;
        out.sent += 1;
    }
    Ok(out)
}

/// Write a VN-200 byte file (raw or serial log) to `out`: a log at its recorded timing, raw
/// bytes at `baud`'s pace (10 bits a byte), both scaled by `speed`.
pub fn replay_serial(
    file: &Path,
    out: &mut impl Write,
    baud: u32,
    speed: Speed,
) -> Result<u64, crate::Error> {
    let first = first_log_time(file)?;
    replay_serial_on(
        Files::from(file),
        out,
        baud,
        &Pacer::new(&SystemClock, first.unwrap_or_default(), speed),
    )
}

/// The first receive time of a serial log (None for raw bytes, which have no times).
fn first_log_time(file: &Path) -> Result<Option<HostTime>, crate::Error> {
    let f = std::fs::File::open(file).map_err(|e| format!("{}: {e}", file.display()))?;
    match spherecal_hal::serial::LogReader::new(std::io::BufReader::new(f)) {
        Ok(mut r) => Ok(r
            .next_record(&mut Vec::new())
            .map_err(|e| format!("{}: {e}", file.display()))?
            .map(|s| s.wall)),
        Err(_) => Ok(None),
    }
}

/// Write VN-200 byte files (one, or a rig's rotated logs in name order, one at a time in
/// memory) to `out`: a serial log's reads each when `clock` says their receive time is due; raw
/// bytes at `baud`'s pace (10 bits a byte) from the clock's start, scaled by its speed.
pub fn replay_serial_on(
    files: impl Into<Files>,
    out: &mut impl Write,
    baud: u32,
    clock: &Pacer<'_>,
) -> Result<u64, crate::Error> {
    let mut written = 0u64;
    for f in files.into().expand()? {
        written += replay_one_serial(&f, out, baud, clock, written)?;
    }
    Ok(written)
}

/// One file of [`replay_serial_on`]; `before`: bytes already written (raw bytes keep the
/// baud rate's pace across files).
fn replay_one_serial(
    file: &Path,
    out: &mut impl Write,
    baud: u32,
    clock: &Pacer<'_>,
    before: u64,
) -> Result<u64, crate::Error> {
    let (bytes, stamps) = spherecal_hal::serial::read_byte_file(file)
        .map_err(|e| format!("{}: {e}", file.display()))?;
    let write =
        |out: &mut dyn Write, b: &[u8]| out.write_all(b).map_err(|e| format!("serial write: {e}"));
    let mut written = 0u64;
    match stamps {
        Some(st) => {
            for (i, (at, stamp)) in st.iter().enumerate() {
                let end = st.get(i + 1).map_or(bytes.len(), |n| n.0 as usize);
                clock.wait_for(stamp.wall);
                write(out, &bytes[*at as usize..end])?;
                written += (end - *at as usize) as u64;
            }
        }
        None => {
            let rate = match clock.speed {
                Speed::Max => None,
                Speed::Factor(f) => Some(f64::from(baud.max(1)) * f / 10.0),
            };
            for c in bytes.chunks(64) {
                if let Some(r) = rate {
                    clock.wait_until(Duration::from_secs_f64((before + written) as f64 / r));
                }
                write(out, c)?;
                written += c.len() as u64;
            }
        }
    }
    out.flush().map_err(|e| format!("serial write: {e}"))?;
    Ok(written)
}

/// Replay captures and (optionally) VN-200 files together on one clock: the datagrams to
/// `to`, the serial bytes to `serial`. Their recorded times keep their order and spacing.
pub fn replay_both(
    pcap: impl Into<Files>,
    to: Target,
    ins: Option<(&Files, &mut (dyn Write + Send), u32)>,
    speed: Speed,
) -> Result<(UdpReplay, Option<u64>), crate::Error> {
    let pcap = pcap.into();
    let (fu, fl) = first_times(&pcap, ins.as_ref().map(|i| i.0))?;
    let t0 = match (fu, fl) {
        (Some(a), Some(b)) => a.min(b),
        (a, b) => a.or(b).unwrap_or_default(),
    };
    let clock = Pacer::new(&SystemClock, t0, speed);
    std::thread::scope(|sc| {
        let serial = ins.map(|(file, out, baud)| {
            sc.spawn(move || {
                let mut out = out;
                replay_serial_on(file, &mut out, baud, &clock)
            })
        });
        let udp = replay_udp_on(&pcap, to, &clock);
        let ser = joined(serial);
        Ok((udp?, ser?))
    })
}

/// The bytes a replay's serial thread wrote, once it ends (None: there was none).
fn joined(
    serial: Option<std::thread::ScopedJoinHandle<'_, Result<u64, crate::Error>>>,
) -> Result<Option<u64>, crate::Error> {
    serial
        .map(|h| {
            h.join().unwrap_or_else(|_| {
                Err(crate::Error::internal(
                    "the replay's serial thread panicked",
                ))
            })
        })
        .transpose()
}

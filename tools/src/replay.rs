//! `spherecal replay`: recorded files back through the rig's own inputs: the capture's UDP
//! datagrams to their ports on a host (loopback in tests) with their original pacing scaled,
//! the serial bytes to a device at the baud rate's pace or the log's own timing.

use spherecal_hal::pcap::PcapSource;
use spherecal_hal::serial::{replay, Pace, RxStamp};
use spherecal_hal::{PacketSource, Record};
use std::io::Write;
use std::net::{Ipv4Addr, SocketAddrV4, UdpSocket};
use std::path::Path;
use std::time::{Duration, Instant};

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

/// What a UDP replay sent.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UdpReplay {
    /// Datagrams sent.
    pub sent: u64,
    /// Records skipped (not UDP/IPv4).
    pub skipped: u64,
}

/// Send every UDP datagram of a capture to `host` at its destination port.
pub fn replay_udp(pcap: &Path, host: Ipv4Addr, speed: Speed) -> Result<UdpReplay, String> {
    let mut src = PcapSource::open(pcap).map_err(|e| format!("{}: {e}", pcap.display()))?;
    let sock =
        UdpSocket::bind((Ipv4Addr::UNSPECIFIED, 0)).map_err(|e| format!("UDP socket: {e}"))?;
    let start = Instant::now();
    let mut first: Option<i128> = None;
    let mut out = UdpReplay::default();
    while let Some(rec) = src
        .next_record()
        .map_err(|e| format!("{}: {e}", pcap.display()))?
    {
        let d = match rec {
            Record::Udp(d) => d,
            Record::Skipped { .. } => {
                out.skipped += 1;
                continue;
            }
        };
        if let Speed::Factor(f) = speed {
            let t0 = *first.get_or_insert(d.time.0);
            let due = Duration::from_secs_f64(((d.time.0 - t0).max(0) as f64 * 1e-9) / f);
            let now = start.elapsed();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        sock.send_to(d.payload, SocketAddrV4::new(host, d.dst_port))
            .map_err(|e| format!("send to {host}:{}: {e}", d.dst_port))?;
        out.sent += 1;
    }
    Ok(out)
}

/// Bytes and when they were received.
type Chunk<'a> = (&'a [u8], Option<RxStamp>);

/// Write a VN-200 byte file (raw or serial log) to `out`: a log at its recorded timing, raw
/// bytes at `baud`'s pace (10 bits a byte), both scaled by `speed`.
pub fn replay_serial(
    file: &Path,
    out: &mut impl Write,
    baud: u32,
    speed: Speed,
) -> Result<u64, String> {
    let (bytes, stamps) = spherecal_hal::serial::read_byte_file(file)
        .map_err(|e| format!("{}: {e}", file.display()))?;
    let (chunks, pace): (Vec<Chunk<'_>>, Pace) = match (&stamps, speed) {
        (Some(st), s) => {
            let mut v = Vec::with_capacity(st.len());
            for (i, (at, stamp)) in st.iter().enumerate() {
                let end = st.get(i + 1).map_or(bytes.len(), |n| n.0 as usize);
                v.push((&bytes[*at as usize..end], Some(*stamp)));
            }
            (
                v,
                match s {
                    Speed::Max => Pace::Max,
                    Speed::Factor(f) => Pace::Recorded(f),
                },
            )
        }
        (None, s) => (
            bytes.chunks(64).map(|c| (c, None)).collect(),
            match s {
                Speed::Max => Pace::Max,
                Speed::Factor(f) => Pace::Baud((f64::from(baud) * f) as u32),
            },
        ),
    };
    replay(out, &chunks, pace).map_err(|e| format!("serial write: {e}"))
}

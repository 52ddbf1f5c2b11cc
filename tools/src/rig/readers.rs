//! The rig's readers: one per socket and the serial port, each into its rings (never blocking: a full ring drops and counts).

use super::shared::{ReaderGuard, ReaderHandle};
use super::{SerialChunk, UdpLogItem, MAX_INS_GAP_NS, SERIAL_CHUNK};
use crate::ouster::Metadata;
use crate::pipeline::{
    end_lidar, enqueue, ins_reader, lidar_reader, ouster_reader, Accept, InsEnd, InsItem,
    InsOutcome, InsRing, LidarItem, LidarRing, Overflow, Vn200Feed,
};
use crate::state::InsState;
use heapless::spsc::Producer;
use spherecal::frames::LocalFrame;
use spherecal::vn200::binary::Masks;
use spherecal::vn200::fields::Group;
use spherecal::vn200::Item;
use spherecal_hal::packet::Datagram;
use spherecal_hal::serial::{RxStamp, SerialSource};
use spherecal_hal::udp::UdpSource;
use spherecal_hal::velodyne::SkipStats;
use spherecal_hal::Tap;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// The LiDAR's two ports, each with its socket, reader and counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum LidarPort {
    /// The data port (2368 by default).
    Data = 0,
    /// The position port (8308 by default).
    Position = 1,
}

impl LidarPort {
    /// Its index in the per-port counters (`received`, `enqueued`, `heard`, ...).
    pub(super) fn index(self) -> usize {
        self as usize
    }
}

/// What a LiDAR socket's reader does with what it receives.
#[derive(Clone, Copy)]
pub(super) struct PortPlan<'m> {
    /// The sensor's ports and address.
    pub(super) accept: Accept,
    /// Which of the two sockets.
    pub(super) port: LidarPort,
    /// An Ouster's data socket: its metadata and the site's leap seconds (its lidar packets
    /// are decoded here, as from a file: [`ouster_reader`]).
    pub(super) ouster: Option<(&'m Metadata, i64)>,
    /// Its end ends the survey (the data socket).
    pub(super) ends_stream: bool,
}

/// One socket until the stop, through the same reader as a capture file ([`lidar_reader`], or
/// [`ouster_reader`] for an Ouster): every datagram to the log ring (a [`Tap`] on the socket;
/// one longer than an Ethernet frame holds as its IPv4 fragments), the sensor's packets to
/// the aligner's ring. Returns the skips and how many datagrams had kernel receive times.
pub(super) fn udp_reader(
    sock: UdpSource,
    mut ring: Producer<'_, LidarItem>,
    mut log: Producer<'_, UdpLogItem>,
    plan: PortPlan<'_>,
    sh: ReaderHandle<'_>,
) -> (SkipStats, u64) {
    let _alive = ReaderGuard(sh.readers);
    let port = sock.port();
    let (accept, port_of) = (plan.accept, plan.port);
    let mut ip_id = 0u16;
    let log_datagram = |d: &Datagram<'_>| {
        sh.readers.received[port_of.index()].fetch_add(1, Ordering::Relaxed);
        if let Ok(mut h) = sh.readers.heard[port_of.index()].lock() {
            h.see(d, accept.ports);
        }
        log_pieces(&mut log, d, &mut ip_id, sh);
    };
    let mut src = Tap::new(sock, log_datagram);
    let mut out = LidarRing {
        ring: &mut ring,
        policy: Overflow::Drop,
        full: sh.ring_drops.lidar(port_of),
        queued: &sh.readers.enqueued[port_of.index()],
    };
    let (skips, r) = match plan.ouster {
        Some((meta, leap)) => {
            let how = (false, accept.sensor);
            ouster_reader(&mut src, &mut out, meta, leap, how, sh.stop)
        }
        None => lidar_reader(&mut src, &mut out, accept, sh.stop),
    };
    let ends_stream = plan.ends_stream;
    if let Err(e) = r {
        sh.said.error(format!("UDP port {port}: {e}"));
        if ends_stream {
            // Without the data socket there is no survey: wind everything down.
            sh.stop.store(true, Ordering::Relaxed);
        }
    }
    sh.readers.poll_kernel_drops();
    if ends_stream {
        // The aligner runs until it sees this (unless it is gone).
        end_lidar(&mut ring, &sh.aligner.gone);
    }
    (skips, src.get_ref().kernel_stamped)
}

/// `d` onto the log ring, whole or as its fragments (identification `id`, then the next).
fn log_pieces(
    log: &mut Producer<'_, UdpLogItem>,
    d: &Datagram<'_>,
    id: &mut u16,
    sh: ReaderHandle<'_>,
) {
    for item in UdpLogItem::pieces(d, *id) {
        enqueue(log, item, Overflow::Drop, &sh.ring_drops.datagram_log);
    }
    *id = id.wrapping_add(1);
}

/// Say once per frame layout if the VN-200 does not send the outputs the board
/// expects (its register 75 configuration differs from `ins.fields`).
pub(super) fn check_outputs(
    m: &Masks,
    offset: u64,
    last: &mut Option<Masks>,
    expected: &[(String, Group, u8)],
    dev: &str,
    sh: ReaderHandle<'_>,
) {
    if *last == Some(*m) {
        return;
    }
    *last = Some(*m);
    let missing: Vec<&str> = expected
        .iter()
        .filter(|(_, g, bit)| !m.has(*g, *bit))
        .map(|(name, _, _)| name.as_str())
        .collect();
    if !missing.is_empty() {
        sh.said.error(format!(
            "serial {dev}: the VN-200 frame at byte {offset} lacks the outputs {} that the board expects (ins.fields)",
            missing.join(", ")
        ));
    }
}

/// Waits between attempts to open a serial device that went away: from the first to the last,
/// doubling [ms].
const REOPEN_MS: (u64, u64) = (250, 2_000);

/// The VN-200's serial port until the stop: every read to the log ring, framed into poses onto
/// the INS ring. A device that goes away (a USB adapter unplugged or re-enumerating: a read
/// error, or the end of its stream) is said on the console, and opened again by its path with
/// a back-off ([`REOPEN_MS`]) until it is back or the run stops.
#[allow(clippy::too_many_arguments)]
pub(super) fn serial_reader(
    dev: &str,
    baud: u32,
    expected: &[(String, Group, u8)],
    mut src: SerialSource,
    frame: &LocalFrame,
    keep_untracked: bool,
    mut ring: Producer<'_, InsItem>,
    mut log: Producer<'_, SerialChunk>,
    sh: ReaderHandle<'_>,
) -> InsState {
    let _alive = ReaderGuard(sh.readers);
    let mut feed = Vn200Feed::new(*frame, keep_untracked, MAX_INS_GAP_NS);
    let mut buf = [0u8; SERIAL_CHUNK];
    let mut last_masks: Option<Masks> = None;
    let mut seen = |it: &spherecal::vn200::Framed<'_>, out: &InsOutcome| {
        if let Item::Binary(f) = &it.item {
            check_outputs(f.masks(), it.offset, &mut last_masks, expected, dev, sh);
        }
        if let InsOutcome::Pose(_, status) = out {
            if let Some(m) = status {
                sh.readers
                    .ins_mode
                    .store((m & 0b11) as u8, Ordering::Relaxed);
            }
            // Usable: tracking (or kept although not, when asked).
            if keep_untracked || status.and_then(crate::state::excluded_by).is_none() {
                sh.readers.ins_watch.pose();
            }
        }
    };
    let mut log_chunk = |b: &[u8], stamp: Option<RxStamp>| {
        sh.readers.ins_watch.bytes();
        sh.readers
            .ins_bytes
            .fetch_add(b.len() as u64, Ordering::Relaxed);
        let mut chunk = SerialChunk {
            stamp: stamp.unwrap_or_else(RxStamp::now),
            len: b.len() as u16,
            bytes: [0; SERIAL_CHUNK],
        };
        chunk.bytes[..b.len()].copy_from_slice(b);
        enqueue(&mut log, chunk, Overflow::Drop, &sh.ring_drops.serial_log);
    };
    let mut out = InsRing {
        ring: &mut ring,
        policy: Overflow::Drop,
        full: &sh.ring_drops.ins,
    };
    loop {
        let why = match ins_reader(
            &mut src,
            &mut buf,
            &mut feed,
            &mut out,
            sh.stop,
            &mut log_chunk,
            &mut seen,
            &mut |steps| sh.readers.ins_watch.set_clock_steps(steps),
        ) {
            Ok(InsEnd::Stopped) => break,
            Ok(InsEnd::SourceEnded) => "its stream ended".to_string(),
            Err(e) => e.to_string(),
        };
        sh.readers.ins_watch.lost(format!(
            "WARNING: serial {dev}: the device went away ({why}); opening it again"
        ));
        let gone = Instant::now();
        match reopen(dev, baud, sh) {
            Some(s) => {
                src = s;
                sh.readers.ins_watch.reopened(format!(
                    "serial {dev}: reopened after {:.1} s",
                    gone.elapsed().as_secs_f64()
                ));
            }
            None => {
                sh.said.error(format!(
                    "serial {dev}: the device went away ({why}) and was not back before the end"
                ));
                break;
            }
        }
    }
    end_ins(&mut ring, sh);
    feed.state()
}

/// Open `dev` again until it opens (`None`: the run stopped first), waiting [`REOPEN_MS`].
fn reopen(dev: &str, baud: u32, sh: ReaderHandle<'_>) -> Option<SerialSource> {
    let mut wait = REOPEN_MS.0;
    while !sh.stop.load(Ordering::Relaxed) {
        if let Ok(s) = SerialSource::open(dev, baud, super::READ_TIMEOUT) {
            return Some(s);
        }
        let until = Instant::now() + Duration::from_millis(wait);
        while Instant::now() < until && !sh.stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(20));
        }
        wait = (wait * 2).min(REOPEN_MS.1);
    }
    None
}

/// End the INS ring: wait for room for the End, unless the aligner is gone.
fn end_ins(ring: &mut Producer<'_, InsItem>, sh: ReaderHandle<'_>) {
    while ring.enqueue(InsItem::End).is_err() && !sh.aligner.gone.load(Ordering::Acquire) {
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// A POS MV's Real-Time Data Port until the stop: every datagram to the log ring, its groups
/// through the same [`PosmvFeed`](crate::pipeline::posmv::PosmvFeed) as a logged file, the
/// poses onto the INS ring (dropped and counted when it is full). The GPS week comes from its
/// Group 3 (select it on the port): poses before one are counted, not guessed.
#[allow(clippy::too_many_arguments)]
pub(super) fn posmv_reader(
    mut sock: UdpSource,
    frame: &LocalFrame,
    group: u16,
    keep_unaligned: bool,
    leap_seconds: i64,
    mut ring: Producer<'_, InsItem>,
    mut log: Producer<'_, UdpLogItem>,
    sh: ReaderHandle<'_>,
) -> InsState {
    use spherecal::posmv::Alignment;
    use spherecal_hal::{PacketSource, Record};
    let _alive = ReaderGuard(sh.readers);
    let port = sock.port();
    let mut ip_id = 0u16;
    let mut feed = crate::pipeline::posmv::PosmvFeed::new(
        *frame,
        group,
        keep_unaligned,
        MAX_INS_GAP_NS,
        leap_seconds,
        None,
    );
    {
        let mut out = InsRing {
            ring: &mut ring,
            policy: Overflow::Drop,
            full: &sh.ring_drops.ins,
        };
        while !sh.stop.load(Ordering::Relaxed) {
            match sock.next_record() {
                Ok(Some(Record::Udp(d))) => {
                    sh.readers.ins_watch.bytes();
                    sh.readers
                        .ins_bytes
                        .fetch_add(d.payload.len() as u64, Ordering::Relaxed);
                    log_pieces(&mut log, &d, &mut ip_id, sh);
                    let before = feed.poses_used();
                    feed.feed(d.payload, Some(d.time), &mut out);
                    if feed.poses_used() > before {
                        sh.readers.ins_watch.pose();
                    }
                    // The status line's INS mode: tracking in full navigation.
                    let mode = match feed.alignment() {
                        Some(Alignment::FullNavigation) => 2,
                        Some(Alignment::NoSolution) => 0,
                        Some(_) => 1,
                        None => continue,
                    };
                    sh.readers.ins_mode.store(mode, Ordering::Relaxed);
                }
                Ok(Some(_)) => {}
                Ok(None) => break,
                Err(e) => {
                    sh.said.error(format!("POS MV UDP port {port}: {e}"));
                    break;
                }
            }
        }
    }
    end_ins(&mut ring, sh);
    feed.state()
}

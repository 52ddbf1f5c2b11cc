//! The rig's aligner thread: the core aligner on the live rings (position packets, poses,
//! data packets), the solver's word applied between batches ([`super::watch`]), the batches
//! to the solver, the counters published for the status line.

use super::shared::AlignerHandle;
use super::summary::FirstMove;
use crate::pipeline::{BatchMsg, InsItem, LidarItem, LidarPacket, RingAligner, BATCH};
use heapless::spsc::Consumer;
use spherecal::align::window::Observation;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Where the aligner's batches go: to the solver in buffers recycled through `pool`, tagged
/// with the time offset they were collected at; a full channel drops the batch (counted).
pub(super) struct Batches<'p, 's> {
    pub(super) tx: crossbeam_channel::Sender<BatchMsg>,
    pub(super) pool: &'p crossbeam_channel::Receiver<Vec<Observation>>,
    pub(super) applied: std::cell::Cell<i64>,
    pub(super) sh: AlignerHandle<'s>,
}

impl Batches<'_, '_> {
    pub(super) fn emit(&self, sphere: usize, obs: &[Observation]) {
        let mut v = self
            .pool
            .try_recv()
            .unwrap_or_else(|_| Vec::with_capacity(BATCH));
        v.clear();
        v.extend_from_slice(obs);
        if let Err(e) = self.tx.try_send(BatchMsg {
            sphere,
            obs: v,
            offset_ns: self.applied.get(),
        }) {
            self.sh
                .aligner
                .batch_drops
                .fetch_add(e.into_inner().obs.len() as u64, Ordering::Relaxed);
        }
    }
}

/// Where the windows first moved: the next data packet's index and the returns windowed so
/// far (published once, for the run summary).
fn first_move(al: &RingAligner<'_>, sh: AlignerHandle<'_>) {
    if let Ok(mut m) = sh.aligner.first_move.lock() {
        *m = Some(FirstMove {
            packet: al.core.next_packet(),
            windowed: (0..sh.aligner.windowed.len())
                .map(|i| al.core.windowed_now(i))
                .collect(),
        });
    }
}

/// The longest a windowed return waits in the aligner's batches before the solver gets it.
const BATCH_AGE: Duration = Duration::from_secs(1);

/// The aligner on the live rings until the data reader's End: position packets and poses as
/// they come, each data packet aligned (waiting for the INS as [`InsWait::Latency`] allows),
/// a new time offset from the solver applied between batches, the counters published.
pub(super) fn align_until_end(
    al: &mut RingAligner<'_>,
    pos_c: &mut Consumer<'_, LidarItem>,
    ins_c: &mut Consumer<'_, InsItem>,
    data_c: &mut Consumer<'_, LidarItem>,
    out: &Batches<'_, '_>,
    sh: AlignerHandle<'_>,
) {
    let mut emit = |i: usize, o: &[Observation]| out.emit(i, o);
    let mut steer = sh.solver.steer.receiver();
    let mut windows_moved = 0;
    let mut published = Instant::now();
    let mut unpublished = false;
    let mut handed = Instant::now();
    loop {
        // What the batches hold goes on at least once a second: in windows tightened around
        // the calibration a far pass fills a batch slowly (table1's second pass over S1: ~300
        // returns in 5 s, half a batch is 512), and the live solves and verdict must see it.
        if handed.elapsed() >= BATCH_AGE {
            al.finish(&mut emit);
            handed = Instant::now();
        }
        while let Some(p) = pos_c.dequeue() {
            if let LidarPacket::Position(p) = p.packet() {
                al.position(&p);
                unpublished = true;
            }
        }
        // The clock's state for the solver, at most 5 times a second.
        if unpublished && published.elapsed() >= Duration::from_millis(200) {
            publish_clock(al, sh);
            (published, unpublished) = (Instant::now(), false);
        }
        al.drain_ins(ins_c);
        let Some(item) = data_c.dequeue() else {
            std::thread::sleep(Duration::from_millis(1));
            continue;
        };
        // The solver's word, between batches: the batches so far go at the old offset and
        // in the old windows.
        if let Some(s) = steer.changed() {
            if s.time_offset_ns != out.applied.get() {
                al.finish(&mut emit);
                al.core.time_offset_ns = s.time_offset_ns;
                out.applied.set(s.time_offset_ns);
            }
            if let Some((b, margin)) = s.windows.filter(|_| s.windows_moved != windows_moved) {
                al.finish(&mut emit);
                if windows_moved == 0 {
                    first_move(al, sh);
                }
                al.core.set_windows(b.mount(), margin);
                windows_moved = s.windows_moved;
            }
        }
        match item.packet() {
            LidarPacket::End => {
                publish_clock(al, sh);
                break;
            }
            LidarPacket::Position(p) => {
                al.position(&p);
                unpublished = true;
            }
            LidarPacket::Data(p) => al.data(&p, item.host, ins_c, None, &mut emit),
            LidarPacket::Points(c) => al.points(c, ins_c, None, &mut emit),
            LidarPacket::Hesai(p) => al.hesai(&p, item.host, ins_c, None, &mut emit),
            LidarPacket::Timed(t0, c, n) => {
                al.timed(t0, c, n, item.host, ins_c, None, &mut emit);
                unpublished = true;
            }
            LidarPacket::HesaiGps(p) => {
                al.hesai_gps(&p);
                unpublished = true;
            }
        }
        sh.aligner
            .aligned
            .store(al.core.stats.data_packets, Ordering::Relaxed);
        if let Some(p) = al.core.pps {
            sh.aligner.pps.store(p.to_byte(), Ordering::Relaxed);
        }
        if let Some(l) = al.core.lag_ns {
            sh.aligner.lag_ns.store(l, Ordering::Relaxed);
        }
        for (i, w) in sh.aligner.windowed.iter().enumerate() {
            w.store(al.core.windowed_now(i), Ordering::Relaxed);
        }
        let w = &al.core.stats.window;
        sh.aligner.without_pose.store(
            w.before_history + w.after_history + w.in_gap,
            Ordering::Relaxed,
        );
    }
}

/// The LiDAR clock's state and the data's first GPS time, for the solver's clock facts.
fn publish_clock(al: &RingAligner<'_>, sh: AlignerHandle<'_>) {
    if let Ok(mut c) = sh.aligner.clock.lock() {
        *c = (al.clock_state(), al.core.stats.lidar_span.map(|s| s.0));
    }
}

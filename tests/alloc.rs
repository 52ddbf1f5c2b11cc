//! A counting global allocator shows that the core's steady state allocates nothing per packet:
//! decode -> clock -> pose interpolation -> georeference -> window.

use spherecal::align::{PoseHistory, PoseSample};
use spherecal::sim::{InsSim, LidarSim, SimPacket};
use spherecal::time::LidarClock;
use spherecal::vlp16::{decode, DataPacket, PointBuf, PositionPacket};
use spherecal::vn200::{Framer, Item, Pose};
use spherecal::window::{Batch, Target, WindowStats, Windowing};
use spherecal_tools::scenario::Scenario;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};

struct Counting;
static ALLOCS: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards every call unchanged to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same layout contract as the caller's.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: p was allocated by System with layout l.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: p was allocated by System with layout l.
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static A: Counting = Counting;

#[test]
fn steady_state_allocates_nothing_per_packet() {
    // The fixed-capacity history is built on the stack: give the test room.
    std::thread::Builder::new()
        .stack_size(64 << 20)
        .spawn(steady_state)
        .unwrap()
        .join()
        .unwrap();
}

fn steady_state() {
    let s = Scenario::load("table1").unwrap();
    let (passes, objects) = (s.passes(), s.objects());
    let w = s.world(&[], &passes, &objects);
    // Everything the loop needs is made up front.
    let mut ins_bytes = Vec::new();
    let mut ins = InsSim::new(&w, s.ins_config());
    let mut buf = [0u8; 128];
    while let Some((_, n)) = ins.next_frame(&mut buf) {
        ins_bytes.extend_from_slice(&buf[..n]);
    }
    let mut packets: Vec<(bool, Vec<u8>)> = Vec::new();
    let mut sim = LidarSim::new(&w, s.lidar_config());
    let mut p = [0u8; 1206];
    while let Some(k) = sim.next_packet(&mut p) {
        let (_, len) = k.port_len();
        packets.push((matches!(k, SimPacket::Data { .. }), p[..len].to_vec()));
    }
    let targets: Vec<Target> = objects
        .iter()
        .filter_map(|o| match o.shape {
            spherecal::sim::Shape::Sphere { c, r } => Some(Target {
                center: c,
                radius: r,
            }),
            _ => None,
        })
        .collect();
    let mut batches: Vec<Batch<4096>> = (0..targets.len()).map(|_| Batch::default()).collect();
    let mut framer: Box<Framer> = Box::default();
    let mut history: Box<PoseHistory<16384>> = Box::new(PoseHistory::new(50_000_000));
    let mut points = PointBuf::new();
    let mut clock = LidarClock::new(s.leap_seconds);
    let mut win = Windowing {
        targets: &targets,
        margin: 0.01,
        mount: w.mount,
        batches: &mut batches,
        stats: WindowStats::default(),
    };

    // Steady state: INS bytes framed into the history, packets decoded, aligned, windowed.
    let before = ALLOCS.load(Ordering::Relaxed);
    let site = w.site;
    framer.consume(&ins_bytes, |it| {
        if let Item::Binary(f) = it.item {
            if let Some(ps) = Pose::from_frame(&f).and_then(|p| PoseSample::from_vn200(&site, &p)) {
                history.push(ps);
            }
        }
    });
    let mut n = 0u64;
    for (data, bytes) in &packets {
        if !data {
            let pp = PositionPacket::new_checked(&bytes[..]).unwrap();
            if !clock.has_hour() {
                let utc = pp.nmea_time().unwrap().utc().unwrap();
                clock.set_from_rmc(&utc, pp.timestamp_us());
            }
            continue;
        }
        let dp = DataPacket::new_checked(&bytes[..]).unwrap();
        if !clock.has_hour() {
            clock.set_from_gps(history.span().unwrap().0, dp.timestamp_us());
        }
        let t0 = clock.to_gps(dp.timestamp_us()).unwrap();
        decode(&dp, &mut points).unwrap();
        win.add_packet(t0, &points, &history, None);
        n += 1;
    }
    let after = ALLOCS.load(Ordering::Relaxed);
    assert_eq!(after - before, 0, "allocations in {n} packets");
    assert!(win.stats.windowed[0] > 1000, "{:?}", win.stats);
    assert_eq!(win.stats.georeferenced, win.stats.points);
}

//! `spherecal run`: the rig. Live acquisition into the same aligner as the file pipeline, raw
//! logging, a solver that calibrates as soon as every sphere has been seen well enough (and
//! again as more returns arrive), and a status line every second.
//!
//! ```text
//! UDP data reader ----> data ring ----\                          /--> batches --> solver
//! UDP position reader -> position ring --> aligner (this thread) -
//! serial reader ------> INS ring -----/   (or a UDP reader of a POS MV's groups)
//!   each reader also --> its log ring --> logger: rotating pcap + serial log
//!                                           --> syncer: fdatasync, so a power cut loses < 1 s
//! status: one line a second on the console; stops everything on SIGINT/SIGTERM or --duration
//! ```
//! Readers never block: a full ring drops the item and counts it (data, position, INS and log
//! rings each have their count); the kernel's own drops on each socket are read back too, so
//! `sent = received + kernel drops` and `received = enqueued + ring drops + skipped`.

use crate::config::board::Board;
use crate::config::site::Site;
use crate::pipeline::{
    AlignStorage, BatchMsg, InsItem, InsWait, LidarItem, LidarPacket, RingAligner, SensorFile,
    BATCH,
};
use crate::report::Report;
use crate::state::InsState;

mod align;
pub mod check;
mod from_logs;
pub mod hearing;
mod inputs;
pub mod ins_watch;
mod logger;
mod readers;
mod shared;
mod solver;
pub mod status;
mod summary;
pub mod watch;

use inputs::{Plan, RigIo, Rings};
use shared::{pps_name, AlignerGuard, Shared};

use heapless::spsc::Consumer;
use logger::{logger, syncer};
use readers::{posmv_reader, serial_reader, udp_reader, LidarPort, PortPlan};
use solver::solver;
use spherecal::align::window::Observation;
use spherecal_hal::console::Console;
use spherecal_hal::packet::{Datagram, HostTime};
use spherecal_hal::pcap::FRAGMENT_BYTES;
use spherecal_hal::serial::RxStamp;
use spherecal_hal::velodyne::SkipStats;
use status::{show, snapshot, status_loop};
use std::net::Ipv4Addr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};
use summary::Ended;
pub use summary::{render, RunSummary};

/// Data ring (holds N - 1 items: 21.7 s of a VLP-16 at 754 packets/s, 10.9 s dual return; an
/// Ouster's packet is one item per 32 returns: 0.8 s of an OS1-64 whose every pixel returns,
/// 0.4 s of a 128-beam one, more than [`INS_LATENCY`]; 21 MB). With 1,024 an OS1-64 through
/// the rig at eight times real time lost 853 of 40,000 packets on a busy machine.
pub const DATA_RING: usize = 16_384;
/// Position ring (and its log ring): position packets come ~1 a second from a VLP-16, but some
/// captures hold bursts of them.
pub const POSITION_RING: usize = 256;
/// Log ring for data datagrams and their fragments (24 MB: 21 s of a VLP-16, 2.7 s of an
/// OS1-64, 1.4 s of a 128-beam Ouster, for a disk that stalls).
pub const DATA_LOG_RING: usize = 16_384;
/// Log ring for a POS MV's datagrams (1.5 MB: 5 s at 200 Hz).
pub const POSMV_LOG_RING: usize = 1024;
/// Serial log ring (reads of up to [`SERIAL_CHUNK`] bytes; 2 MB, ~10 s of reads at 200 Hz).
pub const SERIAL_LOG_RING: usize = 2048;
/// Largest serial read.
pub const SERIAL_CHUNK: usize = 1024;
/// Largest datagram logged whole (an Ethernet MTU's UDP payload); longer ones (an Ouster's
/// lidar packets) are logged as the IPv4 fragments a 1500-byte link carries them in.
pub const MAX_DATAGRAM: usize = 1472;
/// Observations kept per sphere for the solver (older ones stay; newer ones are counted).
pub const MAX_OBS_PER_SPHERE: usize = 200_000;
/// Once calibrated, the windows reach this many residual RMS beyond the spheres ...
pub const LIVE_MARGIN_RMS: f64 = 8.0;
/// ... but at least this [m] (and at most [`crate::session::KEEP_NEAR_M`] and the site's margin).
pub const LIVE_MARGIN_FLOOR_M: f64 = 0.3;

/// Read timeout of every reader: how fast a stop is noticed.
pub const READ_TIMEOUT: Duration = Duration::from_millis(100);
/// How long after a packet's arrival the aligner waits for the INS to cover it (the data ring
/// holds more: [`DATA_RING`]).
pub const INS_LATENCY: Duration = Duration::from_millis(300);
/// The aligner interpolates across INS gaps up to this [ns] (wider ones are counted as gaps).
pub const MAX_INS_GAP_NS: i64 = 50_000_000;

/// What `run` is asked to do.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// The board.
    pub board: Board,
    /// Serial device (overrides the board's).
    pub serial: Option<String>,
    /// The site: without one, the rig only acquires and logs.
    pub site: Option<Site>,
    /// Raw log folder (overrides the board's).
    pub log_dir: Option<PathBuf>,
    /// Rotation size in bytes (overrides the board's `rotate_mb`).
    pub rotate_bytes: Option<u64>,
    /// Stop after this long.
    pub duration: Option<Duration>,
    /// Write the calibration report here after every solve.
    pub report: Option<PathBuf>,
    /// Use VN-200 poses whose InsStatus says not tracking (else left out, counted).
    pub keep_untracked_ins: bool,
    /// Claim although the LiDAR clock is not PPS-locked with a valid RMC (as `calibrate
    /// --allow-unlocked-clock`).
    pub allow_unlocked_clock: bool,
    /// Spans whose returns the calibration leaves out (`--exclude`) [GPS s, or seconds of the
    /// week].
    pub exclude: Vec<(f64, f64)>,
}

/// A datagram on its way to the log, whole or one of its IPv4 fragments.
#[derive(Clone)]
struct UdpLogItem {
    time: HostTime,
    src: (Ipv4Addr, u16),
    dst_port: u16,
    /// A fragment's identification, byte offset in the IP payload and "more fragments".
    fragment: Option<(u16, usize, bool)>,
    len: u16,
    bytes: [u8; FRAGMENT_BYTES],
}

impl UdpLogItem {
    /// `d` as log items: whole up to [`MAX_DATAGRAM`] bytes, else its IPv4 fragments
    /// (identification `id`); none for a datagram longer than UDP allows.
    fn pieces<'d>(d: &'d Datagram<'_>, id: u16) -> impl Iterator<Item = Self> + 'd {
        let whole = d.payload.len() <= MAX_DATAGRAM;
        spherecal_hal::pcap::udp_fragments(d.src_port, d.dst_port, d.payload)
            .into_iter()
            .flatten()
            .map(move |p| {
                let mut item = Self {
                    time: d.time,
                    src: (d.src_addr, d.src_port),
                    dst_port: d.dst_port,
                    fragment: (!whole).then_some((id, p.offset, p.more)),
                    len: 0,
                    bytes: [0; FRAGMENT_BYTES],
                };
                let head = match (whole, p.udp_header) {
                    (false, Some(h)) => {
                        item.bytes[..8].copy_from_slice(&h);
                        8
                    }
                    _ => 0,
                };
                let n = head + p.payload.len();
                item.bytes[head..n].copy_from_slice(p.payload);
                item.len = n as u16;
                item
            })
    }
}

/// A serial read on its way to the log.
#[derive(Clone)]
struct SerialChunk {
    stamp: RxStamp,
    len: u16,
    bytes: [u8; SERIAL_CHUNK],
}

/// A named scoped thread (names show in `top -H` and in panics). Spawning fails only when the
/// OS has no threads left, which ends the program as `std::thread::spawn` would.
fn spawn<'s, 'e, T: Send + 's>(
    sc: &'s std::thread::Scope<'s, 'e>,
    name: &str,
    f: impl FnOnce() -> T + Send + 's,
) -> std::thread::ScopedJoinHandle<'s, T> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn_scoped(sc, f)
        .unwrap_or_else(|e| panic!("cannot start the {name} thread: {e}"))
}

/// The rig's worker threads (the aligner is the caller's).
struct Workers<'s> {
    data: std::thread::ScopedJoinHandle<'s, (SkipStats, u64)>,
    pos: std::thread::ScopedJoinHandle<'s, (SkipStats, u64)>,
    ins: Option<std::thread::ScopedJoinHandle<'s, InsState>>,
    logger: std::thread::ScopedJoinHandle<'s, (Vec<PathBuf>, [u64; 2])>,
    syncer: std::thread::ScopedJoinHandle<'s, ()>,
    solver: std::thread::ScopedJoinHandle<'s, Option<Report>>,
    status: std::thread::ScopedJoinHandle<'s, &'s mut Console>,
}

/// After the aligner's end: the position items left, the INS to its end, every worker
/// joined (one that panicked fails the run), the last status line; the threads' results.
fn wind_down(
    w: Workers<'_>,
    al: &mut RingAligner<'_>,
    pos_c: &mut Consumer<'_, LidarItem>,
    ins_c: &mut Consumer<'_, InsItem>,
    plan: &Plan,
    sh: &Shared<'_>,
    started: Instant,
) -> Result<Ended, crate::Error> {
    // The position reader may still hold items; the INS reader ends with its End.
    let mut panicked = Vec::new();
    let skips_pos = joined(w.pos, "position reader", &mut panicked);
    while let Some(p) = pos_c.dequeue() {
        if let LidarPacket::Position(p) = p.packet() {
            al.position(&p);
        }
    }
    al.drain_until_end(ins_c);
    let skips_data = joined(w.data, "data reader", &mut panicked);
    let ins = w.ins.map(|h| joined(h, "INS reader", &mut panicked));
    let logged = joined(w.logger, "logger", &mut panicked);
    joined(w.syncer, "log syncer", &mut panicked);
    let ended = Ended {
        skips: [skips_data, skips_pos],
        ins: ins.unwrap_or_default(),
        logged,
        calibration: joined(w.solver, "solver", &mut panicked),
        align: al.core.stats,
        clock: al.clock_state(),
    };
    // The last line, with the final counts and calibration.
    sh.aligner
        .aligned
        .store(al.core.stats.data_packets, Ordering::Relaxed);
    match w.status.join() {
        Ok(c) => {
            let mut last = [u64::MAX; 2];
            if let Err(e) = show(c, &snapshot(sh, &plan.ids, started, &mut last)) {
                sh.said.error(format!("console: {e}"));
            }
        }
        Err(_) => panicked.push("status"),
    }
    if panicked.is_empty() {
        Ok(ended)
    } else {
        Err(crate::Error::internal(format!(
            "the rig's {} thread panicked",
            panicked.join(", ")
        )))
    }
}

/// A worker's result; a worker that panicked is named in `panicked` (the run then fails as
/// an internal error instead of ending with that worker's counts silently zero).
fn joined<T: Default>(
    h: std::thread::ScopedJoinHandle<'_, T>,
    name: &'static str,
    panicked: &mut Vec<&'static str>,
) -> T {
    h.join().unwrap_or_else(|_| {
        panicked.push(name);
        T::default()
    })
}

/// The UTC start stamp that names a run's files, e.g. `20261122T084638Z`.
pub fn stamp_now() -> String {
    let t = spherecal::time::UtcDateTime::from_unix_ns(spherecal_hal::clock::wall().0);
    format!(
        "{:04}{:02}{:02}T{:02}{:02}{:02}Z",
        t.year, t.month, t.day, t.hour, t.minute, t.second
    )
}

fn parse_addr(s: &str, key: &str) -> Result<Ipv4Addr, crate::Error> {
    s.parse()
        .map_err(|_| format!("board: {key} = {s:?} is not an IPv4 address").into())
}

/// Run the rig until `stop` is set (by a signal) or the duration has passed. Status lines go
/// to `console`.
pub fn run(
    opts: &RunOptions,
    console: &mut Console,
    stop: &AtomicBool,
) -> Result<RunSummary, crate::Error> {
    // The rings are built on the stack before they move to the heap: give them room whatever
    // thread the caller is on.
    std::thread::scope(|sc| {
        std::thread::Builder::new()
            .name("rig".into())
            .stack_size(64 << 20)
            .spawn_scoped(sc, || run_rig(opts, console, stop))
            .map_err(|e| crate::Error::internal(format!("the rig thread: {e}")))?
            .join()
            .map_err(|_| crate::Error::internal("the rig thread panicked"))?
    })
}

fn run_rig(
    opts: &RunOptions,
    console: &mut Console,
    stop: &AtomicBool,
) -> Result<RunSummary, crate::Error> {
    let mut io = RigIo::open(opts)?;
    // The VN-200 set up as the board says, before anything reads the port.
    if let (true, Some((dev, src))) = (opts.board.ins.configure, io.serial.as_mut()) {
        let lines = match crate::vn200::configure::configure(
            src.port_mut(),
            dev,
            &opts.board.ins,
            crate::vn200::configure::Options::default(),
        ) {
            Ok(c) => c.steps.iter().map(|s| format!("vn200: {s}")).collect(),
            Err(e) => vec![format!(
                "WARNING: VN-200 configuration failed: {e}; the rig goes on with what the unit sends (spherecal vn200 configure --board ... tries again)"
            )],
        };
        for l in lines {
            console
                .write_line(&l)
                .map_err(|e| format!("console: {e}"))?;
        }
    }
    let plan = Plan::new(opts, io.sensor.as_ref());
    let probes = [io.data_sock.drop_probe(), io.pos_sock.drop_probe()];
    let readers = 2 + usize::from(io.serial.is_some()) + usize::from(io.posmv.is_some());
    let ouster = match &io.sensor {
        Some(SensorFile::Ouster(m)) => Some((m.format, m.columns_per_frame as u32, m.imu_port)),
        _ => None,
    };
    let sh = Shared::new(
        stop,
        readers,
        plan.ids.len(),
        probes,
        (io.accept.ports, ouster),
    );
    sh.readers
        .ins_watch
        .stale_bytes
        .store(io.stale_serial_bytes, Ordering::Relaxed);
    let started = Instant::now();
    let path = io.log_dir.join(format!("{}-run.json", io.stamp));
    let mut ended = run_threads(opts, console, io, &plan, &sh, started)?;
    // The final answer: the file engine over the rig's own logs, what `calibrate` gives on
    // them (the live solves work on a store pruned and rebased as the data came).
    if let Some(site) = &opts.site {
        match from_logs::final_from_logs(opts, site, &ended.logged.0, &plan) {
            Ok(Some(rep)) => {
                let line = format!(
                    "final (the rig's logs through the file engine): {}; the rounds {}",
                    if rep.converged {
                        "converged".to_string()
                    } else {
                        format!("NOT CONVERGED: {}", rep.reason.as_deref().unwrap_or("-"))
                    },
                    crate::report::termination_words(&rep.termination)
                );
                if let Err(e) = console.write_line(&line) {
                    sh.said.error(format!("console: {e}"));
                }
                if let Some(p) = &opts.report {
                    if let Err(e) = crate::report::write_json_atomically(p, &rep) {
                        sh.said.error(e.to_string());
                    }
                }
                ended.calibration = Some(rep);
            }
            Ok(None) => {}
            Err(e) => sh.said.error(format!(
                "the final calibration from the logs: {e} (the live one is kept)"
            )),
        }
    }
    let summary = RunSummary::new(ended, &sh, started);
    let json = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    std::fs::write(&path, json + "\n").map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(summary)
}

/// Every thread of the rig until the stop: readers, logger, syncer, solver, status, and the
/// aligner on this thread; then their results.
fn run_threads(
    opts: &RunOptions,
    console: &mut Console,
    io: RigIo,
    plan: &Plan,
    sh: &Shared<'_>,
    started: Instant,
) -> Result<Ended, crate::Error> {
    let mut rings = Rings::new();
    let (data_p, mut data_c) = rings.data.split();
    let (pos_p, mut pos_c) = rings.pos.split();
    let (mut ins_p, mut ins_c) = rings.ins.split();
    let (dlog_p, dlog_c) = rings.data_log.split();
    let (plog_p, plog_c) = rings.pos_log.split();
    let (ilog_p, ilog_c) = rings.posmv_log.split();
    let (slog_p, slog_c) = rings.serial_log.split();
    let (tx, rx) = crossbeam_channel::bounded::<BatchMsg>(64);
    let (pool_tx, pool_rx) = crossbeam_channel::bounded::<Vec<Observation>>(64);
    for _ in 0..16 {
        let _ = pool_tx.try_send(Vec::with_capacity(BATCH));
    }
    let to_sync = Mutex::new(Vec::new());
    let RigIo {
        accept,
        bind,
        data_sock,
        pos_sock,
        serial,
        posmv,
        mut raw_log,
        sensor,
        ..
    } = io;
    let ouster = match &sensor {
        Some(SensorFile::Ouster(m)) => Some((&**m, opts.board.leap_seconds)),
        _ => None,
    };
    // Each thread's handle: what it writes and reads of the shared state.
    let (rh, lh, ah) = (sh.reader(), sh.logger(), sh.aligner());
    // Each socket's reader (an Ouster's IMU packets, if they come to the position port, are
    // counted as its other port's); the data socket's end ends the survey.
    let port_plan = |port| PortPlan {
        accept,
        port,
        ouster,
        ends_stream: port == LidarPort::Data,
    };
    std::thread::scope(|sc| {
        let data = spawn(sc, "udp-data", move || {
            udp_reader(data_sock, data_p, dlog_p, port_plan(LidarPort::Data), rh)
        });
        let pos = spawn(sc, "udp-position", move || {
            udp_reader(pos_sock, pos_p, plog_p, port_plan(LidarPort::Position), rh)
        });
        let ins = match (serial, posmv) {
            (Some((dev, src)), _) => Some(spawn(sc, "serial", move || {
                let (frame, keep) = (&plan.frame, opts.keep_untracked_ins);
                let baud = opts.board.ins.baud;
                serial_reader(
                    &dev,
                    baud,
                    &plan.expected,
                    src,
                    frame,
                    keep,
                    ins_p,
                    slog_p,
                    rh,
                )
            })),
            (None, Some(sock)) => Some(spawn(sc, "udp-posmv", move || {
                let b = &opts.board;
                let (frame, keep) = (&plan.frame, opts.keep_untracked_ins);
                let (group, leap) = (b.ins.posmv_group, b.leap_seconds);
                posmv_reader(sock, frame, group, keep, leap, ins_p, ilog_p, rh)
            })),
            (None, None) => {
                let _ = ins_p.enqueue(InsItem::End);
                None
            }
        };
        let to_sync = &to_sync;
        let syncer = spawn(sc, "syncer", move || syncer(to_sync, lh));
        let logger = spawn(sc, "logger", move || {
            logger(
                &mut raw_log,
                [dlog_c, plog_c, ilog_c],
                slog_c,
                bind,
                to_sync,
                lh,
            );
            raw_log.written()
        });
        let solver = spawn(sc, "solver", move || {
            solver(
                rx,
                pool_tx,
                &solver::SolverPlan::of(opts, plan),
                sh.solver(),
            )
        });
        let status = spawn(sc, "status", move || {
            status_loop(
                console,
                &plan.ids,
                opts.duration,
                started,
                sh,
                (bind, accept.sensor),
            )
        });

        // Aligner (this thread). Should it fail, everything winds down.
        let _aligner = AlignerGuard(sh);
        let mut storage = AlignStorage::new(plan.targets.len(), MAX_INS_GAP_NS);
        let mut al = RingAligner::new(
            &mut storage,
            &plan.targets,
            plan.margin,
            plan.b0.mount(),
            opts.board.leap_seconds,
            InsWait::Latency(INS_LATENCY),
            &spherecal_hal::clock::SystemClock,
        );
        al.core.set_model(opts.board.lidar_model());
        match &sensor {
            Some(SensorFile::Hesai(c)) => {
                al = al.with_hesai((**c).clone());
                al.clock.hesai = true;
            }
            Some(SensorFile::Ouster(m)) => al.clock.ouster = Some(crate::pipeline::ouster_clock(m)),
            None => {}
        }
        let out = align::Batches {
            tx,
            pool: &pool_rx,
            applied: std::cell::Cell::new(0),
            sh: ah,
        };
        align::align_until_end(&mut al, &mut pos_c, &mut ins_c, &mut data_c, &out, ah);
        al.finish(&mut |i, o| out.emit(i, o));
        for (w, n) in sh.aligner.windowed.iter().zip(&al.core.windowed) {
            w.store(*n, Ordering::Relaxed);
        }
        drop(out);
        let workers = Workers {
            data,
            pos,
            ins,
            logger,
            syncer,
            solver,
            status,
        };
        wind_down(workers, &mut al, &mut pos_c, &mut ins_c, plan, sh, started)
    })
}

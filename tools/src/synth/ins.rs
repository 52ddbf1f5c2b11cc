//! The INS side of [`synth`](super::synth): the VN-200 stream (`ins.bin`, `ins.vnlog`), a POS
//! MV's logged groups (`ins.posmv`) and post-processed trajectory (`sbet_ins.out`,
//! `smrmsg_ins.out`), and the truth of the correlated navigation errors (`nav-errors.csv`).

use super::{io, SERIAL_BAUD, SERIAL_LATENCY_NS};
use crate::config::scenario::Scenario;
use crate::output::Staged;
use spherecal::sim::ins::InsStats;
use spherecal::sim::{InsSim, World};
use spherecal::time::gps_to_unix_ns;
use spherecal_hal::packet::HostTime;
use spherecal_hal::serial::{LogWriter, RxStamp};
use std::io::Write;
use std::path::Path;

/// The file of the correlated navigation errors (with `[ins.correlated]`): per INS sample its
/// GPS time (true) and the error the sample carries, reported minus true.
pub const NAV_ERRORS: &str = "nav-errors.csv";
const NAV_ERRORS_HEADER: &str = "gps_time_s,north_m,east_m,down_m,roll_deg,pitch_deg,heading_deg\n";

/// Only the INS files of a scenario (`ins.bin`, `ins.vnlog`; for a POS MV `ins.posmv`,
/// `sbet_ins.out`, `smrmsg_ins.out`; with `[ins.correlated]` `nav-errors.csv`), into `dir`
/// (created if needed): the same streams [`synth`](super::synth) writes.
pub fn synth_ins(s: &Scenario, dir: &Path) -> Result<InsStats, crate::Error> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    s.with_world(|world| {
        let mut files = Vec::new();
        let stats = write_ins(s, world, dir, &mut files)?;
        crate::output::commit_all(files)?;
        Ok(stats)
    })
    .map_err(|e| e.to_string())?
}

pub(super) fn write_ins(
    s: &Scenario,
    world: &World<'_>,
    dir: &Path,
    files: &mut Vec<Staged>,
) -> Result<InsStats, crate::Error> {
    let ins_path = dir.join("ins.bin");
    let log_path = dir.join("ins.vnlog");
    let mut w = Staged::create(&ins_path)?;
    let mut log =
        LogWriter::new(Staged::create(&log_path)?, SERIAL_BAUD).map_err(|e| io(&log_path, e))?;
    let cfg = s.ins_config();
    let mut ins = InsSim::new(world, cfg);
    // The correlated navigation errors the stream carries, sample by sample: the truth a
    // trajectory correction is checked against.
    let err_path = dir.join(NAV_ERRORS);
    let mut errs = None;
    if cfg.correlated.is_on() {
        let mut e = Staged::create(&err_path)?;
        e.write_all(NAV_ERRORS_HEADER.as_bytes())
            .map_err(|e| io(&err_path, e))?;
        errs = Some(e);
    }
    let mut buf = [0u8; 128];
    let mut first_wall: Option<i64> = None;
    while let Some((t, n)) = ins.next_frame(&mut buf) {
        w.write_all(&buf[..n]).map_err(|e| io(&ins_path, e))?;
        if let Some(e) = errs.as_mut() {
            let [n_, e_, d, r, p, h] = ins.last_error.0;
            writeln!(
                e,
                "{:.4},{n_:.5},{e_:.5},{d:.5},{:.6},{:.6},{:.6}",
                t.0 as f64 * 1e-9,
                r.to_degrees(),
                p.to_degrees(),
                h.to_degrees()
            )
            .map_err(|e| io(&err_path, e))?;
        }
        let wall = gps_to_unix_ns(t, s.leap_seconds)
            + SERIAL_LATENCY_NS
            + (n as i64 * 10 * 1_000_000_000) / i64::from(SERIAL_BAUD);
        let first = *first_wall.get_or_insert(wall);
        let stamp = RxStamp {
            mono_ns: u64::try_from(wall - first).unwrap_or(0),
            wall: HostTime(wall),
        };
        log.record(stamp, &buf[..n]).map_err(|e| io(&log_path, e))?;
    }
    files.push(w);
    files.push(log.into_inner());
    files.extend(errs);
    if s.ins.kind == "posmv" {
        files.extend(write_pospac(s, world, dir)?);
        // The Logging Data Port's byte stream, as a POS MV logs it (.000 files).
        let p = dir.join("ins.posmv");
        let mut w = Staged::create(&p)?;
        let mut sim = InsSim::new(world, s.ins_config());
        let mut buf = [0u8; 1024];
        while let Some((_, n)) = sim.next_posmv(&mut buf) {
            w.write_all(&buf[..n]).map_err(|e| io(&p, e))?;
        }
        files.push(w);
    }

    Ok(ins.stats)
}

/// A POS MV survey's post-processed trajectory, as POSPac writes it: `sbet_ins.out` (one record
/// per INS sample, the same samples and errors as its real-time groups; wander angle 0) and
/// `smrmsg_ins.out` (each whole second, the per-axis sigmas the samples carry, as Group 2 states
/// them).
fn write_pospac(s: &Scenario, world: &World<'_>, dir: &Path) -> Result<Vec<Staged>, crate::Error> {
    use spherecal_hal::sbet::{SbetRecord, SmrmsgRecord};
    let (sbet_path, rms_path) = (dir.join(SBET), dir.join(SMRMSG));
    let (mut sbet, mut rms) = (Staged::create(&sbet_path)?, Staged::create(&rms_path)?);
    let mut sim = InsSim::new(world, s.ins_config());
    let sig = sim.stated_sigmas();
    let arcmin = |rad: f64| rad.to_degrees() * 60.0;
    let mut last_second = None;
    while let Some((t, [r, p, h], g)) = sim.next_pose() {
        let (_, tow_ns) = t.week_tow_ns();
        let tow_s = tow_ns as f64 * 1e-9;
        let rec = SbetRecord {
            tow_s,
            lat: g.lat,
            lon: g.lon,
            h: g.h,
            roll: r,
            pitch: p,
            platform_heading: h,
            wander: 0.0,
        };
        sbet.write_all(&rec.emit()).map_err(|e| io(&sbet_path, e))?;
        let second = tow_ns.div_euclid(1_000_000_000);
        if last_second != Some(second) {
            last_second = Some(second);
            let m = SmrmsgRecord {
                tow_s,
                position_m: [sig[0], sig[1], sig[2]],
                velocity_mps: [0.01; 3],
                attitude_arcmin: [arcmin(sig[3]), arcmin(sig[4]), arcmin(sig[5])],
            };
            rms.write_all(&m.emit()).map_err(|e| io(&rms_path, e))?;
        }
    }
    Ok(vec![sbet, rms])
}

/// A POS MV survey's SBET and its accuracy file (written by [`synth`] with `[ins] kind =
/// "posmv"`).
pub const SBET: &str = "sbet_ins.out";
/// See [`SBET`].
pub const SMRMSG: &str = "smrmsg_ins.out";

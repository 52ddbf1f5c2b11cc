//! An Ouster capture onto the LiDAR ring: its lidar packets (6-25 kB, larger than a ring item)
//! decoded in the reader into chunks of returns, each timed from its column's timestamp
//! ([`LidarItem::timed`]); the aligner takes them as they are ([`super::RingAligner::timed`]).
//!
//! The column timestamps by the metadata's `timestamp_mode` (firmware manual, "Time
//! Synchronization"): `TIME_FROM_PTP_1588` counts TAI nanoseconds (GPS = TAI - 19 s);
//! `TIME_FROM_SYNC_PULSE_IN` counts UTC from the pulse's NMEA (GPS = UTC + the site's leap
//! seconds); `TIME_FROM_INTERNAL_OSC`, or any time before 2010 (a PTP or pulse the sensor never
//! locked to: it counts from power-on), is free-running: the capture's receive time of the
//! first packet places it, the clock is unlocked ([`OusterClock`], counted by the aligner from
//! each chunk's [`ColumnsTimed`]).

use super::readers::LidarRing;
use super::{enqueue, ColumnsTimed, LidarItem, Overflow};
use crate::ouster::{Metadata, TimestampMode};
use crate::state::OusterClock;
use spherecal::ouster::LidarPacket;
use spherecal::time::{unix_ns_to_gps, GpsTime};
use spherecal::velodyne::{Point, Return};
use spherecal_hal::packet::{HostTime, SkipReason};
use spherecal_hal::rosbag::clouds::Chunk;
use spherecal_hal::velodyne::SkipStats;
use spherecal_hal::{PacketSource, Record};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// 2010-01-01T00:00:00Z [ns since 1970]: a synchronised clock's time is after it.
const PLAUSIBLE_NS: u64 = 1_262_304_000_000_000_000;
/// GPS epoch (1980-01-06) [s since 1970].
const GPS_EPOCH_S: i64 = 315_964_800;

/// Decodes an Ouster's lidar packets into timed chunks.
struct Decoder<'m> {
    meta: &'m Metadata,
    leap_seconds: i64,
    /// Columns timed since the last chunk went out.
    columns: ColumnsTimed,
    /// A free-running clock's offset to UTC [ns] (the first packet's receive time minus its
    /// first column's timestamp).
    free_offset: Option<i64>,
    /// A packet's CRC-64 agreed: the others are checked.
    crc_on: bool,
    /// The packets come from a bag's lidar topic: each is a lidar packet, ouster-ros's with one
    /// byte more than the format's length (`buf.resize(lidar_packet_size + 1)`).
    from_bag: bool,
}

impl Decoder<'_> {
    /// A column timestamp as GPS time, counting how it was read.
    fn gps(&mut self, ts: u64, host: HostTime) -> GpsTime {
        let synchronised = ts >= PLAUSIBLE_NS
            && matches!(
                self.meta.timestamp_mode,
                Some(TimestampMode::Ptp | TimestampMode::SyncPulseIn)
            );
        // (A timestamp beyond i64 is garbage: held at the end of time, never wrapped.)
        let ts = i64::try_from(ts).unwrap_or(i64::MAX);
        if synchronised {
            self.columns.synchronised = self.columns.synchronised.saturating_add(1);
            return match self.meta.timestamp_mode {
                Some(TimestampMode::Ptp) => GpsTime(ts - (GPS_EPOCH_S + 19) * 1_000_000_000),
                _ => unix_ns_to_gps(ts, self.leap_seconds),
            };
        }
        self.columns.free_running = self.columns.free_running.saturating_add(1);
        let off = *self.free_offset.get_or_insert(host.0.saturating_sub(ts));
        unix_ns_to_gps(ts.saturating_add(off), self.leap_seconds)
    }

    /// The packet's returns in chunks onto the ring; `Err` when it is no packet of the
    /// metadata's format (or its CRC disagrees once they were seen to agree). The ring's
    /// counts are the packet's, as for a packet that is one item: enqueued when every chunk
    /// was, else one drop (a full ring's waits are counted as they come).
    fn packet(
        &mut self,
        bytes: &[u8],
        host: HostTime,
        out: &mut LidarRing<'_, '_>,
    ) -> Result<(), SkipReason> {
        let n = self.meta.format.packet_len();
        let bytes = match bytes.len() {
            len if self.from_bag && len == n + 1 => &bytes[..n],
            _ => bytes,
        };
        let p = LidarPacket::new_checked(bytes, self.meta.format).map_err(SkipReason::Ouster)?;
        if let Some((sent, computed)) = p.crc() {
            if sent == computed {
                self.crc_on = true;
            } else if self.crc_on {
                return Err(SkipReason::Ouster(spherecal::ouster::Error::Crc {
                    stored: sent,
                    computed,
                }));
            }
        }
        let g = &self.meta.intrinsics;
        let mut chunk: Option<(GpsTime, Chunk)> = None;
        let mut lost = false;
        let flush = |c: Option<(GpsTime, Chunk)>,
                     columns: &mut ColumnsTimed,
                     lost: &mut bool,
                     out: &mut LidarRing<'_, '_>| {
            if let Some((t0, c)) = c.filter(|(_, c)| !c.points().is_empty()) {
                let item = LidarItem::timed(t0, &c, Some(host), core::mem::take(columns));
                let waits = AtomicU64::new(0);
                *lost |= !enqueue(out.ring, item, out.policy, &waits);
                if out.policy == Overflow::Wait {
                    out.full.fetch_add(waits.into_inner(), Ordering::Relaxed);
                }
            }
        };
        for (i, col) in p.columns().enumerate() {
            if !col.valid() {
                continue;
            }
            let t = self.gps(col.timestamp_ns(), host);
            let columns = &mut self.columns;
            let geo = g.column(col.measurement_id());
            col.for_each_return(|beam, ret, range_mm| {
                let (t0, c) = chunk.get_or_insert((t, Chunk::new(HostTime(0))));
                let offset = t.0.saturating_sub(t0.0);
                let px = col.pixel(beam);
                let bp = geo.point(beam, range_mm);
                let point = Point {
                    x: bp.xyz[0] as f32,
                    y: bp.xyz[1] as f32,
                    z: bp.xyz[2] as f32,
                    azimuth: bp.azimuth_deg.to_radians() as f32,
                    offset_ns: u32::try_from(offset).unwrap_or(u32::MAX),
                    distance_raw: u16::try_from(range_mm).unwrap_or(u16::MAX),
                    range: range_mm as f32 * 1e-3,
                    intensity: px.reflectivity[ret],
                    block: i as u8,
                    channel: beam as u8,
                    laser: beam as u8,
                    ret: if ret == 0 {
                        Return::Strongest
                    } else {
                        Return::DualStrongest
                    },
                };
                // A chunk holds returns of one second at most (offsets in u32 ns).
                if !(0..1_000_000_000).contains(&offset) || !c.push(point) {
                    let full = chunk.replace((t, Chunk::new(HostTime(0))));
                    flush(full, columns, &mut lost, out);
                    if let Some((_, c)) = chunk.as_mut() {
                        c.push(Point {
                            offset_ns: 0,
                            ..point
                        });
                    }
                }
            });
        }
        flush(chunk, &mut self.columns, &mut lost, out);
        let count = if lost { out.full } else { out.queued };
        count.fetch_add(1, Ordering::Relaxed);
        Ok(())
    }
}

/// An Ouster's clock as its metadata names it, nothing counted yet.
pub fn ouster_clock(meta: &Metadata) -> OusterClock {
    OusterClock {
        mode: meta
            .timestamp_mode
            .as_ref()
            .map(|m| m.name().to_string())
            .unwrap_or_default(),
        ..OusterClock::default()
    }
}

/// Every record of `src` until it ends, fails or `stop` is set: the metadata's lidar packets
/// (from `sensor`, when given) decoded onto the ring, the rest counted by reason (its IMU
/// packets as another port's).
pub fn ouster_reader<S: PacketSource>(
    src: &mut S,
    out: &mut LidarRing<'_, '_>,
    meta: &Metadata,
    leap_seconds: i64,
    (from_bag, sensor): (bool, Option<std::net::Ipv4Addr>),
    stop: &AtomicBool,
) -> (SkipStats, Result<(), S::Error>) {
    let mut skips = SkipStats::default();
    let mut d = Decoder {
        meta,
        leap_seconds,
        columns: ColumnsTimed::default(),
        free_offset: None,
        crc_on: false,
        from_bag,
    };
    while !stop.load(Ordering::Relaxed) {
        let rec = match src.next_record() {
            Ok(Some(r)) => r,
            Ok(None) => break,
            Err(e) => return (skips, Err(e)),
        };
        let dg = match rec {
            Record::Skipped { offset, reason } => {
                skips.count(offset, &reason);
                continue;
            }
            Record::Idle => continue,
            Record::Udp(dg) => dg,
        };
        let r = match sensor {
            Some(a) if a != dg.src_addr => Err(SkipReason::OtherSender(dg.src_addr)),
            _ if from_bag || dg.dst_port == meta.lidar_port => d.packet(dg.payload, dg.time, out),
            _ => Err(SkipReason::OtherPort(dg.dst_port)),
        };
        if let Err(reason) = r {
            skips.count(dg.offset, &reason);
        }
    }
    (skips, Ok(()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta(mode: &str) -> Metadata {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../tests/data/ouster/OS-0-32-U1_v2.2.0_1024x10.json"
        ))
        .unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v["config_params"]["timestamp_mode"] = mode.into();
        Metadata::parse(&v).unwrap()
    }

    /// PTP's TAI and the sync pulse's UTC to GPS time (2024-06-12T10:59:25Z is GPS
    /// 1402225183 s: UTC + 18 s); a free-running count placed by the first receive time; any
    /// timestamp, however wild, gives a time and no overflow.
    #[test]
    fn column_times_by_the_timestamp_mode() {
        let utc_ns: i64 = 1_718_189_965_000_000_000;
        let gps = GpsTime(1_402_225_183 * 1_000_000_000);
        let host = HostTime(utc_ns + 1_400_000);
        let m = meta("TIME_FROM_PTP_1588");
        let mut d = Decoder {
            meta: &m,
            leap_seconds: 18,
            columns: ColumnsTimed::default(),
            free_offset: None,
            crc_on: false,
            from_bag: false,
        };
        let tai = (utc_ns + 37_000_000_000) as u64;
        assert_eq!(d.gps(tai, host), gps);
        assert_eq!(d.gps(516_000_000_000, host), GpsTime(gps.0 + 1_400_000));
        assert_eq!(d.gps(517_000_000_000, host), GpsTime(gps.0 + 1_001_400_000));
        assert_eq!((d.columns.synchronised, d.columns.free_running), (1, 2));
        for wild in [0, u64::MAX, i64::MAX as u64 + 1, 1 << 62] {
            let _ = d.gps(wild, host);
        }
        let m = meta("TIME_FROM_SYNC_PULSE_IN");
        d.meta = &m;
        assert_eq!(d.gps(utc_ns as u64, host), gps);
        let m = meta("TIME_FROM_INTERNAL_OSC");
        d.meta = &m;
        let before = d.columns.free_running;
        let _ = d.gps(utc_ns as u64, host);
        assert_eq!(
            d.columns.free_running,
            before + 1,
            "free-running whatever its value"
        );
    }
}

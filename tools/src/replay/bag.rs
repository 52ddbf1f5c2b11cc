//! A ROS 2 bag played back through the rig's own inputs: its scans' packets as UDP datagrams
//! to the data port at their stamps, its VectorNav groups as the VN-200 binary frames they
//! were parsed from (the core's emitter: [`spherecal::ros2::CommonGroup::vn200_frame`]) to a
//! serial device at their header stamps, both on one [`Pacer`].

use super::{joined, send_all, Pacer, Speed, Target, UdpReplay};
use crate::pipeline::Files;
use spherecal_hal::clock::SystemClock;
use spherecal_hal::serial::{ByteSource, ReadOutcome};
use spherecal_hal::{PacketSource, Record};
use std::io::Write;
use std::path::Path;

/// What a bag's replay is told.
#[derive(Debug, Clone, Default)]
pub struct BagReplay {
    /// The topic of scans (None: the only VelodyneScan topic).
    pub lidar_topic: Option<String>,
    /// The topic of CommonGroups (None: the only one).
    pub ins_topic: Option<String>,
}

/// Replay `bag`: the scans' packets to `to`, and (with `serial`) the INS frames to the device,
/// on one clock from the earlier of their first stamps, scaled by `speed`. Returns what was
/// sent and the bytes written.
pub fn replay_bag(
    bag: &Path,
    topics: &BagReplay,
    to: Target,
    serial: Option<&mut (dyn Write + Send)>,
    speed: Speed,
) -> Result<(UdpReplay, Option<u64>), crate::Error> {
    let files = Files::from(bag);
    let lidar = || crate::pipeline::open_captures(&files, topics.lidar_topic.as_deref(), None);
    let mut first = None;
    let mut src = lidar()?;
    while let Some(rec) = src.next_record().map_err(|e| e.to_string())? {
        if let Record::Udp(d) = rec {
            first = Some(d.time);
            break;
        }
    }
    let opened = match serial {
        Some(_) => Some(crate::bag::open(
            bag,
            None,
            topics.ins_topic.as_deref(),
            false,
        )?),
        None => None,
    };
    // The leap seconds turn a UTC time reference into GPS time (18 since 2017).
    let mut ins = opened.as_ref().map(|o| o.ins(18)).transpose()?;
    // The first INS stamp: a second source over the same messages.
    if let Some(o) = &opened {
        let mut probe = o.ins(18)?;
        if let ReadOutcome::Data { stamp: Some(s), .. } = probe
            .read_chunk(&mut [0u8; 256])
            .map_err(|e| e.to_string())?
        {
            first = Some(first.map_or(s.wall, |f: spherecal_hal::clock::HostTime| f.min(s.wall)));
        }
    }
    let clock = Pacer::new(&SystemClock, first.unwrap_or_default(), speed);
    std::thread::scope(|sc| {
        let ser = match (serial, ins.as_mut()) {
            (Some(out), Some(src)) => Some(sc.spawn(move || -> Result<u64, crate::Error> {
                let mut buf = [0u8; 256];
                let mut written = 0u64;
                loop {
                    match src.read_chunk(&mut buf).map_err(|e| e.to_string())? {
                        ReadOutcome::End => break,
                        ReadOutcome::Idle => {}
                        ReadOutcome::Data { len, stamp } => {
                            if let Some(s) = stamp {
                                clock.wait_for(s.wall);
                            }
                            out.write_all(&buf[..len])
                                .map_err(|e| format!("serial write: {e}"))?;
                            written += len as u64;
                        }
                    }
                }
                out.flush().map_err(|e| format!("serial write: {e}"))?;
                Ok(written)
            })),
            _ => None,
        };
        let udp = send_all(lidar()?, to, &clock);
        let ser = joined(ser);
        Ok((udp?, ser?))
    })
}

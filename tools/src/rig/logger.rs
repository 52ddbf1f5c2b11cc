//! The raw logger (every datagram and serial read into rotating files: pcap + serial log, or
//! MCAP) and the thread that syncs them to disk twice a second.

use super::shared::LoggerHandle;
use super::{SerialChunk, UdpLogItem};
use heapless::spsc::Consumer;
use spherecal_hal::packet::HostTime;
use spherecal_hal::rawlog::{McapLog, PcapLog, SerialLog};
use spherecal_hal::serial::RxStamp;
use std::net::Ipv4Addr;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The raw logs of a run.
pub(super) enum RawLog {
    /// A pcap of the datagrams and, with a serial INS, a serial log.
    Files {
        pcap: Box<PcapLog>,
        serial: Option<Box<SerialLog>>,
    },
    /// One rosbag2 folder of MCAP files.
    Mcap(Box<McapLog>),
}

impl RawLog {
    /// Log a whole datagram (`Ok(true)`).
    fn datagram(
        &mut self,
        time: HostTime,
        src: (Ipv4Addr, u16),
        dst: (Ipv4Addr, u16),
        payload: &[u8],
    ) -> std::io::Result<bool> {
        match self {
            RawLog::Files { pcap, .. } => pcap.write(time, src, dst, payload),
            RawLog::Mcap(m) => m.write_datagram(time, src, dst, payload),
        }
        .map(|()| true)
    }

    /// Log one IPv4 fragment of a datagram (identification, byte offset, more); `Ok(false)`:
    /// an MCAP log holds whole datagrams only (a board whose sensor sends longer ones logs
    /// pcap: `Board::check`), so the fragment is counted as not logged.
    fn fragment(
        &mut self,
        time: HostTime,
        addrs: (Ipv4Addr, Ipv4Addr),
        f: (u16, usize, bool),
        bytes: &[u8],
    ) -> std::io::Result<bool> {
        match self {
            RawLog::Files { pcap, .. } => pcap.write_fragment(time, addrs, f, bytes).map(|()| true),
            RawLog::Mcap(_) => Ok(false),
        }
    }

    /// Log a serial read; None when there is no serial log.
    fn serial(&mut self, stamp: RxStamp, bytes: &[u8]) -> Option<std::io::Result<()>> {
        match self {
            RawLog::Files { serial, .. } => serial.as_mut().map(|s| s.write(stamp, bytes)),
            RawLog::Mcap(m) => Some(m.write_serial(stamp, bytes)),
        }
    }

    /// To the OS; the handles to sync.
    fn flush(&mut self) -> std::io::Result<Vec<std::fs::File>> {
        match self {
            RawLog::Files { pcap, serial } => {
                let mut v = vec![pcap.flush()?];
                if let Some(s) = serial {
                    v.push(s.flush()?);
                }
                Ok(v)
            }
            RawLog::Mcap(m) => Ok(vec![m.flush()?]),
        }
    }

    /// The end of the run: an MCAP file's summary and footer, and the bag's metadata.yaml.
    fn finish(&mut self) -> std::io::Result<()> {
        match self {
            RawLog::Files { .. } => Ok(()),
            RawLog::Mcap(m) => m.finish(),
        }
    }

    /// What was written: the files (an MCAP log: its bag folder), and the datagrams and
    /// serial reads.
    pub(super) fn written(&self) -> (Vec<PathBuf>, [u64; 2]) {
        match self {
            RawLog::Files { pcap, serial } => {
                let mut files = pcap.files().to_vec();
                let mut n = [pcap.records, 0];
                if let Some(s) = serial {
                    files.extend_from_slice(s.files());
                    n[1] = s.records;
                }
                (files, n)
            }
            RawLog::Mcap(m) => (vec![m.bag().to_path_buf()], [m.datagrams, m.reads]),
        }
    }
}

#[allow(clippy::too_many_arguments)]
pub(super) fn logger(
    log: &mut RawLog,
    [mut data, mut pos, mut posmv]: [Consumer<'_, UdpLogItem>; 3],
    mut ser: Consumer<'_, SerialChunk>,
    dst: Ipv4Addr,
    to_sync: &Mutex<Vec<std::fs::File>>,
    sh: LoggerHandle<'_>,
) {
    let mut synced = Instant::now();
    let mut failed = false;
    let fail = |e: std::io::Error, failed: &mut bool| {
        if !*failed {
            sh.said.error(format!("raw log: {e}; logging stopped"));
            *failed = true;
        }
    };
    loop {
        let done = sh.readers.running.load(Ordering::Acquire) == 0;
        let mut n = 0usize;
        loop {
            // Merge the sockets' datagrams in receive order.
            let times = [data.peek(), pos.peek(), posmv.peek()].map(|p| p.map(|i| i.time));
            let Some(k) = (0..3)
                .filter(|&k| times[k].is_some())
                .min_by_key(|&k| times[k])
            else {
                break;
            };
            let it = match k {
                0 => data.dequeue(),
                1 => pos.dequeue(),
                _ => posmv.dequeue(),
            };
            let Some(it) = it else { break };
            n += 1;
            if failed {
                sh.ring_drops.datagram_log.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            let bytes = &it.bytes[..usize::from(it.len)];
            let r = match it.fragment {
                None => log.datagram(it.time, it.src, (dst, it.dst_port), bytes),
                Some(f) => log.fragment(it.time, (it.src.0, dst), f, bytes),
            };
            match r {
                Ok(true) => {}
                Ok(false) => {
                    sh.ring_drops.datagram_log.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => fail(e, &mut failed),
            }
        }
        while let Some(c) = ser.dequeue() {
            n += 1;
            match (failed, log.serial(c.stamp, &c.bytes[..usize::from(c.len)])) {
                (false, Some(Err(e))) => fail(e, &mut failed),
                (false, Some(Ok(()))) => {}
                _ => {
                    sh.ring_drops.serial_log.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        if synced.elapsed() >= Duration::from_millis(500) || (done && n == 0) {
            synced = Instant::now();
            if !failed {
                // To the OS now; to the disk on the syncer thread.
                let handles = log.flush().unwrap_or_else(|e| {
                    fail(e, &mut failed);
                    Vec::new()
                });
                if done && n == 0 {
                    if let Err(e) = log.finish() {
                        fail(e, &mut failed);
                    }
                    for f in &handles {
                        if let Err(e) = f.sync_data() {
                            fail(e, &mut failed);
                        }
                    }
                } else if let Ok(mut p) = to_sync.lock() {
                    *p = handles;
                }
            }
        }
        if done && n == 0 {
            sh.logger_done.store(true, Ordering::Release);
            return;
        }
        if n == 0 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

/// Makes the logs durable: `fdatasync` on the handles the logger last flushed, every 200 ms,
/// until the readers and the logger are done (the logger syncs its last bytes itself).
pub(super) fn syncer(to_sync: &Mutex<Vec<std::fs::File>>, sh: LoggerHandle<'_>) {
    loop {
        let files = to_sync
            .lock()
            .map(|mut v| std::mem::take(&mut *v))
            .unwrap_or_default();
        for f in &files {
            if let Err(e) = f.sync_data() {
                sh.said.error(format!("raw log sync: {e}"));
            }
        }
        if sh.readers.running.load(Ordering::Acquire) == 0 && sh.logger_done.load(Ordering::Acquire)
        {
            return;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

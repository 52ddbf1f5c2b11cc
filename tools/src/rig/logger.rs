//! The raw logger (every datagram and serial read into rotating files) and the thread that syncs them to disk twice a second.

use super::*;

#[allow(clippy::too_many_arguments)]
pub(super) fn logger(
    pcap: &mut PcapLog,
    mut serial: Option<&mut SerialLog>,
    [mut data, mut pos, mut posmv]: [Consumer<'_, UdpLogItem>; 3],
    mut ser: Consumer<'_, SerialChunk>,
    dst: Ipv4Addr,
    to_sync: &Mutex<Vec<std::fs::File>>,
    sh: &Shared<'_>,
) {
    let mut synced = Instant::now();
    let mut failed = false;
    let fail = |e: std::io::Error, failed: &mut bool| {
        if !*failed {
            sh.error(format!("raw log: {e}; logging stopped"));
            *failed = true;
        }
    };
    loop {
        let done = sh.readers.load(Ordering::Acquire) == 0;
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
            if let Err(e) = pcap.write(
                it.time,
                it.src,
                (dst, it.dst_port),
                &it.bytes[..usize::from(it.len)],
            ) {
                fail(e, &mut failed);
            }
        }
        while let Some(c) = ser.dequeue() {
            n += 1;
            match serial.as_deref_mut() {
                Some(s) if !failed => {
                    if let Err(e) = s.write(c.stamp, &c.bytes[..usize::from(c.len)]) {
                        fail(e, &mut failed);
                    }
                }
                _ => {
                    sh.ring_drops.serial_log.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        if synced.elapsed() >= Duration::from_millis(500) || (done && n == 0) {
            synced = Instant::now();
            if !failed {
                // To the OS now; to the disk on the syncer thread.
                let mut handles = Vec::with_capacity(2);
                match pcap.flush() {
                    Ok(f) => handles.push(f),
                    Err(e) => fail(e, &mut failed),
                }
                if let Some(s) = serial.as_deref_mut() {
                    match s.flush() {
                        Ok(f) => handles.push(f),
                        Err(e) => fail(e, &mut failed),
                    }
                }
                if done && n == 0 {
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
pub(super) fn syncer(to_sync: &Mutex<Vec<std::fs::File>>, sh: &Shared<'_>) {
    loop {
        let files = to_sync
            .lock()
            .map(|mut v| std::mem::take(&mut *v))
            .unwrap_or_default();
        for f in &files {
            if let Err(e) = f.sync_data() {
                sh.error(format!("raw log sync: {e}"));
            }
        }
        if sh.readers.load(Ordering::Acquire) == 0 && sh.logger_done.load(Ordering::Acquire) {
            return;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

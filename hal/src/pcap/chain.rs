//! Several capture files read as one (a rig's rotated logs, `STAMP-lidar-000.pcap`, `-001`
//! ...): ordered by the time of their first datagram, streamed one after the other. Records keep
//! their byte offsets in their own file; errors name the file.

use super::{PcapError, PcapSource};
use crate::packet::{HostTime, PacketSource, Record};
use std::fmt;
use std::io::BufReader;
use std::path::{Path, PathBuf};

/// An error of one file of a chain.
#[derive(Debug)]
pub struct ChainError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub fault: ChainFault,
}

/// What went wrong with a file of a chain.
#[derive(Debug)]
pub enum ChainFault {
    /// Reading it.
    File(PcapError),
    /// It starts before the file read before it ended (two recordings of one time, or one
    /// file under two names): that file, its last datagram's time, and this file's first.
    Overlaps(PathBuf, HostTime, HostTime),
}

impl fmt::Display for ChainError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.fault {
            ChainFault::Overlaps(earlier, last, first) => write!(
                f,
                "{}: its first datagram ({:.6} s) comes before the last of {} ({:.6} s): the captures cover the same time (two recordings of one survey, or one file under two names); give the captures of one recording",
                self.path.display(),
                first.as_secs_f64(),
                earlier.display(),
                last.as_secs_f64()
            ),
            ChainFault::File(e) => write!(f, "{}: {e}", self.path.display()),
        }
    }
}

impl std::error::Error for ChainError {}

impl ChainError {
    fn of(path: &Path, error: PcapError) -> Self {
        Self {
            path: path.to_path_buf(),
            fault: ChainFault::File(error),
        }
    }
}

/// Capture files in time order, as one [`PacketSource`]. Between two files it yields one
/// [`Record::Idle`] (a reader goes on; the borrow of a finished file ends there). A file that
/// starts before the one before it ended is refused ([`ChainFault::Overlaps`]).
pub struct PcapChain {
    files: Vec<PathBuf>,
    /// Each file's first datagram time.
    firsts: Vec<Option<HostTime>>,
    next: usize,
    cur: Option<PcapSource<BufReader<std::fs::File>>>,
    /// The last datagram's time read so far.
    last: Option<HostTime>,
}

/// The time of a capture's first datagram (`None`: it has none).
fn first_time(path: &Path) -> Result<Option<HostTime>, PcapError> {
    let mut src = PcapSource::open(path)?;
    while let Some(r) = src.next_record()? {
        if let Record::Udp(d) = r {
            return Ok(Some(d.time));
        }
    }
    Ok(None)
}

impl PcapChain {
    /// `paths` in the order of their first datagram's time (files without one last, ties in
    /// the order given); each is opened now to check it.
    pub fn open(paths: &[PathBuf]) -> Result<Self, ChainError> {
        let mut timed = Vec::with_capacity(paths.len());
        for (i, p) in paths.iter().enumerate() {
            let t = first_time(p).map_err(|error| ChainError::of(p, error))?;
            timed.push((t.map_or(i64::MAX, |t| t.0), i, p.clone(), t));
        }
        timed.sort_by_key(|(t, i, _, _)| (*t, *i));
        Ok(Self {
            firsts: timed.iter().map(|(_, _, _, t)| *t).collect(),
            files: timed.into_iter().map(|(_, _, p, _)| p).collect(),
            next: 0,
            cur: None,
            last: None,
        })
    }

    /// The files, in the order they are read.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// The file being read.
    pub fn current(&self) -> Option<&Path> {
        self.next
            .checked_sub(1)
            .and_then(|i| self.files.get(i))
            .map(PathBuf::as_path)
    }
}

impl PacketSource for PcapChain {
    type Error = ChainError;

    fn next_record(&mut self) -> Result<Option<Record<'_>>, ChainError> {
        if self.cur.as_ref().is_some_and(|c| c.finished()) {
            self.cur = None;
        }
        if self.cur.is_none() {
            let Some(path) = self.files.get(self.next) else {
                return Ok(None);
            };
            if let (Some(last), Some(Some(first)), Some(prev)) = (
                self.last,
                self.firsts.get(self.next),
                self.next.checked_sub(1).and_then(|i| self.files.get(i)),
            ) {
                if first.0 < last.0 {
                    return Err(ChainError {
                        path: path.clone(),
                        fault: ChainFault::Overlaps(prev.clone(), last, *first),
                    });
                }
            }
            let src = PcapSource::open(path).map_err(|error| ChainError::of(path, error))?;
            self.cur = Some(src);
            self.next += 1;
        }
        let path = &self.files[self.next - 1];
        let Some(src) = self.cur.as_mut() else {
            return Ok(None);
        };
        let r = src
            .next_record()
            .map_err(|error| ChainError::of(path, error))?;
        if let Some(Record::Udp(d)) = &r {
            self.last = Some(d.time);
        }
        // At a file's end: the next call opens the next file.
        Ok(Some(r.unwrap_or(Record::Idle)))
    }
}

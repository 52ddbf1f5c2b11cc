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
    pub error: PcapError,
}

impl fmt::Display for ChainError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.error)
    }
}

impl std::error::Error for ChainError {}

/// Capture files in time order, as one [`PacketSource`]. Between two files it yields one
/// [`Record::Idle`] (a reader goes on; the borrow of a finished file ends there).
pub struct PcapChain {
    files: Vec<PathBuf>,
    next: usize,
    cur: Option<PcapSource<BufReader<std::fs::File>>>,
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
            let t = first_time(p).map_err(|error| ChainError {
                path: p.clone(),
                error,
            })?;
            timed.push((t.map_or(i64::MAX, |t| t.0), i, p.clone()));
        }
        timed.sort();
        Ok(Self {
            files: timed.into_iter().map(|(_, _, p)| p).collect(),
            next: 0,
            cur: None,
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
            let src = PcapSource::open(path).map_err(|error| ChainError {
                path: path.clone(),
                error,
            })?;
            self.cur = Some(src);
            self.next += 1;
        }
        let path = &self.files[self.next - 1];
        let Some(src) = self.cur.as_mut() else {
            return Ok(None);
        };
        let r = src.next_record().map_err(|error| ChainError {
            path: path.clone(),
            error,
        })?;
        // At a file's end: the next call opens the next file.
        Ok(Some(r.unwrap_or(Record::Idle)))
    }
}

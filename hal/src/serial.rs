//! Byte streams: the VN-200's serial line, raw byte files, and our timestamped serial log.
//!
//! Serial log format (`.vnlog`, all little-endian), so that a replay has the original timing:
//!
//! ```text
//! file header, 16 bytes: magic "SCSERLOG", u32 version = 1, u32 baud rate (0 = unknown)
//! record:                u64 monotonic receive time [ns since the logging process started]
//!                        i64 wall-clock receive time [ns since 1970-01-01 UTC]
//!                        u32 n, then n bytes as read from the port
//! ```
//! A file that does not start with the magic is a plain raw byte file.

use crate::clock::{monotonic_ns, wall, HostTime};
use std::io::{self, Read, Write};
use std::time::Duration;

/// Magic at the start of a serial log.
pub const LOG_MAGIC: &[u8; 8] = b"SCSERLOG";
/// Log format version.
pub const LOG_VERSION: u32 = 1;
/// Bytes of a record header.
pub const RECORD_HEADER: usize = 20;
/// Largest record a reader accepts (a corrupt length field beyond it is an error).
pub const MAX_RECORD: usize = 1 << 20;

/// When a chunk of bytes arrived, on the host's two clocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RxStamp {
    /// Monotonic nanoseconds since this process's clock base (see [`monotonic_ns`]).
    pub mono_ns: u64,
    /// The wall clock.
    pub wall: HostTime,
}

impl RxStamp {
    /// Now.
    pub fn now() -> Self {
        Self {
            mono_ns: monotonic_ns(),
            wall: wall(),
        }
    }
}

/// What one read gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadOutcome {
    /// `len` bytes, received at `stamp` (None for a raw file, which has no times).
    Data {
        /// Bytes written to the caller's buffer.
        len: usize,
        /// Receive time.
        stamp: Option<RxStamp>,
    },
    /// Nothing arrived within the read timeout (live sources only).
    Idle,
    /// The stream has ended.
    End,
}

/// A source of bytes with receive times: a serial port, a raw file, a serial log.
pub trait ByteSource {
    /// What stops the source for good.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Read what is available into `buf`.
    fn read_chunk(&mut self, buf: &mut [u8]) -> Result<ReadOutcome, Self::Error>;
}

/// A serial port (the VN-200), each read stamped with the host's receive time.
pub struct SerialSource {
    port: Box<dyn serialport::SerialPort>,
}

impl SerialSource {
    /// Open `path` at `baud`, 8N1, no flow control, with a short read timeout so that a reader
    /// thread can notice shutdown.
    pub fn open(path: &str, baud: u32, timeout: Duration) -> Result<Self, serialport::Error> {
        let port = serialport::new(path, baud).timeout(timeout).open()?;
        Ok(Self { port })
    }

    /// Discard what waits in the port's input buffer (bytes from before this program opened
    /// it: an earlier session's stream); how many.
    pub fn discard_pending(&mut self) -> Result<u32, serialport::Error> {
        let n = self.port.bytes_to_read()?;
        self.port.clear(serialport::ClearBuffer::Input)?;
        Ok(n)
    }

    /// Wrap a port opened elsewhere (a pseudo-terminal in tests).
    pub fn from_port(port: Box<dyn serialport::SerialPort>) -> Self {
        Self { port }
    }

    /// The port, to write to the device (its configuration) before reading.
    pub fn port_mut(&mut self) -> &mut Box<dyn serialport::SerialPort> {
        &mut self.port
    }
}

impl ByteSource for SerialSource {
    type Error = io::Error;
    fn read_chunk(&mut self, buf: &mut [u8]) -> Result<ReadOutcome, io::Error> {
        match self.port.read(buf) {
            Ok(0) => Ok(ReadOutcome::End),
            Ok(len) => Ok(ReadOutcome::Data {
                len,
                stamp: Some(RxStamp::now()),
            }),
            Err(e)
                if e.kind() == io::ErrorKind::TimedOut || e.kind() == io::ErrorKind::WouldBlock =>
            {
                Ok(ReadOutcome::Idle)
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(ReadOutcome::Idle),
            Err(e) => Err(e),
        }
    }
}

/// A plain file (or any reader) of raw bytes: no receive times.
pub struct RawSource<R: Read> {
    inner: R,
}

impl<R: Read> RawSource<R> {
    /// Wrap a reader.
    pub fn new(inner: R) -> Self {
        Self { inner }
    }
}

impl<R: Read> ByteSource for RawSource<R> {
    type Error = io::Error;
    fn read_chunk(&mut self, buf: &mut [u8]) -> Result<ReadOutcome, io::Error> {
        loop {
            match self.inner.read(buf) {
                Ok(0) => return Ok(ReadOutcome::End),
                Ok(len) => return Ok(ReadOutcome::Data { len, stamp: None }),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }
}

/// Writes a serial log: header once, then one record per chunk.
pub struct LogWriter<W: Write> {
    inner: W,
}

impl<W: Write> LogWriter<W> {
    /// Write the file header.
    pub fn new(mut inner: W, baud: u32) -> io::Result<Self> {
        inner.write_all(LOG_MAGIC)?;
        inner.write_all(&LOG_VERSION.to_le_bytes())?;
        inner.write_all(&baud.to_le_bytes())?;
        Ok(Self { inner })
    }

    /// Append one record.
    pub fn record(&mut self, stamp: RxStamp, bytes: &[u8]) -> io::Result<()> {
        let mut head = [0u8; RECORD_HEADER];
        head[..8].copy_from_slice(&stamp.mono_ns.to_le_bytes());
        head[8..16].copy_from_slice(&stamp.wall.0.to_le_bytes());
        head[16..20].copy_from_slice(&(bytes.len() as u32).to_le_bytes());
        self.inner.write_all(&head)?;
        self.inner.write_all(bytes)
    }

    /// Flush to the OS.
    pub fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }

    /// The underlying writer, to flush it.
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.inner
    }

    /// The underlying writer.
    pub fn into_inner(self) -> W {
        self.inner
    }
}

/// Why a serial log cannot be read further.
#[derive(Debug)]
pub enum LogError {
    /// Read error.
    Io(io::Error),
    /// Not a log (no magic) or an unknown version.
    BadHeader(String),
    /// A record whose length field is impossible.
    Corrupt {
        /// Byte offset of the record.
        offset: u64,
        /// What was wrong.
        what: String,
    },
}

impl std::fmt::Display for LogError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LogError::Io(e) => write!(f, "read error: {e}"),
            LogError::BadHeader(s) => write!(f, "offset 0: {s}"),
            LogError::Corrupt { offset, what } => write!(f, "offset {offset}: {what}"),
        }
    }
}

impl std::error::Error for LogError {}

impl From<io::Error> for LogError {
    fn from(e: io::Error) -> Self {
        LogError::Io(e)
    }
}

/// Reads a serial log record by record.
pub struct LogReader<R: Read> {
    inner: R,
    offset: u64,
    /// Baud rate from the header (0 = unknown).
    pub baud: u32,
    /// Set when the file ended inside a record (a power cut): bytes of the partial record.
    pub truncated_tail: Option<(u64, usize)>,
    done: bool,
}

fn read_full<R: Read>(r: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

impl<R: Read> LogReader<R> {
    /// Read and check the file header.
    pub fn new(mut inner: R) -> Result<Self, LogError> {
        let mut head = [0u8; 16];
        let n = read_full(&mut inner, &mut head)?;
        if n < 16 || &head[..8] != LOG_MAGIC {
            return Err(LogError::BadHeader(
                "not a spherecal serial log (magic SCSERLOG)".into(),
            ));
        }
        let version = u32::from_le_bytes([head[8], head[9], head[10], head[11]]);
        if version != LOG_VERSION {
            return Err(LogError::BadHeader(format!(
                "serial log version {version}, expected {LOG_VERSION}"
            )));
        }
        let baud = u32::from_le_bytes([head[12], head[13], head[14], head[15]]);
        Ok(Self {
            inner,
            offset: 16,
            baud,
            truncated_tail: None,
            done: false,
        })
    }

    /// The next record into `buf` (cleared first): its stamp, or `None` at the end. A record cut
    /// short by the end of the file ends the log and is noted in `truncated_tail`.
    pub fn next_record(&mut self, buf: &mut Vec<u8>) -> Result<Option<RxStamp>, LogError> {
        buf.clear();
        if self.done {
            return Ok(None);
        }
        let mut head = [0u8; RECORD_HEADER];
        let n = read_full(&mut self.inner, &mut head)?;
        if n == 0 {
            self.done = true;
            return Ok(None);
        }
        if n < RECORD_HEADER {
            self.done = true;
            self.truncated_tail = Some((self.offset, n));
            return Ok(None);
        }
        let le8 = |a: &[u8]| -> [u8; 8] { [a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7]] };
        let stamp = RxStamp {
            mono_ns: u64::from_le_bytes(le8(&head[..8])),
            wall: HostTime(i64::from_le_bytes(le8(&head[8..16]))),
        };
        let len = u32::from_le_bytes([head[16], head[17], head[18], head[19]]) as usize;
        if len > MAX_RECORD {
            self.done = true;
            return Err(LogError::Corrupt {
                offset: self.offset,
                what: format!("record claims {len} bytes"),
            });
        }
        buf.resize(len, 0);
        let got = read_full(&mut self.inner, buf)?;
        if got < len {
            self.done = true;
            self.truncated_tail = Some((self.offset, RECORD_HEADER + got));
            buf.truncate(got);
            return Ok(if got > 0 { Some(stamp) } else { None });
        }
        self.offset += (RECORD_HEADER + len) as u64;
        Ok(Some(stamp))
    }
}

/// A VN-200 byte file as a [`ByteSource`]: a serial log's records with their receive stamps
/// (a record cut by a power cut ends the stream, as [`LogReader`] reads it), or a raw file's
/// bytes without stamps.
pub enum FileSource {
    /// Raw bytes.
    Raw(RawSource<io::BufReader<std::fs::File>>),
    /// A serial log, and what is left of the record being handed out.
    Log {
        /// The log.
        reader: LogReader<io::BufReader<std::fs::File>>,
        /// The current record's bytes.
        record: Vec<u8>,
        /// How many of them were handed out.
        at: usize,
        /// Its stamp.
        stamp: RxStamp,
    },
}

impl FileSource {
    /// Open `path`, a serial log if it starts with the magic, else raw bytes.
    pub fn open(path: &std::path::Path) -> Result<Self, LogError> {
        let mut f = std::fs::File::open(path)?;
        let mut magic = [0u8; 8];
        let n = read_full(&mut f, &mut magic)?;
        io::Seek::rewind(&mut f)?;
        let f = io::BufReader::with_capacity(1 << 16, f);
        if n == 8 && &magic == LOG_MAGIC {
            Ok(Self::Log {
                reader: LogReader::new(f)?,
                record: Vec::new(),
                at: 0,
                stamp: RxStamp::default(),
            })
        } else {
            Ok(Self::Raw(RawSource::new(f)))
        }
    }
}

/// An error of one file of a [`FileChain`].
#[derive(Debug)]
pub struct FileChainError {
    /// The file.
    pub path: std::path::PathBuf,
    /// What went wrong.
    pub error: LogError,
}

impl std::fmt::Display for FileChainError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.error)
    }
}

impl std::error::Error for FileChainError {}

/// Several VN-200 byte files (a rig's rotated serial logs, `STAMP-ins-000.vnlog`, `-001` ...)
/// as one stream, in the order given (the rig's numbering); each file a [`FileSource`].
pub struct FileChain {
    files: Vec<std::path::PathBuf>,
    next: usize,
    cur: Option<FileSource>,
}

impl FileChain {
    /// The files; the first is opened now (to fail early).
    pub fn open(files: Vec<std::path::PathBuf>) -> Result<Self, FileChainError> {
        let mut c = Self {
            files,
            next: 0,
            cur: None,
        };
        c.open_next()?;
        Ok(c)
    }

    fn open_next(&mut self) -> Result<bool, FileChainError> {
        let Some(path) = self.files.get(self.next) else {
            return Ok(false);
        };
        self.cur = Some(FileSource::open(path).map_err(|error| FileChainError {
            path: path.clone(),
            error,
        })?);
        self.next += 1;
        Ok(true)
    }
}

impl ByteSource for FileChain {
    type Error = FileChainError;
    fn read_chunk(&mut self, buf: &mut [u8]) -> Result<ReadOutcome, FileChainError> {
        loop {
            if self.cur.is_none() && !self.open_next()? {
                return Ok(ReadOutcome::End);
            }
            let path = &self.files[self.next - 1];
            let Some(src) = self.cur.as_mut() else {
                return Ok(ReadOutcome::End);
            };
            match src.read_chunk(buf).map_err(|error| FileChainError {
                path: path.clone(),
                error,
            })? {
                ReadOutcome::End => self.cur = None,
                other => return Ok(other),
            }
        }
    }
}

impl ByteSource for FileSource {
    type Error = LogError;
    fn read_chunk(&mut self, buf: &mut [u8]) -> Result<ReadOutcome, LogError> {
        match self {
            Self::Raw(r) => Ok(r.read_chunk(buf)?),
            Self::Log {
                reader,
                record,
                at,
                stamp,
            } => {
                while *at >= record.len() {
                    match reader.next_record(record)? {
                        Some(s) => {
                            *stamp = s;
                            *at = 0;
                        }
                        None => return Ok(ReadOutcome::End),
                    }
                }
                let n = (record.len() - *at).min(buf.len());
                buf[..n].copy_from_slice(&record[*at..*at + n]);
                *at += n;
                Ok(ReadOutcome::Data {
                    len: n,
                    stamp: Some(*stamp),
                })
            }
        }
    }
}

/// A byte stream and, for a serial log, where each record begins in it and when it arrived.
pub type ByteStream = (Vec<u8>, Option<Vec<(u64, RxStamp)>>);

/// The byte stream a file holds: a serial log's record bytes concatenated, or the raw bytes.
/// Returns the bytes and, for a log, the receive stamps with the stream offset where each
/// record begins.
pub fn read_byte_file(path: &std::path::Path) -> Result<ByteStream, LogError> {
    let all = std::fs::read(path)?;
    if all.len() < 8 || &all[..8] != LOG_MAGIC {
        return Ok((all, None));
    }
    let mut r = LogReader::new(&all[..])?;
    let mut bytes = Vec::with_capacity(all.len());
    let mut stamps = Vec::new();
    let mut rec = Vec::new();
    while let Some(stamp) = r.next_record(&mut rec)? {
        stamps.push((bytes.len() as u64, stamp));
        bytes.extend_from_slice(&rec);
    }
    Ok((bytes, Some(stamps)))
}

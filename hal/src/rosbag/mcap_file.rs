//! One MCAP file, read front to back with the `mcap` crate's sans-io reader (chunks
//! decompressed as they come, zstd or lz4; CRCs checked): the schemas and channels as they
//! appear, the messages of the wanted topics. A file cut short (a recorder killed, a disk
//! full) gives the messages of its whole records and chunks before the cut, and says where it
//! ends ([`Reader::truncated`]); a damaged one is an error naming the byte.

use super::{BagError, Message, Topic};
use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader};
use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};

/// The reader, over a file (or any bytes: [`messages_in`]).
pub(super) struct Reader<R: Read = std::fs::File> {
    path: PathBuf,
    file: R,
    rd: LinearReader,
    /// Bytes handed to the reader so far.
    read: u64,
    /// The bytes have ended (a read gave none).
    at_end: bool,
    /// Schema id -> its name (the ROS type).
    schemas: HashMap<u16, String>,
    /// Channel id -> its topic's index in `topics`.
    channels: HashMap<u16, usize>,
    topics: Vec<Topic>,
    want: Option<Vec<String>>,
    /// The current message: topic index, log time, bytes, offset.
    cur: Option<(usize, i64, u64)>,
    data: Vec<u8>,
    /// The bytes ended inside a record at this byte (the file cut short).
    pub(super) truncated: Option<u64>,
}

impl Reader {
    /// Open `path`; only the topics in `want` are returned (all when None).
    pub(super) fn open(path: &Path, want: Option<&[String]>) -> Result<Self, BagError> {
        let file = std::fs::File::open(path).map_err(|e| BagError::io(path, e))?;
        let len = file.metadata().map_err(|e| BagError::io(path, e))?.len();
        Ok(Reader::over(path, file, len, want))
    }
}

/// Every message of MCAP `bytes`, each shown to `each` (topic, type, log time, data), until the
/// end or the first error (the fuzz target's entry: any bytes, never a panic).
pub fn messages_in(
    bytes: &[u8],
    mut each: impl FnMut(&str, &str, i64, &[u8]),
) -> Result<u64, BagError> {
    let mut r = Reader::over(Path::new("<bytes>"), bytes, bytes.len() as u64, None);
    let mut n = 0;
    while let Some(m) = r.next()? {
        each(&m.topic.name, &m.topic.type_name, m.log_time_ns, m.data);
        n += 1;
    }
    Ok(n)
}

/// The longest record (or decompressed chunk) a file of `len` bytes is let hold: 16 times
/// the file (at least 1 MiB), at most 512 MiB. A damaged length field is then an error, not
/// an allocation of terabytes (found by the fuzz target `rosbag_mcap`); rosbag2 writes chunks
/// of a few MB.
fn record_limit(len: u64) -> usize {
    (len.max(1 << 20).saturating_mul(16)).min(512 << 20) as usize
}

impl<R: Read> Reader<R> {
    fn over(path: &Path, file: R, len: u64, want: Option<&[String]>) -> Self {
        use mcap::sans_io::linear_reader::LinearReaderOptions;
        Self {
            path: path.to_path_buf(),
            file,
            rd: LinearReader::new_with_options(
                LinearReaderOptions::default().with_record_length_limit(record_limit(len)),
            ),
            read: 0,
            at_end: false,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            topics: Vec::new(),
            want: want.map(<[String]>::to_vec),
            cur: None,
            data: Vec::new(),
            truncated: None,
        }
    }

    /// The topics seen so far.
    pub(super) fn topics(&self) -> &[Topic] {
        &self.topics
    }

    fn err(&self, what: impl std::fmt::Display) -> BagError {
        BagError::new(&self.path, what.to_string())
    }

    /// Move to the next wanted message; false at the file's end.
    pub(super) fn advance(&mut self) -> Result<bool, BagError> {
        self.cur = None;
        loop {
            let event = match self.rd.next_event() {
                None => return Ok(false),
                Some(Ok(e)) => e,
                // The bytes ended inside a record: the file was cut short. What came before
                // its cut is whole (each chunk's CRC was checked): the end, said.
                Some(Err(_)) if self.at_end => {
                    self.truncated = Some(self.read);
                    return Ok(false);
                }
                Some(Err(e)) => {
                    let at = self.read;
                    return Err(self.err(format_args!(
                        "not a complete MCAP file: {e} (after byte {at}: not written to the end, or damaged)"
                    )));
                }
            };
            match event {
                LinearReadEvent::ReadRequest(n) => {
                    // `n` is a hint, as large as a damaged length says (fuzz target
                    // `rosbag_mcap`: 2.3 GB asked of a 1 kB file): read at most 1 MiB at a time.
                    let got = match self.file.read(self.rd.insert(n.clamp(1, 1 << 20))) {
                        Ok(k) => k,
                        Err(e) => return Err(BagError::io(&self.path, e)),
                    };
                    if got == 0 {
                        // The end of the bytes; a reader that asks again past it would spin
                        // (fuzz target `rosbag_mcap`: a damaged chunk did): it ends here, cut
                        // short inside a record.
                        if self.at_end {
                            self.truncated = Some(self.read);
                            return Ok(false);
                        }
                        self.at_end = true;
                    }
                    self.rd.notify_read(got);
                    self.read += got as u64;
                }
                LinearReadEvent::Record { opcode, data } => {
                    // Only the records read here are parsed: mcap 0.26's parser of the others
                    // can panic on a damaged one (an attachment shorter than its CRC: fuzz
                    // target `rosbag_mcap`), and they are not needed.
                    use mcap::records::op;
                    if ![op::SCHEMA, op::CHANNEL, op::MESSAGE].contains(&opcode) {
                        continue;
                    }
                    let rec = match mcap::parse_record(opcode, data) {
                        Ok(r) => r,
                        Err(e) => {
                            let at = self.read;
                            return Err(BagError::new(
                                &self.path,
                                format!("a malformed MCAP record (opcode 0x{opcode:02x}) before byte {at}: {e}"),
                            ));
                        }
                    };
                    match rec {
                        Record::Schema { header, .. } => {
                            self.schemas.insert(header.id, header.name);
                        }
                        Record::Channel(c) => {
                            let type_name =
                                self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                            let i = match self.topics.iter().position(|t| t.name == c.topic) {
                                Some(i) => i,
                                None => {
                                    self.topics.push(Topic {
                                        name: c.topic,
                                        type_name,
                                        encoding: c.message_encoding,
                                    });
                                    self.topics.len() - 1
                                }
                            };
                            self.channels.insert(c.id, i);
                        }
                        Record::Message { header, data } => {
                            let Some(&i) = self.channels.get(&header.channel_id) else {
                                continue;
                            };
                            let wanted = self
                                .want
                                .as_ref()
                                .is_none_or(|w| w.contains(&self.topics[i].name));
                            if wanted {
                                self.data.clear();
                                self.data.extend_from_slice(&data);
                                let t = i64::try_from(header.log_time).unwrap_or(i64::MAX);
                                self.cur = Some((i, t, self.read));
                                return Ok(true);
                            }
                        }
                        _ => {}
                    }
                }
            }
        }
    }

    /// The current message.
    pub(super) fn current(&self) -> Option<Message<'_>> {
        let (i, t, at) = self.cur?;
        Some(Message {
            topic: &self.topics[i],
            log_time_ns: t,
            data: &self.data,
            file: &self.path,
            at,
        })
    }

    /// `advance` then `current`.
    pub(super) fn next(&mut self) -> Result<Option<Message<'_>>, BagError> {
        Ok(if self.advance()? {
            self.current()
        } else {
            None
        })
    }
}

/// The topics of a complete MCAP file from its summary section (channels, schemas and
/// per-channel counts, without reading the messages); `None` when it has none (a recording
/// not closed, a writer that writes no summary).
pub(super) fn summary_topics(path: &Path) -> Result<Option<Vec<super::TopicStats>>, BagError> {
    use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader};
    use std::io::Seek as _;
    let mut file = std::fs::File::open(path).map_err(|e| BagError::io(path, e))?;
    let mut rd = SummaryReader::new();
    while let Some(ev) = rd.next_event() {
        let Ok(ev) = ev else {
            return Ok(None);
        };
        match ev {
            SummaryReadEvent::ReadRequest(n) => {
                let got = file.read(rd.insert(n)).map_err(|e| BagError::io(path, e))?;
                rd.notify_read(got);
            }
            // A file shorter than its footer (cut short) has no summary to seek to.
            SummaryReadEvent::SeekRequest(to) => {
                let Ok(at) = file.seek(to) else {
                    return Ok(None);
                };
                rd.notify_seeked(at);
            }
        }
    }
    let Some(s) = rd.finish() else {
        return Ok(None);
    };
    let Some(stats) = s.stats else {
        return Ok(None);
    };
    // The file's span (its statistics give it for all channels together).
    let span = (stats.message_end_time >= stats.message_start_time && stats.message_count > 0)
        .then(|| {
            (
                i64::try_from(stats.message_start_time).unwrap_or(i64::MAX),
                i64::try_from(stats.message_end_time).unwrap_or(i64::MAX),
            )
        });
    let mut ids: Vec<&u16> = s.channels.keys().collect();
    ids.sort();
    let mut out: Vec<super::TopicStats> = Vec::new();
    for id in ids {
        let c = &s.channels[id];
        let count = stats.channel_message_counts.get(id).copied().unwrap_or(0);
        let topic = Topic {
            name: c.topic.clone(),
            type_name: c
                .schema
                .as_ref()
                .map(|s| s.name.clone())
                .unwrap_or_default(),
            encoding: c.message_encoding.clone(),
        };
        match out.iter_mut().find(|t| t.topic.name == topic.name) {
            Some(t) => t.count += count,
            None => out.push(super::TopicStats { topic, count, span }),
        }
    }
    Ok(Some(out))
}

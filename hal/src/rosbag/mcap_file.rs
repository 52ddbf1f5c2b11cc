//! One MCAP file, read front to back with the `mcap` crate's sans-io reader (chunks
//! decompressed as they come, zstd or lz4; CRCs checked): the schemas and channels as they
//! appear, the messages of the wanted topics. A file cut short is an error naming the byte
//! where it ends.

use super::{BagError, Message, Topic};
use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader};
use std::collections::HashMap;
use std::io::Read as _;
use std::path::{Path, PathBuf};

/// The reader.
pub(super) struct Reader {
    path: PathBuf,
    file: std::fs::File,
    rd: LinearReader,
    /// Bytes handed to the reader so far.
    read: u64,
    /// Schema id -> its name (the ROS type).
    schemas: HashMap<u16, String>,
    /// Channel id -> its topic's index in `topics`.
    channels: HashMap<u16, usize>,
    topics: Vec<Topic>,
    want: Option<Vec<String>>,
    /// The current message: topic index, log time, bytes, offset.
    cur: Option<(usize, i64, u64)>,
    data: Vec<u8>,
}

impl Reader {
    /// Open `path`; only the topics in `want` are returned (all when None).
    pub(super) fn open(path: &Path, want: Option<&[String]>) -> Result<Self, BagError> {
        let file = std::fs::File::open(path).map_err(|e| BagError::io(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            file,
            rd: LinearReader::new(),
            read: 0,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            topics: Vec::new(),
            want: want.map(<[String]>::to_vec),
            cur: None,
            data: Vec::new(),
        })
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
                Some(Err(e)) => {
                    let at = self.read;
                    return Err(self.err(format_args!(
                        "not a complete MCAP file: {e} (after byte {at}: cut short, or not written to the end)"
                    )));
                }
            };
            match event {
                LinearReadEvent::ReadRequest(n) => {
                    let got = match self.file.read(self.rd.insert(n)) {
                        Ok(k) => k,
                        Err(e) => return Err(BagError::io(&self.path, e)),
                    };
                    self.rd.notify_read(got);
                    self.read += got as u64;
                }
                LinearReadEvent::Record { opcode, data } => {
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
            SummaryReadEvent::SeekRequest(to) => {
                let at = file.seek(to).map_err(|e| BagError::io(path, e))?;
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
            None => out.push(super::TopicStats {
                topic,
                count,
                span: None,
            }),
        }
    }
    Ok(Some(out))
}

//! rosbag2 recordings: a bag folder (its `metadata.yaml` names the storage and the files, split
//! bags in order), a single `.mcap` or a single `.db3`, read message by message with each
//! message's topic, type, log time and CDR bytes ([`Messages`]). Storage only: what the
//! messages mean is the core's `ros2` views; [`sources`] turns them into the packet and byte
//! sources the pipeline reads (DESIGN.md "ROS 2 bags").
//!
//! rosbag2 writes sqlite3 by default on Humble and MCAP from Iron on; MCAP chunks may be
//! zstd- or lz4-compressed. A bag compressed as a whole by rosbag2 (`compression_mode: FILE`
//! or `MESSAGE`) is refused with how to decompress it.

pub mod clouds;
mod mcap_file;
mod metadata;
pub mod nav;
pub mod sources;
#[cfg(feature = "sqlite")]
mod sqlite_file;
#[cfg(not(feature = "sqlite"))]
#[path = "no_sqlite.rs"]
mod sqlite_file;

pub use mcap_file::messages_in as mcap_messages_in;

pub use metadata::Metadata;

use std::fmt;
use std::path::{Path, PathBuf};

/// How a bag file stores its messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Storage {
    /// MCAP (`.mcap`).
    Mcap,
    /// SQLite 3 (`.db3`).
    Sqlite3,
}

impl Storage {
    /// rosbag2's storage identifier.
    pub fn name(self) -> &'static str {
        match self {
            Storage::Mcap => "mcap",
            Storage::Sqlite3 => "sqlite3",
        }
    }

    /// What a file's first bytes say it is.
    fn sniff(path: &Path) -> Result<Option<Self>, BagError> {
        use std::io::Read as _;
        let mut head = [0u8; 16];
        let mut f = std::fs::File::open(path).map_err(|e| BagError::io(path, e))?;
        let mut n = 0;
        while n < head.len() {
            match f.read(&mut head[n..]) {
                Ok(0) => break,
                Ok(k) => n += k,
                Err(e) => return Err(BagError::io(path, e)),
            }
        }
        Ok(if head[..n].starts_with(b"\x89MCAP0\r\n") {
            Some(Storage::Mcap)
        } else if head[..n].starts_with(b"SQLite format 3\0") {
            Some(Storage::Sqlite3)
        } else {
            None
        })
    }
}

/// A bag that cannot be read: the file and what went wrong.
#[derive(Debug)]
pub struct BagError {
    /// The file (or folder).
    pub path: PathBuf,
    /// What went wrong, for people.
    pub what: String,
}

impl BagError {
    fn new(path: &Path, what: impl Into<String>) -> Self {
        Self {
            path: path.to_path_buf(),
            what: what.into(),
        }
    }

    fn io(path: &Path, e: std::io::Error) -> Self {
        Self::new(path, e.to_string())
    }
}

impl fmt::Display for BagError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.what)
    }
}

impl std::error::Error for BagError {}

/// A topic of a bag: its name, message type and serialisation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topic {
    /// e.g. `/velodyne_packets`.
    pub name: String,
    /// e.g. `velodyne_msgs/msg/VelodyneScan`.
    pub type_name: String,
    /// `cdr` for every ROS 2 middleware.
    pub encoding: String,
}

/// A topic with what the bag holds of it.
#[derive(Debug, Clone, PartialEq)]
pub struct TopicStats {
    /// The topic.
    pub topic: Topic,
    /// Messages.
    pub count: u64,
    /// First and last log time [ns since the Unix epoch] (None: no message).
    pub span: Option<(i64, i64)>,
}

/// A message: its topic, log time and serialised bytes, and where it is.
#[derive(Debug, Clone, Copy)]
pub struct Message<'a> {
    /// Its topic.
    pub topic: &'a Topic,
    /// When the recorder received it [ns since the Unix epoch].
    pub log_time_ns: i64,
    /// The CDR bytes.
    pub data: &'a [u8],
    /// The file it is in.
    pub file: &'a Path,
    /// Where: the byte offset of its record (MCAP: of the chunk holding it) or its row id
    /// (sqlite3).
    pub at: u64,
}

/// A bag, opened: its files in order.
#[derive(Debug, Clone)]
pub struct Bag {
    /// What was named.
    pub path: PathBuf,
    /// The files in the order they were recorded, with their storage.
    pub files: Vec<(PathBuf, Storage)>,
    /// The folder's metadata.yaml, if there is one.
    pub metadata: Option<Metadata>,
}

/// Whether `path` names a bag: a `.mcap` or `.db3` file, or a folder with a `metadata.yaml`
/// or such files.
pub fn is_bag(path: &Path) -> bool {
    let suffix = |p: &Path| matches!(p.extension().and_then(|e| e.to_str()), Some("mcap" | "db3"));
    if path.is_dir() {
        path.join("metadata.yaml").is_file()
            || std::fs::read_dir(path).is_ok_and(|d| {
                d.filter_map(Result::ok)
                    .any(|e| suffix(&e.path()) && e.path().is_file())
            })
    } else {
        suffix(path)
    }
}

/// The files of one recording split by the recorder follow one another: the next starts within
/// this of where the one before ended [ns].
pub const SPLIT_GAP_NS: i64 = 10_000_000_000;

impl Bag {
    /// Open what `path` names: a bag folder (the files its metadata.yaml lists, else its
    /// `.mcap` / `.db3` files by name), or one file (its storage from its first bytes).
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let mut metadata = None;
        let names: Vec<PathBuf> = if path.is_dir() {
            let meta = path.join("metadata.yaml");
            if meta.is_file() {
                let text = std::fs::read_to_string(&meta).map_err(|e| BagError::io(&meta, e))?;
                let m = Metadata::parse(&text).map_err(|w| BagError::new(&meta, w))?;
                if let Some(mode) = m.compression_mode.as_deref().filter(|c| !c.is_empty()) {
                    return Err(BagError::new(
                        path,
                        format!(
                            "compressed by rosbag2 as a whole ({mode}, {}): decompress it first (`ros2 bag decompress`, or `zstd -d` on each file and the metadata's paths without .zstd)",
                            m.compression_format.as_deref().unwrap_or("?")
                        ),
                    ));
                }
                let files: Vec<PathBuf> =
                    m.relative_file_paths.iter().map(|f| path.join(f)).collect();
                metadata = Some(m);
                files
            } else {
                let mut v: Vec<PathBuf> = std::fs::read_dir(path)
                    .map_err(|e| BagError::io(path, e))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| {
                        p.is_file()
                            && matches!(
                                p.extension().and_then(|e| e.to_str()),
                                Some("mcap" | "db3")
                            )
                    })
                    .collect();
                v.sort();
                v
            }
        } else {
            vec![path.to_path_buf()]
        };
        if names.is_empty() {
            return Err(BagError::new(
                path,
                "no bag file in it (no metadata.yaml, no .mcap or .db3 file)",
            ));
        }
        let mut files = Vec::with_capacity(names.len());
        for f in names {
            if !f.is_file() {
                return Err(BagError::new(
                    &f,
                    "listed in the bag's metadata.yaml but not there",
                ));
            }
            let Some(s) = Storage::sniff(&f)? else {
                let zstd = f.extension().is_some_and(|e| e == "zstd");
                return Err(BagError::new(
                    &f,
                    if zstd {
                        "compressed by rosbag2 as a whole: decompress it first (`zstd -d`)"
                    } else {
                        "neither MCAP nor SQLite 3: not a rosbag2 file"
                    },
                ));
            };
            files.push((f, s));
        }
        let bag = Self {
            path: path.to_path_buf(),
            files,
            metadata,
        };
        if bag.metadata.is_none() && bag.files.len() > 1 {
            bag.check_one_recording()?;
        }
        Ok(bag)
    }

    /// A folder of files without a metadata.yaml to tie them: they are one recording split
    /// into files only when each starts within [`SPLIT_GAP_NS`] of where the one before
    /// ended; else they are unrelated recordings (a folder of bags) and refused, each named
    /// with its span, to choose one.
    fn check_one_recording(&self) -> Result<(), BagError> {
        let mut spans: Vec<(PathBuf, Option<(i64, i64)>)> = Vec::new();
        for (f, s) in &self.files {
            let one = Bag {
                path: f.clone(),
                files: vec![(f.clone(), *s)],
                metadata: None,
            };
            let span = one
                .topic_list()?
                .iter()
                .filter_map(|t| t.span)
                .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)));
            spans.push((f.clone(), span));
        }
        spans.sort_by_key(|s| s.1.map_or(i64::MAX, |s| s.0));
        let apart = spans.windows(2).any(|w| match (w[0].1, w[1].1) {
            (Some(a), Some(b)) => b.0 > a.1.saturating_add(SPLIT_GAP_NS),
            _ => false,
        });
        if !apart {
            return Ok(());
        }
        let list: Vec<String> = spans
            .iter()
            .map(|(f, s)| {
                let name = f
                    .file_name()
                    .map_or(String::new(), |n| n.to_string_lossy().into_owned());
                match s {
                    Some((a, b)) => {
                        let secs = a.div_euclid(1_000_000_000);
                        let (y, mo, d) = spherecal::time::civil_from_days(secs.div_euclid(86_400));
                        let t = secs.rem_euclid(86_400);
                        format!(
                            "{name} ({:.1} s from {y:04}-{mo:02}-{d:02} {:02}:{:02}:{:02} UTC)",
                            (b - a) as f64 * 1e-9,
                            t / 3600,
                            t / 60 % 60,
                            t % 60
                        )
                    }
                    None => format!("{name} (no message)"),
                }
            })
            .collect();
        Err(BagError::new(
            &self.path,
            format!(
                "holds {} recordings whose times do not follow one another and no metadata.yaml ties them: {}; give one of them (its file, or its own folder)",
                spans.len(),
                list.join(", ")
            ),
        ))
    }

    /// The storage(s), for people: `mcap`, `sqlite3`, or both joined.
    pub fn storage(&self) -> String {
        let mut v: Vec<&str> = self.files.iter().map(|f| f.1.name()).collect();
        v.dedup();
        v.join("+")
    }

    /// Every topic with its message count, without reading the messages where the storage
    /// can say (sqlite3's tables, a complete MCAP's summary; no span then), else as
    /// [`Bag::topics`].
    pub fn topic_list(&self) -> Result<Vec<TopicStats>, BagError> {
        let mut out: Vec<TopicStats> = Vec::new();
        for (f, s) in &self.files {
            let stats = match s {
                Storage::Sqlite3 => sqlite_file::Reader::open(f, None)?.stats()?,
                Storage::Mcap => match mcap_file::summary_topics(f)? {
                    Some(t) => t,
                    None => return self.topics(),
                },
            };
            for t in stats {
                match out.iter_mut().find(|o| o.topic.name == t.topic.name) {
                    Some(o) => add(o, t.count, t.span),
                    None => out.push(t),
                }
            }
        }
        Ok(out)
    }

    /// Every topic of every file (first seen first) with its message count and span; reads
    /// the whole bag.
    pub fn topics(&self) -> Result<Vec<TopicStats>, BagError> {
        let mut out: Vec<TopicStats> = Vec::new();
        for (f, s) in &self.files {
            let stats = match s {
                Storage::Sqlite3 => sqlite_file::Reader::open(f, None)?.stats()?,
                Storage::Mcap => {
                    let mut r = mcap_file::Reader::open(f, None)?;
                    let mut st: Vec<TopicStats> = Vec::new();
                    while let Some(m) = r.next()? {
                        let at = match st.iter().position(|t| t.topic.name == m.topic.name) {
                            Some(i) => i,
                            None => {
                                st.push(TopicStats {
                                    topic: m.topic.clone(),
                                    count: 0,
                                    span: None,
                                });
                                st.len() - 1
                            }
                        };
                        add(&mut st[at], 1, Some((m.log_time_ns, m.log_time_ns)));
                    }
                    for t in r.topics() {
                        if !st.iter().any(|s| s.topic.name == t.name) {
                            st.push(TopicStats {
                                topic: t.clone(),
                                count: 0,
                                span: None,
                            });
                        }
                    }
                    st
                }
            };
            for t in stats {
                match out.iter_mut().find(|o| o.topic.name == t.topic.name) {
                    Some(o) => add(o, t.count, t.span),
                    None => out.push(t),
                }
            }
        }
        Ok(out)
    }

    /// The messages of `topics` (all topics when empty), file after file, in each file's order.
    pub fn messages(&self, topics: &[&str]) -> Messages {
        Messages {
            files: self.files.clone(),
            topics: topics.iter().map(|t| t.to_string()).collect(),
            next: 0,
            cur: None,
            cut: Vec::new(),
        }
    }
}

fn add(t: &mut TopicStats, count: u64, span: Option<(i64, i64)>) {
    t.count += count;
    t.span = match (t.span, span) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, b) => a.or(b),
    };
}

enum FileReader {
    Mcap(Box<mcap_file::Reader>),
    Sqlite(Box<sqlite_file::Reader>),
}

/// The messages of some topics of a bag, one at a time ([`Messages::next`]); each borrows
/// the reader until the next call.
pub struct Messages {
    files: Vec<(PathBuf, Storage)>,
    topics: Vec<String>,
    next: usize,
    cur: Option<FileReader>,
    cut: Vec<(PathBuf, u64)>,
}

impl Messages {
    /// The next message, or `None` after the last file's last.
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Result<Option<Message<'_>>, BagError> {
        loop {
            if self.cur.is_none() {
                let Some((f, s)) = self.files.get(self.next) else {
                    return Ok(None);
                };
                self.next += 1;
                let want = (!self.topics.is_empty()).then_some(&self.topics[..]);
                self.cur = Some(match s {
                    Storage::Mcap => FileReader::Mcap(Box::new(mcap_file::Reader::open(f, want)?)),
                    Storage::Sqlite3 => {
                        FileReader::Sqlite(Box::new(sqlite_file::Reader::open(f, want)?))
                    }
                });
            }
            // Whether the file has a message left (the borrow of it is then returned).
            let more = match self.cur.as_mut() {
                Some(FileReader::Mcap(r)) => r.advance()?,
                Some(FileReader::Sqlite(r)) => r.advance()?,
                None => false,
            };
            if more {
                return Ok(match self.cur.as_ref() {
                    Some(FileReader::Mcap(r)) => r.current(),
                    Some(FileReader::Sqlite(r)) => r.current(),
                    None => None,
                });
            }
            if let (Some(FileReader::Mcap(r)), Some((f, _))) =
                (self.cur.as_ref(), self.files.get(self.next - 1))
            {
                if let Some(at) = r.truncated {
                    self.cut.push((f.clone(), at));
                }
            }
            self.cur = None;
        }
    }

    /// The MCAP files found cut short so far, with the byte each ends at: their messages
    /// before the cut were read.
    pub fn cut(&self) -> &[(PathBuf, u64)] {
        &self.cut
    }
}

/// Words for files cut short ([`Messages::cut`]): empty when none.
pub fn cut_words(cut: &[(PathBuf, u64)]) -> String {
    cut.iter()
        .map(|(f, at)| {
            format!(
                "; {} is cut short at byte {at} (a recording not closed): the messages before were read, those in its last unfinished chunk are lost (`mcap recover` or `ros2 bag reindex` may recover more)",
                f.display()
            )
        })
        .collect()
}

#[cfg(test)]
mod tests;

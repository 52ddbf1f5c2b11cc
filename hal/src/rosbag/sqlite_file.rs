//! One rosbag2 sqlite3 file (`.db3`): the `topics` table (id, name, type,
//! serialization_format: Humble's and Jazzy's schemas alike) and the `messages` table (id,
//! topic_id, timestamp, data), read in pages in row order, opened read-only.

use super::{BagError, Message, Topic, TopicStats};
use rusqlite::{Connection, OpenFlags};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};

/// Rows fetched per query.
const PAGE: i64 = 256;

/// The reader.
pub(super) struct Reader {
    path: PathBuf,
    conn: Connection,
    /// Topic id -> topic.
    topics: Vec<(i64, Topic)>,
    /// The query for the next page (the wanted topics' ids in it).
    query: String,
    last_id: i64,
    page: VecDeque<(i64, usize, i64, Vec<u8>)>,
    done: bool,
    cur: Option<(i64, usize, i64, Vec<u8>)>,
}

impl Reader {
    /// Open `path`; only the topics in `want` are returned (all when None).
    pub(super) fn open(path: &Path, want: Option<&[String]>) -> Result<Self, BagError> {
        let err = |e: rusqlite::Error| BagError::new(path, format!("SQLite: {e}"));
        let conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(err)?;
        let mut topics = Vec::new();
        {
            let mut st = conn
                .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
                .map_err(|e| {
                    BagError::new(
                        path,
                        format!("not a rosbag2 sqlite3 file (no topics table as rosbag2 writes it): {e}"),
                    )
                })?;
            let rows = st
                .query_map([], |r| {
                    Ok((
                        r.get::<_, i64>(0)?,
                        Topic {
                            name: r.get(1)?,
                            type_name: r.get(2)?,
                            encoding: r.get(3)?,
                        },
                    ))
                })
                .map_err(err)?;
            for r in rows {
                topics.push(r.map_err(err)?);
            }
        }
        let ids: Vec<String> = topics
            .iter()
            .filter(|(_, t)| want.is_none_or(|w| w.contains(&t.name)))
            .map(|(id, _)| id.to_string())
            .collect();
        let query = format!(
            "SELECT id, topic_id, timestamp, data FROM messages WHERE id > ?1 AND topic_id IN ({}) ORDER BY id LIMIT {PAGE}",
            if ids.is_empty() { "NULL".to_string() } else { ids.join(",") }
        );
        Ok(Self {
            path: path.to_path_buf(),
            conn,
            topics,
            query,
            last_id: i64::MIN,
            page: VecDeque::new(),
            done: false,
            cur: None,
        })
    }

    fn err(&self, e: rusqlite::Error) -> BagError {
        BagError::new(&self.path, format!("SQLite: {e}"))
    }

    /// Each topic's count and span (one query).
    pub(super) fn stats(&self) -> Result<Vec<TopicStats>, BagError> {
        let mut out: Vec<TopicStats> = self
            .topics
            .iter()
            .map(|(_, t)| TopicStats {
                topic: t.clone(),
                count: 0,
                span: None,
            })
            .collect();
        let mut st = self
            .conn
            .prepare("SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages GROUP BY topic_id")
            .map_err(|e| self.err(e))?;
        let rows = st
            .query_map([], |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, i64>(1)?,
                    r.get::<_, i64>(2)?,
                    r.get::<_, i64>(3)?,
                ))
            })
            .map_err(|e| self.err(e))?;
        for r in rows {
            let (id, n, a, b) = r.map_err(|e| self.err(e))?;
            if let Some(i) = self.topics.iter().position(|t| t.0 == id) {
                out[i].count = n.max(0) as u64;
                out[i].span = Some((a, b));
            }
        }
        Ok(out)
    }

    /// Move to the next wanted message; false at the file's end.
    pub(super) fn advance(&mut self) -> Result<bool, BagError> {
        if self.page.is_empty() && !self.done {
            self.fetch()?;
        }
        self.cur = self.page.pop_front();
        Ok(self.cur.is_some())
    }

    fn fetch(&mut self) -> Result<(), BagError> {
        let mut st = self
            .conn
            .prepare_cached(&self.query)
            .map_err(|e| BagError::new(&self.path, format!("SQLite: {e}")))?;
        let topics = &self.topics;
        let rows = st
            .query_map([self.last_id], |r| {
                let tid: i64 = r.get(1)?;
                Ok((
                    r.get::<_, i64>(0)?,
                    topics.iter().position(|t| t.0 == tid).unwrap_or(0),
                    r.get::<_, i64>(2)?,
                    r.get::<_, Vec<u8>>(3)?,
                ))
            })
            .map_err(|e| BagError::new(&self.path, format!("SQLite: {e}")))?;
        let mut n = 0;
        for r in rows {
            let row = r.map_err(|e| BagError::new(&self.path, format!("SQLite: {e}")))?;
            self.last_id = row.0;
            self.page.push_back(row);
            n += 1;
        }
        self.done = n < PAGE;
        Ok(())
    }

    /// The current message.
    pub(super) fn current(&self) -> Option<Message<'_>> {
        let (id, i, t, data) = self.cur.as_ref()?;
        Some(Message {
            topic: &self.topics.get(*i)?.1,
            log_time_ns: *t,
            data,
            file: &self.path,
            at: *id as u64,
        })
    }
}

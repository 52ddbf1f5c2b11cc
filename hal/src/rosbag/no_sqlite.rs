//! Built without the `sqlite` feature: a `.db3` is refused, saying so.

use super::{BagError, Message, TopicStats};
use std::path::Path;

/// Never made.
pub(super) enum Reader {}

impl Reader {
    pub(super) fn open(path: &Path, _want: Option<&[String]>) -> Result<Self, BagError> {
        Err(BagError::new(
            path,
            "a sqlite3 bag: this build has no SQLite (the hal's `sqlite` feature)",
        ))
    }

    pub(super) fn stats(&self) -> Result<Vec<TopicStats>, BagError> {
        match *self {}
    }

    pub(super) fn advance(&mut self) -> Result<bool, BagError> {
        match *self {}
    }

    pub(super) fn current(&self) -> Option<Message<'_>> {
        match *self {}
    }
}

//! A bag folder's `metadata.yaml` (rosbag2 `rosbag2_bagfile_information`, versions 4-9): only
//! the keys needed to read the files, by a line parser (no YAML crate for five keys): the
//! storage, the files in order, and the compression.

/// What a metadata.yaml says.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Metadata {
    /// `storage_identifier`: `sqlite3` or `mcap`.
    pub storage_identifier: Option<String>,
    /// `relative_file_paths`, in order.
    pub relative_file_paths: Vec<String>,
    /// `compression_format` (`zstd`, or empty).
    pub compression_format: Option<String>,
    /// `compression_mode` (`FILE`, `MESSAGE`, or empty).
    pub compression_mode: Option<String>,
    /// The bag's `message_count` (all topics), as the recorder wrote it when it closed.
    pub message_count: Option<u64>,
}

fn scalar(v: &str) -> String {
    let v = v.trim();
    let v = v
        .strip_prefix('"')
        .and_then(|v| v.strip_suffix('"'))
        .or_else(|| v.strip_prefix('\'').and_then(|v| v.strip_suffix('\'')))
        .unwrap_or(v);
    v.to_string()
}

impl Metadata {
    /// Parse the text; Err when it is not rosbag2's metadata.
    pub fn parse(text: &str) -> Result<Self, String> {
        if !text.contains("rosbag2_bagfile_information") {
            return Err("not a rosbag2 metadata.yaml (no rosbag2_bagfile_information)".into());
        }
        let mut m = Metadata::default();
        let mut in_paths: Option<usize> = None;
        for line in text.lines() {
            let indent = line.len() - line.trim_start().len();
            let t = line.trim();
            if let Some(ind) = in_paths {
                if let Some(item) = t.strip_prefix("- ").filter(|_| indent >= ind) {
                    m.relative_file_paths.push(scalar(item));
                    continue;
                }
                if !t.is_empty() {
                    in_paths = None;
                }
            }
            if let Some(v) = t.strip_prefix("message_count:").filter(|_| indent <= 2) {
                // The bag's own count (the topics' are indented deeper).
                m.message_count = m.message_count.or(scalar(v).parse().ok());
            } else if let Some(v) = t.strip_prefix("storage_identifier:") {
                m.storage_identifier = Some(scalar(v));
            } else if let Some(v) = t.strip_prefix("compression_format:") {
                m.compression_format = Some(scalar(v));
            } else if let Some(v) = t.strip_prefix("compression_mode:") {
                m.compression_mode = Some(scalar(v));
            } else if let Some(v) = t.strip_prefix("relative_file_paths:") {
                let v = v.trim();
                if let Some(list) = v.strip_prefix('[').and_then(|v| v.strip_suffix(']')) {
                    m.relative_file_paths
                        .extend(list.split(',').map(scalar).filter(|s| !s.is_empty()));
                } else {
                    in_paths = Some(indent);
                }
            }
        }
        if m.relative_file_paths.is_empty() {
            return Err("metadata.yaml lists no file (relative_file_paths)".into());
        }
        // rosbag2 keeps a bag's files in its folder: a path that leaves it (absolute, or
        // through `..`) would read files the bag does not own.
        if let Some(p) = m.relative_file_paths.iter().find(|p| {
            let p = std::path::Path::new(p.as_str());
            p.is_absolute()
                || p.components()
                    .any(|c| !matches!(c, std::path::Component::Normal(_)))
        }) {
            return Err(format!(
                "metadata.yaml lists {p:?}, which is not in the bag's folder: refused (rosbag2 keeps a bag's files beside its metadata.yaml)"
            ));
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_rosbag2s_keys() {
        // As rosbag2 (Humble) writes it.
        let t = "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n  duration:\n    nanoseconds: 10\n  relative_file_paths:\n    - rec_0.db3\n    - rec_1.db3\n  topics_with_message_count:\n    - topic_metadata:\n        name: /a\n      message_count: 3\n  compression_format: \"\"\n  compression_mode: \"\"\n";
        let m = Metadata::parse(t).unwrap();
        assert_eq!(m.storage_identifier.as_deref(), Some("sqlite3"));
        assert_eq!(m.relative_file_paths, ["rec_0.db3", "rec_1.db3"]);
        assert_eq!(m.compression_mode.as_deref(), Some(""));
        // The bag's own count, not a topic's (indented deeper).
        assert_eq!(m.message_count, None);
        let counted = t.replace("  duration:", "  message_count: 12\n  duration:");
        assert_eq!(Metadata::parse(&counted).unwrap().message_count, Some(12));
        // A file outside the bag's folder is refused by name.
        for bad in ["../other/rec_0.db3", "/etc/passwd", "sub/../../x.db3"] {
            let e = Metadata::parse(&t.replace("rec_1.db3", bad)).unwrap_err();
            assert!(
                e.contains(bad) && e.contains("not in the bag's folder"),
                "{e}"
            );
        }
        let f = "rosbag2_bagfile_information:\n  relative_file_paths: [a_0.mcap.zstd]\n  compression_format: zstd\n  compression_mode: FILE\n";
        let m = Metadata::parse(f).unwrap();
        assert_eq!(m.relative_file_paths, ["a_0.mcap.zstd"]);
        assert_eq!(m.compression_mode.as_deref(), Some("FILE"));
        assert!(Metadata::parse("hello: 1").is_err());
        assert!(Metadata::parse("rosbag2_bagfile_information:\n  version: 5\n").is_err());
    }
}

//! The containers a ROS 2 bag comes in: one MCAP file, one sqlite3 file
//! (`.db3`, rosbag2's default storage before Iron, which most published bags
//! use), or a bag folder whose `metadata.yaml` lists several of either
//! (split bags), each whole-file compressed or with compressed messages.
//! No ROS 2 installation is needed: MCAP is read by the `mcap` crate
//! (compressed chunks included), sqlite3 by `rusqlite` with its bundled
//! SQLite, zstd by the `zstd` crate.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::BagError;

/// One message as the bag stores it.
#[derive(Clone, Debug)]
pub struct RawMessage {
    pub topic: String,
    /// The message type, e.g. `geometry_msgs/msg/Twist`.
    pub message_type: String,
    /// `cdr` for ROS 2.
    pub encoding: String,
    /// When the recorder received it, nanoseconds on the recorder's clock.
    pub log_time_ns: i64,
    pub data: Vec<u8>,
}

/// A topic of the bag: its name, message type and how many messages it has.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Topic {
    pub name: String,
    pub message_type: String,
    pub messages: u64,
}

/// The files of a bag, in the order they were recorded.
#[derive(Clone, Debug)]
pub struct Bag {
    /// What the user named: a file or a bag folder.
    pub path: PathBuf,
    files: Vec<Source>,
}

/// Where a bag file's bytes are.
#[derive(Clone, Debug)]
enum Source {
    File(PathBuf),
    /// Bytes already in memory (a fuzzer's, a test's), named by the bag's path.
    Memory(Vec<u8>),
}

/// The zstd frame's first bytes: a file or message rosbag2 compressed.
const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];
const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

/// rosbag2's `metadata.yaml`: only what locating the files needs.
#[derive(serde::Deserialize)]
struct Metadata {
    rosbag2_bagfile_information: BagInformation,
}

#[derive(serde::Deserialize)]
struct BagInformation {
    #[serde(default)]
    relative_file_paths: Vec<String>,
    #[serde(default)]
    storage_identifier: String,
}

impl Bag {
    /// A bag file (`.mcap`, `.db3`, either zstd-compressed) or a bag folder
    /// (with `metadata.yaml`, or failing that its bag files in name order).
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let error = |message: String| BagError::new(path, message);
        let meta = std::fs::metadata(path).map_err(|e| error(format!("cannot read it: {e}")))?;
        let files = if meta.is_dir() {
            folder_files(path)?
        } else {
            vec![path.to_owned()]
        };
        if files.is_empty() {
            return Err(error(
                "holds no bag file (.mcap or .db3) and no metadata.yaml naming one".to_owned(),
            ));
        }
        Ok(Self {
            path: path.to_owned(),
            files: files.into_iter().map(Source::File).collect(),
        })
    }

    /// A one-file bag whose bytes are in memory, named `name` in errors.
    pub fn from_bytes(name: &Path, bytes: Vec<u8>) -> Self {
        Self {
            path: name.to_owned(),
            files: vec![Source::Memory(bytes)],
        }
    }

    /// Every topic with its type and message count, by name.
    pub fn topics(&self) -> Result<Vec<Topic>, BagError> {
        let mut found: BTreeMap<String, Topic> = BTreeMap::new();
        self.each_message(None, |m| {
            found
                .entry(m.topic.clone())
                .or_insert_with(|| Topic {
                    name: m.topic.clone(),
                    message_type: m.message_type.clone(),
                    messages: 0,
                })
                .messages += 1;
            Ok(())
        })?;
        Ok(found.into_values().collect())
    }

    /// The messages of `topics` (all when `None`), file after file, each
    /// message decompressed if rosbag2 compressed it.
    pub fn messages(&self, topics: Option<&[&str]>) -> Result<Vec<RawMessage>, BagError> {
        let mut out = Vec::new();
        self.each_message(topics, |m| {
            out.push(m);
            Ok(())
        })?;
        Ok(out)
    }

    fn each_message(
        &self,
        topics: Option<&[&str]>,
        mut take: impl FnMut(RawMessage) -> Result<(), BagError>,
    ) -> Result<(), BagError> {
        for source in &self.files {
            let (file, bytes) = match source {
                Source::File(path) => (path.as_path(), read_file(path)?),
                Source::Memory(bytes) => (
                    self.path.as_path(),
                    decompressed(bytes.clone(), &self.path)?,
                ),
            };
            let mut take_one = |mut m: RawMessage| {
                if topics.is_none_or(|t| t.contains(&m.topic.as_str())) {
                    if m.data.starts_with(&ZSTD_MAGIC) {
                        m.data = zstd::decode_all(m.data.as_slice()).map_err(|e| {
                            BagError::new(
                                file,
                                format!(
                                    "topic {}: a compressed message does not decompress: {e}",
                                    m.topic
                                ),
                            )
                        })?;
                    }
                    take(m)?;
                }
                Ok(())
            };
            if bytes.starts_with(mcap::MAGIC) {
                mcap_messages(&bytes, file, &mut take_one)?;
            } else if bytes.starts_with(SQLITE_MAGIC) {
                sqlite_messages(&bytes, file, &mut take_one)?;
            } else {
                return Err(BagError::new(
                    file,
                    "is neither an MCAP nor a sqlite3 (.db3) ROS 2 bag".to_owned(),
                ));
            }
        }
        Ok(())
    }
}

/// A bag file's bytes, decompressed if rosbag2 compressed the whole file.
fn read_file(file: &Path) -> Result<Vec<u8>, BagError> {
    let bytes =
        std::fs::read(file).map_err(|e| BagError::new(file, format!("cannot read it: {e}")))?;
    decompressed(bytes, file)
}

fn decompressed(bytes: Vec<u8>, file: &Path) -> Result<Vec<u8>, BagError> {
    if bytes.starts_with(&ZSTD_MAGIC) {
        return zstd::decode_all(bytes.as_slice())
            .map_err(|e| BagError::new(file, format!("does not decompress (zstd): {e}")));
    }
    Ok(bytes)
}

/// The bag files of a bag folder: as its `metadata.yaml` lists them, or
/// every `.mcap` and `.db3` (compressed or not) in name order.
fn folder_files(dir: &Path) -> Result<Vec<PathBuf>, BagError> {
    let metadata = dir.join("metadata.yaml");
    if metadata.is_file() {
        let text = std::fs::read_to_string(&metadata)
            .map_err(|e| BagError::new(&metadata, format!("cannot read it: {e}")))?;
        let parsed: Metadata = serde_yaml_ng::from_str(&text).map_err(|e| {
            let line = e
                .location()
                .map_or(String::new(), |l| format!(":{}", l.line()));
            BagError::new(
                &metadata,
                format!("{line} is not rosbag2 metadata: {e}")
                    .trim_start_matches(':')
                    .to_owned(),
            )
        })?;
        let info = parsed.rosbag2_bagfile_information;
        if !["", "sqlite3", "mcap"].contains(&info.storage_identifier.as_str()) {
            return Err(BagError::new(
                &metadata,
                format!(
                    "storage `{}` is not read; bags in sqlite3 or mcap storage are",
                    info.storage_identifier
                ),
            ));
        }
        return info
            .relative_file_paths
            .iter()
            .map(|relative| {
                let file = dir.join(relative);
                if file.is_file() {
                    Ok(file)
                } else {
                    Err(BagError::new(
                        &metadata,
                        format!("lists {relative}, which is not in {}", dir.display()),
                    ))
                }
            })
            .collect();
    }
    let entries =
        std::fs::read_dir(dir).map_err(|e| BagError::new(dir, format!("cannot list it: {e}")))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| is_bag_file(p))
        .collect();
    files.sort_by_key(|p| natural_key(p));
    Ok(files)
}

/// Whether `path` is named as a bag file: `.mcap` or `.db3`, zstd-compressed
/// (`.zstd`, as rosbag2 names its compressed files) or not.
pub fn is_bag_file(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    [".mcap", ".db3", ".mcap.zstd", ".db3.zstd"]
        .iter()
        .any(|ext| name.ends_with(ext))
}

/// Orders `bag_10.db3` after `bag_9.db3`, as rosbag2 numbers its splits.
fn natural_key(path: &Path) -> (String, u64) {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem = name.split('.').next().unwrap_or("");
    let digits: String = stem
        .chars()
        .rev()
        .take_while(char::is_ascii_digit)
        .collect();
    let number: String = digits.chars().rev().collect();
    (
        stem[..stem.len() - number.len()].to_owned(),
        number.parse().unwrap_or(0),
    )
}

fn mcap_messages(
    bytes: &[u8],
    file: &Path,
    take: &mut dyn FnMut(RawMessage) -> Result<(), BagError>,
) -> Result<(), BagError> {
    let stream = mcap::MessageStream::new(bytes)
        .map_err(|e| BagError::new(file, format!("is not a readable MCAP file: {e}")))?;
    for message in stream {
        let message = message
            .map_err(|e| BagError::new(file, format!("the bag is damaged or cut short: {e}")))?;
        let log_time_ns = i64::try_from(message.log_time).map_err(|_| {
            BagError::new(
                file,
                format!(
                    "topic {}: log time {} ns is past the year 2262",
                    message.channel.topic, message.log_time
                ),
            )
        })?;
        take(RawMessage {
            topic: message.channel.topic.clone(),
            message_type: message
                .channel
                .schema
                .as_ref()
                .map_or_else(|| "(no schema)".to_owned(), |s| s.name.clone()),
            encoding: message.channel.message_encoding.clone(),
            log_time_ns,
            data: message.data.into_owned(),
        })?;
    }
    Ok(())
}

/// A rosbag2 sqlite3 file: `topics(id, name, type, serialization_format,
/// ...)` and `messages(id, topic_id, timestamp, data)`, the same in every
/// ROS 2 release from Foxy on; the message definitions, which Iron added,
/// are not needed (the types read here are decoded by their known layouts).
fn sqlite_messages(
    bytes: &[u8],
    file: &Path,
    take: &mut dyn FnMut(RawMessage) -> Result<(), BagError>,
) -> Result<(), BagError> {
    let sql_error =
        |e: rusqlite::Error| BagError::new(file, format!("cannot read the sqlite3 bag: {e}"));
    // Read from the bytes already in memory: the file is opened by no one
    // else and may sit on a read-only disk, or have been decompressed.
    let mut db = rusqlite::Connection::open_in_memory().map_err(sql_error)?;
    let bytes = without_wal_mode(bytes);
    db.deserialize_read_exact(rusqlite::MAIN_DB, bytes.as_ref(), bytes.len(), true)
        .map_err(sql_error)?;
    let mut query = db
        .prepare(
            "SELECT topics.name, topics.type, topics.serialization_format, messages.timestamp, messages.data \
             FROM messages JOIN topics ON messages.topic_id = topics.id ORDER BY messages.timestamp, messages.id",
        )
        .map_err(|e| {
            BagError::new(
                file,
                format!("is a sqlite3 file without rosbag2's topics and messages tables: {e}"),
            )
        })?;
    let mut rows = query.query([]).map_err(sql_error)?;
    while let Some(row) = rows.next().map_err(sql_error)? {
        take(RawMessage {
            topic: row.get(0).map_err(sql_error)?,
            message_type: row.get(1).map_err(sql_error)?,
            encoding: row.get(2).map_err(sql_error)?,
            log_time_ns: row.get(3).map_err(sql_error)?,
            data: row.get(4).map_err(sql_error)?,
        })?;
    }
    Ok(())
}

/// A database in WAL mode (rosbag2's "resilient" preset) cannot be opened
/// from memory; its header bytes 18-19 say so. Marked as a rollback-journal
/// database, the same pages read the same. (What a killed recorder left in
/// the `-wal` file beside it, uncheckpointed, is not in these pages.)
fn without_wal_mode(bytes: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    match bytes.get(18..20) {
        Some([2, _] | [_, 2]) => {
            let mut owned = bytes.to_vec();
            owned[18] = 1;
            owned[19] = 1;
            std::borrow::Cow::Owned(owned)
        }
        _ => std::borrow::Cow::Borrowed(bytes),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_files_are_read_in_the_order_rosbag2_numbers_them() {
        let mut names = vec!["run_10.db3", "run_2.db3", "run_0.db3", "run_1.db3"];
        names.sort_by_key(|n| natural_key(Path::new(n)));
        assert_eq!(names, ["run_0.db3", "run_1.db3", "run_2.db3", "run_10.db3"]);
    }
}

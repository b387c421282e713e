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

/// What a pass over a bag read: its result, and a sentence for each file
/// its recorder left unfinished (killed before it closed the file): an MCAP
/// file that ends in the middle of a record (what came before the cut was
/// read), an sqlite3 file whose last messages are still in its `-wal`
/// file beside it (they were read too).
#[derive(Clone, Debug)]
pub struct Reading<T> {
    pub found: T,
    pub unfinished: Vec<String>,
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
/// How a ROS 1 bag begins (rosbag format 2.0): no shorter than
/// `SQLITE_MAGIC`, so the bytes read to tell the kind hold it.
const ROS1_MAGIC: &[u8] = b"#ROSBAG V";

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

    /// Every topic with its type and message count, by name. No message's
    /// data is read: a bag of camera images lists as fast as one of poses.
    pub fn topics(&self) -> Result<Reading<Vec<Topic>>, BagError> {
        let mut found: BTreeMap<String, Topic> = BTreeMap::new();
        let unfinished = self.each_stored(Wanted::Headers, |m| {
            found
                .entry(m.topic.to_owned())
                .or_insert_with(|| Topic {
                    name: m.topic.to_owned(),
                    message_type: crate::ros::full_type_name(m.message_type),
                    messages: 0,
                })
                .messages += 1;
            Ok(())
        })?;
        Ok(Reading {
            found: found.into_values().collect(),
            unfinished,
        })
    }

    /// The messages of `topics` (all when `None`), file after file, each
    /// message decompressed if rosbag2 compressed it. Only these topics'
    /// messages are held: a bag of many gigabytes of images is read a
    /// chunk (MCAP) or a row (sqlite3) at a time.
    pub fn messages(&self, topics: Option<&[&str]>) -> Result<Reading<Vec<RawMessage>>, BagError> {
        let mut out = Vec::new();
        let unfinished = self.each_stored(Wanted::Messages(topics), |m| {
            let data = if m.data.starts_with(&ZSTD_MAGIC) {
                zstd::decode_all(m.data).map_err(|e| {
                    BagError::new(
                        m.file,
                        format!(
                            "topic {}: a compressed message does not decompress: {e}",
                            m.topic
                        ),
                    )
                })?
            } else {
                m.data.to_vec()
            };
            out.push(RawMessage {
                topic: m.topic.to_owned(),
                message_type: crate::ros::full_type_name(m.message_type),
                encoding: m.encoding.to_owned(),
                log_time_ns: m.log_time_ns,
                data,
            });
            Ok(())
        })?;
        Ok(Reading {
            found: out,
            unfinished,
        })
    }

    /// Calls `take` with each wanted message, file after file; returns what
    /// [`Reading::unfinished`] says.
    fn each_stored(
        &self,
        wanted: Wanted,
        mut take: impl FnMut(Stored) -> Result<(), BagError>,
    ) -> Result<Vec<String>, BagError> {
        let mut unfinished = Vec::new();
        for source in &self.files {
            let ended = match source {
                Source::File(path) => each_in_file(path, wanted, &mut take)?,
                Source::Memory(bytes) => {
                    let bytes = decompressed(bytes.clone(), &self.path)?;
                    each_in_bytes(&bytes, &self.path, wanted, &mut take)?
                }
            };
            unfinished.extend(ended);
        }
        Ok(unfinished)
    }
}

/// What one pass over a bag reads.
#[derive(Clone, Copy, Debug)]
enum Wanted<'a> {
    /// Every message's topic, type and time, its data left unread (a
    /// listing).
    Headers,
    /// The whole messages of these topics (all when `None`).
    Messages(Option<&'a [&'a str]>),
}

impl Wanted<'_> {
    fn topic(&self, topic: &str) -> bool {
        match self {
            Wanted::Headers | Wanted::Messages(None) => true,
            Wanted::Messages(Some(topics)) => topics.contains(&topic),
        }
    }
}

/// One message as a reader holds it: borrowed from the chunk or row being
/// read. For [`Wanted::Headers`] its data may be left empty (sqlite3 then
/// never loads them).
struct Stored<'a> {
    file: &'a Path,
    topic: &'a str,
    message_type: &'a str,
    encoding: &'a str,
    log_time_ns: i64,
    data: &'a [u8],
}

type Take<'t> = dyn FnMut(Stored) -> Result<(), BagError> + 't;

/// How a file's messages ended: `Some` sentence when its recorder left it
/// unfinished ([`Reading::unfinished`]).
type Ended = Result<Option<String>, BagError>;

/// The messages of one bag file, read where it lies: an MCAP file streamed
/// (one chunk in memory at a time), an sqlite3 file queried in place. A
/// file rosbag2 compressed whole is decompressed first: an MCAP as a
/// stream, an sqlite3 file (which SQLite must read at random) into memory.
fn each_in_file(file: &Path, wanted: Wanted, take: &mut Take) -> Ended {
    let open = || {
        std::fs::File::open(file).map_err(|e| BagError::new(file, format!("cannot read it: {e}")))
    };
    let magic = first_bytes(open()?, file)?;
    if magic.starts_with(&ZSTD_MAGIC) {
        let decompressing = || {
            zstd::Decoder::new(open()?)
                .map_err(|e| BagError::new(file, format!("does not decompress (zstd): {e}")))
        };
        if first_bytes(decompressing()?, file)?.starts_with(mcap::MAGIC) {
            return mcap_messages(decompressing()?, file, record_limit(file), wanted, take);
        }
        return each_in_bytes(&read_file(file)?, file, wanted, take);
    }
    if magic.starts_with(mcap::MAGIC) {
        let reader = std::io::BufReader::new(open()?);
        return mcap_messages(reader, file, record_limit(file), wanted, take);
    }
    if magic.starts_with(SQLITE_MAGIC) {
        if let Some(wal) = unmerged_wal(file) {
            return sqlite_with_wal(file, &wal, wanted, take);
        }
        return match sqlite_in_place(file) {
            Some(db) => sqlite_messages(&db, file, wanted, take).map(|()| None),
            None => each_in_bytes(&read_file(file)?, file, wanted, take),
        };
    }
    Err(not_a_bag(file, &magic))
}

/// A bag file's bytes already in memory (decompressed).
fn each_in_bytes(bytes: &[u8], file: &Path, wanted: Wanted, take: &mut Take) -> Ended {
    if bytes.starts_with(mcap::MAGIC) {
        // In memory (a fuzzer's bytes, a test's) no record is longer than
        // the bytes themselves.
        mcap_messages(bytes, file, bytes.len(), wanted, take)
    } else if bytes.starts_with(SQLITE_MAGIC) {
        sqlite_messages(&sqlite_in_memory(bytes, file)?, file, wanted, take).map(|()| None)
    } else {
        Err(not_a_bag(file, bytes))
    }
}

/// Why a file is not read as a bag: what it is, where that is known, and
/// what to do.
fn not_a_bag(file: &Path, magic: &[u8]) -> BagError {
    if magic.starts_with(ROS1_MAGIC) {
        return BagError::new(
            file,
            format!(
                "is a ROS 1 bag (rosbag format 2.0), not a ROS 2 bag: convert it without ROS \
                 (pip install rosbags; rosbags-convert --src {} --dst FOLDER), then diagnose FOLDER",
                file.display()
            ),
        );
    }
    BagError::new(
        file,
        "is neither an MCAP nor a sqlite3 (.db3) ROS 2 bag".to_owned(),
    )
}

/// The first bytes of `reader`, enough to tell the file's kind (fewer if
/// the file is shorter).
fn first_bytes(mut reader: impl std::io::Read, file: &Path) -> Result<Vec<u8>, BagError> {
    use std::io::Read;
    let mut magic = Vec::with_capacity(SQLITE_MAGIC.len());
    reader
        .by_ref()
        .take(SQLITE_MAGIC.len() as u64)
        .read_to_end(&mut magic)
        .map_err(|e| BagError::new(file, format!("cannot read it: {e}")))?;
    Ok(magic)
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
                listed_file(dir, relative).ok_or_else(|| {
                    BagError::new(
                        &metadata,
                        format!("lists {relative}, which is not in {}", dir.display()),
                    )
                })
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

/// A file `metadata.yaml` lists, where rosbag2's versions put it: beside
/// the metadata; or, as Eloquent and Foxy's compressing writer wrote it
/// (`bag/bag_0.db3.zstd`), from the folder above; or, in a folder since
/// renamed, by its name alone.
fn listed_file(dir: &Path, relative: &str) -> Option<PathBuf> {
    let by_name = Path::new(relative).file_name().map(|name| dir.join(name));
    [
        Some(dir.join(relative)),
        dir.parent().map(|up| up.join(relative)),
        by_name,
    ]
    .into_iter()
    .flatten()
    .find(|file| file.is_file())
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

/// Whether `path` is a ROS 1 bag: read, it is refused with how to convert
/// it, rather than taken for something else.
pub fn is_ros1_bag(path: &Path) -> bool {
    std::fs::File::open(path)
        .ok()
        .and_then(|f| first_bytes(f, path).ok())
        .is_some_and(|magic| magic.starts_with(ROS1_MAGIC))
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

/// The most bytes asked of an MCAP file in one read.
const READ_AT_MOST: usize = 1 << 20;

/// The longest MCAP record read from `file`: its own length, or 256 MiB if
/// that is more (a message in a compressed chunk may be longer than the
/// file that holds it; no ROS message a diagnosis reads comes near).
fn record_limit(file: &Path) -> usize {
    const FLOOR: usize = 256 << 20;
    std::fs::metadata(file)
        .map_or(FLOOR, |m| usize::try_from(m.len()).unwrap_or(usize::MAX))
        .max(FLOOR)
}

/// An MCAP stream, record by record: MCAP's own sans-io reader holds one
/// chunk at a time (decompressed), so memory does not grow with the file.
/// A file that ends in the middle of a record after some messages is what
/// a recorder killed before it wrote its summary leaves: every message
/// before the cut is whole (MCAP writes chunks whole), so they are read
/// and the cut is said.
fn mcap_messages(
    mut reader: impl std::io::Read,
    file: &Path,
    record_limit: usize,
    wanted: Wanted,
    take: &mut Take,
) -> Ended {
    use mcap::records::Record;
    use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader};
    let damaged = |e: &dyn std::fmt::Display| {
        BagError::new(file, format!("the bag is damaged or cut short: {e}"))
    };
    // Schema names by id; channels by id with their topic, type, encoding.
    let mut schemas: BTreeMap<u16, String> = BTreeMap::new();
    let mut channels: BTreeMap<u16, (String, String, String)> = BTreeMap::new();
    // A record longer than `record_limit` is an error: a damaged length
    // (the fuzzer's 72 PB) is never taken at its word.
    let mut stream = LinearReader::new_with_options(
        mcap::sans_io::linear_reader::LinearReaderOptions::default()
            .with_record_length_limit(record_limit),
    );
    let mut messages = 0_u64;
    while let Some(event) = stream.next_event() {
        let event = match event {
            Err(mcap::McapError::UnexpectedEof) if messages > 0 => {
                return Ok(Some(format!(
                    "{} ends in the middle of a record after {messages} messages (was its recorder killed?); \
                     reading the messages before the cut",
                    file.display()
                )));
            }
            other => other.map_err(|e| damaged(&e))?,
        };
        match event {
            LinearReadEvent::ReadRequest(need) => {
                // Asked for a whole record or chunk at once, the reader
                // would zero that much memory before a byte arrived; in
                // pieces, its buffer grows only with what the file holds.
                let read = reader
                    .read(stream.insert(need.min(READ_AT_MOST)))
                    .map_err(|e| BagError::new(file, format!("cannot read it: {e}")))?;
                stream.notify_read(read);
            }
            LinearReadEvent::Record { opcode, data } => {
                match mcap::parse_record(opcode, data).map_err(|e| damaged(&e))? {
                    Record::Schema { header, .. } => {
                        schemas.insert(header.id, header.name);
                    }
                    Record::Channel(channel) => {
                        let message_type = schemas
                            .get(&channel.schema_id)
                            .cloned()
                            .unwrap_or_else(|| "(no schema)".to_owned());
                        channels.insert(
                            channel.id,
                            (channel.topic, message_type, channel.message_encoding),
                        );
                    }
                    Record::Message { header, data } => {
                        messages += 1;
                        let Some((topic, message_type, encoding)) =
                            channels.get(&header.channel_id)
                        else {
                            return Err(damaged(&format!(
                                "a message of channel {} before the channel was described",
                                header.channel_id
                            )));
                        };
                        if !wanted.topic(topic) {
                            continue;
                        }
                        let log_time_ns = i64::try_from(header.log_time).map_err(|_| {
                            BagError::new(
                                file,
                                format!(
                                    "topic {topic}: log time {} ns is past the year 2262",
                                    header.log_time
                                ),
                            )
                        })?;
                        take(Stored {
                            file,
                            topic,
                            message_type,
                            encoding,
                            log_time_ns,
                            data: &data,
                        })?;
                    }
                    _ => {}
                }
            }
        }
    }
    Ok(None)
}

/// An sqlite3 bag file opened where it lies, read-only and as immutable:
/// SQLite then takes no lock and writes nothing beside it (no `-shm`, no
/// journal), so a bag on a read-only disk, or one another process holds,
/// reads alike. `None` for a path SQLite cannot be given as a URI (not
/// UTF-8), which is then read into memory instead.
fn sqlite_in_place(file: &Path) -> Option<rusqlite::Connection> {
    let path = file.to_str()?;
    // A URI's path is percent-decoded and ends at `?` or `#`.
    let mut escaped = String::with_capacity(path.len());
    for c in path.chars() {
        match c {
            '%' | '?' | '#' => escaped.push_str(&format!("%{:02X}", c as u32)),
            c => escaped.push(c),
        }
    }
    use rusqlite::OpenFlags;
    rusqlite::Connection::open_with_flags(
        format!("file:{escaped}?immutable=1"),
        OpenFlags::SQLITE_OPEN_READ_ONLY
            | OpenFlags::SQLITE_OPEN_URI
            | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .ok()
}

/// The `-wal` file beside an sqlite3 bag, if it holds anything: a
/// recorder in WAL mode (rosbag2's "resilient" preset) that was killed
/// leaves its last messages there, not yet moved into the bag.
fn unmerged_wal(file: &Path) -> Option<PathBuf> {
    let mut name = file.as_os_str().to_owned();
    name.push("-wal");
    let wal = PathBuf::from(name);
    std::fs::metadata(&wal)
        .is_ok_and(|m| m.is_file() && m.len() > 0)
        .then_some(wal)
}

/// An sqlite3 bag with messages still in its `-wal` file, read with them:
/// SQLite merges a WAL only into a database it may write beside, and the
/// user's bag is never written to (nor is a `-shm` created beside it), so
/// the two files are copied into a folder of our own and read there.
fn sqlite_with_wal(file: &Path, wal: &Path, wanted: Wanted, take: &mut Take) -> Ended {
    // Removed with our copies in it when dropped.
    let scratch = tempfile::Builder::new()
        .prefix("shoal-bag-")
        .tempdir()
        .map_err(|e| {
            BagError::new(
                &std::env::temp_dir(),
                format!(
                    "cannot make a folder in it to read {}'s -wal file: {e}",
                    file.display()
                ),
            )
        })?;
    let copy = |from: &Path, to: &Path| {
        std::fs::copy(from, to).map_err(|e| {
            BagError::new(
                from,
                format!(
                    "cannot copy it to {} to read its -wal file beside it: {e}",
                    to.display()
                ),
            )
        })
    };
    let (db_copy, wal_copy) = (
        scratch.path().join("bag.db3"),
        scratch.path().join("bag.db3-wal"),
    );
    copy(file, &db_copy)?;
    let wal_bytes = copy(wal, &wal_copy)?;
    use rusqlite::OpenFlags;
    let db = rusqlite::Connection::open_with_flags(
        &db_copy,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(|e| {
        BagError::new(
            file,
            format!("cannot read the sqlite3 bag with its -wal file: {e}"),
        )
    })?;
    sqlite_messages(&db, file, wanted, take)?;
    Ok(Some(format!(
        "{} has its last messages in {} ({wal_bytes} bytes; was its recorder killed?); read them too",
        file.display(),
        wal.display()
    )))
}

/// An sqlite3 bag held in memory (a decompressed file, a fuzzer's bytes).
fn sqlite_in_memory(bytes: &[u8], file: &Path) -> Result<rusqlite::Connection, BagError> {
    let sql_error =
        |e: rusqlite::Error| BagError::new(file, format!("cannot read the sqlite3 bag: {e}"));
    let mut db = rusqlite::Connection::open_in_memory().map_err(sql_error)?;
    let bytes = without_wal_mode(bytes);
    db.deserialize_read_exact(rusqlite::MAIN_DB, bytes.as_ref(), bytes.len(), true)
        .map_err(sql_error)?;
    Ok(db)
}

/// A rosbag2 sqlite3 file: `topics(id, name, type, serialization_format,
/// ...)` and `messages(id, topic_id, timestamp, data)`, the same in every
/// ROS 2 release from Foxy on; the message definitions, which Iron added,
/// are not needed (the types read here are decoded by their known layouts).
/// Only the wanted topics' rows are read, and a listing reads no data: a
/// message's data are pages of their own that SQLite then never loads.
fn sqlite_messages(
    db: &rusqlite::Connection,
    file: &Path,
    wanted: Wanted,
    take: &mut Take,
) -> Result<(), BagError> {
    let sql_error = |e: rusqlite::Error| {
        let damaged = e.sqlite_error_code() == Some(rusqlite::ErrorCode::DatabaseCorrupt);
        BagError::new(
            file,
            if damaged {
                format!("the sqlite3 bag is damaged or cut short: {e}")
            } else {
                format!("cannot read the sqlite3 bag: {e}")
            },
        )
    };
    let (data, only) = match wanted {
        Wanted::Headers => ("NULL", None),
        Wanted::Messages(topics) => ("messages.data", topics),
    };
    let filter = match only {
        Some(topics) => format!(
            "WHERE topics.name IN ({})",
            vec!["?"; topics.len()].join(", ")
        ),
        None => String::new(),
    };
    let mut query = db
        .prepare(&format!(
            "SELECT topics.name, topics.type, topics.serialization_format, messages.timestamp, {data} \
             FROM messages JOIN topics ON messages.topic_id = topics.id {filter} \
             ORDER BY messages.timestamp, messages.id"
        ))
        .map_err(|e| match e.sqlite_error_code() {
            Some(rusqlite::ErrorCode::DatabaseCorrupt) => sql_error(e),
            _ => BagError::new(
                file,
                format!("is a sqlite3 file without rosbag2's topics and messages tables: {e}"),
            ),
        })?;
    let mut rows = query
        .query(rusqlite::params_from_iter(only.unwrap_or_default()))
        .map_err(sql_error)?;
    while let Some(row) = rows.next().map_err(sql_error)? {
        let text = |k: usize| {
            row.get_ref(k)
                .and_then(|v| Ok(v.as_str()?))
                .map_err(sql_error)
        };
        let bytes = match row.get_ref(4).map_err(sql_error)? {
            rusqlite::types::ValueRef::Blob(b) => b,
            rusqlite::types::ValueRef::Null => &[],
            other => {
                return Err(BagError::new(
                    file,
                    format!("a message's data is {:?}, not a blob", other.data_type()),
                ));
            }
        };
        take(Stored {
            file,
            topic: text(0)?,
            message_type: text(1)?,
            encoding: text(2)?,
            log_time_ns: row.get(3).map_err(sql_error)?,
            data: bytes,
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

    #[test]
    fn files_listed_from_the_folder_above_or_under_an_old_name_are_found() {
        let root = std::env::temp_dir().join(format!("shoal-listed-{}", std::process::id()));
        let dir = root.join("renamed");
        std::fs::create_dir_all(&dir).expect("temporary folder");
        std::fs::write(dir.join("bag_0.db3"), b"").expect("file");
        // As rosbag2 writes it today; as Foxy's compressing writer did, with
        // the folder's name; and after the folder was renamed.
        for listed in ["bag_0.db3", "renamed/bag_0.db3", "recorded/bag_0.db3"] {
            assert_eq!(
                listed_file(&dir, listed),
                Some(dir.join("bag_0.db3")),
                "{listed}"
            );
        }
        assert_eq!(listed_file(&dir, "bag_1.db3"), None);
        std::fs::remove_dir_all(&root).expect("remove the temporary folder");
    }
}

//! The recording's file, written so that a failed write is seen at once and
//! what was written stays readable.
//!
//! Rerun's own `FileSink` writes on a thread of its own and only logs a
//! failed write: on a full disk the recorder went on, the launcher exited 0,
//! and the file ended in the middle of a message, which the official reader
//! refuses whole ("Message payload ... exceeds file size"). Here every
//! message is written whole or not at all (a failed write is cut back to the
//! last whole message), the first fault is kept for the recorder to report,
//! and no flush waits on a stuck disk longer than [`FLUSH_LIMIT`].

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rerun::external::re_log_encoding::{EncodeError, Encoder, EncodingOptions};
use rerun::log::LogMsg;
use rerun::sink::{LogSink, SinkFlushError};

/// The longest any flush or the file's end waits for the writer: a disk
/// that does not answer within it is reported, never waited out.
pub const FLUSH_LIMIT: Duration = Duration::from_secs(2);
/// Messages queued for the writer before the batcher waits (a second or two
/// of a large swarm's chunks).
const QUEUE: usize = 1024;

/// The first write that failed, and what the file kept.
#[derive(Clone, Debug)]
pub struct WriteFault {
    pub path: PathBuf,
    pub error: String,
    /// What the file holds: whole messages only, unless `cut_back` failed.
    pub kept_bytes: u64,
    /// Whether a partly written message was cut off (false: the file could
    /// not be shortened, e.g. its file system went read-only).
    pub cut_back: bool,
}

impl std::fmt::Display for WriteFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "cannot write the recording {}: {}; it keeps its first {} bytes",
            self.path.display(),
            self.error,
            self.kept_bytes
        )?;
        if !self.cut_back {
            write!(
                f,
                " (a partly written message may follow them: `shoal record --repair {}` cuts it off)",
                self.path.display()
            )?;
        }
        Ok(())
    }
}

/// What the recorder may ask of the file while the stream owns its sink.
#[derive(Clone)]
pub struct RrdFileState {
    path: PathBuf,
    shared: Arc<Shared>,
}

#[derive(Default)]
struct Shared {
    fault: Mutex<Option<WriteFault>>,
    written: AtomicU64,
    /// A partly written message could not be cut off (the file system went
    /// read-only, say): the file may end mid-message.
    cut_failed: std::sync::atomic::AtomicBool,
}

impl RrdFileState {
    pub fn fault(&self) -> Option<WriteFault> {
        self.shared.fault.lock().ok().and_then(|f| f.clone())
    }

    /// Bytes of whole messages in the file so far.
    pub fn written(&self) -> u64 {
        self.shared.written.load(Ordering::Relaxed)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

enum Command {
    Send(LogMsg),
    Flush(SyncSender<Result<(), String>>),
    /// Writes the footer and ends the writer.
    Finish(SyncSender<Result<(), String>>),
}

/// A Rerun sink that writes an `.rrd` file message by message.
pub struct RrdFileSink {
    queue: Mutex<Option<SyncSender<Command>>>,
    state: RrdFileState,
}

impl RrdFileSink {
    /// Creates (or replaces) `path` and starts its writer.
    pub fn create(path: &Path) -> anyhow::Result<(Self, RrdFileState)> {
        use anyhow::Context as _;
        let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let shared = Arc::new(Shared::default());
        let cutter = file.try_clone().context("duplicating the file handle")?;
        let out = WholeMessages {
            file,
            committed: 0,
            shared: Arc::clone(&shared),
        };
        let encoder = Encoder::new_eager(
            re_build_info::CrateVersion::LOCAL,
            EncodingOptions::PROTOBUF_COMPRESSED,
            out,
        )
        .map_err(|e| anyhow::anyhow!("writing the header of {}: {e}", path.display()))?;
        let state = RrdFileState {
            path: path.to_owned(),
            shared,
        };
        let (queue, commands) = std::sync::mpsc::sync_channel(QUEUE);
        let writer_state = state.clone();
        std::thread::Builder::new()
            .name("rrd-writer".into())
            .spawn(move || write_messages(encoder, &cutter, &commands, &writer_state))
            .context("starting the recording's writer thread")?;
        Ok((
            Self {
                queue: Mutex::new(Some(queue)),
                state: state.clone(),
            },
            state,
        ))
    }

    /// Writes the footer (the index the viewer seeks with) and ends the
    /// writer; within [`FLUSH_LIMIT`], or an error.
    pub fn finish(&self) -> Result<(), String> {
        let queue = self.queue.lock().ok().and_then(|mut q| q.take());
        match queue {
            Some(queue) => ask(&queue, Command::Finish, FLUSH_LIMIT),
            None => Ok(()),
        }
    }
}

/// Sends a command that answers, and waits for its answer at most `limit`.
fn ask(
    queue: &SyncSender<Command>,
    command: fn(SyncSender<Result<(), String>>) -> Command,
    limit: Duration,
) -> Result<(), String> {
    let (answer, answered) = std::sync::mpsc::sync_channel(1);
    queue
        .send(command(answer))
        .map_err(|_| "the recording's writer has ended".to_owned())?;
    match answered.recv_timeout(limit) {
        Ok(result) => result,
        Err(RecvTimeoutError::Timeout) => Err(format!(
            "the disk did not take the recording within {} s",
            limit.as_secs()
        )),
        Err(RecvTimeoutError::Disconnected) => Err("the recording's writer has ended".to_owned()),
    }
}

impl LogSink for RrdFileSink {
    fn send(&self, msg: LogMsg) {
        // A faulted file takes nothing more; the fault is already reported.
        if self.state.fault().is_some() {
            return;
        }
        if let Ok(queue) = self.queue.lock()
            && let Some(queue) = queue.as_ref()
        {
            let _ = queue.send(Command::Send(msg));
        }
    }

    fn flush_blocking(&self, timeout: Duration) -> Result<(), SinkFlushError> {
        let queue = self.queue.lock().ok().and_then(|q| q.clone());
        let Some(queue) = queue else {
            return Ok(());
        };
        ask(&queue, Command::Flush, timeout.min(FLUSH_LIMIT))
            .map_err(|message| SinkFlushError::Failed { message })
    }

    fn defers_finalization_to_shutdown(&self) -> bool {
        true
    }
}

impl Drop for RrdFileSink {
    fn drop(&mut self) {
        // A fault is the recorder's to report; only a stuck end is said here.
        if let Err(e) = self.finish()
            && self.state.fault().is_none()
        {
            eprintln!(
                "shoal-viewer-log: warning: ending {}: {e}; it reads to its last whole message, \
                 without the footer a viewer seeks with",
                self.state.path.display()
            );
        }
    }
}

/// The writer thread: appends each message whole, keeps the first fault.
fn write_messages(
    mut encoder: Encoder<WholeMessages>,
    cutter: &File,
    commands: &Receiver<Command>,
    state: &RrdFileState,
) {
    // After a fault the file takes nothing more, not even the footer the
    // encoder would add when dropped: it would refer to lost messages.
    let fail = |encoder: &mut Encoder<WholeMessages>, error: EncodeError| {
        encoder.do_not_emit_footer();
        let fault = encoder_fault(state, &error);
        if let Ok(mut slot) = state.shared.fault.lock()
            && slot.is_none()
        {
            *slot = Some(fault);
        }
    };
    while let Ok(command) = commands.recv() {
        match command {
            Command::Send(msg) => {
                if state.fault().is_none()
                    && let Err(e) = encoder.append(&msg)
                {
                    fail(&mut encoder, e);
                }
            }
            Command::Flush(answer) => {
                let _ = answer.send(match state.fault() {
                    Some(fault) => Err(fault.to_string()),
                    None => Ok(()),
                });
            }
            Command::Finish(answer) => {
                let result = match state.fault() {
                    Some(fault) => Err(fault.to_string()),
                    None => finish(&mut encoder, cutter, state).map_err(|e| {
                        fail(&mut encoder, e);
                        state.fault().map_or_else(String::new, |f| f.to_string())
                    }),
                };
                let _ = answer.send(result);
                return;
            }
        }
    }
    // Every sender gone without a finish: the footer is written anyway.
    if state.fault().is_none()
        && let Err(e) = finish(&mut encoder, cutter, state)
    {
        fail(&mut encoder, e);
    }
}

/// Writes the footer; a footer that fails half-way is cut off whole
/// (through `cutter`, a second handle on the file: the encoder keeps its
/// writer to itself), so the file ends on its last message.
fn finish(
    encoder: &mut Encoder<WholeMessages>,
    cutter: &File,
    state: &RrdFileState,
) -> Result<(), EncodeError> {
    let before = state.written();
    let result = encoder.finish();
    if result.is_err() && cutter.set_len(before).is_ok() {
        state.shared.written.store(before, Ordering::Relaxed);
    }
    result
}

fn encoder_fault(state: &RrdFileState, error: &EncodeError) -> WriteFault {
    WriteFault {
        path: state.path.clone(),
        error: match error {
            EncodeError::Write(e) => e.to_string(),
            other => other.to_string(),
        },
        kept_bytes: state.written(),
        cut_back: !state.shared.cut_failed.load(Ordering::Relaxed),
    }
}

/// The file under the encoder. The encoder writes each message (and each
/// piece of the footer) with one `write_all`; one that fails is cut back, so
/// the file always ends on a whole message.
struct WholeMessages {
    file: File,
    /// Bytes of whole messages.
    committed: u64,
    shared: Arc<Shared>,
}

impl WholeMessages {
    fn cut_back_to(&mut self, length: u64) -> bool {
        use std::io::Seek as _;
        let cut = self.file.set_len(length).is_ok()
            && self.file.seek(std::io::SeekFrom::Start(length)).is_ok();
        if cut {
            self.committed = length;
            self.shared.written.store(length, Ordering::Relaxed);
        }
        cut
    }
}

impl Write for WholeMessages {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.write_all(buf).map(|()| buf.len())
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        match self.file.write_all(buf) {
            Ok(()) => {
                self.committed += buf.len() as u64;
                self.shared.written.store(self.committed, Ordering::Relaxed);
                Ok(())
            }
            Err(e) => {
                let committed = self.committed;
                if !self.cut_back_to(committed) {
                    self.shared.cut_failed.store(true, Ordering::Relaxed);
                }
                Err(e)
            }
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

/// Bytes of an `.rrd` stream's header, and of each message's header (kind
/// and length, little-endian u64s): the layout of `re_log_encoding`'s
/// `StreamHeader` and `MessageHeader`, which it does not let a reader walk
/// without decoding every payload.
const STREAM_HEADER_BYTES: usize = 12;
const MESSAGE_HEADER_BYTES: usize = 16;
/// The message kind that ends a stream; the stream footer follows its payload.
const END_KIND: u64 = 0;
/// A stream footer with its one entry.
const STREAM_FOOTER_BYTES: usize = 32;

/// How much of an `.rrd` stream ends on a whole message: all of it for a
/// file written to its end, less a partial last message for one whose
/// writer was killed or lost power mid-write. None when it is no `.rrd`.
pub fn whole_prefix(bytes: &[u8]) -> Option<usize> {
    if bytes.len() < STREAM_HEADER_BYTES || &bytes[..4] != b"RRF2" {
        return None;
    }
    let mut at = STREAM_HEADER_BYTES;
    loop {
        let Some(header) = bytes.get(at..at + MESSAGE_HEADER_BYTES) else {
            return Some(at);
        };
        let (kind, len) = header.split_at(8);
        let kind = u64::from_le_bytes(kind.try_into().ok()?);
        let len = usize::try_from(u64::from_le_bytes(len.try_into().ok()?)).ok()?;
        let end = at
            .checked_add(MESSAGE_HEADER_BYTES)
            .and_then(|a| a.checked_add(len))?;
        if end > bytes.len() {
            return Some(at);
        }
        if kind == END_KIND {
            // The footer is whole, or the stream ends before its end marker.
            return Some(if bytes.len() - end >= STREAM_FOOTER_BYTES {
                bytes.len()
            } else {
                at
            });
        }
        at = end;
    }
}

/// Cuts a partial last message off the `.rrd` file at `path`, so every
/// reader reads it to its last whole message. Returns the bytes cut off.
pub fn cut_partial_tail(path: &Path) -> anyhow::Result<u64> {
    use anyhow::Context as _;
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let whole = whole_prefix(&bytes)
        .with_context(|| format!("{} is not a Rerun recording (.rrd)", path.display()))?;
    let cut = (bytes.len() - whole) as u64;
    if cut > 0 {
        std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .and_then(|f| f.set_len(whole as u64))
            .with_context(|| format!("cutting the partial last message off {}", path.display()))?;
    }
    Ok(cut)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A real recording of `frames` points written through the sink.
    fn record(path: &Path, frames: usize) -> RrdFileState {
        let (sink, state) = RrdFileSink::create(path).expect("create");
        let rec = rerun::RecordingStreamBuilder::new("shoal-test")
            .set_sinks(vec![Box::new(sink) as Box<dyn LogSink>])
            .expect("stream");
        for i in 0..frames {
            rec.set_time_sequence("tick", i as i64);
            rec.log("p", &rerun::Points2D::new([[i as f32, 0.0]]))
                .expect("log");
            rec.flush_blocking().expect("flush");
        }
        drop(rec);
        state
    }

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("shoal-rrd-file-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("folder");
        dir
    }

    #[test]
    fn a_whole_recording_ends_on_its_footer_and_a_cut_one_on_its_last_whole_message() {
        let dir = scratch("cut");
        let path = dir.join("r.rrd");
        let state = record(&path, 20);
        assert!(state.fault().is_none());
        let bytes = std::fs::read(&path).expect("read");
        assert_eq!(state.written(), bytes.len() as u64);
        assert_eq!(
            whole_prefix(&bytes),
            Some(bytes.len()),
            "a finished file is whole"
        );
        // Cut anywhere past the header, the file is whole up to a message
        // boundary at or before the cut, and a boundary is itself whole.
        let mut boundaries = std::collections::BTreeSet::new();
        for cut in (STREAM_HEADER_BYTES..bytes.len()).step_by(7) {
            let whole = whole_prefix(&bytes[..cut]).expect("still an rrd");
            assert!(whole <= cut && whole >= STREAM_HEADER_BYTES);
            assert_eq!(whole_prefix(&bytes[..whole]), Some(whole));
            boundaries.insert(whole);
        }
        assert!(boundaries.len() > 5, "messages found: {boundaries:?}");
        assert_eq!(whole_prefix(b"not a recording"), None);
        // The repair cuts a file's partial tail off, and only that.
        let cut_at = bytes.len() - 10;
        std::fs::write(&path, &bytes[..cut_at]).expect("write");
        let removed = cut_partial_tail(&path).expect("repair");
        let left = std::fs::metadata(&path).expect("stat").len();
        assert_eq!(left + removed, cut_at as u64);
        assert_eq!(cut_partial_tail(&path).expect("again"), 0);
        std::fs::remove_dir_all(dir).expect("cleanup");
    }

    #[test]
    fn a_file_that_cannot_be_created_is_an_error_naming_it() {
        let missing = Path::new("/nonexistent-shoal-folder/r.rrd");
        let error = RrdFileSink::create(missing).err().expect("an error");
        assert!(format!("{error:#}").contains("/nonexistent-shoal-folder/r.rrd"));
    }
}

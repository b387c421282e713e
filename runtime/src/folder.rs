//! A swarm's small on-disk footprint beside the bus: the scenario it runs, its
//! clock mode, and each robot's last pose, so `shoal restart` and `shoal
//! spawn` work from any terminal. It is a notebook, not a controller: robots
//! never read each other's files.

use std::io;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SwarmMeta {
    /// Robots step on the clock's ticks instead of on their own timers.
    pub lockstep: bool,
    /// The shared time origin of a real-time swarm, ms since the Unix epoch.
    pub epoch_unix_ms: u64,
    pub period_s: f64,
}

/// The lock whose holder sweeps the swarm's dead nodes. The file says when
/// the last finished sweep started (ms since the Unix epoch).
const SWEEP_LOCK: &str = "sweep";

/// What came of [`SwarmRuntime::sweep_unless_swept_since`].
#[derive(Debug, PartialEq, Eq)]
pub enum Sweep<R> {
    /// This process swept; what the sweep returned.
    Done(R),
    /// A sweep that started after the dead node was noticed has finished.
    AlreadyDone,
    /// Another process is sweeping now.
    Busy,
}

/// A report a helper process keeps in the swarm's folder for the other
/// processes (SLAM's for `shoal status`; the link's for the launcher,
/// `kill`, `spawn` and the recorder). Its type lives with the helper that
/// writes it; the folder only stores it.
pub trait HelperReport: Serialize + serde::de::DeserializeOwned {
    /// Its file in the swarm's folder.
    const FILE: &'static str;
    /// The process that writes it: a report whose writer is gone says
    /// nothing of today.
    fn writer_pid(&self) -> u32;
}

/// A report that is there but cannot be read: an error to show, never
/// taken for an absent helper.
#[derive(Debug, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct ReportError {
    pub path: PathBuf,
    pub message: String,
}

#[derive(Clone, Debug)]
pub struct SwarmRuntime {
    /// The per-user root all swarms' folders live in.
    pub root: PathBuf,
    pub dir: PathBuf,
}

/// The file that marks a folder as one Shoal created for a swarm. Shoal only
/// ever removes a folder that holds it, so a `--swarm` or
/// `SHOAL_RUNTIME_DIR` that names a user's own folder is refused, not
/// emptied.
const OWNER_MARK: &str = ".shoal-swarm";
const OWNER_MARK_TEXT: &str =
    "This folder was created by Shoal for one swarm and is removed when the swarm stops.\n";

impl SwarmRuntime {
    /// `$SHOAL_RUNTIME_DIR/<swarm>`, or `<tmp>/shoal-<uid>/<swarm>`; for a
    /// host of a swarm that is not this machine's own (`--host`), in
    /// `host-<name>/` below that, so two hosts on one machine keep
    /// separate folders as two machines would.
    pub fn locate(swarm: &str) -> Self {
        Self::locate_on(swarm, crate::host::current())
    }

    /// The folder of swarm `swarm`'s part on `host` (of this machine).
    pub fn locate_on(swarm: &str, host: &crate::host::Host) -> Self {
        let base = std::env::var_os("SHOAL_RUNTIME_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| std::env::temp_dir().join(format!("shoal-{}", current_uid())));
        let root = if host.separate {
            base.join(format!("host-{}", host.name))
        } else {
            base
        };
        Self {
            dir: root.join(swarm),
            root,
        }
    }

    /// Creates the per-user root (mode 0700) if it is missing, and refuses a
    /// root that is a symlink, belongs to someone else, or that others may
    /// write to: anyone who can write there could make Shoal write, or
    /// remove, through a link of theirs.
    pub fn check_root(&self) -> io::Result<()> {
        use std::os::unix::fs::{DirBuilderExt, MetadataExt};
        match std::fs::symlink_metadata(&self.root) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => std::fs::DirBuilder::new()
                .recursive(true)
                .mode(0o700)
                .create(&self.root)
                .map_err(|e| with_path(e, &self.root, "cannot create Shoal's runtime folder")),
            Err(e) => Err(with_path(
                e,
                &self.root,
                "cannot inspect Shoal's runtime folder",
            )),
            Ok(meta) => {
                let refuse = |why: String| {
                    io::Error::new(
                        io::ErrorKind::PermissionDenied,
                        format!(
                            "{}: refusing to use it as Shoal's runtime folder: {why} (set SHOAL_RUNTIME_DIR to a folder of your own)",
                            self.root.display()
                        ),
                    )
                };
                if meta.file_type().is_symlink() {
                    return Err(refuse("it is a symbolic link".into()));
                }
                if !meta.is_dir() {
                    return Err(refuse("it is not a folder".into()));
                }
                if meta.uid() != current_uid() {
                    return Err(refuse(format!(
                        "it belongs to uid {}, not to you (uid {})",
                        meta.uid(),
                        current_uid()
                    )));
                }
                if meta.mode() & 0o022 != 0 {
                    return Err(refuse(format!(
                        "others may write to it (mode {:o})",
                        meta.mode() & 0o7777
                    )));
                }
                Ok(())
            }
        }
    }

    /// Runs `sweep`, a removal of the swarm's dead nodes, unless a sweep
    /// that started at or after `since` has finished meanwhile: one process
    /// of the swarm sweeps at a time, and the others take its result. A
    /// sweep lists every node of the machine, reading each one's details:
    /// when 50 of 1000 robots were killed, each of their neighbours swept
    /// at once and the swarm spent three minutes on it (BENCHMARKS.md,
    /// build 0676a74). With `wait` false a sweep under way makes this return
    /// [`Sweep::Busy`] at once; the caller asks again later.
    pub fn sweep_unless_swept_since<R>(
        &self,
        since: std::time::SystemTime,
        wait: bool,
        sweep: impl FnOnce() -> R,
    ) -> io::Result<Sweep<R>> {
        use std::io::{Seek, Write};
        if self.last_sweep_start().is_some_and(|start| start >= since) {
            return Ok(Sweep::AlreadyDone);
        }
        let mut lock = match self.lock(SWEEP_LOCK, wait) {
            Ok(file) => file,
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(Sweep::Busy),
            Err(e) => return Err(e),
        };
        // One may have finished between the look above and the lock.
        if self.last_sweep_start().is_some_and(|start| start >= since) {
            return Ok(Sweep::AlreadyDone);
        }
        let started = std::time::SystemTime::now();
        let result = sweep();
        let started_ms = started
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis());
        lock.set_len(0)?;
        lock.rewind()?;
        write!(lock, "{started_ms}")?;
        Ok(Sweep::Done(result))
    }

    /// When the last finished sweep of dead nodes started, as its sweeper
    /// wrote it into the sweep lock.
    fn last_sweep_start(&self) -> Option<std::time::SystemTime> {
        let text = read_no_follow(&self.lock_path(SWEEP_LOCK)).ok()?;
        let ms: u64 = text.trim().parse().ok()?;
        Some(std::time::UNIX_EPOCH + std::time::Duration::from_millis(ms))
    }

    fn lock_path(&self, role: &str) -> PathBuf {
        let name = self
            .dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        self.root.join(format!("{name}.{role}.lock"))
    }

    /// Takes the swarm's `role` lock (`launch`: one `shoal up` per swarm;
    /// `ids`: one command picking new robot ids at a time). The lock lives
    /// beside the swarm's folder, in the root, and is released when the
    /// returned file is dropped or the process dies. With `wait` false a
    /// held lock is an error naming it.
    pub fn lock(&self, role: &str, wait: bool) -> io::Result<std::fs::File> {
        use std::os::fd::AsRawFd;
        self.check_root()?;
        let path = self.lock_path(role);
        let file = {
            use std::os::unix::fs::OpenOptionsExt;
            std::fs::OpenOptions::new()
                .write(true)
                .create(true)
                .truncate(false)
                .mode(0o600)
                .custom_flags(libc::O_NOFOLLOW)
                .open(&path)
                .map_err(|e| with_path(e, &path, "cannot open lock"))?
        };
        let operation = if wait {
            libc::LOCK_EX
        } else {
            libc::LOCK_EX | libc::LOCK_NB
        };
        // SAFETY: flock on a descriptor this function owns.
        if unsafe { libc::flock(file.as_raw_fd(), operation) } != 0 {
            let e = io::Error::last_os_error();
            if e.kind() == io::ErrorKind::WouldBlock {
                return Err(io::Error::new(
                    io::ErrorKind::WouldBlock,
                    format!(
                        "{}: another shoal command holds this swarm's {role} lock",
                        path.display()
                    ),
                ));
            }
            return Err(with_path(e, &path, "cannot lock"));
        }
        Ok(file)
    }

    /// Whether the swarm's folder is one Shoal made (holds the owner mark and
    /// is a real folder, not a link to one).
    fn is_ours(&self) -> io::Result<bool> {
        match std::fs::symlink_metadata(&self.dir) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(false),
            Err(e) => Err(e),
            Ok(meta) if !meta.is_dir() || meta.file_type().is_symlink() => Ok(false),
            Ok(_) => {
                Ok(read_no_follow(&self.dir.join(OWNER_MARK)).is_ok_and(|t| t == OWNER_MARK_TEXT))
            }
        }
    }

    /// Makes an empty folder for a new run of the swarm: removes the last
    /// run's folder if Shoal made it, and refuses one it did not.
    pub fn prepare(&self) -> io::Result<()> {
        use std::os::unix::fs::DirBuilderExt;
        self.check_root()?;
        self.remove()?;
        std::fs::DirBuilder::new()
            .mode(0o700)
            .create(&self.dir)
            .map_err(|e| with_path(e, &self.dir, "cannot create the swarm's folder"))?;
        write_atomically(&self.dir.join(OWNER_MARK), OWNER_MARK_TEXT)
    }

    /// Removes the swarm's folder, only if Shoal made it; anything else at
    /// that path is left alone and named in the error.
    pub fn remove(&self) -> io::Result<()> {
        if std::fs::symlink_metadata(&self.dir).is_err_and(|e| e.kind() == io::ErrorKind::NotFound)
        {
            return Ok(());
        }
        if !self.is_ours()? {
            return Err(io::Error::new(
                io::ErrorKind::AlreadyExists,
                format!(
                    "{} exists and was not created by Shoal (it has no {OWNER_MARK} file); Shoal never removes what it did not create: pick another --swarm name or SHOAL_RUNTIME_DIR",
                    self.dir.display()
                ),
            ));
        }
        std::fs::remove_dir_all(&self.dir)
    }

    /// Removes the swarm's state but keeps its logs, so the user can read
    /// why a robot died after the swarm stopped.
    pub fn remove_all_but_logs(&self) -> io::Result<()> {
        if !self.is_ours()? {
            return Ok(());
        }
        for entry in std::fs::read_dir(&self.dir)? {
            let path = entry?.path();
            let keep = path.extension().is_some_and(|e| e == "log")
                || path.file_name().is_some_and(|n| n == OWNER_MARK);
            if keep {
                continue;
            }
            // Inside a folder Shoal made; remove_dir_all does not follow links.
            if std::fs::symlink_metadata(&path)?.is_dir() {
                std::fs::remove_dir_all(&path)?;
            } else {
                std::fs::remove_file(&path)?;
            }
        }
        Ok(())
    }

    /// Creates (or empties) a log file in the swarm's folder, refusing to
    /// write through a symlink someone put there.
    pub fn create_log(&self, name: &str) -> io::Result<std::fs::File> {
        let path = self.dir.join(name);
        open_no_follow(&path, true).map_err(|e| with_path(e, &path, "cannot create log"))
    }

    /// The last `lines` lines of a log in the swarm's folder.
    pub fn log_tail(&self, name: &str, lines: usize) -> Vec<String> {
        let text = read_no_follow(&self.dir.join(name)).unwrap_or_default();
        let all: Vec<&str> = text.lines().collect();
        all[all.len().saturating_sub(lines)..]
            .iter()
            .map(|l| (*l).to_owned())
            .collect()
    }

    /// Marks robot `id` as stopped on purpose by a user's command, so the
    /// launcher does not report its death as a failure.
    pub fn mark_stopped_by_user(&self, id: u32) -> io::Result<()> {
        write_atomically(&self.stopped_path(id), "")
    }

    /// Whether robot `id` was stopped by a user's command; forgets it.
    pub fn take_stopped_by_user(&self, id: u32) -> bool {
        std::fs::remove_file(self.stopped_path(id)).is_ok()
    }

    fn stopped_path(&self, id: u32) -> PathBuf {
        self.dir.join(format!("agent-{id}.stopped"))
    }

    pub fn scenario_path(&self) -> PathBuf {
        self.dir.join("scenario.toml")
    }

    fn meta_path(&self) -> PathBuf {
        self.dir.join("swarm.toml")
    }

    /// The name of robot `id`'s log in the swarm's folder.
    pub fn agent_log_name(id: u32) -> String {
        format!("agent-{id}.log")
    }

    pub fn log_path(&self, id: u32) -> PathBuf {
        self.dir.join(Self::agent_log_name(id))
    }

    fn pose_path(&self, id: u32) -> PathBuf {
        self.dir.join(format!("agent-{id}.pose"))
    }

    /// A fresh folder for the swarm holding its scenario and clock mode.
    pub fn create(&self, scenario_toml: &str, meta: &SwarmMeta) -> io::Result<()> {
        self.prepare()?;
        write_atomically(&self.scenario_path(), scenario_toml)?;
        let meta = toml::to_string(meta).map_err(io::Error::other)?;
        write_atomically(&self.meta_path(), &meta)
    }

    /// Whether the swarm still runs: its launcher removes the swarm's files
    /// when it stops. Helpers started from another terminal (`shoal slam`,
    /// `shoal record`) end by it rather than outlive their swarm.
    pub fn is_up(&self) -> bool {
        self.meta_path().exists()
    }

    pub fn read_meta(&self) -> io::Result<SwarmMeta> {
        let path = self.meta_path();
        let text = read_no_follow(&path).map_err(|e| {
            io::Error::new(
                e.kind(),
                format!("{}: {e} (is the swarm running?)", path.display()),
            )
        })?;
        toml::from_str(&text).map_err(|e| {
            io::Error::new(
                io::ErrorKind::InvalidData,
                format!("{}: {e}", path.display()),
            )
        })
    }

    /// A helper's report in the swarm's folder, written whole so a reader
    /// never sees half of one.
    pub fn write_report<R: HelperReport>(&self, report: &R) -> io::Result<()> {
        let text = toml::to_string(report).map_err(io::Error::other)?;
        write_atomically(&self.dir.join(R::FILE), &text)
    }

    /// A helper's report, if its writer still runs: `None` when there is no
    /// report or its writer is gone; an error when the file is there but
    /// cannot be read or parsed.
    pub fn read_report<R: HelperReport>(&self) -> Result<Option<R>, ReportError> {
        let path = self.dir.join(R::FILE);
        let text = match read_no_follow(&path) {
            Ok(text) => text,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => {
                return Err(ReportError {
                    path,
                    message: format!("cannot read it: {e}"),
                });
            }
        };
        let report: R = toml::from_str(&text).map_err(|e| ReportError {
            path: path.clone(),
            message: format!("not a report Shoal can read: {}", e.message()),
        })?;
        Ok(crate::pid_alive(report.writer_pid() as i32).then_some(report))
    }

    pub fn write_last_pose(&self, id: u32, pose: [f64; 3]) -> io::Result<()> {
        write_atomically(&self.pose_path(id), &pose_line(pose))
    }

    /// Where robot `id` notes its pose as it goes, for `shoal restart`.
    pub fn pose_note(&self, id: u32) -> io::Result<PoseNote> {
        let path = self.pose_path(id);
        let file = open_no_follow(&path, true).map_err(|e| with_path(e, &path, "creating"))?;
        Ok(PoseNote {
            file,
            path,
            noted: None,
        })
    }

    pub fn read_last_pose(&self, id: u32) -> Option<[f64; 3]> {
        let text = read_no_follow(&self.pose_path(id)).ok()?;
        let values: Vec<f64> = text
            .split_whitespace()
            .filter_map(|v| v.parse().ok())
            .collect();
        match values[..] {
            [x, y, theta] if values.iter().all(|v| v.is_finite()) => Some([x, y, theta]),
            _ => None,
        }
    }

    /// Ids of every robot that ever wrote a pose in this swarm.
    pub fn known_agent_ids(&self) -> Vec<u32> {
        let Ok(entries) = std::fs::read_dir(&self.dir) else {
            return Vec::new();
        };
        entries
            .filter_map(|e| e.ok())
            .filter_map(|e| {
                let name = e.file_name().into_string().ok()?;
                name.strip_prefix("agent-")?
                    .strip_suffix(".pose")?
                    .parse()
                    .ok()
            })
            .collect()
    }
}

/// A robot's last pose, noted in place: one file, opened once, whose one
/// line of fixed width is rewritten at its start. Writing a new file and
/// renaming it over the old one takes the folder's lock, and a thousand
/// robots queued on that lock for a fifth of the machine's time
/// (BENCHMARKS.md, "1000 robots in real time"). A write this small is never seen half done
/// by a robot that is killed, and the pose is read only once it is dead.
pub struct PoseNote {
    file: std::fs::File,
    path: PathBuf,
    /// The pose the file holds, once one was written.
    noted: Option<[f64; 3]>,
}

/// A pose is noted again only once the robot moved this far (metres) or
/// turned this much (radians): a thousand robots standing in formation
/// need not rewrite anything.
const NOTED_POSE_MOVE_M: f64 = 0.05;
const NOTED_POSE_TURN_RAD: f64 = 0.05;

impl PoseNote {
    pub fn write(&self, pose: [f64; 3]) -> io::Result<()> {
        use std::os::unix::fs::FileExt;
        self.file
            .write_all_at(pose_line(pose).as_bytes(), 0)
            .map_err(|e| with_path(e, &self.path, "noting the pose"))
    }

    /// Notes `pose` if the robot moved or turned enough since the pose
    /// noted last (or none was).
    pub fn note_if_moved(&mut self, pose: [f64; 3]) -> io::Result<()> {
        let moved = self.noted.is_none_or(|[x, y, theta]| {
            (pose[0] - x).hypot(pose[1] - y) >= NOTED_POSE_MOVE_M
                || (pose[2] - theta).abs() >= NOTED_POSE_TURN_RAD
        });
        if moved {
            self.write(pose)?;
            self.noted = Some(pose);
        }
        Ok(())
    }
}

/// A pose as one line of fixed width (26 characters a number), so that
/// rewriting it in place never leaves the end of a longer one behind.
fn pose_line(pose: [f64; 3]) -> String {
    format!(
        "{:>+26.16e} {:>+26.16e} {:>+26.16e}\n",
        pose[0], pose[1], pose[2]
    )
}

/// Readers never see half a file: write beside, then rename (a rename
/// replaces a link at `path`, never what it points to).
fn write_atomically(path: &Path, text: &str) -> io::Result<()> {
    use std::io::Write;
    let partial = partial_path(path);
    open_no_follow(&partial, true)?.write_all(text.as_bytes())?;
    std::fs::rename(&partial, path).map_err(|e| with_path(e, path, "writing"))
}

/// Where `path` is written before it is renamed into place: unique to the
/// file and the writing process. (`agent-3.partial` once served both a
/// robot's `agent-3.pose` and the launcher's `agent-3.stopped`; the two
/// processes renamed each other's file away, and the chaos run failed with
/// a bare "No such file or directory".)
fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{}.partial", std::process::id()));
    path.with_file_name(name)
}

fn current_uid() -> u32 {
    // SAFETY: getuid has no preconditions and cannot fail.
    unsafe { libc::getuid() }
}

fn with_path(e: io::Error, path: &Path, what: &str) -> io::Error {
    io::Error::new(e.kind(), format!("{}: {what}: {e}", path.display()))
}

/// Opens `path` for writing (created 0600, emptied), or for reading, and
/// fails instead of following a symbolic link.
fn open_no_follow(path: &Path, write: bool) -> io::Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    let mut options = std::fs::OpenOptions::new();
    if write {
        options.write(true).create(true).truncate(true).mode(0o600);
    } else {
        options.read(true);
    }
    options.custom_flags(libc::O_NOFOLLOW).open(path)
}

fn read_no_follow(path: &Path) -> io::Result<String> {
    use std::io::Read;
    let mut text = String::new();
    open_no_follow(path, false)?.read_to_string(&mut text)?;
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    /// A robot's pose and the launcher's stop mark, written at once by two
    /// processes, never share the file they are written through.
    #[test]
    fn files_of_one_robot_are_written_through_files_of_their_own() {
        let dir = Path::new("/tmp/shoal-x/swarm");
        let pose = partial_path(&dir.join("agent-3.pose"));
        let stopped = partial_path(&dir.join("agent-3.stopped"));
        assert_ne!(pose, stopped);
        assert_eq!(pose.parent(), Some(dir));
        assert!(
            pose.to_string_lossy()
                .ends_with(&format!("agent-3.pose.{}.partial", std::process::id())),
            "{}",
            pose.display()
        );
    }

    fn runtime_in(root: &Path, swarm: &str) -> SwarmRuntime {
        SwarmRuntime {
            root: root.to_owned(),
            dir: root.join(swarm),
        }
    }

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("shoal-runtime-test-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch folder");
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).expect("chmod");
        dir
    }

    fn meta() -> SwarmMeta {
        SwarmMeta {
            lockstep: false,
            epoch_unix_ms: 0,
            period_s: 0.2,
        }
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct TestReport {
        pid: u32,
        steps: u64,
    }

    impl HelperReport for TestReport {
        const FILE: &'static str = "test-report.toml";
        fn writer_pid(&self) -> u32 {
            self.pid
        }
    }

    /// A report reads back as written while its writer runs; a missing one
    /// or one whose writer is gone is no report; a corrupt one is an error
    /// naming the file, never taken for an absent helper.
    #[test]
    fn a_report_reads_back_and_a_corrupt_one_is_an_error_not_an_absent_helper() {
        let root = scratch("report");
        let runtime = runtime_in(&root, "s");
        runtime.create("", &meta()).expect("create");
        assert!(matches!(runtime.read_report::<TestReport>(), Ok(None)));
        let mine = TestReport {
            pid: std::process::id(),
            steps: 7,
        };
        runtime.write_report(&mine).expect("write");
        assert_eq!(
            runtime.read_report::<TestReport>().expect("read"),
            Some(mine)
        );
        // No process has pid 0 to own it: a report of a writer that is gone.
        runtime
            .write_report(&TestReport { pid: 0, steps: 1 })
            .expect("write");
        assert!(matches!(runtime.read_report::<TestReport>(), Ok(None)));
        std::fs::write(
            runtime.dir.join(TestReport::FILE),
            "pid = 12\nsteps = \"many\"\n",
        )
        .expect("corrupt it");
        let error = runtime.read_report::<TestReport>().unwrap_err().to_string();
        assert!(error.contains("test-report.toml"), "{error}");
        assert!(error.contains("not a report Shoal can read"), "{error}");
        std::fs::remove_dir_all(&root).expect("cleanup");
    }

    #[test]
    fn a_folder_shoal_did_not_make_is_never_removed() {
        let root = scratch("foreign");
        let documents = root.join("Documents");
        std::fs::create_dir(&documents).expect("user folder");
        std::fs::write(documents.join("thesis.txt"), "years of work").expect("user file");
        let runtime = runtime_in(&root, "Documents");
        let error = runtime.create("", &meta()).unwrap_err();
        assert!(
            error.to_string().contains("not created by Shoal"),
            "{error}"
        );
        assert!(runtime.remove().is_err());
        assert_eq!(
            std::fs::read_to_string(documents.join("thesis.txt")).expect("still there"),
            "years of work"
        );
        std::fs::remove_dir_all(&root).expect("cleanup");
    }

    #[test]
    fn a_symlinked_swarm_folder_is_neither_followed_nor_removed() {
        let root = scratch("link");
        let target = scratch("link-target");
        std::fs::write(target.join(OWNER_MARK), OWNER_MARK_TEXT).expect("a forged mark");
        std::fs::write(target.join("keep.txt"), "mine").expect("user file");
        std::os::unix::fs::symlink(&target, root.join("lab")).expect("symlink");
        let runtime = runtime_in(&root, "lab");
        assert!(runtime.create("", &meta()).is_err());
        assert!(target.join("keep.txt").exists());
        std::fs::remove_dir_all(&root).expect("cleanup");
        std::fs::remove_dir_all(&target).expect("cleanup");
    }

    #[test]
    fn one_sweep_serves_every_death_noticed_before_it_started() {
        let root = scratch("sweep");
        let runtime = runtime_in(&root, "lab");
        let noticed = std::time::SystemTime::now() - std::time::Duration::from_secs(1);
        assert_eq!(
            runtime
                .sweep_unless_swept_since(noticed, false, || 3)
                .expect("sweep"),
            Sweep::Done(3)
        );
        // Noticed before that sweep started: nothing more to do.
        assert_eq!(
            runtime
                .sweep_unless_swept_since(noticed, false, || 4)
                .expect("sweep"),
            Sweep::AlreadyDone
        );
        // While another process holds the lock, a robot does not wait.
        let later = std::time::SystemTime::now() + std::time::Duration::from_secs(1);
        let held = runtime.lock(SWEEP_LOCK, false).expect("lock");
        assert_eq!(
            runtime
                .sweep_unless_swept_since(later, false, || 5)
                .expect("sweep"),
            Sweep::Busy
        );
        drop(held);
        // Noticed after the last sweep started: it sweeps again.
        assert_eq!(
            runtime
                .sweep_unless_swept_since(later, false, || 6)
                .expect("sweep"),
            Sweep::Done(6)
        );
        std::fs::remove_dir_all(&root).expect("cleanup");
    }

    #[test]
    fn a_pose_noted_in_place_reads_back_whatever_was_noted_before() {
        let root = scratch("note");
        let runtime = runtime_in(&root, "lab");
        runtime.create("name = 'x'", &meta()).expect("created");
        let note = runtime.pose_note(4).expect("note");
        note.write([-123456.789, 1e-9, 3.0]).expect("long pose");
        note.write([1.5, 2.0, -0.25]).expect("short pose");
        assert_eq!(runtime.read_last_pose(4), Some([1.5, 2.0, -0.25]));
        let pose = [0.1 + 0.2, 1.0 / 3.0, -std::f64::consts::PI];
        note.write(pose).expect("exact pose");
        assert_eq!(
            runtime.read_last_pose(4),
            Some(pose),
            "noted to the last bit"
        );
        let mut note = runtime.pose_note(5).expect("note");
        note.note_if_moved([1.0, 1.0, 0.0]).expect("first pose");
        note.note_if_moved([1.01, 1.0, 0.01]).expect("barely moved");
        assert_eq!(
            runtime.read_last_pose(5),
            Some([1.0, 1.0, 0.0]),
            "not worth a write"
        );
        note.note_if_moved([1.1, 1.0, 0.0]).expect("moved");
        assert_eq!(runtime.read_last_pose(5), Some([1.1, 1.0, 0.0]));
        runtime.remove().expect("removed");
        std::fs::remove_dir_all(&root).expect("cleanup");
    }

    #[test]
    fn shoal_removes_its_own_folder_and_keeps_logs_when_asked() {
        let root = scratch("own");
        let runtime = runtime_in(&root, "lab");
        runtime.create("name = 'x'", &meta()).expect("created");
        std::io::Write::write_all(
            &mut runtime.create_log("agent-1.log").expect("log"),
            b"one\ntwo\nthree\n",
        )
        .expect("write");
        runtime.write_last_pose(1, [1.0, 2.0, 0.0]).expect("pose");
        runtime.remove_all_but_logs().expect("state removed");
        assert!(runtime.log_path(1).exists());
        assert!(!runtime.scenario_path().exists());
        assert_eq!(runtime.log_tail("agent-1.log", 2), ["two", "three"]);
        runtime
            .create("name = 'x'", &meta())
            .expect("a new run replaces our own folder");
        runtime.remove().expect("removed");
        assert!(!runtime.dir.exists());
        std::fs::remove_dir_all(&root).expect("cleanup");
    }

    #[test]
    fn a_root_others_may_write_to_is_refused() {
        let root = scratch("open-root");
        std::fs::set_permissions(&root, std::fs::Permissions::from_mode(0o777)).expect("chmod");
        let error = runtime_in(&root, "lab").check_root().unwrap_err();
        assert!(error.to_string().contains("others may write"), "{error}");
        std::fs::remove_dir_all(&root).expect("cleanup");
    }

    #[test]
    fn a_missing_root_is_created_private() {
        let parent = scratch("new-root");
        let root = parent.join("shoal");
        runtime_in(&root, "lab").check_root().expect("created");
        let mode = std::fs::metadata(&root)
            .expect("exists")
            .permissions()
            .mode();
        assert_eq!(mode & 0o777, 0o700);
        std::fs::remove_dir_all(&parent).expect("cleanup");
    }
}

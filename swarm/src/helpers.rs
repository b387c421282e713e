//! The processes that serve a swarm beside its robots: the recorder, SLAM
//! and the link to other hosts. Each is started with its log in the swarm's
//! folder; one that ends unasked is reported as a death, with its log's end.
//! The supervisor owns them as one [`Helpers`].

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::{Context, Result};
use shoal_broker::liveness::remove_dead_nodes;
use shoal_runtime::SwarmRuntime;

use crate::deaths::{Death, helper_log_name};
use crate::helper_log::HelperLog;
use crate::pacing::pace_name;
use crate::process::{Pinned, RECORDER_BINARY, SLAM_BINARY, Tie, sibling_binary, stop_processes};

/// How long a helper (the recorder writing its footer) gets to leave cleanly.
const HELPER_GRACE: Duration = Duration::from_secs(10);

/// A process that serves the swarm (recorder, SLAM, link).
struct Helper {
    binary: String,
    child: Child,
    log: HelperLog,
}

/// The processes that serve a swarm: those running, the recording the
/// recorder writes, and what stopping them cost.
#[derive(Default)]
pub(crate) struct Helpers {
    running: Vec<Helper>,
    recording: Option<PathBuf>,
    stop_notes: Vec<String>,
}

/// Where the recorder sends the run: a file, a live viewer, or both.
#[derive(Clone, Debug, Default)]
pub struct RecordOptions {
    pub out: Option<std::path::PathBuf>,
    /// With `out`: each robot's trajectories as TUM files here, for evo.
    pub tum: Option<std::path::PathBuf>,
    /// A Rerun viewer started now.
    pub viewer: bool,
    /// A Rerun viewer already running at this address.
    pub connect: Option<String>,
    /// How long the run lasts, if known: the recorder warns at the start
    /// when the disk will not hold it.
    pub expected_seconds: Option<f64>,
}

impl RecordOptions {
    /// Into a file (and TUM files beside it, if `tum`).
    pub fn file(out: &std::path::Path, tum: Option<&std::path::Path>) -> Self {
        Self {
            out: Some(out.to_owned()),
            tum: tum.map(ToOwned::to_owned),
            ..Self::default()
        }
    }

    pub fn wanted(&self) -> bool {
        self.out.is_some() || self.viewer || self.connect.is_some()
    }

    /// The recorder's arguments (beside `--swarm`).
    pub fn recorder_args(&self) -> Vec<std::ffi::OsString> {
        let mut args = Vec::new();
        if let Some(out) = &self.out {
            args.push(out.as_os_str().to_owned());
        }
        if let Some(tum) = &self.tum {
            args.extend(["--tum".into(), tum.as_os_str().to_owned()]);
        }
        if self.viewer {
            args.push("--viewer".into());
        }
        if let Some(addr) = &self.connect {
            args.extend(["--connect".into(), addr.into()]);
        }
        if let Some(seconds) = self.expected_seconds {
            args.extend(["--expected-seconds".into(), seconds.to_string().into()]);
        }
        args
    }
}

/// How this host's part of a swarm joins the other hosts' (`--link zenoh`).
#[derive(Clone, Debug, Default)]
pub struct LinkOptions {
    /// A Zenoh configuration file: mode, endpoints, TLS, access control.
    pub zenoh_config: Option<std::path::PathBuf>,
    pub listen: Vec<String>,
    pub connect: Vec<String>,
}

impl LinkOptions {
    pub(crate) fn args(&self, swarm: &str) -> Vec<std::ffi::OsString> {
        let mut args: Vec<std::ffi::OsString> = vec!["--swarm".into(), swarm.into()];
        if let Some(file) = &self.zenoh_config {
            args.extend(["--zenoh-config".into(), file.clone().into_os_string()]);
        }
        for endpoint in &self.listen {
            args.extend(["--listen".into(), endpoint.into()]);
        }
        for endpoint in &self.connect {
            args.extend(["--connect".into(), endpoint.into()]);
        }
        args
    }
}

impl Helpers {
    /// Starts helper `binary` with `args`, its output into its log in the
    /// swarm's folder.
    pub(crate) fn start(
        &mut self,
        runtime: &SwarmRuntime,
        tie: Tie,
        binary: &str,
        args: &[OsString],
    ) -> Result<()> {
        let log = runtime.create_log(&helper_log_name(binary))?;
        let mut command = Command::new(sibling_binary(binary)?);
        command
            .args(args)
            .stdin(Stdio::null())
            .stdout(log.try_clone()?)
            .stderr(log);
        shoal_runtime::host::pass_to(&mut command);
        tie.apply(&mut command);
        let child = command
            .spawn()
            .with_context(|| format!("starting {binary}"))?;
        self.running.push(Helper {
            binary: binary.to_owned(),
            child,
            log: HelperLog::new(runtime.dir.join(helper_log_name(binary))),
        });
        Ok(())
    }

    /// Starts the recorder of swarm `swarm`: into a file, a live viewer, or both.
    pub(crate) fn start_recorder(
        &mut self,
        runtime: &SwarmRuntime,
        tie: Tie,
        swarm: &str,
        to: &RecordOptions,
    ) -> Result<()> {
        let mut args = to.recorder_args();
        args.extend(["--swarm".into(), swarm.into()]);
        self.recording.clone_from(&to.out);
        self.start(runtime, tie, RECORDER_BINARY, &args)
    }

    /// Starts a SLAM process of swarm `swarm` following `follow`, with more
    /// `options` of `shoal-slam` (particles, learning, initial model).
    pub(crate) fn start_slam(
        &mut self,
        runtime: &SwarmRuntime,
        tie: Tie,
        swarm: &str,
        follow: &shoal_slam::follow::Follow,
        options: &[String],
    ) -> Result<()> {
        let mut args: Vec<OsString> = vec![
            "--swarm".into(),
            swarm.into(),
            "--follow".into(),
            follow.to_string().into(),
        ];
        args.extend(options.iter().map(Into::into));
        self.start(runtime, tie, SLAM_BINARY, &args)
    }

    pub(crate) fn recorder_pid(&self) -> Option<i32> {
        self.running
            .iter()
            .find(|h| h.binary == RECORDER_BINARY)
            .map(|h| h.child.id() as i32)
    }

    /// Warnings the helpers wrote into their logs since the last call
    /// (a disk filling up, a viewer that does not answer).
    pub(crate) fn take_warnings(&mut self) -> Vec<String> {
        self.running
            .iter_mut()
            .flat_map(|h| h.log.new_warnings())
            .collect()
    }

    /// What stopping the swarm cost: helpers that had to be killed.
    pub(crate) fn stop_notes(&self) -> &[String] {
        &self.stop_notes
    }

    /// Kills the recorder of swarm `swarm` as a crash would (SIGKILL); not
    /// reported as a death.
    pub(crate) fn kill_recorder(&mut self, swarm: &str) -> Result<()> {
        if let Some(index) = self
            .running
            .iter()
            .position(|h| h.binary == RECORDER_BINARY)
        {
            let Helper { mut child, .. } = self.running.remove(index);
            if let Some(process) = Pinned::child(&child) {
                process.signal(libc::SIGKILL)?;
            }
            child.wait().context("waiting for the killed recorder")?;
            remove_dead_nodes(swarm)?;
        }
        Ok(())
    }

    /// Notes helpers that ended on their own into `deaths`.
    pub(crate) fn reap(&mut self, runtime: &SwarmRuntime, deaths: &mut Vec<Death>) {
        self.running.retain_mut(|h| match h.child.try_wait() {
            Ok(None) => true,
            Ok(Some(status)) => {
                let log = helper_log_name(&h.binary);
                deaths.extend(Death::unless_clean(h.binary.clone(), status, runtime, &log));
                false
            }
            Err(_) => false,
        });
    }

    /// Whether a running helper reports its progress as `pace`.
    pub(crate) fn serves(&self, pace: &str) -> bool {
        self.running.iter().any(|h| pace_name(&h.binary) == pace)
    }

    /// Stops every helper (SIGTERM, then SIGKILL after its grace), noting
    /// those that had to be killed and what that cost.
    pub(crate) fn stop_all(&mut self) {
        for mut helper in std::mem::take(&mut self.running) {
            let killed = stop_processes(
                &Pinned::child(&helper.child).into_iter().collect::<Vec<_>>(),
                HELPER_GRACE,
            ) > 0;
            let _ = helper.child.wait();
            if killed {
                let note = self.killed_note(&helper.binary);
                self.stop_notes.push(note);
            }
        }
    }

    /// What killing helper `binary` after its grace cost, and for the
    /// recorder, the repair of its file's end: a write cut short by the kill
    /// would leave a partial message that readers refuse.
    fn killed_note(&self, binary: &str) -> String {
        let mut note = format!(
            "{binary} did not stop within {} s of SIGTERM and was killed",
            HELPER_GRACE.as_secs()
        );
        if binary == RECORDER_BINARY
            && let Some(recording) = &self.recording
        {
            note.push_str(&format!(
                "; {} ends at its last flush (up to a second before the kill), without the \
                 footer a viewer seeks with",
                recording.display()
            ));
            let repair = sibling_binary(RECORDER_BINARY).and_then(|bin| {
                Command::new(bin)
                    .arg("--repair")
                    .arg(recording)
                    .stdin(Stdio::null())
                    .output()
                    .context("running the recorder's repair")
            });
            match repair {
                Ok(out) => {
                    let said = String::from_utf8_lossy(&out.stderr);
                    let said = said.trim().trim_start_matches("shoal-viewer-log: ");
                    note.push_str(&format!("; {said}"));
                }
                Err(e) => note.push_str(&format!("; its end was not checked: {e:#}")),
            }
        }
        note
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_recorder_and_the_link_get_the_arguments_asked_for() {
        let mut record = RecordOptions::file(
            std::path::Path::new("run.rrd"),
            Some(std::path::Path::new("tum")),
        );
        record.expected_seconds = Some(60.0);
        assert!(record.wanted());
        assert_eq!(
            record.recorder_args(),
            ["run.rrd", "--tum", "tum", "--expected-seconds", "60"].map(std::ffi::OsString::from)
        );
        assert!(!RecordOptions::default().wanted());
        let link = LinkOptions {
            zenoh_config: None,
            listen: vec!["tcp/0.0.0.0:7447".into()],
            connect: vec!["tcp/10.0.0.2:7447".into()],
        };
        assert_eq!(
            link.args("lab"),
            [
                "--swarm",
                "lab",
                "--listen",
                "tcp/0.0.0.0:7447",
                "--connect",
                "tcp/10.0.0.2:7447"
            ]
            .map(std::ffi::OsString::from)
        );
    }
}

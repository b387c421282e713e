//! The processes that serve a swarm beside its robots: the recorder, SLAM
//! and the link to other hosts. Each is started with its log in the swarm's
//! folder; one that ends unasked is reported as a death, with its log's end.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use shoal_broker::liveness::remove_dead_nodes;
use shoal_link::report::LinkReport;

use crate::deaths::{Death, helper_log_name};
use crate::pacing::{RECORDER_LAG_TICKS, SLAM_LAG_TICKS, pace_name};
use crate::process::{Pinned, sibling_binary};
use crate::shutdown::HELPER_GRACE;
use crate::supervisor::RunningSwarm;

/// A process that serves the swarm (recorder, SLAM, link).
pub(crate) struct Helper {
    pub(crate) binary: String,
    pub(crate) child: Child,
    pub(crate) log: crate::helper_log::HelperLog,
}

pub const RECORDER_BINARY: &str = "shoal-viewer-log";

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

/// How long the launcher waits for its link to have heard the other hosts.
const LINK_TIMEOUT: Duration = Duration::from_secs(20);
pub(crate) const LINK_BINARY: &str = "shoal-link";

impl RunningSwarm {
    /// Waits until the link has heard the other hosts, and refuses robot
    /// ids `first_id..first_id + count` if another host runs one of them.
    pub(crate) fn await_link(&mut self, first_id: u32, count: usize) -> Result<()> {
        let started = Instant::now();
        let report = loop {
            self.reap_helpers();
            if let Some(death) = self.children.deaths.iter().find(|d| d.who == LINK_BINARY) {
                self.keep_logs = true;
                bail!("the link to the other hosts failed: {death}");
            }
            if self.termination_requested() {
                bail!("interrupted while linking to the other hosts");
            }
            if let Some(report) = self
                .runtime
                .read_report::<LinkReport>()?
                .filter(|r| r.ready)
            {
                break report;
            }
            if started.elapsed() > LINK_TIMEOUT {
                self.keep_logs = true;
                bail!(
                    "the link to the other hosts did not get ready within {} s; its log is kept in {}",
                    LINK_TIMEOUT.as_secs(),
                    self.runtime.dir.display()
                );
            }
            std::thread::sleep(Duration::from_millis(100));
        };
        let ours = u64::from(first_id)..u64::from(first_id) + count as u64;
        let clashes: Vec<String> = report
            .hosts
            .iter()
            .filter_map(|host| {
                let ids: Vec<String> = host
                    .robots
                    .iter()
                    .filter(|r| ours.contains(&u64::from(r.id)))
                    .map(|r| r.id.to_string())
                    .collect();
                (!ids.is_empty())
                    .then(|| format!("host `{}` runs robots {}", host.name, ids.join(", ")))
            })
            .collect();
        if !clashes.is_empty() {
            bail!(
                "robot ids {}..={} of this host `{}` are taken: {}; robot ids must be unique across the swarm: choose another --first-id",
                ours.start,
                ours.end.saturating_sub(1),
                report.host,
                clashes.join("; ")
            );
        }
        let remote: usize = report.hosts.iter().map(|h| h.robots.len()).sum();
        eprintln!(
            "shoal: linked host `{}` to {} other host(s) of swarm `{}` ({remote} robots there)",
            report.host,
            report.hosts.len(),
            self.name
        );
        Ok(())
    }

    /// Starts the recorder process: into a file, a live viewer, or both.
    pub fn record(&mut self, to: &RecordOptions) -> Result<()> {
        let mut args = to.recorder_args();
        args.extend(["--swarm".into(), self.name.clone().into()]);
        self.pace_to("recorder", RECORDER_LAG_TICKS)?;
        self.recording.clone_from(&to.out);
        self.start_helper(RECORDER_BINARY, &args)
    }

    /// Starts a SLAM process following `follow`, with more `options`
    /// of `shoal-slam` (particles, learning, initial model).
    pub fn follow_with_slam(
        &mut self,
        follow: &shoal_slam::follow::Follow,
        options: &[String],
    ) -> Result<()> {
        let mut args: Vec<std::ffi::OsString> = vec![
            "--swarm".into(),
            self.name.clone().into(),
            "--follow".into(),
            follow.to_string().into(),
        ];
        args.extend(options.iter().map(Into::into));
        self.pace_to("slam", SLAM_LAG_TICKS)?;
        self.start_helper("shoal-slam", &args)
    }

    pub(crate) fn start_helper(&mut self, binary: &str, args: &[std::ffi::OsString]) -> Result<()> {
        let log = self.runtime.create_log(&helper_log_name(binary))?;
        let mut command = Command::new(sibling_binary(binary)?);
        command
            .args(args)
            .stdin(Stdio::null())
            .stdout(log.try_clone()?)
            .stderr(log);
        shoal_runtime::host::pass_to(&mut command);
        self.tie().apply(&mut command);
        let child = command
            .spawn()
            .with_context(|| format!("starting {binary}"))?;
        self.helpers.push(Helper {
            binary: binary.to_owned(),
            child,
            log: crate::helper_log::HelperLog::new(self.runtime.dir.join(helper_log_name(binary))),
        });
        Ok(())
    }

    pub fn recorder_pid(&self) -> Option<i32> {
        self.helpers
            .iter()
            .find(|h| h.binary == RECORDER_BINARY)
            .map(|h| h.child.id() as i32)
    }

    /// Warnings the helpers wrote into their logs since the last call
    /// (a disk filling up, a viewer that does not answer).
    pub fn take_helper_warnings(&mut self) -> Vec<String> {
        self.helpers
            .iter_mut()
            .flat_map(|h| h.log.new_warnings())
            .collect()
    }

    /// What stopping the swarm cost: helpers that had to be killed.
    pub fn stop_notes(&self) -> &[String] {
        &self.stop_notes
    }

    /// Kills the recorder as a crash would (SIGKILL); not reported as a death.
    pub fn kill_recorder(&mut self) -> Result<()> {
        if let Some(index) = self
            .helpers
            .iter()
            .position(|h| h.binary == RECORDER_BINARY)
        {
            let Helper { mut child, .. } = self.helpers.remove(index);
            if let Some(process) = Pinned::child(&child) {
                process.signal(libc::SIGKILL)?;
            }
            child.wait().context("waiting for the killed recorder")?;
            remove_dead_nodes(&self.name)?;
        }
        self.paces.retain(|p| p.helper != "recorder");
        Ok(())
    }

    /// Notes helpers (recorder, SLAM) that ended on their own; a lockstep
    /// clock no longer waits for them.
    pub(crate) fn reap_helpers(&mut self) {
        let runtime = &self.runtime;
        let deaths = &mut self.children.deaths;
        self.helpers.retain_mut(|h| match h.child.try_wait() {
            Ok(None) => true,
            Ok(Some(status)) => {
                let log = helper_log_name(&h.binary);
                deaths.extend(Death::unless_clean(h.binary.clone(), status, runtime, &log));
                false
            }
            Err(_) => false,
        });
        let helpers = &self.helpers;
        self.paces
            .retain(|p| helpers.iter().any(|h| pace_name(&h.binary) == p.helper));
    }

    /// What killing helper `binary` after its grace cost, and for the
    /// recorder, the repair of its file's end: a write cut short by the kill
    /// would leave a partial message that readers refuse.
    pub(crate) fn killed_helper_note(&self, binary: &str) -> String {
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

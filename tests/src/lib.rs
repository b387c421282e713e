//! Helpers for end-to-end tests: they start the real `shoal` binaries, which
//! talk over real iceoryx2 shared memory.

use std::path::PathBuf;
use std::process::{Child, Command, Output, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use glam::DVec2;
use serde_json::Value;
use shoal_physics::metrics::{FormationMetrics, formation_metrics};

/// The machine has two cores: swarms of different tests would starve each
/// other, so tests take turns.
static ONE_SWARM_AT_A_TIME: Mutex<()> = Mutex::new(());

pub fn serial() -> MutexGuard<'static, ()> {
    ONE_SWARM_AT_A_TIME
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A workspace binary, built by `cargo build --release --workspace` beside this test.
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("target directory");
    let path = dir.join(name);
    assert!(
        path.exists(),
        "{} is missing: run `cargo build --release --workspace` first (scripts/test does)",
        path.display()
    );
    path
}

pub fn shoal(args: &[&str]) -> Output {
    Command::new(bin("shoal"))
        .args(args)
        .output()
        .expect("run shoal")
}

/// `shoal ARGS`, which must succeed: a failure shows what it said.
pub fn shoal_ok(args: &[&str]) -> Output {
    let output = shoal(args);
    assert!(
        output.status.success(),
        "shoal {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

/// `shoal status --json` of `swarm`.
pub fn status(swarm: &str) -> Value {
    let output = shoal(&["status", "--swarm", swarm, "--json"]);
    assert!(
        output.status.success(),
        "status failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("status prints JSON")
}

pub fn alive_agents(status: &Value) -> Vec<&Value> {
    status["agents"]
        .as_array()
        .map(|a| a.iter().filter(|a| a["state"] == "alive").collect())
        .unwrap_or_default()
}

pub fn alive_ids(status: &Value) -> Vec<u64> {
    alive_agents(status)
        .iter()
        .filter_map(|a| a["id"].as_u64())
        .collect()
}

/// Formation metrics of the robots `status` lists as alive with a pose.
pub fn status_metrics(status: &Value, spread: f64) -> FormationMetrics {
    let positions: Vec<DVec2> = alive_agents(status)
        .iter()
        .filter_map(|a| Some(DVec2::new(a["x"].as_f64()?, a["y"].as_f64()?)))
        .collect();
    formation_metrics(&positions, spread)
}

pub fn wait_until(timeout: Duration, mut condition: impl FnMut() -> bool) -> bool {
    let started = Instant::now();
    while started.elapsed() < timeout {
        if condition() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    false
}

pub use shoal_runtime::pid_alive;

/// A `shoal up` running in the background. Dropping it stops the swarm with
/// Ctrl-C (SIGINT), as a user would, so no test leaves robots behind.
pub struct BackgroundSwarm {
    pub name: String,
    child: Option<Child>,
    log: PathBuf,
}

impl BackgroundSwarm {
    pub fn start(name: &str, extra: &[&str]) -> Self {
        let mut args = vec!["up", "--swarm", name];
        args.extend_from_slice(extra);
        // A file, not a pipe: nobody reads a pipe while the test waits, and a
        // full pipe would stall `shoal up` and with it a lockstep swarm.
        let log = std::env::temp_dir().join(format!("shoal-e2e-{name}.log"));
        let out = std::fs::File::create(&log).expect("create the shoal up log");
        let err = out.try_clone().expect("clone the log handle");
        let child = Command::new(bin("shoal"))
            .args(&args)
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(err)
            .spawn()
            .expect("start shoal up");
        Self {
            name: name.to_owned(),
            child: Some(child),
            log,
        }
    }

    /// What `shoal up` has printed so far, for failure messages.
    pub fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// Waits until exactly `count` robots are alive and have published a
    /// pose; panics with the status and the launcher's output otherwise.
    pub fn wait_alive(&mut self, count: usize, timeout: Duration) {
        let mut last = Value::Null;
        let reached = wait_until(timeout, || {
            if let Some(Ok(Some(exit))) = self.child.as_mut().map(Child::try_wait) {
                panic!(
                    "shoal up {} ended early ({exit}):\n{}",
                    self.name,
                    self.log()
                );
            }
            last = status(&self.name);
            let agents = alive_agents(&last);
            agents.len() == count && agents.iter().all(|a| a["x"].is_f64())
        });
        assert!(
            reached,
            "{count} robots of {} not alive within {timeout:?}\nstatus: {last}\nshoal up said:\n{}",
            self.name,
            self.log()
        );
    }

    pub fn pid(&self) -> i32 {
        self.child.as_ref().map_or(0, |c| c.id() as i32)
    }

    /// Waits for `shoal up` to end by itself (or by a signal the test sent)
    /// and returns how it ended and what it printed.
    pub fn wait_end(&mut self) -> (std::process::ExitStatus, String) {
        let mut child = self.child.take().expect("running");
        let status = child.wait().expect("wait for shoal up");
        (status, self.log())
    }

    /// Sends Ctrl-C to `shoal up`, waits for it and returns what it printed.
    pub fn interrupt(&mut self) -> (std::process::ExitStatus, String) {
        let mut child = self.child.take().expect("running");
        // SAFETY: plain kill(2) on a child we own.
        unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
        let status = child.wait().expect("wait for shoal up");
        (status, self.log())
    }
}

impl Drop for BackgroundSwarm {
    fn drop(&mut self) {
        if self.child.is_some() {
            let _ = self.interrupt();
        }
    }
}

/// What is left of `swarm` on the bus: its nodes and services.
pub fn residue(swarm: &str) -> (usize, Vec<String>) {
    let nodes = shoal_broker::liveness::swarm_nodes(swarm)
        .expect("list nodes")
        .len();
    let services = shoal_broker::liveness::swarm_services(swarm).expect("list services");
    (nodes, services)
}

/// A fresh folder for one test's files, named after the test and this
/// process so parallel runs never share one.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("shoal-e2e-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

/// This package's folder (`tests/`) in the checkout under test. `cargo
/// test` says it at run time: the path compiled in is where the binary was
/// built, and a target folder shared by two checkouts (CI's clean clone
/// and a working copy) keeps binaries built in the other one.
pub fn package_dir() -> PathBuf {
    std::env::var_os("CARGO_MANIFEST_DIR")
        .map_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")), PathBuf::from)
}

/// What `tests/python/check_recording.py` finds in a recording, read with
/// the official Rerun reader.
pub fn inspect_recording(recording: &std::path::Path) -> Value {
    let script = package_dir().join("python/check_recording.py");
    let output = Command::new("python3")
        .arg(script)
        .arg(recording)
        .output()
        .expect("python3");
    assert!(
        output.status.success(),
        "{} does not open in the Rerun reader: {}",
        recording.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("JSON from the reader")
}

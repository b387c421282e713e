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

pub use shoal::process::pid_alive;

/// A `shoal up` running in the background. Dropping it stops the swarm with
/// Ctrl-C (SIGINT), as a user would, so no test leaves robots behind.
pub struct BackgroundSwarm {
    pub name: String,
    child: Option<Child>,
}

impl BackgroundSwarm {
    pub fn start(name: &str, extra: &[&str]) -> Self {
        let mut args = vec!["up", "--swarm", name];
        args.extend_from_slice(extra);
        let child = Command::new(bin("shoal"))
            .args(&args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start shoal up");
        Self {
            name: name.to_owned(),
            child: Some(child),
        }
    }

    pub fn pid(&self) -> i32 {
        self.child.as_ref().map_or(0, |c| c.id() as i32)
    }

    /// Sends Ctrl-C to `shoal up` and returns its output.
    pub fn interrupt(&mut self) -> Output {
        let child = self.child.take().expect("running");
        // SAFETY: plain kill(2) on a child we own.
        unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
        child.wait_with_output().expect("wait for shoal up")
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

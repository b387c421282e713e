//! Stopping a swarm: helpers first (the recorder writes its footer), then
//! every robot, also those started elsewhere, within a grace that grows
//! with their number; then the bus and the swarm's folder are cleaned.

use std::time::Duration;

use anyhow::{Context, Result};
use shoal_broker::liveness::{SwarmNodeState, remove_dead_nodes, swarm_nodes};

use crate::process::{Pinned, stop_processes};
use crate::supervisor::RunningSwarm;

/// How long robots get to leave cleanly before they are killed: a robot
/// leaves in milliseconds, but a thousand leaving at once queue on the
/// kernel for seconds (their shared mappings unmapped together), and every
/// one killed leaves resources the launcher must then clean up one node at
/// a time, a third of a second each (BENCHMARKS.md, "1000 robots in real time").
pub fn shutdown_grace(robots: usize) -> Duration {
    Duration::from_secs(5) + Duration::from_millis(15) * robots as u32
}

impl RunningSwarm {
    /// Stops every robot of the swarm (also those started elsewhere), cleans
    /// the bus and removes the swarm's files.
    pub fn shutdown(&mut self) -> Result<()> {
        if self.stopped {
            return Ok(());
        }
        self.stopped = true;
        // The stop sweeps every dead node itself, once the robots are gone.
        self.sweeper.stop();
        // What died before the stop is reported; what the stop ends is not.
        self.children.reap(&self.runtime);
        self.reap_helpers();
        // Helpers go first: the recorder then does not log every robot
        // leaving, and gets time to write the recording's footer.
        self.helpers.stop_all();
        let pids = self.agent_pids();
        let mut processes: Vec<Pinned> = self
            .children
            .running
            .values()
            .filter_map(Pinned::child)
            .collect();
        // Robots started elsewhere (`shoal restart`, `spawn`) are known only
        // by the pid their bus node names; pinning checks it is still one of ours.
        let me = std::process::id() as i32;
        for node in swarm_nodes(&self.name)? {
            if node.agent_id.is_some()
                && node.state == SwarmNodeState::Alive
                && node.pid != me
                && !pids.contains(&node.pid)
            {
                processes.extend(Pinned::shoal_process(node.pid));
            }
        }
        stop_processes(&processes, shutdown_grace(processes.len()));
        for child in self.children.running.values_mut() {
            let _ = child.wait();
        }
        self.children.running.clear();
        remove_dead_nodes(&self.name)?;
        if self.keep_logs || !self.children.deaths.is_empty() {
            self.runtime
                .remove_all_but_logs()
                .with_context(|| format!("clearing {}", self.runtime.dir.display()))?;
        } else {
            self.runtime
                .remove()
                .with_context(|| format!("removing {}", self.runtime.dir.display()))?;
        }
        Ok(())
    }
}

impl Drop for RunningSwarm {
    fn drop(&mut self) {
        if let Err(e) = self.shutdown() {
            eprintln!("shoal: stopping swarm `{}`: {e:#}", self.name);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A thousand robots leaving together queue on the kernel for seconds:
    /// their grace grows with their number.
    #[test]
    fn the_grace_grows_with_the_robots_to_stop() {
        assert_eq!(shutdown_grace(0), Duration::from_secs(5));
        assert_eq!(shutdown_grace(1000), Duration::from_secs(20));
    }
}

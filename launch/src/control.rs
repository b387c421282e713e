//! `shoal kill`, `shoal restart`, `shoal spawn`: act on a running swarm from any terminal.

use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use shoal_broker::SwarmRuntime;
use shoal_broker::liveness::{SwarmNode, SwarmNodeState, remove_dead_nodes, swarm_nodes};
use shoal_physics::{Pose, Scenario};

use crate::process::{pid_alive, signal, start_agent};

fn alive_robot(nodes: &[SwarmNode], id: u32) -> Option<&SwarmNode> {
    nodes
        .iter()
        .find(|n| n.agent_id == Some(id) && n.state == SwarmNodeState::Alive)
}

/// Signals robots by id: SIGKILL, or SIGTERM when `graceful`.
pub fn kill(swarm: &str, ids: &[u32], graceful: bool) -> Result<()> {
    let nodes = swarm_nodes(swarm)?;
    let sig = if graceful {
        libc::SIGTERM
    } else {
        libc::SIGKILL
    };
    let mut missing = Vec::new();
    for &id in ids {
        match alive_robot(&nodes, id) {
            Some(node) => {
                signal(node.pid, sig)?;
                println!(
                    "killed robot {id} (pid {}){}",
                    node.pid,
                    if graceful { " gracefully" } else { "" }
                );
            }
            None => missing.push(id),
        }
    }
    if !missing.is_empty() {
        bail!("no live robot with id {missing:?} in swarm `{swarm}`");
    }
    Ok(())
}

fn open_swarm(swarm: &str) -> Result<(SwarmRuntime, Scenario)> {
    let runtime = SwarmRuntime::locate(swarm);
    runtime
        .read_meta()
        .with_context(|| format!("swarm `{swarm}` was not started with `shoal up`"))?;
    let scenario = Scenario::from_file(&runtime.scenario_path())?;
    Ok((runtime, scenario))
}

/// Starts a new process for each id, at its last pose or at `at`.
pub fn restart(swarm: &str, ids: &[u32], at: Option<[f64; 2]>) -> Result<()> {
    let (runtime, scenario) = open_swarm(swarm)?;
    let nodes = swarm_nodes(swarm)?;
    for &id in ids {
        if let Some(node) = alive_robot(&nodes, id) {
            signal(node.pid, libc::SIGTERM)?;
            let deadline = Instant::now() + Duration::from_secs(5);
            while pid_alive(node.pid) && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(20));
            }
            if pid_alive(node.pid) {
                signal(node.pid, libc::SIGKILL)?;
            }
        }
    }
    remove_dead_nodes(swarm)?;
    for &id in ids {
        let pose = match at {
            Some([x, y]) => Pose::new(x, y, 0.0),
            None => runtime.read_last_pose(id).map_or_else(
                || scenario.start_poses(id, 1)[0],
                |[x, y, theta]| Pose::new(x, y, theta),
            ),
        };
        let child = start_agent(swarm, id, pose, &runtime.log_path(id), true)?;
        println!(
            "restarted robot {id} (pid {}) at ({:.2}, {:.2})",
            child.id(),
            pose.x,
            pose.y
        );
    }
    Ok(())
}

/// Adds `count` robots with fresh ids, around `at` or in the start region.
pub fn spawn(swarm: &str, count: usize, at: Option<[f64; 2]>) -> Result<Vec<u32>> {
    let (runtime, scenario) = open_swarm(swarm)?;
    let highest_node = swarm_nodes(swarm)?.iter().filter_map(|n| n.agent_id).max();
    let highest_file = runtime.known_agent_ids().into_iter().max();
    let first = highest_node
        .max(highest_file)
        .map_or(0, |h| h + 1)
        .max(scenario.agents.count as u32);
    let mut ids = Vec::new();
    for k in 0..count {
        let id = first + k as u32;
        let pose = match at {
            Some([x, y]) => {
                // Several robots at one place stand on a small ring around it.
                let angle = std::f64::consts::TAU * k as f64 / count as f64;
                let r = if count > 1 {
                    scenario.formation.spread / 2.0
                } else {
                    0.0
                };
                Pose::new(x + r * angle.cos(), y + r * angle.sin(), angle)
            }
            None => scenario.start_poses(id, 1)[0],
        };
        let child = start_agent(swarm, id, pose, &runtime.log_path(id), true)?;
        println!(
            "spawned robot {id} (pid {}) at ({:.2}, {:.2})",
            child.id(),
            pose.x,
            pose.y
        );
        ids.push(id);
    }
    Ok(ids)
}

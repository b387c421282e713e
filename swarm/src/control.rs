//! `shoal kill`, `shoal restart`, `shoal spawn`: act on a running swarm from any terminal.

use std::time::Duration;

/// How long a robot being restarted gets to leave cleanly.
const RESTART_GRACE: Duration = Duration::from_secs(5);
/// How long `shoal down` gives a swarm's processes to leave cleanly.
const DOWN_GRACE: Duration = Duration::from_secs(8);

use anyhow::{Context, Result, bail};
use shoal_broker::liveness::{SwarmNode, SwarmNodeState, remove_dead_nodes, swarm_nodes};
use shoal_link::report::LinkReport;
use shoal_physics::Pose;
use shoal_runtime::SwarmRuntime;
use shoal_scenario::Scenario;

use crate::process::{MAX_ROBOT_ID, Pinned, Tie, check_id_range, start_agent, stop_processes};
use crate::shutdown::shutdown_grace;

fn alive_robot(nodes: &[SwarmNode], id: u32) -> Option<&SwarmNode> {
    nodes
        .iter()
        .find(|n| n.agent_id == Some(id) && n.state == SwarmNodeState::Alive)
}

/// Refuses to act here on robots another host runs (as this host's link
/// knows them), naming that host.
fn refuse_remote(swarm: &str, runtime: &SwarmRuntime, ids: &[u32], verb: &str) -> Result<()> {
    let Some(report) = runtime.read_report::<LinkReport>()? else {
        return Ok(());
    };
    let remote: Vec<String> = ids
        .iter()
        .filter_map(|&id| {
            report.host_of(id).map(|host| {
                format!(
                    "robot {id} runs on host `{host}`: run `shoal {verb} {id} --swarm {swarm} --host {host}` there"
                )
            })
        })
        .collect();
    if !remote.is_empty() {
        bail!("{}", remote.join("; "));
    }
    Ok(())
}

/// Signals robots by id: SIGKILL, or SIGTERM when `graceful`.
pub fn kill(swarm: &str, ids: &[u32], graceful: bool) -> Result<()> {
    let nodes = swarm_nodes(swarm)?;
    let runtime = SwarmRuntime::locate(swarm);
    let sig = if graceful {
        libc::SIGTERM
    } else {
        libc::SIGKILL
    };
    let mut missing = Vec::new();
    for &id in ids {
        match alive_robot(&nodes, id) {
            Some(node) => {
                // The launcher reports robots that die unasked; this one was asked.
                runtime.mark_stopped_by_user(id).with_context(|| {
                    format!(
                        "noting in {} that robot {id} is stopped on purpose",
                        runtime.dir.display()
                    )
                })?;
                let Some(process) = Pinned::shoal_process(node.pid) else {
                    missing.push(id);
                    continue;
                };
                process.signal(sig)?;
                println!(
                    "killed robot {id} (pid {}){}",
                    node.pid,
                    if graceful { " gracefully" } else { "" }
                );
            }
            None => missing.push(id),
        }
    }
    refuse_remote(swarm, &runtime, &missing, "kill")?;
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
    let scenario = runtime.read_scenario()?;
    Ok((runtime, scenario))
}

/// Starts a new process for each id, at its last pose or at `at`.
pub fn restart(swarm: &str, ids: &[u32], at: Option<[f64; 2]>) -> Result<()> {
    if let Some(id) = ids.iter().find(|id| **id > MAX_ROBOT_ID) {
        bail!("robot id {id} is above the highest id Shoal runs, {MAX_ROBOT_ID}");
    }
    let (runtime, scenario) = open_swarm(swarm)?;
    refuse_remote(swarm, &runtime, ids, "restart")?;
    let nodes = swarm_nodes(swarm)?;
    for &id in ids {
        if let Some(node) = alive_robot(&nodes, id) {
            runtime.mark_stopped_by_user(id)?;
            stop_processes(
                &Pinned::shoal_process(node.pid)
                    .into_iter()
                    .collect::<Vec<_>>(),
                RESTART_GRACE,
            );
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
        let child = start_agent(swarm, id, pose, &runtime, Tie::Detached)?;
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
    // Back-to-back spawns would otherwise pick the same ids: one at a time.
    let _ids_lock = runtime.lock("ids", true)?;
    let highest_node = swarm_nodes(swarm)?.iter().filter_map(|n| n.agent_id).max();
    let highest_file = runtime.known_agent_ids().into_iter().max();
    // Ids are unique across the hosts of a swarm: above every other host's too.
    let highest_remote = runtime
        .read_report::<LinkReport>()?
        .and_then(|report| report.robots().map(|(_, r)| r.id).max());
    let first = highest_node
        .max(highest_file)
        .max(highest_remote)
        .map_or(0, |h| h + 1)
        .max(scenario.agents.count as u32);
    check_id_range(first, count)?;
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
        // Noting its pose now takes the id before the lock is let go, even
        // if the robot is not yet on the bus.
        runtime.write_last_pose(id, [pose.x, pose.y, pose.theta])?;
        let child = start_agent(swarm, id, pose, &runtime, Tie::Detached)?;
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

/// Stops swarm `swarm` from any terminal: its launcher first (which stops
/// what it started), then every other process on its bus (robots started by
/// `shoal restart` or `spawn`, the recorder, SLAM); then what the processes
/// of a killed swarm left (dead nodes, its folder). Returns how many
/// processes were stopped.
pub fn down(swarm: &str) -> Result<usize> {
    let me = std::process::id() as i32;
    // Only Shoal's own processes: a user's Python reader on the bus is not ours to stop.
    let alive = |launcher_only: bool| -> Result<Vec<Pinned>> {
        let launcher = shoal_broker::names::tool_node(swarm, crate::supervisor::LAUNCHER_ROLE);
        let mut pids: Vec<i32> = swarm_nodes(swarm)?
            .into_iter()
            .filter(|n| n.state == SwarmNodeState::Alive && n.pid != me)
            .filter(|n| !launcher_only || n.name == launcher)
            .map(|n| n.pid)
            .collect();
        pids.sort_unstable();
        pids.dedup();
        Ok(pids.into_iter().filter_map(Pinned::shoal_process).collect())
    };
    let before = alive(false)?;
    if !before.is_empty() {
        // The launcher stops its robots itself, with their grace.
        let robots = before.len();
        stop_processes(&alive(true)?, DOWN_GRACE + shutdown_grace(robots));
        let rest = alive(false)?;
        stop_processes(&rest, DOWN_GRACE.max(shutdown_grace(rest.len())));
    }
    remove_dead_nodes(swarm)?;
    let swept = shoal_broker::liveness::remove_dead_nodes_of_abandoned_swarms()?;
    if let Some(swept) = shoal_broker::liveness::describe_swept(&swept) {
        eprintln!("shoal: {swept}");
    }
    let runtime = SwarmRuntime::locate(swarm);
    runtime
        .remove()
        .with_context(|| format!("removing {}", runtime.dir.display()))?;
    Ok(before.len())
}

//! Who is on the bus: iceoryx2 marks a killed process's node `Dead`; any
//! process of the swarm may then remove its stale resources so a restarted
//! robot with the same id can rejoin at once.

use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

use std::collections::BTreeMap;
use std::time::SystemTime;

use shoal_runtime::{SwarmRuntime, Sweep};

use crate::bus::BusError;
use crate::names;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SwarmNodeState {
    Alive,
    Dead,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SwarmNode {
    pub name: String,
    /// The robot id, for robot nodes.
    pub agent_id: Option<u32>,
    pub pid: i32,
    pub state: SwarmNodeState,
}

/// Every node of `swarm` on this machine, alive or dead.
pub fn swarm_nodes(swarm: &str) -> Result<Vec<SwarmNode>, BusError> {
    crate::bus::quiet_iceoryx();
    let prefix = names::prefix(swarm);
    let mut nodes = Vec::new();
    Node::<ipc::Service>::list(&crate::bus::domain_config(), |state| {
        let (view_details, alive) = match &state {
            NodeState::Alive(view) => (view.details().clone(), true),
            NodeState::Dead(view) => (view.details().clone(), false),
            _ => (None, false),
        };
        if let Some(details) = view_details {
            let name = details.name().as_str().to_owned();
            if name.starts_with(&prefix) {
                nodes.push(SwarmNode {
                    agent_id: names::agent_id_of_node(swarm, &name),
                    pid: details.process_id().value(),
                    state: if alive {
                        SwarmNodeState::Alive
                    } else {
                        SwarmNodeState::Dead
                    },
                    name,
                });
            }
        }
        CallbackProgression::Continue
    })
    .map_err(|e| BusError::iceoryx("list nodes", e))?;
    Ok(nodes)
}

/// Removes the stale resources of every dead node of `swarm`; returns how many it cleaned.
pub fn remove_dead_nodes(swarm: &str) -> Result<usize, BusError> {
    remove_dead_nodes_while(swarm, || true)
}

/// As [`remove_dead_nodes`], but stops between two nodes once `go_on`
/// says no. iceoryx2 removes a dead node's connections by listing every
/// file in `/dev/shm` once per port the node had: about 3.7 s per node
/// among 1000 robots (70,000 files), so a process that must stay
/// responsive (the launcher, on Ctrl-C) checks between nodes.
pub fn remove_dead_nodes_while(swarm: &str, go_on: impl Fn() -> bool) -> Result<usize, BusError> {
    let prefix = names::prefix(swarm);
    Ok(remove_dead_nodes_named(|name| name.starts_with(&prefix), go_on)?.len())
}

/// Removes the dead nodes of every Shoal swarm on this host's bus that has
/// no live node left: a swarm killed whole (its lockstep launcher killed
/// with SIGKILL) has nobody left to sweep its nodes, and they would wait
/// for a `shoal down` with its exact name. A swarm with live nodes sweeps
/// its own dead (its robots and launcher, one at a time, under its sweep
/// lock): taking that over here would make `shoal status` wait seconds per
/// node among many robots. iceoryx2 declares a node dead only once its
/// process is gone. Returns the nodes removed, by swarm.
pub fn remove_dead_nodes_of_abandoned_swarms() -> Result<BTreeMap<String, usize>, BusError> {
    crate::bus::quiet_iceoryx();
    let mut alive: BTreeMap<String, bool> = BTreeMap::new();
    Node::<ipc::Service>::list(&crate::bus::domain_config(), |state| {
        let (details, is_alive) = match &state {
            NodeState::Alive(view) => (view.details().clone(), true),
            NodeState::Dead(view) => (view.details().clone(), false),
            _ => (None, false),
        };
        if let Some(swarm) = details
            .as_ref()
            .and_then(|d| names::swarm_of_node(d.name().as_str()))
        {
            *alive.entry(swarm.to_owned()).or_insert(false) |= is_alive;
        }
        CallbackProgression::Continue
    })
    .map_err(|e| BusError::iceoryx("list nodes", e))?;
    let abandoned: Vec<String> = alive
        .into_iter()
        .filter(|(_, any_alive)| !any_alive)
        .map(|(swarm, _)| swarm)
        .collect();
    let wanted =
        |name: &str| names::swarm_of_node(name).is_some_and(|s| abandoned.iter().any(|a| a == s));
    let mut removed = BTreeMap::new();
    for name in remove_dead_nodes_named(wanted, || true)? {
        if let Some(swarm) = names::swarm_of_node(&name) {
            *removed.entry(swarm.to_owned()).or_insert(0) += 1;
        }
    }
    Ok(removed)
}

/// Says what [`remove_dead_nodes_of_abandoned_swarms`] removed, if anything.
pub fn describe_swept(swept: &BTreeMap<String, usize>) -> Option<String> {
    if swept.is_empty() {
        return None;
    }
    let each: Vec<String> = swept
        .iter()
        .map(|(swarm, n)| format!("{n} of swarm `{swarm}`"))
        .collect();
    Some(format!(
        "removed the bus resources of dead nodes whose processes had gone: {}",
        each.join(", ")
    ))
}

/// Removes the stale resources of every dead node whose name `wanted`
/// accepts, stopping between two once `go_on` says no; returns the names
/// of the nodes removed.
fn remove_dead_nodes_named(
    wanted: impl Fn(&str) -> bool,
    go_on: impl Fn() -> bool,
) -> Result<Vec<String>, BusError> {
    crate::bus::quiet_iceoryx();
    let mut dead = Vec::new();
    Node::<ipc::Service>::list(&crate::bus::domain_config(), |state| {
        if let NodeState::Dead(view) = state {
            let name = view
                .details()
                .as_ref()
                .map(|d| d.name().as_str().to_owned());
            if let Some(name) = name.filter(|n| wanted(n)) {
                dead.push((name, view));
            }
        }
        CallbackProgression::Continue
    })
    .map_err(|e| BusError::iceoryx("list nodes", e))?;
    let mut removed = Vec::new();
    for (name, view) in dead {
        if !go_on() {
            break;
        }
        if view.try_remove_stale_resources().is_ok() {
            removed.push(name);
        }
    }
    Ok(removed)
}

/// Removes the dead nodes of `swarm`, whose runtime folder is `runtime`,
/// unless a sweep that started at or after `noticed` (when the death was
/// noticed) has finished meanwhile: one process of the swarm sweeps at a
/// time ([`SwarmRuntime::sweep_unless_swept_since`]) and stops between two
/// nodes once `go_on` says no. What it removed, or why it could not, goes
/// to the log. False when another process is sweeping and `wait` is
/// false: the caller asks again later.
pub fn sweep_dead_nodes(
    runtime: &SwarmRuntime,
    swarm: &str,
    noticed: SystemTime,
    wait: bool,
    go_on: impl Fn() -> bool,
) -> bool {
    match runtime.sweep_unless_swept_since(noticed, wait, || remove_dead_nodes_while(swarm, go_on))
    {
        Ok(Sweep::Busy) => return false,
        Ok(Sweep::Done(Ok(removed))) if removed > 0 => {
            tracing::info!("removed the stale resources of {removed} dead nodes");
        }
        Ok(Sweep::Done(Err(e))) => tracing::warn!(
            "sweeping the dead nodes of swarm `{swarm}`: {:#}",
            anyhow::Error::from(e)
        ),
        Ok(_) => {}
        Err(e) => tracing::warn!("cannot take the sweep lock of swarm `{swarm}`: {e}"),
    }
    true
}

/// Names of every service of `swarm` that still exists on this machine.
pub fn swarm_services(swarm: &str) -> Result<Vec<String>, BusError> {
    use iceoryx2::service::Service;
    crate::bus::quiet_iceoryx();
    let prefix = names::prefix(swarm);
    let mut services = Vec::new();
    ipc::Service::list(&crate::bus::domain_config(), |details| {
        let name = details.static_details.name().as_str().to_owned();
        if name.starts_with(&prefix) {
            services.push(name);
        }
        CallbackProgression::Continue
    })
    .map_err(|e| BusError::iceoryx("list services", e))?;
    Ok(services)
}

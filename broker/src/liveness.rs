//! Who is on the bus: iceoryx2 marks a killed process's node `Dead`; any
//! process of the swarm may then remove its stale resources so a restarted
//! robot with the same id can rejoin at once.

use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

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
    crate::bus::quiet_iceoryx();
    let prefix = names::prefix(swarm);
    let mut dead = Vec::new();
    Node::<ipc::Service>::list(&crate::bus::domain_config(), |state| {
        if let NodeState::Dead(view) = state {
            let ours = view
                .details()
                .as_ref()
                .is_some_and(|d| d.name().as_str().starts_with(&prefix));
            if ours {
                dead.push(view);
            }
        }
        CallbackProgression::Continue
    })
    .map_err(|e| BusError::iceoryx("list nodes", e))?;
    let mut cleaned = 0;
    for view in dead {
        if !go_on() {
            break;
        }
        if view.try_remove_stale_resources().is_ok() {
            cleaned += 1;
        }
    }
    Ok(cleaned)
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

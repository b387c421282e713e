//! Every service of a swarm lives under `shoal/<swarm>/`, so two swarms on one
//! machine never see each other.

use crate::error::BusError;

/// Checks a swarm name: letters, digits, `-` and `_`, at most 32 characters.
pub fn validate_swarm(swarm: &str) -> Result<(), BusError> {
    if shoal_runtime::host::is_plain_name(swarm) {
        Ok(())
    } else {
        Err(BusError::InvalidSwarm(swarm.to_owned()))
    }
}

pub fn prefix(swarm: &str) -> String {
    format!("shoal/{swarm}/")
}

/// The swarm a node or service named `name` belongs to, if it is Shoal's.
pub fn swarm_of_node(name: &str) -> Option<&str> {
    let rest = name.strip_prefix("shoal/")?;
    let (swarm, _) = rest.split_once('/')?;
    shoal_runtime::host::is_plain_name(swarm).then_some(swarm)
}

pub fn cell(swarm: &str, cx: i32, cy: i32) -> String {
    format!("{}{cx}_{cy}", cell_prefix(swarm))
}

/// What every cell service's name of `swarm` starts with.
pub fn cell_prefix(swarm: &str) -> String {
    format!("shoal/{swarm}/cell/")
}

pub fn roster(swarm: &str) -> String {
    format!("shoal/{swarm}/roster")
}

/// Every followed robot's particles, from the SLAM process to viewers.
pub fn slam_particles(swarm: &str) -> String {
    format!("shoal/{swarm}/slam/particles")
}

/// Every followed robot's coarse map, from the SLAM process to viewers.
pub fn slam_map(swarm: &str) -> String {
    format!("shoal/{swarm}/slam/map")
}

/// How far `helper` (recorder, slam) has read, for a lockstep clock.
pub fn progress(swarm: &str, helper: &str) -> String {
    format!("shoal/{swarm}/progress/{helper}")
}

pub fn clock(swarm: &str) -> String {
    format!("shoal/{swarm}/clock")
}

pub fn clock_event(swarm: &str) -> String {
    format!("shoal/{swarm}/clock-event")
}

pub fn ack_event(swarm: &str) -> String {
    format!("shoal/{swarm}/ack-event")
}

pub fn scan(swarm: &str, id: u32) -> String {
    format!("shoal/{swarm}/scan/{id}")
}

pub fn estimate(swarm: &str, id: u32) -> String {
    format!("shoal/{swarm}/estimate/{id}")
}

pub fn model(swarm: &str, id: u32) -> String {
    format!("shoal/{swarm}/model/{id}")
}

pub fn agent_node(swarm: &str, id: u32) -> String {
    format!("shoal/{swarm}/agent/{id}")
}

/// The agent id in a node name of this swarm, if it is an agent's.
pub fn agent_id_of_node(swarm: &str, node_name: &str) -> Option<u32> {
    node_name
        .strip_prefix(&format!("shoal/{swarm}/agent/"))?
        .parse()
        .ok()
}

pub fn tool_node(swarm: &str, role: &str) -> String {
    format!("shoal/{swarm}/{role}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agent_ids_round_trip_through_node_names() {
        assert_eq!(agent_id_of_node("a", &agent_node("a", 17)), Some(17));
        assert_eq!(agent_id_of_node("b", &agent_node("a", 17)), None);
        assert_eq!(agent_id_of_node("a", "shoal/a/agent/x"), None);
    }

    #[test]
    fn swarm_names_are_restricted() {
        assert!(validate_swarm("lab-2_b").is_ok());
        assert!(validate_swarm("").is_err());
        assert!(validate_swarm("a/b").is_err());
    }
}

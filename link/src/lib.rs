//! The link between the hosts of one swarm, over Zenoh: a gateway process
//! per host (`shoal-link`) that carries robots' poses between the hosts'
//! iceoryx2 domains. Within a host, poses stay in shared memory; a remote
//! robot appears in a host's cells as if it ran there (its pose republished
//! by the link), so robots need no change to see across hosts, and no
//! process coordinates the hosts.
//!
//! Zenoh key expressions, all under `shoal/<swarm>/`:
//! - `pose/<cx>_<cy>/<host>/<id>`: every pose of a robot standing in cell
//!   `(cx, cy)`. A host asks only for the cells its robots listen to, so
//!   only what another host needs crosses the network; while someone there
//!   reads the whole swarm (a recorder, `shoal status`), it asks for all.
//! - `summary/<host>`: once a second, who runs on the host (JSON).
//! - `host/<host>`: a liveliness token; it goes when the host's link does
//!   (process gone, or Zenoh's lease expired on a cut network).

pub mod interest;
pub mod report;
pub mod wire;

/// The Zenoh key expressions of swarm `swarm`.
pub mod keys {
    use shoal_broker::CellKey;

    pub fn pose(swarm: &str, cell: CellKey, host: &str, id: u32) -> String {
        format!("shoal/{swarm}/pose/{}_{}/{host}/{id}", cell.0, cell.1)
    }

    /// Every pose from cell `cell`.
    pub fn cell_poses(swarm: &str, cell: CellKey) -> String {
        format!("shoal/{swarm}/pose/{}_{}/**", cell.0, cell.1)
    }

    pub fn all_poses(swarm: &str) -> String {
        format!("shoal/{swarm}/pose/**")
    }

    /// The host and robot id a pose key names.
    pub fn pose_origin(swarm: &str, key: &str) -> Option<(String, u32)> {
        let rest = key.strip_prefix(&format!("shoal/{swarm}/pose/"))?;
        let mut parts = rest.split('/');
        let (_cell, host, id) = (parts.next()?, parts.next()?, parts.next()?);
        if parts.next().is_some() {
            return None;
        }
        Some((host.to_owned(), id.parse().ok()?))
    }

    pub fn summary(swarm: &str, host: &str) -> String {
        format!("shoal/{swarm}/summary/{host}")
    }

    pub fn all_summaries(swarm: &str) -> String {
        format!("shoal/{swarm}/summary/*")
    }

    pub fn host_token(swarm: &str, host: &str) -> String {
        format!("shoal/{swarm}/host/{host}")
    }

    pub fn all_hosts(swarm: &str) -> String {
        format!("shoal/{swarm}/host/*")
    }

    /// The host a summary or liveliness key names: its last chunk.
    pub fn last_chunk(key: &str) -> &str {
        key.rsplit('/').next().unwrap_or_default()
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn a_pose_key_names_its_host_and_robot() {
            let key = pose("lab", (-2, 3), "b", 105);
            assert_eq!(key, "shoal/lab/pose/-2_3/b/105");
            assert_eq!(pose_origin("lab", &key), Some(("b".into(), 105)));
            assert_eq!(pose_origin("other", &key), None);
            assert_eq!(pose_origin("lab", "shoal/lab/pose/0_0/b"), None);
            assert_eq!(pose_origin("lab", "shoal/lab/pose/0_0/b/x"), None);
            assert_eq!(last_chunk(&host_token("lab", "a")), "a");
        }
    }
}

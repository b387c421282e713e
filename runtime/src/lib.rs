//! What every Shoal process shares beside the bus: the swarm's runtime
//! folder (its scenario, clock mode, robots' last poses, SLAM's report) and
//! the frame of every binary.

pub mod folder;
pub mod process_main;

pub use folder::{FollowedReport, SlamReport, SwarmMeta, SwarmRuntime};

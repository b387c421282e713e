//! What every Shoal process shares beside the bus: the swarm's runtime
//! folder (its scenario, clock mode, robots' last poses, the helpers'
//! reports) and
//! the frame of every binary. Reading files is here, so `shoal-physics`
//! stays free of I/O.

pub mod folder;
pub mod host;
pub mod process_main;
pub mod report;

use std::path::Path;

use shoal_scenario::Scenario;
use shoal_scenario::ScenarioError;

pub use folder::{HelperReport, ReportError, SwarmMeta, SwarmRuntime, Sweep};

/// Reads and checks a scenario file; errors name the file (and the line
/// and field, for what is in it).
pub fn read_scenario(path: &Path) -> Result<Scenario, ScenarioError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ScenarioError {
        file: file.clone(),
        line: None,
        field: None,
        message: format!("cannot read: {e}"),
    })?;
    Scenario::from_toml(&text, &file)
}

impl SwarmRuntime {
    /// The scenario the swarm runs.
    pub fn read_scenario(&self) -> Result<Scenario, ScenarioError> {
        read_scenario(&self.scenario_path())
    }
}

/// Whether `pid` is a running (not zombie) process.
pub fn pid_alive(pid: i32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        // The state letter follows the parenthesised command name.
        Ok(stat) => stat
            .rsplit_once(')')
            .and_then(|(_, rest)| rest.trim_start().chars().next())
            .is_some_and(|s| s != 'Z' && s != 'X'),
        Err(_) => false,
    }
}

//! The pieces behind the `shoal` command line: starting and watching swarms,
//! the lockstep clock driver, status, control and the experiments.

pub mod clock;
pub mod control;
pub mod demo;
pub mod experiment;
pub mod helper_log;
pub mod observer;
pub mod process;
pub mod report;
pub mod status;
pub mod swarm;
pub mod sweeper;
pub mod up;

//! Running a swarm, as a library: a supervisor that starts robot processes
//! and watches them ([`supervisor`]), the helpers that serve the swarm
//! (recorder, SLAM, link: [`helpers`]), the lockstep clock and its pacing
//! ([`clock`], [`pacing`]), deaths ([`deaths`]), the stop ([`shutdown`]), and
//! acting on a running swarm from any terminal ([`control`]). The `shoal`
//! command line and the lab drive it; it prints nothing of its own but the
//! lines a user must see as they happen.

pub mod clock;
pub mod control;
pub mod deaths;
pub mod helper_log;
pub mod helpers;
pub mod observer;
pub mod pacing;
pub mod process;
pub mod shutdown;
pub mod supervisor;
pub mod sweeper;

pub use deaths::Death;
pub use helpers::{LinkOptions, RecordOptions};
pub use process::RECORDER_BINARY;
pub use supervisor::{Launch, RunningSwarm};

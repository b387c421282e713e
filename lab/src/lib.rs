//! The lab: the swarm's experiments and the demo. Each runs real robot
//! processes through `shoal-swarm` and returns a report; `shoal experiment`
//! and `shoal demo` print them, and `shoal-bench` reuses the runs.

pub mod demo;
pub mod experiment;

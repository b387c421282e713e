//! Pure physics of a Shoal swarm: poses, legged motion models, the arena,
//! scenarios, formation control and the simulated body. No I/O lives here,
//! so every rule can be tested directly.

pub mod arena;
pub mod body;
pub mod effects;
pub mod formation;
pub mod legged;
pub mod metrics;
pub mod mixture;
pub mod planner;
pub mod pose;
pub mod range;
pub mod toml_file;
pub mod unicycle;
pub mod wander;

pub use arena::{Arena, Obstacle, Surface, Wall};
pub use body::{Body, StepOutcome};
pub use effects::{Effect, ScopedEffect};
pub use formation::{ForceLaw, FormationParams, Neighbour};
pub use legged::{Command, MotionModel, MotionSample};
pub use mixture::Mixture2;
pub use pose::{Pose, wrap_angle, yaw_of_quaternion};
pub use toml_file::ScenarioError;
pub use unicycle::{Actuators, CommandGrid, Executed, UnicycleModel};

//! `shoal diagnose`: where a simulation and a real run differ, which physics
//! the simulation left out, and how much better the run is explained with it.
//! Pure logic: inputs arrive as text or numbers, outputs leave as values.

pub mod candidates;
pub mod covariates;
pub mod diagnosis;
pub mod entry;
pub mod feedback;
pub mod fit;
pub mod glitches;
pub mod heldout;
pub mod input;
pub mod likelihood;
pub mod locate;
pub mod mocap;
pub mod motive;
pub mod prepared;
pub mod recording;
pub mod replay;
pub mod segments;
pub mod selection;
pub mod timeout;
pub mod track;
pub mod vicon;
pub mod zones;

pub use diagnosis::{Diagnosis, Options, diagnose};
pub use recording::Recording;

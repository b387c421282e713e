//! `shoal diagnose`: where a simulation and a real run differ, which physics
//! the simulation left out, and how much better the run is explained with it.
//! Pure logic: inputs arrive as text or numbers, outputs leave as values.

pub mod input;
pub mod likelihood;
pub mod recording;
pub mod segments;
pub mod fit;
pub mod generate;

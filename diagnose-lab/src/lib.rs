//! The diagnosis's lab: runs generated with known physics, and the harness
//! that diagnoses them blind and counts what was named. Kept out of the pure
//! `shoal-diagnose` library, which only diagnoses.

pub mod experiment;
pub mod generate;

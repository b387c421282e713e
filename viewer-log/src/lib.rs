//! Recordings of a swarm as Rerun `.rrd` files. The only crate that depends on `rerun`.

pub mod arena;
pub mod motion;
pub mod recorder;
pub mod slam;
pub mod tum;

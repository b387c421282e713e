//! Recordings of a swarm as Rerun `.rrd` files. The only crate that depends on `rerun`.

pub mod arena;
pub mod motion;
pub mod presence;
pub mod recorder;
pub mod rrd_file;
pub mod run_files;
pub mod slam;
pub mod space;
pub mod tum;

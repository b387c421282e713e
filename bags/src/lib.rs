//! ROS 2 bags as people record them, read without a ROS 2 installation:
//! MCAP and sqlite3 (`.db3`) storage, split bags in a folder, compressed
//! files, chunks and messages (`storage`); the standard messages of velocity
//! commands and poses (`ros`); a robot's pose composed through a TF tree
//! (`tf`); the one clock commands and poses are compared on (`clock`); and a
//! writer of bags Shoal's generator makes (`write`).

pub mod clock;
pub mod ros;
pub mod run;
pub mod storage;
pub mod tf;
pub mod write;

pub use clock::{ClockChoice, StampsPreference, Timing};
pub use run::{BagRun, Selection, read_run};
pub use storage::{Bag, RawMessage, Topic};

/// What went wrong reading a bag, naming the file.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{file}: {message}")]
pub struct BagError {
    pub file: String,
    pub message: String,
}

impl BagError {
    pub fn new(file: &std::path::Path, message: String) -> Self {
        Self {
            file: file.display().to_string(),
            message,
        }
    }
}

/// Whether `path` names a bag: an `.mcap` or `.db3` file (zstd-compressed
/// or not), a folder holding `metadata.yaml` or such files, or a ROS 1
/// bag (which reading refuses, saying how to convert it).
pub fn looks_like_bag(path: &std::path::Path) -> bool {
    if path.is_dir() {
        path.join("metadata.yaml").is_file()
            || std::fs::read_dir(path).is_ok_and(|entries| {
                entries
                    .filter_map(Result::ok)
                    .any(|e| storage::is_bag_file(&e.path()))
            })
    } else {
        storage::is_bag_file(path) || storage::is_ros1_bag(path)
    }
}

//! A swarm's small on-disk footprint beside the bus: the scenario it runs, its
//! clock mode, and each robot's last pose, so `shoal restart` and `shoal
//! spawn` work from any terminal. It is a notebook, not a controller: robots
//! never read each other's files.

use std::io;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SwarmMeta {
    /// Robots step on the clock's ticks instead of on their own timers.
    pub lockstep: bool,
    /// The shared time origin of a real-time swarm, ms since the Unix epoch.
    pub epoch_unix_ms: u64,
    pub period_s: f64,
}

/// The SLAM process's view of each robot it follows.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SlamReport {
    pub pid: u32,
    pub followed: Vec<FollowedReport>,
}

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FollowedReport {
    pub id: u32,
    pub steps: u64,
    /// How far the learned model has moved from the one SLAM started with:
    /// the mean over commands and parameters of |mean shift| / starting std.
    pub model_distance: f64,
    /// No scan for a while: the robot is gone, its filter waits.
    pub paused: bool,
    /// The filter's pose estimate, once it has started.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate: Option<[f64; 3]>,
}

#[derive(Clone, Debug)]
pub struct SwarmRuntime {
    pub dir: PathBuf,
}

impl SwarmRuntime {
    /// `$SHOAL_RUNTIME_DIR/<swarm>`, or `<tmp>/shoal-<uid>/<swarm>`.
    pub fn locate(swarm: &str) -> Self {
        let base = std::env::var_os("SHOAL_RUNTIME_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| {
                // SAFETY: getuid has no preconditions and cannot fail.
                let uid = unsafe { libc::getuid() };
                std::env::temp_dir().join(format!("shoal-{uid}"))
            });
        Self {
            dir: base.join(swarm),
        }
    }

    pub fn scenario_path(&self) -> PathBuf {
        self.dir.join("scenario.toml")
    }

    fn meta_path(&self) -> PathBuf {
        self.dir.join("swarm.toml")
    }

    pub fn log_path(&self, id: u32) -> PathBuf {
        self.dir.join(format!("agent-{id}.log"))
    }

    fn pose_path(&self, id: u32) -> PathBuf {
        self.dir.join(format!("agent-{id}.pose"))
    }

    pub fn create(&self, scenario_toml: &str, meta: &SwarmMeta) -> io::Result<()> {
        std::fs::create_dir_all(&self.dir)?;
        write_atomically(&self.scenario_path(), scenario_toml)?;
        let meta = toml::to_string(meta).map_err(io::Error::other)?;
        write_atomically(&self.meta_path(), &meta)
    }

    pub fn read_meta(&self) -> io::Result<SwarmMeta> {
        let path = self.meta_path();
        let text = std::fs::read_to_string(&path).map_err(|e| {
            io::Error::new(
                e.kind(),
                format!("{}: {e} (is the swarm running?)", path.display()),
            )
        })?;
        toml::from_str(&text).map_err(|e| {
            io::Error::new(
                io::ErrorKind::InvalidData,
                format!("{}: {e}", path.display()),
            )
        })
    }

    fn slam_report_path(&self) -> PathBuf {
        self.dir.join("slam.toml")
    }

    /// What the SLAM process says of the robots it follows, for `shoal status`.
    pub fn write_slam_report(&self, report: &SlamReport) -> io::Result<()> {
        let text = toml::to_string(report).map_err(io::Error::other)?;
        write_atomically(&self.slam_report_path(), &text)
    }

    pub fn read_slam_report(&self) -> Option<SlamReport> {
        let text = std::fs::read_to_string(self.slam_report_path()).ok()?;
        toml::from_str(&text).ok()
    }

    pub fn write_last_pose(&self, id: u32, pose: [f64; 3]) -> io::Result<()> {
        write_atomically(
            &self.pose_path(id),
            &format!("{} {} {}\n", pose[0], pose[1], pose[2]),
        )
    }

    pub fn read_last_pose(&self, id: u32) -> Option<[f64; 3]> {
        let text = std::fs::read_to_string(self.pose_path(id)).ok()?;
        let values: Vec<f64> = text
            .split_whitespace()
            .filter_map(|v| v.parse().ok())
            .collect();
        match values[..] {
            [x, y, theta] if values.iter().all(|v| v.is_finite()) => Some([x, y, theta]),
            _ => None,
        }
    }

    /// Ids of every robot that ever wrote a pose in this swarm.
    pub fn known_agent_ids(&self) -> Vec<u32> {
        let Ok(entries) = std::fs::read_dir(&self.dir) else {
            return Vec::new();
        };
        entries
            .filter_map(|e| e.ok())
            .filter_map(|e| {
                let name = e.file_name().into_string().ok()?;
                name.strip_prefix("agent-")?
                    .strip_suffix(".pose")?
                    .parse()
                    .ok()
            })
            .collect()
    }

    pub fn remove(&self) -> io::Result<()> {
        match std::fs::remove_dir_all(&self.dir) {
            Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
            _ => Ok(()),
        }
    }
}

/// Readers never see half a file: write beside, then rename.
fn write_atomically(path: &Path, text: &str) -> io::Result<()> {
    let partial = path.with_extension("partial");
    std::fs::write(&partial, text)?;
    std::fs::rename(&partial, path)
}

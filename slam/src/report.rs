//! SLAM's report in the swarm's folder: what the SLAM process says of each
//! robot it follows, for `shoal status`, the demo and the tests.

use shoal_runtime::folder::HelperReport;

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
    /// The tick the estimate is of (its newest stepped scan's): a reader
    /// holds it against where the robot stood then, not now.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate_tick: Option<u64>,
    /// How far the learned model says a stride of `stride_walk` carries,
    /// metres: the scalar a reader can hold against the truth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stride_m: Option<f64>,
    /// The walk command (1-3) of `stride_m`: the one the robot was
    /// commanded most (3, the full stride, before it walked).
    #[serde(default = "full_stride_walk")]
    pub stride_walk: u8,
    /// Filter steps per second since the report before: a robot at 5 Hz
    /// needs 5 to keep up.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps_per_s: Option<f64>,
    /// How far the filter trails its robot: seconds of the robot's scans
    /// not yet stepped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub behind_s: Option<f64>,
    /// Scans of ticks the robot was seen on that the filter never stepped
    /// (lost on the bus while it fell behind): their motion is missing.
    #[serde(default)]
    pub scans_missed: u64,
    /// Scans whose command moved the filter without their ranges being
    /// scored, while it caught up with its robot.
    #[serde(default)]
    pub scans_coasted: u64,
    /// Steps whose scan fitted far worse than usual from where the motion
    /// model led, matched again from turns the model does not reach: a
    /// robot that turned far past its model.
    #[serde(default)]
    pub steps_rematched: u64,
    /// Particles the filter holds now: fewer than configured while it
    /// sheds work to keep up with its robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub particles: Option<usize>,
}

/// The walk command of the full stride (`walk(3)`): the stride reported
/// before a robot has walked.
pub const FULL_STRIDE_WALK: u8 = 3;

fn full_stride_walk() -> u8 {
    FULL_STRIDE_WALK
}

impl HelperReport for SlamReport {
    const FILE: &'static str = "slam.toml";
    fn writer_pid(&self) -> u32 {
        self.pid
    }
}

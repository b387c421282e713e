//! What crosses shared memory. Every type is `#[repr(C)]` with an explicit
//! type name, so the Python `iceoryx2` client can read it with a ctypes
//! structure of the same name and layout (see `python/shoal_wire.py`).

use iceoryx2::prelude::ZeroCopySend;

/// The most neighbours a pose sample lists.
pub const MAX_NEIGHBOURS: usize = 16;

/// One robot's state after one control period.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("shoal.Pose")]
#[repr(C)]
pub struct PoseSample {
    pub agent_id: u32,
    pub pid: u32,
    /// The control period this pose ends.
    pub tick: u64,
    pub sim_time: f64,
    /// True pose, as the body's localisation reports it.
    pub x: f64,
    pub y: f64,
    pub theta: f64,
    /// What the robot believes from its own motion model (dead reckoning,
    /// corrected by SLAM when it is followed).
    pub believed_x: f64,
    pub believed_y: f64,
    pub believed_theta: f64,
    /// Velocity over the last period, m/s.
    pub vx: f64,
    pub vy: f64,
    /// Index of the command executed in this period (`shoal_physics::Command::ALL`).
    pub command: u32,
    /// Bit set of [`Health`] flags.
    pub health: u32,
    /// How many robots it could see this period.
    pub visible: u32,
    pub neighbour_count: u32,
    pub neighbours: [u32; MAX_NEIGHBOURS],
    /// Control periods this robot has missed since it started: in real time,
    /// periods it woke too late for. None can be missed in lockstep.
    pub missed_periods: u32,
    /// How old the oldest neighbour pose it acted on this period was, ms:
    /// from the start of that pose's period to when this robot acted.
    pub neighbour_age_ms: u32,
}

impl PoseSample {
    /// A robot standing still at `(x, y, theta)`, believing it is exactly there.
    pub fn standing(agent_id: u32, pid: u32, tick: u64, x: f64, y: f64, theta: f64) -> Self {
        Self {
            agent_id,
            pid,
            tick,
            sim_time: 0.0,
            x,
            y,
            theta,
            believed_x: x,
            believed_y: y,
            believed_theta: theta,
            vx: 0.0,
            vy: 0.0,
            command: 0,
            health: 0,
            visible: 0,
            neighbour_count: 0,
            neighbours: [0; MAX_NEIGHBOURS],
            missed_periods: 0,
            neighbour_age_ms: 0,
        }
    }

    pub fn neighbour_ids(&self) -> &[u32] {
        &self.neighbours[..(self.neighbour_count as usize).min(MAX_NEIGHBOURS)]
    }
}

/// Flags in [`PoseSample::health`].
pub struct Health;

impl Health {
    /// A wall, obstacle or robot stopped the last step.
    pub const BUMPED: u32 = 1;
    /// The robot sees no other robot.
    pub const ISOLATED: u32 = 2;
    /// The robot could not publish into its cell last period (cell full).
    pub const CELL_FULL: u32 = 4;
    /// The robot rejected malformed samples since it started.
    pub const REJECTED_INPUT: u32 = 8;
}

/// The most beams a scan carries.
pub const MAX_BEAMS: usize = 361;

/// What a robot's range sensor read after executing a command.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("shoal.Scan")]
#[repr(C)]
pub struct ScanSample {
    pub agent_id: u32,
    pub pid: u32,
    pub tick: u64,
    pub sim_time: f64,
    /// Index of the command executed before the scan (`shoal_physics::Command::ALL`).
    pub command: u32,
    /// 1 when a wall or robot stopped the command's translation.
    pub bumped: u32,
    pub beam_count: u32,
    pub reserved: u32,
    /// Beams spread evenly over this angle, centred on the heading.
    pub field_of_view: f64,
    /// Ranges at or beyond this returned nothing.
    pub max_range: f64,
    pub ranges: [f32; MAX_BEAMS],
}

impl ScanSample {
    pub fn ranges(&self) -> &[f32] {
        &self.ranges[..(self.beam_count as usize).min(MAX_BEAMS)]
    }
}

/// A SLAM process's estimate of a robot's pose.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("shoal.Estimate")]
#[repr(C)]
pub struct EstimateSample {
    pub agent_id: u32,
    pub reserved: u32,
    pub tick: u64,
    pub x: f64,
    pub y: f64,
    pub theta: f64,
    pub effective_particles: f64,
}

/// A learned motion-model parameter: one command, one of D, C, T, as a
/// two-Gaussian mixture.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("shoal.ModelUpdate")]
#[repr(C)]
pub struct ModelUpdate {
    pub agent_id: u32,
    pub command: u32,
    /// 0 = D (along), 1 = C (across), 2 = T (turn).
    pub param: u32,
    pub reserved: u32,
    /// The SLAM step that produced it.
    pub step: u64,
    pub weights: [f64; 2],
    pub means: [f64; 2],
    pub variances: [f64; 2],
}

/// One beat of the lockstep clock.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("shoal.ClockTick")]
#[repr(C)]
pub struct ClockTick {
    pub tick: u64,
    pub sim_time: f64,
    pub period_s: f64,
}

/// How many particles a SLAM view shows at most.
pub const MAX_SHOWN_PARTICLES: usize = 256;
/// The side of a SLAM map view, in cells at most.
pub const MAX_MAP_SIDE: usize = 128;

/// A followed robot's particles after a SLAM step (an even subsample), for viewers.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("shoal.SlamParticles")]
#[repr(C)]
pub struct SlamParticles {
    pub agent_id: u32,
    pub count: u32,
    /// The robot's tick of the scan this step used.
    pub tick: u64,
    pub sim_time: f64,
    pub xy: [[f32; 2]; MAX_SHOWN_PARTICLES],
}

/// A followed robot's map (its best particle's), coarsened to at most
/// `MAX_MAP_SIDE` cells a side, as ROS occupancy: 0 free, 100 occupied, 255 unknown.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("shoal.SlamMap")]
#[repr(C)]
pub struct SlamMap {
    pub agent_id: u32,
    pub width: u32,
    pub height: u32,
    pub cell_size: f32,
    pub origin: [f32; 2],
    pub tick: u64,
    pub sim_time: f64,
    pub cells: [u8; MAX_MAP_SIDE * MAX_MAP_SIDE],
}

/// The newest lockstep tick a helper (recorder, SLAM) has read; the
/// launcher of a lockstep swarm paces its clock to it, so a helper misses
/// no tick.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("shoal.HelperProgress")]
#[repr(C)]
pub struct HelperProgress {
    pub tick: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_match_the_python_mirror() {
        // python/shoal_wire.py declares the same fields; these sizes pin the layout.
        assert_eq!(core::mem::size_of::<PoseSample>(), 176);
        assert_eq!(core::mem::size_of::<ClockTick>(), 24);
        assert_eq!(core::mem::size_of::<ScanSample>(), 56 + 4 * MAX_BEAMS + 4);
        assert_eq!(core::mem::size_of::<EstimateSample>(), 48);
        assert_eq!(core::mem::size_of::<ModelUpdate>(), 72);
        assert_eq!(
            core::mem::size_of::<SlamParticles>(),
            24 + 8 * MAX_SHOWN_PARTICLES
        );
        assert_eq!(
            core::mem::size_of::<SlamMap>(),
            40 + MAX_MAP_SIDE * MAX_MAP_SIDE
        );
        assert_eq!(core::mem::size_of::<HelperProgress>(), 8);
        assert_eq!(
            unsafe { <PoseSample as ZeroCopySend>::type_name() },
            "shoal.Pose"
        );
    }
}

//! Nothing from the bus is trusted. Every wire type has one check, [`Wire::check`],
//! and every reader in this crate applies it before handing a sample on:
//! what fails is counted by the reader and never used. [`SampleCheck`] adds
//! what only a reader that knows the map can judge: a pose far outside it.

use shoal_physics::Mixture2;
use shoal_physics::legged::{Command, Param};

use crate::wire::{
    ClockTick, EstimateSample, HelperProgress, MAX_BEAMS, MAX_MAP_SIDE, MAX_NEIGHBOURS,
    MAX_SHOWN_PARTICLES, ModelUpdate, PoseSample, ScanSample, SlamMap, SlamParticles,
};

/// No swarm runs this many ticks (35 years at 1 kHz); a larger tick is a
/// forgery that would make every robot wait for a tick that never comes.
pub const MAX_TICK: u64 = 1 << 40;
/// Nor this many seconds.
pub const MAX_SIM_TIME_S: f64 = 1.0e9;
/// Positions further than this from the origin (metres) are not of a robot.
pub const MAX_COORDINATE_M: f64 = 1.0e6;
/// The longest control period a clock may announce.
pub const MAX_PERIOD_S: f64 = 60.0;
/// The longest range a scan may claim.
pub const MAX_SCAN_RANGE_M: f64 = 1.0e4;

/// Why a sample was not used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Rejection {
    #[error("{field} is {value}, not a finite number")]
    NotFinite { field: &'static str, value: f64 },
    #[error("{field} is {value}, outside {range}")]
    OutOfRange {
        field: &'static str,
        value: f64,
        range: &'static str,
    },
    #[error("{field} counts {count}, more than the {max} it can hold")]
    TooMany {
        field: &'static str,
        count: u64,
        max: u64,
    },
    #[error("{field} is {value}, which names nothing")]
    Unknown { field: &'static str, value: u64 },
    #[error("the model mixture is invalid: {0}")]
    BadMixture(String),
    #[error("the pose is far outside the map")]
    OutsideMap,
}

/// A type that crosses the bus and can say whether a sample of it is usable.
pub trait Wire {
    fn check(&self) -> Result<(), Rejection>;
}

fn finite(field: &'static str, value: f64) -> Result<(), Rejection> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(Rejection::NotFinite { field, value })
    }
}

fn within(
    field: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    range: &'static str,
) -> Result<(), Rejection> {
    finite(field, value)?;
    if value < lo || value > hi {
        return Err(Rejection::OutOfRange {
            field,
            value,
            range,
        });
    }
    Ok(())
}

fn tick(field: &'static str, value: u64) -> Result<(), Rejection> {
    if value > MAX_TICK {
        return Err(Rejection::OutOfRange {
            field,
            value: value as f64,
            range: "[0, 2^40]",
        });
    }
    Ok(())
}

fn sim_time(value: f64) -> Result<(), Rejection> {
    within("sim_time", value, 0.0, MAX_SIM_TIME_S, "[0, 1e9] s")
}

fn coordinate(field: &'static str, value: f64) -> Result<(), Rejection> {
    within(
        field,
        value,
        -MAX_COORDINATE_M,
        MAX_COORDINATE_M,
        "[-1e6, 1e6] m",
    )
}

fn count(field: &'static str, count: u32, max: usize) -> Result<usize, Rejection> {
    if count as usize > max {
        return Err(Rejection::TooMany {
            field,
            count: count.into(),
            max: max as u64,
        });
    }
    Ok(count as usize)
}

fn command(value: u32) -> Result<(), Rejection> {
    Command::from_index(value as usize)
        .map(|_| ())
        .ok_or(Rejection::Unknown {
            field: "command",
            value: value.into(),
        })
}

impl Wire for PoseSample {
    fn check(&self) -> Result<(), Rejection> {
        tick("tick", self.tick)?;
        sim_time(self.sim_time)?;
        coordinate("x", self.x)?;
        coordinate("y", self.y)?;
        finite("theta", self.theta)?;
        coordinate("believed_x", self.believed_x)?;
        coordinate("believed_y", self.believed_y)?;
        finite("believed_theta", self.believed_theta)?;
        within("vx", self.vx, -1e3, 1e3, "[-1000, 1000] m/s")?;
        within("vy", self.vy, -1e3, 1e3, "[-1000, 1000] m/s")?;
        command(self.command)?;
        count("neighbour_count", self.neighbour_count, MAX_NEIGHBOURS)?;
        Ok(())
    }
}

impl Wire for ClockTick {
    fn check(&self) -> Result<(), Rejection> {
        tick("tick", self.tick)?;
        sim_time(self.sim_time)?;
        within(
            "period_s",
            self.period_s,
            1e-6,
            MAX_PERIOD_S,
            "[1e-6, 60] s",
        )?;
        // The clock's time is its tick count times its period; a tick that
        // disagrees with itself was not sent by a clock.
        let expected = self.tick as f64 * self.period_s;
        if (self.sim_time - expected).abs() > self.period_s {
            return Err(Rejection::OutOfRange {
                field: "sim_time",
                value: self.sim_time,
                range: "tick * period_s (within one period)",
            });
        }
        Ok(())
    }
}

impl Wire for HelperProgress {
    fn check(&self) -> Result<(), Rejection> {
        tick("tick", self.tick)
    }
}

impl Wire for ScanSample {
    fn check(&self) -> Result<(), Rejection> {
        tick("tick", self.tick)?;
        sim_time(self.sim_time)?;
        command(self.command)?;
        if self.bumped > 1 {
            return Err(Rejection::Unknown {
                field: "bumped",
                value: self.bumped.into(),
            });
        }
        let beams = count("beam_count", self.beam_count, MAX_BEAMS)?;
        within(
            "field_of_view",
            self.field_of_view,
            0.0,
            core::f64::consts::TAU,
            "[0, 2 pi] rad",
        )?;
        within(
            "max_range",
            self.max_range,
            1e-3,
            MAX_SCAN_RANGE_M,
            "[0.001, 1e4] m",
        )?;
        for range in &self.ranges[..beams] {
            within(
                "ranges",
                f64::from(*range),
                0.0,
                MAX_SCAN_RANGE_M,
                "[0, 1e4] m",
            )?;
        }
        Ok(())
    }
}

impl Wire for EstimateSample {
    fn check(&self) -> Result<(), Rejection> {
        tick("tick", self.tick)?;
        coordinate("x", self.x)?;
        coordinate("y", self.y)?;
        finite("theta", self.theta)?;
        within(
            "effective_particles",
            self.effective_particles,
            0.0,
            1e9,
            "[0, 1e9]",
        )
    }
}

impl Wire for ModelUpdate {
    fn check(&self) -> Result<(), Rejection> {
        command(self.command)?;
        if Param::ALL.get(self.param as usize).is_none() {
            return Err(Rejection::Unknown {
                field: "param",
                value: self.param.into(),
            });
        }
        // The same rule a model file obeys: a step moves metres, not kilometres.
        self.mixture().validate().map_err(Rejection::BadMixture)
    }
}

impl ModelUpdate {
    /// The learned `mixture` of `command`'s `param` for robot `agent_id`,
    /// after `step` SLAM steps, as it goes on the wire.
    pub fn new(
        agent_id: u32,
        command: Command,
        param: Param,
        step: u64,
        mixture: &Mixture2,
    ) -> Self {
        Self {
            agent_id,
            command: command.index() as u32,
            param: param.index() as u32,
            reserved: 0,
            step,
            weights: mixture.weights,
            means: mixture.means,
            variances: mixture.variances,
        }
    }

    /// Which mixture of a motion model the update replaces, or `None` for
    /// indices that name nothing (the wire check refuses those).
    pub fn target(&self) -> Option<(Command, Param)> {
        let command = Command::from_index(self.command as usize)?;
        let param = *Param::ALL.get(self.param as usize)?;
        Some((command, param))
    }

    pub fn mixture(&self) -> Mixture2 {
        Mixture2 {
            weights: self.weights,
            means: self.means,
            variances: self.variances,
        }
    }
}

impl Wire for SlamParticles {
    fn check(&self) -> Result<(), Rejection> {
        tick("tick", self.tick)?;
        sim_time(self.sim_time)?;
        let shown = count("count", self.count, MAX_SHOWN_PARTICLES)?;
        for [x, y] in &self.xy[..shown] {
            coordinate("xy", f64::from(*x))?;
            coordinate("xy", f64::from(*y))?;
        }
        Ok(())
    }
}

impl Wire for SlamMap {
    fn check(&self) -> Result<(), Rejection> {
        tick("tick", self.tick)?;
        sim_time(self.sim_time)?;
        let width = count("width", self.width, MAX_MAP_SIDE)?;
        let height = count("height", self.height, MAX_MAP_SIDE)?;
        if width == 0 || height == 0 {
            return Err(Rejection::OutOfRange {
                field: "width x height",
                value: 0.0,
                range: "at least one cell",
            });
        }
        within(
            "cell_size",
            f64::from(self.cell_size),
            1e-3,
            1e3,
            "[0.001, 1000] m",
        )?;
        coordinate("origin", f64::from(self.origin[0]))?;
        coordinate("origin", f64::from(self.origin[1]))?;
        // ROS occupancy: 0..=100, or 255 for unknown.
        if let Some(cell) = self.cells[..width * height]
            .iter()
            .find(|c| **c > 100 && **c != 255)
        {
            return Err(Rejection::Unknown {
                field: "cells",
                value: (*cell).into(),
            });
        }
        Ok(())
    }
}

/// Counts what one reader rejected, warning on the first of each run of
/// rejections so a flood of forgeries cannot flood the log too.
#[derive(Debug, Default)]
pub struct Rejected {
    count: core::cell::Cell<u64>,
}

impl Rejected {
    /// Passes a sample that checks out; counts and drops one that does not.
    pub fn filter<T: Wire>(&self, what: &str, sample: &T) -> bool {
        match sample.check() {
            Ok(()) => true,
            Err(rejection) => {
                self.count_one(what, rejection);
                false
            }
        }
    }

    /// Counts a sample the reader itself found unusable.
    pub fn count_one(&self, what: &str, why: impl core::fmt::Display) {
        let count = self.count.get() + 1;
        self.count.set(count);
        if count.is_power_of_two() {
            tracing::warn!(count, "rejected a malformed {what}: {why}");
        }
    }

    pub fn count(&self) -> u64 {
        self.count.get()
    }
}

/// Checks pose samples against the map and counts what it rejects.
#[derive(Clone, Debug)]
pub struct SampleCheck {
    /// `[xmin, ymin, xmax, ymax]` of what is plausible.
    bounds: [f64; 4],
    pub rejected: u64,
}

/// How far outside the map a pose may be and still be plausible: a robot
/// pushed against a wall, with its pose noise.
const MAP_MARGIN_M: f64 = 1.0;

impl SampleCheck {
    /// Poses more than [`MAP_MARGIN_M`] outside the scenario's arena are implausible.
    pub fn for_scenario(scenario: &shoal_scenario::Scenario) -> Self {
        Self::for_map(scenario.arena.width, scenario.arena.height, MAP_MARGIN_M)
    }

    /// Poses more than `margin` metres outside a `width` x `height` map are implausible.
    fn for_map(width: f64, height: f64, margin: f64) -> Self {
        Self {
            bounds: [-margin, -margin, width + margin, height + margin],
            rejected: 0,
        }
    }

    pub fn inspect(&self, sample: &PoseSample) -> Result<(), Rejection> {
        sample.check()?;
        let [x0, y0, x1, y1] = self.bounds;
        if sample.x < x0 || sample.x > x1 || sample.y < y0 || sample.y > y1 {
            return Err(Rejection::OutsideMap);
        }
        Ok(())
    }

    /// True when the sample may be used; counts it otherwise.
    pub fn accept(&mut self, sample: &PoseSample) -> bool {
        match self.inspect(sample) {
            Ok(()) => true,
            Err(rejection) => {
                self.rejected += 1;
                tracing::warn!(
                    agent = sample.agent_id,
                    "rejected a malformed pose sample: {rejection}"
                );
                false
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x: f64, y: f64) -> PoseSample {
        PoseSample::standing(1, 1, 0, x, y, 0.0)
    }

    #[test]
    fn non_finite_and_far_away_poses_are_rejected_and_counted() {
        let mut check = SampleCheck::for_map(10.0, 10.0, 1.0);
        assert!(check.accept(&sample(5.0, 5.0)));
        assert!(!check.accept(&sample(f64::NAN, 5.0)));
        assert!(!check.accept(&sample(5.0, f64::INFINITY)));
        assert!(!check.accept(&sample(5.0, 1e6)));
        let mut bad = sample(5.0, 5.0);
        bad.neighbour_count = 99;
        assert!(!check.accept(&bad));
        assert_eq!(check.rejected, 4);
    }

    #[test]
    fn a_model_update_names_the_mixture_it_was_made_from() {
        let mixture = Mixture2::gaussian(0.2, 0.01);
        let update = ModelUpdate::new(7, Command::Walk(3), Param::C, 12, &mixture);
        assert_eq!(update.check(), Ok(()));
        assert_eq!(update.target(), Some((Command::Walk(3), Param::C)));
        assert_eq!(update.mixture(), mixture);
        let nowhere = ModelUpdate { param: 3, ..update };
        assert_eq!(nowhere.target(), None);
        assert!(nowhere.check().is_err());
    }

    #[test]
    fn forged_clock_ticks_are_rejected() {
        let good = ClockTick {
            tick: 100,
            sim_time: 10.0,
            period_s: 0.1,
        };
        assert_eq!(good.check(), Ok(()));
        for bad in [
            ClockTick {
                tick: u64::MAX,
                ..good
            },
            ClockTick {
                sim_time: f64::NAN,
                ..good
            },
            ClockTick {
                period_s: 0.0,
                ..good
            },
            ClockTick {
                sim_time: 1e6,
                ..good
            },
        ] {
            assert!(bad.check().is_err(), "{bad:?} passed");
        }
        assert!(HelperProgress { tick: u64::MAX }.check().is_err());
    }

    #[test]
    fn model_updates_that_would_throw_a_robot_to_infinity_are_rejected() {
        let good = ModelUpdate {
            agent_id: 1,
            command: 1,
            param: 0,
            reserved: 0,
            step: 3,
            weights: [0.5, 0.5],
            means: [0.1, 0.2],
            variances: [0.01, 0.01],
        };
        assert_eq!(good.check(), Ok(()));
        let huge = ModelUpdate {
            means: [1e308, 0.0],
            ..good
        };
        assert!(matches!(huge.check(), Err(Rejection::BadMixture(_))));
        assert!(
            ModelUpdate {
                command: 14,
                ..good
            }
            .check()
            .is_err()
        );
        assert!(ModelUpdate { param: 3, ..good }.check().is_err());
    }

    #[test]
    fn scans_maps_and_particles_are_checked_within_their_counts() {
        let mut scan = ScanSample {
            agent_id: 1,
            pid: 1,
            tick: 1,
            sim_time: 0.1,
            command: 0,
            bumped: 0,
            beam_count: 2,
            reserved: 0,
            field_of_view: 3.0,
            max_range: 5.0,
            ranges: [f32::NAN; MAX_BEAMS],
        };
        scan.ranges[0] = 1.0;
        scan.ranges[1] = 2.0;
        // Beams past the count are not read, so they may hold anything.
        assert_eq!(scan.check(), Ok(()));
        scan.beam_count = 3;
        assert!(scan.check().is_err());
        scan.beam_count = MAX_BEAMS as u32 + 1;
        assert!(scan.check().is_err());

        let mut map = SlamMap {
            agent_id: 1,
            width: 2,
            height: 2,
            cell_size: 0.1,
            origin: [0.0, 0.0],
            tick: 1,
            sim_time: 0.1,
            cells: [7; MAX_MAP_SIDE * MAX_MAP_SIDE],
        };
        assert_eq!(map.check(), Ok(()));
        map.cells[1] = 200;
        assert!(map.check().is_err());
        map.cells[1] = 255;
        map.width = 0;
        assert!(map.check().is_err());

        let particles = SlamParticles {
            agent_id: 1,
            count: 1,
            tick: 1,
            sim_time: 0.1,
            xy: [[f32::INFINITY; 2]; MAX_SHOWN_PARTICLES],
        };
        assert!(particles.check().is_err());
        assert_eq!(
            SlamParticles {
                count: 0,
                ..particles
            }
            .check(),
            Ok(())
        );
    }

    #[test]
    fn a_reader_counts_what_it_rejects() {
        let rejected = Rejected::default();
        assert!(rejected.filter("tick", &HelperProgress { tick: 5 }));
        assert!(!rejected.filter("tick", &HelperProgress { tick: u64::MAX }));
        assert_eq!(rejected.count(), 1);
    }
}

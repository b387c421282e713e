//! One period of one robot, free of I/O: choose neighbours, sum forces, plan
//! a command with the robot's own model, let the body execute it.

use glam::DVec2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use shoal_physics::formation::{choose_neighbours, net_force};
use shoal_physics::planner::plan_command;
use shoal_physics::wander::{range_ahead, wander_command};
use shoal_physics::{Body, Command, MotionModel, Neighbour, Pose, StepOutcome};
use shoal_scenario::Behaviour;
use shoal_scenario::Scenario;

/// Metres of desired motion per unit of net force.
const STEP_PER_UNIT_FORCE: f64 = 0.1;

pub struct Robot {
    pub id: u32,
    pub body: Body,
    /// The model the robot believes it moves by: it plans and dead-reckons with it.
    pub belief: MotionModel,
    pub believed: Pose,
    /// Pure dead reckoning with the believed model, never corrected: the
    /// motion between two ticks, to carry a late SLAM estimate forward.
    pub odometry: Pose,
    rng: StdRng,
    /// The sensor draws its own noise, so sensing never changes how the body moves.
    sensor_rng: StdRng,
    /// The last scan and command, for a wandering robot.
    last_ranges: Vec<f64>,
    last_command: Command,
    steps: u64,
}

/// What the robot did in one period.
#[derive(Clone, Debug)]
pub struct Decision {
    pub tracked: Vec<Neighbour>,
    pub force: DVec2,
    pub command: Command,
    pub outcome: StepOutcome,
}

impl Robot {
    /// Robot `id` of a swarm seeded with `seed`; each robot draws its own noise.
    pub fn new(id: u32, start: Pose, scenario: &Scenario) -> Self {
        let seed = scenario
            .agents
            .seed
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(u64::from(id));
        Self {
            id,
            body: Body {
                pose: start,
                radius: scenario.agents.radius,
                model: scenario.motion.clone(),
                sim_time: 0.0,
            },
            belief: scenario.motion.clone(),
            believed: start,
            odometry: start,
            rng: StdRng::seed_from_u64(seed),
            sensor_rng: StdRng::seed_from_u64(seed ^ 0x5ca9),
            last_ranges: Vec::new(),
            last_command: Command::Stand,
            steps: 0,
        }
    }

    /// What the range sensor reads now, with `others` as the bodies around.
    pub fn scan(&mut self, scenario: &Scenario, others: &[DVec2]) -> Vec<f64> {
        let ranges = scenario.sensor.read(
            &scenario.arena,
            &self.body.pose,
            others,
            self.body.radius,
            &mut self.sensor_rng,
        );
        self.last_ranges.clone_from(&ranges);
        ranges
    }

    /// One control period against the robots it senses.
    pub fn step(&mut self, sensed: &[Neighbour], scenario: &Scenario) -> Decision {
        let me = self.body.pose.position();
        let tracked = choose_neighbours(me, sensed, &scenario.formation);
        let force = net_force(me, &tracked, &scenario.formation);
        let max_step = self.belief.full_stride();
        let displacement = if force == DVec2::ZERO {
            DVec2::ZERO
        } else {
            force.normalize() * (force.length() * STEP_PER_UNIT_FORCE).min(max_step)
        };
        let command = match scenario.agents.behaviour {
            Behaviour::Formation => plan_command(&self.body.pose, displacement, &self.belief),
            Behaviour::Wander => {
                let ahead = range_ahead(&self.last_ranges, &scenario.sensor);
                self.steps += 1;
                wander_command(self.steps, ahead, self.last_command)
            }
        };
        self.last_command = command;
        let nearby: Vec<DVec2> = sensed
            .iter()
            .map(|n| n.position)
            .filter(|p| p.distance(me) < 4.0 * self.body.radius + 0.5)
            .collect();
        let outcome = self
            .body
            .step(command, &scenario.arena, &nearby, &mut self.rng);
        let expected = self.belief.mean(command);
        self.believed = self
            .believed
            .advanced(expected.along, expected.across, expected.turn);
        self.odometry = self
            .odometry
            .advanced(expected.along, expected.across, expected.turn);
        Decision {
            tracked,
            force,
            command,
            outcome,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use shoal_physics::metrics::formation_metrics;

    /// Many robots stepping against each other's previous poses, as lockstep
    /// does, but in one process: the controller alone must form a lattice.
    #[test]
    fn a_dozen_robots_form_one_evenly_spaced_group() {
        let mut scenario = Scenario::default_arena();
        scenario.agents.count = 12;
        let starts = scenario.start_poses(0, 12);
        let mut robots: Vec<Robot> = starts
            .iter()
            .enumerate()
            .map(|(i, p)| Robot::new(i as u32, *p, &scenario))
            .collect();
        for _ in 0..600 {
            let poses: Vec<Neighbour> = robots
                .iter()
                .map(|r| Neighbour {
                    id: r.id,
                    position: r.body.pose.position(),
                })
                .collect();
            for robot in &mut robots {
                let others: Vec<Neighbour> = poses
                    .iter()
                    .filter(|n| {
                        n.id != robot.id && n.position.distance(robot.body.pose.position()) < 5.0
                    })
                    .copied()
                    .collect();
                robot.step(&others, &scenario);
            }
        }
        let positions: Vec<DVec2> = robots.iter().map(|r| r.body.pose.position()).collect();
        let metrics = formation_metrics(&positions, scenario.formation.spread);
        assert_eq!(metrics.components, 1, "{metrics:?}");
        assert!((metrics.spacing_ratio - 1.0).abs() < 0.15, "{metrics:?}");
    }
}

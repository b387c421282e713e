use glam::DVec2;
use rand::Rng;

use crate::arena::Arena;
use crate::legged::{Command, MotionModel, MotionSample};
use crate::pose::Pose;

/// The simulated body of one robot: its true pose and true motion
/// distributions. This is the only part a real robot would replace.
#[derive(Clone, Debug)]
pub struct Body {
    pub pose: Pose,
    pub radius: f64,
    pub model: MotionModel,
    /// Seconds into the run: surfaces may appear part-way.
    pub sim_time: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepOutcome {
    /// What the command did on this floor, before any contact.
    pub motion: MotionSample,
    /// A wall, an obstacle or another robot stopped the translation.
    pub bumped: bool,
}

impl Body {
    /// Executes `command`: draws the motion from the true distributions,
    /// applies the surface underfoot, and refuses translations into walls,
    /// obstacles or robots at `others` (the turn still happens).
    pub fn step(
        &mut self,
        command: Command,
        arena: &Arena,
        others: &[DVec2],
        rng: &mut impl Rng,
    ) -> StepOutcome {
        let mut motion = self.model.sample(command, rng);
        if let Some(surface) = arena.surface_at_time(self.pose.position(), self.sim_time) {
            motion = surface.apply(motion);
        }
        let candidate = self.pose.advanced(motion.along, motion.across, motion.turn);
        let from = self.pose.position();
        let to = candidate.position();
        let midpoint = (from + to) / 2.0;
        let contact = 2.0 * self.radius;
        // Moving apart is always allowed, so robots that start overlapping can separate.
        let hits_robot = others
            .iter()
            .any(|o| o.distance(to) < contact && o.distance(to) < o.distance(from));
        let bumped =
            arena.blocks(to, self.radius) || arena.blocks(midpoint, self.radius) || hits_robot;
        self.pose = if bumped {
            Pose {
                theta: candidate.theta,
                ..self.pose
            }
        } else {
            candidate
        };
        StepOutcome { motion, bumped }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn open_floor() -> Arena {
        Arena {
            width: 10.0,
            height: 10.0,
            walls: vec![],
            obstacles: vec![],
            surfaces: vec![],
        }
    }

    #[test]
    fn a_body_walks_along_its_heading() {
        let mut body = Body {
            pose: Pose::new(5.0, 5.0, 0.0),
            radius: 0.15,
            model: MotionModel::legged_default(),
            sim_time: 0.0,
        };
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let outcome = body.step(Command::Walk(2), &open_floor(), &[], &mut rng);
        assert!(!outcome.bumped);
        assert!(body.pose.x > 5.05 && (body.pose.y - 5.0).abs() < 0.05);
    }

    #[test]
    fn walls_and_robots_stop_translation_but_not_turning() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(2);
        let mut body = Body {
            pose: Pose::new(9.8, 5.0, 0.0),
            radius: 0.15,
            model: MotionModel::legged_default(),
            sim_time: 0.0,
        };
        assert!(
            body.step(Command::Walk(3), &open_floor(), &[], &mut rng)
                .bumped
        );
        assert!((body.pose.x - 9.8).abs() < 1e-12);

        let mut body = Body {
            pose: Pose::new(5.0, 5.0, 0.0),
            radius: 0.15,
            model: MotionModel::legged_default(),
            sim_time: 0.0,
        };
        let other = [DVec2::new(5.35, 5.0)];
        assert!(
            body.step(Command::Walk(2), &open_floor(), &other, &mut rng)
                .bumped
        );
        assert!((body.pose.x - 5.0).abs() < 1e-12);
    }
}

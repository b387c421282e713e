//! Turns a desired motion into the next discrete command, using the robot's
//! own (believed, possibly learned) motion model.

use glam::DVec2;

use crate::legged::{Command, MotionModel};
use crate::pose::Pose;

/// A two-step plan costs this much more than reaching the target in one step,
/// so the planner prefers commands that make progress now.
const SECOND_STEP_PENALTY_M: f64 = 0.02;

/// Picks the command whose expected outcome, possibly followed by one more
/// translation, lands closest to `pose + displacement`.
pub fn plan_command(pose: &Pose, displacement: DVec2, model: &MotionModel) -> Command {
    if displacement.length() < 1e-9 {
        return Command::Stand;
    }
    let target = pose.position() + displacement;
    let after = |from: &Pose, command: Command| {
        let step = model.mean(command);
        from.advanced(step.along, step.across, step.turn)
    };
    let translations: Vec<Command> = Command::ALL
        .iter()
        .copied()
        .filter(|c| matches!(c, Command::Walk(_) | Command::Strafe(_)))
        .collect();
    let mut best = (pose.position().distance(target), Command::Stand);
    for first in Command::ALL {
        let one_step = after(pose, first);
        let mut cost = one_step.position().distance(target);
        for &second in &translations {
            let two_steps = after(&one_step, second);
            cost = cost.min(two_steps.position().distance(target) + SECOND_STEP_PENALTY_M);
        }
        if cost < best.0 - 1e-9 {
            best = (cost, first);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn walks_forward_towards_a_target_ahead() {
        let model = MotionModel::legged_default();
        let command = plan_command(&Pose::new(0.0, 0.0, 0.0), DVec2::new(0.15, 0.0), &model);
        assert_eq!(command, Command::Walk(2));
    }

    #[test]
    fn turns_towards_a_target_behind() {
        let model = MotionModel::legged_default();
        let command = plan_command(&Pose::new(0.0, 0.0, 0.0), DVec2::new(-0.2, 0.0), &model);
        assert!(
            matches!(command, Command::Turn(3) | Command::Turn(-3)),
            "{command}"
        );
    }

    #[test]
    fn stands_when_there_is_nowhere_to_go() {
        let model = MotionModel::legged_default();
        assert_eq!(
            plan_command(&Pose::default(), DVec2::ZERO, &model),
            Command::Stand
        );
        assert_eq!(
            plan_command(&Pose::default(), DVec2::new(0.005, 0.0), &model),
            Command::Stand
        );
    }
}

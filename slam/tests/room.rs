//! The filter following a simulated robot in a small room, in one process.

use rand::SeedableRng;
use shoal_physics::range::RangeSensor;
use shoal_physics::{Arena, Body, Command, MotionModel, Pose};
use shoal_scenario::Scenario;
use shoal_slam::filter::{FilterConfig, ParticleFilter};

fn room() -> Arena {
    Scenario::room().arena
}

/// Drives the body around the room for `steps` steps and returns the
/// filter's position errors, metres.
fn follow(
    true_model: &MotionModel,
    filter_model: MotionModel,
    learning: bool,
    steps: usize,
) -> Vec<f64> {
    follow_changing(true_model, None, filter_model, learning, steps)
}

/// As [`follow`], the body's true model becoming `later` half-way if given.
fn follow_changing(
    true_model: &MotionModel,
    later: Option<&MotionModel>,
    filter_model: MotionModel,
    learning: bool,
    steps: usize,
) -> Vec<f64> {
    let arena = room();
    let sensor = RangeSensor::default();
    let start = Pose::new(1.5, 0.6, std::f64::consts::FRAC_PI_2);
    let mut body = Body {
        pose: start,
        radius: 0.15,
        model: true_model.clone(),
        sim_time: 0.0,
    };
    let config = FilterConfig {
        learning,
        sensor: sensor.clone(),
        ..FilterConfig::default()
    };
    let mut filter =
        ParticleFilter::new(start, filter_model, config, arena.width, arena.height, 11);
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    filter.observe_start(&sensor.read(&arena, &body.pose, &[], 0.15, &mut rng));
    let mut errors = Vec::new();
    let mut command = Command::Stand;
    for step in 0..steps {
        if step == steps / 2
            && let Some(later) = later
        {
            body.model = later.clone();
        }
        let ahead = sensor.cast_exact(&arena, &body.pose, &[], 0.15)[sensor.beams / 2];
        command = if ahead < 0.7 || (matches!(command, Command::Turn(_)) && ahead < 1.2) {
            Command::Turn(2)
        } else if step % 9 == 0 {
            Command::Turn(-1)
        } else {
            Command::Walk(2)
        };
        let outcome = body.step(command, &arena, &[], &mut rng);

        let ranges = sensor.read(&arena, &body.pose, &[], 0.15, &mut rng);
        let report = filter.step(command, outcome.bumped, &ranges);
        errors.push(report.estimate.position().distance(body.pose.position()));
    }
    errors
}

#[test]
fn with_a_correct_model_and_learning_the_filter_tracks_the_robot() {
    let model = MotionModel::legged_default();
    let errors = follow(&model, model.clone(), true, 300);
    let worst = errors.iter().copied().fold(0.0, f64::max);
    let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    eprintln!("300 steps: worst {worst:.3} m, rmse {rmse:.3} m");
    // Measured 0.08-0.10 m worst, 0.04-0.05 m rmse over the likelihoods
    // this filter has had; losing the robot costs metres.
    assert!(worst < 0.12, "worst {worst:.3} m, rmse {rmse:.3} m");
}

fn rmse(errors: &[f64]) -> f64 {
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt()
}

#[test]
fn learning_corrects_a_model_whose_turns_are_twice_too_large() {
    let truth = MotionModel::legged_default();
    let mut wrong = truth.clone();
    for command in Command::ALL {
        if matches!(command, Command::Turn(_)) {
            let model = wrong.command_mut(command);
            model.t = model.t.scaled(2.0);
        }
    }
    let learning = follow(&truth, wrong.clone(), true, 300);
    let fixed = follow(&truth, wrong, false, 300);
    let (late_learning, late_fixed) = (rmse(&learning[150..]), rmse(&fixed[150..]));
    eprintln!("last 150 steps: rmse {late_learning:.3} m learning, {late_fixed:.3} m not learning");
    assert!(
        late_learning < 0.10 && late_fixed > 0.10,
        "last 150 steps: rmse {late_learning:.3} m learning, {late_fixed:.3} m not learning"
    );
}

#[test]
fn a_surface_change_part_way_is_tracked_by_learning() {
    let before = MotionModel::legged_default();
    // A slippery floor: every stride carries 40% less far from step 150 on.
    let after = before.scaled(0.6, 1.0, 1.0);
    let learning = follow_changing(&before, Some(&after), before.clone(), true, 300);
    let fixed = follow_changing(&before, Some(&after), before.clone(), false, 300);
    let (late_learning, late_fixed) = (rmse(&learning[200..]), rmse(&fixed[200..]));
    eprintln!(
        "after the change: rmse {late_learning:.3} m learning, {late_fixed:.3} m not learning"
    );
    assert!(
        late_learning < 0.10,
        "after the change: rmse {late_learning:.3} m learning, {late_fixed:.3} m not learning"
    );
}

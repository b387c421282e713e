//! One robot alone on a map SLAM never saw, with a wrong model: an
//! L-shaped 6 x 5 m room, strides 25% longer and turns 30% larger than the
//! model the filter starts from, two minutes at 5 Hz. In one process, so
//! each seed takes seconds.

use rand::SeedableRng;
use shoal_physics::range::RangeSensor;
use shoal_physics::wander::{range_ahead, wander_command};
use shoal_physics::{Arena, Body, Command, MotionModel, Pose, Wall};
use shoal_slam::filter::{FilterConfig, ParticleFilter, Proposal};

/// A 6 x 5 m room whose north-east quarter (3 x 2.5 m) is walled off.
fn l_shaped_room() -> Arena {
    Arena {
        width: 6.0,
        height: 5.0,
        walls: vec![
            Wall {
                from: [3.0, 2.5],
                to: [6.0, 2.5],
            },
            Wall {
                from: [3.0, 2.5],
                to: [3.0, 5.0],
            },
        ],
        obstacles: vec![],
        surfaces: vec![],
    }
}

/// Absolute position error of each step (what `evo_ape` reports without
/// alignment), and the stride and turn the filter learned.
struct Run {
    errors: Vec<f64>,
    learned: MotionModel,
}

/// The robot's true model: strides 25% longer and turns 30% larger than
/// the legged default the filter starts from.
fn true_model() -> MotionModel {
    MotionModel::legged_default().scaled(1.25, 1.25, 1.3)
}

fn wander(proposal: Proposal, particles: usize, seed: u64, steps: usize) -> Run {
    let config = FilterConfig {
        particles,
        proposal,
        ..FilterConfig::default()
    };
    wander_from(MotionModel::legged_default(), config, seed, steps)
}

/// [`wander`] with the filter started from `model` and set up as `config`
/// (its sensor: the room's).
fn wander_from(model: MotionModel, config: FilterConfig, seed: u64, steps: usize) -> Run {
    let arena = l_shaped_room();
    let sensor = RangeSensor::default();
    let start = Pose::new(1.0, 1.0, 0.3);
    let mut body = Body {
        pose: start,
        radius: 0.15,
        model: true_model(),
        sim_time: 0.0,
    };
    let config = FilterConfig {
        sensor: sensor.clone(),
        ..config
    };
    let mut filter = ParticleFilter::new(start, model, config, arena.width, arena.height, seed);
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 100);
    let mut ranges = sensor.read(&arena, &body.pose, &[], 0.15, &mut rng);
    filter.observe_start(&ranges);
    let mut command = Command::Stand;
    let mut errors = Vec::new();
    for step in 0..steps {
        command = wander_command(step as u64 + 1, range_ahead(&ranges, &sensor), command);
        let outcome = body.step(command, &arena, &[], &mut rng);
        ranges = sensor.read(&arena, &body.pose, &[], 0.15, &mut rng);
        let report = filter.step(command, outcome.bumped, &ranges);
        errors.push(report.estimate.position().distance(body.pose.position()));
    }
    Run {
        errors,
        learned: filter.model().clone(),
    }
}

fn rmse(errors: &[f64]) -> f64 {
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt()
}

/// Prints `run` as EXPERIMENTS.md reports it; returns the position RMSE
/// over the last 24 s.
fn report(label: &str, run: &Run) -> f64 {
    let truth = true_model();
    let (all, late) = (
        rmse(&run.errors),
        rmse(&run.errors[run.errors.len() * 4 / 5..]),
    );
    let (walk, turn) = (Command::Walk(2), Command::Turn(2));
    eprintln!(
        "{label}: position rmse {all:.3} m over the run, {late:.3} m over its last fifth; walk(2) stride {:.3} m learned, {:.3} m true; turn(2) {:.3} rad learned, {:.3} rad true",
        run.learned.mean(walk).along,
        truth.mean(walk).along,
        run.learned.mean(turn).turn,
        truth.mean(turn).turn,
    );
    late
}

#[test]
fn a_lone_robot_with_a_wrong_model_is_held_on_a_room_slam_never_saw() {
    let defaults = FilterConfig::default();
    for seed in 0..3 {
        let late = report(
            &format!("seed {seed}"),
            &wander(defaults.proposal, defaults.particles, seed, 600),
        );
        // With the defaults (the scan-matched proposal, 50 particles)
        // measured 0.063, 0.059, 0.038 m (0.043, 0.047, 0.036 m over the
        // whole run); 0.118, 0.092, 0.059 m while beams grazing a wall
        // still erased it (grid::FREE_STOP_M); 0.26 m before a beam ending
        // in unmapped space stopped scoring as half a hit.
        assert!(
            late < 0.1,
            "seed {seed}: last 24 s: position rmse {late:.3} m"
        );
    }
}

/// The two proposals side by side (EXPERIMENTS.md, "SLAM"): `cargo test
/// --release -p shoal-slam --test unseen -- --ignored --nocapture`.
#[test]
#[ignore = "an experiment: a minute of filtering"]
fn the_scan_matched_proposal_against_the_motion_models() {
    for seed in 0..3 {
        for (proposal, particles) in [
            (Proposal::Motion, 500),
            (Proposal::Motion, 100),
            (Proposal::ScanMatched, 100),
            (Proposal::ScanMatched, 50),
            (Proposal::ScanMatched, 30),
        ] {
            let started = std::time::Instant::now();
            let run = wander(proposal, particles, seed, 600);
            let label = format!(
                "seed {seed}, {proposal:?}, {particles} particles, {:.1} s",
                started.elapsed().as_secs_f64()
            );
            report(&label, &run);
        }
    }
}

/// EXPERIMENTS.md 8b's six-seed figures: the default filter (50 scan-matched
/// particles) against 500 drawn from the model, learning against the
/// model held fixed, from the wrong model and from the true one, and the
/// default on cells half as wide (`shoal-slam --grid 0.025`): `cargo
/// test --release -p shoal-slam --test unseen -- --ignored --nocapture
/// six_seeds`.
#[test]
#[ignore = "an experiment: two minutes of filtering"]
fn six_seeds_of_each_filter_learning_and_fixed() {
    let defaults = FilterConfig::default();
    let runs = [
        (
            "default, learning, wrong model",
            defaults.clone(),
            MotionModel::legged_default(),
        ),
        (
            "default, fixed, wrong model",
            FilterConfig {
                learning: false,
                ..defaults.clone()
            },
            MotionModel::legged_default(),
        ),
        (
            "default, learning, true model",
            defaults.clone(),
            true_model(),
        ),
        (
            "default, fixed, true model",
            FilterConfig {
                learning: false,
                ..defaults.clone()
            },
            true_model(),
        ),
        (
            "default on 2.5 cm cells, learning, wrong model",
            FilterConfig {
                cell_size: 0.025,
                ..defaults.clone()
            },
            MotionModel::legged_default(),
        ),
        (
            "default on 2.5 cm cells, fixed, true model",
            FilterConfig {
                cell_size: 0.025,
                learning: false,
                ..defaults.clone()
            },
            true_model(),
        ),
        (
            "500 drawn from the model, learning, wrong model",
            FilterConfig {
                particles: 500,
                proposal: Proposal::Motion,
                ..defaults
            },
            MotionModel::legged_default(),
        ),
    ];
    for (label, config, model) in runs {
        let rmses: Vec<f64> = (0..6)
            .map(|seed| rmse(&wander_from(model.clone(), config.clone(), seed, 600).errors))
            .collect();
        eprintln!(
            "{label}: position rmse over 2 minutes, seeds 0-5: mean {:.3} m, worst {:.3} m, each {:.3?}",
            rmses.iter().sum::<f64>() / rmses.len() as f64,
            rmses.iter().copied().fold(0.0, f64::max),
            rmses
        );
    }
}

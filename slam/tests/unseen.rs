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

fn wander(proposal: Proposal, particles: usize, seed: u64, steps: usize) -> Run {
    let arena = l_shaped_room();
    let sensor = RangeSensor::default();
    let start = Pose::new(1.0, 1.0, 0.3);
    let model = MotionModel::legged_default();
    let truth = model.scaled(1.25, 1.25, 1.3);
    let mut body = Body {
        pose: start,
        radius: 0.15,
        model: truth,
        sim_time: 0.0,
    };
    let config = FilterConfig {
        particles,
        proposal,
        sensor: sensor.clone(),
        ..FilterConfig::default()
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
    let truth = MotionModel::legged_default().scaled(1.25, 1.25, 1.3);
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
        // measured 0.06-0.09 m; 0.09-0.12 m with 500 particles drawn from
        // the motion model; 0.26 m before a beam ending in unmapped space
        // stopped scoring as half a hit (grid::occupancy_within).
        assert!(
            late < 0.15,
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

//! SLAM's cost: steps and particle-beam evaluations per second for a robot
//! walking a room, by particle count, against 100 particles as the baseline.

use std::time::Instant;

use anyhow::Result;
use rand::SeedableRng;
use serde::Serialize;
use shoal_physics::range::RangeSensor;
use shoal_physics::{Arena, Body, Command, MotionModel, Obstacle, Pose};
use shoal_slam::filter::{FilterConfig, ParticleFilter};

#[derive(Debug, Serialize)]
struct Row {
    particles: usize,
    beams: usize,
    scored_beams_per_step: usize,
    steps_per_s: f64,
    particle_beam_evals_per_s: f64,
    /// Steps per second over the 10 steps per second of a robot at 10 Hz.
    realtime_factor_10hz: f64,
    /// Time per step against 100 particles' (the baseline).
    step_time_vs_100: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    rows: Vec<Row>,
}

fn room() -> Arena {
    Arena {
        width: 6.0,
        height: 5.0,
        walls: vec![],
        obstacles: vec![Obstacle::Box {
            min: [3.5, 2.0],
            max: [4.2, 2.6],
        }],
        surfaces: vec![],
    }
}

/// Seconds per step of a filter with `particles` following a wandering robot.
fn seconds_per_step(particles: usize, steps: usize) -> (f64, usize) {
    let arena = room();
    let sensor = RangeSensor {
        beams: 180,
        ..RangeSensor::default()
    };
    let model = MotionModel::legged_default();
    let start = Pose::new(1.5, 1.5, 0.3);
    let mut body = Body {
        pose: start,
        radius: 0.15,
        model: model.clone(),
        sim_time: 0.0,
    };
    let config = FilterConfig {
        particles,
        sensor: sensor.clone(),
        ..FilterConfig::default()
    };
    let scored = sensor.beams.div_ceil(config.score_stride.max(1));
    let mut filter = ParticleFilter::new(start, model, config, arena.width, arena.height, 3);
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    filter.observe_start(&sensor.read(&arena, &body.pose, &[], 0.15, &mut rng));
    let mut elapsed = 0.0;
    for step in 0..steps {
        let ahead = sensor.cast_exact(&arena, &body.pose, &[], 0.15)[sensor.beams / 2];
        let command = if ahead < 0.8 {
            Command::Turn(2)
        } else if step % 7 == 0 {
            Command::Turn(-1)
        } else {
            Command::Walk(2)
        };
        let outcome = body.step(command, &arena, &[], &mut rng);
        let ranges = sensor.read(&arena, &body.pose, &[], 0.15, &mut rng);
        let started = Instant::now();
        filter.step(command, outcome.bumped, &ranges);
        elapsed += started.elapsed().as_secs_f64();
    }
    (elapsed / steps as f64, scored)
}

pub fn run(particles: &[usize], steps: usize, json: bool) -> Result<()> {
    let (baseline, _) = seconds_per_step(100, steps);
    let mut rows = Vec::new();
    for &n in particles {
        let (per_step, scored) = seconds_per_step(n, steps);
        rows.push(Row {
            particles: n,
            beams: 180,
            scored_beams_per_step: scored,
            steps_per_s: 1.0 / per_step,
            particle_beam_evals_per_s: (n * scored) as f64 / per_step,
            realtime_factor_10hz: 1.0 / per_step / 10.0,
            step_time_vs_100: per_step / baseline,
        });
    }
    shoal::report::print(&Report { rows }, json)
}

//! SLAM's cost: steps and particle-beam evaluations per second for a robot
//! walking the SLAM tests' room, by particle count and by threads (one, and
//! every core), against 100 particles on one thread as the baseline.

use std::time::Instant;

use anyhow::Result;
use rand::SeedableRng;
use serde::Serialize;
use shoal_physics::range::RangeSensor;
use shoal_physics::wander::{range_ahead, wander_command};
use shoal_physics::{Body, Command, MotionModel, Pose, Scenario};
use shoal_slam::filter::{FilterConfig, ParticleFilter};

#[derive(Debug, Serialize)]
struct Row {
    particles: usize,
    threads: usize,
    beams: usize,
    scored_beams_per_step: usize,
    steps_per_s: f64,
    particle_beam_evals_per_s: f64,
    particle_beam_evals_per_s_per_thread: f64,
    /// Steps per second over the 10 steps per second of a robot at 10 Hz.
    realtime_factor_10hz: f64,
    /// Steps per second over what following the demo's 20 robots at 5 Hz
    /// takes (100 steps per second), with this many particles each.
    realtime_factor_20_robots_5hz: f64,
    /// Time per step against 100 particles' on one thread (the baseline).
    step_time_vs_100_one_thread: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    rows: Vec<Row>,
}

/// Seconds per step of a filter with `particles` following a wandering robot.
fn seconds_per_step(particles: usize, steps: usize) -> (f64, usize) {
    let arena = Scenario::room().arena;
    let sensor = RangeSensor {
        beams: 180,
        ..RangeSensor::default()
    };
    let model = MotionModel::legged_default();
    let start = Pose::new(1.5, 0.6, std::f64::consts::FRAC_PI_2);
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
    let mut ranges = sensor.read(&arena, &body.pose, &[], 0.15, &mut rng);
    filter.observe_start(&ranges);
    let mut command = Command::Stand;
    let mut elapsed = 0.0;
    for step in 0..steps {
        command = wander_command(step as u64 + 1, range_ahead(&ranges, &sensor), command);
        let outcome = body.step(command, &arena, &[], &mut rng);
        ranges = sensor.read(&arena, &body.pose, &[], 0.15, &mut rng);
        let started = Instant::now();
        filter.step(command, outcome.bumped, &ranges);
        elapsed += started.elapsed().as_secs_f64();
    }
    (elapsed / steps as f64, scored)
}

/// [`seconds_per_step`] with the filter's particles shared over `threads`.
fn seconds_per_step_on(threads: usize, particles: usize, steps: usize) -> Result<(f64, usize)> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    Ok(pool.install(|| seconds_per_step(particles, steps)))
}

pub fn run(particles: &[usize], steps: usize, json: bool) -> Result<()> {
    let (baseline, _) = seconds_per_step_on(1, 100, steps)?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut rows = Vec::new();
    for &n in particles {
        for threads in [1, cores] {
            let (per_step, scored) = seconds_per_step_on(threads, n, steps)?;
            let evals = (n * scored) as f64 / per_step;
            rows.push(Row {
                particles: n,
                threads,
                beams: 180,
                scored_beams_per_step: scored,
                steps_per_s: 1.0 / per_step,
                particle_beam_evals_per_s: evals,
                particle_beam_evals_per_s_per_thread: evals / threads as f64,
                realtime_factor_10hz: 1.0 / per_step / 10.0,
                realtime_factor_20_robots_5hz: 1.0 / per_step / 100.0,
                step_time_vs_100_one_thread: per_step / baseline,
            });
            if cores == 1 {
                break;
            }
        }
    }
    shoal::report::print(&Report { rows }, json)
}

//! SLAM's cost: steps and particle-beam evaluations per second for a robot
//! walking the SLAM tests' room (or a scenario's arena), by proposal (the motion model's, and the
//! scan-matched one), particle count and threads (one, and every core),
//! against the motion model's proposal with 100 particles on one thread as
//! the baseline.

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use rand::SeedableRng;
use serde::Serialize;
use shoal_physics::range::RangeSensor;
use shoal_physics::wander::{range_ahead, wander_command};
use shoal_physics::{Body, Command, MotionModel, Pose};
use shoal_scenario::Scenario;
use shoal_slam::filter::{FilterConfig, ParticleFilter, Proposal, cell_for};

#[derive(Debug, Serialize)]
struct Row {
    proposal: String,
    particles: usize,
    threads: usize,
    beams: usize,
    /// The map's cell, metres: what the filter chooses for this sensor and
    /// arena (`filter::cell_for`).
    cell_m: f64,
    /// Scored beams per pose, on average (every second beam that returned).
    scored_beams: f64,
    /// Poses scored per particle and step, on average: the learner's draws
    /// (at least 250 a step over all particles, one per particle beyond
    /// that), and for the scan-matched proposal the matcher's search (on
    /// half the beams) and the proposal's probes.
    poses_scored_per_particle: f64,
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

/// Where the robot walks and what it senses.
struct World {
    arena: shoal_physics::arena::Arena,
    sensor: RangeSensor,
    start: Pose,
    /// The map's cell, if not the filter's own choice.
    grid: Option<f64>,
}

impl World {
    /// The SLAM tests' room with a sensor of 180 beams, or `scenario`'s
    /// arena and sensor from the middle of its start region.
    fn new(scenario: Option<&Path>, grid: Option<f64>) -> Result<Self> {
        Ok(match scenario {
            None => Self {
                arena: Scenario::room().arena,
                sensor: RangeSensor {
                    beams: 180,
                    ..RangeSensor::default()
                },
                start: Pose::new(1.5, 0.6, std::f64::consts::FRAC_PI_2),
                grid,
            },
            Some(path) => {
                let scenario = shoal_runtime::read_scenario(path)?;
                let [x0, y0, x1, y1] = scenario.agents.start_region;
                Self {
                    arena: scenario.arena,
                    sensor: scenario.sensor,
                    start: Pose::new((x0 + x1) / 2.0, (y0 + y1) / 2.0, 0.0),
                    grid,
                }
            }
        })
    }

    /// The cell the filter maps with.
    fn cell_m(&self) -> f64 {
        self.grid
            .unwrap_or_else(|| cell_for(&self.sensor, self.arena.width, self.arena.height))
    }
}

/// What following a wandering robot cost per step.
struct Cost {
    seconds: f64,
    /// Particle-beam evaluations (poses scored times beams each).
    evaluations: f64,
    poses_per_particle: f64,
    scored_beams: f64,
}

/// [`Cost`] of a filter with `particles` and `proposal` following a
/// wandering robot for `steps` steps.
fn cost_per_step(world: &World, proposal: Proposal, particles: usize, steps: usize) -> Cost {
    let World {
        arena,
        sensor,
        start,
        grid,
    } = world;
    let (sensor, start) = (sensor.clone(), *start);
    let model = MotionModel::legged_default();
    let mut body = Body {
        pose: start,
        radius: 0.15,
        model: model.clone(),
        sim_time: 0.0,
    };
    let config = FilterConfig {
        particles,
        proposal,
        sensor: sensor.clone(),
        cell_size: *grid,
        ..FilterConfig::default()
    };
    let mut filter = ParticleFilter::new(start, model, config, arena.width, arena.height, 3);
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    let mut ranges = sensor.read(arena, &body.pose, &[], 0.15, &mut rng);
    filter.observe_start(&ranges);
    let mut command = Command::Stand;
    let (mut elapsed, mut evaluations, mut poses, mut scored) = (0.0, 0.0, 0.0, 0.0);
    for step in 0..steps {
        command = wander_command(step as u64 + 1, range_ahead(&ranges, &sensor), command);
        let outcome = body.step(command, arena, &[], &mut rng);
        ranges = sensor.read(arena, &body.pose, &[], 0.15, &mut rng);
        let started = Instant::now();
        let report = filter.step(command, outcome.bumped, &ranges);
        elapsed += started.elapsed().as_secs_f64();
        evaluations += report.beam_evaluations as f64;
        poses += report.poses_scored as f64 / particles as f64;
        scored += report.scored_beams as f64;
    }
    let steps = steps.max(1) as f64;
    Cost {
        seconds: elapsed / steps,
        evaluations: evaluations / steps,
        poses_per_particle: poses / steps,
        scored_beams: scored / steps,
    }
}

/// [`cost_per_step`] with the filter's particles shared over `threads`.
fn cost_on(
    world: &World,
    threads: usize,
    (proposal, particles): (Proposal, usize),
    steps: usize,
) -> Result<Cost> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    Ok(pool.install(|| cost_per_step(world, proposal, particles, steps)))
}

/// A proposal as the command line names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ProposalArg {
    Motion,
    Matched,
}

pub fn run(
    particles: &[usize],
    steps: usize,
    (scenario, proposals, grid): (Option<&Path>, &[ProposalArg], Option<f64>),
    json: bool,
) -> Result<()> {
    let world = World::new(scenario, grid)?;
    let baseline = cost_on(&world, 1, (Proposal::Motion, 100), steps)?.seconds;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut rows = Vec::new();
    for proposal in proposals.iter().map(|p| match p {
        ProposalArg::Motion => Proposal::Motion,
        ProposalArg::Matched => Proposal::ScanMatched,
    }) {
        for &n in particles {
            for threads in [1, cores] {
                let cost = cost_on(&world, threads, (proposal, n), steps)?;
                let evals = cost.evaluations / cost.seconds;
                rows.push(Row {
                    proposal: format!("{proposal:?}"),
                    particles: n,
                    threads,
                    beams: world.sensor.beams,
                    cell_m: world.cell_m(),
                    scored_beams: cost.scored_beams,
                    poses_scored_per_particle: cost.poses_per_particle,
                    steps_per_s: 1.0 / cost.seconds,
                    particle_beam_evals_per_s: evals,
                    particle_beam_evals_per_s_per_thread: evals / threads as f64,
                    realtime_factor_10hz: 1.0 / cost.seconds / 10.0,
                    realtime_factor_20_robots_5hz: 1.0 / cost.seconds / 100.0,
                    step_time_vs_100_one_thread: cost.seconds / baseline,
                });
                if cores == 1 {
                    break;
                }
            }
        }
    }
    shoal_runtime::report::print(&Report { rows }, json)
}

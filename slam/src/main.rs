//! `shoal-slam`: follows robots' sensor streams on the bus, runs particle-filter
//! SLAM for each, learns each robot's motion model online and publishes pose
//! estimates and model updates back to the robots.

mod view;

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Parser;
use shoal_broker::robot_streams::{self, StreamPublisher, StreamSubscriber};
use shoal_broker::{
    Bus, BusLimits, EstimateSample, FollowedReport, HelperProgress, ModelUpdate, RosterReader,
    ScanSample, SlamReport, SwarmRuntime, names,
};
use shoal_physics::legged::Param;
use shoal_physics::{Command, MotionModel, Pose, Scenario};
use shoal_slam::filter::{Bodies, FilterConfig, ParticleFilter, mask_bodies};

#[derive(Parser)]
#[command(
    version,
    about = "Particle-filter SLAM that learns each followed robot's motion model online"
)]
struct Args {
    #[arg(long, default_value = "default")]
    swarm: String,
    /// Ids of the robots to follow, e.g. 0,3.
    #[arg(long, value_delimiter = ',', required = true)]
    follow: Vec<u32>,
    #[arg(long, default_value_t = 500)]
    particles: usize,
    /// The learning window k (5..=10).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u64).range(5..=10))]
    window: u64,
    #[arg(long, value_enum, default_value_t = Learning::On)]
    learning: Learning,
    /// The model to start from (TOML, per command: d, c, t mixtures); default: the swarm's.
    #[arg(long)]
    initial_model: Option<PathBuf>,
    /// Occupancy grid cell size, metres.
    #[arg(long, default_value_t = 0.05)]
    grid: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Learning {
    On,
    Off,
}

/// Reads a motion model file; errors name the file and line.
fn read_model(path: &PathBuf) -> Result<MotionModel> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(MotionModel::from_toml(&text, &path.display().to_string())?)
}

struct Followed {
    scans: StreamSubscriber<ScanSample>,
    estimates: StreamPublisher<EstimateSample>,
    models: StreamPublisher<ModelUpdate>,
    filter: Option<ParticleFilter>,
    /// Scans that came before their tick's pose, while the filter waits to start.
    waiting: Vec<ScanSample>,
    steps: u64,
    last_scan: Option<std::time::Instant>,
}

const MIN_GRID_M: f64 = 0.01;
/// Ticks of true poses kept per followed robot, to start its filter from.
const ANCHOR_TICKS: usize = 64;
/// Scans kept while a filter waits for the pose of their tick.
const WAITING_SCANS: usize = 16;
const MAX_GRID_M: f64 = 1.0;

fn run(args: Args) -> Result<()> {
    // A bad model file is reported before anything else, swarm or not.
    let from_file = args.initial_model.as_ref().map(read_model).transpose()?;
    let runtime = SwarmRuntime::locate(&args.swarm);
    runtime.read_meta()?;
    let scenario = Scenario::from_file(&runtime.scenario_path())?;
    let initial = from_file.unwrap_or_else(|| scenario.motion.clone());
    // The map has (arena / grid)^2 cells per particle: a cell far below a
    // centimetre would ask for more memory than any machine has.
    if !(MIN_GRID_M..=MAX_GRID_M).contains(&args.grid) {
        bail!(
            "--grid {} is outside [{MIN_GRID_M}, {MAX_GRID_M}] metres per cell",
            args.grid
        );
    }
    let bus = Bus::join(
        &args.swarm,
        &names::tool_node(&args.swarm, &format!("slam-{}", std::process::id())),
        BusLimits::default(),
    )?;
    let roster = RosterReader::new(&bus)?;
    let particles_out = robot_streams::slam_particles_publisher(&bus)?;
    let maps_out = robot_streams::slam_map_publisher(&bus)?;
    let progress = robot_streams::progress_publisher(&bus, "slam")?;
    let mut newest_roster: u64 = 0;
    // The newest tick each followed robot announced on the roster: it
    // publishes its scan before its pose, so once the pose is read and the
    // scans after it processed, that tick is done.
    let mut seen_ticks: BTreeMap<u32, u64> = BTreeMap::new();
    let mut followed: BTreeMap<u32, Followed> = BTreeMap::new();
    for &id in &args.follow {
        followed.insert(
            id,
            Followed {
                scans: robot_streams::scan_subscriber(&bus, id)?,
                estimates: robot_streams::estimate_publisher(&bus, id)?,
                models: robot_streams::model_publisher(&bus, id)?,
                filter: None,
                waiting: Vec::new(),
                steps: 0,
                last_scan: None,
            },
        );
    }
    let config = FilterConfig {
        particles: args.particles.max(1),
        cell_size: args.grid,
        learning: args.learning == Learning::On,
        window: args.window as usize,
        sensor: scenario.sensor.clone(),
        ..FilterConfig::default()
    };
    tracing::info!(follow = ?args.follow, learning = ?args.learning, "SLAM following");
    // Each followed robot's recent true poses by tick, to start its filter at.
    let mut anchors: BTreeMap<u32, BTreeMap<u64, Pose>> = BTreeMap::new();
    let mut last_report = std::time::Instant::now();
    // Where every robot stands, and at which tick, to drop beams that ended
    // on one: robots move, so they do not belong in the map. A robot silent
    // for longer than the swarm's staleness is gone, and so is its body.
    let mut bodies = Bodies::new((scenario.timing.stale_periods.ceil() as u64).max(1) + 1);
    while !bus.termination_requested() {
        // A filter starts at the robot's pose when following begins, so its
        // estimates and the robot's true pose share one frame.
        // The roster passes only samples that pass their wire check.
        roster.receive(|s| {
            newest_roster = newest_roster.max(s.tick);
            if followed.contains_key(&s.agent_id) {
                let seen = seen_ticks.entry(s.agent_id).or_insert(0);
                *seen = (*seen).max(s.tick);
            }
            if followed.contains_key(&s.agent_id) {
                let poses = anchors.entry(s.agent_id).or_default();
                poses.insert(s.tick, Pose::new(s.x, s.y, s.theta));
                while poses.len() > ANCHOR_TICKS {
                    poses.pop_first();
                }
            }
            bodies.saw(s.agent_id, glam::DVec2::new(s.x, s.y), s.tick);
        })?;
        bodies.forget_gone();
        let mut idle = true;
        for (id, robot) in &mut followed {
            let mut scans = std::mem::take(&mut robot.waiting);
            robot.scans.receive(|scan| scans.push(scan))?;
            if !scans.is_empty() {
                idle = false;
                robot.last_scan = Some(std::time::Instant::now());
            }
            if robot.filter.is_none() {
                // The filter starts at the true pose of the tick of a scan,
                // mapping that scan; the command that led there is already
                // in the pose and is not applied again. (Starting from the
                // newest pose and stepping the first scan's command turned a
                // formation robot, whose first command is a turn in place,
                // by that turn twice: SLAM then ran 90 degrees off.)
                let poses = anchors.get(id);
                let Some(first) = scans
                    .iter()
                    .rposition(|s| poses.is_some_and(|p| p.contains_key(&s.tick)))
                else {
                    // The roster may bring the scan's pose a moment later.
                    let keep = scans.len().saturating_sub(WAITING_SCANS);
                    robot.waiting = scans.split_off(keep);
                    continue;
                };
                let scan = scans[first];
                let Some(start) = poses.and_then(|p| p.get(&scan.tick)).copied() else {
                    continue;
                };
                let mut ranges: Vec<f64> = scan.ranges().iter().map(|r| f64::from(*r)).collect();
                // A swarm starts crowded: beams that end on another robot
                // would put it in the map as a wall for ever.
                mask_bodies(&mut ranges, &start, &scenario.sensor, bodies.others(*id));
                let mut filter = ParticleFilter::new(
                    start,
                    initial.clone(),
                    config.clone(),
                    scenario.arena.width,
                    scenario.arena.height,
                    u64::from(*id),
                );
                filter.observe_start(&ranges);
                robot.filter = Some(filter);
                scans.drain(..=first);
            }
            for scan in scans {
                let Some(filter) = &mut robot.filter else {
                    break;
                };
                let mut ranges: Vec<f64> = scan.ranges().iter().map(|r| f64::from(*r)).collect();
                // Beams that end on another robot are dropped: robots move,
                // so they do not belong in the map. Which beams those are is
                // perception (a robot knows a robot when it sees one), so
                // it is judged from where the robot stood, as the roster
                // says, not from SLAM's own estimate: a wrong estimate
                // let robots into the map as walls, and the map then held
                // the estimate wrong (in a crowd of 20, 1.6 m against 0.7 m).
                let seen_from = anchors
                    .get(id)
                    .and_then(|poses| poses.get(&scan.tick))
                    .copied()
                    .unwrap_or_else(|| filter.estimate());
                mask_bodies(
                    &mut ranges,
                    &seen_from,
                    &scenario.sensor,
                    bodies.others(*id),
                );
                let Some(command) = Command::from_index(scan.command as usize) else {
                    continue;
                };
                let report = filter.step(command, scan.bumped != 0, &ranges);
                robot.steps += 1;
                particles_out.publish(&view::particles(*id, &scan, filter))?;
                if robot.steps % MAP_EVERY_STEPS == 1 {
                    maps_out.publish(&view::map(*id, &scan, filter))?;
                }
                robot.estimates.publish(&EstimateSample {
                    agent_id: *id,
                    reserved: 0,
                    tick: scan.tick,
                    x: report.estimate.x,
                    y: report.estimate.y,
                    theta: report.estimate.theta,
                    effective_particles: report.effective_particles,
                })?;
                for param in Param::ALL {
                    let mixture = filter.model().command(command).param(param);
                    robot.models.publish(&ModelUpdate::new(
                        *id,
                        command,
                        param,
                        robot.steps,
                        mixture,
                    ))?;
                }
            }
        }
        // A lockstep launcher paces its clock to this, so no scan is dropped.
        // Done up to the oldest tick of the followed robots still stepping;
        // a robot that is gone (two ticks behind the swarm) is not waited for.
        let done = seen_ticks
            .values()
            .copied()
            .filter(|&t| t + 2 >= newest_roster)
            .min()
            .unwrap_or(newest_roster);
        progress.publish(&HelperProgress { tick: done })?;
        if last_report.elapsed() >= REPORT_EVERY {
            last_report = std::time::Instant::now();
            if !runtime.is_up() {
                eprintln!(
                    "shoal-slam: swarm `{}` has stopped; so does SLAM",
                    args.swarm
                );
                break;
            }
            let report = report(&followed, &initial);
            if let Err(e) = runtime.write_slam_report(&report) {
                tracing::warn!("cannot write the SLAM report: {e}");
            }
        }
        if idle {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    Ok(())
}

/// How often `shoal status` learns what SLAM knows.
const REPORT_EVERY: Duration = Duration::from_secs(1);
/// A followed robot without scans this long is paused: killed, its filter
/// waits for it to come back.
const PAUSED_AFTER: Duration = Duration::from_secs(2);

fn report(followed: &BTreeMap<u32, Followed>, initial: &MotionModel) -> SlamReport {
    SlamReport {
        pid: std::process::id(),
        followed: followed
            .iter()
            .map(|(id, robot)| {
                let estimate = robot.filter.as_ref().map(ParticleFilter::estimate);
                FollowedReport {
                    id: *id,
                    steps: robot.steps,
                    model_distance: robot
                        .filter
                        .as_ref()
                        .map_or(0.0, |f| f.model().distance_from(initial)),
                    paused: robot.last_scan.is_none_or(|t| t.elapsed() > PAUSED_AFTER),
                    estimate: estimate.map(|p| [p.x, p.y, p.theta]),
                    stride_m: robot.filter.as_ref().map(|f| f.model().full_stride()),
                }
            })
            .collect(),
    }
}

/// Viewers get a map every this many steps: a map is 16 KB, particles 2 KB.
const MAP_EVERY_STEPS: u64 = 10;

fn main() -> std::process::ExitCode {
    shoal_broker::process_main::run_main("shoal-slam", "info", || run(Args::parse()))
}

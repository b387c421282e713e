//! `shoal-slam`: follows robots' sensor streams on the bus, runs particle-filter
//! SLAM for each, learns each robot's motion model online and publishes pose
//! estimates and model updates back to the robots.

mod view;

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Parser;
use shoal_broker::robot_streams;
use shoal_broker::{
    Bus, BusLimits, EstimateSample, HelperProgress, ModelUpdate, Receiver, ScanSample, Sender,
    SlamMap, SlamParticles,
};
use shoal_physics::legged::Param;
use shoal_physics::{Command, MotionModel, Pose};
use shoal_runtime::SwarmRuntime;
use shoal_slam::filter::{Bodies, FilterConfig, ParticleFilter, Proposal};
use shoal_slam::follow::Follow;
use shoal_slam::follower::{FirstLooks, Follower, Scan, Stepped};
use shoal_slam::report::{FollowedReport, SlamReport};

#[derive(Parser)]
#[command(
    version,
    about = "Particle-filter SLAM that learns each followed robot's motion model online"
)]
struct Args {
    #[arg(long, default_value = "default")]
    swarm: String,
    /// The robots to follow: ids, e.g. 0,3, or `all` (every robot of the
    /// swarm, those that join later included).
    #[arg(long, required = true)]
    follow: Follow,
    /// Particles per followed robot (default: the filter's, 50).
    #[arg(long, default_value_t = FilterConfig::default().particles)]
    particles: usize,
    /// The fewest particles a filter behind its robot sheds to before it
    /// coasts through scans (default: a fifth of --particles; as many as
    /// --particles never sheds).
    #[arg(long)]
    fewest_particles: Option<usize>,
    /// The learning window k (5..=10).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u64).range(5..=10))]
    window: u64,
    #[arg(long, value_enum, default_value_t = Learning::On)]
    learning: Learning,
    /// The model to start from (TOML, per command: d, c, t mixtures); default: the swarm's.
    #[arg(long)]
    initial_model: Option<PathBuf>,
    /// Occupancy grid cell size, metres (default: as wide as the sensor's
    /// range noise at half its reach, 2.5-5 cm, coarser where the arena
    /// would make the map too large).
    #[arg(long)]
    grid: Option<f64>,
    /// Where particles go each step: `matched` (GMapping's improved
    /// proposal: scan-matched, then drawn around the match; the default) or
    /// `motion` (drawn from the motion model, weighted by the scan; needs
    /// about ten times the particles for the same accuracy: EXPERIMENTS.md,
    /// "SLAM").
    #[arg(long, value_enum, default_value_t = ProposalArg::Matched)]
    proposal: ProposalArg,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ProposalArg {
    Motion,
    Matched,
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

/// One followed robot: its filter and its streams.
struct Followed {
    follower: Follower,
    scans: Receiver<ScanSample>,
    estimates: Sender<EstimateSample>,
    models: Sender<ModelUpdate>,
    last_scan: Option<std::time::Instant>,
    /// Scans received and not yet stepped, oldest first.
    pending: std::collections::VecDeque<Scan>,
    /// Steps when the last report was written, for the step rate.
    steps_reported: u64,
}

const MIN_GRID_M: f64 = 0.01;
const MAX_GRID_M: f64 = 1.0;

/// What viewers see of SLAM.
struct Views {
    particles: Sender<SlamParticles>,
    maps: Sender<SlamMap>,
}

impl Views {
    /// Particles after every step; a map every [`MAP_EVERY_STEPS`].
    fn publish(&self, id: u32, step: &Stepped<'_>) -> Result<()> {
        self.particles.publish(&view::particles(id, step))?;
        if step.steps % MAP_EVERY_STEPS == 1 {
            self.maps.publish(&view::map(id, step))?;
        }
        Ok(())
    }
}

/// A step's pose estimate as the robot receives it.
fn estimate_of(id: u32, step: &Stepped<'_>) -> EstimateSample {
    let estimate = step.report.estimate;
    EstimateSample {
        agent_id: id,
        reserved: 0,
        tick: step.tick,
        x: estimate.x,
        y: estimate.y,
        theta: estimate.theta,
        effective_particles: step.report.effective_particles,
    }
}

/// A scan as the filter takes it.
fn scan_of(sample: &ScanSample) -> Scan {
    Scan {
        tick: sample.tick,
        sim_time: sample.sim_time,
        command: Command::from_index(sample.command as usize),
        bumped: sample.bumped != 0,
        ranges: sample.ranges().iter().map(|r| f64::from(*r)).collect(),
    }
}

/// How each followed robot's filter is set up.
struct Setup {
    config: FilterConfig,
    arena: [f64; 2],
    initial: MotionModel,
}

impl Setup {
    fn new(args: &Args, scenario: &shoal_scenario::Scenario, initial: &MotionModel) -> Self {
        Self {
            config: FilterConfig {
                particles: args.particles.max(1),
                fewest_particles: args.fewest_particles,
                cell_size: args.grid,
                learning: args.learning == Learning::On,
                window: args.window as usize,
                sensor: scenario.sensor.clone(),
                proposal: match args.proposal {
                    ProposalArg::Motion => Proposal::Motion,
                    ProposalArg::Matched => Proposal::ScanMatched,
                },
                ..FilterConfig::default()
            },
            arena: [scenario.arena.width, scenario.arena.height],
            initial: initial.clone(),
        }
    }

    /// A follower of robot `id` and its streams.
    fn follow(&self, bus: &Bus, id: u32) -> Result<Followed> {
        Ok(Followed {
            // Seeded by the id, so runs repeat.
            follower: Follower::new(
                id,
                u64::from(id),
                self.initial.clone(),
                self.config.clone(),
                self.arena,
            ),
            scans: robot_streams::scan_subscriber(bus, id)?,
            estimates: robot_streams::estimate_publisher(bus, id)?,
            models: robot_streams::model_publisher(bus, id)?,
            last_scan: None,
            pending: std::collections::VecDeque::new(),
            steps_reported: 0,
        })
    }
}

fn run(args: Args) -> Result<()> {
    // A bad model file is reported before anything else, swarm or not.
    let from_file = args.initial_model.as_ref().map(read_model).transpose()?;
    let runtime = SwarmRuntime::locate(&args.swarm);
    runtime.read_meta()?;
    let scenario = runtime.read_scenario()?;
    let initial = from_file.unwrap_or_else(|| scenario.motion.clone());
    // The map has (arena / grid)^2 cells per particle: a cell far below a
    // centimetre would ask for more memory than any machine has.
    if let Some(grid) = args.grid
        && !(MIN_GRID_M..=MAX_GRID_M).contains(&grid)
    {
        bail!("--grid {grid} is outside [{MIN_GRID_M}, {MAX_GRID_M}] metres per cell");
    }
    let (bus, roster) = shoal_broker::roster::join_reader(
        &args.swarm,
        &format!("slam-{}", std::process::id()),
        BusLimits::default(),
    )?;
    let views = Views {
        particles: robot_streams::slam_particles_publisher(&bus)?,
        maps: robot_streams::slam_map_publisher(&bus)?,
    };
    let progress = robot_streams::progress_publisher(&bus, robot_streams::SLAM_PROGRESS)?;
    let setup = Setup::new(&args, &scenario, &initial);
    let mut followed = BTreeMap::new();
    for &id in args.follow.named() {
        followed.insert(id, setup.follow(&bus, id)?);
    }
    let cell_m = setup.config.cell_in(setup.arena[0], setup.arena[1]);
    tracing::info!(follow = %args.follow, learning = ?args.learning, cell_m, "SLAM following");
    let mut newest_roster: u64 = 0;
    let mut last_report = std::time::Instant::now();
    let mut report_failing = false;
    // Where every robot stands, and at which tick, to drop beams that ended
    // on one: robots move, so they do not belong in the map. A robot silent
    // for longer than the swarm's staleness is gone, and so is its body.
    let mut bodies = Bodies::new((scenario.timing.stale_periods.ceil() as u64).max(1) + 1);
    let mut first_looks = FirstLooks::default();
    let mut pass_begins_at = 0;
    while !bus.termination_requested() {
        newest_roster = newest_roster.max(hear_roster(
            &roster,
            &mut followed,
            &mut bodies,
            (&setup, &bus, &args.follow),
        )?);
        bodies.forget_gone();
        let idle = !step_followed(
            &mut followed,
            &bodies,
            &mut first_looks,
            &views,
            &mut pass_begins_at,
        )?;
        progress.publish(&HelperProgress {
            tick: done_up_to(&followed, newest_roster),
        })?;
        if last_report.elapsed() >= REPORT_EVERY {
            let since = last_report.elapsed().as_secs_f64();
            last_report = std::time::Instant::now();
            if !runtime.is_up() {
                eprintln!(
                    "shoal-slam: swarm `{}` has stopped; so does SLAM",
                    args.swarm
                );
                break;
            }
            let report = report(&mut followed, &initial, (since, scenario.timing.period_s));
            write_report(&runtime, &report, &mut report_failing);
        }
        if idle {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    Ok(())
}

/// Reads the roster: each followed robot's announced pose, where every
/// robot stands (to drop beams that ended on one), and with `--follow all`
/// a robot that joined, followed from the first pose the roster shows of
/// it. Returns the newest tick heard (0 if none).
fn hear_roster(
    roster: &shoal_broker::RosterReader,
    followed: &mut BTreeMap<u32, Followed>,
    bodies: &mut Bodies,
    (setup, bus, follow): (&Setup, &Bus, &Follow),
) -> Result<u64> {
    let mut newest = 0;
    let mut joined = Vec::new();
    // The roster passes only samples that pass their wire check.
    roster.receive(|s| {
        newest = newest.max(s.tick);
        if let Some(robot) = followed.get_mut(&s.agent_id) {
            robot
                .follower
                .announced(s.tick, Pose::new(s.x, s.y, s.theta));
        } else if follow.includes(s.agent_id) {
            joined.push((s.agent_id, s.tick, Pose::new(s.x, s.y, s.theta)));
        }
        bodies.saw(s.agent_id, glam::DVec2::new(s.x, s.y), s.tick);
    })?;
    for (id, tick, pose) in joined {
        if let std::collections::btree_map::Entry::Vacant(place) = followed.entry(id) {
            let robot = place.insert(setup.follow(bus, id)?);
            robot.follower.announced(tick, pose);
            tracing::info!(robot = id, "SLAM follows a robot that joined");
        }
    }
    Ok(newest)
}

/// The tick SLAM is done up to (`follower::done_up_to`) over the robots
/// it follows.
fn done_up_to(followed: &BTreeMap<u32, Followed>, newest_roster: u64) -> u64 {
    shoal_slam::follower::done_up_to(
        followed.values().map(|robot| {
            (
                robot.follower.newest_announced(),
                robot.pending.front().map(|scan| scan.tick),
            )
        }),
        newest_roster,
    )
}

/// Takes every followed robot's new scans, then steps each robot's filter
/// on its oldest waiting scan and publishes the step: the views, the
/// estimate and the model. One scan per robot per call, so a SLAM process
/// that falls behind falls behind on every robot alike, and reads the
/// roster and its scans between steps (stepping one robot's whole backlog
/// at a time left the others' scans to overflow their buffers, lost). Each
/// filter shares its robot's first scan with the others and maps theirs.
/// Each pass begins one robot further on than the last (`begins_at`;
/// [`shoal_slam::follower::pass_order`] says why). False when no robot had
/// a scan to step.
fn step_followed(
    followed: &mut BTreeMap<u32, Followed>,
    bodies: &Bodies,
    first_looks: &mut FirstLooks,
    views: &Views,
    begins_at: &mut u32,
) -> Result<bool> {
    let mut stepped = false;
    let (order, next) =
        shoal_slam::follower::pass_order(&followed.keys().copied().collect(), *begins_at);
    *begins_at = next;
    for id in order {
        let Some(robot) = followed.get_mut(&id) else {
            continue;
        };
        let mut samples = Vec::new();
        robot.scans.receive(|scan| samples.push(scan))?;
        if !samples.is_empty() {
            robot.last_scan = Some(std::time::Instant::now());
        }
        robot.pending.extend(samples.iter().map(scan_of));
        // A SLAM process that cannot keep up for long drops its oldest
        // scans rather than its memory; the follower counts them missed.
        while robot.pending.len() > MAX_PENDING_SCANS {
            robot.pending.pop_front();
        }
        robot.follower.catch_up(&mut robot.pending);
        let Some(scan) = robot.pending.pop_front() else {
            continue;
        };
        stepped = true;
        let Followed {
            follower,
            estimates,
            models,
            ..
        } = robot;
        follower.on_scans(vec![scan], bodies, first_looks, |step| {
            views.publish(id, &step)?;
            estimates.publish(&estimate_of(id, &step))?;
            for param in Param::ALL {
                let mixture = step.filter.model().command(step.command).param(param);
                models.publish(&ModelUpdate::new(
                    id,
                    step.command,
                    param,
                    step.steps,
                    mixture,
                ))?;
            }
            Ok::<(), anyhow::Error>(())
        })?;
    }
    Ok(stepped)
}

/// Writes SLAM's report for `shoal status`. A failure is said once, and
/// again if it fails after working again; SLAM goes on either way.
fn write_report(runtime: &SwarmRuntime, report: &SlamReport, failing: &mut bool) {
    match runtime.write_report(report) {
        Err(e) if !*failing => {
            *failing = true;
            eprintln!(
                "shoal-slam: warning: cannot write the SLAM report in {}: {e}; \
                 `shoal status` shows what it last read; SLAM goes on",
                runtime.dir.display()
            );
        }
        Err(_) => {}
        Ok(()) => *failing = false,
    }
}

/// Scans a followed robot may have waiting: 13 s at 5 Hz.
const MAX_PENDING_SCANS: usize = 64;

/// How often `shoal status` learns what SLAM knows.
const REPORT_EVERY: Duration = Duration::from_secs(1);
/// A followed robot without scans this long is paused: killed, its filter
/// waits for it to come back.
const PAUSED_AFTER: Duration = Duration::from_secs(2);

/// What `shoal status` shows of SLAM: per followed robot, its steps, the
/// step rate over the last `since` seconds, and how far it trails its robot
/// (ticks of `period_s`).
fn report(
    followed: &mut BTreeMap<u32, Followed>,
    initial: &MotionModel,
    (since, period_s): (f64, f64),
) -> SlamReport {
    SlamReport {
        pid: std::process::id(),
        followed: followed
            .iter_mut()
            .map(|(id, robot)| {
                let steps = robot.follower.steps();
                let rate = (steps - robot.steps_reported.min(steps)) as f64 / since.max(1e-3);
                robot.steps_reported = steps;
                let filter = robot.follower.filter();
                let walked = robot.follower.most_walked();
                FollowedReport {
                    id: *id,
                    steps,
                    model_distance: filter.map_or(0.0, |f| f.model().distance_from(initial)),
                    paused: robot.last_scan.is_none_or(|t| t.elapsed() > PAUSED_AFTER),
                    estimate: filter.map(|f| {
                        let p = f.estimate();
                        [p.x, p.y, p.theta]
                    }),
                    estimate_tick: filter.and(robot.follower.stepped_tick()),
                    stride_m: filter.map(|f| f.model().mean(Command::Walk(walked)).along),
                    stride_walk: walked,
                    steps_per_s: filter.map(|_| rate),
                    behind_s: robot
                        .follower
                        .ticks_behind()
                        .map(|ticks| ticks as f64 * period_s),
                    scans_missed: robot.follower.scans_missed(),
                    scans_coasted: robot.follower.scans_coasted(),
                    steps_rematched: robot.follower.steps_rematched(),
                    particles: filter.map(ParticleFilter::particle_count),
                }
            })
            .collect(),
    }
}

/// Viewers get a map every this many steps: a map is 16 KB, particles 2 KB.
const MAP_EVERY_STEPS: u64 = 10;

fn main() -> std::process::ExitCode {
    shoal_runtime::process_main::run_main("shoal-slam", "info", || run(Args::parse()))
}

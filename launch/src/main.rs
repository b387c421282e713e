//! `shoal`: the command line of the Shoal swarm runtime.

use shoal::{status, up};
use shoal_lab::{demo, experiment};
use shoal_runtime::report;
use shoal_swarm::control;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};
use shoal_runtime::process_main::print_out;

#[derive(Parser)]
#[command(
    version,
    about = "Shoal: a runtime for robot swarms, one process per robot over iceoryx2"
)]
struct Cli {
    #[command(subcommand)]
    command: Commands,
    /// This machine's part of a swarm that spans hosts (default: the
    /// machine's name, or SHOAL_HOST). Two hosts on one machine are kept
    /// apart as two machines would be.
    #[arg(long, global = true)]
    host: Option<String>,
}

/// How the hosts of a swarm are joined.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum LinkKind {
    /// Zenoh: peers find each other by scouting or --connect.
    Zenoh,
}

#[derive(Subcommand)]
enum Commands {
    /// Start a swarm and watch it until Ctrl-C or --duration.
    Up(UpArgs),
    /// All of Shoal in one run: robots form, SLAM learns, four robots are
    /// killed and restarted, and the recording is diagnosed.
    Demo {
        /// A scenario file; default: the demo's own (scenarios/demo.toml in
        /// the repository: copy it and change it).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Where the recording goes.
        #[arg(long, default_value = "demo.rrd")]
        out: PathBuf,
        /// How long the swarm runs, in seconds (real time).
        #[arg(long, default_value_t = 90.0, value_parser = positive_seconds, allow_negative_numbers = true)]
        seconds: f64,
        #[arg(long, default_value = "demo")]
        swarm: String,
        /// Print the summary as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Run particle-filter SLAM on robots of a running swarm (see `shoal-slam --help`).
    #[command(disable_help_flag = true)]
    Slam {
        /// Arguments for shoal-slam, e.g. --follow 3 --learning off --particles 200.
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// Find where a simulation and a real run differ and name the missing physics (see `shoal-diagnose --help`).
    #[command(disable_help_flag = true)]
    Diagnose {
        /// Arguments for shoal-diagnose, e.g. --mrclam DIR --robot 3 --json --out diag.
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// Record a running swarm into a Rerun file (.rrd) until Ctrl-C.
    #[command(disable_help_flag = true)]
    Record {
        /// Arguments for shoal-viewer-log: [OUT.rrd] [--viewer | --connect ADDR] [--swarm NAME] [--tum DIR] [--duration SECS].
        #[arg(trailing_var_arg = true, allow_hyphen_values = true, required = true)]
        args: Vec<String>,
    },
    /// List every robot on the bus: id, pid, state, pose, neighbours.
    Status {
        #[arg(long, default_value = "default")]
        swarm: String,
        #[arg(long)]
        json: bool,
        /// Also show how full each spatial cell's service is (publishers and
        /// listeners against the `[bus]` limits), fullest first.
        #[arg(long)]
        cells: bool,
    },
    /// Kill robots (SIGKILL; --graceful for SIGTERM).
    Kill {
        ids: Vec<u32>,
        #[arg(long, default_value = "default")]
        swarm: String,
        #[arg(long)]
        graceful: bool,
    },
    /// Start robots again with the same id, at their last pose or --at X,Y.
    Restart {
        ids: Vec<u32>,
        #[arg(long, default_value = "default")]
        swarm: String,
        #[arg(long, value_parser = shoal_physics::pose::parse_point)]
        at: Option<[f64; 2]>,
    },
    /// Reproduce the thesis's results with real processes in lockstep.
    Experiment {
        #[command(subcommand)]
        which: ExperimentKind,
        /// Print JSON instead of a Markdown table.
        #[arg(long, global = true)]
        json: bool,
    },
    /// Stop a swarm from any terminal: its launcher, robots, recorder and SLAM.
    Down {
        #[arg(long, default_value = "default")]
        swarm: String,
    },
    /// Add new robots to a running swarm.
    Spawn {
        #[arg(long, default_value_t = 1, value_parser = robot_count)]
        count: usize,
        #[arg(long, default_value = "default")]
        swarm: String,
        #[arg(long, value_parser = shoal_physics::pose::parse_point)]
        at: Option<[f64; 2]>,
    },
}

#[derive(Subcommand)]
enum ExperimentKind {
    /// Tracked neighbours 1..10, with and without sectors.
    Formation {
        #[arg(long, default_value_t = 20)]
        agents: usize,
        #[arg(long, default_value_t = 1)]
        seeds: u64,
        /// Simulated seconds per run.
        #[arg(long, default_value_t = 60.0)]
        max_seconds: f64,
    },
    /// 20 robots among 400 random obstacles, and in a clear arena.
    Obstacles {
        #[arg(long, default_value_t = 20)]
        agents: usize,
        #[arg(long, default_value_t = 3)]
        seeds: u64,
        #[arg(long, default_value_t = 120.0)]
        max_seconds: f64,
    },
    /// Remove the 4 central robots of 20; add 6 at the edge of 19.
    Healing {
        #[arg(long, default_value_t = 3)]
        seeds: u64,
        #[arg(long, default_value_t = 90.0)]
        max_seconds: f64,
    },
    /// Online model learning: a wandering robot and a SLAM process, learning on and off.
    Learning {
        /// Simulated seconds per run.
        #[arg(long, default_value_t = 60.0)]
        seconds: f64,
        /// How many perturbed initial models (the thesis used 19).
        #[arg(long, default_value_t = 19)]
        perturbed: u64,
        #[arg(long, default_value_t = 500)]
        particles: usize,
    },
    /// Concealed effects, null runs and pairs diagnosed blind (see `shoal-diagnose experiment --help`).
    #[command(disable_help_flag = true)]
    Diagnose {
        /// Arguments for `shoal-diagnose experiment`, e.g. --seeds 5.
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// A real-time swarm under kills, freezes and recorder crashes.
    Chaos(experiment::chaos::ChaosArgs),
    /// From 3 to hundreds of robot processes.
    Scale {
        #[arg(long, value_delimiter = ',', default_value = "3,10,25,50,100,200")]
        sizes: Vec<usize>,
        #[arg(long, default_value_t = 60.0)]
        max_seconds: f64,
        /// Run each swarm in real time (robots keep their own period)
        /// instead of in lockstep, and report missed periods and how old
        /// the neighbour poses robots act on are.
        #[arg(long)]
        real_time: bool,
    },
}

/// `shoal up`'s arguments.
#[derive(clap::Args)]
struct UpArgs {
    /// How many robots (overrides the scenario).
    #[arg(long, value_parser = robot_count)]
    agents: Option<usize>,
    /// A scenario file (TOML); default: a walled arena with obstacles and two surfaces.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// The swarm's name: swarms with different names never see each other.
    #[arg(long, default_value = "default")]
    swarm: String,
    /// Stop after this many seconds (simulated seconds in lockstep).
    #[arg(long, value_parser = positive_seconds, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Step all robots on one clock, faster than real time and deterministic for a seed
    /// (unless a SLAM process follows them: its corrections and learned models reach
    /// the robots on its own clock).
    #[arg(long)]
    lockstep: bool,
    /// Seed of start poses and noise (overrides the scenario).
    #[arg(long)]
    seed: Option<u64>,
    /// Print a JSON summary when the swarm stops.
    #[arg(long)]
    json: bool,
    /// Record the run into this Rerun file (.rrd).
    #[arg(long)]
    record: Option<PathBuf>,
    /// With --record: also write each robot's true and believed trajectory as TUM files here.
    #[arg(long, requires = "record")]
    tum: Option<PathBuf>,
    /// Watch the run live in a Rerun viewer started now (`rerun` on PATH).
    #[arg(long)]
    viewer: bool,
    /// Without --link: stream the run live to a Rerun viewer already
    /// running at ADDR (HOST:PORT). With --link zenoh: a Zenoh endpoint
    /// of another host to connect to, e.g. tcp/10.0.0.2:7447 (repeatable).
    #[arg(long, value_name = "ADDR")]
    connect: Vec<String>,
    /// Join this host's robots to the swarm's other hosts.
    #[arg(long, value_enum)]
    link: Option<LinkKind>,
    /// The first robot's id; the others follow. Ids must be unique
    /// across the hosts of a swarm.
    #[arg(long, default_value_t = 0)]
    first_id: u32,
    /// With --link zenoh: a Zenoh configuration file (JSON5), for
    /// endpoints, scouting, TLS and access control.
    #[arg(long, requires = "link")]
    zenoh_config: Option<PathBuf>,
    /// With --link zenoh: a Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable).
    #[arg(long, requires = "link")]
    listen: Vec<String>,
    /// Start a SLAM process following these robots, e.g. 0,3, or `all`
    /// (every robot, those that join later included), beside those the
    /// scenario's `[slam]` names; `none` starts no SLAM process at all.
    #[arg(long)]
    slam: Option<up::SlamAsked>,
}

/// Becomes the sibling binary (exec): one process, so the pid the user sees
/// is the one doing the work, signals reach it, and `--help` is its own.
fn become_binary(binary: &str, args: &[String]) -> Result<()> {
    use std::os::unix::process::CommandExt;
    let path = shoal_swarm::process::sibling_binary(binary)?;
    let mut command = std::process::Command::new(&path);
    shoal_runtime::host::pass_to(&mut command);
    let error = command.args(args).exec();
    Err(anyhow::Error::new(error).context(format!("starting {}", path.display())))
}

fn run(cli: Cli) -> Result<()> {
    shoal_runtime::host::choose(cli.host.as_deref())?;
    match cli.command {
        Commands::Up(args) => up_command(args),
        Commands::Demo {
            scenario,
            out,
            seconds,
            swarm,
            json,
        } => demo_command(scenario, out, seconds, swarm, json),
        Commands::Slam { args } => become_binary("shoal-slam", &args),
        Commands::Record { args } => become_binary("shoal-viewer-log", &args),
        Commands::Diagnose { args } => become_binary("shoal-diagnose", &args),
        Commands::Status { swarm, json, cells } => status_command(&swarm, json, cells),
        Commands::Experiment { which, json } => experiment_command(which, json),
        Commands::Kill {
            ids,
            swarm,
            graceful,
        } => control::kill(&swarm, &ids, graceful),
        Commands::Restart { ids, swarm, at } => control::restart(&swarm, &ids, at),
        Commands::Down { swarm } => {
            let stopped = control::down(&swarm)?;
            print_out(|out| writeln!(out, "stopped swarm `{swarm}` ({stopped} processes)"))
        }
        Commands::Spawn { count, swarm, at } => control::spawn(&swarm, count, at).map(drop),
    }
}

/// `shoal up`: where the run goes (a linked swarm's hosts, a viewer), then
/// the swarm until Ctrl-C or its duration.
fn up_command(args: UpArgs) -> Result<()> {
    let UpArgs {
        agents,
        scenario,
        swarm,
        duration,
        lockstep,
        seed,
        json,
        record,
        tum,
        viewer,
        connect,
        slam,
        link,
        first_id,
        zenoh_config,
        listen,
    } = args;
    let (link, viewer_at) = match link {
        Some(LinkKind::Zenoh) => (
            Some(shoal_swarm::LinkOptions {
                zenoh_config,
                listen,
                connect,
            }),
            None,
        ),
        None => match connect.as_slice() {
            [] => (None, None),
            [addr] if !viewer => (None, Some(addr.clone())),
            [_] => anyhow::bail!(
                "--viewer starts a viewer; --connect streams to a running one: choose one"
            ),
            _ => anyhow::bail!(
                "--connect names one Rerun viewer, or with --link zenoh the Zenoh endpoints of other hosts"
            ),
        },
    };
    up::up(up::UpOptions {
        swarm,
        scenario,
        agents,
        seed,
        launch: shoal_swarm::Launch {
            lockstep,
            first_id,
            link,
        },
        duration_s: duration,
        json,
        record: shoal_swarm::RecordOptions {
            out: record,
            tum,
            viewer,
            connect: viewer_at,
            expected_seconds: duration,
        },
        slam,
    })
    .map(drop)
}

fn demo_command(
    scenario: Option<PathBuf>,
    out: PathBuf,
    seconds: f64,
    swarm: String,
    json: bool,
) -> Result<()> {
    let summary = demo::run(&demo::DemoOptions {
        swarm,
        scenario: scenario.clone(),
        out,
        seconds,
    })?;
    let scenario = demo::demo_scenario(scenario.as_deref())?;
    print_out(|out| {
        if json {
            writeln!(out, "{}", serde_json::to_string(&summary)?)
        } else {
            demo::print(out, &summary, &scenario)
        }
    })
}

fn status_command(swarm: &str, json: bool, cells: bool) -> Result<()> {
    let report = status::gather(swarm, cells)?;
    print_out(|out| {
        if json {
            return writeln!(out, "{}", serde_json::to_string(&report)?);
        }
        status::print_table(out, &report)?;
        match &report.cells {
            Some(cells) => status::print_cells(out, cells),
            None => Ok(()),
        }
    })
}

/// `shoal experiment`: runs one of the lab's experiments and prints its
/// report; the diagnosis's experiment is `shoal-diagnose experiment`.
fn experiment_command(which: ExperimentKind, json: bool) -> Result<()> {
    match which {
        ExperimentKind::Formation {
            agents,
            seeds,
            max_seconds,
        } => report::print(
            &experiment::formation::run(agents, seeds, max_seconds)?,
            json,
        ),
        ExperimentKind::Obstacles {
            agents,
            seeds,
            max_seconds,
        } => report::print(
            &experiment::obstacles::run(agents, seeds, max_seconds)?,
            json,
        ),
        ExperimentKind::Healing { seeds, max_seconds } => {
            report::print(&experiment::healing::run(seeds, max_seconds)?, json)
        }
        ExperimentKind::Chaos(args) => report::print(&experiment::chaos::run(&args)?, json),
        ExperimentKind::Scale {
            sizes,
            max_seconds,
            real_time,
        } => report::print(
            &experiment::scale::run(&sizes, max_seconds, real_time)?,
            json,
        ),
        ExperimentKind::Learning {
            seconds,
            perturbed,
            particles,
        } => report::print(
            &experiment::learning::run(seconds, perturbed, particles)?,
            json,
        ),
        ExperimentKind::Diagnose { mut args } => {
            args.insert(0, "experiment".into());
            if json {
                args.push("--json".into());
            }
            become_binary("shoal-diagnose", &args)
        }
    }
}

/// A count of robots: at least one (ids are checked against their range
/// where the first id is known).
fn robot_count(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(0) => Err("a swarm needs at least one robot".to_owned()),
        Ok(n) if n > shoal_swarm::process::MAX_ROBOT_ID as usize + 1 => Err(format!(
            "Shoal runs at most {} robots (ids 0 to {})",
            shoal_swarm::process::MAX_ROBOT_ID as usize + 1,
            shoal_swarm::process::MAX_ROBOT_ID
        )),
        Ok(n) => Ok(n),
        Err(e) => Err(format!("not a count of robots: {e}")),
    }
}

/// A span of time: a positive, finite number of seconds.
fn positive_seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if s.is_finite() && s > 0.0 => Ok(s),
        Ok(_) => Err("must be a positive number of seconds".to_owned()),
        Err(e) => Err(format!("not a number of seconds: {e}")),
    }
}

fn main() -> ExitCode {
    shoal_runtime::process_main::run_main("shoal", "warn", || run(Cli::parse()))
}

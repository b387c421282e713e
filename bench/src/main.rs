//! `shoal-bench`: what the bus costs, measured against a baseline in the same run.

mod bus;
mod diagnose;
mod link;
mod record;
mod scan;
mod slam;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    about = "Shoal benchmarks: each prints ratios against a baseline measured in the same run"
)]
struct Cli {
    #[command(subcommand)]
    command: Commands,
}

#[derive(Subcommand)]
enum Commands {
    /// Pose latency between two robot processes over iceoryx2 and over Unix
    /// domain sockets, among swarms of the given sizes; CPU per robot per period.
    Bus {
        #[arg(long, value_delimiter = ',', default_value = "2,20,200")]
        agents: Vec<usize>,
        /// Poses sent per transport and swarm size.
        #[arg(long, default_value_t = 2000)]
        samples: usize,
        /// Listener slots of every cell's service (`bus.max_listeners_per_cell`;
        /// default: the scenario default). A send visits every slot.
        #[arg(long)]
        listeners_per_cell: Option<usize>,
        #[arg(long)]
        json: bool,
    },
    /// What recording costs: bytes per robot per second and recorder CPU,
    /// against the robots' CPU, for real-time swarms of the given sizes.
    Record {
        #[arg(long, value_delimiter = ',', default_value = "20,100")]
        agents: Vec<usize>,
        #[arg(long, default_value_t = 60.0)]
        seconds: f64,
        #[arg(long)]
        json: bool,
    },
    /// How long `shoal diagnose` takes on runs of these lengths at 100 Hz,
    /// against reading the same files.
    Diagnose {
        #[arg(long, value_delimiter = ',', default_value = "10,60")]
        minutes: Vec<f64>,
        #[arg(long)]
        json: bool,
    },
    /// SLAM steps and particle-beam evaluations per second by particle count
    /// (180 beams), and the real-time factor for one robot at 10 Hz.
    Slam {
        #[arg(long, value_delimiter = ',', default_value = "100,1000,5000")]
        particles: Vec<usize>,
        #[arg(long, default_value_t = 100)]
        steps: usize,
        /// A scenario whose arena and range sensor the robot walks with
        /// (e.g. scenarios/demo.toml); default: the SLAM tests' 3 x 4 m room
        /// and a 4 m sensor of 180 beams.
        #[arg(long)]
        scenario: Option<std::path::PathBuf>,
        /// Which proposals: motion, matched, or both.
        #[arg(long, value_delimiter = ',', default_value = "motion,matched")]
        proposal: Vec<slam::ProposalArg>,
        /// The map's cell, metres (default: the filter's for the sensor and
        /// arena, as `shoal-slam` chooses it).
        #[arg(long)]
        grid: Option<f64>,
        #[arg(long)]
        json: bool,
    },
    /// One robot's range scan among this many robots around it, against
    /// casting every beam at every robot.
    Scan {
        #[arg(long, value_delimiter = ',', default_value = "0,8,20,40")]
        robots: Vec<usize>,
        #[arg(long, default_value_t = 5000)]
        repeats: usize,
        #[arg(long)]
        json: bool,
    },
    /// Two hosts of this many robots each on this machine, linked over
    /// Zenoh on loopback: wire bytes and link CPU, and pose latency across
    /// hosts against within one, in the same run.
    Link {
        #[arg(long, default_value_t = 50)]
        agents: usize,
        /// Seconds each phase measures.
        #[arg(long, default_value_t = 30.0)]
        seconds: f64,
        #[arg(long)]
        json: bool,
    },
    /// Internal: one end of the latency probe.
    #[command(hide = true)]
    Probe {
        #[arg(long)]
        role: bus::Role,
        #[arg(long)]
        swarm: String,
        #[arg(long)]
        samples: usize,
        #[arg(long)]
        socket: std::path::PathBuf,
        #[arg(long)]
        listeners_per_cell: usize,
    },
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Commands::Bus {
            agents,
            samples,
            listeners_per_cell,
            json,
        } => bus::run(&agents, samples, listeners_per_cell, json),
        Commands::Record {
            agents,
            seconds,
            json,
        } => record::run(&agents, seconds, json),
        Commands::Diagnose { minutes, json } => diagnose::run(&minutes, json),
        Commands::Link {
            agents,
            seconds,
            json,
        } => link::run(agents, seconds, json),
        Commands::Slam {
            particles,
            steps,
            scenario,
            proposal,
            grid,
            json,
        } => slam::run(
            &particles,
            steps,
            (scenario.as_deref(), &proposal, grid),
            json,
        ),
        Commands::Scan {
            robots,
            repeats,
            json,
        } => scan::run(&robots, repeats, json),
        Commands::Probe {
            role,
            swarm,
            samples,
            socket,
            listeners_per_cell,
        } => bus::probe(role, &swarm, samples, &socket, listeners_per_cell),
    }
}

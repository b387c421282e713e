//! `shoal-bench`: what the bus costs, measured against a baseline in the same run.

mod bus;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(about = "Shoal benchmarks: each prints ratios against a baseline measured in the same run")]
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
    },
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Commands::Bus { agents, samples, json } => bus::run(&agents, samples, json),
        Commands::Probe { role, swarm, samples, socket } => bus::probe(role, &swarm, samples, &socket),
    }
}

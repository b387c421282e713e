//! `shoal`: the command line of the Shoal swarm runtime.

mod clock;
mod control;
mod observer;
mod process;
mod status;
mod swarm;
mod up;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(version, about = "Shoal: a runtime for robot swarms, one process per robot over iceoryx2")]
struct Cli {
    #[command(subcommand)]
    command: Commands,
}

#[derive(Subcommand)]
enum Commands {
    /// Start a swarm and watch it until Ctrl-C or --duration.
    Up {
        /// How many robots (overrides the scenario).
        #[arg(long)]
        agents: Option<usize>,
        /// A scenario file (TOML); default: a walled arena with obstacles and two surfaces.
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// The swarm's name: swarms with different names never see each other.
        #[arg(long, default_value = "default")]
        swarm: String,
        /// Stop after this many seconds (simulated seconds in lockstep).
        #[arg(long)]
        duration: Option<f64>,
        /// Step all robots on one clock, faster than real time and deterministic for a seed.
        #[arg(long)]
        lockstep: bool,
        /// Seed of start poses and noise (overrides the scenario).
        #[arg(long)]
        seed: Option<u64>,
        /// Print a JSON summary when the swarm stops.
        #[arg(long)]
        json: bool,
    },
    /// List every robot on the bus: id, pid, state, pose, neighbours.
    Status {
        #[arg(long, default_value = "default")]
        swarm: String,
        #[arg(long)]
        json: bool,
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
        #[arg(long, value_parser = parse_point)]
        at: Option<[f64; 2]>,
    },
    /// Add new robots to a running swarm.
    Spawn {
        #[arg(long, default_value_t = 1)]
        count: usize,
        #[arg(long, default_value = "default")]
        swarm: String,
        #[arg(long, value_parser = parse_point)]
        at: Option<[f64; 2]>,
    },
}

fn parse_point(text: &str) -> Result<[f64; 2], String> {
    let parts: Vec<&str> = text.split(',').collect();
    let [x, y] = parts[..] else { return Err("expected X,Y".to_owned()) };
    let parse = |v: &str| v.trim().parse::<f64>().map_err(|e| format!("`{v}`: {e}")).and_then(|v| {
        if v.is_finite() { Ok(v) } else { Err(format!("`{v}` is not finite")) }
    });
    Ok([parse(x)?, parse(y)?])
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Commands::Up { agents, scenario, swarm, duration, lockstep, seed, json } => {
            up::up(up::UpOptions { swarm, scenario, agents, seed, lockstep, duration_s: duration, json })?;
        }
        Commands::Status { swarm, json } => {
            let report = status::gather(&swarm)?;
            if json {
                println!("{}", serde_json::to_string(&report)?);
            } else {
                status::print_table(&report);
            }
        }
        Commands::Kill { ids, swarm, graceful } => control::kill(&swarm, &ids, graceful)?,
        Commands::Restart { ids, swarm, at } => control::restart(&swarm, &ids, at)?,
        Commands::Spawn { count, swarm, at } => {
            control::spawn(&swarm, count, at)?;
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()))
        .with_writer(std::io::stderr)
        .init();
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("shoal: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

//! `shoal-agent`: one robot of a swarm. Normally started by `shoal up`,
//! `shoal spawn` or `shoal restart`.

use clap::Parser;
use shoal_agent::run::{AgentOptions, run};
use shoal_physics::Pose;

#[derive(Parser)]
#[command(
    version,
    about = "One robot of a Shoal swarm (started by `shoal up`, `spawn` or `restart`)"
)]
struct Args {
    /// The swarm to join.
    #[arg(long, default_value = "default")]
    swarm: String,
    /// This robot's id.
    #[arg(long)]
    id: u32,
    /// Start pose `X,Y[,THETA]`.
    #[arg(long, value_parser = shoal_physics::pose::parse_pose)]
    at: Pose,
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    let name = format!("shoal-agent {}", args.id);
    shoal_runtime::process_main::run_main(&name, "info", || {
        run(AgentOptions {
            swarm: args.swarm,
            id: args.id,
            start: args.at,
        })
    })
}

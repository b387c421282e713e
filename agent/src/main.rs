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
    #[arg(long, value_parser = parse_pose)]
    at: Pose,
}

fn parse_pose(text: &str) -> Result<Pose, String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|e| format!("`{v}`: {e}")))
        .collect::<Result<_, _>>()?;
    match values[..] {
        [x, y] => Ok(Pose::new(x, y, 0.0)),
        [x, y, theta] => Ok(Pose::new(x, y, theta)),
        _ => Err("expected X,Y or X,Y,THETA".to_owned()),
    }
    .and_then(|p| {
        if p.is_finite() {
            Ok(p)
        } else {
            Err("pose must be finite".to_owned())
        }
    })
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    let name = format!("shoal-agent {}", args.id);
    shoal_broker::process_main::run_main(&name, "info", || {
        run(AgentOptions {
            swarm: args.swarm,
            id: args.id,
            start: args.at,
        })
    })
}

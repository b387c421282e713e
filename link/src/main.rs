//! `shoal-link`: one host's gateway between its iceoryx2 domain and the
//! swarm's other hosts over Zenoh. `shoal up --link zenoh` starts it.

use std::path::PathBuf;

use clap::Parser;

mod gateway;

#[derive(Parser)]
#[command(
    version,
    about = "Carries a swarm's poses between its hosts over Zenoh (started by `shoal up --link zenoh`)"
)]
struct Args {
    #[arg(long, default_value = "default")]
    swarm: String,
    /// A Zenoh configuration file (JSON5): mode, endpoints, scouting, TLS,
    /// access control. --listen and --connect add to its endpoints.
    #[arg(long)]
    zenoh_config: Option<PathBuf>,
    /// Zenoh endpoints to listen on, e.g. tcp/0.0.0.0:7447.
    #[arg(long)]
    listen: Vec<String>,
    /// Zenoh endpoints of other hosts to connect to, e.g. tcp/10.0.0.2:7447.
    #[arg(long)]
    connect: Vec<String>,
}

fn main() -> std::process::ExitCode {
    shoal_runtime::process_main::run_main("shoal-link", "info", || {
        let args = Args::parse();
        gateway::run(&gateway::Options {
            swarm: args.swarm,
            zenoh_config: args.zenoh_config,
            listen: args.listen,
            connect: args.connect,
        })
    })
}

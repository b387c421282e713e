//! A trial of the official iceoryx2 link (its tunnel over the Zenoh carrier,
//! 0.10, a prototype upstream) between two Shoal hosts' iceoryx2 domains,
//! limited to one swarm's cell services: what Shoal's own link was chosen
//! against (EXPERIMENTS.md 11).
//! Usage: iceoryx2-tunnel-trial DOMAIN_PREFIX SWARM ENDPOINT listen|connect
//! (host `a`'s domain prefix is `shoal_a_`).
use iceoryx2::prelude::*;
use iceoryx2_integrations_zenoh_link_carrier::ZenohCarrier;
use iceoryx2_link::Link;
use iceoryx2_link_tunnel::Tunnel;
use std::time::{Duration, Instant};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (prefix, swarm, endpoint, mode) = (&args[1], &args[2], &args[3], &args[4]);
    let mut config = Config::global_config().clone();
    config.global.prefix = FileName::new(prefix.as_bytes()).unwrap();
    let mut z = zenoh::Config::default();
    let key = if mode == "listen" { "listen/endpoints" } else { "connect/endpoints" };
    z.insert_json5(key, &format!("[\"{endpoint}\"]")).unwrap();
    z.insert_json5("scouting/multicast/enabled", "false").unwrap();
    let carrier = ZenohCarrier::create(z).unwrap();
    let node = NodeBuilder::new().config(&config).create::<ipc::Service>().unwrap();
    let cells = format!("shoal/{swarm}/cell/");
    let mut link = Link::new(node, Tunnel::new(carrier, &config))
        .with_filter(move |name| name.as_str().starts_with(&cells));
    let started = Instant::now();
    let mut errors = 0u64;
    let mut last = Instant::now();
    let mut last_discover = Instant::now() - Duration::from_secs(1);
    loop {
        if last_discover.elapsed() >= Duration::from_secs(1) {
            last_discover = Instant::now();
            if link.discover().is_err() { errors += 1; }
        }
        if link.propagate().is_err() { errors += 1; }
        if last.elapsed() > Duration::from_secs(5) {
            last = Instant::now();
            eprintln!("{:.0}s errors {errors}", started.elapsed().as_secs_f64());
        }
        // Ends on Ctrl-C or SIGTERM, so the node's resources are removed.
        if link.node().wait(Duration::from_millis(5)).is_err() {
            break;
        }
    }
}

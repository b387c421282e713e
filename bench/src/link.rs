//! What joining hosts over Zenoh costs: two hosts of `agents` robots each on
//! this machine (separate iceoryx2 domains, linked over loopback TCP), their
//! robots in one formation across the border. Two phases:
//!
//! 1. Nobody else reads the swarm: each link asks only for the cells its
//!    robots listen to. Bytes on the wire per robot per second (the loopback
//!    interface's counter) and each link's CPU.
//! 2. An observer on host a reads the whole roster (as a recorder does), so
//!    host a's link asks for every pose of host b. The age at which each pose
//!    reaches the observer, for robots of host a (shared memory only: the
//!    baseline) and of host b (through both links and the network), in the
//!    same run, from the same clock.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, bail};
use serde::Serialize;
use shoal_broker::BusLimits;
use shoal_link::report::LinkReport;
use shoal_runtime::SwarmRuntime;
use shoal_runtime::host::{self, Host};
use shoal_swarm::process::{sibling_binary, usage};

/// Robots of host b have ids from here on.
const SECOND_FIRST_ID: u32 = 1000;

#[derive(Debug, Serialize)]
struct Report {
    robots_per_host: usize,
    seconds_per_phase: f64,
    /// Phase 1: the cells robots listen to only.
    border_only: Traffic,
    /// Phase 2: host a also asks for every pose of host b.
    whole_swarm: Traffic,
    /// Phase 2: pose age at the observer on host a, ms.
    same_host_p50_ms: f64,
    same_host_p99_ms: f64,
    other_host_p50_ms: f64,
    other_host_p99_ms: f64,
    /// What crossing hosts adds at the median, ms, and as a ratio.
    added_p50_ms: f64,
    other_vs_same_p50: f64,
    poses_timed: [usize; 2],
}

#[derive(Debug, Serialize)]
struct Traffic {
    /// Bytes the loopback interface sent (both directions between the
    /// hosts, TCP and Zenoh headers included) per robot of the swarm per second.
    wire_bytes_per_robot_per_s: f64,
    /// Pose messages each link handed to Zenoh, per second.
    poses_offered_per_s: [f64; 2],
    /// Each link's CPU time over wall time (1.0 is one core).
    link_cpu_share: [f64; 2],
}

struct HostProcess {
    host: Host,
    child: Child,
}

impl Drop for HostProcess {
    fn drop(&mut self) {
        // SAFETY: kill(2) of a child this process started.
        unsafe { libc::kill(self.child.id() as i32, libc::SIGINT) };
        let _ = self.child.wait();
    }
}

fn start_host(
    swarm: &str,
    name: &str,
    first_id: u32,
    scenario: &Path,
    zenoh: [&str; 2],
) -> Result<HostProcess> {
    let child = Command::new(sibling_binary("shoal")?)
        .args(["up", "--swarm", swarm, "--host", name, "--link", "zenoh"])
        .args(["--first-id", &first_id.to_string()])
        .arg("--scenario")
        .arg(scenario)
        .args(zenoh)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .context("starting shoal up")?;
    Ok(HostProcess {
        host: host::host_named(name.to_owned()),
        child,
    })
}

fn loopback_tx_bytes() -> u64 {
    std::fs::read_to_string("/sys/class/net/lo/statistics/tx_bytes")
        .ok()
        .and_then(|t| t.trim().parse().ok())
        .unwrap_or(0)
}

fn link_state(swarm: &str, host: &Host) -> Result<Option<(i32, u64)>> {
    let report = SwarmRuntime::locate_on(swarm, host).read_report::<LinkReport>()?;
    Ok(report.map(|r| (r.pid as i32, r.traffic.poses_offered)))
}

/// Wire bytes and link CPU over `seconds`.
fn measure_traffic(
    swarm: &str,
    hosts: &[&Host; 2],
    robots: usize,
    seconds: f64,
) -> Result<Traffic> {
    let [Some(a), Some(b)] = [link_state(swarm, hosts[0])?, link_state(swarm, hosts[1])?] else {
        bail!("a host's link is not running");
    };
    // A link that died mid-measurement is an error, never 0 CPU.
    let cpu_of = |pid: i32| -> Result<f64> {
        usage(pid)
            .map(|u| u.cpu_s)
            .with_context(|| format!("the link (pid {pid}) ended during the measurement"))
    };
    let cpu_before = [cpu_of(a.0)?, cpu_of(b.0)?];
    let bytes_before = loopback_tx_bytes();
    let started = Instant::now();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let wall = started.elapsed().as_secs_f64();
    let bytes = loopback_tx_bytes().saturating_sub(bytes_before);
    let [Some(a_after), Some(b_after)] =
        [link_state(swarm, hosts[0])?, link_state(swarm, hosts[1])?]
    else {
        bail!("a host's link stopped reporting during the measurement");
    };
    let after = [a_after, b_after];
    let cpu_after = [cpu_of(a.0)?, cpu_of(b.0)?];
    Ok(Traffic {
        wire_bytes_per_robot_per_s: bytes as f64 / (robots as f64 * wall),
        poses_offered_per_s: [0, 1].map(|i| after[i].1.saturating_sub([a, b][i].1) as f64 / wall),
        link_cpu_share: [0, 1].map(|i| (cpu_after[i] - cpu_before[i]) / wall),
    })
}

fn percentile(sorted: &[f64], share: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((share * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1]
}

/// A scenario for one of the two hosts: its half of one arena (starting at
/// `x0`), the goal on the halves' border.
fn half_scenario(
    dir: &Path,
    name: &str,
    agents: usize,
    x0: f64,
    seed: u64,
) -> Result<std::path::PathBuf> {
    let width = arena_width(agents);
    let height = width * 0.75;
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            "name = \"{name}\"\n[arena]\nwidth = {width}\nheight = {height}\n\
             [agents]\ncount = {agents}\nstart_region = [{x0}, 2.0, {}, {}]\nseed = {seed}\n\
             [formation]\ngoal = [{}, {}]\n",
            x0 + width / 2.0 - 3.0,
            height - 2.0,
            width / 2.0,
            height / 2.0
        ),
    )?;
    Ok(path)
}

/// The width of the arena both hosts share, for `agents` robots each.
fn arena_width(agents: usize) -> f64 {
    (agents as f64).sqrt() * 3.0 + 6.0
}

/// Waits until both hosts' links report a state.
fn wait_for_links(swarm: &str, hosts: [&Host; 2]) -> Result<()> {
    let started = Instant::now();
    while link_state(swarm, hosts[0])?.is_none() || link_state(swarm, hosts[1])?.is_none() {
        if started.elapsed() > Duration::from_secs(60) {
            bail!("the hosts did not come up within 60 s");
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    Ok(())
}

/// Phase 2: an observer on host a (this process joins it) times every
/// pose it hears, by host, while the link's traffic is measured.
fn pose_ages(
    swarm: &str,
    hosts: [&Host; 2],
    agents: usize,
    seconds: f64,
) -> Result<(Traffic, [Vec<f64>; 2])> {
    host::choose(Some(&hosts[0].name))?;
    let epoch_ms = SwarmRuntime::locate(swarm).read_meta()?.epoch_unix_ms as f64;
    let (_bus, roster) =
        shoal_broker::roster::join_reader(swarm, "bench-observer", BusLimits::default())?;
    // The link asks for every pose at its next second.
    std::thread::sleep(Duration::from_secs(3));
    roster.receive(|_| {})?;
    let mut ages: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let traffic = std::thread::scope(|scope| -> Result<Traffic> {
        let traffic = scope.spawn(|| measure_traffic(swarm, &hosts, 2 * agents, seconds));
        let timed = Instant::now();
        while timed.elapsed().as_secs_f64() < seconds {
            roster.receive(|sample| {
                let now_ms = SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .map_or(0.0, |d| d.as_secs_f64() * 1000.0);
                let age = now_ms - (epoch_ms + sample.sim_time * 1000.0);
                ages[usize::from(sample.agent_id >= SECOND_FIRST_ID)].push(age);
            })?;
            std::thread::sleep(Duration::from_millis(1));
        }
        traffic
            .join()
            .map_err(|_| anyhow::anyhow!("the traffic measurement panicked"))?
    })?;
    for list in &mut ages {
        list.sort_by(f64::total_cmp);
    }
    Ok((traffic, ages))
}

pub fn run(agents: usize, seconds: f64, json: bool) -> Result<()> {
    let swarm = format!("benchlink{}", std::process::id() % 100_000);
    let dir = std::env::temp_dir().join(&swarm);
    std::fs::create_dir_all(&dir)?;
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let a = start_host(
        &swarm,
        "bench-a",
        0,
        &half_scenario(&dir, "bench-a", agents, 2.0, 1)?,
        ["--listen", &endpoint],
    )?;
    std::thread::sleep(Duration::from_secs(2));
    let b = start_host(
        &swarm,
        "bench-b",
        SECOND_FIRST_ID,
        &half_scenario(&dir, "bench-b", agents, arena_width(agents) / 2.0 + 1.0, 2)?,
        ["--connect", &endpoint],
    )?;
    let hosts = [&a.host, &b.host];
    wait_for_links(&swarm, hosts)?;
    // Let every robot start and the formation settle.
    std::thread::sleep(Duration::from_secs(15));
    let border_only = measure_traffic(&swarm, &hosts, 2 * agents, seconds)?;
    let (whole_swarm, [same, other]) = pose_ages(&swarm, hosts, agents, seconds)?;
    let report = Report {
        robots_per_host: agents,
        seconds_per_phase: seconds,
        border_only,
        whole_swarm,
        same_host_p50_ms: percentile(&same, 0.5),
        same_host_p99_ms: percentile(&same, 0.99),
        other_host_p50_ms: percentile(&other, 0.5),
        other_host_p99_ms: percentile(&other, 0.99),
        added_p50_ms: percentile(&other, 0.5) - percentile(&same, 0.5),
        other_vs_same_p50: percentile(&other, 0.5) / percentile(&same, 0.5),
        poses_timed: [same.len(), other.len()],
    };
    drop(b);
    drop(a);
    let _ = std::fs::remove_dir_all(&dir);
    shoal_runtime::report::print(&report, json)
}

//! `shoal status`: who is in a swarm, read from the bus.

use std::collections::BTreeMap;
use std::io::{self, Write};
use std::time::{Duration, Instant};

use anyhow::Result;
use serde::Serialize;
use shoal_broker::liveness::{SwarmNode, SwarmNodeState, swarm_nodes};
use shoal_broker::{BusLimits, CellOccupancy, PoseSample, names};
use shoal_link::report::LinkReport;
use shoal_runtime::{HelperReport, SwarmRuntime};
use shoal_slam::report::{FollowedReport, SlamReport};

#[derive(Debug, Serialize)]
pub struct AgentStatus {
    pub id: u32,
    /// The host that runs it (`--host`).
    pub host: String,
    pub pid: i32,
    pub state: &'static str,
    pub x: Option<f64>,
    pub y: Option<f64>,
    pub theta: Option<f64>,
    pub tick: Option<u64>,
    pub health: Option<u32>,
    pub neighbours: Vec<u32>,
    /// Control periods it has missed since it started.
    pub missed_periods: Option<u32>,
    /// How old the oldest neighbour pose it last acted on was.
    pub neighbour_age_ms: Option<u32>,
    /// What the SLAM process knows of this robot, if it follows it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slam: Option<FollowedReport>,
}

#[derive(Debug, Serialize)]
pub struct StatusReport {
    pub swarm: String,
    /// The host this report was made on.
    pub host: String,
    /// Every host of the swarm heard from, this one first.
    pub hosts: Vec<String>,
    pub agents: Vec<AgentStatus>,
    /// Dead nodes of this swarm whose resources could not be removed.
    pub stale_nodes: usize,
    /// Dead nodes this command removed before it looked, by swarm: those of
    /// swarms on this host with no live node left, which nobody else would
    /// remove (a swarm with live nodes removes its own).
    pub swept: std::collections::BTreeMap<String, usize>,
    /// Every robot a live SLAM process follows, present or not.
    pub slam: Vec<FollowedReport>,
    /// How full each cell's service is (`--cells`): publishers and
    /// listeners against the slots its service was made with.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cells: Option<Vec<CellOccupancy>>,
    /// Helpers' reports that are there but cannot be read (a corrupt
    /// `slam.toml`, say): the helper may run, but what it says is unknown.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub unreadable_reports: Vec<String>,
}

/// Listens to the roster for a few periods and lists every node of the
/// swarm; with `cells`, also how full each cell's service is.
pub fn gather(swarm: &str, cells: bool) -> Result<StatusReport> {
    names::validate_swarm(swarm)?;
    let swept = shoal_broker::liveness::remove_dead_nodes_of_abandoned_swarms()?;
    let runtime = SwarmRuntime::locate(swarm);
    let period = runtime.read_meta().map_or(0.2, |m| m.period_s);
    let (bus, roster) = shoal_broker::roster::join_reader(
        swarm,
        &format!("status-{}", std::process::id()),
        BusLimits::default(),
    )?;
    // The swarm's nodes, listed once (each listing reads every node's details).
    let nodes = swarm_nodes(swarm)?;
    let latest = listen(&roster, &nodes, period)?;
    // A report that cannot be read is shown as such, not taken for an
    // absent helper; one whose writer is gone says nothing of today.
    let mut unreadable_reports = Vec::new();
    let slam = readable::<SlamReport>(&runtime, &mut unreadable_reports);
    let link = readable::<LinkReport>(&runtime, &mut unreadable_reports);
    let host = shoal_runtime::host::current().name.clone();
    let stale_nodes = nodes
        .iter()
        .filter(|n| n.state == SwarmNodeState::Dead)
        .count();
    let mut agents: Vec<AgentStatus> = nodes
        .iter()
        .filter_map(|node| local_robot(node, &latest, &host, slam.as_ref()))
        .collect();
    let mut hosts = vec![host.clone()];
    // Robots of other hosts, as this host's link last heard them summarised.
    if let Some(link) = link {
        agents.extend(link.robots().map(|(host, robot)| remote_robot(host, robot)));
        hosts.extend(link.hosts.into_iter().map(|h| h.name));
    }
    agents.sort_by_key(|a| (a.id, a.state));
    let cells = if cells {
        Some(shoal_broker::cells::occupancy(&bus)?)
    } else {
        None
    };
    Ok(StatusReport {
        swarm: swarm.to_owned(),
        host,
        hosts,
        agents,
        stale_nodes,
        swept,
        slam: slam.map(|r| r.followed).unwrap_or_default(),
        cells,
        unreadable_reports,
    })
}

/// A helper's report, if it can be read; one that cannot is noted in
/// `unreadable` for the user to see.
fn readable<R: HelperReport>(runtime: &SwarmRuntime, unreadable: &mut Vec<String>) -> Option<R> {
    runtime.read_report::<R>().unwrap_or_else(|e| {
        unreadable.push(e.to_string());
        None
    })
}

/// Each robot's newest sample on the roster, heard for up to three
/// periods. Once every live robot among `nodes` has been heard, listening
/// longer tells nothing more: a formed swarm of 1000 answered in 0.85 s
/// when status always listened three periods.
fn listen(
    roster: &shoal_broker::RosterReader,
    nodes: &[SwarmNode],
    period_s: f64,
) -> Result<BTreeMap<u32, PoseSample>> {
    let listen = Duration::from_secs_f64((3.0 * period_s).clamp(0.3, 3.0));
    let expected: Vec<(u32, i32)> = nodes
        .iter()
        .filter(|n| n.state == SwarmNodeState::Alive)
        .filter_map(|n| Some((n.agent_id?, n.pid)))
        .collect();
    let mut latest: BTreeMap<u32, PoseSample> = BTreeMap::new();
    let started = Instant::now();
    while started.elapsed() < listen {
        // The roster passes only samples that pass their wire check.
        roster.receive(|s| {
            latest.insert(s.agent_id, s);
        })?;
        let heard_all = expected
            .iter()
            .all(|(id, pid)| latest.get(id).is_some_and(|s| s.pid as i32 == *pid));
        if heard_all {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    Ok(latest)
}

/// A robot of this host, as its bus node and its newest sample show it.
fn local_robot(
    node: &SwarmNode,
    latest: &BTreeMap<u32, PoseSample>,
    host: &str,
    slam: Option<&SlamReport>,
) -> Option<AgentStatus> {
    let id = node.agent_id?;
    let alive = node.state == SwarmNodeState::Alive;
    let sample = latest
        .get(&id)
        .filter(|s| s.pid as i32 == node.pid && alive);
    Some(AgentStatus {
        id,
        host: host.to_owned(),
        pid: node.pid,
        state: if alive { "alive" } else { "dead" },
        x: sample.map(|s| s.x),
        y: sample.map(|s| s.y),
        theta: sample.map(|s| s.theta),
        tick: sample.map(|s| s.tick),
        health: sample.map(|s| s.health),
        neighbours: sample
            .map(|s| s.neighbour_ids().to_vec())
            .unwrap_or_default(),
        missed_periods: sample.map(|s| s.missed_periods),
        neighbour_age_ms: sample.map(|s| s.neighbour_age_ms),
        slam: slam.and_then(|r| r.followed.iter().find(|f| f.id == id).cloned()),
    })
}

/// A robot of another host, as that host's summary last said.
fn remote_robot(host: &str, robot: &shoal_link::report::RemoteRobot) -> AgentStatus {
    AgentStatus {
        id: robot.id,
        host: host.to_owned(),
        pid: robot.pid as i32,
        state: "alive",
        x: Some(robot.x),
        y: Some(robot.y),
        theta: Some(robot.theta),
        tick: Some(robot.tick),
        health: None,
        neighbours: robot.neighbours.clone(),
        missed_periods: Some(robot.missed_periods),
        neighbour_age_ms: Some(robot.neighbour_age_ms),
        slam: None,
    }
}

/// Prints `report` as a table, one robot a line.
pub fn print_table(out: &mut dyn Write, report: &StatusReport) -> io::Result<()> {
    let alive = report.agents.iter().filter(|a| a.state == "alive").count();
    writeln!(
        out,
        "swarm `{}` seen from host `{}`: {alive} alive, {} stale nodes{}",
        report.swarm,
        report.host,
        report.stale_nodes,
        if report.hosts.len() > 1 {
            format!(" (hosts: {})", report.hosts.join(", "))
        } else {
            String::new()
        }
    )?;
    if let Some(swept) = shoal_broker::liveness::describe_swept(&report.swept) {
        writeln!(out, "{swept}")?;
    }
    for unreadable in &report.unreadable_reports {
        writeln!(out, "unreadable report: {unreadable}")?;
    }
    for f in report.slam.iter().filter(|f| f.paused) {
        writeln!(
            out,
            "SLAM follows robot {} (paused: no scans from it)",
            f.id
        )?;
    }
    writeln!(
        out,
        "{:>5} {:<10} {:>8} {:>6} {:>8} {:>8} {:>7}  {:<48} neighbours",
        "id", "host", "pid", "state", "x", "y", "theta", "slam"
    )?;
    for a in &report.agents {
        let num = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.2}"));
        let neighbours: Vec<String> = a.neighbours.iter().map(u32::to_string).collect();
        let slam = a.slam.as_ref().map_or_else(
            || "-".to_owned(),
            |f| {
                let particles = f
                    .particles
                    .map(|n| format!(", {n} particles"))
                    .unwrap_or_default();
                let keeping_up = match (f.steps_per_s, f.behind_s) {
                    (Some(rate), Some(behind)) => {
                        format!(" ({rate:.1}/s, {behind:.1} s behind{particles})")
                    }
                    _ => String::new(),
                };
                let missed = if f.scans_missed > 0 {
                    format!(", {} scans missed", f.scans_missed)
                } else {
                    String::new()
                };
                let rematched = if f.steps_rematched > 0 {
                    format!(", {} steps matched again", f.steps_rematched)
                } else {
                    String::new()
                };
                format!(
                    "{} steps{keeping_up}{missed}{rematched}, model moved {:.2}{}",
                    f.steps,
                    f.model_distance,
                    if f.paused { ", paused" } else { "" }
                )
            },
        );
        writeln!(
            out,
            "{:>5} {:<10} {:>8} {:>6} {:>8} {:>8} {:>7}  {:<48} {}",
            a.id,
            a.host,
            a.pid,
            a.state,
            num(a.x),
            num(a.y),
            num(a.theta),
            slam,
            neighbours.join(",")
        )?;
    }
    Ok(())
}

/// Prints `cells` fullest first (by listeners), under a line on the fullest.
pub fn print_cells(out: &mut dyn Write, cells: &[CellOccupancy]) -> io::Result<()> {
    let mut by_listeners: Vec<&CellOccupancy> = cells.iter().collect();
    by_listeners.sort_by_key(|c| std::cmp::Reverse((c.listeners, c.publishers)));
    let busiest = by_listeners.first();
    writeln!(
        out,
        "{} cells; most listeners in one cell: {} of {}; most publishers: {} of {}",
        cells.len(),
        busiest.map_or(0, |c| c.listeners),
        busiest.map_or(0, |c| c.max_listeners),
        cells.iter().map(|c| c.publishers).max().unwrap_or(0),
        cells.first().map_or(0, |c| c.max_publishers),
    )?;
    writeln!(
        out,
        "{:>12} {:>11} {:>10}",
        "cell", "publishers", "listeners"
    )?;
    for c in by_listeners {
        writeln!(
            out,
            "{:>12} {:>5} / {:<3} {:>4} / {:<4}",
            format!("{},{}", c.cell.0, c.cell.1),
            c.publishers,
            c.max_publishers,
            c.listeners,
            c.max_listeners
        )?;
    }
    Ok(())
}

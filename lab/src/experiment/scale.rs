//! From 3 to hundreds of robot processes (thesis III.C: 3 to 200 agents).

use std::time::Instant;

use anyhow::Result;
use serde::Serialize;
use shoal_scenario::Scenario;

use super::{run_until_settled, swarm_name};
use shoal_swarm::RunningSwarm;
use shoal_swarm::observer::Timeliness;
use shoal_swarm::process::{ProcessUsage, usage};

#[derive(Debug, Serialize)]
pub struct Row {
    pub agents: usize,
    pub components: usize,
    pub spacing_ratio: f64,
    pub converge_s: Option<f64>,
    pub ticks: u64,
    /// CPU time of all robot processes divided by robots and ticks.
    pub cpu_ms_per_agent_tick: f64,
    /// Resident memory per robot process, shared-memory pages included.
    pub rss_mb_per_agent: f64,
    /// Of which private to the process.
    pub private_mb_per_agent: f64,
    /// Simulated seconds per wall-clock second.
    pub speedup: f64,
    /// Seconds the launcher took to start every robot.
    pub start_s: f64,
    /// In real time, whether it held once every robot had joined (in
    /// lockstep, ages are simulated time).
    #[serde(flatten)]
    pub timeliness: Timeliness,
}

#[derive(Debug, Serialize)]
pub struct Report {
    pub rows: Vec<Row>,
}

/// Runs each size for `max_s` simulated seconds, in lockstep (as fast as
/// the robots compute) or in real time.
pub fn run(sizes: &[usize], max_s: f64, real_time: bool) -> Result<Report> {
    let mut rows = Vec::new();
    for (index, &agents) in sizes.iter().enumerate() {
        let launched = Instant::now();
        let mut swarm = RunningSwarm::launch(
            &swarm_name("scale", index),
            Scenario::open_arena(agents),
            !real_time,
        )?;
        let start_s = launched.elapsed().as_secs_f64();
        swarm.observer.reset_timeliness_once_heard(agents);
        let pids = swarm.agent_pids();
        let before: ProcessUsage = pids.iter().filter_map(|p| usage(*p)).sum();
        let wall = Instant::now();
        // A fixed run, long enough that CPU time (counted in 10 ms steps) is measurable.
        let outcome = run_until_settled(&mut swarm, max_s, f64::INFINITY)?;
        let wall_s = wall.elapsed().as_secs_f64();
        let after: Vec<ProcessUsage> = pids.iter().filter_map(|p| usage(*p)).collect();
        let measured = after.len().max(1) as f64;
        let after_total: ProcessUsage = after.iter().copied().sum();
        swarm.shutdown()?;
        let ticks = outcome.ticks.max(1) as f64;
        let row = Row {
            agents,
            components: outcome.metrics.components,
            spacing_ratio: outcome.metrics.spacing_ratio,
            converge_s: outcome.converge_s,
            ticks: outcome.ticks,
            cpu_ms_per_agent_tick: (after_total.cpu_s - before.cpu_s) * 1000.0
                / (agents as f64 * ticks),
            rss_mb_per_agent: after_total.rss_mb / measured,
            private_mb_per_agent: after_total.private_mb / measured,
            speedup: outcome.ticks as f64 * swarm.scenario.timing.period_s / wall_s,
            start_s,
            timeliness: swarm.observer.timeliness(),
        };
        eprintln!(
            "scale: {agents} robots: started in {:.1} s, groups {}, spacing {:.2}, formed after {:?} s, {:.3} ms CPU per robot per tick, {:.1} MB RSS per robot, {:.1}x real time, {:.2} missed periods per robot, neighbour age p50 {:?} ms p99 {:?} ms",
            row.start_s,
            row.components,
            row.spacing_ratio,
            row.converge_s,
            row.cpu_ms_per_agent_tick,
            row.rss_mb_per_agent,
            row.speedup,
            row.timeliness.missed_periods_mean,
            row.timeliness.neighbour_age_p50_ms,
            row.timeliness.neighbour_age_p99_ms
        );
        rows.push(row);
    }
    Ok(Report { rows })
}

//! What recording costs: bytes per robot per second and the recorder's CPU
//! share, beside the robots' own CPU in the same run.

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use serde::Serialize;
use shoal_scenario::Scenario;
use shoal_swarm::RunningSwarm;
use shoal_swarm::process::{ProcessUsage, usage};

#[derive(Debug, Serialize)]
struct Row {
    agents: usize,
    seconds: f64,
    bytes: u64,
    bytes_per_robot_per_s: f64,
    /// Recorder CPU time over wall time (1.0 is one core).
    recorder_cpu_share: f64,
    /// All robots' CPU time over wall time, the baseline.
    robots_cpu_share: f64,
    /// The recorder's CPU divided by the robots'.
    recorder_vs_robots: f64,
}

pub fn run(agents: &[usize], seconds: f64, json: bool) -> Result<()> {
    let mut rows = Vec::new();
    for &count in agents {
        let name = format!("benchrec{}-{count}", std::process::id());
        let out = std::env::temp_dir().join(format!("{name}.rrd"));
        let mut swarm = RunningSwarm::launch(&name, Scenario::open_arena(count), false)?;
        swarm.record(&shoal_swarm::RecordOptions::file(&out, None))?;
        std::thread::sleep(Duration::from_secs(3));
        let recorder = swarm.recorder_pid().context("the recorder did not start")?;
        let robots = swarm.agent_pids();
        let bytes_before = std::fs::metadata(&out).map_or(0, |m| m.len());
        let recorder_before = usage(recorder).unwrap_or_default();
        let robots_before: ProcessUsage = robots.iter().filter_map(|p| usage(*p)).sum();
        let started = Instant::now();
        std::thread::sleep(Duration::from_secs_f64(seconds));
        let wall = started.elapsed().as_secs_f64();
        let recorder_after = usage(recorder).unwrap_or_default();
        let robots_after: ProcessUsage = robots.iter().filter_map(|p| usage(*p)).sum();
        let bytes_after = std::fs::metadata(&out).map_or(0, |m| m.len());
        swarm.shutdown()?;
        let _ = std::fs::remove_file(&out);
        let recorder_cpu = (recorder_after.cpu_s - recorder_before.cpu_s) / wall;
        let robots_cpu = (robots_after.cpu_s - robots_before.cpu_s) / wall;
        let bytes = bytes_after.saturating_sub(bytes_before);
        rows.push(Row {
            agents: count,
            seconds: wall,
            bytes,
            bytes_per_robot_per_s: bytes as f64 / (count as f64 * wall),
            recorder_cpu_share: recorder_cpu,
            robots_cpu_share: robots_cpu,
            recorder_vs_robots: recorder_cpu / robots_cpu.max(1e-9),
        });
    }
    shoal_runtime::report::print(&serde_json::json!({ "rows": rows }), json)?;
    Ok(())
}

//! A robot's range scan among robots standing around it: the time of one
//! scan as Shoal casts it (each robot against the beams that point at it),
//! against casting every beam at every robot, measured in the same run.

use std::hint::black_box;
use std::time::Instant;

use anyhow::Result;
use glam::DVec2;
use serde::Serialize;
use shoal_physics::Pose;
use shoal_physics::range::RangeSensor;
use shoal_scenario::Scenario;

#[derive(Debug, Serialize)]
struct Row {
    robots_around: usize,
    beams: usize,
    scan_us: f64,
    every_pair_us: f64,
    scan_vs_every_pair: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    rows: Vec<Row>,
}

/// Mean seconds of `scan` over `repeats` calls.
fn time_per_call(repeats: usize, mut scan: impl FnMut() -> Vec<f64>) -> f64 {
    let started = Instant::now();
    for _ in 0..repeats {
        black_box(scan());
    }
    started.elapsed().as_secs_f64() / repeats as f64
}

pub fn run(robots: &[usize], repeats: usize, json: bool) -> Result<()> {
    let scenario = Scenario::open_arena(1);
    let (arena, sensor): (_, RangeSensor) = (scenario.arena, scenario.sensor);
    let radius = scenario.agents.radius;
    let middle = arena.width / 2.0;
    let pose = Pose::new(middle, middle, 0.3);
    let mut rows = Vec::new();
    for &count in robots {
        // The formation's lattice around the robot, at its 1 m spread.
        let side = (count as f64).sqrt().ceil() as usize;
        let around: Vec<DVec2> = (0..count)
            .map(|k| {
                let (i, j) = ((k % side) as f64, (k / side) as f64);
                let offset = (side as f64 - 1.0) / 2.0;
                DVec2::new(middle + i - offset + 0.5, middle + j - offset + 0.5)
            })
            .collect();
        let scan = time_per_call(repeats, || {
            sensor.cast_exact(&arena, &pose, &around, radius)
        });
        let every_pair = time_per_call(repeats, || {
            sensor.cast_every_pair(&arena, &pose, &around, radius)
        });
        rows.push(Row {
            robots_around: count,
            beams: sensor.beams,
            scan_us: scan * 1e6,
            every_pair_us: every_pair * 1e6,
            scan_vs_every_pair: scan / every_pair,
        });
    }
    shoal_runtime::report::print(&Report { rows }, json)
}

//! How long `shoal diagnose` takes on long runs at 100 Hz, beside the time
//! to merely read the same files (the baseline, measured in the same run).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use serde::Serialize;
use shoal_diagnose::input::{commands_csv, poses_csv};
use shoal_diagnose_lab::generate::{Settings, generate};
use shoal_physics::{Effect, ScopedEffect, UnicycleModel};

#[derive(Debug, Serialize)]
struct Row {
    minutes: f64,
    command_rows: usize,
    pose_rows: usize,
    /// Reading and parsing both CSV files, the baseline.
    read_s: f64,
    /// The whole `shoal-diagnose DIR --json` process, reading included.
    diagnose_s: f64,
    diagnose_vs_read: f64,
    effects_found: usize,
}

#[derive(Debug, Serialize)]
struct Report {
    rows: Vec<Row>,
}

fn write_csvs(dir: &Path, minutes: f64) -> Result<(usize, usize)> {
    let truth = UnicycleModel::with_effects(vec![
        ScopedEffect::always(Effect::Latency { seconds: 0.12 }),
        ScopedEffect::always(Effect::HeadingDrift { rad_per_m: 0.04 }),
    ]);
    let recording = generate(
        &truth,
        &Settings {
            duration_s: minutes * 60.0,
            command_hz: 100.0,
            pose_hz: 100.0,
            ..Settings::default()
        },
    );
    std::fs::create_dir_all(dir)?;
    let (commands, poses) = recording.to_csv();
    std::fs::write(dir.join("commands.csv"), commands)?;
    std::fs::write(dir.join("poses.csv"), poses)?;
    Ok((recording.commands.t.len(), recording.poses.t.len()))
}

pub fn run(minutes: &[f64], json: bool) -> Result<()> {
    let binary = shoal_swarm::process::sibling_binary("shoal-diagnose")?;
    let mut rows = Vec::new();
    for &m in minutes {
        let dir =
            std::env::temp_dir().join(format!("shoal-bench-diagnose-{}-{m}", std::process::id()));
        let (command_rows, pose_rows) = write_csvs(&dir, m)?;

        let started = Instant::now();
        let commands = std::fs::read_to_string(dir.join("commands.csv"))?;
        let poses = std::fs::read_to_string(dir.join("poses.csv"))?;
        commands_csv(&commands, "commands.csv")?;
        poses_csv(&poses, "poses.csv")?;
        let read_s = started.elapsed().as_secs_f64();

        let started = Instant::now();
        let output = std::process::Command::new(&binary)
            .arg(&dir)
            .arg("--json")
            .output()
            .context("run shoal-diagnose")?;
        let diagnose_s = started.elapsed().as_secs_f64();
        if !output.status.success() {
            bail!(
                "shoal-diagnose failed: {}",
                String::from_utf8_lossy(&output.stderr)
            );
        }
        let value: serde_json::Value = serde_json::from_slice(&output.stdout)?;
        let _ = std::fs::remove_dir_all(&dir);
        rows.push(Row {
            minutes: m,
            command_rows,
            pose_rows,
            read_s,
            diagnose_s,
            diagnose_vs_read: diagnose_s / read_s.max(1e-9),
            effects_found: value["effects"].as_array().map_or(0, Vec::len),
        });
    }
    shoal_runtime::report::print(&Report { rows }, json)
}

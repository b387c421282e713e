//! Recordings, read back with the official Rerun tools (`pip install rerun-sdk`) and evo.

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;
use shoal_broker::{Bus, BusLimits, RosterReader, names};
use shoal_e2e::*;

/// What `tests/python/check_recording.py` finds in a recording.
fn inspect(recording: &Path) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/check_recording.py");
    let output = Command::new("python3")
        .arg(script)
        .arg(recording)
        .output()
        .expect("python3");
    assert!(
        output.status.success(),
        "the Rerun reader failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("JSON from the reader")
}

fn rerun_cli(args: &[&str]) -> std::process::Output {
    Command::new("rerun")
        .args(args)
        .output()
        .expect("the rerun CLI (pip install rerun-sdk)")
}

#[test]
fn a_recording_holds_the_swarm_as_the_robots_published_it() {
    let _turn = serial();
    let dir = scratch("record");
    let recording = dir.join("run.rrd");
    let tum = dir.join("tum");
    let swarm_name = "e2e-record";
    let mut swarm = BackgroundSwarm::start(
        swarm_name,
        &[
            "--agents",
            "12",
            "--record",
            recording.to_str().expect("utf-8"),
            "--tum",
            tum.to_str().expect("utf-8"),
        ],
    );
    // Listen to the roster ourselves, as one more observer, to know what the robots published.
    swarm.wait_alive(12, Duration::from_secs(30));
    let bus = Bus::join(
        swarm_name,
        &names::tool_node(swarm_name, "e2e-observer"),
        BusLimits::default(),
    )
    .expect("join");
    let roster = RosterReader::new(&bus).expect("roster");
    let mut published: HashMap<String, [f64; 2]> = HashMap::new();
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs(6) {
        roster
            .receive(|s| {
                published.insert(format!("{}@{}", s.agent_id, s.tick), [s.x, s.y]);
            })
            .expect("receive");
        std::thread::sleep(Duration::from_millis(20));
    }
    drop(roster);
    drop(bus);
    let (exit, said) = swarm.interrupt();
    assert!(exit.success(), "{}", said);

    let verify = rerun_cli(&["rrd", "verify", recording.to_str().expect("utf-8")]);
    assert!(
        verify.status.success(),
        "rerun rrd verify: {}",
        String::from_utf8_lossy(&verify.stderr)
    );
    let stats = rerun_cli(&["rrd", "stats", recording.to_str().expect("utf-8")]);
    assert!(
        stats.status.success(),
        "rerun rrd stats: {}",
        String::from_utf8_lossy(&stats.stderr)
    );

    let found = inspect(&recording);
    let entities: Vec<&str> = found["entities"]
        .as_array()
        .expect("entities")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    for expected in [
        "/world/arena/walls",
        "/world/arena/obstacles/discs",
        "/world/arena/surfaces",
        "/world/arena/map",
        "/world/robots/true",
        "/world/robots/believed",
        "/world/robots/heading",
        "/world/robots/trails",
        "/world/links",
        "/robots/0/health",
        "/swarm/components",
        "/events",
    ] {
        assert!(
            entities.contains(&expected),
            "{expected} missing from {entities:?}"
        );
    }
    assert_eq!(
        found["robots"].as_array().map(Vec::len),
        Some(12),
        "{}",
        found["robots"]
    );
    assert!(
        found["ticks"].as_u64().expect("ticks") >= 25,
        "only {} ticks recorded",
        found["ticks"]
    );
    // Every pose we saw on the bus that the recording also holds is identical (to f32).
    let recorded = found["poses"].as_object().expect("poses");
    let mut compared = 0;
    for (key, [x, y]) in &published {
        if let Some(position) = recorded.get(key) {
            let rx = position[0].as_f64().expect("x");
            let ry = position[1].as_f64().expect("y");
            assert!(
                (rx - x).abs() < 1e-4 && (ry - y).abs() < 1e-4,
                "{key}: recorded ({rx}, {ry}), published ({x}, {y})"
            );
            compared += 1;
        }
    }
    assert!(compared >= 100, "only {compared} poses could be compared");
    let events = found["events"].to_string();
    assert!(events.contains("joined"), "{events}");

    // The trajectories open in evo.
    let truth = tum.join("robot-0-true.tum");
    let estimate = tum.join("robot-0-estimated.tum");
    let evo = Command::new("evo_traj")
        .args([
            "tum",
            truth.to_str().expect("utf-8"),
            estimate.to_str().expect("utf-8"),
        ])
        .output()
        .expect("evo_traj (pip install evo)");
    assert!(
        evo.status.success(),
        "evo_traj: {}",
        String::from_utf8_lossy(&evo.stderr)
    );
    let ape = Command::new("evo_ape")
        .args([
            "tum",
            truth.to_str().expect("utf-8"),
            estimate.to_str().expect("utf-8"),
        ])
        .output()
        .expect("evo_ape");
    assert!(
        ape.status.success(),
        "evo_ape: {}",
        String::from_utf8_lossy(&ape.stderr)
    );
    assert!(String::from_utf8_lossy(&ape.stdout).contains("rmse"));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_recorder_killed_with_sigkill_leaves_a_readable_file() {
    let _turn = serial();
    let dir = scratch("sigkill");
    let recording = dir.join("killed.rrd");
    let mut swarm = BackgroundSwarm::start("e2e-sigkill", &["--agents", "6"]);
    swarm.wait_alive(6, Duration::from_secs(30));
    let mut recorder = Command::new(bin("shoal-viewer-log"))
        .arg(&recording)
        .args(["--swarm", &swarm.name])
        .spawn()
        .expect("start the recorder");
    std::thread::sleep(Duration::from_millis(4500));
    recorder.kill().expect("SIGKILL");
    let _ = recorder.wait();
    drop(swarm);

    let found = inspect(&recording);
    // Flushed at least every second: of 4.5 s, at least the first 3 s survive.
    let ticks = found["ticks"].as_u64().expect("ticks");
    assert!(
        ticks >= 15,
        "only {ticks} ticks survived the SIGKILL: {found}"
    );
    assert_eq!(found["robots"].as_array().map(Vec::len), Some(6));
    let _ = std::fs::remove_dir_all(dir);
}

/// Robots walk from a plain floor into mud their motion model does not know;
/// `shoal diagnose` finds the mud from the recorded run alone.
#[test]
fn a_surface_the_robots_model_lacks_is_diagnosed_from_the_recorded_run() {
    let _turn = serial();
    let dir = scratch("mud");
    let scenario = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/mud.toml");
    let run = dir.join("run");
    let output = shoal(&[
        "up",
        "--swarm",
        "e2e-mud",
        "--scenario",
        scenario.to_str().expect("utf-8"),
        "--lockstep",
        "--duration",
        "150",
        "--record",
        run.join("run.rrd").to_str().expect("utf-8"),
        "--tum",
        run.to_str().expect("utf-8"),
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let mut found_mud = Vec::new();
    for robot in 0..6 {
        let robot_dir = run.join(format!("robot-{robot}"));
        let poses = std::fs::read_to_string(robot_dir.join("poses.csv")).expect("poses.csv");
        // The lockstep clock waits for the recorder: every tick is there.
        assert!(
            poses.lines().count() >= 745,
            "robot {robot}: {} rows",
            poses.lines().count()
        );
        let output = shoal(&["diagnose", robot_dir.to_str().expect("utf-8"), "--json"]);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let d: Value = serde_json::from_slice(&output.stdout).expect("JSON");
        assert_eq!(d["mismatch"], true, "robot {robot}: {d}");
        let zone = d["effects"].as_array().expect("effects").iter().find(|e| {
            e["kind"] == "surface_zone"
                && e["where"]["region"][0]
                    .as_f64()
                    .is_some_and(|x0| (17.0..23.0).contains(&x0))
                && e["params"]["speed_factor"]
                    .as_f64()
                    .is_some_and(|f| (0.4..0.8).contains(&f))
        });
        if zone.is_some() {
            found_mud.push(robot);
        }
    }
    // The mud starts at x = 20 and shortens strides by 40%.
    assert!(
        found_mud.len() >= 4,
        "mud found for robots {found_mud:?} only"
    );
    let _ = std::fs::remove_dir_all(dir);
}

/// A SLAM process's particles, map and learned model land in the recording.
#[test]
fn a_recording_holds_what_slam_learns() {
    let _turn = serial();
    let dir = scratch("slam-record");
    let recording = dir.join("slam.rrd");
    let output = shoal(&[
        "up",
        "--swarm",
        "e2e-slam-record",
        "--agents",
        "4",
        "--duration",
        "12",
        "--slam",
        "0",
        "--record",
        recording.to_str().expect("utf-8"),
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let found = inspect(&recording);
    let rows = |entity: &str| found["slam_rows"][entity].as_u64().unwrap_or(0);
    // One particle batch per SLAM step, and at least a few dozen steps in 12 s.
    assert!(
        rows("/world/slam/0/particles") >= 20,
        "{}",
        found["slam_rows"]
    );
    // The map is logged again as it fills in.
    assert!(rows("/world/slam/0/map") >= 2, "{}", found["slam_rows"]);
    let model_entities = found["slam_rows"]
        .as_object()
        .expect("slam rows")
        .keys()
        .filter(|k| k.starts_with("/slam/0/model/"))
        .count();
    assert!(model_entities >= 3, "{}", found["slam_rows"]);
    let _ = std::fs::remove_dir_all(dir);
}

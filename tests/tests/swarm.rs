//! The swarm end to end: real `shoal-agent` processes on real iceoryx2 shared memory.

use std::time::Duration;

use serde_json::Value;
use shoal_e2e::*;

const SPREAD: f64 = 1.0;

fn up_json(args: &[&str]) -> Value {
    let output = shoal(args);
    assert!(
        output.status.success(),
        "shoal up failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("shoal up --json prints JSON")
}

#[test]
fn twelve_robots_form_one_group_at_the_desired_spacing_and_leave_nothing_behind() {
    let _turn = serial();
    let swarm = "e2e-form";
    let summary = up_json(&[
        "up",
        "--swarm",
        swarm,
        "--agents",
        "12",
        "--lockstep",
        "--duration",
        "80",
        "--json",
    ]);
    assert_eq!(summary["agents"], 12, "{summary}");
    assert_eq!(summary["components"], 1, "{summary}");
    let ratio = summary["spacing_ratio"].as_f64().expect("ratio");
    assert!(
        (ratio - 1.0).abs() <= 0.15,
        "spacing {ratio} x spread: {summary}"
    );
    assert!(summary["converge_s"].as_f64().is_some(), "{summary}");
    // In lockstep no period is missed, and a robot acts on the poses its
    // neighbours published one tick (0.2 s) before.
    assert_eq!(summary["missed_periods_max"], 0, "{summary}");
    assert_eq!(summary["neighbour_age_p50_ms"], 200, "{summary}");
    let p99 = summary["neighbour_age_p99_ms"].as_u64().expect("age p99");
    assert!((200..=400).contains(&p99), "{summary}");
    assert_eq!(residue(swarm), (0, vec![]), "nodes or services left behind");
}

#[test]
fn lockstep_runs_are_deterministic_for_a_seed() {
    let _turn = serial();
    let run = |swarm: &str, seed: &str| {
        up_json(&[
            "up",
            "--swarm",
            swarm,
            "--agents",
            "8",
            "--lockstep",
            "--duration",
            "20",
            "--seed",
            seed,
            "--json",
        ])
    };
    let first = run("e2e-det-a", "5");
    let second = run("e2e-det-b", "5");
    let other = run("e2e-det-c", "6");
    assert_eq!(
        first["spacing_ratio"], second["spacing_ratio"],
        "{first} vs {second}"
    );
    assert_eq!(first["spacing_cv"], second["spacing_cv"]);
    assert_ne!(
        first["spacing_ratio"], other["spacing_ratio"],
        "another seed, another run"
    );
}

#[test]
fn killed_robots_are_dropped_cleaned_and_restarted() {
    let _turn = serial();
    let mut swarm = BackgroundSwarm::start("e2e-heal", &["--agents", "14", "--lockstep"]);
    let formed = wait_until(Duration::from_secs(60), || {
        let s = status(&swarm.name);
        alive_ids(&s).len() == 14 && status_metrics(&s, SPREAD).components == 1
    });
    assert!(
        formed,
        "14 robots never formed one group: {}",
        status(&swarm.name)
    );

    // Two by `shoal kill`, one by kill -9 from outside: both must be handled alike.
    let before = status(&swarm.name);
    let outsider_pid = alive_agents(&before)
        .iter()
        .find(|a| a["id"] == 5)
        .and_then(|a| a["pid"].as_i64())
        .expect("pid of 5");
    let output = shoal(&["kill", "--swarm", &swarm.name, "3", "4"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    // SAFETY: plain kill(2).
    unsafe { libc::kill(outsider_pid as i32, libc::SIGKILL) };

    let healed = wait_until(Duration::from_secs(30), || {
        let s = status(&swarm.name);
        let ids = alive_ids(&s);
        let nobody_tracks_the_dead = alive_agents(&s).iter().all(|a| {
            a["neighbours"].as_array().is_some_and(|n| {
                n.iter()
                    .all(|id| ![3, 4, 5].contains(&id.as_u64().unwrap_or(0)))
            })
        });
        ids.len() == 11
            && s["agents"].as_array().is_some_and(|a| a.len() == 11)
            && s["stale_nodes"] == 0
            && nobody_tracks_the_dead
            && status_metrics(&s, SPREAD).components == 1
    });
    assert!(healed, "the swarm did not heal: {}", status(&swarm.name));

    let output = shoal(&["restart", "--swarm", &swarm.name, "3", "4", "5"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let rejoined = wait_until(Duration::from_secs(30), || {
        let s = status(&swarm.name);
        let mut ids = alive_ids(&s);
        ids.sort_unstable();
        ids == (0..14).collect::<Vec<u64>>() && alive_agents(&s).iter().all(|a| a["x"].is_number())
    });
    assert!(
        rejoined,
        "restarted robots did not rejoin: {}",
        status(&swarm.name)
    );

    let agent_pids: Vec<i32> = alive_agents(&status(&swarm.name))
        .iter()
        .filter_map(|a| a["pid"].as_i64())
        .map(|p| p as i32)
        .collect();
    let (exit, said) = swarm.interrupt();
    assert!(exit.success(), "Ctrl-C must stop cleanly: {}", said);
    assert!(
        agent_pids.iter().all(|p| !pid_alive(*p)),
        "robots outlived Ctrl-C (restarted ones too)"
    );
    assert_eq!(residue("e2e-heal"), (0, vec![]));
}

#[test]
fn robots_spawned_into_a_running_swarm_are_absorbed() {
    let _turn = serial();
    let mut swarm = BackgroundSwarm::start("e2e-spawn", &["--agents", "10", "--lockstep"]);
    swarm.wait_alive(10, Duration::from_secs(60));
    let output = shoal(&[
        "spawn",
        "--swarm",
        &swarm.name,
        "--count",
        "3",
        "--at",
        "14,14",
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let absorbed = wait_until(Duration::from_secs(60), || {
        let s = status(&swarm.name);
        alive_ids(&s).len() == 13 && status_metrics(&s, SPREAD).components == 1
    });
    assert!(
        absorbed,
        "spawned robots were not absorbed: {}",
        status(&swarm.name)
    );
}

#[test]
fn two_swarms_with_different_names_do_not_see_each_other() {
    let _turn = serial();
    let red = BackgroundSwarm::start("e2e-red", &["--agents", "6", "--lockstep"]);
    let blue = BackgroundSwarm::start("e2e-blue", &["--agents", "9", "--lockstep"]);
    let both_up = wait_until(Duration::from_secs(60), || {
        alive_ids(&status(&red.name)).len() == 6 && alive_ids(&status(&blue.name)).len() == 9
    });
    assert!(
        both_up,
        "red {} blue {}",
        status(&red.name),
        status(&blue.name)
    );
    let red_status = status(&red.name);
    let blue_status = status(&blue.name);
    let pids = |s: &Value| -> Vec<i64> {
        alive_agents(s)
            .iter()
            .filter_map(|a| a["pid"].as_i64())
            .collect()
    };
    let (red_pids, blue_pids) = (pids(&red_status), pids(&blue_status));
    assert!(red_pids.iter().all(|p| !blue_pids.contains(p)));
    // Red has ids 0..6 only, so no red robot may track one of blue's ids 6..9.
    for agent in alive_agents(&red_status) {
        for id in agent["neighbours"].as_array().expect("neighbours") {
            assert!(
                id.as_u64().expect("id") < 6,
                "red robot tracks a foreign robot: {agent}"
            );
        }
    }
    // Each robot publishes into the one cell it stands in, so a swarm's
    // cells (`status --cells`) hold its own robots' publishers and no
    // other's. A robot crossing into a new cell drops its old publisher
    // before it opens the next, so the count is asked for until it holds.
    let cells = |swarm: &str| -> Value {
        let output = shoal_ok(&["status", "--swarm", swarm, "--cells", "--json"]);
        let report: Value = serde_json::from_slice(&output.stdout).expect("status prints JSON");
        report["cells"].clone()
    };
    let publishers = |cells: &Value| -> u64 {
        cells
            .as_array()
            .map(|c| c.iter().filter_map(|c| c["publishers"].as_u64()).sum())
            .unwrap_or(0)
    };
    let counted = wait_until(Duration::from_secs(10), || {
        publishers(&cells(&red.name)) == 6 && publishers(&cells(&blue.name)) == 9
    });
    assert!(
        counted,
        "red cells {} blue cells {}",
        cells(&red.name),
        cells(&blue.name)
    );
    let red_cells = cells(&red.name);
    assert!(
        red_cells
            .as_array()
            .expect("cells")
            .iter()
            .all(|c| c["listeners"].as_u64() <= c["max_listeners"].as_u64()),
        "{red_cells}"
    );
}

#[test]
fn a_malformed_scenario_names_file_line_and_field() {
    let dir = std::env::temp_dir().join(format!("shoal-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("bad.toml");
    let cases = [
        (
            "[arena]\nwidth = 20.0\nheight = 20.0\n\n[formation]\nneighbours = \"four\"\n",
            "bad.toml:6: field `formation.neighbours`",
        ),
        (
            "[arena]\nwidth = 20.0\nheight = 20.0\n[timing]\nperiod_s = -0.2\n",
            "bad.toml:5: field `timing.period_s`",
        ),
    ];
    for (text, expected) in cases {
        std::fs::write(&path, text).expect("write");
        let scenario = path.to_str().expect("utf-8");
        let output = shoal(&[
            "up",
            "--swarm",
            "e2e-bad",
            "--scenario",
            scenario,
            "--duration",
            "1",
        ]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success());
        assert!(stderr.contains(expected), "{stderr}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn malformed_bus_samples_are_rejected_and_counted() {
    use shoal_broker::{Bus, BusLimits, CellExchange, PoseSample};
    let _turn = serial();
    let mut swarm = BackgroundSwarm::start("e2e-rogue", &["--agents", "8", "--lockstep"]);
    swarm.wait_alive(8, Duration::from_secs(60));

    // A rogue publisher writes NaN and far-away poses into the cells where the
    // robots stand and into the roster.
    let bus = Bus::join_tool(&swarm.name, "rogue", BusLimits::default()).expect("join");
    let roster = shoal_broker::roster::publisher(&bus).expect("roster");
    let s = status(&swarm.name);
    let target = alive_agents(&s)[0].clone();
    let (x, y) = (
        target["x"].as_f64().expect("x"),
        target["y"].as_f64().expect("y"),
    );
    let mut cells = CellExchange::new(shoal_broker::BusSection::default().cell_size);
    let mut bad = PoseSample::standing(999, std::process::id(), u64::MAX / 2, x, y, f64::NAN);
    for round in 0..20 {
        bad.x = if round % 2 == 0 { x } else { 1e9 };
        bad.theta = if round % 2 == 0 { f64::NAN } else { 0.0 };
        // The cell is chosen from the pose, so publish the far pose's twin into the robots' cell.
        let mut in_cell = bad;
        in_cell.x = x;
        let _ = cells.publish(&bus, &in_cell);
        roster.publish(&bad).expect("publish");
        std::thread::sleep(Duration::from_millis(50));
    }
    let flagged = wait_until(Duration::from_secs(10), || {
        let s = status(&swarm.name);
        alive_agents(&s).iter().any(|a| {
            a["health"]
                .as_u64()
                .is_some_and(|h| h & u64::from(shoal_broker::Health::REJECTED_INPUT) != 0)
        })
    });
    let s = status(&swarm.name);
    assert!(flagged, "no robot reported rejected input: {s}");
    assert_eq!(
        alive_ids(&s).len(),
        8,
        "the rogue was counted as a robot: {s}"
    );
    assert!(
        alive_agents(&s)
            .iter()
            .all(|a| a["x"].as_f64().is_some_and(f64::is_finite))
    );
    drop(cells);
    drop(roster);
    drop(bus);
}

#[test]
fn a_real_time_swarm_keeps_going_when_shoal_up_is_killed() {
    let _turn = serial();
    let mut swarm = BackgroundSwarm::start("e2e-orphans", &["--agents", "6"]);
    swarm.wait_alive(6, Duration::from_secs(30));
    // SAFETY: plain kill(2) on our child.
    unsafe { libc::kill(swarm.pid(), libc::SIGKILL) };
    let ticks = |s: &Value| -> Vec<u64> {
        alive_agents(s)
            .iter()
            .filter_map(|a| a["tick"].as_u64())
            .collect()
    };
    let before = ticks(&status(&swarm.name));
    std::thread::sleep(Duration::from_secs(2));
    let after_status = status(&swarm.name);
    let after = ticks(&after_status);
    assert_eq!(
        after.len(),
        6,
        "robots died with the launcher: {after_status}"
    );
    assert!(
        after.iter().min() > before.iter().max(),
        "robots stopped stepping: {before:?} then {after:?}"
    );
    let ids: Vec<String> = alive_ids(&after_status)
        .iter()
        .map(u64::to_string)
        .collect();
    let mut args = vec!["kill", "--graceful", "--swarm", "e2e-orphans"];
    args.extend(ids.iter().map(String::as_str));
    assert!(shoal(&args).status.success());
    assert!(wait_until(Duration::from_secs(10), || alive_ids(&status(
        "e2e-orphans"
    ))
    .is_empty()));
    let _ = std::fs::remove_dir_all(shoal_runtime::SwarmRuntime::locate("e2e-orphans").dir);
    drop(swarm);
}

#[test]
fn the_official_python_iceoryx2_client_reads_the_roster() {
    let _turn = serial();
    let mut swarm = BackgroundSwarm::start("e2e-python", &["--agents", "5"]);
    swarm.wait_alive(5, Duration::from_secs(30));
    let script = shoal_e2e::package_dir().join("python/read_roster.py");
    let output = std::process::Command::new("python3")
        .arg(script)
        .args([swarm.name.as_str(), "1.5"])
        .output()
        .expect("python3");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let read: Value = serde_json::from_slice(&output.stdout).expect("JSON");
    let robots = read["robots"].as_object().expect("robots");
    let mut ids: Vec<u64> = robots.keys().filter_map(|k| k.parse().ok()).collect();
    ids.sort_unstable();
    assert_eq!(ids, vec![0, 1, 2, 3, 4], "{read}");
    for value in robots.values() {
        let (x, y) = (value[0].as_f64().expect("x"), value[1].as_f64().expect("y"));
        assert!(
            (0.0..=20.0).contains(&x) && (0.0..=20.0).contains(&y),
            "{value}"
        );
    }
}

/// A process of the test's own, killed if the test ends early.
struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        if matches!(self.0.try_wait(), Ok(None)) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
}

/// `shoal slam` and `shoal record` started from another terminal end with
/// their swarm instead of outliving it.
#[test]
fn helpers_started_by_hand_end_with_their_swarm() {
    let _turn = serial();
    let dir = scratch("helpers-end");
    let swarm = "e2e-helpers-end";
    let mut up = BackgroundSwarm::start(swarm, &["--agents", "3", "--duration", "8"]);
    up.wait_alive(3, Duration::from_secs(30));
    let recording = dir.join("run.rrd");
    let hand_started = |args: &[&str]| {
        KillOnDrop(
            std::process::Command::new(bin("shoal"))
                .args(args)
                .stderr(std::process::Stdio::null())
                .spawn()
                .expect("start a helper"),
        )
    };
    let mut helpers = [
        hand_started(&["slam", "--swarm", swarm, "--follow", "0"]),
        hand_started(&[
            "record",
            recording.to_str().expect("utf-8"),
            "--swarm",
            swarm,
        ]),
    ];
    let (exit, said) = up.wait_end();
    assert!(exit.success(), "{said}");
    for helper in &mut helpers {
        let ended = wait_until(Duration::from_secs(10), || {
            matches!(helper.0.try_wait(), Ok(Some(_)))
        });
        assert!(ended, "a helper outlived its swarm by 10 s");
        let status = helper.0.wait().expect("wait");
        assert!(status.success(), "a helper failed: {status}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

//! Nothing a user owns is deleted, no robot dies silently, nothing outlives
//! its swarm: real `shoal` processes against real folders and shared memory.

use std::process::{Command, Stdio};
use std::time::Duration;

use shoal_e2e::*;
use shoal_runtime::pid_alive;

#[test]
fn a_swarm_named_like_a_users_folder_leaves_that_folder_alone() {
    let _turn = serial();
    let root = scratch("victim");
    let documents = root.join("Documents");
    std::fs::create_dir(&documents).expect("user folder");
    std::fs::write(documents.join("thesis.txt"), "years of work").expect("user file");
    let output = Command::new(bin("shoal"))
        .args(["up", "--swarm", "Documents", "--duration", "3"])
        .env("SHOAL_RUNTIME_DIR", &root)
        .output()
        .expect("run shoal up");
    let said = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{said}");
    assert!(said.contains("not created by Shoal"), "{said}");
    assert_eq!(
        std::fs::read_to_string(documents.join("thesis.txt"))
            .expect("the user's file is still there"),
        "years of work"
    );
    std::fs::remove_dir_all(&root).expect("cleanup");
}

#[test]
fn a_reader_that_stops_reading_ends_a_command_quietly_not_in_a_panic() {
    // `shoal status | head -1` on a large swarm: the reader has gone before
    // status writes. The pipe's reading end is closed before status starts,
    // so every write it makes fails.
    let (reader, writer) = std::io::pipe().expect("pipe");
    drop(reader);
    for args in [
        &["status", "--swarm", "nobody-reads", "--cells"][..],
        &["status", "--swarm", "nobody-reads", "--json"][..],
        &["down", "--swarm", "nobody-reads"][..],
    ] {
        let output = Command::new(bin("shoal"))
            .args(args)
            .stdout(writer.try_clone().expect("pipe"))
            .output()
            .expect("run shoal status");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

#[test]
fn robots_sent_sigterm_while_they_start_leave_no_half_made_node() {
    // A robot gets SIGTERM before it has a handler for it when `shoal up`
    // is stopped in the middle of starting many. Ended half way through
    // making its iceoryx2 node, it left files no sweep removes (10 of 400
    // robots before the signal was held back; BENCHMARKS.md, build 705c845).
    let _turn = serial();
    let swarm = BackgroundSwarm::start("e2e-sigterm-start", &["--agents", "2"]);
    let up = wait_until(Duration::from_secs(30), || {
        alive_ids(&status(&swarm.name)).len() == 2
    });
    assert!(up, "{}", swarm.log());
    let nodes = shoal_broker::bus::iceoryx_root().join("nodes");
    let entries = || -> std::collections::BTreeSet<std::ffi::OsString> {
        std::fs::read_dir(&nodes)
            .map(|dir| dir.filter_map(|e| e.ok().map(|e| e.file_name())).collect())
            .unwrap_or_default()
    };
    let before = entries();
    for (i, delay_us) in (0..100u32).map(|i| (i, (i * 7919) % 30_000)) {
        let mut robot = Command::new(bin("shoal-agent"))
            .args(["--swarm", &swarm.name, "--id", &(100 + i).to_string()])
            .args(["--at", "3,3,0"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start a robot");
        std::thread::sleep(Duration::from_micros(u64::from(delay_us)));
        // SAFETY: kill only sends a signal to the child started above.
        unsafe { libc::kill(robot.id() as i32, libc::SIGTERM) };
        robot.wait().expect("wait for the robot");
    }
    let left: Vec<_> = entries().difference(&before).cloned().collect();
    assert!(left.is_empty(), "left in {}: {left:?}", nodes.display());
}

#[test]
fn a_scenario_with_a_nan_range_is_refused_naming_file_line_and_field() {
    let dir = scratch("nan");
    let path = dir.join("nan.toml");
    std::fs::write(
        &path,
        "[arena]\nwidth = 10.0\nheight = 10.0\n[agents]\ncount = 3\nstart_region = [1.0, 1.0, 9.0, 9.0]\n[sensor]\nmax_range = nan\n",
    )
    .expect("scenario");
    let output = shoal(&[
        "up",
        "--swarm",
        "e2e-nan",
        "--scenario",
        path.to_str().expect("utf-8 path"),
        "--duration",
        "3",
    ]);
    let said = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{said}");
    assert!(
        said.contains("nan.toml:8: field `sensor.max_range`"),
        "{said}"
    );
    std::fs::remove_dir_all(&dir).expect("cleanup");
}

#[test]
fn a_robot_that_fails_is_reported_with_its_log_and_fails_the_run() {
    let _turn = serial();
    let name = "e2e-crash";
    let mut swarm = BackgroundSwarm::start(name, &["--agents", "3", "--duration", "12"]);
    swarm.wait_alive(3, Duration::from_secs(30));
    let robot = alive_agents(&status(name))
        .into_iter()
        .find(|a| a["id"] == 1)
        .map(|a| a["pid"].as_i64().expect("pid") as i32)
        .expect("robot 1");
    // Robot 1 cannot note its last pose on the way out (a folder stands
    // where its file goes), so its exit fails: a real error exit.
    let runtime = shoal_runtime::SwarmRuntime::locate(name);
    let pose = runtime.dir.join("agent-1.pose");
    let _ = std::fs::remove_file(&pose);
    std::fs::create_dir(&pose).expect("block the pose file");
    std::fs::create_dir(pose.join("keep")).expect("a non-empty folder");
    // SAFETY: plain kill(2) on a robot of this test's swarm.
    unsafe { libc::kill(robot, libc::SIGTERM) };
    let reported = wait_until(Duration::from_secs(15), || {
        swarm.log().contains("robot 1 exited with status 1")
    });
    assert!(
        reported,
        "the launcher did not report robot 1:\n{}",
        swarm.log()
    );
    let (exit, said) = swarm.wait_end();
    assert!(
        !exit.success(),
        "shoal up exited 0 after a robot failed:\n{said}"
    );
    assert!(
        said.contains("noting the last pose on the way out"),
        "no log tail:\n{said}"
    );
    let log =
        std::fs::read_to_string(runtime.dir.join("agent-1.log")).expect("the robot's log is kept");
    assert!(log.contains("noting the last pose"), "{log}");
    std::fs::remove_dir_all(&runtime.dir).expect("cleanup");
}

#[test]
fn forwarding_commands_become_the_tool_so_help_and_signals_reach_it() {
    let help = shoal(&["diagnose", "--help"]);
    let text = String::from_utf8_lossy(&help.stdout);
    assert!(help.status.success(), "{text}");
    assert!(
        text.contains("--mrclam"),
        "shoal diagnose --help is not the tool's help:\n{text}"
    );
    let _turn = serial();
    let name = "e2e-exec";
    let mut swarm = BackgroundSwarm::start(name, &["--agents", "2"]);
    swarm.wait_alive(2, Duration::from_secs(30));
    let dir = scratch("exec");
    let mut recorder = Command::new(bin("shoal"))
        .args([
            "record",
            dir.join("r.rrd").to_str().expect("utf-8"),
            "--swarm",
            name,
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start shoal record");
    let pid = recorder.id() as i32;
    let exe = wait_until(Duration::from_secs(10), || {
        std::fs::read_link(format!("/proc/{pid}/exe"))
            .is_ok_and(|p| p.file_name().is_some_and(|n| n == "shoal-viewer-log"))
    });
    assert!(exe, "the pid shoal record shows is not the recorder");
    // SAFETY: plain kill(2) on our own child.
    unsafe { libc::kill(pid, libc::SIGKILL) };
    recorder.wait().expect("reap");
    assert!(!pid_alive(pid));
    let recorders = Command::new("pgrep")
        .args(["-f", "shoal-viewer-log.*e2e-exec"])
        .output()
        .expect("pgrep");
    assert!(
        recorders.stdout.is_empty(),
        "a recorder outlived kill -9 of shoal record"
    );
    swarm.interrupt();
    std::fs::remove_dir_all(&dir).expect("cleanup");
}

#[test]
fn a_lockstep_swarm_ends_when_its_launcher_is_killed_and_shoal_down_stops_the_rest() {
    let _turn = serial();
    let name = "e2e-orphan-lockstep";
    let dir = scratch("orphan");
    let out = dir.join("r.rrd");
    let mut swarm = BackgroundSwarm::start(
        name,
        &[
            "--agents",
            "4",
            "--lockstep",
            "--slam",
            "0",
            "--record",
            out.to_str().expect("utf-8"),
        ],
    );
    swarm.wait_alive(4, Duration::from_secs(60));
    // The recorder and SLAM join the bus after the robots: wait for them.
    let mut pids: Vec<i32> = Vec::new();
    let launcher = swarm.pid();
    let all_there = wait_until(Duration::from_secs(30), || {
        pids = shoal_broker::liveness::swarm_nodes(name)
            .expect("nodes")
            .iter()
            .map(|n| n.pid)
            .filter(|p| *p != launcher)
            .collect();
        pids.len() >= 6
    });
    assert!(all_there, "robots, recorder and SLAM: {pids:?}");
    // SAFETY: plain kill(2) on our own child.
    unsafe { libc::kill(swarm.pid(), libc::SIGKILL) };
    let _ = swarm.wait_end();
    let gone = wait_until(Duration::from_secs(10), || {
        pids.iter().all(|p| !pid_alive(*p))
    });
    assert!(
        gone,
        "children outlived their lockstep launcher: {:?}",
        pids.iter().filter(|p| pid_alive(**p)).collect::<Vec<_>>()
    );
    let cleaned = shoal(&["down", "--swarm", name]);
    assert!(
        cleaned.status.success(),
        "{}",
        String::from_utf8_lossy(&cleaned.stderr)
    );
    assert_eq!(residue(name), (0, vec![]), "nodes or services left behind");

    // A real-time swarm goes on without its launcher; `shoal down` stops it.
    let name = "e2e-down";
    let mut swarm = BackgroundSwarm::start(name, &["--agents", "3"]);
    swarm.wait_alive(3, Duration::from_secs(30));
    let spawned = shoal(&["spawn", "--swarm", name]);
    assert!(
        spawned.status.success(),
        "{}",
        String::from_utf8_lossy(&spawned.stderr)
    );
    let down = shoal(&["down", "--swarm", name]);
    assert!(
        down.status.success(),
        "{}",
        String::from_utf8_lossy(&down.stderr)
    );
    let (_, said) = swarm.wait_end();
    assert!(
        wait_until(Duration::from_secs(5), || alive_agents(&status(name))
            .is_empty()),
        "robots still alive after shoal down:\n{said}"
    );
    assert_eq!(residue(name), (0, vec![]), "nodes or services left behind");
    assert!(!shoal_runtime::SwarmRuntime::locate(name).dir.exists());
    std::fs::remove_dir_all(&dir).expect("cleanup");
}

#[test]
fn a_second_launcher_of_a_running_swarm_is_refused_and_spawns_never_share_ids() {
    let _turn = serial();
    let name = "e2e-lock";
    let mut swarm = BackgroundSwarm::start(name, &["--agents", "2"]);
    swarm.wait_alive(2, Duration::from_secs(30));
    let second = shoal(&["up", "--swarm", name, "--agents", "2", "--duration", "2"]);
    let said = String::from_utf8_lossy(&second.stderr);
    assert!(!second.status.success(), "{said}");
    assert!(said.contains("already"), "{said}");
    let spawns: Vec<std::process::Child> = (0..3)
        .map(|_| {
            Command::new(bin("shoal"))
                .args(["spawn", "--swarm", name])
                .stdout(Stdio::piped())
                .spawn()
                .expect("spawn")
        })
        .collect();
    let mut ids: Vec<String> = spawns
        .into_iter()
        .map(|c| String::from_utf8_lossy(&c.wait_with_output().expect("wait").stdout).into_owned())
        .filter_map(|out| out.split_whitespace().nth(2).map(str::to_owned))
        .collect();
    ids.sort();
    ids.dedup();
    assert_eq!(ids.len(), 3, "three spawns at once picked ids {ids:?}");
    swarm.wait_alive(5, Duration::from_secs(30));
    let down = shoal(&["down", "--swarm", name]);
    assert!(
        down.status.success(),
        "{}",
        String::from_utf8_lossy(&down.stderr)
    );
    let _ = swarm.wait_end();
}

#[test]
fn an_absurd_robot_id_is_refused_at_once() {
    let started = std::time::Instant::now();
    let output = shoal(&["restart", "1000000", "--swarm", "e2e-absurd"]);
    let said = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{said}");
    assert!(said.contains("highest id"), "{said}");
    assert!(started.elapsed() < Duration::from_secs(5));
}

/// Forged clock ticks and model updates on the real bus
/// are rejected and counted; the swarm keeps stepping and no robot's pose
/// goes to infinity.
#[test]
fn forged_clock_ticks_and_model_updates_are_rejected_and_the_swarm_keeps_stepping() {
    use shoal_broker::{Bus, BusLimits, ClockSource, ClockTick, Health, ModelUpdate};
    use shoal_physics::Command as Motion;
    use shoal_physics::legged::Param;

    let _turn = serial();
    let mut swarm = BackgroundSwarm::start("e2e-forger", &["--agents", "4", "--lockstep"]);
    swarm.wait_alive(4, Duration::from_secs(60));
    let bus = Bus::join_tool(&swarm.name, "forger", BusLimits::default()).expect("join");
    let ticks = |status: &serde_json::Value| -> Vec<u64> {
        alive_agents(status)
            .iter()
            .filter_map(|a| a["tick"].as_u64())
            .collect()
    };
    let before = status(&swarm.name);
    let target = alive_ids(&before)[0] as u32;
    let clock = ClockSource::new(&bus).expect("a second clock publisher");
    let models = shoal_broker::robot_streams::model_publisher(&bus, target).expect("model stream");
    let newest = ticks(&before).into_iter().max().expect("ticks");
    let forged_ticks = [
        // Past every tick the real clock will send: robots would wait forever.
        ClockTick {
            tick: u64::MAX,
            sim_time: 1.0,
            period_s: 0.1,
        },
        // Self-consistent, but a leap no clock makes.
        ClockTick {
            tick: newest + 1_000_000_000,
            sim_time: (newest + 1_000_000_000) as f64 * 0.1,
            period_s: 0.1,
        },
        ClockTick {
            tick: newest + 1,
            sim_time: f64::NAN,
            period_s: 0.1,
        },
    ];
    for round in 0..10 {
        clock
            .tick(forged_ticks[round % forged_ticks.len()])
            .expect("forge a tick");
        for (command, _) in Motion::ALL.iter().enumerate() {
            for (param, _) in Param::ALL.iter().enumerate() {
                models
                    .publish(&ModelUpdate {
                        agent_id: target,
                        command: command as u32,
                        param: param as u32,
                        reserved: 0,
                        step: round as u64,
                        weights: [0.5, 0.5],
                        means: [1e308, -1e308],
                        variances: [1e-3, 1e-3],
                    })
                    .expect("forge a model update");
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    // Let the swarm run on a while after the forgeries.
    let moved_on = wait_until(Duration::from_secs(20), || {
        let now = status(&swarm.name);
        let now_ticks = ticks(&now);
        now_ticks.len() == 4 && now_ticks.iter().all(|t| *t > newest + 20)
    });
    let after = status(&swarm.name);
    assert!(
        moved_on,
        "the swarm stopped stepping after forged ticks: {after}\n{}",
        swarm.log()
    );
    let agents = alive_agents(&after);
    assert_eq!(agents.len(), 4, "a robot vanished: {after}");
    for agent in &agents {
        for field in ["x", "y"] {
            assert!(
                agent[field].as_f64().is_some_and(|v| v.abs() < 1e3),
                "{field} of {agent}"
            );
        }
        assert!(
            agent["health"]
                .as_u64()
                .is_some_and(|h| h & u64::from(Health::REJECTED_INPUT) != 0),
            "robot {} did not report the forgeries it rejected: {agent}",
            agent["id"]
        );
    }
    drop(models);
    drop(clock);
    drop(bus);
    let (exit, said) = swarm.interrupt();
    assert!(exit.success(), "{said}");
}

/// The chaos experiment (EXPERIMENTS.md, "Chaos") in small: kills, freezes and recorder crashes
/// on a real-time swarm leave no dead node, no crash, no lost second of
/// recording and nothing behind; the recordings open in the Rerun reader.
#[test]
fn a_swarm_under_kills_freezes_and_recorder_crashes_heals_and_leaves_nothing() {
    let _turn = serial();
    let dir = scratch("chaos");
    let output = shoal(&[
        "experiment",
        "chaos",
        "--agents",
        "12",
        "--seconds",
        "45",
        "--recorder-every",
        "15",
        "--keep",
        dir.to_str().expect("utf-8 path"),
        "--json",
    ]);
    let said = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{said}");
    let report: serde_json::Value =
        serde_json::from_slice(&output.stdout).expect("chaos prints JSON");
    assert!(report["robot_kills"].as_u64() >= Some(15), "{report}");
    assert!(report["robot_freezes"].as_u64() >= Some(2), "{report}");
    assert_eq!(report["recorder_kills"], 2, "{report}");
    for figure in report["figures"].as_array().expect("figures") {
        assert_eq!(figure["met"], true, "{figure}\n{report}\n{said}");
    }
    for segment in 0..3 {
        let rrd = dir.join(format!("recording-{segment}.rrd"));
        let content = inspect_recording(&rrd);
        assert!(
            content["ticks"].as_u64() > Some(20),
            "{}: {content}",
            rrd.display()
        );
    }
    std::fs::remove_dir_all(&dir).expect("cleanup");
}

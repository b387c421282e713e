//! Recordings, read back with the official Rerun tools (`pip install rerun-sdk`) and evo.

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;
use shoal_broker::BusLimits;
use shoal_e2e::*;

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
    let (bus, roster) =
        shoal_broker::roster::join_reader(swarm_name, "e2e-observer", BusLimits::default())
            .expect("join the bus and read the roster");
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

    let found = inspect_recording(&recording);
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
    // The motion rows diagnosis reads hold the published poses exactly, and
    // commands the robot's model can execute.
    let motion = found["motion"].as_object().expect("motion rows");
    let mut compared = 0;
    for (key, [x, y]) in &published {
        if let Some(row) = motion.get(key) {
            // Exact in the file; JSON between Python and serde_json may
            // round the last digit.
            let (rx, ry) = (row[0].as_f64().expect("x"), row[1].as_f64().expect("y"));
            assert!(
                (rx - x).abs() < 1e-12 && (ry - y).abs() < 1e-12,
                "{key}: motion row {row}, published ({x}, {y})"
            );
            let v = row[3].as_f64().expect("command_v");
            assert!(v.is_finite() && v.abs() < 2.0, "{key}: command_v {v}");
            compared += 1;
        }
    }
    assert!(
        compared >= 100,
        "only {compared} motion rows could be compared"
    );
    assert_eq!(found["period_s"].as_f64(), Some(0.2));
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

    let found = inspect_recording(&recording);
    // Flushed at least every second: of 4.5 s, at least the first 3 s survive.
    let ticks = found["ticks"].as_u64().expect("ticks");
    assert!(
        ticks >= 15,
        "only {ticks} ticks survived the SIGKILL: {found}"
    );
    assert_eq!(found["robots"].as_array().map(Vec::len), Some(6));
    let _ = std::fs::remove_dir_all(dir);
}

/// Runs `scenario` in lockstep for `seconds` as swarm `swarm`, recording
/// to `run/run.rrd` and the TUM side folder `run`; returns the recording.
fn record_lockstep(
    swarm: &str,
    scenario: &Path,
    seconds: u32,
    run: &Path,
    extra: &[&str],
) -> std::path::PathBuf {
    let recording = run.join("run.rrd");
    let seconds = seconds.to_string();
    let mut args = vec![
        "up",
        "--swarm",
        swarm,
        "--scenario",
        scenario.to_str().expect("utf-8"),
        "--lockstep",
        "--duration",
        &seconds,
        "--record",
        recording.to_str().expect("utf-8"),
        "--tum",
        run.to_str().expect("utf-8"),
    ];
    args.extend_from_slice(extra);
    shoal_ok(&args);
    recording
}

/// Whether an effect's feedback check (its JSON `feedback_free`) confirms it
/// where no command answered the noise, not only keeps it for its size.
fn confirmed_where_no_command_answered(check: &Value) -> bool {
    check["z"]
        .as_f64()
        .zip(check["z_needed"].as_f64())
        .is_some_and(|(z, needed)| z >= needed)
}

/// Robots walk from a plain floor into mud their motion model does not know;
/// `shoal diagnose run.rrd --robot N` finds the mud from the recording alone,
/// and agrees with what it finds from the TUM side folder.
#[test]
fn a_surface_the_robots_model_lacks_is_diagnosed_from_the_recording_alone() {
    let _turn = serial();
    let dir = scratch("mud");
    let scenario = shoal_e2e::package_dir().join("scenarios/mud.toml");
    let run = dir.join("run");
    let recording = record_lockstep("e2e-mud", &scenario, 150, &run, &[]);
    let diagnose = |input: &[&str]| -> Value {
        let mut args = vec!["diagnose"];
        args.extend_from_slice(input);
        args.push("--json");
        serde_json::from_slice(&shoal_ok(&args).stdout).expect("JSON")
    };
    let is_mud = |e: &Value| {
        e["kind"] == "surface_zone"
            && e["where"]["region"][0]
                .as_f64()
                .is_some_and(|x0| (17.0..23.0).contains(&x0))
            && e["params"]["speed_factor"]
                .as_f64()
                .is_some_and(|f| (0.4..0.8).contains(&f))
    };
    // A robot that spent nearly all its run in the mud cannot tell the mud
    // from a slower body: there, a speed factor of the mud's acting
    // everywhere names it too.
    let mostly_in_mud = |robot: usize| -> bool {
        let poses = numeric_rows(&run.join(format!("robot-{robot}/poses.csv")));
        let in_mud = poses.iter().filter(|p| p[1] >= 20.0).count();
        in_mud as f64 >= 0.85 * poses.len() as f64
    };
    let slower_body = |e: &Value| {
        e["kind"] == "speed_scale"
            && e["params"]["factor"]
                .as_f64()
                .is_some_and(|f| (0.4..0.8).contains(&f))
    };
    let mut found_mud = Vec::new();
    // Robots whose mud is confirmed where no command answered the noise
    // (one command period), not only kept for its size.
    let mut confirmed_short = Vec::new();
    for robot in 0..6 {
        let id = robot.to_string();
        let d = diagnose(&[recording.to_str().expect("utf-8"), "--robot", &id]);
        // The lockstep clock waits for the recorder: every tick is there.
        let segments = d["segments"].as_u64().expect("segments");
        assert!(segments >= 100, "robot {robot}: {segments} segments: {d}");
        assert_eq!(d["mismatch"], true, "robot {robot}: {d}");
        let effects = d["effects"].as_array().expect("effects");
        let names_mud = |effects: &[Value]| {
            effects.iter().any(is_mud) || (mostly_in_mud(robot) && effects.iter().any(slower_body))
        };
        if names_mud(effects) {
            found_mud.push(robot);
            let check = effects
                .iter()
                .find(|e| is_mud(e) || slower_body(e))
                .map(|e| &e["feedback_free"]);
            eprintln!("robot {robot}: the mud's short-horizon check {check:?}");
            if check.is_some_and(confirmed_where_no_command_answered) {
                confirmed_short.push(robot);
            }
        }
        // The side folder holds the same run (to the CSV's printed digits).
        let robot_dir = run.join(format!("robot-{robot}"));
        let from_csv = diagnose(&[robot_dir.to_str().expect("utf-8")]);
        assert_eq!(
            names_mud(from_csv["effects"].as_array().expect("effects")),
            names_mud(effects),
            "robot {robot}: the recording and the side folder disagree:\n{d}\n{from_csv}"
        );
    }
    // The mud starts at x = 20 and shortens strides by 40%.
    assert!(
        found_mud.len() >= 4,
        "mud found for robots {found_mud:?} only"
    );
    // Confirmed where no command answered the noise, not only kept for its
    // size: the feedback stage must not lose a gait's mud (EXPERIMENTS.md
    // 5c, "Both models scored with one noise"; measured z 2.5-7.7 on the
    // six robots, at 0.2 s or within held commands).
    assert!(
        confirmed_short.len() >= 3,
        "the mud is confirmed on one command period for robots {confirmed_short:?} only (found for {found_mud:?})"
    );
    // A robot the recording does not hold is named, with those it does.
    let missing = shoal(&[
        "diagnose",
        recording.to_str().expect("utf-8"),
        "--robot",
        "42",
    ]);
    assert!(!missing.status.success());
    let said = String::from_utf8_lossy(&missing.stderr);
    assert!(
        said.contains("no robot 42") && said.contains("holds robots 0-5"),
        "{said}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

/// Ten legged robots wander an office on a rug that lengthens their strides
/// by 20% and shortens their turns by 10%; they walk into walls, obstacles
/// and each other, held there while their commands go on. Contact is set
/// aside, reported in the text and the JSON, and the rug named. Measured
/// on this recording (deterministic but for its length, `--slam none`):
/// every robot's held-out error falls by 26-44% (robot 8's by 4% when the
/// run ends a tick early) and 9 robots name a speed scale of 1.15-1.21;
/// before contact was set aside, 8 did, and robots 0 and 9 fell by 2-3%
/// only: one stop of 0.8 s against an obstacle contradicted the speed scale
/// in the block that held it (EXPERIMENTS.md 7, "Contact set aside").
#[test]
fn robots_held_by_walls_are_set_aside_and_the_floor_named() {
    let _turn = serial();
    let dir = scratch("rug");
    let scenario = shoal_e2e::package_dir().join("scenarios/rug.toml");
    let run = dir.join("run");
    let recording = record_lockstep("e2e-rug", &scenario, 90, &run, &[]);
    let rug_speed = |e: &Value| {
        (e["kind"] == "speed_scale"
            && e["params"]["factor"]
                .as_f64()
                .is_some_and(|f| (1.1..1.3).contains(&f)))
            || (e["kind"] == "surface_zone"
                && e["params"]["speed_factor"]
                    .as_f64()
                    .is_some_and(|f| (1.1..1.3).contains(&f)))
    };
    let (mut named, mut held, mut improved) = (Vec::new(), Vec::new(), Vec::new());
    for robot in 0..10 {
        let id = robot.to_string();
        let path = recording.to_str().expect("utf-8");
        let d: Value =
            serde_json::from_slice(&shoal_ok(&["diagnose", path, "--robot", &id, "--json"]).stdout)
                .expect("JSON");
        let held_here = d["glitches"]
            .as_array()
            .expect("glitches")
            .iter()
            .filter(|g| g["kind"] == "held_in_place")
            .count();
        if held_here > 0 {
            held.push(robot);
            let text =
                String::from_utf8_lossy(&shoal_ok(&["diagnose", path, "--robot", &id]).stdout)
                    .into_owned();
            assert!(
                text.contains("held in place against the command")
                    && text.contains("of commanded travel not made"),
                "robot {robot}: {text}"
            );
        }
        let effects = d["effects"].as_array().expect("effects");
        if effects.iter().any(rug_speed) {
            named.push(robot);
        }
        let error = |model: &str| d[model]["heldout_rmse_pos_m"].as_f64().expect("rmse");
        assert!(
            error("improved") <= error("baseline"),
            "robot {robot}: held-out error {:.3} -> {:.3} m: {d}",
            error("baseline"),
            error("improved")
        );
        if error("improved") < 0.85 * error("baseline") {
            improved.push(robot);
        }
        eprintln!(
            "robot {robot}: held-out error {:.3} -> {:.3} m",
            error("baseline"),
            error("improved")
        );
    }
    assert!(
        held.len() >= 5,
        "contact set aside for robots {held:?} only"
    );
    // The lockstep run may end a tick early (the recorder's last tick), and
    // robot 8's speed scale is refused by one held-out block: its zone of
    // 121% then enters (150 -> 110 mm) or, a tick short, not (149 -> 143
    // mm). Before contact was set aside, 8 robots improved by 15%.
    assert!(
        improved.len() >= 9,
        "held-out error down by 15% for robots {improved:?} only"
    );
    assert!(
        named.len() >= 8,
        "the rug's strides named for robots {named:?} only"
    );
    let _ = std::fs::remove_dir_all(dir);
}

/// The demo's legged robots walk from carpet onto sand (strides 40% shorter)
/// a few seconds into the run, while the formation changes their commands
/// every step. Most never hold a command long enough for the held-command
/// horizon, so the sand must be confirmed on one command period; and over
/// the whole run its mismatch is diluted by the carpet before, so it must be
/// tried over the part of the run after the robot stepped on it. Measured
/// on this recording (`--slam none`, deterministic): 6 robots name it; 1
/// when nothing was tried over part of the run unless located in time
/// first, none when the feedback stage also scored each model with its
/// own noise (EXPERIMENTS.md 7, "The demo's sand").
#[test]
fn the_demos_sand_is_named_for_robots_whose_commands_change_every_step() {
    let _turn = serial();
    let dir = scratch("sand");
    let scenario = shoal_e2e::package_dir().join("../scenarios/demo.toml");
    let run = dir.join("run");
    let recording = record_lockstep("e2e-sand", &scenario, 90, &run, &["--slam", "none"]);
    // The demo's sand: x >= 12 and y >= 11.
    let on_sand = |x: f64, y: f64| x >= 12.0 && y >= 11.0;
    let first_on_sand = |robot: usize| -> Option<f64> {
        numeric_rows(&run.join(format!("robot-{robot}/poses.csv")))
            .iter()
            .find_map(|p| on_sand(p[1], p[2]).then_some(p[0]))
    };
    let sand_factor = |f: &Value| f.as_f64().is_some_and(|f| (0.45..0.75).contains(&f));
    let (mut named, mut stuck) = (Vec::new(), Vec::new());
    for robot in 0..20 {
        let id = robot.to_string();
        let output = shoal_ok(&[
            "diagnose",
            recording.to_str().expect("utf-8"),
            "--robot",
            &id,
            "--json",
        ]);
        let d: Value = serde_json::from_slice(&output.stdout).expect("JSON");
        let entered = first_on_sand(robot);
        let names_sand = |e: &Value| {
            let zone_on_sand = e["kind"] == "surface_zone"
                && sand_factor(&e["params"]["speed_factor"])
                && e["where"]["region"].as_array().is_some_and(|r| {
                    let c: Vec<f64> = r.iter().filter_map(Value::as_f64).collect();
                    c.len() == 4 && on_sand(0.5 * (c[0] + c[2]), 0.5 * (c[1] + c[3]))
                });
            // Over the part of the run after it stepped on the sand.
            let slower_since_sand = e["kind"] == "speed_scale"
                && sand_factor(&e["params"]["factor"])
                && e["where"]["t_start"]
                    .as_f64()
                    .zip(entered)
                    .is_some_and(|(start, entered)| (start - entered).abs() < 5.0);
            (zone_on_sand || slower_since_sand)
                && confirmed_where_no_command_answered(&e["feedback_free"])
        };
        let effects = d["effects"].as_array().expect("effects");
        if effects.iter().any(names_sand) {
            named.push(robot);
        }
        // A robot that walks into its neighbours at the goal and stays
        // there for the last 30 s, commanded on, is set aside as contact
        // for most of that time, however it got there.
        let (commanded, moved) = last_seconds_of(&run.join(format!("robot-{robot}")), 30.0);
        if commanded > 5.0 && moved < 0.1 {
            let held_s: f64 = d["glitches"]
                .as_array()
                .expect("glitches")
                .iter()
                .filter(|g| g["kind"] == "held_in_place")
                .filter_map(|g| Some(g["t_end"].as_f64()? - g["t_start"].as_f64()?.max(60.0)))
                .filter(|s| *s > 0.0)
                .fold(0.0, |total, s| total + s);
            stuck.push(robot);
            assert!(
                held_s > 20.0,
                "robot {robot}: commanded {commanded:.1} m over its last 30 s, moved {moved:.2} m, \
                 but only {held_s:.1} s of it set aside: {}",
                d["glitches"]
            );
        }
        eprintln!(
            "robot {robot} (on sand from {entered:?} s): {:?}",
            effects.iter().map(|e| &e["sentence"]).collect::<Vec<_>>()
        );
    }
    // Several robots walk into each other at the goal and do not move
    // whatever they are commanded: that is set aside as contact, and what
    // is left of them is too short to show the sand.
    assert!(
        named.len() >= 4,
        "the sand is named and confirmed for robots {named:?} only"
    );
    // Measured: robots 1, 2, 6 and 7.
    assert!(
        stuck.len() >= 2,
        "robots {stuck:?} only are stuck at the goal: the check above tests little"
    );
    let _ = std::fs::remove_dir_all(dir);
}

/// The rows of a CSV file Shoal wrote (`commands.csv`: t, v, omega;
/// `poses.csv`: t, x, y, theta), header skipped, every field a number.
fn numeric_rows(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .skip(1)
        .map(|l| l.split(',').filter_map(|f| f.parse().ok()).collect())
        .filter(|r: &Vec<f64>| r.len() >= 3)
        .collect()
}

/// Over the last `seconds` of a run folder (`commands.csv`, `poses.csv`):
/// the travel its commands asked (each held until the next) and how far
/// the robot is from where it stood.
fn last_seconds_of(robot: &Path, seconds: f64) -> (f64, f64) {
    let commands = numeric_rows(&robot.join("commands.csv"));
    let poses = numeric_rows(&robot.join("poses.csv"));
    let end = poses.last().expect("poses")[0];
    let from = end - seconds;
    let commanded: f64 = commands
        .windows(2)
        .map(|w| (w[1][0].min(end) - w[0][0].max(from)).max(0.0) * w[0][1].abs())
        .sum();
    let start = poses.iter().find(|p| p[0] >= from).expect("a pose");
    let last = poses.last().expect("a pose");
    (commanded, (last[1] - start[1]).hypot(last[2] - start[2]))
}

/// A SLAM process's particles, map and learned model land in the recording.
#[test]
fn a_recording_holds_what_slam_learns() {
    let _turn = serial();
    let dir = scratch("slam-record");
    let recording = dir.join("slam.rrd");
    shoal_ok(&[
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
    let found = inspect_recording(&recording);
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

/// A Rerun viewer's gRPC endpoint, played by the official `rerun` CLI saving
/// what it receives (`rerun --port P --save FILE`): it needs no display.
struct ListeningViewer {
    child: std::process::Child,
    port: u16,
}

impl ListeningViewer {
    fn start(save: &Path) -> Self {
        // A port nobody holds now; the viewer binds it a moment later.
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let child = Command::new("rerun")
            .arg(format!("--port={port}"))
            .arg("--save")
            .arg(save)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("the rerun CLI (pip install rerun-sdk)");
        let started = Instant::now();
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                started.elapsed() < Duration::from_secs(30),
                "rerun never listened on {port}"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        Self { child, port }
    }

    /// Stops the viewer as Ctrl-C would; it finishes its file.
    fn stop(mut self) {
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(self.child.id() as i32, libc::SIGINT) };
        let started = Instant::now();
        while self.child.try_wait().expect("wait").is_none() {
            if started.elapsed() > Duration::from_secs(20) {
                let _ = self.child.kill();
                panic!("rerun did not stop on SIGINT");
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// `--connect` streams the run live to a running viewer, and the `.rrd`
/// file is still written whole beside it.
#[test]
fn a_run_streams_live_to_a_viewer_and_still_writes_its_file() {
    let _turn = serial();
    let dir = scratch("live");
    let live = dir.join("live.rrd");
    let recording = dir.join("run.rrd");
    let viewer = ListeningViewer::start(&live);
    shoal_ok(&[
        "up",
        "--swarm",
        "e2e-live",
        "--agents",
        "4",
        "--duration",
        "6",
        "--record",
        recording.to_str().expect("utf-8"),
        "--connect",
        &format!("127.0.0.1:{}", viewer.port),
    ]);
    viewer.stop();
    for (what, file) in [("streamed", &live), ("written", &recording)] {
        let found = inspect_recording(file);
        assert_eq!(
            found["robots"].as_array().map(Vec::len),
            Some(4),
            "{what}: {}",
            found["robots"]
        );
        let ticks = found["ticks"].as_u64().expect("ticks");
        assert!(ticks >= 20, "{what}: only {ticks} ticks");
        assert!(
            found["motion"].as_object().is_some_and(|m| m.len() >= 80),
            "{what}: motion rows missing"
        );
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// `--viewer` without the Rerun viewer installed says what to install, and
/// starts nothing.
#[test]
fn asking_for_a_viewer_that_is_not_installed_is_a_clear_error() {
    let _turn = serial();
    let dir = scratch("no-viewer");
    let output = Command::new(bin("shoal"))
        .args([
            "up",
            "--swarm",
            "e2e-no-viewer",
            "--agents",
            "2",
            "--duration",
            "2",
            "--viewer",
        ])
        .env("PATH", &dir)
        .output()
        .expect("run shoal");
    assert!(!output.status.success());
    let said = String::from_utf8_lossy(&output.stderr);
    assert!(
        said.contains("--viewer needs the Rerun viewer") && said.contains("pip install rerun-sdk"),
        "{said}"
    );
    assert!(!said.contains("swarm `e2e-no-viewer` up"), "{said}");
    let _ = std::fs::remove_dir_all(dir);
}

/// The demo, shortened: its recording holds the swarm, SLAM's particles and
/// map, the kill and the restart, and it ends with a diagnosis.
#[test]
fn the_demo_records_slam_healing_and_a_diagnosis() {
    let _turn = serial();
    let dir = scratch("demo");
    let recording = dir.join("demo.rrd");
    let scenario = shoal_e2e::package_dir().join("../scenarios/demo.toml");
    let output = shoal_ok(&[
        "demo",
        "--swarm",
        "e2e-demo",
        "--scenario",
        scenario.to_str().expect("utf-8"),
        "--out",
        recording.to_str().expect("utf-8"),
        "--seconds",
        "30",
        "--json",
    ]);
    let summary: Value = serde_json::from_slice(&output.stdout).expect("JSON summary");
    assert_eq!(summary["robots"], 20, "{summary}");
    let killed: Vec<u64> = summary["killed"]
        .as_array()
        .expect("killed")
        .iter()
        .filter_map(Value::as_u64)
        .collect();
    assert_eq!(killed.len(), 4, "{summary}");
    assert!(
        summary["diagnoses"]
            .as_array()
            .is_some_and(|d| !d.is_empty()),
        "{summary}"
    );
    let found = inspect_recording(&recording);
    let rows = |entity: &str| found["slam_rows"][entity].as_u64().unwrap_or(0);
    for robot in [0, 1] {
        assert!(
            rows(&format!("/world/slam/{robot}/particles")) >= 10,
            "robot {robot}: {}",
            found["slam_rows"]
        );
        assert!(
            rows(&format!("/world/slam/{robot}/map")) >= 2,
            "robot {robot}: {}",
            found["slam_rows"]
        );
    }
    let events: Vec<&str> = found["events"]
        .as_array()
        .expect("events")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    for id in &killed {
        let fell = events
            .iter()
            .any(|e| e.starts_with(&format!("robot {id} (pid")) && e.contains("fell silent"));
        let back = events
            .iter()
            .any(|e| e.starts_with(&format!("robot {id} restarted")));
        assert!(
            fell && back,
            "robot {id}'s kill and restart are not in the recording's events: {events:?}"
        );
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// `--viewer` starts the `rerun` program on PATH and streams to it. Here that
/// program is the official CLI told to save what it receives (no display on a
/// test machine); the viewer outlives the swarm, as a user's window does.
#[test]
fn the_viewer_option_starts_rerun_and_streams_the_run_to_it() {
    let _turn = serial();
    let dir = scratch("viewer");
    let live = dir.join("live.rrd");
    let real = Command::new("sh")
        .args(["-c", "command -v rerun"])
        .output()
        .expect("sh");
    let real = String::from_utf8_lossy(&real.stdout).trim().to_owned();
    assert!(!real.is_empty(), "the rerun CLI (pip install rerun-sdk)");
    let bin_dir = dir.join("bin");
    std::fs::create_dir_all(&bin_dir).expect("bin folder");
    let wrapper = bin_dir.join("rerun");
    std::fs::write(
        &wrapper,
        format!(
            "#!/bin/sh\nif [ \"$1\" = --version ]; then exec {real} --version; fi\nexec {real} \"$@\" --save {}\n",
            live.display()
        ),
    )
    .expect("wrapper");
    let mut permissions = std::fs::metadata(&wrapper).expect("wrapper").permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut permissions, 0o755);
    std::fs::set_permissions(&wrapper, permissions).expect("chmod");
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let output = Command::new(bin("shoal"))
        .args([
            "up",
            "--swarm",
            "e2e-viewer",
            "--agents",
            "3",
            "--duration",
            "5",
            "--viewer",
        ])
        .env("PATH", &path)
        .output()
        .expect("run shoal");
    // The viewer is stopped as a user closes it; it then finishes its file.
    let stopped = |signal: &str| {
        Command::new("pkill")
            .args([signal, "-f", live.to_str().expect("utf-8")])
            .status()
            .is_ok_and(|s| s.success())
    };
    let started = Instant::now();
    while stopped("-INT") && started.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(500));
    }
    stopped("-KILL");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let found = inspect_recording(&live);
    assert_eq!(found["robots"].as_array().map(Vec::len), Some(3), "{found}");
    assert!(
        found["ticks"].as_u64().expect("ticks") >= 15,
        "{}",
        found["ticks"]
    );
    let _ = std::fs::remove_dir_all(dir);
}

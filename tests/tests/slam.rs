//! The SLAM process from the command line.

use shoal_e2e::*;

#[test]
fn a_model_file_with_a_negative_variance_or_bad_weights_is_rejected() {
    let dir = std::env::temp_dir().join(format!("shoal-e2e-model-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch");
    let cases = [
        (
            "negative-variance.toml",
            "[\"walk(2)\"]\nd = { weights = [0.5, 0.5], means = [0.1, 0.2], variances = [-1e-4, 1e-4] }\n\
             c = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n\
             t = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n",
            "toml:2: walk(2).d: variance 0 is -0.0001",
        ),
        (
            "weights.toml",
            "[\"turn(1)\"]\nd = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n\
             c = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n\
             t = { weights = [0.5, 0.7], means = [0.1, 0.2], variances = [1e-4, 1e-4] }\n",
            "toml:4: turn(1).t: weights sum to 1.2",
        ),
    ];
    for (name, text, expected) in cases {
        let path = dir.join(name);
        std::fs::write(&path, text).expect("write the model");
        let output = shoal(&[
            "slam",
            "--follow",
            "0",
            "--initial-model",
            path.to_str().expect("utf-8"),
        ]);
        assert!(!output.status.success(), "{name} was accepted");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            stderr.contains(name) && stderr.contains(expected),
            "{name}: {stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(dir);
}

fn followed(status: &serde_json::Value, id: u64) -> Option<serde_json::Value> {
    status["slam"]
        .as_array()?
        .iter()
        .find(|f| f["id"] == id)
        .cloned()
}

fn steps(status: &serde_json::Value, id: u64) -> u64 {
    followed(status, id)
        .and_then(|s| s["steps"].as_u64())
        .unwrap_or(0)
}

/// Killing a followed robot pauses its filter and restarting it resumes it;
/// killing the SLAM process leaves the swarm alone, and a new one resumes
/// from the live streams. `shoal status` shows it all.
#[test]
fn slam_pauses_with_its_robot_and_the_swarm_outlives_slam() {
    let _turn = serial();
    let mut swarm = BackgroundSwarm::start("e2e-slam-live", &["--agents", "5", "--slam", "0"]);
    swarm.wait_alive(5, std::time::Duration::from_secs(30));
    let name = swarm.name.clone();
    let learning = wait_until(std::time::Duration::from_secs(20), || {
        steps(&status(&name), 0) > 10
    });
    assert!(learning, "SLAM never stepped: {}", status(&name));
    let s = status(&name);
    let report = followed(&s, 0).expect("robot 0 is followed");
    let agent = s["agents"]
        .as_array()
        .and_then(|a| a.iter().find(|a| a["id"] == 0))
        .expect("robot 0");
    assert_eq!(agent["slam"]["id"], 0, "{agent}");
    assert_eq!(report["paused"], false, "{report}");
    assert!(report["model_distance"].as_f64().is_some(), "{report}");

    assert!(shoal(&["kill", "--swarm", &name, "0"]).status.success());
    let paused = wait_until(std::time::Duration::from_secs(10), || {
        followed(&status(&name), 0).is_some_and(|f| f["paused"] == true)
    });
    assert!(
        paused,
        "the filter of a killed robot did not pause: {}",
        status(&name)
    );
    assert!(shoal(&["restart", "--swarm", &name, "0"]).status.success());
    let before = steps(&status(&name), 0);
    let resumed = wait_until(std::time::Duration::from_secs(15), || {
        let s = status(&name);
        followed(&s, 0).is_some_and(|f| f["paused"] == false) && steps(&s, 0) > before + 5
    });
    assert!(resumed, "the filter did not resume: {}", status(&name));

    let slam_pid = shoal_runtime::SwarmRuntime::locate(&name)
        .read_report::<shoal_slam::report::SlamReport>()
        .expect("a readable SLAM report")
        .expect("a SLAM report")
        .pid as i32;
    // SAFETY: plain kill(2) of the SLAM process the swarm started.
    unsafe { libc::kill(slam_pid, libc::SIGKILL) };
    let ticks = |s: &serde_json::Value| -> u64 {
        alive_agents(s)
            .iter()
            .filter_map(|a| a["tick"].as_u64())
            .max()
            .unwrap_or(0)
    };
    let before = ticks(&status(&name));
    std::thread::sleep(std::time::Duration::from_secs(2));
    let after = status(&name);
    assert_eq!(alive_ids(&after).len(), 5, "{after}");
    assert!(
        ticks(&after) > before,
        "the swarm stopped with SLAM: {after}"
    );
    assert!(
        followed(&after, 0).is_none(),
        "a dead SLAM process still reports: {after}"
    );

    // The SLAM binary itself, so that killing it below leaves nothing behind.
    let mut again = std::process::Command::new(bin("shoal-slam"))
        .args(["--swarm", &name, "--follow", "0"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start shoal slam");
    let restarted = wait_until(std::time::Duration::from_secs(20), || {
        steps(&status(&name), 0) > 5
    });
    let _ = again.kill();
    let _ = again.wait();
    assert!(
        restarted,
        "a new SLAM process did not pick the robot up: {}",
        status(&name)
    );
    let (exit, said) = swarm.interrupt();
    assert!(exit.success(), "{said}");
}

/// `--slam all` follows every robot of the swarm, and a robot spawned later
/// from the moment the roster shows it; `shoal status` reports each one's
/// steps.
#[test]
fn slam_all_follows_every_robot_and_one_that_joins_later() {
    let _turn = serial();
    let mut swarm = BackgroundSwarm::start(
        "e2e-slam-all",
        &["--agents", "3", "--slam", "all", "--lockstep"],
    );
    swarm.wait_alive(3, std::time::Duration::from_secs(30));
    let name = swarm.name.clone();
    let all_stepping = |ids: &[u64]| {
        let s = status(&name);
        ids.iter().all(|&id| steps(&s, id) > 5)
    };
    assert!(
        wait_until(std::time::Duration::from_secs(30), || all_stepping(&[
            0, 1, 2
        ])),
        "SLAM did not follow every robot: {}",
        status(&name)
    );
    let spawned = shoal(&["spawn", "--swarm", &name]);
    assert!(
        spawned.status.success(),
        "{}",
        String::from_utf8_lossy(&spawned.stderr)
    );
    assert!(
        wait_until(std::time::Duration::from_secs(30), || all_stepping(&[
            0, 1, 2, 3
        ])),
        "SLAM did not follow the robot that joined: {}",
        status(&name)
    );
    // Each followed robot's step rate and lag reach `shoal status`.
    let s = status(&name);
    for id in 0..4 {
        let f = followed(&s, id).expect("followed");
        assert!(
            f["steps_per_s"].as_f64().is_some() && f["behind_s"].as_f64().is_some(),
            "robot {id}: {f}"
        );
    }
    let (exit, said) = swarm.interrupt();
    assert!(exit.success(), "{said}");
}

/// Position errors of robot 0's believed pose against its true pose, from the
/// TUM files the recorder writes.
fn belief_errors(tum: &std::path::Path) -> Vec<f64> {
    let read = |kind: &str| -> std::collections::BTreeMap<String, (f64, f64)> {
        std::fs::read_to_string(tum.join(format!("robot-0-{kind}.tum")))
            .expect("a TUM file")
            .lines()
            .filter_map(|l| {
                let v: Vec<&str> = l.split_whitespace().collect();
                Some((
                    v.first()?.to_string(),
                    (v.get(1)?.parse().ok()?, v.get(2)?.parse().ok()?),
                ))
            })
            .collect()
    };
    let (truth, believed) = (read("true"), read("estimated"));
    truth
        .iter()
        .filter_map(|(t, (x, y))| believed.get(t).map(|(bx, by)| (x - bx).hypot(y - by)))
        .collect()
}

/// A robot that adopts SLAM's estimates and learned model knows where it is
/// far better than one that only dead-reckons.
#[test]
fn a_robot_followed_by_slam_knows_where_it_is_better_than_dead_reckoning() {
    let _turn = serial();
    let scenario = shoal_e2e::package_dir().join("scenarios/room.toml");
    let dir = std::env::temp_dir().join(format!("shoal-e2e-belief-{}", std::process::id()));
    let run = |slam: bool| {
        let tum = dir.join(if slam { "slam" } else { "alone" });
        let mut args = vec![
            "up".to_owned(),
            "--swarm".into(),
            "e2e-belief".into(),
            "--scenario".into(),
            scenario.display().to_string(),
            "--lockstep".into(),
            "--duration".into(),
            "60".into(),
            "--record".into(),
            tum.join("run.rrd").display().to_string(),
            "--tum".into(),
            tum.display().to_string(),
        ];
        if slam {
            args.extend(["--slam".into(), "0".into()]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let output = shoal(&args);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        belief_errors(&tum)
    };
    let rmse = |e: &[f64]| (e.iter().map(|x| x * x).sum::<f64>() / e.len().max(1) as f64).sqrt();
    let (with_slam, alone) = (run(true), run(false));
    assert!(
        with_slam.len() >= 290 && alone.len() >= 290,
        "{} and {} poses",
        with_slam.len(),
        alone.len()
    );
    let (late_slam, late_alone) = (rmse(&with_slam[150..]), rmse(&alone[150..]));
    eprintln!(
        "believed pose, last 150 ticks: rmse {late_slam:.3} m with SLAM, {late_alone:.3} m dead reckoning"
    );
    assert!(
        late_slam < 0.15 && late_slam * 4.0 < late_alone,
        "with SLAM {late_slam:.3} m, dead reckoning {late_alone:.3} m"
    );
    let _ = std::fs::remove_dir_all(dir);
}

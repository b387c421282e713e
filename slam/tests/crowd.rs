//! The filter following one robot of the demo's crowd, in one process: the
//! robots' own steps (formation, body, range sensor) in lockstep, without
//! the bus. Robots hide most walls from each other here, which a room with
//! one robot in it never shows.

use glam::DVec2;
use shoal_agent::robot::Robot;
use shoal_physics::{MotionModel, Neighbour};
use shoal_scenario::Scenario;
use shoal_slam::filter::{Bodies, FilterConfig, Proposal};
use shoal_slam::follower::{Follower, Scan};

fn demo() -> Scenario {
    let text = include_str!("../../scenarios/demo.toml");
    Scenario::from_toml(text, "scenarios/demo.toml").expect("the demo's scenario parses")
}

struct Followed {
    /// Position error after each step, metres.
    errors: Vec<f64>,
    /// The learned full stride after each step, metres.
    strides: Vec<f64>,
}

/// Walks `count` robots of the demo for `steps` periods while a filter
/// follows robot 0 from `model` as `shoal-slam` does (the same
/// [`Follower`]): started at the announced pose of its first scan, beams
/// that end on other robots masked.
fn follow_in_crowd(count: usize, steps: usize, model: &MotionModel, seed: u64) -> Followed {
    follow_in_crowd_with(count, steps, model, seed, FilterConfig::default())
}

/// [`follow_in_crowd`] with the filter's `config` (its sensor: the demo's).
fn follow_in_crowd_with(
    count: usize,
    steps: usize,
    model: &MotionModel,
    seed: u64,
    config: FilterConfig,
) -> Followed {
    let scenario = demo();
    let starts = scenario.start_poses(0, count);
    let mut robots: Vec<Robot> = starts
        .iter()
        .enumerate()
        .map(|(i, p)| Robot::new(i as u32, *p, &scenario))
        .collect();
    let config = FilterConfig {
        sensor: scenario.sensor.clone(),
        ..config
    };
    let arena = [scenario.arena.width, scenario.arena.height];
    let mut follower = Follower::new(0, seed, model.clone(), config, arena);
    let mut bodies = Bodies::new(3);
    let (mut errors, mut strides) = (Vec::new(), Vec::new());
    for tick in 0..steps as u64 {
        let positions: Vec<DVec2> = robots.iter().map(|r| r.body.pose.position()).collect();
        let mut scan = None;
        for (i, robot) in robots.iter_mut().enumerate() {
            let sensed: Vec<Neighbour> = positions
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(j, p)| Neighbour {
                    id: j as u32,
                    position: *p,
                })
                .collect();
            let decision = robot.step(&sensed, &scenario);
            let others: Vec<DVec2> = sensed.iter().map(|n| n.position).collect();
            let ranges = robot.scan(&scenario, &others);
            if i == 0 {
                scan = Some(Scan {
                    tick,
                    sim_time: tick as f64 * scenario.timing.period_s,
                    command: Some(decision.command),
                    bumped: decision.outcome.bumped,
                    ranges,
                });
            }
        }
        for (i, robot) in robots.iter().enumerate() {
            bodies.saw(i as u32, robot.body.pose.position(), tick);
        }
        follower.announced(tick, robots[0].body.pose);
        let truth = robots[0].body.pose.position();
        follower
            .on_scans(scan.into_iter().collect(), &bodies, |step| {
                errors.push(step.report.estimate.position().distance(truth));
                strides.push(step.filter.model().full_stride());
                Ok::<(), ()>(())
            })
            .expect("the callback never fails");
    }
    assert!(follower.filter().is_some(), "the filter started");
    Followed { errors, strides }
}

#[test]
fn in_a_crowd_a_filter_started_with_short_strides_holds_the_robot_and_learns_its_stride() {
    let truth = demo().motion;
    // The model the demo starts SLAM from: strides a quarter too short.
    let short = truth.scaled(0.75, 1.0, 1.0);
    let (wrong, right) = (short.full_stride(), truth.full_stride());
    // Three seeds of the filter with its defaults; `--nocapture` prints
    // what EXPERIMENTS.md ("SLAM accuracy: a crowd, a lone robot on an
    // unseen room, the demo") reports. A beam ending on unseen ground once
    // scored as half a hit and left the robot 0.6-1.2 m off; an untempered
    // likelihood, 13 m and more.
    // The robot walks on carpet for its first 50 steps and then onto the
    // sand, where its strides are 0.6 of the carpet's: the learned stride
    // is judged against the carpet's after 50 steps, and must then move
    // towards the sand's. (Judged against the carpet's at the end, a filter
    // that learned the sand failed.)
    let sand = right * 0.6;
    for seed in 0..3 {
        let followed = follow_in_crowd(20, 150, &short, seed);
        let worst_late = followed.errors[100..].iter().copied().fold(0.0, f64::max);
        let last = followed.errors.last().copied().unwrap_or(f64::NAN);
        let (on_carpet, at_end) = (
            followed.strides[49],
            followed.strides.last().copied().unwrap_or(f64::NAN),
        );
        eprintln!(
            "seed {seed}: last {last:.2} m, worst of the last 50 steps {worst_late:.2} m; full stride {wrong:.3} -> {on_carpet:.3} m after 50 steps (carpet {right:.3}) -> {at_end:.3} m at the end (sand {sand:.3})"
        );
        // Issue 30's bar: within 0.2 m at the end. Measured 0.11, 0.01,
        // 0.11 m (worst of the last 50 steps 0.17, 0.05, 0.12 m); 0.25,
        // 0.20, 0.31 m while beams grazing a wall still erased it.
        assert!(
            last < 0.2 && worst_late < 0.3,
            "seed {seed}: position error {last:.2} m at the end, worst {worst_late:.2} m over the last 50 steps"
        );
        assert!(
            (on_carpet - right).abs() < (wrong - right).abs(),
            "seed {seed}: on the carpet the stride moved away from the truth: {wrong:.3} -> {on_carpet:.3} m (truth {right:.3})"
        );
        assert!(
            at_end < on_carpet,
            "seed {seed}: on the sand the stride did not shorten: {on_carpet:.3} -> {at_end:.3} m (sand {sand:.3})"
        );
    }
}

/// The two proposals side by side in the crowd, from the demo's short
/// strides and from the true model (EXPERIMENTS.md, "SLAM"): `cargo test
/// --release -p shoal-slam --test crowd -- --ignored --nocapture`.
#[test]
#[ignore = "an experiment: a minute of filtering"]
fn the_scan_matched_proposal_against_the_motion_models_in_a_crowd() {
    let truth = demo().motion;
    for (start, model) in [
        ("short strides", truth.scaled(0.75, 1.0, 1.0)),
        ("true model", truth.clone()),
    ] {
        for (proposal, particles) in [
            (Proposal::Motion, 500),
            (Proposal::ScanMatched, 100),
            (Proposal::ScanMatched, 50),
            (Proposal::ScanMatched, 30),
        ] {
            let ends: Vec<String> = (0..3)
                .map(|seed| {
                    let config = FilterConfig {
                        particles,
                        proposal,
                        ..FilterConfig::default()
                    };
                    let followed = follow_in_crowd_with(20, 150, &model, seed, config);
                    format!("{:.2}", followed.errors.last().copied().unwrap_or(f64::NAN))
                })
                .collect();
            eprintln!(
                "{start}, {proposal:?}, {particles} particles: position error after 150 steps {} m (seeds 0-2)",
                ends.join(" / ")
            );
        }
    }
}

/// EXPERIMENTS.md 8b's ten-seed figures: the default filter (50
/// scan-matched particles) against 500 drawn from the motion model, from
/// the demo's short strides, on seeds 0-9 and 10-19: `cargo test --release
/// -p shoal-slam --test crowd -- --ignored --nocapture ten_seeds`.
#[test]
#[ignore = "an experiment: two minutes of filtering"]
fn ten_seeds_of_the_default_against_500_drawn_from_the_model() {
    let short = demo().motion.scaled(0.75, 1.0, 1.0);
    for config in [
        FilterConfig::default(),
        FilterConfig {
            particles: 500,
            proposal: Proposal::Motion,
            ..FilterConfig::default()
        },
    ] {
        for first in [0, 10] {
            let ends: Vec<f64> = (first..first + 10)
                .map(|seed| {
                    let followed = follow_in_crowd_with(20, 150, &short, seed, config.clone());
                    followed.errors.last().copied().unwrap_or(f64::NAN)
                })
                .collect();
            eprintln!(
                "{:?}, {} particles, seeds {first}-{}: error after 150 steps mean {:.3} m, worst {:.3} m",
                config.proposal,
                config.particles,
                first + 9,
                ends.iter().sum::<f64>() / ends.len() as f64,
                ends.iter().copied().fold(0.0, f64::max)
            );
        }
    }
}

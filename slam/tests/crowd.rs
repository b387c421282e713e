//! The filter following one robot of the demo's crowd, in one process: the
//! robots' own steps (formation, body, range sensor) in lockstep, without
//! the bus. Robots hide most walls from each other here, which a room with
//! one robot in it never shows.

use std::collections::VecDeque;

use glam::DVec2;
use shoal_agent::robot::Robot;
use shoal_physics::{MotionModel, Neighbour};
use shoal_scenario::Scenario;
use shoal_slam::filter::{Bodies, FilterConfig, Proposal};
use shoal_slam::follower::{FirstLooks, Follower, Scan, Stepped};

fn demo() -> Scenario {
    let text = include_str!("../../scenarios/demo.toml");
    Scenario::from_toml(text, "scenarios/demo.toml").expect("the demo's scenario parses")
}

/// Which of the crowd's robots a run follows through every step.
#[derive(Clone, Copy, PartialEq)]
enum Judged {
    /// Robot 0 only; every other filter only starts, to share its first
    /// scan (what robot 0's filter gets from `shoal-slam --follow all`).
    RobotZero,
    Every,
}

struct Followed {
    /// Each judged robot's position error after each step, metres.
    errors: Vec<Vec<f64>>,
    /// The tick of each of `errors`' steps.
    error_ticks: Vec<Vec<u64>>,
    /// Each judged robot's learned full stride after each step, metres.
    strides: Vec<Vec<f64>>,
    /// The particles each filter held at the end.
    particles: Vec<usize>,
    /// Particle-beam evaluations over every judged robot's steps: the work.
    beam_evaluations: usize,
    /// Steps matched again from turns the model does not reach.
    rematched: usize,
}

/// The mean of `values` (NaN if there are none).
fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// The last `steps` of `series`.
fn last(series: &[f64], steps: usize) -> &[f64] {
    &series[series.len().saturating_sub(steps)..]
}

impl Followed {
    /// Notes judged robot `i`'s step, its estimate held against `truth`,
    /// where the robot stood at the step's tick.
    fn record(&mut self, i: usize, step: &Stepped<'_>, truth: DVec2) {
        self.errors[i].push(step.report.estimate.position().distance(truth));
        self.error_ticks[i].push(step.tick);
        self.strides[i].push(step.filter.model().full_stride());
        self.beam_evaluations += step.report.beam_evaluations;
        self.rematched += usize::from(step.report.rematched);
    }

    /// The mean over the judged robots of `of` each robot's series.
    fn mean(series: &[Vec<f64>], of: impl Fn(&[f64]) -> f64) -> f64 {
        series.iter().map(|s| of(s)).sum::<f64>() / series.len() as f64
    }

    /// Mean position error over the first `steps` steps, over the robots.
    fn error_over_first(&self, steps: usize) -> f64 {
        Self::mean(&self.errors, |e| mean(&e[..steps.min(e.len())]))
    }

    /// Mean position error over the last `steps` steps, over the robots.
    fn error_over_last(&self, steps: usize) -> f64 {
        Self::mean(&self.errors, |e| mean(last(e, steps)))
    }

    /// The worst robot's mean position error over the last `steps` steps.
    fn worst_over_last(&self, steps: usize) -> f64 {
        self.errors
            .iter()
            .map(|e| mean(last(e, steps)))
            .fold(0.0, f64::max)
    }

    /// Mean position error over the steps of ticks `from..` (steps that
    /// were scored), over the robots, and the worst robot's.
    fn error_from_tick(&self, from: u64) -> (f64, f64) {
        let per_robot: Vec<f64> = self
            .errors
            .iter()
            .zip(&self.error_ticks)
            .map(|(e, t)| {
                let late: Vec<f64> = e
                    .iter()
                    .zip(t)
                    .filter(|(_, t)| **t >= from)
                    .map(|(e, _)| *e)
                    .collect();
                mean(&late)
            })
            .collect();
        (
            mean(&per_robot),
            per_robot.iter().copied().fold(0.0, f64::max),
        )
    }

    fn error_at_end(&self) -> f64 {
        Self::mean(&self.errors, |e| e.last().copied().unwrap_or(f64::NAN))
    }

    fn stride_after(&self, step: usize) -> f64 {
        Self::mean(&self.strides, |s| s[step.min(s.len() - 1)])
    }
}

/// One run of the crowd: the demo's robots walked for `steps` periods.
struct Crowd {
    steps: usize,
    /// Robot `i`'s filter draws from `seed + i`.
    seed: u64,
    /// The filters' setup (their sensor: the demo's).
    config: FilterConfig,
    judged: Judged,
    /// Whether the filters share their robots' first scans, as
    /// `shoal-slam` does; not sharing, each keeps its own robot's look.
    share: bool,
    /// Whether the demo's tile and sand carry as its carpet does: one
    /// floor, which a model learned anywhere holds everywhere.
    one_floor: bool,
    /// Each judged filter scores one scan in this many and coasts through
    /// the others' commands (`Follower::coast`), as `shoal-slam` does on a
    /// machine too slow to score every scan: 1 scores them all.
    scored_every: u64,
    /// A machine that gives SLAM this many particle-beam evaluations per
    /// robot and tick: each tick adds them to a budget, and the filters
    /// step their waiting scans in turn, as `shoal-slam` does (one scan
    /// per robot per pass, `Follower::catch_up` first), while it lasts.
    /// Mapping is not counted, so a filter that sheds particles saves a
    /// little more than the budget credits it with. None: every scan is
    /// stepped as it comes.
    evaluations_per_tick: Option<f64>,
}

impl Crowd {
    /// `steps` periods on `seed`, the filters as `shoal-slam` runs them.
    fn new(steps: usize, seed: u64, judged: Judged) -> Self {
        Self {
            steps,
            seed,
            config: FilterConfig::default(),
            judged,
            share: true,
            one_floor: false,
            scored_every: 1,
            evaluations_per_tick: None,
        }
    }
}

/// Walks the demo's robots through `crowd` while filters follow them from
/// `model` as `shoal-slam` does (the same [`Follower`]): each started at
/// the announced pose of its first scan, mapping the other robots' first
/// scans, beams that end on other robots masked.
fn follow_in_crowd(model: &MotionModel, crowd: Crowd) -> Followed {
    let Crowd {
        steps,
        seed,
        config,
        judged,
        share,
        one_floor,
        scored_every,
        evaluations_per_tick,
    } = crowd;
    let mut scenario = demo();
    if one_floor {
        for surface in &mut scenario.arena.surfaces {
            (
                surface.along_scale,
                surface.across_scale,
                surface.turn_scale,
            ) = (1.0, 1.0, 1.0);
        }
    }
    let count = scenario.agents.count;
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
    let mut followers: Vec<Follower> = (0..count)
        .map(|i| {
            Follower::new(
                i as u32,
                seed + i as u64,
                model.clone(),
                config.clone(),
                arena,
            )
        })
        .collect();
    let mut looks: Vec<FirstLooks> = (0..count).map(|_| FirstLooks::default()).collect();
    let mut bodies = Bodies::new(3);
    let judged_count = if judged == Judged::Every { count } else { 1 };
    let mut followed = Followed {
        errors: vec![Vec::new(); judged_count],
        error_ticks: vec![Vec::new(); judged_count],
        strides: vec![Vec::new(); judged_count],
        beam_evaluations: 0,
        rematched: 0,
        particles: Vec::new(),
    };
    // With a machine short of time: each robot's waiting scans, where each
    // stood by tick (a scan is judged against its own tick), the budget
    // left and whose turn it is.
    let mut pending: Vec<VecDeque<Scan>> = (0..count).map(|_| VecDeque::new()).collect();
    let mut stood: Vec<Vec<DVec2>> = vec![Vec::new(); count];
    let (mut budget, mut turn) = (0.0, 0);
    for tick in 0..steps as u64 {
        // Each robot scans after its step with the others where they stood
        // before it, as a robot that last heard of them a tick ago.
        let positions: Vec<DVec2> = robots.iter().map(|r| r.body.pose.position()).collect();
        let mut scans = Vec::new();
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
            scans.push(Scan {
                tick,
                sim_time: tick as f64 * scenario.timing.period_s,
                command: Some(decision.command),
                bumped: decision.outcome.bumped,
                ranges,
            });
        }
        for (i, robot) in robots.iter().enumerate() {
            bodies.saw(i as u32, robot.body.pose.position(), tick);
        }
        if let Some(per_robot) = evaluations_per_tick {
            assert!(
                judged == Judged::Every,
                "a slow machine follows every robot"
            );
            for (i, scan) in scans.into_iter().enumerate() {
                followers[i].announced(tick, robots[i].body.pose);
                stood[i].push(robots[i].body.pose.position());
                pending[i].push_back(scan);
            }
            budget += per_robot * count as f64;
            // One scan per robot in turn while the budget lasts; a filter
            // that has not started starts at once (it costs no scoring).
            let mut idle = 0;
            while budget > 0.0 && idle < count {
                let i = turn;
                turn = (turn + 1) % count;
                let follower = &mut followers[i];
                follower.catch_up(&mut pending[i]);
                let Some(scan) = pending[i].pop_front() else {
                    idle += 1;
                    continue;
                };
                idle = 0;
                let truth = stood[i][scan.tick as usize];
                follower
                    .on_scans(vec![scan], &bodies, &mut looks[0], |step| {
                        followed.record(i, &step, truth);
                        budget -= step.report.beam_evaluations as f64;
                        Ok::<(), ()>(())
                    })
                    .expect("the callback never fails");
            }
            // Time unused is not saved up.
            budget = budget.min(0.0);
            continue;
        }
        for (i, scan) in scans.into_iter().enumerate() {
            if i >= judged_count && followers[i].filter().is_some() {
                continue;
            }
            let follower = &mut followers[i];
            follower.announced(tick, robots[i].body.pose);
            let truth = robots[i].body.pose.position();
            if !tick.is_multiple_of(scored_every) && follower.coast(&scan) {
                continue;
            }
            // Not sharing, each filter keeps its own robot's look to itself.
            let looks = &mut looks[if share { 0 } else { i }];
            follower
                .on_scans(vec![scan], &bodies, looks, |step| {
                    followed.record(i, &step, truth);
                    Ok::<(), ()>(())
                })
                .expect("the callback never fails");
        }
    }
    assert!(
        followers.iter().all(|f| f.filter().is_some()),
        "every filter started"
    );
    followed.particles = followers
        .iter()
        .filter_map(|f| f.filter().map(|f| f.particle_count()))
        .collect();
    followed
}

#[test]
fn in_a_crowd_filters_started_with_short_strides_hold_every_robot_and_learn_its_stride() {
    let truth = demo().motion;
    // The model the demo starts SLAM from: strides a quarter too short.
    let short = truth.scaled(0.75, 1.0, 1.0);
    let (wrong, right) = (short.full_stride(), truth.full_stride());
    // Every robot of the demo followed, as `shoal demo` does, on three
    // seeds of the filters with their defaults; `--nocapture` prints what
    // EXPERIMENTS.md 8b reports. The robots walk on carpet for their first
    // 50 steps and then onto the sand, where strides are 0.6 of the
    // carpet's: the learned stride is judged against the carpet's after 50
    // steps, and must then move towards the sand's.
    let sand = right * 0.6;
    for seed in 0..3 {
        let followed = follow_in_crowd(&short, Crowd::new(150, seed, Judged::Every));
        let (late, last) = (followed.error_over_last(50), followed.error_at_end());
        let (on_carpet, at_end) = (followed.stride_after(49), followed.stride_after(149));
        eprintln!(
            "seed {seed}: mean over 20 robots: error over the last 50 steps {late:.3} m, at the end {last:.3} m; full stride {wrong:.3} -> {on_carpet:.3} m after 50 steps (carpet {right:.3}) -> {at_end:.3} m at the end (sand {sand:.3}); {} steps matched again",
            followed.rematched
        );
        // Issue 30's bar: within 0.2 m at the end, now over every robot
        // (this test judged robot 0 alone until the filters shared their
        // robots' first scans). Measured 0.146, 0.179, 0.138 m at the end
        // and 0.136, 0.165, 0.135 m over the last 50 steps.
        assert!(
            last < 0.2 && late < 0.2,
            "seed {seed}: mean position error {last:.3} m at the end, {late:.3} m over the last 50 steps"
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

/// The two proposals side by side in the crowd, following robot 0 from
/// the demo's short strides and from the true model (EXPERIMENTS.md 8b):
/// `cargo test --release -p shoal-slam --test crowd -- --ignored
/// --nocapture proposal`.
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
                    let followed = follow_in_crowd(
                        &model,
                        Crowd {
                            config,
                            ..Crowd::new(150, seed, Judged::RobotZero)
                        },
                    );
                    format!("{:.2}", followed.error_at_end())
                })
                .collect();
            eprintln!(
                "{start}, {proposal:?}, {particles} particles: robot 0's position error after 150 steps {} m (seeds 0-2)",
                ends.join(" / ")
            );
        }
    }
}

/// EXPERIMENTS.md 8b's ten-seed figures: the default filter (50
/// scan-matched particles) against 500 drawn from the motion model, from
/// the demo's short strides, following robot 0 on seeds 0-9 and 10-19:
/// `cargo test --release -p shoal-slam --test crowd -- --ignored
/// --nocapture ten_seeds`.
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
                    follow_in_crowd(
                        &short,
                        Crowd {
                            config: config.clone(),
                            ..Crowd::new(150, seed, Judged::RobotZero)
                        },
                    )
                    .error_at_end()
                })
                .collect();
            eprintln!(
                "{:?}, {} particles, seeds {first}-{}: robot 0's error after 150 steps mean {:.3} m, worst {:.3} m",
                config.proposal,
                config.particles,
                first + 9,
                ends.iter().sum::<f64>() / ends.len() as f64,
                ends.iter().copied().fold(0.0, f64::max)
            );
        }
    }
}

/// The demo offline on cells half as wide (`shoal-slam --grid 0.025`),
/// which hold a lone robot in a small room closer (EXPERIMENTS.md 8b):
/// `cargo test --release -p shoal-slam --test crowd -- --ignored
/// --nocapture finer_grid`.
#[test]
#[ignore = "an experiment: three minutes of filtering"]
fn the_demo_offline_on_a_finer_grid() {
    let short = demo().motion.scaled(0.75, 1.0, 1.0);
    for seed in [0, 100] {
        let started = std::time::Instant::now();
        let followed = follow_in_crowd(
            &short,
            Crowd {
                config: FilterConfig {
                    cell_size: Some(0.025),
                    ..FilterConfig::default()
                },
                ..Crowd::new(450, seed, Judged::Every)
            },
        );
        eprintln!(
            "2.5 cm cells, seed {seed}: {:.1} s; mean over 20 robots, first 10 s {:.3} m, last 10 s {:.3} m, worst robot over the last 10 s {:.3} m",
            started.elapsed().as_secs_f64(),
            followed.error_over_first(50),
            followed.error_over_last(50),
            followed.worst_over_last(50),
        );
    }
}

/// The demo offline: its 20 robots for its 90 s (450 steps), every one
/// followed, each filter mapping the others' first scans or not
/// (EXPERIMENTS.md 8b): `cargo test --release -p shoal-slam --test crowd
/// -- --ignored --nocapture the_demo`.
#[test]
#[ignore = "an experiment: three minutes of filtering"]
fn the_demo_offline_with_and_without_the_first_scans_shared() {
    let short = demo().motion.scaled(0.75, 1.0, 1.0);
    for share in [false, true] {
        for seed in [0, 100] {
            let started = std::time::Instant::now();
            let followed = follow_in_crowd(
                &short,
                Crowd {
                    share,
                    ..Crowd::new(450, seed, Judged::Every)
                },
            );
            // Its cost beside its accuracy (BENCHMARKS.md 4): the work,
            // and the time on this machine's cores.
            let seconds = started.elapsed().as_secs_f64();
            eprintln!(
                "first scans shared: {share}, seed {seed}: {:.0} M particle-beam evaluations in {seconds:.1} s",
                followed.beam_evaluations as f64 / 1e6
            );
            eprintln!(
                "first scans shared: {share}, seed {seed}: mean over 20 robots, first 10 s {:.3} m, last 10 s {:.3} m, worst robot over the last 10 s {:.3} m; {} steps matched again",
                followed.error_over_first(50),
                followed.error_over_last(50),
                followed.worst_over_last(50),
                followed.rematched,
            );
        }
    }
}

/// What the demo's error offline is made of (EXPERIMENTS.md 8b): the demo
/// as it runs (filters started from strides a quarter short, robots
/// walking from the carpet onto tile and sand), the filters started from
/// the carpet's true model, and the true model on one floor (no surface
/// for the model to learn anew): `cargo test --release -p shoal-slam
/// --test crowd -- --ignored --nocapture made_of`.
#[test]
#[ignore = "an experiment: nine minutes of filtering"]
fn what_the_demos_error_is_made_of() {
    let truth = demo().motion;
    for (label, model, one_floor) in [
        (
            "as the demo (strides a quarter short, three floors)",
            truth.scaled(0.75, 1.0, 1.0),
            false,
        ),
        (
            "the carpet's true model, three floors",
            truth.clone(),
            false,
        ),
        ("the true model, one floor", truth.clone(), true),
    ] {
        let runs: Vec<Followed> = [0, 100, 1, 2]
            .into_iter()
            .map(|seed| {
                follow_in_crowd(
                    &model,
                    Crowd {
                        one_floor,
                        ..Crowd::new(450, seed, Judged::Every)
                    },
                )
            })
            .collect();
        let late: Vec<f64> = runs.iter().map(|r| r.error_over_last(50)).collect();
        let listed = |values: &[f64], digits: usize| -> String {
            let texts: Vec<String> = values.iter().map(|v| format!("{v:.digits$}")).collect();
            texts.join(", ")
        };
        let worst: Vec<f64> = runs.iter().map(|r| r.worst_over_last(50)).collect();
        eprintln!(
            "{label}: seeds 0, 100, 1, 2: mean over 20 robots over the last 10 s {} m (their mean {:.3} m); worst robot {} m",
            listed(&late, 3),
            mean(&late),
            listed(&worst, 2),
        );
    }
}

/// Resampling at other shares of the effective sample size than GMapping's
/// half, on the four seeds of [`what_the_demos_error_is_made_of`] (whose
/// first row is the half's): `cargo test --release -p shoal-slam --test
/// crowd -- --ignored --nocapture resampling`.
#[test]
#[ignore = "an experiment: twelve minutes of filtering"]
fn resampling_below_a_quarter_and_three_quarters() {
    let short = demo().motion.scaled(0.75, 1.0, 1.0);
    for resample_below in [0.25, 0.75] {
        let late: Vec<f64> = [0, 100, 1, 2]
            .into_iter()
            .map(|seed| {
                let crowd = Crowd {
                    config: FilterConfig {
                        resample_below,
                        ..FilterConfig::default()
                    },
                    ..Crowd::new(450, seed, Judged::Every)
                };
                follow_in_crowd(&short, crowd).error_over_last(50)
            })
            .collect();
        eprintln!(
            "resampling below {resample_below} of the particles: seeds 0, 100, 1, 2: mean over 20 robots over the last 10 s {late:.3?} m (their mean {:.3} m)",
            mean(&late)
        );
    }
}

/// What a filter short of time should give up (EXPERIMENTS.md 10), on the
/// demo offline: scans (one in two or three scored, the rest coasted
/// through, as `shoal-slam` catching up does) against particles or beams
/// (every scan scored by a cheaper filter): `cargo test --release -p
/// shoal-slam --test crowd -- --ignored --nocapture give_up`.
#[test]
#[ignore = "an experiment: twelve minutes of filtering"]
fn what_a_filter_short_of_time_should_give_up() {
    let short = demo().motion.scaled(0.75, 1.0, 1.0);
    let default = FilterConfig::default();
    let cheaper = |particles, score_stride| FilterConfig {
        particles,
        score_stride,
        ..default.clone()
    };
    for (label, config, scored_every) in [
        ("50 particles, every scan", default.clone(), 1),
        ("50 particles, one scan in 2", default.clone(), 2),
        ("50 particles, one scan in 3", default.clone(), 3),
        ("25 particles", cheaper(25, 2), 1),
        ("every 4th beam scored", cheaper(50, 4), 1),
        ("15 particles", cheaper(15, 2), 1),
        ("25 particles, every 4th beam scored", cheaper(25, 4), 1),
    ] {
        for seed in [0, 100] {
            let started = std::time::Instant::now();
            let followed = follow_in_crowd(
                &short,
                Crowd {
                    config: config.clone(),
                    scored_every,
                    ..Crowd::new(450, seed, Judged::Every)
                },
            );
            // The last 10 s hold 50 ticks, of which one in k was scored.
            let last_10_s = (50 / scored_every) as usize;
            eprintln!(
                "{label}, seed {seed}: mean over 20 robots, first 10 s {:.3} m, last 10 s {:.3} m, worst robot over the last 10 s {:.3} m; stride at the end {:.3} m; {:.0} M particle-beam evaluations in {:.1} s",
                followed.error_over_first(last_10_s),
                followed.error_over_last(last_10_s),
                followed.worst_over_last(last_10_s),
                followed.stride_after(usize::MAX),
                followed.beam_evaluations as f64 / 1e6,
                started.elapsed().as_secs_f64(),
            );
        }
    }
}

/// The demo offline on a machine that gives SLAM part of the work its
/// filters need at full strength (EXPERIMENTS.md 10), the filters stepping
/// their waiting scans in turn as `shoal-slam` does: shedding particles
/// first, coasting through scans when that is not enough, against coasting
/// alone. `cargo test --release -p shoal-slam --test crowd -- --ignored
/// --nocapture --exact the_demo_offline_on_a_machine_short_of_time`.
#[test]
#[ignore = "an experiment: nine minutes of filtering"]
fn the_demo_offline_on_a_machine_short_of_time() {
    let short = demo().motion.scaled(0.75, 1.0, 1.0);
    let default = FilterConfig::default();
    for seed in [0, 100] {
        // What a step costs the filters at full strength, on this seed:
        // the machine's share is of that.
        let full = follow_in_crowd(&short, Crowd::new(450, seed, Judged::Every));
        let full_step = full.beam_evaluations as f64 / (20 * 450) as f64;
        let (late, worst) = full.error_from_tick(400);
        eprintln!(
            "full strength, seed {seed}: mean over 20 robots over the last 10 s {late:.3} m, worst robot {worst:.3} m; {full_step:.0} particle-beam evaluations a step"
        );
        for share in [0.5, 0.3] {
            for (label, fewest) in [
                ("coasting alone", default.particles),
                ("shedding particles", 10),
            ] {
                let started = std::time::Instant::now();
                let followed = follow_in_crowd(
                    &short,
                    Crowd {
                        evaluations_per_tick: Some(share * full_step),
                        config: FilterConfig {
                            fewest_particles: Some(fewest),
                            ..default.clone()
                        },
                        ..Crowd::new(450, seed, Judged::Every)
                    },
                );
                let (late, worst) = followed.error_from_tick(400);
                let steps: usize = followed.errors.iter().map(Vec::len).sum();
                eprintln!(
                    "share {share}, {label}, seed {seed}: mean over 20 robots over the last 10 s {late:.3} m, worst robot {worst:.3} m; {steps} of {} scans scored; particles at the end {:?}; stride at the end {:.3} m; {:.1} s",
                    20 * 450,
                    followed.particles,
                    followed.stride_after(usize::MAX),
                    started.elapsed().as_secs_f64(),
                );
            }
        }
    }
}

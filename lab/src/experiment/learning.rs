//! Online motion-model learning (thesis IV.E): a real robot process wanders
//! a small room in lockstep while a real `shoal-slam` process follows it;
//! every case runs with learning on and off and is scored against the truth.

use std::collections::BTreeMap;

use anyhow::{Context, Result};
use glam::DVec2;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use shoal_broker::BusLimits;
use shoal_broker::SlamMap;
use shoal_broker::robot_streams;
use shoal_physics::legged::Param;
use shoal_physics::{Command, MotionModel, Pose, Surface, wrap_angle};
use shoal_scenario::Scenario;
use shoal_slam::metrics::{CoarseMap, map_error};

use super::swarm_name;
use shoal_swarm::RunningSwarm;

/// The commands a wandering robot uses, where the learned model is scored.
const USED: [Command; 4] = [
    Command::Walk(2),
    Command::Turn(2),
    Command::Turn(1),
    Command::Turn(-1),
];
/// Errors under this keep a robot localised (the "fewest particles" threshold).
const POSE_THRESHOLD_M: f64 = 0.10;

#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Scores {
    pub pos_rmse_m: f64,
    pub theta_rmse_rad: f64,
    /// Share of the observed map cells classified wrongly.
    pub map_error: Option<f64>,
    /// Mean shift of the learned model's means from the body's true ones,
    /// in true standard deviations, over the commands the robot used.
    pub param_error: f64,
}

#[derive(Debug, Serialize)]
pub struct Case {
    pub name: String,
    pub particles: usize,
    pub runs: usize,
    pub learning: Scores,
    pub no_learning: Scores,
    /// Case-specific numbers (spread of perturbed models, fewest particles).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub details: BTreeMap<String, f64>,
}

#[derive(Debug, Serialize)]
pub struct Report {
    pub cases: Vec<Case>,
}

/// One SLAM run: what it scored and the model it ended with.
struct Outcome {
    scores: Scores,
    learned: MotionModel,
}

/// The room of the SLAM tests with its wandering robot, seeded.
fn room(seed: u64) -> Scenario {
    let mut scenario = Scenario::room();
    scenario.agents.seed = seed;
    scenario
}

/// A floor covering the room from `from_s` seconds, scaling strides and turns.
fn floor(along: f64, turn: f64, from_s: f64) -> Surface {
    Surface {
        name: "changed-floor".into(),
        region: [0.0, 0.0, 3.0, 4.0],
        along_scale: along,
        across_scale: along,
        turn_scale: turn,
        from_s,
    }
}

/// The motion the body truly makes on `surface` (or on the base floor).
fn true_model(base: &MotionModel, surface: Option<&Surface>) -> MotionModel {
    surface.map_or_else(
        || base.clone(),
        |s| base.scaled(s.along_scale, s.across_scale, s.turn_scale),
    )
}

/// Position and heading RMSE of the estimates of ticks `1..=ticks` against
/// the truth, and how many were compared (NaN where none were).
fn rmse(
    estimated: &BTreeMap<u64, Pose>,
    truth: &BTreeMap<u64, Pose>,
    ticks: u64,
) -> (f64, f64, f64) {
    let (mut pos, mut theta, mut n) = (0.0, 0.0, 0.0);
    for (tick, e) in estimated.range(1..=ticks) {
        if let Some(t) = truth.get(tick) {
            pos += e.position().distance_squared(t.position());
            theta += wrap_angle(e.theta - t.theta).powi(2);
            n += 1.0;
        }
    }
    if n > 0.0 {
        ((pos / n).sqrt(), (theta / n).sqrt(), n)
    } else {
        (f64::NAN, f64::NAN, n)
    }
}

/// How far SLAM's last map is from the arena's walls.
fn map_error_of(m: &SlamMap, scenario: &Scenario) -> Option<f64> {
    let cells = (m.width * m.height) as usize;
    map_error(
        &CoarseMap {
            width: m.width as usize,
            height: m.height as usize,
            cell_size: f64::from(m.cell_size),
            origin: DVec2::new(f64::from(m.origin[0]), f64::from(m.origin[1])),
            cells: &m.cells[..cells.min(m.cells.len())],
        },
        &scenario.arena,
    )
}

fn run_once(
    label: &str,
    index: usize,
    scenario: &Scenario,
    initial: &MotionModel,
    learning: bool,
    particles: usize,
    seconds: f64,
) -> Result<Outcome> {
    let name = swarm_name("learning", index);
    let mut swarm = RunningSwarm::launch(&name, scenario.clone(), true)?;
    let model_file = swarm.runtime.dir.join("initial-model.toml");
    std::fs::write(&model_file, toml::to_string(initial)?)
        .with_context(|| format!("writing {}", model_file.display()))?;
    let (bus, roster) = shoal_broker::roster::join_reader(&name, "learning", BusLimits::default())?;
    let estimates = robot_streams::estimate_subscriber(&bus, 0)?;
    let models = robot_streams::model_subscriber(&bus, 0)?;
    let maps = robot_streams::slam_map_subscriber(&bus)?;
    swarm.follow_with_slam(
        &shoal_slam::follow::Follow::Robots(vec![0]),
        &[
            // The thesis's filter, whose particle counts this sweeps.
            "--proposal".into(),
            "motion".into(),
            "--particles".into(),
            particles.to_string(),
            "--learning".into(),
            if learning { "on" } else { "off" }.into(),
            "--initial-model".into(),
            model_file.display().to_string(),
        ],
    )?;
    let mut truth: BTreeMap<u64, Pose> = BTreeMap::new();
    let mut estimated: BTreeMap<u64, Pose> = BTreeMap::new();
    let mut learned = initial.clone();
    let mut last_map = None;
    let ticks = (seconds / scenario.timing.period_s).round() as u64;
    // A few ticks more, so the SLAM process's last estimates come in.
    while swarm.clock.as_ref().map_or(0, |c| c.tick) < ticks + 6 {
        swarm.advance()?;
        roster.receive(|s| {
            truth.insert(s.tick, Pose::new(s.x, s.y, s.theta));
        })?;
        estimates.receive(|e| {
            estimated.insert(e.tick, Pose::new(e.x, e.y, e.theta));
        })?;
        models.receive(|u| {
            let (Some(command), Some(param)) = (
                Command::from_index(u.command as usize),
                Param::ALL.get(u.param as usize),
            ) else {
                return;
            };
            let mixture = learned.command_mut(command).param_mut(*param);
            mixture.weights = u.weights;
            mixture.means = u.means;
            mixture.variances = u.variances;
        })?;
        maps.receive(|m| last_map = Some(m))?;
    }
    swarm.shutdown()?;

    let truth_now = true_model(&scenario.motion, scenario.arena.surfaces.last());
    let (pos_rmse_m, theta_rmse_rad, n) = rmse(&estimated, &truth, ticks);
    let scores = Scores {
        pos_rmse_m,
        theta_rmse_rad,
        map_error: last_map.and_then(|m| map_error_of(&m, scenario)),
        param_error: learned.distance_over(&truth_now, &USED),
    };
    eprintln!(
        "learning: {label} ({} learning, {particles} particles): {n} estimates, position rmse {:.3} m, heading {:.3} rad, map {:?}, model {:.2}",
        if learning { "with" } else { "without" },
        scores.pos_rmse_m,
        scores.theta_rmse_rad,
        scores.map_error.map(|e| (e * 1000.0).round() / 1000.0),
        scores.param_error
    );
    Ok(Outcome { scores, learned })
}

/// The runs of the experiment, numbered in order (each its own swarm).
struct Runs {
    next: usize,
    particles: usize,
    seconds: f64,
}

impl Runs {
    fn once(
        &mut self,
        label: &str,
        scenario: &Scenario,
        initial: &MotionModel,
        learning: bool,
        particles: usize,
    ) -> Result<Outcome> {
        self.next += 1;
        run_once(
            label,
            self.next - 1,
            scenario,
            initial,
            learning,
            particles,
            self.seconds,
        )
    }

    /// A case with learning on and off, with `particles` per filter.
    fn both_with(
        &mut self,
        label: &str,
        scenario: &Scenario,
        initial: &MotionModel,
        particles: usize,
    ) -> Result<(Outcome, Outcome)> {
        Ok((
            self.once(label, scenario, initial, true, particles)?,
            self.once(label, scenario, initial, false, particles)?,
        ))
    }

    /// A case with learning on and off, one row of the report.
    fn case(&mut self, label: &str, scenario: &Scenario, initial: &MotionModel) -> Result<Case> {
        let (on, off) = self.both_with(label, scenario, initial, self.particles)?;
        Ok(case(label, self.particles, &on, &off))
    }
}

fn mean_scores(all: &[Scores]) -> Scores {
    let n = all.len().max(1) as f64;
    let maps: Vec<f64> = all.iter().filter_map(|s| s.map_error).collect();
    Scores {
        pos_rmse_m: all.iter().map(|s| s.pos_rmse_m).sum::<f64>() / n,
        theta_rmse_rad: all.iter().map(|s| s.theta_rmse_rad).sum::<f64>() / n,
        map_error: (!maps.is_empty()).then(|| maps.iter().sum::<f64>() / maps.len() as f64),
        param_error: all.iter().map(|s| s.param_error).sum::<f64>() / n,
    }
}

/// Each mixture's means and variances scaled at random, as a wrong guess.
fn perturbed(model: &MotionModel, seed: u64) -> MotionModel {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut out = model.clone();
    for command in Command::ALL {
        for param in Param::ALL {
            let m = out.command_mut(command).param_mut(param);
            let scale = rng.random_range(0.6..1.4);
            m.means = m.means.map(|v| v * scale);
            let spread = rng.random_range(0.5..2.0);
            m.variances = m.variances.map(|v| v * spread);
        }
    }
    out
}

fn case(name: &str, particles: usize, on: &Outcome, off: &Outcome) -> Case {
    Case {
        name: name.into(),
        particles,
        runs: 1,
        learning: on.scores,
        no_learning: off.scores,
        details: BTreeMap::new(),
    }
}

pub fn run(seconds: f64, perturbed_runs: u64, particles: usize) -> Result<Report> {
    let mut runs = Runs {
        next: 0,
        particles,
        seconds,
    };
    let base = room(1);
    let truth = base.motion.clone();
    let mut cases = vec![runs.case("correct-model", &base, &truth)?];
    cases.push(perturbed_models(&mut runs, &truth, perturbed_runs)?);

    // turn(1) believed to be turn(2).
    let mut initial = truth.clone();
    *initial.command_mut(Command::Turn(1)) = *truth.command(Command::Turn(2));
    cases.push(runs.case("turn1-as-turn2", &base, &initial)?);

    // The floor changes half-way: strides 40% shorter, turns 20% wider.
    let mut changing = base.clone();
    changing.arena.surfaces.push(floor(0.6, 1.2, seconds / 2.0));
    cases.push(runs.case("surface-change", &changing, &truth)?);

    cases.push(model_transfer(&mut runs, &base, &truth)?);
    cases.extend(fewest_particles(&mut runs, &base, &truth)?);
    Ok(Report { cases })
}

/// Initial models perturbed at random: how close learning brings walk(2)'s
/// stride and turn(2)'s turn to the truth.
fn perturbed_models(runs: &mut Runs, truth: &MotionModel, count: u64) -> Result<Case> {
    let (mut on_all, mut off_all, mut walk, mut turn) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for seed in 1..=count {
        let initial = perturbed(truth, seed);
        let (on, off) = runs.both_with(
            &format!("perturbed-{seed}"),
            &room(seed),
            &initial,
            runs.particles,
        )?;
        walk.push(
            on.learned.command(Command::Walk(2)).d.mean()
                / truth.command(Command::Walk(2)).d.mean(),
        );
        turn.push(
            on.learned.command(Command::Turn(2)).t.mean()
                / truth.command(Command::Turn(2)).t.mean(),
        );
        on_all.push(on.scores);
        off_all.push(off.scores);
    }
    let spread = |v: &[f64]| {
        let n = v.len().max(1) as f64;
        let mean = v.iter().sum::<f64>() / n;
        (
            mean,
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt(),
        )
    };
    let (walk_mean, walk_sd) = spread(&walk);
    let (turn_mean, turn_sd) = spread(&turn);
    let initial_error = (1..=count)
        .map(|s| perturbed(truth, s).distance_over(truth, &USED))
        .sum::<f64>()
        / count.max(1) as f64;
    Ok(Case {
        name: "perturbed-models".into(),
        particles: runs.particles,
        runs: count as usize,
        learning: mean_scores(&on_all),
        no_learning: mean_scores(&off_all),
        details: BTreeMap::from([
            ("initial_param_error".into(), initial_error),
            ("learned_walk2_d_mean_over_true".into(), walk_mean),
            ("learned_walk2_d_mean_over_true_sd".into(), walk_sd),
            ("learned_turn2_t_mean_over_true".into(), turn_mean),
            ("learned_turn2_t_mean_over_true_sd".into(), turn_sd),
        ]),
    })
}

/// A model learned on one robot, used for another that moves differently.
fn model_transfer(runs: &mut Runs, base: &Scenario, truth: &MotionModel) -> Result<Case> {
    let mut other = base.clone();
    other.arena.surfaces.push(floor(0.8, 1.25, 0.0));
    let mut first = base.clone();
    first.agents.seed = 7;
    let donor = runs.once("transfer-donor", &first, truth, true, runs.particles)?;
    runs.case("model-transfer", &other, &donor.learned)
}

/// The fewest particles that keep the pose error under the threshold,
/// starting from a model whose turns are 1.5 times too large: one row per
/// particle count tried, then the summary.
fn fewest_particles(runs: &mut Runs, base: &Scenario, truth: &MotionModel) -> Result<Vec<Case>> {
    let mut wide = truth.clone();
    for command in Command::ALL {
        if matches!(command, Command::Turn(_)) {
            let m = wide.command_mut(command);
            m.t = m.t.scaled(1.5);
        }
    }
    let mut cases = Vec::new();
    let (mut fewest_on, mut fewest_off) = (None, None);
    let mut scores_at: BTreeMap<usize, (Scores, Scores)> = BTreeMap::new();
    for count in [25, 50, 100, 200, 500] {
        let (on, off) = runs.both_with(&format!("fewest-{count}"), base, &wide, count)?;
        if fewest_on.is_none() && on.scores.pos_rmse_m < POSE_THRESHOLD_M {
            fewest_on = Some(count);
        }
        if fewest_off.is_none() && off.scores.pos_rmse_m < POSE_THRESHOLD_M {
            fewest_off = Some(count);
        }
        scores_at.insert(count, (on.scores, off.scores));
        let mut row = case(&format!("particles-{count}"), count, &on, &off);
        row.details.insert("turns_scaled".into(), 1.5);
        cases.push(row);
    }
    let as_number = |v: Option<usize>| v.map_or(f64::NAN, |c| c as f64);
    // The scores where each mode first stayed under the threshold (or at
    // the most particles tried, where it never did).
    let at = |fewest: Option<usize>| {
        fewest
            .or_else(|| scores_at.keys().last().copied())
            .and_then(|c| scores_at.get(&c).copied())
            .unwrap_or_default()
    };
    cases.push(Case {
        name: "fewest-particles".into(),
        particles: fewest_on.unwrap_or(0),
        runs: scores_at.len(),
        learning: at(fewest_on).0,
        no_learning: at(fewest_off).1,
        details: BTreeMap::from([
            ("threshold_m".into(), POSE_THRESHOLD_M),
            ("fewest_with_learning".into(), as_number(fewest_on)),
            ("fewest_without_learning".into(), as_number(fewest_off)),
        ]),
    });
    Ok(cases)
}

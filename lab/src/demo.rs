//! `shoal demo`: all of Shoal in one run. Robots form in real time on a
//! scenario file; a SLAM process follows two of them from a model whose
//! strides are too short and learns; part-way through four robots are
//! killed and later restarted; at the end `shoal diagnose` reads the demo's
//! own recording and names the floor the robots' model does not know.

use std::collections::BTreeMap;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use glam::DVec2;
use serde::Serialize;
use shoal_physics::metrics::{centroid, formation_metrics};
use shoal_physics::{Command, MotionModel, Pose, Surface};
use shoal_scenario::Scenario;

use shoal_slam::filter::PositionsByTick;
use shoal_slam::follow::{Follow, SlamSection};
use shoal_slam::report::SlamReport;
use shoal_swarm::RecordOptions;
use shoal_swarm::RunningSwarm;

use crate::mean_of;

/// The SLAM process starts from strides this much too short.
const STRIDE_ERROR: f64 = 0.25;
/// How many robots are killed, and when (share of the run), and for how long.
const KILLED: usize = 4;
const KILL_AT: f64 = 0.45;
const DOWN_S: f64 = 8.0;
/// The hole counts as closed once a robot stands this close to its centre,
/// in the swarm's mean spacing just before the kill (its killed robots stood
/// about 0.7 spacings from it, the survivors around it at least one).
const HOLE_CLOSED_SPACINGS: f64 = 0.5;
/// Robots diagnosed: those that walked longest on a floor the model lacks.
const DIAGNOSED: usize = 3;
/// SLAM error is averaged over this long at the start and at the end.
const SLAM_WINDOW_S: f64 = 10.0;

/// The demo's scenario as shipped, for a `shoal demo` run outside the
/// repository; `scenarios/demo.toml` is the same file to copy and change.
pub const DEMO_SCENARIO: &str = include_str!("../../scenarios/demo.toml");

pub struct DemoOptions {
    pub swarm: String,
    /// None: [`DEMO_SCENARIO`].
    pub scenario: Option<PathBuf>,
    pub out: PathBuf,
    pub seconds: f64,
}

#[derive(Debug, Default, Serialize)]
pub struct DemoSummary {
    pub robots: usize,
    pub groups: usize,
    pub spacing_ratio: f64,
    pub killed: Vec<u32>,
    /// Seconds from the kill until a robot stood in the hole.
    pub hole_closed_s: Option<f64>,
    /// Seconds from the restart until every robot was back in one group.
    pub whole_again_s: Option<f64>,
    /// Per followed robot: mean SLAM position error over the first and the
    /// last seconds of the run, metres.
    pub slam: Vec<SlamProgress>,
    pub diagnoses: Vec<DiagnosisLine>,
    pub recording: PathBuf,
}

#[derive(Debug, Default, Serialize)]
pub struct SlamProgress {
    pub robot: u32,
    /// None where SLAM gave no estimate in the window (a robot followed
    /// only late, or killed through it): an empty window is no error of 0.
    pub early_error_m: Option<f64>,
    pub late_error_m: Option<f64>,
    /// How far the learned model moved from where SLAM started (in starting
    /// standard deviations).
    pub model_distance: Option<f64>,
    /// The stride of the walk command the robot was given most
    /// (`stride_walk`, 1-3; 3 is the full stride): what SLAM started from,
    /// what it learned, and the truth on the floor the robot ended on,
    /// metres.
    pub stride_walk: u8,
    pub stride_start_m: f64,
    pub stride_learned_m: Option<f64>,
    pub stride_true_m: f64,
    /// The most the filter trailed its robot (read once a second), and
    /// the robot's scans it never stepped: whether SLAM kept up.
    pub most_behind_s: f64,
    pub scans_missed: u64,
    /// Scans the filter moved through without scoring them, catching up,
    /// and the fewest particles it held (read once a second): what it gave
    /// up to keep up.
    pub scans_coasted: u64,
    pub fewest_particles: Option<usize>,
    /// Steps the filter matched again from turns its model does not reach.
    pub steps_rematched: u64,
}

#[derive(Debug, Serialize)]
pub struct DiagnosisLine {
    pub robot: u32,
    /// Seconds it walked on a floor its model does not know.
    pub seconds_on_unknown_floor: f64,
    pub finding: String,
}

/// The model SLAM starts from: every stride `1 - error` of the true one.
fn short_strides(model: &MotionModel, error: f64) -> MotionModel {
    model.scaled(1.0 - error, 1.0, 1.0)
}

/// Whether `p` lies on a floor the robots' model (which knows none) lacks.
fn unknown_floor_at(scenario: &Scenario, p: DVec2, t: f64) -> bool {
    scenario
        .arena
        .surface_at_time(p, t)
        .is_some_and(Surface::changes_motion)
}

/// A block of `count` robots in the middle of the swarm: the one nearest the
/// centre of all `robots` and its nearest neighbours among `candidates`.
fn block_in_the_middle(
    robots: &[DVec2],
    candidates: &[(u32, Pose)],
    count: usize,
) -> Vec<(u32, Pose)> {
    let middle = centroid(robots);
    let Some(&(_, seed)) = candidates.iter().min_by(|a, b| {
        a.1.position()
            .distance(middle)
            .total_cmp(&b.1.position().distance(middle))
    }) else {
        return Vec::new();
    };
    let mut by_distance = candidates.to_vec();
    by_distance.sort_by(|a, b| {
        a.1.position()
            .distance(seed.position())
            .total_cmp(&b.1.position().distance(seed.position()))
    });
    by_distance.truncate(count);
    by_distance
}

/// The demo's healing act, free of I/O: when to kill a block of robots in
/// the middle of the swarm, when the hole they leave has closed, when to
/// restart them where they fell, and when the swarm is whole again.
struct Healing {
    kill_at: f64,
    spread: f64,
    /// Robots never killed (SLAM's).
    spared: Vec<u32>,
    killed_at: Option<f64>,
    down: Vec<(u32, Pose)>,
    hole: DVec2,
    hole_radius: f64,
    restarted_at: Option<f64>,
    hole_closed_s: Option<f64>,
    whole_again_s: Option<f64>,
}

/// What the healing act asks of the swarm.
#[derive(Debug, PartialEq)]
enum Act {
    Kill(Vec<u32>),
    /// The hole closed after so many seconds.
    HoleClosed(f64),
    Restart(Vec<(u32, Pose)>),
}

impl Healing {
    fn new(kill_at: f64, spread: f64, spared: Vec<u32>) -> Self {
        Self {
            kill_at,
            spread,
            spared,
            killed_at: None,
            down: Vec::new(),
            hole: DVec2::ZERO,
            hole_radius: 0.0,
            restarted_at: None,
            hole_closed_s: None,
            whole_again_s: None,
        }
    }

    fn killed(&self) -> Vec<u32> {
        self.down.iter().map(|(id, _)| *id).collect()
    }

    /// One look at the swarm at sim time `now`: `robots` is every robot
    /// heard, `expected` how many the swarm should have.
    fn step(&mut self, now: f64, robots: &[(u32, Pose)], expected: usize) -> Option<Act> {
        let positions: Vec<DVec2> = robots.iter().map(|(_, p)| p.position()).collect();
        let Some(killed_at) = self.killed_at else {
            if now < self.kill_at {
                return None;
            }
            let candidates: Vec<(u32, Pose)> = robots
                .iter()
                .filter(|(id, _)| !self.spared.contains(id))
                .copied()
                .collect();
            self.down = block_in_the_middle(&positions, &candidates, KILLED);
            if self.down.is_empty() {
                return None;
            }
            let spacing = formation_metrics(&positions, self.spread).spacing_ratio * self.spread;
            self.hole_radius = HOLE_CLOSED_SPACINGS * spacing;
            let fallen: Vec<DVec2> = self.down.iter().map(|(_, p)| p.position()).collect();
            self.hole = centroid(&fallen);
            self.killed_at = Some(now);
            return Some(Act::Kill(self.killed()));
        };
        let Some(restarted_at) = self.restarted_at else {
            let in_hole = robots
                .iter()
                .filter(|(id, _)| !self.down.iter().any(|(d, _)| d == id))
                .any(|(_, p)| p.position().distance(self.hole) <= self.hole_radius);
            if self.hole_closed_s.is_none() && in_hole {
                self.hole_closed_s = Some(now - killed_at);
                return Some(Act::HoleClosed(now - killed_at));
            }
            if now >= killed_at + DOWN_S {
                self.restarted_at = Some(now);
                return Some(Act::Restart(self.down.clone()));
            }
            return None;
        };
        if self.whole_again_s.is_none()
            && robots.len() == expected
            && formation_metrics(&positions, self.spread).components == 1
        {
            self.whole_again_s = Some(now - restarted_at);
        }
        None
    }
}

/// The scenario file given, or the demo's own.
pub fn demo_scenario(path: Option<&Path>) -> Result<Scenario> {
    Ok(match path {
        Some(path) => shoal_runtime::read_scenario(path)?,
        None => Scenario::from_toml(DEMO_SCENARIO, "scenarios/demo.toml")?,
    })
}

/// How SLAM did for robot `id`: its mean error over the first and last
/// seconds of a run ending at `end`, how far its filter fell behind and
/// the fewest particles it held (all as `watched` noted them), and the
/// stride of the walk it was given most: where SLAM started, what it
/// learned, and the truth on a floor that scales strides by `floor`.
fn slam_progress(
    id: u32,
    followed: Option<&shoal_slam::report::FollowedReport>,
    watched: &Watched,
    end: f64,
    truth: &MotionModel,
    floor: f64,
) -> SlamProgress {
    let walk = followed.map_or(shoal_slam::report::FULL_STRIDE_WALK, |f| f.stride_walk);
    let stride = Command::Walk(walk);
    let mean_error = |from: f64, to: f64| {
        mean_of(
            watched
                .slam_errors
                .iter()
                .filter(|(t, r, _)| *r == id && *t >= from && *t <= to)
                .map(|(_, _, e)| *e),
        )
    };
    SlamProgress {
        robot: id,
        early_error_m: mean_error(0.0, SLAM_WINDOW_S),
        late_error_m: mean_error(end - SLAM_WINDOW_S, end),
        model_distance: followed.map(|f| f.model_distance),
        stride_walk: walk,
        stride_start_m: short_strides(truth, STRIDE_ERROR).mean(stride).along,
        stride_learned_m: followed.and_then(|f| f.stride_m),
        stride_true_m: truth.mean(stride).along * floor,
        most_behind_s: watched.most_behind_s.get(&id).copied().unwrap_or(0.0),
        scans_missed: followed.map_or(0, |f| f.scans_missed),
        scans_coasted: followed.map_or(0, |f| f.scans_coasted),
        fewest_particles: watched.fewest_particles.get(&id).copied(),
        steps_rematched: followed.map_or(0, |f| f.steps_rematched),
    }
}

/// Starts the demo's swarm, its recorder, and SLAM following robots
/// `follow` from strides too short.
fn launch(options: &DemoOptions, scenario: &Scenario, follow: &Follow) -> Result<RunningSwarm> {
    let mut swarm = RunningSwarm::launch(&options.swarm, scenario.clone(), false)?;
    swarm.record(&RecordOptions::file(&options.out, None))?;
    if !follow.is_empty() {
        let model_path = swarm.runtime.dir.join("demo-initial-model.toml");
        let wrong = short_strides(&scenario.motion, STRIDE_ERROR);
        std::fs::write(&model_path, toml::to_string(&wrong)?)
            .with_context(|| format!("writing {}", model_path.display()))?;
        swarm.follow_with_slam(
            follow,
            &["--initial-model".into(), model_path.display().to_string()],
        )?;
    }
    let followed = match follow {
        Follow::All => "every robot".to_owned(),
        Follow::Robots(ids) => format!("robots {ids:?}"),
    };
    eprintln!(
        "shoal demo: {} robots forming in real time for {:.0} s, recorded into {}; a SLAM process follows {followed} from strides {:.0}% too short",
        scenario.agents.count,
        options.seconds,
        options.out.display(),
        STRIDE_ERROR * 100.0
    );
    Ok(swarm)
}

/// Does what the healing act asks, and says so.
fn carry_out(swarm: &mut RunningSwarm, now: f64, act: Act) -> Result<()> {
    match act {
        Act::Kill(ids) => {
            for id in &ids {
                swarm.signal_robot(*id, libc::SIGKILL)?;
                swarm.observer.forget(*id);
            }
            eprintln!("shoal demo: t {now:.0} s: SIGKILL to robots {ids:?}");
        }
        Act::HoleClosed(after) => {
            eprintln!("shoal demo: t {now:.0} s: the hole closed after {after:.1} s");
        }
        Act::Restart(down) => {
            for (id, pose) in &down {
                swarm.start(*id, *pose)?;
            }
            let ids: Vec<u32> = down.iter().map(|(id, _)| *id).collect();
            eprintln!("shoal demo: t {now:.0} s: robots {ids:?} restarted where they fell");
        }
    }
    Ok(())
}

/// (now, robot, position error) of each followed robot SLAM's report has
/// an estimate of, against where the robot stood at the estimate's tick
/// (from `truth`): the report is up to a second old when read, and a robot
/// walks 0.3 m in that second.
fn slam_errors_now(report: &SlamReport, now: f64, truth: &PositionsByTick) -> Vec<(f64, u32, f64)> {
    report
        .followed
        .iter()
        .filter_map(|followed| {
            let [x, y, _] = followed.estimate?;
            let stood = truth.at(followed.id, followed.estimate_tick?)?;
            Some((now, followed.id, (x - stood.x).hypot(y - stood.y)))
        })
        .collect()
}

/// True positions kept per robot: 20 s at 5 Hz, far more than SLAM trails.
const TRUTH_TICKS: usize = 100;

pub fn run(options: &DemoOptions) -> Result<DemoSummary> {
    let scenario = demo_scenario(options.scenario.as_deref())?;
    if scenario.agents.count < KILLED + 4 {
        bail!(
            "{}: the demo kills {KILLED} robots, so it needs at least {} (agents.count is {})",
            scenario.name,
            KILLED + 4,
            scenario.agents.count
        );
    }
    let follow = scenario.section::<SlamSection>()?.follow;
    let spread = scenario.formation.spread;
    let mut swarm = launch(options, &scenario, &follow)?;
    let watched = watch(&mut swarm, &scenario, options.seconds, follow.named())?;
    // Every robot SLAM follows, for the summary.
    let follow = follow.ids_among(scenario.agents.count);
    let mut summary = DemoSummary {
        recording: options.out.clone(),
        killed: watched.healing.killed(),
        hole_closed_s: watched.healing.hole_closed_s,
        whole_again_s: watched.healing.whole_again_s,
        ..DemoSummary::default()
    };
    let metrics = swarm.observer.metrics(spread);
    (summary.robots, summary.groups, summary.spacing_ratio) =
        (metrics.agents, metrics.components, metrics.spacing_ratio);
    let slam_report = swarm.runtime.read_report::<SlamReport>()?;
    let end = swarm.sim_time();
    let floor_scale = floor_scales(&swarm, &scenario, &follow, end);
    swarm.shutdown()?;
    summary.slam = follow
        .iter()
        .map(|id| {
            let followed = slam_report
                .as_ref()
                .and_then(|r| r.followed.iter().find(|f| f.id == *id));
            let floor = floor_scale.get(id).copied().unwrap_or(1.0);
            slam_progress(*id, followed, &watched, end, &scenario.motion, floor)
        })
        .collect();
    let mut walkers: Vec<(u32, f64)> = watched
        .on_floor
        .into_iter()
        .filter(|(id, _)| !summary.killed.contains(id))
        .collect();
    walkers.sort_by(|a, b| b.1.total_cmp(&a.1));
    for (robot, seconds) in walkers.into_iter().take(DIAGNOSED) {
        summary.diagnoses.push(DiagnosisLine {
            robot,
            seconds_on_unknown_floor: seconds,
            finding: diagnose_robot(&options.out, robot)?,
        });
    }
    Ok(summary)
}

/// What the demo saw while the swarm ran.
struct Watched {
    healing: Healing,
    /// Seconds each robot moved on a floor its model lacks.
    on_floor: BTreeMap<u32, f64>,
    /// (sim time, robot, position error) of the followed robots.
    slam_errors: Vec<(f64, u32, f64)>,
    /// Where each robot stood at each recent tick.
    truth: PositionsByTick,
    /// The most each followed robot's filter trailed it, seconds.
    most_behind_s: BTreeMap<u32, f64>,
    /// The fewest particles each followed robot's filter held.
    fewest_particles: BTreeMap<u32, usize>,
}

/// Runs the swarm for `seconds`: kills and restarts robots as `Healing`
/// says, notes who walks on unknown floors and how far SLAM is off, and
/// prints a line every 10 s.
fn watch(
    swarm: &mut RunningSwarm,
    scenario: &Scenario,
    seconds: f64,
    follow: &[u32],
) -> Result<Watched> {
    let spread = scenario.formation.spread;
    let mut watched = Watched {
        healing: Healing::new(KILL_AT * seconds, spread, follow.to_vec()),
        on_floor: BTreeMap::new(),
        slam_errors: Vec::new(),
        truth: PositionsByTick::new(TRUTH_TICKS),
        most_behind_s: BTreeMap::new(),
        fewest_particles: BTreeMap::new(),
    };
    let mut last_tick = 0;
    let mut last_line = std::time::Instant::now();
    let mut last_slam_read = std::time::Instant::now();
    while swarm.sim_time() < seconds {
        if swarm.termination_requested() {
            eprintln!("shoal demo: interrupted");
            break;
        }
        swarm.advance()?;
        for death in swarm.take_deaths() {
            eprintln!("shoal demo: {death}");
        }
        let now = swarm.sim_time();
        if swarm.observer.newest_tick != last_tick {
            last_tick = swarm.observer.newest_tick;
            for s in swarm.observer.samples() {
                watched.truth.saw(s.agent_id, s.tick, DVec2::new(s.x, s.y));
                let moved = s.vx.hypot(s.vy) > 0.01;
                if moved && unknown_floor_at(scenario, DVec2::new(s.x, s.y), s.sim_time) {
                    *watched.on_floor.entry(s.agent_id).or_default() += scenario.timing.period_s;
                }
            }
        }
        // SLAM's estimates reach the launcher through its report (once a second).
        if last_slam_read.elapsed() >= Duration::from_secs(1) {
            last_slam_read = std::time::Instant::now();
            if let Some(report) = swarm.runtime.read_report::<SlamReport>()? {
                let errors = slam_errors_now(&report, now, &watched.truth);
                watched.slam_errors.extend(errors);
                for followed in &report.followed {
                    let most = watched.most_behind_s.entry(followed.id).or_default();
                    *most = most.max(followed.behind_s.unwrap_or(0.0));
                    if let Some(held) = followed.particles {
                        let fewest = watched.fewest_particles.entry(followed.id).or_insert(held);
                        *fewest = (*fewest).min(held);
                    }
                }
            }
        }
        let robots: Vec<(u32, Pose)> = swarm
            .observer
            .samples()
            .map(|s| (s.agent_id, Pose::new(s.x, s.y, s.theta)))
            .collect();
        if let Some(act) = watched.healing.step(now, &robots, scenario.agents.count) {
            carry_out(swarm, now, act)?;
        }
        if last_line.elapsed() >= Duration::from_secs(10) {
            last_line = std::time::Instant::now();
            let m = swarm.observer.metrics(spread);
            eprintln!(
                "shoal demo: t {now:.0} s | robots {} | groups {} | spacing {:.2} x spread",
                m.agents, m.components, m.spacing_ratio
            );
        }
    }
    Ok(watched)
}

/// The stride scale of the floor each followed robot stands on at `end`:
/// the true stride its SLAM model should have learned.
fn floor_scales(
    swarm: &RunningSwarm,
    scenario: &Scenario,
    follow: &[u32],
    end: f64,
) -> BTreeMap<u32, f64> {
    follow
        .iter()
        .filter_map(|id| swarm.observer.get(*id).map(|s| (*id, DVec2::new(s.x, s.y))))
        .map(|(id, at)| {
            let scale = scenario
                .arena
                .surface_at_time(at, end)
                .map_or(1.0, |floor| floor.along_scale);
            (id, scale)
        })
        .collect()
}

/// `shoal diagnose RECORDING --robot N`: its first finding, as a sentence.
fn diagnose_robot(recording: &Path, robot: u32) -> Result<String> {
    let output =
        std::process::Command::new(shoal_swarm::process::sibling_binary("shoal-diagnose")?)
            .arg(recording)
            .args(["--robot", &robot.to_string(), "--json"])
            .output()
            .context("running shoal-diagnose")?;
    if !output.status.success() {
        return Ok(format!(
            "diagnosis failed: {}",
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    let d: serde_json::Value =
        serde_json::from_slice(&output.stdout).context("reading shoal-diagnose's JSON")?;
    let sentences: Vec<&str> = d["effects"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|e| e["sentence"].as_str())
        .collect();
    // Without an effect named, the diagnosis's own one-line summary says
    // what it found (the noise alone, an effect it could not tell from the
    // controller's answer, a mismatch nothing explains).
    Ok(if sentences.is_empty() {
        d["summary"]
            .as_str()
            .map(|s| s.trim_start_matches("In short: ").trim_end_matches('.'))
            .unwrap_or("no summary in the diagnosis")
            .to_owned()
    } else {
        sentences.join(" ")
    })
}

/// Followed robots up to this many get a line each; more, one line for all.
const SLAM_LINES: usize = 4;

/// One followed robot's line: its error early and late, its stride.
fn print_slam_robot(out: &mut dyn Write, s: &SlamProgress) -> io::Result<()> {
    writeln!(
        out,
        "  SLAM robot {}: position error {} in the first {SLAM_WINDOW_S:.0} s -> {} in the last, learning from strides {:.0}% too short{}",
        s.robot,
        in_mm(s.early_error_m),
        in_mm(s.late_error_m),
        STRIDE_ERROR * 100.0,
        s.stride_learned_m
            .map(|learned| format!(
                ": a walk({}) stride {:.0} mm at the start, {learned_mm:.0} mm learned, {:.0} mm true on its floor",
                s.stride_walk,
                s.stride_start_m * 1e3,
                s.stride_true_m * 1e3,
                learned_mm = learned * 1e3
            ))
            .unwrap_or_default()
    )
}

/// An error in millimetres, or that there was no estimate to take it of.
fn in_mm(error_m: Option<f64>) -> String {
    error_m.map_or_else(
        || "no estimate".to_string(),
        |e| format!("{:.0} mm", e * 1e3),
    )
}

/// Every followed robot in one line: the mean error early and late, the
/// worst robot late, and how far the learned strides are from the truth.
fn print_slam_overall(out: &mut dyn Write, slam: &[SlamProgress]) -> io::Result<()> {
    let worst = slam
        .iter()
        .filter_map(|s| Some((s, s.late_error_m?)))
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let stride_errors: Vec<f64> = slam
        .iter()
        .filter_map(|s| Some((s.stride_learned_m? - s.stride_true_m).abs() / s.stride_true_m))
        .collect();
    let start_error = mean_of(
        slam.iter()
            .map(|s| (s.stride_start_m - s.stride_true_m).abs() / s.stride_true_m),
    )
    .unwrap_or(0.0);
    writeln!(
        out,
        "  SLAM followed {} robots at once: each filter at most {:.1} s behind its robot, {} scans missed and {} coasted through in all, {} steps matched again from turns past the model{}",
        slam.len(),
        slam.iter().map(|s| s.most_behind_s).fold(0.0, f64::max),
        slam.iter().map(|s| s.scans_missed).sum::<u64>(),
        slam.iter().map(|s| s.scans_coasted).sum::<u64>(),
        slam.iter().map(|s| s.steps_rematched).sum::<u64>(),
        slam.iter()
            .filter_map(|s| s.fewest_particles)
            .min()
            .map(|fewest| format!(", as few as {fewest} particles to keep up"))
            .unwrap_or_default(),
    )?;
    writeln!(
        out,
        "  SLAM, {} robots followed: mean position error {} in the first {SLAM_WINDOW_S:.0} s -> {} in the last{}; a full stride {:.0}% off the truth on each robot's floor at the start, {:.0}% off as learned (mean over {} robots; `--json` has each)",
        slam.len(),
        in_mm(mean_of(slam.iter().filter_map(|s| s.early_error_m))),
        in_mm(mean_of(slam.iter().filter_map(|s| s.late_error_m))),
        worst
            .map(|(w, late)| format!(" (worst: robot {}, {:.0} mm)", w.robot, late * 1e3))
            .unwrap_or_default(),
        start_error * 100.0,
        mean_of(stride_errors.iter().copied()).unwrap_or(0.0) * 100.0,
        stride_errors.len()
    )
}

/// What a person reads at the end.
pub fn print(out: &mut dyn Write, summary: &DemoSummary, scenario: &Scenario) -> io::Result<()> {
    let spread = scenario.formation.spread;
    writeln!(out, "\nShoal demo: what happened")?;
    writeln!(
        out,
        "  formation: {} robots in {} group(s), mean spacing {:.2} x the spread ({spread} m)",
        summary.robots, summary.groups, summary.spacing_ratio
    )?;
    let seconds =
        |s: Option<f64>| s.map_or("not within the run".to_owned(), |s| format!("{s:.1} s"));
    writeln!(
        out,
        "  healing: robots {:?} killed with SIGKILL; the hole closed in {}; restarted, all were back in one group in {}",
        summary.killed,
        seconds(summary.hole_closed_s),
        seconds(summary.whole_again_s)
    )?;
    if summary.slam.len() > SLAM_LINES {
        print_slam_overall(out, &summary.slam)?;
    } else {
        for s in &summary.slam {
            print_slam_robot(out, s)?;
        }
    }
    let floors: Vec<String> = scenario
        .arena
        .surfaces
        .iter()
        .filter(|s| s.changes_motion())
        .map(|s| {
            format!(
                "{} in [{}, {}]-[{}, {}] m (strides x{}, turns x{})",
                s.name,
                s.region[0],
                s.region[1],
                s.region[2],
                s.region[3],
                s.along_scale,
                s.turn_scale
            )
        })
        .collect();
    writeln!(
        out,
        "  floors the robots' model lacks (the truth): {}",
        floors.join("; ")
    )?;
    for d in &summary.diagnoses {
        writeln!(
            out,
            "  diagnose robot {} ({:.0} s on a floor its model lacks): {}",
            d.robot, d.seconds_on_unknown_floor, d.finding
        )?;
    }
    writeln!(
        out,
        "  open the recording: rerun {}   (pip install rerun-sdk==0.36.3)",
        summary.recording.display()
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use shoal_physics::Command;

    #[test]
    fn a_window_without_an_estimate_is_said_as_such_not_as_no_error() {
        let followed = SlamProgress {
            robot: 3,
            early_error_m: None,
            late_error_m: Some(0.2),
            ..SlamProgress::default()
        };
        let mut one = Vec::new();
        print_slam_robot(&mut one, &followed).expect("writes to memory");
        let one = String::from_utf8(one).expect("utf-8");
        assert!(
            one.contains("no estimate in the first") && one.contains("200 mm in the last"),
            "{one}"
        );
        let other = SlamProgress {
            robot: 4,
            early_error_m: Some(0.1),
            late_error_m: None,
            ..SlamProgress::default()
        };
        let mut all = Vec::new();
        print_slam_overall(&mut all, &[followed, other]).expect("writes to memory");
        let all = String::from_utf8(all).expect("utf-8");
        assert!(
            all.contains("100 mm in the first")
                && all.contains("200 mm in the last (worst: robot 3"),
            "the means are over the windows with an estimate: {all}"
        );
    }

    #[test]
    fn the_shipped_scenario_has_what_the_demo_shows() {
        let scenario = demo_scenario(None).expect("the demo's scenario parses");
        assert!(scenario.agents.count >= KILLED + 4);
        let slam: SlamSection = scenario.section().expect("the demo's [slam] section");
        assert_eq!(slam.follow, Follow::All);
        assert!(scenario.arena.surfaces.iter().any(Surface::changes_motion));
    }

    #[test]
    fn the_killed_block_is_the_middle_robot_and_its_nearest_spared_neighbours() {
        // A row of seven robots 1 m apart: robot 3 stands in the middle, and
        // robot 2, as near to it as robot 4, is followed by SLAM: spared.
        let robots: Vec<DVec2> = (0..7).map(|i| DVec2::new(f64::from(i), 0.0)).collect();
        let candidates: Vec<(u32, Pose)> = (0..7u32)
            .filter(|i| *i != 2)
            .map(|i| (i, Pose::new(f64::from(i), 0.0, 0.0)))
            .collect();
        let block: Vec<u32> = block_in_the_middle(&robots, &candidates, 2)
            .iter()
            .map(|(id, _)| *id)
            .collect();
        assert_eq!(block, vec![3, 4]);
        assert!(block_in_the_middle(&robots, &[], 3).is_empty());
    }

    #[test]
    fn slam_starts_from_strides_a_quarter_too_short() {
        let truth = MotionModel::legged_default();
        let wrong = short_strides(&truth, STRIDE_ERROR);
        let walk = Command::Walk(2);
        let ratio = wrong.mean(walk).along / truth.mean(walk).along;
        assert!((ratio - 0.75).abs() < 1e-12, "{ratio}");
        assert_eq!(wrong.mean(walk).turn, truth.mean(walk).turn);
        // What the SLAM process reads back is what was meant.
        let text = toml::to_string(&wrong).expect("toml");
        assert_eq!(
            MotionModel::from_toml(&text, "model.toml").expect("reads"),
            wrong
        );
    }
}

//! Chaos: a real-time swarm under constant abuse. A random robot is killed
//! (SIGKILL) every few seconds and restarted where it stood a second later;
//! another is frozen (SIGSTOP) for 3-15 s and thawed; the recorder is killed
//! and restarted every minute. What a user needs to hold: no dead node is
//! left on the bus, no robot panics, the swarm is one group again soon after
//! each kill, the recording loses at most about a second per recorder kill,
//! and nothing is left behind afterwards.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use shoal_broker::SwarmNodeState;
use shoal_broker::liveness::{swarm_nodes, swarm_services};
use shoal_physics::Pose;
use shoal_scenario::Scenario;

use super::swarm_name;
use shoal_swarm::RunningSwarm;

/// What to do to the swarm, and for how long.
#[derive(Clone, Debug, clap::Args)]
pub struct ChaosArgs {
    #[arg(long, default_value_t = 50)]
    pub agents: usize,
    /// Wall-clock seconds of chaos.
    #[arg(long, default_value_t = 600.0)]
    pub seconds: f64,
    /// A random robot is killed this often (seconds).
    #[arg(long, default_value_t = 2.0)]
    pub kill_every: f64,
    /// and restarted this long after (seconds).
    #[arg(long, default_value_t = 1.0)]
    pub restart_after: f64,
    /// The recorder is killed and restarted this often (seconds).
    #[arg(long, default_value_t = 60.0)]
    pub recorder_every: f64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Keep the recordings here (default: a temporary folder, removed after).
    #[arg(long)]
    pub keep: Option<PathBuf>,
}

#[derive(Debug, Serialize)]
pub struct Figure {
    pub measure: String,
    pub value: Option<f64>,
    pub goal: String,
    pub met: bool,
}

#[derive(Debug, Serialize)]
pub struct Report {
    pub figures: Vec<Figure>,
    pub agents: usize,
    pub seconds: f64,
    pub robot_kills: usize,
    pub robot_freezes: usize,
    pub recorder_kills: usize,
    /// Dead nodes on the bus just before each next kill.
    pub stale_nodes_after_kill: Vec<usize>,
    /// Seconds from each kill until the swarm was one group again (None: not before the run ended).
    pub regroup_s: Vec<Option<f64>>,
    /// The longest run of ticks missing from the recordings around each recorder kill, in seconds.
    pub recording_gap_s: Vec<f64>,
    pub recordings: Option<PathBuf>,
}

struct Kill {
    at_s: f64,
    id: u32,
    /// The killed process; the robot is back once another pid speaks for it.
    pid: u32,
    stale_nodes: Option<usize>,
    regroup_s: Option<f64>,
}

/// How long after a recorder kill the recordings are searched for a gap.
const GAP_WINDOW_S: f64 = 5.0;
/// A kill this close to the end of the run is not held against healing.
const HEAL_WINDOW_S: f64 = 10.0;

fn dead_nodes(swarm: &str) -> Result<usize> {
    let dead: Vec<String> = swarm_nodes(swarm)?
        .into_iter()
        .filter(|n| n.state == SwarmNodeState::Dead)
        .map(|n| n.name)
        .collect();
    if !dead.is_empty() {
        tracing::warn!(?dead, "dead nodes left on the bus");
    }
    Ok(dead.len())
}

/// Processes still running with `swarm` on their command line.
fn processes_of(swarm: &str) -> usize {
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return 0;
    };
    entries
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().parse::<u32>().is_ok())
        .filter_map(|e| std::fs::read(e.path().join("cmdline")).ok())
        .filter(|cmdline| {
            let args: Vec<&[u8]> = cmdline.split(|b| *b == 0).collect();
            args.windows(2)
                .any(|w| w[0] == b"--swarm" && w[1] == swarm.as_bytes())
        })
        .count()
}

fn shared_memory_files() -> usize {
    std::fs::read_dir("/dev/shm").map_or(0, |d| d.count())
}

/// Ticks of every pose the recordings under `dir` hold (their TUM-side CSVs,
/// written by the recorder at the same flushes as its `.rrd`).
fn recorded_ticks(dir: &Path, period_s: f64) -> Result<BTreeSet<i64>> {
    let mut ticks = BTreeSet::new();
    for segment in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let segment = segment?.path();
        if !segment.is_dir() {
            continue;
        }
        for robot in std::fs::read_dir(&segment)? {
            let poses = robot?.path().join("poses.csv");
            let Ok(text) = std::fs::read_to_string(&poses) else {
                continue;
            };
            for line in text.lines().skip(1) {
                if let Some(t) = line.split(',').next().and_then(|t| t.parse::<f64>().ok()) {
                    ticks.insert((t / period_s).round() as i64);
                }
            }
        }
    }
    Ok(ticks)
}

/// The longest run of missing ticks within `window_s` after `at_s`, in seconds.
fn longest_gap(ticks: &BTreeSet<i64>, at_s: f64, window_s: f64, period_s: f64) -> f64 {
    let from = ((at_s - 2.0) / period_s).floor() as i64;
    let to = ((at_s + window_s) / period_s).ceil() as i64;
    let mut longest = 0;
    let mut run = 0;
    for tick in from..=to {
        if ticks.contains(&tick) {
            run = 0;
        } else {
            run += 1;
            longest = longest.max(run);
        }
    }
    f64::from(longest) * period_s
}

fn percentile(values: &[f64], q: f64) -> Option<f64> {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let index = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted.get(index).copied()
}

fn figure(measure: &str, value: Option<f64>, goal: &str, met: bool) -> Figure {
    Figure {
        measure: measure.into(),
        value,
        goal: goal.into(),
        met,
    }
}

/// What the chaos measured, each against its goal; `left` counts what
/// outlived the run: processes, shared-memory files, bus nodes and services.
fn figures(
    kills: &[Kill],
    crashes: &[shoal_swarm::Death],
    recording_gap_s: &[f64],
    left: [usize; 3],
    seconds: f64,
) -> Vec<Figure> {
    let [processes_left, shm_left, nodes_left] = left;
    let regroup: Vec<f64> = kills.iter().filter_map(|k| k.regroup_s).collect();
    // A kill in the last seconds of the run had no time to heal.
    let never_whole = kills
        .iter()
        .filter(|k| k.regroup_s.is_none() && k.at_s + HEAL_WINDOW_S < seconds)
        .count();
    let max_stale = kills
        .iter()
        .filter_map(|k| k.stale_nodes)
        .max()
        .unwrap_or(0);
    let worst_gap = recording_gap_s.iter().copied().fold(0.0, f64::max);
    vec![
        figure(
            "stale nodes after a kill (max)",
            Some(max_stale as f64),
            "0",
            max_stale == 0,
        ),
        figure(
            "robot panics or crashes",
            Some(crashes.len() as f64),
            "0",
            crashes.is_empty(),
        ),
        figure(
            "back to one group after a kill, p50 (s)",
            percentile(&regroup, 0.5),
            "-",
            true,
        ),
        figure(
            "back to one group after a kill, max (s)",
            percentile(&regroup, 1.0),
            "-",
            true,
        ),
        figure(
            "kills not healed within the run (10 s or more before its end)",
            Some(never_whole as f64),
            "0",
            never_whole == 0,
        ),
        figure(
            "ticks missing around a recorder kill, worst (s)",
            Some(worst_gap),
            "<= 1",
            worst_gap <= 1.0 + 1e-9,
        ),
        figure(
            "processes left after the run",
            Some(processes_left as f64),
            "0",
            processes_left == 0,
        ),
        figure(
            "shared-memory files left after the run",
            Some(shm_left as f64),
            "0",
            shm_left == 0,
        ),
        figure(
            "nodes and services left on the bus",
            Some(nodes_left as f64),
            "0",
            nodes_left == 0,
        ),
    ]
}

/// What the chaos did, and what it saw.
struct Abuse {
    kills: Vec<Kill>,
    freezes: usize,
    /// Sim times of the recorder kills.
    recorder_kills: Vec<f64>,
    crashes: Vec<shoal_swarm::Death>,
}

/// `args.seconds` of chaos on `swarm`: kills and restarts, freezes, and
/// recorder kills (each next recording segment from `segment(k)`).
fn abuse(
    swarm: &mut RunningSwarm,
    args: &ChaosArgs,
    name: &str,
    segment: impl Fn(usize) -> (PathBuf, PathBuf),
) -> Result<Abuse> {
    let spread = swarm.scenario.formation.spread;
    let started = Instant::now();
    let mut chaos = Chaos {
        rng: StdRng::seed_from_u64(args.seed),
        restarts: Vec::new(),
        frozen: None,
        next_kill: args.kill_every,
        next_freeze: 1.0,
        next_recorder: args.recorder_every,
        abuse: Abuse {
            kills: Vec::new(),
            freezes: 0,
            recorder_kills: Vec::new(),
            crashes: Vec::new(),
        },
    };
    let mut next_progress = 10.0;
    while started.elapsed().as_secs_f64() < args.seconds {
        if swarm.termination_requested() {
            anyhow::bail!("interrupted");
        }
        swarm.advance()?;
        let crashed = swarm.take_deaths().into_iter().filter(|d| d.crashed);
        chaos.abuse.crashes.extend(crashed);
        let now = started.elapsed().as_secs_f64();
        // One group of every robot not frozen: the killed one restarted and back in.
        let expected = args.agents - usize::from(chaos.frozen.is_some());
        let whole =
            swarm.observer.len() >= expected && swarm.observer.metrics(spread).components == 1;
        chaos.note_regroups(swarm, now, whole);
        chaos.kill_and_restart(swarm, args, name, now)?;
        chaos.freeze_or_thaw(swarm, now)?;
        // A recorder kill needs time after it to see what the recording lost.
        if now >= chaos.next_recorder && now + GAP_WINDOW_S < args.seconds {
            chaos.next_recorder += args.recorder_every;
            // The recorder's times are the swarm's clock, which started with it.
            chaos.abuse.recorder_kills.push(swarm.sim_time());
            swarm.kill_recorder()?;
            let (rrd, tum) = segment(chaos.abuse.recorder_kills.len());
            swarm.record(&shoal_swarm::RecordOptions::file(&rrd, Some(&tum)))?;
        }
        if now >= next_progress {
            next_progress += 10.0;
            eprintln!(
                "chaos: {now:4.0} s, {} kills, {} freezes, {} recorder kills",
                chaos.abuse.kills.len(),
                chaos.abuse.freezes,
                chaos.abuse.recorder_kills.len()
            );
        }
    }
    if let Some((id, _)) = chaos.frozen {
        swarm.pause_robot(id, false)?;
    }
    let mut abuse = chaos.abuse;
    // The last kill is judged as the others were: one kill interval later.
    if let Some(last) = abuse.kills.last_mut() {
        while started.elapsed().as_secs_f64() < last.at_s + args.kill_every {
            swarm.advance()?;
        }
        last.stale_nodes = Some(dead_nodes(name)?);
    }
    Ok(abuse)
}

/// The chaos run's state between steps.
struct Chaos {
    rng: StdRng,
    /// (when, robot, where) of the killed robots still to restart.
    restarts: Vec<(f64, u32, Pose)>,
    /// The frozen robot, and until when.
    frozen: Option<(u32, f64)>,
    next_kill: f64,
    next_freeze: f64,
    next_recorder: f64,
    abuse: Abuse,
}

impl Chaos {
    /// A killed robot has regrouped once another process speaks for it and
    /// the swarm is one group again.
    fn note_regroups(&mut self, swarm: &RunningSwarm, now: f64, whole: bool) {
        for kill in self
            .abuse
            .kills
            .iter_mut()
            .filter(|k| k.regroup_s.is_none())
        {
            let back = swarm
                .observer
                .get(kill.id)
                .is_some_and(|s| s.pid != kill.pid);
            if whole && back {
                kill.regroup_s = Some(now - kill.at_s);
            }
        }
    }

    /// A random robot neither being restarted nor frozen.
    fn pick(&mut self, swarm: &RunningSwarm) -> Option<(u32, u32, Pose)> {
        let busy: Vec<u32> = self
            .restarts
            .iter()
            .map(|(_, id, _)| *id)
            .chain(self.frozen.map(|(id, _)| id))
            .collect();
        let ids: Vec<(u32, u32, Pose)> = swarm
            .observer
            .samples()
            .filter(|s| !busy.contains(&s.agent_id))
            .map(|s| (s.agent_id, s.pid, Pose::new(s.x, s.y, s.theta)))
            .collect();
        (!ids.is_empty()).then(|| ids[self.rng.random_range(0..ids.len())])
    }

    /// Every kill interval, SIGKILLs a random robot (noting the stale nodes
    /// the previous kill left); restarts those whose time has come.
    fn kill_and_restart(
        &mut self,
        swarm: &mut RunningSwarm,
        args: &ChaosArgs,
        name: &str,
        now: f64,
    ) -> Result<()> {
        if now >= self.next_kill {
            self.next_kill += args.kill_every;
            if let Some(last) = self.abuse.kills.last_mut() {
                last.stale_nodes = Some(dead_nodes(name)?);
            }
            if let Some((id, pid, pose)) = self.pick(swarm) {
                swarm.signal_robot(id, libc::SIGKILL)?;
                self.restarts.push((now + args.restart_after, id, pose));
                self.abuse.kills.push(Kill {
                    at_s: now,
                    id,
                    pid,
                    stale_nodes: None,
                    regroup_s: None,
                });
            }
        }
        let due: Vec<(f64, u32, Pose)> = self
            .restarts
            .iter()
            .filter(|r| r.0 <= now)
            .copied()
            .collect();
        self.restarts.retain(|r| r.0 > now);
        for (_, id, pose) in due {
            swarm.start(id, pose)?;
        }
        Ok(())
    }

    /// Thaws the frozen robot when its time is up; a second later freezes
    /// another for 3-15 s.
    fn freeze_or_thaw(&mut self, swarm: &mut RunningSwarm, now: f64) -> Result<()> {
        match self.frozen {
            Some((id, until)) if now >= until => {
                swarm.pause_robot(id, false)?;
                self.frozen = None;
                self.next_freeze = now + 1.0;
            }
            None if now >= self.next_freeze => {
                if let Some((id, _, _)) = self.pick(swarm) {
                    swarm.pause_robot(id, true)?;
                    self.frozen = Some((id, now + self.rng.random_range(3.0..15.0)));
                    self.abuse.freezes += 1;
                }
            }
            _ => {}
        }
        Ok(())
    }
}

/// What a stopped swarm left behind: its processes, shared-memory files
/// beyond the `shm_before` there were, and nodes and services on the bus
/// (each printed).
fn left_behind(name: &str, shm_before: usize) -> Result<[usize; 3]> {
    let left: Vec<String> = swarm_nodes(name)?
        .into_iter()
        .map(|n| format!("node {} ({:?})", n.name, n.state))
        .chain(
            swarm_services(name)?
                .into_iter()
                .map(|s| format!("service {s}")),
        )
        .collect();
    for what in &left {
        eprintln!("chaos: left on the bus: {what}");
    }
    // Robots exit within the shutdown's grace; give the kernel a moment to tidy.
    std::thread::sleep(Duration::from_millis(500));
    let processes_left = processes_of(name);
    let shm_left = shared_memory_files().saturating_sub(shm_before);
    Ok([processes_left, shm_left, left.len()])
}

pub fn run(args: &ChaosArgs) -> Result<Report> {
    let name = swarm_name("chaos", args.seed as usize);
    let scratch = std::env::temp_dir().join(format!("shoal-chaos-{}", std::process::id()));
    let dir = args.keep.clone().unwrap_or_else(|| scratch.clone());
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let shm_before = shared_memory_files();
    let scenario = Scenario::open_arena(args.agents);
    let period_s = scenario.timing.period_s;
    let mut swarm = RunningSwarm::launch(&name, scenario, false)?;
    let segment = |k: usize| {
        (
            dir.join(format!("recording-{k}.rrd")),
            dir.join(format!("poses-{k}")),
        )
    };
    let (rrd, tum) = segment(0);
    swarm.record(&shoal_swarm::RecordOptions::file(&rrd, Some(&tum)))?;
    // Everyone in, before the chaos starts.
    let joined = Instant::now();
    while swarm.observer.len() < args.agents && joined.elapsed() < Duration::from_secs(60) {
        swarm.advance()?;
    }
    let Abuse {
        kills,
        freezes,
        recorder_kills,
        crashes,
    } = abuse(&mut swarm, args, &name, segment)?;
    swarm.shutdown()?;
    // The launcher's own node and services go with it.
    drop(swarm);
    let [processes_left, shm_left, nodes_left] = left_behind(&name, shm_before)?;
    let ticks = recorded_ticks(&dir, period_s)?;
    let recording_gap_s: Vec<f64> = recorder_kills
        .iter()
        .map(|at| longest_gap(&ticks, *at, GAP_WINDOW_S, period_s))
        .collect();

    let stale: Vec<usize> = kills.iter().filter_map(|k| k.stale_nodes).collect();
    let figures = figures(
        &kills,
        &crashes,
        &recording_gap_s,
        [processes_left, shm_left, nodes_left],
        args.seconds,
    );
    for crash in &crashes {
        eprintln!("chaos: {crash}");
    }
    let recordings = match &args.keep {
        Some(dir) => Some(dir.clone()),
        None => {
            std::fs::remove_dir_all(&scratch)
                .with_context(|| format!("removing {}", scratch.display()))?;
            None
        }
    };
    Ok(Report {
        figures,
        agents: args.agents,
        seconds: args.seconds,
        robot_kills: kills.len(),
        robot_freezes: freezes,
        recorder_kills: recorder_kills.len(),
        stale_nodes_after_kill: stale,
        regroup_s: kills.iter().map(|k| k.regroup_s).collect(),
        recording_gap_s,
        recordings,
    })
}

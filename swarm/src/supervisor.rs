//! A swarm started from this process: its robots, its clock (in lockstep),
//! an observer of the roster, and the deaths it reports. `shoal up`, the
//! lab's experiments and the demo drive it; its helpers, the lockstep
//! pacing and the stop are modules of their own (`helpers`, `pacing`,
//! `shutdown`).

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, bail};
use shoal_broker::liveness::{SwarmNodeState, remove_dead_nodes, swarm_nodes};
use shoal_broker::{Bus, BusLimits, BusSection, RosterReader, SampleCheck, names};
use shoal_link::report::LinkReport;
use shoal_physics::Pose;
use shoal_runtime::{SwarmMeta, SwarmRuntime, pid_alive};
use shoal_scenario::Scenario;
use shoal_slam::follow::SlamSection;

use crate::clock::LockstepClock;
use crate::deaths::{Children, Death};
use crate::helpers::{Helpers, LinkOptions, RecordOptions};
use crate::observer::Observer;
use crate::pacing::{Pace, RECORDER_LAG_TICKS, SLAM_LAG_TICKS};
use crate::process::{LINK_BINARY, Pinned, Tie, check_id_range, start_agent};
use crate::sweeper::Sweeper;
use shoal_broker::robot_streams::{RECORDER_PROGRESS, SLAM_PROGRESS};

/// The launcher's tool role on the bus (`shoal/<swarm>/launcher`): how a
/// running swarm's launcher is told from a passing `shoal status`.
pub(crate) const LAUNCHER_ROLE: &str = "launcher";
/// How long the launcher waits for its robots to announce themselves.
const STARTUP_TIMEOUT: Duration = Duration::from_secs(30);
/// How long the launcher waits for its link to have heard the other hosts.
const LINK_TIMEOUT: Duration = Duration::from_secs(20);

pub struct RunningSwarm {
    pub name: String,
    pub scenario: Scenario,
    pub runtime: SwarmRuntime,
    pub observer: Observer,
    pub clock: Option<LockstepClock>,
    pub(crate) bus: Bus,
    pub(crate) roster: RosterReader,
    pub(crate) children: Children,
    /// Processes that serve the swarm (recorder, SLAM, link).
    pub(crate) helpers: Helpers,
    /// In lockstep, the clock waits for helpers (recorder, SLAM) to keep up.
    pub(crate) paces: Vec<Pace>,
    /// Helper progress reports rejected, by helpers no longer paced or as
    /// reports of ticks not yet sent.
    pub(crate) rejected_progress: u64,
    started: Instant,
    pub(crate) stopped: bool,
    /// Deaths already handed to the caller by `take_deaths`.
    reported_deaths: usize,
    /// Keep the robots' logs when the swarm stops (a failed start).
    pub(crate) keep_logs: bool,
    /// Removes the nodes of robots that died, off this loop.
    pub(crate) sweeper: Sweeper,
    /// Held while this launcher runs the swarm.
    _launch_lock: std::fs::File,
}

/// How a swarm is started beyond its scenario.
#[derive(Clone, Debug, Default)]
pub struct Launch {
    /// Step all robots on one clock (faster than real time, deterministic).
    pub lockstep: bool,
    /// The first robot's id; the others follow it.
    pub first_id: u32,
    /// Join the swarm's parts on other hosts.
    pub link: Option<LinkOptions>,
}

impl RunningSwarm {
    /// Starts `scenario.agents.count` robots in swarm `name`.
    pub fn launch(name: &str, scenario: Scenario, lockstep: bool) -> Result<Self> {
        Self::launch_with(
            name,
            scenario,
            &Launch {
                lockstep,
                ..Launch::default()
            },
        )
    }

    /// Starts `scenario.agents.count` robots in swarm `name`, with ids from
    /// `launch.first_id`, linked to the swarm's other hosts if asked.
    pub fn launch_with(name: &str, scenario: Scenario, launch: &Launch) -> Result<Self> {
        names::validate_swarm(name)?;
        if launch.lockstep && launch.link.is_some() {
            bail!(
                "--lockstep cannot span hosts: its clock waits for every robot's answer through this \
                 machine's shared memory each tick, which across a network would pace the swarm to \
                 its slowest round trip; run a linked swarm in real time"
            );
        }
        check_id_range(launch.first_id, scenario.agents.count)?;
        // The sections other crates own are checked before anything starts,
        // so a bad one is refused here, not by every robot on its way up.
        let bus: BusSection = scenario.section()?;
        let _: SlamSection = scenario.section()?;
        // Two launchers of one swarm started together would both pass the
        // check below; the lock makes the second one fail.
        let launch_lock = SwarmRuntime::locate(name)
            .lock("launch", false)
            .with_context(|| format!("swarm `{name}` is already being started or run"))?;
        refuse_a_running_swarm(name)?;
        let runtime = create_folder(name, &scenario, launch.lockstep)?;
        let (bus, roster) =
            shoal_broker::roster::join_reader(name, LAUNCHER_ROLE, BusLimits::of(&bus))?;
        let clock = if launch.lockstep {
            Some(LockstepClock::new(&bus, scenario.timing.period_s)?)
        } else {
            None
        };
        let sweeper = Sweeper::start(runtime.clone(), name.to_owned())
            .context("starting the thread that sweeps dead nodes")?;
        let mut swarm = Self {
            name: name.to_owned(),
            observer: Observer::new(SampleCheck::for_scenario(&scenario)),
            scenario,
            runtime,
            clock,
            bus,
            roster,
            children: Children::default(),
            helpers: Helpers::default(),
            paces: Vec::new(),
            rejected_progress: 0,
            started: Instant::now(),
            stopped: false,
            reported_deaths: 0,
            keep_logs: false,
            sweeper,
            _launch_lock: launch_lock,
        };
        if let Some(link) = &launch.link {
            let tie = swarm.tie();
            swarm
                .helpers
                .start(&swarm.runtime, tie, LINK_BINARY, &link.args(name))?;
            swarm.await_link(launch.first_id, swarm.scenario.agents.count)?;
        }
        swarm.start_robots(launch.first_id)?;
        Ok(swarm)
    }

    /// Starts the scenario's robots from id `first_id`, from the middle of
    /// their start poses outwards, and in lockstep waits until each has
    /// answered the clock.
    fn start_robots(&mut self, first_id: u32) -> Result<()> {
        let count = self.scenario.agents.count;
        let poses = self.scenario.start_poses(0, count);
        for (started, index) in inside_out(&poses).into_iter().enumerate() {
            // Starting many robots takes a while: Ctrl-C stops it at once,
            // and dropping the swarm stops the robots already started.
            if self.termination_requested() {
                bail!("interrupted while starting robots ({started} of {count} started)");
            }
            self.start(first_id + index as u32, poses[index])?;
        }
        let Some(clock) = &mut self.clock else {
            return Ok(());
        };
        let observer = &mut self.observer;
        let joined =
            clock.await_robots(&self.roster, count, STARTUP_TIMEOUT, |s| observer.record(s))?;
        if joined < count {
            self.children.reap(&self.runtime);
            self.keep_logs = true;
            bail!(
                "only {joined} of {count} robots started{}; their logs are kept in {}",
                self.children
                    .deaths
                    .first()
                    .map(|d| format!("; {d}"))
                    .unwrap_or_default(),
                self.runtime.dir.display()
            );
        }
        Ok(())
    }

    /// Waits until the link has heard the other hosts, and refuses robot
    /// ids `first_id..first_id + count` if another host runs one of them.
    fn await_link(&mut self, first_id: u32, count: usize) -> Result<()> {
        let started = Instant::now();
        let report = loop {
            self.reap_helpers();
            if let Some(death) = self.children.deaths.iter().find(|d| d.who == LINK_BINARY) {
                self.keep_logs = true;
                bail!("the link to the other hosts failed: {death}");
            }
            if self.termination_requested() {
                bail!("interrupted while linking to the other hosts");
            }
            if let Some(report) = self
                .runtime
                .read_report::<LinkReport>()?
                .filter(|r| r.ready)
            {
                break report;
            }
            if started.elapsed() > LINK_TIMEOUT {
                self.keep_logs = true;
                bail!(
                    "the link to the other hosts did not get ready within {} s; its log is kept in {}",
                    LINK_TIMEOUT.as_secs(),
                    self.runtime.dir.display()
                );
            }
            std::thread::sleep(Duration::from_millis(100));
        };
        let ours = u64::from(first_id)..u64::from(first_id) + count as u64;
        let clashes: Vec<String> = report
            .hosts
            .iter()
            .filter_map(|host| {
                let ids: Vec<String> = host
                    .robots
                    .iter()
                    .filter(|r| ours.contains(&u64::from(r.id)))
                    .map(|r| r.id.to_string())
                    .collect();
                (!ids.is_empty())
                    .then(|| format!("host `{}` runs robots {}", host.name, ids.join(", ")))
            })
            .collect();
        if !clashes.is_empty() {
            bail!(
                "robot ids {}..={} of this host `{}` are taken: {}; robot ids must be unique across the swarm: choose another --first-id",
                ours.start,
                ours.end.saturating_sub(1),
                report.host,
                clashes.join("; ")
            );
        }
        let remote: usize = report.hosts.iter().map(|h| h.robots.len()).sum();
        eprintln!(
            "shoal: linked host `{}` to {} other host(s) of swarm `{}` ({remote} robots there)",
            report.host,
            report.hosts.len(),
            self.name
        );
        Ok(())
    }

    /// Starts the recorder process: into a file, a live viewer, or both.
    pub fn record(&mut self, to: &RecordOptions) -> Result<()> {
        self.pace_to(RECORDER_PROGRESS, RECORDER_LAG_TICKS)?;
        let tie = self.tie();
        self.helpers
            .start_recorder(&self.runtime, tie, &self.name, to)
    }

    /// Starts a SLAM process following `follow`, with more `options`
    /// of `shoal-slam` (particles, learning, initial model).
    pub fn follow_with_slam(
        &mut self,
        follow: &shoal_slam::follow::Follow,
        options: &[String],
    ) -> Result<()> {
        self.pace_to(SLAM_PROGRESS, SLAM_LAG_TICKS)?;
        let tie = self.tie();
        self.helpers
            .start_slam(&self.runtime, tie, &self.name, follow, options)
    }

    /// In lockstep, makes the clock wait for `helper`'s progress.
    fn pace_to(&mut self, helper: &'static str, lag: u64) -> Result<()> {
        if self.clock.is_some() {
            self.paces.push(Pace::open(&self.bus, helper, lag)?);
        }
        Ok(())
    }

    pub fn recorder_pid(&self) -> Option<i32> {
        self.helpers.recorder_pid()
    }

    /// Warnings the helpers wrote into their logs since the last call
    /// (a disk filling up, a viewer that does not answer).
    pub fn take_helper_warnings(&mut self) -> Vec<String> {
        self.helpers.take_warnings()
    }

    /// What stopping the swarm cost: helpers that had to be killed.
    pub fn stop_notes(&self) -> &[String] {
        self.helpers.stop_notes()
    }

    /// Kills the recorder as a crash would (SIGKILL); not reported as a death.
    pub fn kill_recorder(&mut self) -> Result<()> {
        self.helpers.kill_recorder(&self.name)?;
        self.paces.retain(|p| p.helper != RECORDER_PROGRESS);
        Ok(())
    }

    /// Notes helpers (recorder, SLAM) that ended on their own; a lockstep
    /// clock no longer waits for them.
    pub(crate) fn reap_helpers(&mut self) {
        self.helpers.reap(&self.runtime, &mut self.children.deaths);
        let helpers = &self.helpers;
        self.paces.retain(|p| helpers.serves(p.helper));
    }

    /// Starts robot `id` at `pose` as a child of this process.
    pub fn start(&mut self, id: u32, pose: Pose) -> Result<()> {
        let child = start_agent(&self.name, id, pose, &self.runtime, self.tie())?;
        self.children.running.insert(id, child);
        Ok(())
    }

    /// Lockstep children cannot go on without the clock in this process.
    pub(crate) fn tie(&self) -> Tie {
        if self.lockstep() {
            Tie::DiesWithLauncher
        } else {
            Tie::Child
        }
    }

    /// Pids of the robots this process started and that still run.
    pub fn agent_pids(&self) -> Vec<i32> {
        self.children
            .running
            .values()
            .map(|c| c.id() as i32)
            .collect()
    }

    /// Robots and helpers that died without being asked to, in order; each
    /// is reported once.
    pub fn take_deaths(&mut self) -> Vec<Death> {
        let new = self.children.deaths[self.reported_deaths..].to_vec();
        self.reported_deaths = self.children.deaths.len();
        new
    }

    /// Every unasked-for death since the start.
    pub fn deaths(&self) -> &[Death] {
        &self.children.deaths
    }

    /// Robots this process started that still run.
    pub fn running_children(&self) -> usize {
        self.children.running.len()
    }

    pub fn lockstep(&self) -> bool {
        self.clock.is_some()
    }

    /// Simulated seconds since the start.
    pub fn sim_time(&self) -> f64 {
        match &self.clock {
            Some(clock) => clock.sim_time(),
            None => self.started.elapsed().as_secs_f64(),
        }
    }

    /// Bus samples rejected so far: malformed or implausible poses and
    /// helper progress reports.
    pub fn rejected_samples(&self) -> u64 {
        self.observer.rejected()
            + self.roster.rejected()
            + self.rejected_progress
            + self
                .paces
                .iter()
                .map(|p| p.progress.rejected())
                .sum::<u64>()
    }

    /// Lockstep: one tick. Real time: a short wait. Either way the observer is
    /// brought up to date.
    pub fn advance(&mut self) -> Result<()> {
        self.reap_helpers();
        let children = &mut self.children;
        let runtime = &self.runtime;
        let observer = &mut self.observer;
        match &mut self.clock {
            Some(clock) => {
                let mut silent = Vec::new();
                for (index, pace) in self.paces.iter_mut().enumerate() {
                    if !pace.wait_for(clock.tick, &mut self.rejected_progress)? {
                        tracing::warn!(
                            helper = pace.helper,
                            "a helper stopped answering; the clock no longer waits for it"
                        );
                        silent.push(index);
                    }
                }
                for index in silent.into_iter().rev() {
                    let pace = self.paces.remove(index);
                    self.rejected_progress += pace.progress.rejected();
                }
                let mut ended = 0;
                clock.advance(
                    &self.roster,
                    |pid| {
                        ended += children.reap(runtime);
                        pid_alive(pid)
                    },
                    |s| observer.record(s),
                )?;
                for id in clock.take_deaths() {
                    observer.forget(id);
                }
                if ended > 0 {
                    self.sweeper.request();
                }
            }
            None => {
                std::thread::sleep(Duration::from_millis(50));
                self.roster.receive(|s| {
                    observer.record(s);
                })?;
                // A robot of ours that ended leaves its node behind; sweep it
                // now rather than wait for a neighbour to suspect it.
                if children.reap(runtime) > 0 {
                    self.sweeper.request();
                }
                observer.expire(Duration::from_secs_f64(
                    self.scenario.timing.observer_stale_s(),
                ));
            }
        }
        Ok(())
    }

    pub fn termination_requested(&self) -> bool {
        self.bus.termination_requested()
    }

    /// Sends `sig` to robot `id`, which is expected to end by it.
    pub fn signal_robot(&mut self, id: u32, sig: i32) -> Result<()> {
        let process = self.pin_robot(id)?;
        self.runtime.mark_stopped_by_user(id)?;
        process.signal(sig)
    }

    /// Freezes robot `id` (SIGSTOP) or lets it go on (SIGCONT).
    pub fn pause_robot(&mut self, id: u32, pause: bool) -> Result<()> {
        self.pin_robot(id)?
            .signal(if pause { libc::SIGSTOP } else { libc::SIGCONT })
    }

    fn pin_robot(&self, id: u32) -> Result<Pinned> {
        let process = match self.children.running.get(&id) {
            Some(child) => Pinned::child(child),
            None => match self.observer.get(id) {
                Some(sample) => Pinned::shoal_process(sample.pid as i32),
                None => bail!("robot {id} is not in swarm `{}`", self.name),
            },
        };
        process.with_context(|| format!("robot {id} of swarm `{}` has already ended", self.name))
    }
}

/// Refuses to start swarm `name` while it runs. Robots and a launcher mean
/// it runs; a `shoal status` that happens to be looking (a node of its own
/// for a moment) does not, nor does a node under this very process's pid.
/// Dead nodes of the swarm, and of swarms with no live node, are swept.
fn refuse_a_running_swarm(name: &str) -> Result<()> {
    let me = std::process::id() as i32;
    let launcher = names::tool_node(name, LAUNCHER_ROLE);
    let alive: Vec<String> = swarm_nodes(name)?
        .iter()
        .filter(|n| n.state == SwarmNodeState::Alive && n.pid != me)
        .filter(|n| n.agent_id.is_some() || n.name == launcher)
        .map(|n| format!("{} (pid {})", n.name, n.pid))
        .collect();
    if !alive.is_empty() {
        bail!(
            "swarm `{name}` is already running: {}; stop it first (shoal down --swarm {name}) or pick another --swarm",
            alive.join(", ")
        );
    }
    remove_dead_nodes(name)?;
    let swept = shoal_broker::liveness::remove_dead_nodes_of_abandoned_swarms()?;
    if let Some(swept) = shoal_broker::liveness::describe_swept(&swept) {
        eprintln!("shoal: {swept}");
    }
    Ok(())
}

/// The swarm's runtime folder, with the scenario its robots read and its
/// clock mode.
fn create_folder(name: &str, scenario: &Scenario, lockstep: bool) -> Result<SwarmRuntime> {
    let runtime = SwarmRuntime::locate(name);
    let epoch_unix_ms = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64);
    let meta = SwarmMeta {
        lockstep,
        epoch_unix_ms,
        period_s: scenario.timing.period_s,
    };
    let scenario_file = scenario
        .to_toml()
        .context("writing the scenario for the swarm's robots")?;
    runtime
        .create(&scenario_file, &meta)
        .with_context(|| format!("writing the swarm's files in {}", runtime.dir.display()))?;
    Ok(runtime)
}

/// The order to start robots at `poses` in: from the middle of the group
/// outwards, so each robot starts beside robots already running. Started
/// in id order, robots scattered over the whole start region, each found too
/// few neighbours, listened as far as it could (the widest ring: about 40
/// cells where it needs 9), and every robot started after it connected to
/// all those listeners (BENCHMARKS.md, "Start-up").
fn inside_out(poses: &[Pose]) -> Vec<usize> {
    let positions: Vec<_> = poses.iter().map(Pose::position).collect();
    let middle = shoal_physics::metrics::centroid(&positions);
    let mut order: Vec<usize> = (0..poses.len()).collect();
    order.sort_by(|&a, &b| {
        positions[a]
            .distance(middle)
            .total_cmp(&positions[b].distance(middle))
    });
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn robots_start_from_the_middle_outwards_each_once() {
        let poses: Vec<Pose> = [(9.0, 0.0), (0.0, 1.0), (5.0, 5.0), (10.0, 10.0), (1.0, 9.0)]
            .into_iter()
            .map(|(x, y)| Pose { x, y, theta: 0.0 })
            .collect();
        assert_eq!(inside_out(&poses), vec![2, 4, 0, 1, 3]);
        assert!(inside_out(&[]).is_empty());
    }
}

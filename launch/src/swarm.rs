//! A swarm started from this process: its robots, its clock (in lockstep) and
//! an observer of the roster. `shoal up` and the experiments drive it.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, bail};
use shoal_broker::liveness::{SwarmNodeState, remove_dead_nodes, swarm_nodes};
use shoal_broker::robot_streams::{self, StreamSubscriber};
use shoal_broker::{
    Bus, BusLimits, HelperProgress, RosterReader, SampleCheck, SwarmMeta, SwarmRuntime, names,
};
use shoal_physics::{Pose, Scenario};

use crate::clock::LockstepClock;
use crate::observer::Observer;
use crate::process::{pid_alive, sibling_binary, signal, start_agent};

/// How long robots get to leave cleanly before they are killed.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(5);
/// How long the launcher waits for its robots to announce themselves.
const STARTUP_TIMEOUT: Duration = Duration::from_secs(30);

pub fn bus_limits(scenario: &Scenario) -> BusLimits {
    BusLimits {
        max_per_cell: scenario.bus.max_per_cell,
        max_listeners_per_cell: scenario.bus.max_listeners_per_cell,
        ..BusLimits::default()
    }
}

pub fn check_for(scenario: &Scenario) -> SampleCheck {
    SampleCheck::for_map(scenario.arena.width, scenario.arena.height, 1.0)
}

pub struct RunningSwarm {
    pub name: String,
    pub scenario: Scenario,
    pub runtime: SwarmRuntime,
    pub observer: Observer,
    pub clock: Option<LockstepClock>,
    bus: Bus,
    roster: RosterReader,
    children: BTreeMap<u32, Child>,
    /// Processes that serve the swarm (recorder, SLAM), by binary name.
    helpers: Vec<(String, Child)>,
    /// In lockstep, the clock waits for helpers (recorder, SLAM) to keep up.
    paces: Vec<Pace>,
    started: Instant,
    stopped: bool,
}

/// A helper's progress, which a lockstep clock must not outrun by more than
/// the buffers between robots and helpers (8 roster samples, 32 scans).
struct Pace {
    helper: &'static str,
    /// Ticks the clock may run ahead of this helper.
    lag: u64,
    progress: StreamSubscriber<HelperProgress>,
    tick: Option<u64>,
}

/// Ticks a lockstep clock may run ahead of its recorder (within the
/// roster's buffer); SLAM gets none, so its estimates reach the robot the
/// next tick.
const RECORDER_LAG_TICKS: u64 = 4;
const SLAM_LAG_TICKS: u64 = 0;
/// A helper silent this long is no longer waited for.
const HELPER_PATIENCE: Duration = Duration::from_secs(10);

impl Pace {
    /// Waits until the helper has read up to `tick - lag`;
    /// false when it stopped answering.
    fn wait_for(&mut self, tick: u64) -> Result<bool> {
        let started = Instant::now();
        loop {
            let mut newest = self.tick;
            self.progress
                .receive(|p| newest = Some(newest.map_or(p.tick, |n: u64| n.max(p.tick))))?;
            // A helper that just joined has missed nothing it could have
            // read: it is caught up with the tick at which it first spoke.
            self.tick = newest.map(|t| match self.tick {
                None => t.max(tick),
                Some(_) => t,
            });
            if self.tick.is_some_and(|t| t + self.lag >= tick) {
                return Ok(true);
            }
            if started.elapsed() > HELPER_PATIENCE {
                return Ok(false);
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }
}

impl RunningSwarm {
    /// Starts `scenario.agents.count` robots in swarm `name`.
    pub fn launch(name: &str, scenario: Scenario, lockstep: bool) -> Result<Self> {
        names::validate_swarm(name)?;
        let alive: Vec<i32> = swarm_nodes(name)?
            .iter()
            .filter(|n| n.state == SwarmNodeState::Alive)
            .map(|n| n.pid)
            .collect();
        if !alive.is_empty() {
            bail!(
                "swarm `{name}` is already running (pids {alive:?}); stop it first or pick another --swarm"
            );
        }
        remove_dead_nodes(name)?;
        let runtime = SwarmRuntime::locate(name);
        runtime
            .remove()
            .with_context(|| format!("clearing {}", runtime.dir.display()))?;
        let epoch_unix_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_millis() as u64);
        let meta = SwarmMeta {
            lockstep,
            epoch_unix_ms,
            period_s: scenario.timing.period_s,
        };
        runtime
            .create(&scenario.to_toml(), &meta)
            .with_context(|| format!("writing the swarm's files in {}", runtime.dir.display()))?;
        let bus = Bus::join(
            name,
            &names::tool_node(name, "launcher"),
            bus_limits(&scenario),
        )?;
        let roster = RosterReader::new(&bus)?;
        let clock = if lockstep {
            Some(LockstepClock::new(&bus, scenario.timing.period_s)?)
        } else {
            None
        };
        let mut swarm = Self {
            name: name.to_owned(),
            observer: Observer::new(check_for(&scenario)),
            scenario,
            runtime,
            clock,
            bus,
            roster,
            children: BTreeMap::new(),
            helpers: Vec::new(),
            paces: Vec::new(),
            started: Instant::now(),
            stopped: false,
        };
        let count = swarm.scenario.agents.count;
        let poses = swarm.scenario.start_poses(0, count);
        for (id, pose) in poses.into_iter().enumerate() {
            swarm.start(id as u32, pose)?;
        }
        if let Some(clock) = &mut swarm.clock {
            let observer = &mut swarm.observer;
            let joined = clock.await_robots(&swarm.roster, count, STARTUP_TIMEOUT, |s| {
                observer.record(s)
            })?;
            if joined < count {
                bail!(
                    "only {joined} of {count} robots started; see the logs in {}",
                    swarm.runtime.dir.display()
                );
            }
        }
        Ok(swarm)
    }

    /// Starts robot `id` at `pose` as a child of this process.
    pub fn start(&mut self, id: u32, pose: Pose) -> Result<()> {
        let child = start_agent(&self.name, id, pose, &self.runtime.log_path(id), false)?;
        self.children.insert(id, child);
        Ok(())
    }

    /// Starts the recorder process, writing `out` (and TUM files into `tum`).
    pub fn record(&mut self, out: &Path, tum: Option<&Path>) -> Result<()> {
        let mut args = vec![
            out.as_os_str().to_owned(),
            "--swarm".into(),
            self.name.clone().into(),
        ];
        if let Some(tum) = tum {
            args.extend(["--tum".into(), tum.as_os_str().to_owned()]);
        }
        self.pace_to("recorder", RECORDER_LAG_TICKS)?;
        self.start_helper("shoal-viewer-log", &args)
    }

    /// In lockstep, makes the clock wait for `helper`'s progress.
    fn pace_to(&mut self, helper: &'static str, lag: u64) -> Result<()> {
        if self.clock.is_some() {
            self.paces.push(Pace {
                helper,
                lag,
                progress: robot_streams::progress_subscriber(&self.bus, helper)?,
                tick: None,
            });
        }
        Ok(())
    }

    /// Starts a SLAM process following robots `ids`, with more `options`
    /// of `shoal-slam` (particles, learning, initial model).
    pub fn follow_with_slam(&mut self, ids: &[u32], options: &[String]) -> Result<()> {
        let ids: Vec<String> = ids.iter().map(u32::to_string).collect();
        let mut args: Vec<std::ffi::OsString> = vec![
            "--swarm".into(),
            self.name.clone().into(),
            "--follow".into(),
            ids.join(",").into(),
        ];
        args.extend(options.iter().map(Into::into));
        self.pace_to("slam", SLAM_LAG_TICKS)?;
        self.start_helper("shoal-slam", &args)
    }

    fn start_helper(&mut self, binary: &str, args: &[std::ffi::OsString]) -> Result<()> {
        let log = std::fs::File::create(self.runtime.dir.join(format!("{binary}.log")))?;
        let child = Command::new(sibling_binary(binary)?)
            .args(args)
            .stdin(Stdio::null())
            .stdout(log.try_clone()?)
            .stderr(log)
            .spawn()
            .with_context(|| format!("starting {binary}"))?;
        self.helpers.push((binary.to_owned(), child));
        Ok(())
    }

    pub fn recorder_pid(&self) -> Option<i32> {
        self.helpers
            .iter()
            .find(|(name, _)| name == "shoal-viewer-log")
            .map(|(_, c)| c.id() as i32)
    }

    /// Pids of the robots this process started and that still run.
    pub fn agent_pids(&self) -> Vec<i32> {
        self.children.values().map(|c| c.id() as i32).collect()
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

    /// Lockstep: one tick. Real time: a short wait. Either way the observer is
    /// brought up to date.
    pub fn advance(&mut self) -> Result<()> {
        let children = &mut self.children;
        let observer = &mut self.observer;
        match &mut self.clock {
            Some(clock) => {
                let mut silent = Vec::new();
                for (index, pace) in self.paces.iter_mut().enumerate() {
                    if !pace.wait_for(clock.tick)? {
                        tracing::warn!(
                            helper = pace.helper,
                            "a helper stopped answering; the clock no longer waits for it"
                        );
                        silent.push(index);
                    }
                }
                for index in silent.into_iter().rev() {
                    self.paces.remove(index);
                }
                clock.advance(
                    &self.roster,
                    |pid| {
                        reap(children);
                        pid_alive(pid)
                    },
                    |s| observer.record(s),
                )?;
                for id in clock.take_deaths() {
                    observer.forget(id);
                }
            }
            None => {
                std::thread::sleep(Duration::from_millis(50));
                self.roster.receive(|s| observer.record(s))?;
                reap(children);
                let period = self.scenario.timing.period_s;
                observer.expire(Duration::from_secs_f64(
                    period * self.scenario.timing.stale_periods.max(2.0),
                ));
            }
        }
        Ok(())
    }

    pub fn termination_requested(&self) -> bool {
        self.bus.termination_requested()
    }

    /// Sends `sig` to robot `id`.
    pub fn signal_robot(&mut self, id: u32, sig: i32) -> Result<()> {
        let pid = match self.children.get(&id) {
            Some(child) => child.id() as i32,
            None => match self.observer.get(id) {
                Some(sample) => sample.pid as i32,
                None => bail!("robot {id} is not in swarm `{}`", self.name),
            },
        };
        signal(pid, sig)
    }

    /// Stops every robot of the swarm (also those started elsewhere), cleans
    /// the bus and removes the swarm's files.
    pub fn shutdown(&mut self) -> Result<()> {
        if self.stopped {
            return Ok(());
        }
        self.stopped = true;
        // Helpers go first: the recorder then does not log every robot
        // leaving, and gets time to write the recording's footer.
        for (_, mut helper) in self.helpers.drain(..) {
            let _ = signal(helper.id() as i32, libc::SIGTERM);
            let deadline = Instant::now() + Duration::from_secs(10);
            while matches!(helper.try_wait(), Ok(None)) && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = helper.kill();
            let _ = helper.wait();
        }
        let mut pids: Vec<i32> = self.children.values().map(|c| c.id() as i32).collect();
        for node in swarm_nodes(&self.name)? {
            if node.agent_id.is_some()
                && node.state == SwarmNodeState::Alive
                && !pids.contains(&node.pid)
            {
                pids.push(node.pid);
            }
        }
        for pid in &pids {
            let _ = signal(*pid, libc::SIGTERM);
        }
        let deadline = Instant::now() + SHUTDOWN_GRACE;
        while Instant::now() < deadline {
            reap(&mut self.children);
            if pids.iter().all(|p| !pid_alive(*p)) {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        for pid in pids.iter().filter(|p| pid_alive(**p)) {
            tracing::warn!(pid, "robot ignored SIGTERM; killing it");
            let _ = signal(*pid, libc::SIGKILL);
        }
        for child in self.children.values_mut() {
            let _ = child.wait();
        }
        self.children.clear();
        remove_dead_nodes(&self.name)?;
        self.runtime
            .remove()
            .with_context(|| format!("removing {}", self.runtime.dir.display()))?;
        Ok(())
    }
}

impl Drop for RunningSwarm {
    fn drop(&mut self) {
        if let Err(e) = self.shutdown() {
            eprintln!("shoal: stopping swarm `{}`: {e:#}", self.name);
        }
    }
}

/// Collects exited children so they do not linger as zombies.
fn reap(children: &mut BTreeMap<u32, Child>) {
    children.retain(|_, child| matches!(child.try_wait(), Ok(None)));
}

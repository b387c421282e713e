//! A swarm started from this process: its robots, its clock (in lockstep) and
//! an observer of the roster. `shoal up` and the experiments drive it.

use std::collections::BTreeMap;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, bail};
use shoal_broker::liveness::{SwarmNodeState, remove_dead_nodes, swarm_nodes};
use shoal_broker::robot_streams::{self};
use shoal_broker::{Bus, BusLimits, HelperProgress, RosterReader, SampleCheck, names};
use shoal_physics::{Pose, Scenario};
use shoal_runtime::{SwarmMeta, SwarmRuntime};

use crate::clock::LockstepClock;
use crate::observer::Observer;
use crate::process::{Pinned, Tie, sibling_binary, start_agent, stop_processes};
use crate::sweeper::Sweeper;
use shoal_runtime::pid_alive;

/// How long robots get to leave cleanly before they are killed: a robot
/// leaves in milliseconds, but a thousand leaving at once queue on the
/// kernel for seconds (their shared mappings unmapped together), and every
/// one killed leaves resources the launcher must then clean up one node at
/// a time, a third of a second each (BENCHMARKS.md, "1000 robots in real time: the first run").
pub(crate) fn shutdown_grace(robots: usize) -> Duration {
    Duration::from_secs(5) + Duration::from_millis(15) * robots as u32
}
/// How long a helper (the recorder writing its footer) gets to leave cleanly.
const HELPER_GRACE: Duration = Duration::from_secs(10);
/// How long the launcher waits for its robots to announce themselves.
const STARTUP_TIMEOUT: Duration = Duration::from_secs(30);

pub struct RunningSwarm {
    pub name: String,
    pub scenario: Scenario,
    pub runtime: SwarmRuntime,
    pub observer: Observer,
    pub clock: Option<LockstepClock>,
    bus: Bus,
    roster: RosterReader,
    children: Children,
    /// Processes that serve the swarm (recorder, SLAM).
    helpers: Vec<Helper>,
    /// The recording the recorder writes, if any.
    recording: Option<std::path::PathBuf>,
    /// What stopping the swarm cost (helpers that had to be killed).
    stop_notes: Vec<String>,
    /// In lockstep, the clock waits for helpers (recorder, SLAM) to keep up.
    paces: Vec<Pace>,
    /// Helper progress reports rejected, by helpers no longer paced or as
    /// reports of ticks not yet sent.
    rejected_progress: u64,
    started: Instant,
    stopped: bool,
    /// Deaths already handed to the caller by `take_deaths`.
    reported_deaths: usize,
    /// Keep the robots' logs when the swarm stops (a failed start).
    keep_logs: bool,
    /// Removes the nodes of robots that died, off this loop.
    sweeper: Sweeper,
    /// Held while this launcher runs the swarm.
    _launch_lock: std::fs::File,
}

/// A helper's progress, which a lockstep clock must not outrun by more than
/// the buffers between robots and helpers (8 roster samples, 32 scans).
struct Pace {
    helper: &'static str,
    /// Ticks the clock may run ahead of this helper.
    lag: u64,
    progress: shoal_broker::Receiver<HelperProgress>,
    tick: Option<u64>,
}

/// A process that serves the swarm (recorder, SLAM, link).
struct Helper {
    binary: String,
    child: Child,
    log: crate::helper_log::HelperLog,
}

/// The name a helper's progress reports go by, which a lockstep clock paces to.
fn pace_name(binary: &str) -> &str {
    match binary {
        RECORDER_BINARY => "recorder",
        "shoal-slam" => "slam",
        other => other,
    }
}

/// Ticks a lockstep clock may run ahead of its recorder (within the
/// roster's buffer); SLAM gets none, so its estimates reach the robot the
/// next tick.
const RECORDER_LAG_TICKS: u64 = 4;
const SLAM_LAG_TICKS: u64 = 0;
pub const RECORDER_BINARY: &str = "shoal-viewer-log";
/// A helper silent this long is no longer waited for.
const HELPER_PATIENCE: Duration = Duration::from_secs(10);

impl Pace {
    /// Waits until the helper has read up to `tick - lag`;
    /// false when it stopped answering. Reports it rejects are added to `rejected`.
    fn wait_for(&mut self, tick: u64, rejected: &mut u64) -> Result<bool> {
        let started = Instant::now();
        loop {
            let mut newest = self.tick;
            self.progress.receive(|p| {
                // A helper cannot have read a tick the clock has not sent yet.
                if p.tick > tick {
                    *rejected += 1;
                } else {
                    newest = Some(newest.map_or(p.tick, |n: u64| n.max(p.tick)));
                }
            })?;
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

/// Where the recorder sends the run: a file, a live viewer, or both.
#[derive(Clone, Debug, Default)]
pub struct RecordOptions {
    pub out: Option<std::path::PathBuf>,
    /// With `out`: each robot's trajectories as TUM files here, for evo.
    pub tum: Option<std::path::PathBuf>,
    /// A Rerun viewer started now.
    pub viewer: bool,
    /// A Rerun viewer already running at this address.
    pub connect: Option<String>,
    /// How long the run lasts, if known: the recorder warns at the start
    /// when the disk will not hold it.
    pub expected_seconds: Option<f64>,
}

impl RecordOptions {
    /// Into a file (and TUM files beside it, if `tum`).
    pub fn file(out: &std::path::Path, tum: Option<&std::path::Path>) -> Self {
        Self {
            out: Some(out.to_owned()),
            tum: tum.map(ToOwned::to_owned),
            ..Self::default()
        }
    }

    pub fn wanted(&self) -> bool {
        self.out.is_some() || self.viewer || self.connect.is_some()
    }

    /// The recorder's arguments (beside `--swarm`).
    pub fn recorder_args(&self) -> Vec<std::ffi::OsString> {
        let mut args = Vec::new();
        if let Some(out) = &self.out {
            args.push(out.as_os_str().to_owned());
        }
        if let Some(tum) = &self.tum {
            args.extend(["--tum".into(), tum.as_os_str().to_owned()]);
        }
        if self.viewer {
            args.push("--viewer".into());
        }
        if let Some(addr) = &self.connect {
            args.extend(["--connect".into(), addr.into()]);
        }
        if let Some(seconds) = self.expected_seconds {
            args.extend(["--expected-seconds".into(), seconds.to_string().into()]);
        }
        args
    }
}

/// How this host's part of a swarm joins the other hosts' (`--link zenoh`).
#[derive(Clone, Debug, Default)]
pub struct LinkOptions {
    /// A Zenoh configuration file: mode, endpoints, TLS, access control.
    pub zenoh_config: Option<std::path::PathBuf>,
    pub listen: Vec<String>,
    pub connect: Vec<String>,
}

impl LinkOptions {
    fn args(&self, swarm: &str) -> Vec<std::ffi::OsString> {
        let mut args: Vec<std::ffi::OsString> = vec!["--swarm".into(), swarm.into()];
        if let Some(file) = &self.zenoh_config {
            args.extend(["--zenoh-config".into(), file.clone().into_os_string()]);
        }
        for endpoint in &self.listen {
            args.extend(["--listen".into(), endpoint.into()]);
        }
        for endpoint in &self.connect {
            args.extend(["--connect".into(), endpoint.into()]);
        }
        args
    }
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

/// How long the launcher waits for its link to have heard the other hosts.
const LINK_TIMEOUT: Duration = Duration::from_secs(20);
const LINK_BINARY: &str = "shoal-link";

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
        let lockstep = launch.lockstep;
        names::validate_swarm(name)?;
        if lockstep && launch.link.is_some() {
            bail!(
                "--lockstep cannot span hosts: its clock waits for every robot's answer through this \
                 machine's shared memory each tick, which across a network would pace the swarm to \
                 its slowest round trip; run a linked swarm in real time"
            );
        }
        crate::control::check_id_range(launch.first_id, scenario.agents.count)?;
        // Two launchers of one swarm started together would both pass the
        // check below; the lock makes the second one fail.
        let launch_lock = SwarmRuntime::locate(name)
            .lock("launch", false)
            .with_context(|| format!("swarm `{name}` is already being started or run"))?;
        // Robots and a launcher mean the swarm runs; a `shoal status` that
        // happens to be looking (a node of its own for a moment) does not. A
        // node under this very process's pid cannot be another launcher.
        let me = std::process::id() as i32;
        let launcher = names::tool_node(name, "launcher");
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
        let bus = Bus::join(
            name,
            &names::tool_node(name, "launcher"),
            BusLimits::of(&scenario.bus),
        )?;
        let roster = shoal_broker::roster::reader(&bus)?;
        let clock = if lockstep {
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
            helpers: Vec::new(),
            recording: None,
            stop_notes: Vec::new(),
            paces: Vec::new(),
            rejected_progress: 0,
            started: Instant::now(),
            stopped: false,
            reported_deaths: 0,
            keep_logs: false,
            sweeper,
            _launch_lock: launch_lock,
        };
        let count = swarm.scenario.agents.count;
        if let Some(link) = &launch.link {
            swarm.start_helper(LINK_BINARY, &link.args(name))?;
            swarm.await_link(launch.first_id, count)?;
        }
        let poses = swarm.scenario.start_poses(0, count);
        for (started, index) in inside_out(&poses).into_iter().enumerate() {
            // Starting many robots takes a while: Ctrl-C stops it at once,
            // and dropping the swarm stops the robots already started.
            if swarm.termination_requested() {
                bail!("interrupted while starting robots ({started} of {count} started)");
            }
            swarm.start(launch.first_id + index as u32, poses[index])?;
        }
        if let Some(clock) = &mut swarm.clock {
            let observer = &mut swarm.observer;
            let joined = clock.await_robots(&swarm.roster, count, STARTUP_TIMEOUT, |s| {
                observer.record(s)
            })?;
            if joined < count {
                swarm.children.reap(&swarm.runtime);
                swarm.keep_logs = true;
                bail!(
                    "only {joined} of {count} robots started{}; their logs are kept in {}",
                    swarm
                        .children
                        .deaths
                        .first()
                        .map(|d| format!("; {d}"))
                        .unwrap_or_default(),
                    swarm.runtime.dir.display()
                );
            }
        }
        Ok(swarm)
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
            if let Some(report) = self.runtime.read_link_report().filter(|r| r.ready) {
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

    /// Starts robot `id` at `pose` as a child of this process.
    pub fn start(&mut self, id: u32, pose: Pose) -> Result<()> {
        let child = start_agent(&self.name, id, pose, &self.runtime, self.tie())?;
        self.children.running.insert(id, child);
        Ok(())
    }

    /// Starts the recorder process: into a file, a live viewer, or both.
    pub fn record(&mut self, to: &RecordOptions) -> Result<()> {
        let mut args = to.recorder_args();
        args.extend(["--swarm".into(), self.name.clone().into()]);
        self.pace_to("recorder", RECORDER_LAG_TICKS)?;
        self.recording.clone_from(&to.out);
        self.start_helper(RECORDER_BINARY, &args)
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

    /// Starts a SLAM process following `follow`, with more `options`
    /// of `shoal-slam` (particles, learning, initial model).
    pub fn follow_with_slam(
        &mut self,
        follow: &shoal_slam::follow::Follow,
        options: &[String],
    ) -> Result<()> {
        let mut args: Vec<std::ffi::OsString> = vec![
            "--swarm".into(),
            self.name.clone().into(),
            "--follow".into(),
            follow.to_string().into(),
        ];
        args.extend(options.iter().map(Into::into));
        self.pace_to("slam", SLAM_LAG_TICKS)?;
        self.start_helper("shoal-slam", &args)
    }

    /// Lockstep children cannot go on without the clock in this process.
    fn tie(&self) -> Tie {
        if self.lockstep() {
            Tie::DiesWithLauncher
        } else {
            Tie::Child
        }
    }

    fn start_helper(&mut self, binary: &str, args: &[std::ffi::OsString]) -> Result<()> {
        let log = self.runtime.create_log(&helper_log_name(binary))?;
        let mut command = Command::new(sibling_binary(binary)?);
        command
            .args(args)
            .stdin(Stdio::null())
            .stdout(log.try_clone()?)
            .stderr(log);
        shoal_runtime::host::pass_to(&mut command);
        self.tie().apply(&mut command);
        let child = command
            .spawn()
            .with_context(|| format!("starting {binary}"))?;
        self.helpers.push(Helper {
            binary: binary.to_owned(),
            child,
            log: crate::helper_log::HelperLog::new(self.runtime.dir.join(helper_log_name(binary))),
        });
        Ok(())
    }

    pub fn recorder_pid(&self) -> Option<i32> {
        self.helpers
            .iter()
            .find(|h| h.binary == RECORDER_BINARY)
            .map(|h| h.child.id() as i32)
    }

    /// Warnings the helpers wrote into their logs since the last call
    /// (a disk filling up, a viewer that does not answer).
    pub fn take_helper_warnings(&mut self) -> Vec<String> {
        self.helpers
            .iter_mut()
            .flat_map(|h| h.log.new_warnings())
            .collect()
    }

    /// What stopping the swarm cost: helpers that had to be killed.
    pub fn stop_notes(&self) -> &[String] {
        &self.stop_notes
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

    /// Kills the recorder as a crash would (SIGKILL); not reported as a death.
    pub fn kill_recorder(&mut self) -> Result<()> {
        if let Some(index) = self
            .helpers
            .iter()
            .position(|h| h.binary == RECORDER_BINARY)
        {
            let Helper { mut child, .. } = self.helpers.remove(index);
            if let Some(process) = Pinned::child(&child) {
                process.signal(libc::SIGKILL)?;
            }
            child.wait().context("waiting for the killed recorder")?;
            remove_dead_nodes(&self.name)?;
        }
        self.paces.retain(|p| p.helper != "recorder");
        Ok(())
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

    /// Stops every robot of the swarm (also those started elsewhere), cleans
    /// the bus and removes the swarm's files.
    pub fn shutdown(&mut self) -> Result<()> {
        if self.stopped {
            return Ok(());
        }
        self.stopped = true;
        // The stop sweeps every dead node itself, once the robots are gone.
        self.sweeper.stop();
        // What died before the stop is reported; what the stop ends is not.
        self.children.reap(&self.runtime);
        self.reap_helpers();
        // Helpers go first: the recorder then does not log every robot
        // leaving, and gets time to write the recording's footer.
        for mut helper in std::mem::take(&mut self.helpers) {
            let killed = stop_processes(
                &Pinned::child(&helper.child).into_iter().collect::<Vec<_>>(),
                HELPER_GRACE,
            ) > 0;
            let _ = helper.child.wait();
            if killed {
                let note = self.killed_helper_note(&helper.binary);
                self.stop_notes.push(note);
            }
        }
        let pids = self.agent_pids();
        let mut processes: Vec<Pinned> = self
            .children
            .running
            .values()
            .filter_map(Pinned::child)
            .collect();
        // Robots started elsewhere (`shoal restart`, `spawn`) are known only
        // by the pid their bus node names; pinning checks it is still one of ours.
        let me = std::process::id() as i32;
        for node in swarm_nodes(&self.name)? {
            if node.agent_id.is_some()
                && node.state == SwarmNodeState::Alive
                && node.pid != me
                && !pids.contains(&node.pid)
            {
                processes.extend(Pinned::shoal_process(node.pid));
            }
        }
        stop_processes(&processes, shutdown_grace(processes.len()));
        for child in self.children.running.values_mut() {
            let _ = child.wait();
        }
        self.children.running.clear();
        remove_dead_nodes(&self.name)?;
        if self.keep_logs || !self.children.deaths.is_empty() {
            self.runtime
                .remove_all_but_logs()
                .with_context(|| format!("clearing {}", self.runtime.dir.display()))?;
        } else {
            self.runtime
                .remove()
                .with_context(|| format!("removing {}", self.runtime.dir.display()))?;
        }
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

/// The robots this process started, and how those that ended did.
#[derive(Default)]
struct Children {
    running: BTreeMap<u32, Child>,
    deaths: Vec<Death>,
}

/// A robot or helper that ended without a user or the launcher asking it to.
#[derive(Clone, Debug, PartialEq)]
pub struct Death {
    /// `robot 3`, or the helper's binary.
    pub who: String,
    pub status: String,
    /// The last lines of its log, which say why.
    pub log_tail: Vec<String>,
    /// A crash (an error exit, a panic, a fault), not a kill from outside.
    pub crashed: bool,
}

impl std::fmt::Display for Death {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}", self.who, self.status)?;
        for line in &self.log_tail {
            write!(f, "\n    | {line}")?;
        }
        Ok(())
    }
}

/// Lines of a dead process's log shown to the user.
const LOG_TAIL_LINES: usize = 6;

/// The log of helper `binary` in the swarm's folder.
fn helper_log_name(binary: &str) -> String {
    format!("{binary}.log")
}

impl Death {
    /// The death of `who`, with the end of its log `log`; none for a clean
    /// exit (status 0), which a process makes only when asked to (SIGTERM,
    /// or the Ctrl-C that reaches the whole terminal's process group).
    fn unless_clean(
        who: String,
        status: std::process::ExitStatus,
        runtime: &SwarmRuntime,
        log: &str,
    ) -> Option<Self> {
        (!status.success()).then(|| Self::of(who, status, runtime.log_tail(log, LOG_TAIL_LINES)))
    }

    fn of(who: String, status: std::process::ExitStatus, log_tail: Vec<String>) -> Self {
        use std::os::unix::process::ExitStatusExt;
        let (status, crashed) = match (status.code(), status.signal()) {
            (Some(code), _) => (format!("exited with status {code}"), code != 0),
            // Killed from outside (kill -9, SIGTERM, a closed terminal, the
            // kernel's OOM killer): said, but not a crash of ours.
            (_, Some(sig))
                if [libc::SIGKILL, libc::SIGTERM, libc::SIGINT, libc::SIGHUP].contains(&sig) =>
            {
                (
                    format!("was killed by signal {sig} ({})", signal_name(sig)),
                    false,
                )
            }
            (_, Some(sig)) => (format!("died of signal {sig} ({})", signal_name(sig)), true),
            _ => (format!("ended: {status}"), true),
        };
        Self {
            who,
            status,
            log_tail,
            crashed,
        }
    }
}

fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        libc::SIGINT => "SIGINT",
        libc::SIGHUP => "SIGHUP",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGABRT => "SIGABRT",
        libc::SIGBUS => "SIGBUS",
        libc::SIGFPE => "SIGFPE",
        libc::SIGILL => "SIGILL",
        _ => "signal",
    }
}

impl Children {
    /// Collects exited robots so they do not linger as zombies, and notes
    /// those that nobody asked to stop.
    /// Returns how many ended.
    fn reap(&mut self, runtime: &SwarmRuntime) -> usize {
        let mut ended = Vec::new();
        self.running.retain(|id, child| match child.try_wait() {
            Ok(None) => true,
            Ok(Some(status)) => {
                ended.push((*id, status));
                false
            }
            Err(_) => false,
        });
        let count = ended.len();
        for (id, status) in ended {
            let asked = runtime.take_stopped_by_user(id);
            if !asked {
                let log = SwarmRuntime::agent_log_name(id);
                self.deaths.extend(Death::unless_clean(
                    format!("robot {id}"),
                    status,
                    runtime,
                    &log,
                ));
            }
        }
        count
    }
}

impl RunningSwarm {
    /// Notes helpers (recorder, SLAM) that ended on their own; a lockstep
    /// clock no longer waits for them.
    fn reap_helpers(&mut self) {
        let runtime = &self.runtime;
        let deaths = &mut self.children.deaths;
        self.helpers.retain_mut(|h| match h.child.try_wait() {
            Ok(None) => true,
            Ok(Some(status)) => {
                let log = helper_log_name(&h.binary);
                deaths.extend(Death::unless_clean(h.binary.clone(), status, runtime, &log));
                false
            }
            Err(_) => false,
        });
        let helpers = &self.helpers;
        self.paces
            .retain(|p| helpers.iter().any(|h| pace_name(&h.binary) == p.helper));
    }

    /// What killing helper `binary` after its grace cost, and for the
    /// recorder, the repair of its file's end: a write cut short by the kill
    /// would leave a partial message that readers refuse.
    fn killed_helper_note(&self, binary: &str) -> String {
        let mut note = format!(
            "{binary} did not stop within {} s of SIGTERM and was killed",
            HELPER_GRACE.as_secs()
        );
        if binary == RECORDER_BINARY
            && let Some(recording) = &self.recording
        {
            note.push_str(&format!(
                "; {} ends at its last flush (up to a second before the kill), without the \
                 footer a viewer seeks with",
                recording.display()
            ));
            let repair = sibling_binary(RECORDER_BINARY).and_then(|bin| {
                Command::new(bin)
                    .arg("--repair")
                    .arg(recording)
                    .stdin(Stdio::null())
                    .output()
                    .context("running the recorder's repair")
            });
            match repair {
                Ok(out) => {
                    let said = String::from_utf8_lossy(&out.stderr);
                    let said = said.trim().trim_start_matches("shoal-viewer-log: ");
                    note.push_str(&format!("; {said}"));
                }
                Err(e) => note.push_str(&format!("; its end was not checked: {e:#}")),
            }
        }
        note
    }
}

/// The order to start robots at `poses` in: from the middle of the group
/// outwards, so each robot starts beside robots already running. Started
/// in id order, robots scattered over the whole start region, each found too
/// few neighbours, listened as far as it could (the widest ring: about 40
/// cells where it needs 9), and every robot started after it connected to
/// all those listeners (BENCHMARKS.md, "1000 robots: memory, start-up and the bus").
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

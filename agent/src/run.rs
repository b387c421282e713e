//! The robot's loop: hear the cells around it, step, publish.

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};
use shoal_broker::liveness::sweep_dead_nodes;
use shoal_broker::robot_streams;
use shoal_broker::{
    Bus, BusLimits, BusSection, CellExchange, ClockListener, EstimateSample, Health, ModelUpdate,
    PoseSample, Receiver, RosterPublisher, SampleCheck, ScanSample, Sender, names,
};
use shoal_physics::Pose;
use shoal_runtime::SwarmRuntime;
use shoal_scenario::Scenario;

use crate::member::{Heard, Member};
use crate::neighbours::NeighbourTable;

/// How often a robot notes its last pose for `shoal restart`, and at most how
/// often it sweeps the bus for dead nodes.
const HOUSEKEEPING_PERIOD: Duration = Duration::from_secs(1);

pub struct AgentOptions {
    pub swarm: String,
    pub id: u32,
    pub start: Pose,
}

pub fn run(options: AgentOptions) -> Result<()> {
    let runtime = SwarmRuntime::locate(&options.swarm);
    let scenario = runtime.read_scenario()?;
    let meta = runtime.read_meta()?;
    let pid = std::process::id();
    let bus: BusSection = scenario.section()?;
    let mut member = Member::new(options.id, options.start, &scenario, &bus, pid);
    let mut ports = Ports::open(&options, &scenario, &bus, meta.lockstep)?;
    tracing::info!(
        id = options.id,
        pid,
        lockstep = meta.lockstep,
        "robot joined swarm {}",
        options.swarm
    );
    let period_s = scenario.timing.period_s;
    let stale_after = Duration::from_secs_f64(period_s * scenario.timing.stale_periods);

    let mut last = announce(&mut member, &mut ports, period_s)?;
    // In lockstep a robot's first tick only republishes where it stands: robots
    // that announced themselves before it subscribed were not heard, but every
    // robot hears everyone's first-tick pose, so all views agree from then on.
    let mut settled = ports.clock.is_none();
    let mut last_housekeeping = Instant::now();
    let mut pose_note = runtime.pose_note(options.id)?;
    // When this robot first noticed a neighbour whose process is gone,
    // since the last sweep it took part in.
    let mut dead_noticed: Option<std::time::SystemTime> = None;
    while !ports.bus.termination_requested() {
        let Some((tick, sim_time)) = next_tick(&ports, meta.epoch_unix_ms, period_s, last.tick)?
        else {
            continue;
        };
        if !settled {
            settled = true;
            (last.tick, last.sim_time) = (tick, sim_time);
            ports.say(&mut last)?;
            continue;
        }
        let (current, dropped) = ports.hear(tick, stale_after, &mut member)?;
        let heard = Heard {
            tick,
            sim_time,
            now_s: match ports.clock {
                Some(_) => sim_time,
                None => since_epoch_s(meta.epoch_unix_ms),
            },
            current: &current,
            dropped: &dropped,
            rejected: ports.rejected(),
        };
        let said = member.period(&heard, &last, &scenario);
        if !said.died_nearby.is_empty() {
            tracing::info!(died_nearby = ?said.died_nearby, "dropped robots that fell silent nearby");
        }
        if process_gone_nearby(&said.died_nearby, &dropped) {
            dead_noticed.get_or_insert_with(std::time::SystemTime::now);
        }
        ports.scans.publish(&said.scan)?;
        last = said.pose;
        ports.say(&mut last)?;
        ports.listen(&last, member.listen_radius());
        if last_housekeeping.elapsed() >= HOUSEKEEPING_PERIOD {
            last_housekeeping = Instant::now();
            if let Err(e) = pose_note.note_if_moved([last.x, last.y, last.theta]) {
                tracing::warn!("cannot note last pose: {e}");
            }
            sweep_if_noticed(&runtime, &options.swarm, &mut dead_noticed);
        }
    }
    // Once, on the way out, a whole new file: the last pose is there even if
    // the noted one was removed meanwhile.
    runtime
        .write_last_pose(options.id, [last.x, last.y, last.theta])
        .context("noting the last pose on the way out")?;
    tracing::info!(id = options.id, tick = last.tick, "robot left the swarm");
    Ok(())
}

/// The robot's first pose, standing where it starts, and the cells it
/// listens to; in lockstep it is said at once, so the clock waits for this
/// robot from the next tick on.
fn announce(member: &mut Member, ports: &mut Ports, period_s: f64) -> Result<PoseSample> {
    let mut last = member.standing(0, period_s);
    ports.listen(&last, member.listen_radius());
    if let Some(clock) = &ports.clock {
        last = member.standing(clock.latest()?.map_or(0, |t| t.tick), period_s);
        ports.say(&mut last)?;
    }
    Ok(last)
}

/// The tick after `last_tick` and its time: the lockstep clock's (`None`
/// if it did not advance within 100 ms), or the next period of real time.
fn next_tick(
    ports: &Ports,
    epoch_unix_ms: u64,
    period_s: f64,
    last_tick: u64,
) -> Result<Option<(u64, f64)>> {
    Ok(match &ports.clock {
        Some(clock) => clock
            .wait_after(last_tick, Duration::from_millis(100))?
            .map(|t| (t.tick, t.sim_time)),
        None => Some(wait_for_next_period(epoch_unix_ms, period_s, last_tick)),
    })
}

/// Whether a robot dropped as silent nearby (`died_nearby`, among
/// `dropped`) has a process that is really gone. A robot can fall silent
/// because the machine is overloaded, not dead; sweeping lists every node
/// on the machine, which would only load it more.
fn process_gone_nearby(died_nearby: &[u32], dropped: &[PoseSample]) -> bool {
    dropped
        .iter()
        .filter(|s| died_nearby.contains(&s.agent_id))
        .any(|s| !shoal_runtime::pid_alive(s.pid as i32))
}

/// Sweeps the swarm's dead nodes if this robot noticed a death since the
/// last sweep. Its neighbours noticed the same death: one of them sweeps,
/// and the others take its result; a sweep under way is waited for at the
/// next housekeeping, not here.
fn sweep_if_noticed(
    runtime: &SwarmRuntime,
    swarm: &str,
    dead_noticed: &mut Option<std::time::SystemTime>,
) {
    if let Some(noticed) = *dead_noticed
        && sweep_dead_nodes(runtime, swarm, noticed, false, || true)
    {
        *dead_noticed = None;
    }
}

/// A robot's ports on the bus, and what it keeps of what it heard.
struct Ports {
    bus: Bus,
    cells: CellExchange,
    roster: RosterPublisher,
    clock: Option<ClockListener>,
    scans: Sender<ScanSample>,
    model_updates: Receiver<ModelUpdate>,
    estimates: Receiver<EstimateSample>,
    check: SampleCheck,
    table: NeighbourTable,
    listening: Listening,
}

impl Ports {
    fn open(
        options: &AgentOptions,
        scenario: &Scenario,
        section: &BusSection,
        lockstep: bool,
    ) -> Result<Self> {
        let bus = Bus::join(
            &options.swarm,
            &names::agent_node(&options.swarm, options.id),
            BusLimits::of(section),
        )?;
        Ok(Self {
            cells: CellExchange::new(section.cell_size),
            roster: shoal_broker::roster::publisher(&bus)?,
            clock: lockstep.then(|| ClockListener::new(&bus)).transpose()?,
            scans: robot_streams::scan_publisher(&bus, options.id)?,
            model_updates: robot_streams::model_subscriber(&bus, options.id)?,
            estimates: robot_streams::estimate_subscriber(&bus, options.id)?,
            check: SampleCheck::for_scenario(scenario),
            table: NeighbourTable::new(options.id),
            listening: Listening::default(),
            bus,
        })
    }

    /// The neighbour poses current for `tick` and those that fell silent;
    /// what SLAM sent goes to `member`.
    fn hear(
        &mut self,
        tick: u64,
        stale_after: Duration,
        member: &mut Member,
    ) -> Result<(Vec<PoseSample>, Vec<PoseSample>)> {
        let now = Instant::now();
        let (check, table) = (&mut self.check, &mut self.table);
        self.cells.receive(|sample| {
            if check.accept(&sample) {
                table.insert(sample, now);
            }
        })?;
        // What a SLAM process learned about this robot replaces its own
        // guesses; receivers pass only what passes its wire check.
        self.model_updates.receive(|update| member.learn(&update))?;
        self.estimates
            .receive(|estimate| member.correct(&estimate))?;
        Ok(if self.clock.is_some() {
            self.table.lockstep_view(tick)
        } else {
            self.table.realtime_view(now, stale_after)
        })
    }

    /// Bus input rejected so far, by every check of this robot.
    fn rejected(&self) -> u64 {
        self.check.rejected
            + self.cells.rejected()
            + self.model_updates.rejected()
            + self.estimates.rejected()
            + self.clock.as_ref().map_or(0, |c| c.rejected())
    }

    /// Publishes `pose` to the cell and the roster, and acknowledges the
    /// tick in lockstep. A full cell hides this robot from its neighbours
    /// this period; it says so in its health and tries again next period.
    fn say(&mut self, pose: &mut PoseSample) -> Result<()> {
        if let Err(e) = self.cells.publish(&self.bus, pose) {
            pose.health |= Health::CELL_FULL;
            tracing::warn!("{:#}", anyhow::Error::from(e));
        }
        self.roster.publish(pose)?;
        if let Some(clock) = &self.clock {
            clock.acknowledge()?;
        }
        Ok(())
    }

    /// Listens to the cells within `radius` of `pose`.
    fn listen(&mut self, pose: &PoseSample, radius: f64) {
        self.listening
            .update(&self.bus, &mut self.cells, pose, radius);
    }
}

/// Whether listening to the cells around works; said once when it starts
/// failing and once when it works again, since a failure that lasts would
/// otherwise fill the log every period.
#[derive(Default)]
struct Listening {
    failing: bool,
}

impl Listening {
    /// Listens to the cells within `radius` of `pose`.
    fn update(&mut self, bus: &Bus, cells: &mut CellExchange, pose: &PoseSample, radius: f64) {
        match cells.listen(bus, (pose.x, pose.y), radius) {
            Ok(()) if self.failing => {
                self.failing = false;
                tracing::info!("listening to the cells around again");
            }
            Ok(()) => {}
            Err(e) if !self.failing => {
                self.failing = true;
                tracing::warn!("{:#}; retrying every period", anyhow::Error::from(e));
            }
            Err(_) => {}
        }
    }
}

/// Wall-clock seconds since the swarm's epoch.
fn since_epoch_s(epoch_unix_ms: u64) -> f64 {
    let now_us = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64);
    now_us.saturating_sub(epoch_unix_ms * 1000) as f64 / 1e6
}

/// Sleeps until the next period boundary of the swarm's shared clock and
/// returns its tick number and time.
fn wait_for_next_period(epoch_unix_ms: u64, period_s: f64, last_tick: u64) -> (u64, f64) {
    let elapsed = || since_epoch_s(epoch_unix_ms);
    let next_tick = ((elapsed() / period_s).floor() as u64 + 1).max(last_tick + 1);
    let due = next_tick as f64 * period_s;
    let wait = due - elapsed();
    if wait > 0.0 {
        std::thread::sleep(Duration::from_secs_f64(wait));
    }
    (next_tick, due)
}

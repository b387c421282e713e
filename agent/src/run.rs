//! The robot's loop: hear the cells around it, step, publish.

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};
use shoal_broker::liveness::remove_dead_nodes;
use shoal_broker::robot_streams;
use shoal_broker::{
    Bus, BusLimits, CellExchange, ClockListener, Health, PoseSample, RosterPublisher, SampleCheck,
    names,
};
use shoal_physics::Pose;
use shoal_runtime::SwarmRuntime;

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
    let bus = Bus::join(
        &options.swarm,
        &names::agent_node(&options.swarm, options.id),
        BusLimits::of(&scenario.bus),
    )?;
    let mut cells = CellExchange::new(scenario.bus.cell_size);
    let roster = shoal_broker::roster::publisher(&bus)?;
    let clock = if meta.lockstep {
        Some(ClockListener::new(&bus)?)
    } else {
        None
    };
    let mut check = SampleCheck::for_scenario(&scenario);
    let pid = std::process::id();
    let mut member = Member::new(options.id, options.start, &scenario, pid);
    let scans = robot_streams::scan_publisher(&bus, options.id)?;
    let model_updates = robot_streams::model_subscriber(&bus, options.id)?;
    let estimates = robot_streams::estimate_subscriber(&bus, options.id)?;
    let mut table = NeighbourTable::new(options.id);
    let period = Duration::from_secs_f64(scenario.timing.period_s);
    let stale_after = period.mul_f64(scenario.timing.stale_periods);
    tracing::info!(
        id = options.id,
        pid,
        lockstep = meta.lockstep,
        "robot joined swarm {}",
        options.swarm
    );

    let mut last = member.standing(0, scenario.timing.period_s);
    let mut listening = Listening::default();
    listening.update(&bus, &mut cells, &last, member.range.listen_ring);
    if let Some(clock) = &clock {
        // Announce ourselves so the clock waits for us from the next tick on.
        last = member.standing(
            clock.latest()?.map_or(0, |t| t.tick),
            scenario.timing.period_s,
        );
        publish(&bus, &mut cells, &roster, &mut last)?;
        clock.acknowledge()?;
    }

    // In lockstep a robot's first tick only republishes where it stands: robots
    // that announced themselves before it subscribed were not heard, but every
    // robot hears everyone's first-tick pose, so all views agree from then on.
    let mut settled = clock.is_none();
    let mut last_housekeeping = Instant::now();
    let mut dead_suspected = false;
    while !bus.termination_requested() {
        let (tick, sim_time) = match &clock {
            Some(clock) => match clock.wait_after(last.tick, Duration::from_millis(100))? {
                Some(t) => (t.tick, t.sim_time),
                None => continue,
            },
            None => wait_for_next_period(meta.epoch_unix_ms, scenario.timing.period_s, last.tick),
        };
        if !settled {
            settled = true;
            (last.tick, last.sim_time) = (tick, sim_time);
            publish(&bus, &mut cells, &roster, &mut last)?;
            if let Some(clock) = &clock {
                clock.acknowledge()?;
            }
            continue;
        }
        let now = Instant::now();
        cells.receive(|sample| {
            if check.accept(&sample) {
                table.insert(sample, now);
            }
        })?;
        let (current, dropped) = if clock.is_some() {
            table.lockstep_view(tick)
        } else {
            table.realtime_view(now, stale_after)
        };
        // What a SLAM process learned about this robot replaces its own
        // guesses; subscribers pass only what passes its wire check.
        model_updates.receive(|update| member.learn(&update))?;
        estimates.receive(|estimate| member.correct(&estimate))?;
        let rejected = check.rejected
            + cells.rejected()
            + model_updates.rejected()
            + estimates.rejected()
            + clock.as_ref().map_or(0, |c| c.rejected());
        let heard = Heard {
            tick,
            sim_time,
            current: &current,
            dropped: &dropped,
            rejected,
        };
        let said = member.period(&heard, &last, &scenario);
        if !said.died_nearby.is_empty() {
            tracing::info!(died_nearby = ?said.died_nearby, "dropped robots that fell silent nearby");
            dead_suspected = true;
        }
        scans.publish(&said.scan)?;
        last = said.pose;
        publish(&bus, &mut cells, &roster, &mut last)?;
        if let Some(clock) = &clock {
            clock.acknowledge()?;
        }
        listening.update(&bus, &mut cells, &last, member.range.listen_ring);
        if last_housekeeping.elapsed() >= HOUSEKEEPING_PERIOD {
            last_housekeeping = Instant::now();
            if let Err(e) = runtime.write_last_pose(options.id, [last.x, last.y, last.theta]) {
                tracing::warn!("cannot note last pose: {e}");
            }
            if std::mem::take(&mut dead_suspected) {
                match remove_dead_nodes(&options.swarm) {
                    Ok(0) => {}
                    Ok(n) => tracing::info!("removed the stale resources of {n} dead nodes"),
                    Err(e) => tracing::warn!("{:#}", anyhow::Error::from(e)),
                }
            }
        }
    }
    runtime
        .write_last_pose(options.id, [last.x, last.y, last.theta])
        .context("noting the last pose on the way out")?;
    tracing::info!(id = options.id, tick = last.tick, "robot left the swarm");
    Ok(())
}

/// Whether listening to the cells around works; said once when it starts
/// failing and once when it works again, since a failure that lasts would
/// otherwise fill the log every period.
#[derive(Default)]
struct Listening {
    failing: bool,
}

impl Listening {
    /// Listens to the cells within `ring` of the cell `pose` stands in.
    fn update(&mut self, bus: &Bus, cells: &mut CellExchange, pose: &PoseSample, ring: u32) {
        let center = cells.cell_of(pose.x, pose.y);
        match cells.listen(bus, center, ring) {
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

fn publish(
    bus: &Bus,
    cells: &mut CellExchange,
    roster: &RosterPublisher,
    sample: &mut PoseSample,
) -> Result<()> {
    if let Err(e) = cells.publish(bus, sample) {
        // A full cell hides this robot from its neighbours this period; it
        // says so in its health and tries again next period.
        sample.health |= Health::CELL_FULL;
        tracing::warn!("{:#}", anyhow::Error::from(e));
    }
    roster.publish(sample)?;
    Ok(())
}

/// Sleeps until the next period boundary of the swarm's shared clock and
/// returns its tick number and time.
fn wait_for_next_period(epoch_unix_ms: u64, period_s: f64, last_tick: u64) -> (u64, f64) {
    let elapsed = || {
        let now_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_millis() as u64);
        now_ms.saturating_sub(epoch_unix_ms) as f64 / 1000.0
    };
    let next_tick = ((elapsed() / period_s).floor() as u64 + 1).max(last_tick + 1);
    let due = next_tick as f64 * period_s;
    let wait = due - elapsed();
    if wait > 0.0 {
        std::thread::sleep(Duration::from_secs_f64(wait));
    }
    (next_tick, due)
}

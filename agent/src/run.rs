//! The robot's loop: hear the cells around it, step, publish.

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};
use shoal_broker::liveness::remove_dead_nodes;
use shoal_broker::robot_streams;
use shoal_broker::{
    Bus, BusLimits, CellExchange, ClockListener, Health, MAX_BEAMS, MAX_NEIGHBOURS, PoseSample,
    RosterPublisher, SampleCheck, ScanSample, SwarmRuntime, names,
};
use shoal_physics::{Neighbour, Pose, Scenario};

use crate::neighbours::NeighbourTable;
use crate::robot::Robot;
use crate::sensing::SensingRange;

/// Poses more than this far outside the map are implausible.
const MAP_MARGIN_M: f64 = 1.0;
/// How often a robot notes its last pose for `shoal restart`, and at most how
/// often it sweeps the bus for dead nodes.
const HOUSEKEEPING_PERIOD: Duration = Duration::from_secs(1);
/// How many ticks of believed poses a robot keeps, to apply late SLAM estimates.
const BELIEF_HISTORY_TICKS: usize = 64;
/// A robot sensing fewer robots than this listens further.
const WIDEN_BELOW: usize = 3;

pub struct AgentOptions {
    pub swarm: String,
    pub id: u32,
    pub start: Pose,
}

pub fn run(options: AgentOptions) -> Result<()> {
    let runtime = SwarmRuntime::locate(&options.swarm);
    let scenario = Scenario::from_file(&runtime.scenario_path())?;
    let meta = runtime.read_meta()?;
    let limits = BusLimits {
        max_per_cell: scenario.bus.max_per_cell,
        max_listeners_per_cell: scenario.bus.max_listeners_per_cell,
        ..BusLimits::default()
    };
    let bus = Bus::join(
        &options.swarm,
        &names::agent_node(&options.swarm, options.id),
        limits,
    )?;
    let mut cells = CellExchange::new(scenario.bus.cell_size);
    let roster = RosterPublisher::new(&bus)?;
    let clock = if meta.lockstep {
        Some(ClockListener::new(&bus)?)
    } else {
        None
    };
    let mut check = SampleCheck::for_map(scenario.arena.width, scenario.arena.height, MAP_MARGIN_M);
    let mut robot = Robot::new(options.id, options.start, &scenario);
    let scans = robot_streams::scan_publisher(&bus, options.id)?;
    let model_updates = robot_streams::model_subscriber(&bus, options.id)?;
    let estimates = robot_streams::estimate_subscriber(&bus, options.id)?;
    let mut odometry_history: std::collections::VecDeque<(u64, Pose)> =
        std::collections::VecDeque::new();
    let mut table = NeighbourTable::new(options.id);
    let mut range = SensingRange::new(scenario.bus.max_ring);
    let period = Duration::from_secs_f64(scenario.timing.period_s);
    let stale_after = period.mul_f64(scenario.timing.stale_periods);
    let pid = std::process::id();
    tracing::info!(
        id = options.id,
        pid,
        lockstep = meta.lockstep,
        "robot joined swarm {}",
        options.swarm
    );

    let mut last = PoseSample::standing(
        options.id,
        pid,
        0,
        options.start.x,
        options.start.y,
        options.start.theta,
    );
    let center = cells.cell_of(last.x, last.y);
    if let Err(e) = cells.listen(&bus, center, range.listen_ring) {
        tracing::warn!("{e}");
    }
    if let Some(clock) = &clock {
        // Announce ourselves so the clock waits for us from the next tick on.
        last.tick = clock.latest()?.map_or(0, |t| t.tick);
        last.sim_time = last.tick as f64 * scenario.timing.period_s;
        publish(&bus, &mut cells, &roster, &mut last)?;
        clock.acknowledge()?;
    }

    // In lockstep a robot's first tick only republishes where it stands: robots
    // that announced themselves before it subscribed were not heard, but every
    // robot hears everyone's first-tick pose, so all views agree from then on.
    let mut settled = clock.is_none();
    let mut last_housekeeping = Instant::now();
    let mut dead_suspected = false;
    // Whether the last attempt to listen to the cells around failed.
    let mut listen_failing = false;
    while !bus.termination_requested() {
        let (tick, sim_time) = match &clock {
            Some(clock) => match clock.wait_after(last.tick, Duration::from_millis(100))? {
                Some(t) => (t.tick, t.sim_time),
                None => continue,
            },
            None => {
                let (tick, sim_time) =
                    wait_for_next_period(meta.epoch_unix_ms, scenario.timing.period_s, last.tick);
                (tick, sim_time)
            }
        };
        if !settled {
            settled = true;
            last.tick = tick;
            last.sim_time = sim_time;
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
        let (heard, dropped) = if clock.is_some() {
            table.lockstep_view(tick)
        } else {
            table.realtime_view(now, stale_after)
        };
        let me = robot.body.pose.position();
        let radius = range.sense_radius(scenario.bus.cell_size);
        // A robot that fell silent nearby probably died; one that walked out
        // of earshot did not. Only the first is worth sweeping the bus for.
        let died_nearby: Vec<u32> = dropped
            .iter()
            .filter(|s| glam::DVec2::new(s.x, s.y).distance(me) <= radius)
            .map(|s| s.agent_id)
            .collect();
        if !died_nearby.is_empty() {
            tracing::info!(?died_nearby, "dropped robots that fell silent nearby");
            dead_suspected = true;
        }
        let sensed: Vec<Neighbour> = heard
            .iter()
            .map(|s| Neighbour {
                id: s.agent_id,
                position: glam::DVec2::new(s.x, s.y),
            })
            .filter(|n| n.position.distance(me) <= radius)
            .collect();
        let inner_radius =
            SensingRange::radius(range.sense_ring.saturating_sub(1), scenario.bus.cell_size);
        let within_inner = sensed
            .iter()
            .filter(|n| n.position.distance(me) <= inner_radius)
            .count();

        // What a SLAM process learned about this robot replaces its own guesses.
        // The subscriber passes only updates that pass `ModelUpdate::check`.
        model_updates.receive(|update| apply_model_update(&mut robot.belief, &update))?;
        // An estimate is of a past tick: keep the motion believed since then.
        estimates.receive(|e| {
            let estimate = Pose::new(e.x, e.y, e.theta);
            // Dead reckoning is never corrected, so the motion since the
            // estimate's tick is the same however many corrections came in between.
            if let Some((_, then)) = odometry_history.iter().find(|(t, _)| *t == e.tick) {
                robot.believed = estimate.compose(&robot.odometry.relative_to(then));
            }
        })?;

        let before = robot.body.pose;
        robot.body.sim_time = sim_time;
        let decision = robot.step(&sensed, &scenario);
        let after = robot.body.pose;
        let bodies: Vec<glam::DVec2> = sensed.iter().map(|n| n.position).collect();
        let ranges = robot.scan(&scenario, &bodies);
        let mut scan = ScanSample {
            agent_id: options.id,
            pid,
            tick,
            sim_time,
            command: decision.command.index() as u32,
            bumped: u32::from(decision.outcome.bumped),
            beam_count: ranges.len().min(MAX_BEAMS) as u32,
            reserved: 0,
            field_of_view: scenario.sensor.field_of_view,
            max_range: scenario.sensor.max_range,
            ranges: [0.0; MAX_BEAMS],
        };
        for (slot, range) in scan.ranges.iter_mut().zip(&ranges) {
            *slot = *range as f32;
        }
        scans.publish(&scan)?;
        let mut health = 0;
        if decision.outcome.bumped {
            health |= Health::BUMPED;
        }
        if sensed.is_empty() {
            health |= Health::ISOLATED;
        }
        let rejected = check.rejected
            + cells.rejected()
            + model_updates.rejected()
            + estimates.rejected()
            + clock.as_ref().map_or(0, |c| c.rejected());
        if rejected > 0 {
            health |= Health::REJECTED_INPUT;
        }
        let mut neighbours = [0; MAX_NEIGHBOURS];
        for (slot, n) in neighbours.iter_mut().zip(&decision.tracked) {
            *slot = n.id;
        }
        let dt = scenario.timing.period_s;
        last = PoseSample {
            tick,
            sim_time,
            x: after.x,
            y: after.y,
            theta: after.theta,
            believed_x: robot.believed.x,
            believed_y: robot.believed.y,
            believed_theta: robot.believed.theta,
            vx: (after.x - before.x) / dt,
            vy: (after.y - before.y) / dt,
            command: decision.command.index() as u32,
            health,
            visible: sensed.len() as u32,
            neighbour_count: decision.tracked.len().min(MAX_NEIGHBOURS) as u32,
            neighbours,
            ..last
        };
        publish(&bus, &mut cells, &roster, &mut last)?;
        if let Some(clock) = &clock {
            clock.acknowledge()?;
        }
        odometry_history.push_back((tick, robot.odometry));
        if odometry_history.len() > BELIEF_HISTORY_TICKS {
            odometry_history.pop_front();
        }

        // Widen only when nearly alone: a robot on the edge of a formation
        // legitimately sees fewer than it tracks.
        range.update(
            tick,
            sensed.len(),
            within_inner,
            scenario.formation.neighbours.min(WIDEN_BELOW),
        );
        let center = cells.cell_of(after.x, after.y);
        // Said once when listening starts failing, and once when it works
        // again: a failure that lasts would otherwise fill the log every period.
        match cells.listen(&bus, center, range.listen_ring) {
            Ok(()) if listen_failing => {
                listen_failing = false;
                tracing::info!("listening to the cells around again");
            }
            Ok(()) => {}
            Err(e) if !listen_failing => {
                listen_failing = true;
                tracing::warn!("{e}; retrying every period");
            }
            Err(_) => {}
        }
        if last_housekeeping.elapsed() >= HOUSEKEEPING_PERIOD {
            last_housekeeping = Instant::now();
            if let Err(e) = runtime.write_last_pose(options.id, [after.x, after.y, after.theta]) {
                tracing::warn!("cannot note last pose: {e}");
            }
            if dead_suspected {
                dead_suspected = false;
                match remove_dead_nodes(&options.swarm) {
                    Ok(0) => {}
                    Ok(n) => tracing::info!("removed the stale resources of {n} dead nodes"),
                    Err(e) => tracing::warn!("{e}"),
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

/// Adopts one learned mixture; the update has passed its wire check, so
/// its command and parameter name something.
fn apply_model_update(model: &mut shoal_physics::MotionModel, update: &shoal_broker::ModelUpdate) {
    if let Some((command, param)) = update.target() {
        *model.command_mut(command).param_mut(param) = update.mixture();
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
        tracing::warn!("{e}");
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

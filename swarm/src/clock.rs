//! The lockstep clock driver: one tick at a time, waiting for every live robot.

use std::collections::{HashMap, HashSet};
use std::time::{Duration, Instant};

use anyhow::Result;
use shoal_broker::{Bus, ClockSource, ClockTick, PoseSample, RosterReader};

/// A robot that has not stepped after this long is dropped from the wait.
const HUNG_AFTER: Duration = Duration::from_secs(5);
/// How long to wait for an acknowledgement before checking who died.
const LIVENESS_POLL: Duration = Duration::from_millis(20);

pub struct LockstepClock {
    source: ClockSource,
    pub tick: u64,
    pub period_s: f64,
    /// Robots that must step each tick, with their pids.
    expected: HashMap<u32, i32>,
    /// Robots that announced themselves during the current tick; they step from the next.
    joining: HashMap<u32, i32>,
    /// Robots found dead since the last call of [`LockstepClock::take_deaths`].
    deaths: Vec<u32>,
}

impl LockstepClock {
    pub fn new(bus: &Bus, period_s: f64) -> Result<Self> {
        Ok(Self {
            source: ClockSource::new(bus)?,
            tick: 0,
            period_s,
            expected: HashMap::new(),
            joining: HashMap::new(),
            deaths: Vec::new(),
        })
    }

    pub fn sim_time(&self) -> f64 {
        self.tick as f64 * self.period_s
    }

    pub fn take_deaths(&mut self) -> Vec<u32> {
        std::mem::take(&mut self.deaths)
    }

    /// Waits until `count` robots announced themselves (or `timeout`).
    /// `on_sample` judges each sample; one it refuses never joins the swarm.
    pub fn await_robots(
        &mut self,
        roster: &RosterReader,
        count: usize,
        timeout: Duration,
        mut on_sample: impl FnMut(PoseSample) -> bool,
    ) -> Result<usize> {
        let started = Instant::now();
        while self.joining.len() + self.expected.len() < count && started.elapsed() < timeout {
            self.source.wait_for_acks(LIVENESS_POLL)?;
            roster.receive(|s| {
                if on_sample(s) && !self.expected.contains_key(&s.agent_id) {
                    self.joining.insert(s.agent_id, s.pid as i32);
                }
            })?;
        }
        Ok(self.joining.len() + self.expected.len())
    }

    /// Runs one tick: publishes it and waits until every live robot stepped.
    /// `alive` tells whether a pid still runs; `on_sample` judges each
    /// sample, and one it refuses neither counts as a step nor joins.
    pub fn advance(
        &mut self,
        roster: &RosterReader,
        mut alive: impl FnMut(i32) -> bool,
        mut on_sample: impl FnMut(PoseSample) -> bool,
    ) -> Result<()> {
        self.expected.extend(self.joining.drain());
        self.tick += 1;
        let tick = self.tick;
        self.source.tick(ClockTick {
            tick,
            sim_time: self.sim_time(),
            period_s: self.period_s,
        })?;
        let started = Instant::now();
        let mut last_liveness_check = started;
        let mut done: HashSet<u32> = HashSet::new();
        loop {
            roster.receive(|s| {
                if !on_sample(s) {
                    return;
                }
                match self.expected.get_mut(&s.agent_id) {
                    Some(pid) if *pid == s.pid as i32 => {
                        if s.tick >= tick {
                            done.insert(s.agent_id);
                        }
                    }
                    // A restarted robot (new pid) or a new one: it steps from the next tick.
                    _ => {
                        self.joining.insert(s.agent_id, s.pid as i32);
                    }
                }
            })?;
            if self.expected.keys().all(|id| done.contains(id)) {
                return Ok(());
            }
            self.source.wait_for_acks(LIVENESS_POLL)?;
            if last_liveness_check.elapsed() < LIVENESS_POLL {
                continue;
            }
            last_liveness_check = Instant::now();
            let hung = started.elapsed() > HUNG_AFTER;
            let gone: Vec<u32> = self
                .expected
                .iter()
                .filter(|(id, pid)| !done.contains(id) && (hung || !alive(**pid)))
                .map(|(id, _)| *id)
                .collect();
            for id in gone {
                if hung {
                    tracing::warn!(
                        id,
                        tick,
                        "robot did not step for {HUNG_AFTER:?}; no longer waiting for it"
                    );
                }
                self.expected.remove(&id);
                self.deaths.push(id);
            }
        }
    }
}

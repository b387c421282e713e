//! What an observer knows of the swarm: the newest pose of every robot.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use glam::DVec2;
use shoal_broker::{PoseSample, SampleCheck};
use shoal_physics::metrics::{FormationMetrics, formation_metrics};

pub struct Observer {
    latest: BTreeMap<u32, (PoseSample, Instant)>,
    check: SampleCheck,
    pub newest_tick: u64,
    pub newest_time: f64,
}

impl Observer {
    pub fn new(check: SampleCheck) -> Self {
        Self {
            latest: BTreeMap::new(),
            check,
            newest_tick: 0,
            newest_time: 0.0,
        }
    }

    /// Keeps a plausible sample; false (and counted) for one that is not.
    pub fn record(&mut self, sample: PoseSample) -> bool {
        if !self.check.accept(&sample) {
            return false;
        }
        self.newest_tick = self.newest_tick.max(sample.tick);
        self.newest_time = self.newest_time.max(sample.sim_time);
        self.latest
            .insert(sample.agent_id, (sample, Instant::now()));
        true
    }

    pub fn forget(&mut self, id: u32) {
        self.latest.remove(&id);
    }

    /// Forgets robots silent for longer than `max_age`.
    pub fn expire(&mut self, max_age: Duration) {
        self.latest
            .retain(|_, (_, heard)| heard.elapsed() <= max_age);
    }

    pub fn samples(&self) -> impl Iterator<Item = &PoseSample> {
        self.latest.values().map(|(s, _)| s)
    }

    pub fn get(&self, id: u32) -> Option<&PoseSample> {
        self.latest.get(&id).map(|(s, _)| s)
    }

    /// Where the robots heard from stand on average.
    pub fn centroid(&self) -> DVec2 {
        let positions: Vec<DVec2> = self.samples().map(|s| DVec2::new(s.x, s.y)).collect();
        shoal_physics::metrics::centroid(&positions)
    }

    pub fn len(&self) -> usize {
        self.latest.len()
    }

    pub fn is_empty(&self) -> bool {
        self.latest.is_empty()
    }

    pub fn rejected(&self) -> u64 {
        self.check.rejected
    }

    pub fn metrics(&self, spread: f64) -> FormationMetrics {
        let positions: Vec<DVec2> = self.samples().map(|s| DVec2::new(s.x, s.y)).collect();
        formation_metrics(&positions, spread)
    }
}

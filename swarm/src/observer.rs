//! What an observer knows of the swarm: the newest pose of every robot.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use glam::DVec2;
use serde::Serialize;
use shoal_broker::{PoseSample, SampleCheck};
use shoal_physics::metrics::{FormationMetrics, formation_metrics};

/// Neighbour ages are counted in 1 ms steps up to this; older ones in the last.
const MAX_AGE_MS: usize = 10_000;

pub struct Observer {
    latest: BTreeMap<u32, (PoseSample, Instant)>,
    check: SampleCheck,
    pub newest_tick: u64,
    pub newest_time: f64,
    /// Periods each robot heard from said it had missed. Kept after it
    /// falls silent.
    missed_periods: BTreeMap<u32, MissedPeriods>,
    /// How many samples, among those of robots with neighbours, acted on
    /// neighbour poses this many ms old at most.
    neighbour_ages: Vec<u64>,
    /// The swarm time timeliness is counted from (the last reset); samples
    /// sent before it say nothing of what came after.
    timeliness_from: Option<f64>,
    /// Timeliness is reset once this many robots have been heard.
    reset_when_heard: Option<usize>,
}

/// What one robot said of the periods it missed.
#[derive(Clone, Copy, Debug, Default)]
struct MissedPeriods {
    /// Its count in its first sample sent at or after the last reset; none
    /// yet if every sample heard since was sent before it.
    since: Option<u32>,
    latest: u32,
}

/// Whether real time held, from what the robots' samples say.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Timeliness {
    /// Control periods a robot missed, on average over every robot heard
    /// from, and the most any one missed.
    pub missed_periods_mean: f64,
    pub missed_periods_max: u32,
    /// The age of the oldest neighbour pose a robot acted on in a period,
    /// over every period heard of in which it had neighbours.
    pub neighbour_age_p50_ms: Option<u32>,
    pub neighbour_age_p99_ms: Option<u32>,
    /// The swarm time these are counted from: when every robot had been
    /// heard on the bus, or none if they are counted from the launch.
    pub counted_from_s: Option<f64>,
}

impl Observer {
    pub fn new(check: SampleCheck) -> Self {
        Self {
            latest: BTreeMap::new(),
            check,
            newest_tick: 0,
            newest_time: 0.0,
            missed_periods: BTreeMap::new(),
            neighbour_ages: vec![0; MAX_AGE_MS + 1],
            timeliness_from: None,
            reset_when_heard: None,
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
        self.reset_timeliness_if_all_heard();
        let current = self
            .timeliness_from
            .is_none_or(|from| sample.sim_time >= from);
        let missed = self.missed_periods.entry(sample.agent_id).or_default();
        missed.latest = missed.latest.max(sample.missed_periods);
        if missed.since.is_none() && current {
            missed.since = Some(if self.timeliness_from.is_some() {
                sample.missed_periods
            } else {
                0
            });
        }
        if sample.visible > 0 && current {
            self.neighbour_ages[(sample.neighbour_age_ms as usize).min(MAX_AGE_MS)] += 1;
        }
        true
    }

    /// Counts timeliness from the moment `robots` robots have been heard
    /// (now, if they have been): a robot has started when it is on the
    /// bus, not when its process exists, and while the last of 1000 robots
    /// join, the machine is too busy for the first to keep their periods.
    pub fn reset_timeliness_once_heard(&mut self, robots: usize) {
        self.reset_when_heard = Some(robots);
        self.reset_timeliness_if_all_heard();
    }

    fn reset_timeliness_if_all_heard(&mut self) {
        if self
            .reset_when_heard
            .is_some_and(|robots| self.latest.len() >= robots)
        {
            self.reset_when_heard = None;
            self.reset_timeliness(self.newest_time);
        }
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

    /// Counts timeliness from swarm time `from_s` on: periods missed while
    /// the swarm was still starting say little about whether it runs in
    /// real time. Each robot's count starts from its first sample sent at
    /// or after `from_s`. Its newest sample heard so far is no start: a
    /// launcher busy starting 1000 robots reads samples queued seconds
    /// before, and counting from those put all of start-up's missed periods
    /// after it (24.9 per robot, where none were missed after start-up).
    fn reset_timeliness(&mut self, from_s: f64) {
        self.timeliness_from = Some(from_s);
        for missed in self.missed_periods.values_mut() {
            missed.since = None;
        }
        self.neighbour_ages.fill(0);
    }

    /// Timeliness since the swarm was launched, or since the last reset.
    pub fn timeliness(&self) -> Timeliness {
        let missed = || {
            self.missed_periods
                .values()
                .filter_map(|m| Some(m.latest.saturating_sub(m.since?)))
        };
        let robots = missed().count().max(1) as f64;
        let total: u64 = self.neighbour_ages.iter().sum();
        let percentile = |share: f64| {
            let rank = (share * total as f64).ceil().max(1.0) as u64;
            let mut seen = 0;
            self.neighbour_ages.iter().position(|count| {
                seen += count;
                seen >= rank
            })
        };
        Timeliness {
            missed_periods_mean: missed().map(f64::from).sum::<f64>() / robots,
            missed_periods_max: missed().max().unwrap_or(0),
            neighbour_age_p50_ms: (total > 0)
                .then(|| percentile(0.5))
                .flatten()
                .map(|a| a as u32),
            neighbour_age_p99_ms: (total > 0)
                .then(|| percentile(0.99))
                .flatten()
                .map(|a| a as u32),
            counted_from_s: self.timeliness_from,
        }
    }

    pub fn metrics(&self, spread: f64) -> FormationMetrics {
        let positions: Vec<DVec2> = self.samples().map(|s| DVec2::new(s.x, s.y)).collect();
        formation_metrics(&positions, spread)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use shoal_scenario::Scenario;

    #[test]
    fn timeliness_counts_missed_periods_and_neighbour_age_percentiles() {
        let mut observer = Observer::new(SampleCheck::for_scenario(&Scenario::default_arena()));
        for (id, missed, age, visible) in
            [(1, 0, 100, 2), (1, 3, 300, 2), (2, 1, 200, 1), (3, 0, 0, 0)]
        {
            let mut sample = PoseSample::standing(id, id, 1, 5.0, 5.0, 0.0);
            (
                sample.missed_periods,
                sample.neighbour_age_ms,
                sample.visible,
            ) = (missed, age, visible);
            assert!(observer.record(sample));
        }
        let t = observer.timeliness();
        // Robots 1, 2 and 3 missed 3, 1 and 0 periods.
        assert!((t.missed_periods_mean - 4.0 / 3.0).abs() < 1e-12);
        assert_eq!(t.missed_periods_max, 3);
        // Robot 3 had no neighbours: its age says nothing.
        assert_eq!(
            (t.neighbour_age_p50_ms, t.neighbour_age_p99_ms),
            (Some(200), Some(300))
        );
        // From a reset on, only what robots said in samples sent after it
        // counts, each robot from its first such sample.
        observer.reset_timeliness(10.0);
        assert_eq!(observer.timeliness().missed_periods_max, 0);
        assert_eq!(observer.timeliness().neighbour_age_p50_ms, None);
        let heard = |observer: &mut Observer, sent_s: f64, missed: u32| {
            let mut sample = PoseSample::standing(1, 1, 2, 5.0, 5.0, 0.0);
            (
                sample.sim_time,
                sample.missed_periods,
                sample.neighbour_age_ms,
                sample.visible,
            ) = (sent_s, missed, 250, 3);
            assert!(observer.record(sample));
        };
        // Sent before the reset, read after it: it starts nothing.
        heard(&mut observer, 9.9, 20);
        assert_eq!(observer.timeliness().missed_periods_max, 0);
        assert_eq!(observer.timeliness().neighbour_age_p50_ms, None);
        heard(&mut observer, 10.1, 25);
        heard(&mut observer, 10.3, 27);
        let t = observer.timeliness();
        assert_eq!(
            (t.missed_periods_max, t.neighbour_age_p50_ms),
            (2, Some(250))
        );
        // Robots 2 and 3 were not heard from since: they are not averaged in.
        assert!((t.missed_periods_mean - 2.0).abs() < 1e-12);
    }

    #[test]
    fn timeliness_is_counted_from_when_every_robot_has_been_heard() {
        let mut observer = Observer::new(SampleCheck::for_scenario(&Scenario::default_arena()));
        let heard = |observer: &mut Observer, id: u32, sent_s: f64, missed: u32| {
            let mut sample = PoseSample::standing(id, id, 1, 5.0, 5.0, 0.0);
            (sample.sim_time, sample.missed_periods) = (sent_s, missed);
            assert!(observer.record(sample));
        };
        heard(&mut observer, 1, 1.0, 4);
        observer.reset_timeliness_once_heard(2);
        // Robot 1 misses periods while robot 2 is still starting.
        heard(&mut observer, 1, 3.0, 9);
        assert_eq!(observer.timeliness().counted_from_s, None);
        assert_eq!(observer.timeliness().missed_periods_max, 9);
        heard(&mut observer, 2, 5.0, 7);
        assert_eq!(observer.timeliness().counted_from_s, Some(5.0));
        assert_eq!(observer.timeliness().missed_periods_max, 0);
        // Each robot counts from its first sample sent since: robot 2 from
        // the one that completed the swarm, robot 1 from its next.
        heard(&mut observer, 1, 5.2, 10);
        heard(&mut observer, 1, 5.4, 11);
        heard(&mut observer, 2, 5.4, 7);
        let t = observer.timeliness();
        assert_eq!(t.missed_periods_max, 1);
        assert!((t.missed_periods_mean - 0.5).abs() < 1e-12);
    }
}

//! What a robot remembers of the robots around it.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use shoal_broker::PoseSample;

struct Entry {
    latest: PoseSample,
    previous: Option<PoseSample>,
    heard: Instant,
}

/// The newest two samples of every robot heard recently. Two, because in
/// lockstep a fast neighbour may already have published this tick's pose while
/// this robot still needs the previous one.
#[derive(Default)]
pub struct NeighbourTable {
    own_id: u32,
    entries: HashMap<u32, Entry>,
}

impl NeighbourTable {
    pub fn new(own_id: u32) -> Self {
        Self {
            own_id,
            entries: HashMap::new(),
        }
    }

    pub fn insert(&mut self, sample: PoseSample, now: Instant) {
        if sample.agent_id == self.own_id {
            return;
        }
        match self.entries.get_mut(&sample.agent_id) {
            // A restarted robot (new pid) starts a fresh history.
            Some(entry) if entry.latest.pid == sample.pid => {
                // Samples from one robot can arrive out of order: after it
                // crosses into another cell they come through two publishers.
                if sample.tick > entry.latest.tick {
                    entry.previous = Some(entry.latest);
                    entry.latest = sample;
                    entry.heard = now;
                } else if sample.tick == entry.latest.tick {
                    entry.latest = sample;
                    entry.heard = now;
                } else if entry.previous.is_none_or(|p| sample.tick >= p.tick) {
                    entry.previous = Some(sample);
                }
            }
            _ => {
                self.entries.insert(
                    sample.agent_id,
                    Entry {
                        latest: sample,
                        previous: None,
                        heard: now,
                    },
                );
            }
        }
    }

    /// Lockstep: every robot's pose at the end of tick `tick - 1`; robots
    /// without one are dead or gone and are forgotten. Returns the view and the
    /// last samples of the robots forgotten.
    pub fn lockstep_view(&mut self, tick: u64) -> (Vec<PoseSample>, Vec<PoseSample>) {
        let wanted = tick.saturating_sub(1);
        let mut view = Vec::new();
        let mut dropped = Vec::new();
        self.entries.retain(|_, entry| {
            let at = if entry.latest.tick == wanted {
                Some(entry.latest)
            } else {
                entry
                    .previous
                    .filter(|p| p.tick == wanted && entry.latest.tick > wanted)
            };
            match at {
                Some(sample) => {
                    view.push(sample);
                    true
                }
                None if entry.latest.tick > wanted => true,
                None => {
                    dropped.push(entry.latest);
                    false
                }
            }
        });
        view.sort_by_key(|s| s.agent_id);
        dropped.sort_by_key(|s| s.agent_id);
        (view, dropped)
    }

    /// Real time: the newest pose of every robot heard within `max_age`;
    /// robots silent for longer are forgotten.
    pub fn realtime_view(
        &mut self,
        now: Instant,
        max_age: Duration,
    ) -> (Vec<PoseSample>, Vec<PoseSample>) {
        let mut dropped = Vec::new();
        self.entries.retain(|_, entry| {
            let fresh = now.saturating_duration_since(entry.heard) <= max_age;
            if !fresh {
                dropped.push(entry.latest);
            }
            fresh
        });
        let mut view: Vec<PoseSample> = self.entries.values().map(|e| e.latest).collect();
        view.sort_by_key(|s| s.agent_id);
        dropped.sort_by_key(|s| s.agent_id);
        (view, dropped)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(id: u32, pid: u32, tick: u64) -> PoseSample {
        PoseSample::standing(id, pid, tick, tick as f64, 0.0, 0.0)
    }

    #[test]
    fn lockstep_uses_the_previous_tick_even_when_a_neighbour_ran_ahead() {
        let now = Instant::now();
        let mut table = NeighbourTable::new(0);
        table.insert(sample(1, 10, 4), now);
        table.insert(sample(1, 10, 5), now);
        table.insert(sample(2, 20, 4), now);
        let (view, dropped) = table.lockstep_view(5);
        assert_eq!(
            view.iter()
                .map(|s| (s.agent_id, s.tick))
                .collect::<Vec<_>>(),
            vec![(1, 4), (2, 4)]
        );
        assert!(dropped.is_empty());
    }

    #[test]
    fn out_of_order_samples_keep_the_two_newest() {
        let now = Instant::now();
        let mut table = NeighbourTable::new(0);
        table.insert(sample(1, 10, 3), now);
        table.insert(sample(1, 10, 5), now);
        table.insert(sample(1, 10, 4), now);
        let (view, _) = table.lockstep_view(5);
        assert_eq!(view[0].tick, 4);
    }

    #[test]
    fn a_silent_robot_is_dropped_at_the_next_tick() {
        let now = Instant::now();
        let mut table = NeighbourTable::new(0);
        table.insert(sample(1, 10, 4), now);
        table.insert(sample(2, 20, 4), now);
        table.insert(sample(2, 20, 5), now);
        let (view, dropped) = table.lockstep_view(6);
        assert_eq!(view.len(), 1);
        assert_eq!(
            dropped.iter().map(|s| s.agent_id).collect::<Vec<_>>(),
            vec![1]
        );
    }

    #[test]
    fn realtime_drops_robots_not_heard_within_the_window() {
        let start = Instant::now();
        let mut table = NeighbourTable::new(0);
        table.insert(sample(1, 10, 1), start);
        table.insert(sample(2, 20, 1), start + Duration::from_millis(300));
        let (view, dropped) = table.realtime_view(
            start + Duration::from_millis(450),
            Duration::from_millis(400),
        );
        assert_eq!(view.len(), 1);
        assert_eq!(
            dropped.iter().map(|s| s.agent_id).collect::<Vec<_>>(),
            vec![1]
        );
    }

    #[test]
    fn a_restarted_robot_replaces_its_old_history() {
        let now = Instant::now();
        let mut table = NeighbourTable::new(0);
        table.insert(sample(1, 10, 50), now);
        table.insert(sample(1, 11, 7), now);
        let (view, _) = table.lockstep_view(8);
        assert_eq!(view[0].pid, 11);
    }
}

//! Who is in the swarm, as a recorder hears it: joins, restarts, robots that
//! fell silent or came back, and samples the bus dropped. Pure; the
//! recorder logs what it says.

use std::collections::{BTreeMap, HashMap, VecDeque};

use shoal_broker::PoseSample;

/// Positions kept for each robot's trail.
const TRAIL_LENGTH: usize = 50;

struct Present {
    pid: u32,
    last_tick: u64,
    trail: VecDeque<[f32; 2]>,
}

#[derive(Default)]
pub struct Presence {
    robots: BTreeMap<u32, Present>,
    /// The last pid of robots that fell silent: one that comes back was
    /// restarted, not a newcomer.
    gone: HashMap<u32, u32>,
    /// Samples the bus overwrote before the recorder read them (it fell behind).
    pub dropped: u64,
}

impl Presence {
    /// Notes one sample; returns what changed, if anything did: a join, a
    /// restart, or a robot heard again.
    pub fn saw(&mut self, sample: &PoseSample) -> Option<String> {
        let point = [sample.x as f32, sample.y as f32];
        let (id, pid) = (sample.agent_id, sample.pid);
        let event = match self.robots.get_mut(&id) {
            Some(robot) if robot.pid == pid => {
                if sample.tick > robot.last_tick + 1 {
                    self.dropped += sample.tick - robot.last_tick - 1;
                }
                robot.last_tick = robot.last_tick.max(sample.tick);
                robot.trail.push_back(point);
                if robot.trail.len() > TRAIL_LENGTH {
                    robot.trail.pop_front();
                }
                return None;
            }
            Some(robot) => format!("robot {id} restarted (pid {} -> {pid})", robot.pid),
            None => {
                let at = format!("({:.2}, {:.2})", sample.x, sample.y);
                match self.gone.remove(&id) {
                    // A process stalled longer than the staleness, not restarted.
                    Some(old_pid) if old_pid == pid => {
                        format!("robot {id} (pid {pid}) heard again at {at}")
                    }
                    Some(old_pid) => {
                        format!("robot {id} restarted (pid {old_pid} -> {pid}) at {at}")
                    }
                    None => format!("robot {id} (pid {pid}) joined at {at}"),
                }
            }
        };
        self.robots.insert(
            id,
            Present {
                pid,
                last_tick: sample.tick,
                trail: VecDeque::from([point]),
            },
        );
        Some(event)
    }

    /// Robots not heard of for `silent_ticks` ticks before `now_tick` are
    /// gone: their ids, each with what to say of it.
    pub fn fell_silent(&mut self, now_tick: u64, silent_ticks: u64) -> Vec<(u32, String)> {
        let silent: Vec<u32> = self
            .robots
            .iter()
            .filter(|(_, r)| r.last_tick + silent_ticks < now_tick)
            .map(|(id, _)| *id)
            .collect();
        silent
            .into_iter()
            .filter_map(|id| {
                let robot = self.robots.remove(&id)?;
                self.gone.insert(id, robot.pid);
                Some((
                    id,
                    format!(
                        "robot {id} (pid {}) fell silent after tick {}",
                        robot.pid, robot.last_tick
                    ),
                ))
            })
            .collect()
    }

    /// Each present robot's recent positions, oldest first.
    pub fn trails(&self) -> impl Iterator<Item = Vec<[f32; 2]>> + '_ {
        self.robots
            .values()
            .map(|r| r.trail.iter().copied().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(id: u32, pid: u32, tick: u64) -> PoseSample {
        PoseSample::standing(id, pid, tick, 1.0, 2.0, 0.0)
    }

    #[test]
    fn joins_restarts_silences_and_returns_are_told_apart() {
        let mut presence = Presence::default();
        assert_eq!(
            presence.saw(&at(3, 100, 1)).as_deref(),
            Some("robot 3 (pid 100) joined at (1.00, 2.00)")
        );
        assert_eq!(presence.saw(&at(3, 100, 2)), None);
        // Ticks 3 and 4 never arrived: the bus dropped them.
        assert_eq!(presence.saw(&at(3, 100, 5)), None);
        assert_eq!(presence.dropped, 2);
        assert_eq!(
            presence.saw(&at(3, 101, 6)).as_deref(),
            Some("robot 3 restarted (pid 100 -> 101)")
        );
        assert!(presence.fell_silent(8, 5).is_empty());
        assert_eq!(
            presence.fell_silent(20, 5),
            vec![(3, "robot 3 (pid 101) fell silent after tick 6".to_owned())]
        );
        assert_eq!(
            presence.saw(&at(3, 101, 21)).as_deref(),
            Some("robot 3 (pid 101) heard again at (1.00, 2.00)")
        );
        presence.fell_silent(40, 5);
        assert_eq!(
            presence.saw(&at(3, 102, 41)).as_deref(),
            Some("robot 3 restarted (pid 101 -> 102) at (1.00, 2.00)")
        );
        assert_eq!(presence.trails().count(), 1);
    }
}

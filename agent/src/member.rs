//! A robot as a member of the swarm, free of I/O: from the poses it heard
//! and what SLAM sent it, one period gives the pose sample and scan it
//! publishes. The loop in `run` only moves these between the bus and here.

use std::collections::VecDeque;

use glam::DVec2;
use shoal_broker::BusSection;
use shoal_broker::{
    EstimateSample, Health, MAX_BEAMS, MAX_NEIGHBOURS, ModelUpdate, PoseSample, ScanSample,
};
use shoal_physics::{Neighbour, Pose};
use shoal_scenario::Scenario;

use crate::robot::{Decision, Robot};
use crate::sensing::SensingRange;

/// How many ticks of dead reckoning a robot keeps, to apply late SLAM estimates.
const BELIEF_HISTORY_TICKS: usize = 64;
/// A robot sensing fewer robots than this listens further.
const WIDEN_BELOW: usize = 3;

/// What the bus brought for one period.
pub struct Heard<'a> {
    pub tick: u64,
    pub sim_time: f64,
    /// When the robot acts, on the swarm's clock: wall time since the
    /// swarm's epoch in real time, the tick's time in lockstep.
    pub now_s: f64,
    /// Neighbour poses current for this period.
    pub current: &'a [PoseSample],
    /// Neighbours that fell silent since the last period.
    pub dropped: &'a [PoseSample],
    /// Bus input rejected so far, by every check of this robot.
    pub rejected: u64,
}

/// What one period gives the bus.
pub struct Said {
    pub pose: PoseSample,
    pub scan: ScanSample,
    /// Robots that fell silent within sensing range: probably dead, worth
    /// sweeping the bus for (one that walked out of earshot is not).
    pub died_nearby: Vec<u32>,
}

pub struct Member {
    pub robot: Robot,
    pub range: SensingRange,
    /// How far one ring of listening reaches (the scenario's `[bus]`).
    listen_step: f64,
    /// The robot's dead reckoning at each recent tick, to carry a late
    /// SLAM estimate forward.
    odometry_history: VecDeque<(u64, Pose)>,
    pid: u32,
    /// The tick of this robot's last period, once it has had one.
    last_period: Option<u64>,
    missed_periods: u32,
}

impl Member {
    pub fn new(id: u32, start: Pose, scenario: &Scenario, bus: &BusSection, pid: u32) -> Self {
        Self {
            robot: Robot::new(id, start, scenario),
            range: SensingRange::new(bus.max_ring),
            listen_step: bus.listen_step,
            odometry_history: VecDeque::with_capacity(BELIEF_HISTORY_TICKS + 1),
            pid,
            last_period: None,
            missed_periods: 0,
        }
    }

    /// How far this robot listens now: its current rings of the scenario's
    /// listening step.
    pub fn listen_radius(&self) -> f64 {
        self.range.listen_radius(self.listen_step)
    }

    /// The pose sample of a robot standing at its start, before any period.
    pub fn standing(&self, tick: u64, period_s: f64) -> PoseSample {
        let pose = self.robot.body.pose;
        let mut sample =
            PoseSample::standing(self.robot.id, self.pid, tick, pose.x, pose.y, pose.theta);
        sample.sim_time = tick as f64 * period_s;
        sample
    }

    /// Adopts one learned mixture; the update has passed its wire check, so
    /// its command and parameter name something.
    pub fn learn(&mut self, update: &ModelUpdate) {
        if let Some((command, param)) = update.target() {
            *self.robot.belief.command_mut(command).param_mut(param) = update.mixture();
        }
    }

    /// A SLAM estimate of a past tick replaces the robot's belief, carried
    /// forward by the motion believed since then. Dead reckoning is never
    /// corrected, so that motion is the same however many corrections came
    /// in between. An estimate older than the history is ignored.
    pub fn correct(&mut self, estimate: &EstimateSample) {
        let at = Pose::new(estimate.x, estimate.y, estimate.theta);
        if let Some((_, then)) = self
            .odometry_history
            .iter()
            .find(|(t, _)| *t == estimate.tick)
        {
            self.robot.believed = at.compose(&self.robot.odometry.relative_to(then));
        }
    }

    /// The scan taken this period, as the wire carries it.
    fn scan_sample(
        &self,
        heard: &Heard,
        decision: &Decision,
        ranges: &[f64],
        scenario: &Scenario,
    ) -> ScanSample {
        let mut scan = ScanSample {
            agent_id: self.robot.id,
            pid: self.pid,
            tick: heard.tick,
            sim_time: heard.sim_time,
            command: decision.command.index() as u32,
            bumped: u32::from(decision.outcome.bumped),
            beam_count: ranges.len().min(MAX_BEAMS) as u32,
            reserved: 0,
            field_of_view: scenario.sensor.field_of_view,
            max_range: scenario.sensor.max_range,
            ranges: [0.0; MAX_BEAMS],
        };
        for (slot, range) in scan.ranges.iter_mut().zip(ranges) {
            *slot = *range as f32;
        }
        scan
    }

    /// One control period: sense, step, scan; `previous` is the last pose
    /// sample this robot published.
    pub fn period(&mut self, heard: &Heard, previous: &PoseSample, scenario: &Scenario) -> Said {
        let me = self.robot.body.pose.position();
        let step = self.listen_step;
        let (sensed, died_nearby, oldest_s) = within(heard, me, self.range.sense_radius(step));
        if let Some(last) = self.last_period {
            let missed = heard.tick.saturating_sub(last + 1);
            self.missed_periods = self
                .missed_periods
                .saturating_add(u32::try_from(missed).unwrap_or(u32::MAX));
        }
        self.last_period = Some(heard.tick);
        let inner_radius = SensingRange::radius(self.range.sense_ring.saturating_sub(1), step);
        let within_inner = sensed
            .iter()
            .filter(|n| n.position.distance(me) <= inner_radius)
            .count();

        let before = self.robot.body.pose;
        self.robot.body.sim_time = heard.sim_time;
        let decision = self.robot.step(&sensed, scenario);
        let after = self.robot.body.pose;
        let bodies: Vec<DVec2> = sensed.iter().map(|n| n.position).collect();
        let ranges = self.robot.scan(scenario, &bodies);
        let scan = self.scan_sample(heard, &decision, &ranges, scenario);
        let dt = scenario.timing.period_s;
        let believed = self.robot.believed;
        let pose = PoseSample {
            tick: heard.tick,
            sim_time: heard.sim_time,
            x: after.x,
            y: after.y,
            theta: after.theta,
            believed_x: believed.x,
            believed_y: believed.y,
            believed_theta: believed.theta,
            vx: (after.x - before.x) / dt,
            vy: (after.y - before.y) / dt,
            command: decision.command.index() as u32,
            health: health_of(&decision, &sensed, heard),
            visible: sensed.len() as u32,
            neighbour_count: decision.tracked.len().min(MAX_NEIGHBOURS) as u32,
            neighbours: neighbour_ids(&decision),
            missed_periods: self.missed_periods,
            neighbour_age_ms: (oldest_s * 1000.0).round().min(f64::from(u32::MAX)) as u32,
            ..*previous
        };

        self.odometry_history
            .push_back((heard.tick, self.robot.odometry));
        if self.odometry_history.len() > BELIEF_HISTORY_TICKS {
            self.odometry_history.pop_front();
        }
        // Widen only when nearly alone: a robot on the edge of a formation
        // legitimately sees fewer than it tracks.
        self.range.update(
            heard.tick,
            sensed.len(),
            within_inner,
            scenario.formation.neighbours.min(WIDEN_BELOW),
        );
        Said {
            pose,
            scan,
            died_nearby,
        }
    }
}

/// The neighbours `heard` within `radius` of `me`, those that fell silent
/// there (by id) and the age of the oldest pose acted on (seconds).
fn within(heard: &Heard, me: DVec2, radius: f64) -> (Vec<Neighbour>, Vec<u32>, f64) {
    let near = |s: &&PoseSample| DVec2::new(s.x, s.y).distance(me) <= radius;
    let died_nearby = heard
        .dropped
        .iter()
        .filter(near)
        .map(|s| s.agent_id)
        .collect();
    let acted_on: Vec<&PoseSample> = heard.current.iter().filter(near).collect();
    let sensed = acted_on
        .iter()
        .map(|s| Neighbour {
            id: s.agent_id,
            position: DVec2::new(s.x, s.y),
        })
        .collect();
    let oldest_s = acted_on
        .iter()
        .map(|s| heard.now_s - s.sim_time)
        .fold(0.0, f64::max);
    (sensed, died_nearby, oldest_s)
}

/// The health flags of a period.
fn health_of(decision: &Decision, sensed: &[Neighbour], heard: &Heard) -> u32 {
    let mut health = 0;
    if decision.outcome.bumped {
        health |= Health::BUMPED;
    }
    if sensed.is_empty() {
        health |= Health::ISOLATED;
    }
    if heard.rejected > 0 {
        health |= Health::REJECTED_INPUT;
    }
    health
}

/// The ids of the neighbours a decision tracked, in its pose sample's slots.
fn neighbour_ids(decision: &Decision) -> [u32; MAX_NEIGHBOURS] {
    let mut neighbours = [0; MAX_NEIGHBOURS];
    for (slot, n) in neighbours.iter_mut().zip(&decision.tracked) {
        *slot = n.id;
    }
    neighbours
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenario() -> Scenario {
        let mut scenario = Scenario::default_arena();
        scenario.agents.count = 3;
        scenario
    }

    fn heard<'a>(tick: u64, current: &'a [PoseSample], dropped: &'a [PoseSample]) -> Heard<'a> {
        Heard {
            tick,
            sim_time: tick as f64 * 0.2,
            now_s: tick as f64 * 0.2 + 0.01,
            current,
            dropped,
            rejected: 0,
        }
    }

    #[test]
    fn a_period_answers_with_the_pose_scan_and_neighbours_it_acted_on() {
        let scenario = scenario();
        let start = Pose::new(5.0, 5.0, 0.0);
        let mut member = Member::new(0, start, &scenario, &BusSection::default(), 42);
        // Two robots closer than the formation's spacing: it moves away.
        let others = [
            PoseSample::standing(1, 7, 0, 5.3, 5.0, 0.0),
            PoseSample::standing(2, 8, 0, 5.0, 5.3, 0.0),
        ];
        let previous = member.standing(0, scenario.timing.period_s);
        let said = member.period(&heard(1, &others, &[]), &previous, &scenario);
        assert_eq!(
            (said.pose.agent_id, said.pose.pid, said.pose.tick),
            (0, 42, 1)
        );
        assert_eq!(said.pose.visible, 2);
        assert_eq!(said.pose.health & Health::ISOLATED, 0);
        assert_eq!(said.scan.tick, 1);
        assert_eq!(
            said.scan.beam_count as usize,
            scenario.sensor.beams.min(MAX_BEAMS)
        );
        // Crowded by its neighbours, it tracks both and moves.
        assert_eq!(said.pose.neighbour_count, 2);
        assert_ne!(
            said.pose.command,
            shoal_physics::Command::Stand.index() as u32
        );
        let moved = Pose::new(said.pose.x, said.pose.y, said.pose.theta);
        assert_ne!(moved, start);
    }

    #[test]
    fn a_period_says_how_late_it_ran_and_how_old_its_neighbours_were() {
        let scenario = scenario();
        let mut member = Member::new(
            0,
            Pose::new(5.0, 5.0, 0.0),
            &scenario,
            &BusSection::default(),
            1,
        );
        let mut fresh = PoseSample::standing(1, 2, 4, 5.6, 5.0, 0.0);
        fresh.sim_time = 0.8;
        let mut old = PoseSample::standing(2, 3, 3, 5.0, 5.6, 0.0);
        old.sim_time = 0.6;
        let others = [fresh, old];
        // A robot joining late misses nothing before its first period.
        let previous = member.standing(0, scenario.timing.period_s);
        let first = member.period(&heard(5, &others, &[]), &previous, &scenario);
        assert_eq!(first.pose.missed_periods, 0);
        // It acts at 1.01 s on a pose whose period began at 0.6 s.
        assert_eq!(first.pose.neighbour_age_ms, 410);
        // Woken for tick 8 after tick 5, it missed 6 and 7.
        let later = member.period(&heard(8, &others, &[]), &first.pose, &scenario);
        assert_eq!(later.pose.missed_periods, 2);
        let alone = member.period(&heard(9, &[], &[]), &later.pose, &scenario);
        assert_eq!(
            (alone.pose.missed_periods, alone.pose.neighbour_age_ms),
            (2, 0)
        );
    }

    #[test]
    fn alone_it_says_so_and_a_silent_robot_nearby_is_suspected_dead() {
        let scenario = scenario();
        let start = Pose::new(5.0, 5.0, 0.0);
        let mut member = Member::new(0, start, &scenario, &BusSection::default(), 1);
        let near = PoseSample::standing(1, 2, 0, 5.5, 5.0, 0.0);
        let far = PoseSample::standing(2, 3, 0, 5.0 + 100.0, 5.0, 0.0);
        let previous = member.standing(0, scenario.timing.period_s);
        let mut input = heard(1, &[], &[]);
        let dropped = [near, far];
        input.dropped = &dropped;
        input.rejected = 3;
        let said = member.period(&input, &previous, &scenario);
        assert_ne!(said.pose.health & Health::ISOLATED, 0);
        assert_ne!(said.pose.health & Health::REJECTED_INPUT, 0);
        assert_eq!(said.died_nearby, vec![1]);
    }

    #[test]
    fn a_late_estimate_is_carried_forward_by_the_motion_since() {
        let scenario = scenario();
        let start = Pose::new(5.0, 5.0, 0.0);
        let mut member = Member::new(0, start, &scenario, &BusSection::default(), 1);
        let mut previous = member.standing(0, scenario.timing.period_s);
        for tick in 1..=5 {
            previous = member
                .period(&heard(tick, &[], &[]), &previous, &scenario)
                .pose;
        }
        let odometry_at_2 = member.odometry_history[1].1;
        let since = member.robot.odometry.relative_to(&odometry_at_2);
        let estimate = EstimateSample {
            agent_id: 0,
            reserved: 0,
            tick: 2,
            x: 1.0,
            y: 2.0,
            theta: 0.5,
            effective_particles: 100.0,
        };
        member.correct(&estimate);
        let expected = Pose::new(1.0, 2.0, 0.5).compose(&since);
        let believed = member.robot.believed;
        assert!((believed.x - expected.x).abs() < 1e-12);
        assert!((believed.y - expected.y).abs() < 1e-12);
        // An estimate older than the history changes nothing.
        member.correct(&EstimateSample {
            tick: 10_000,
            ..estimate
        });
        assert_eq!(member.robot.believed, believed);
    }
}

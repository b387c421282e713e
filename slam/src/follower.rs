//! Following one robot, free of I/O: its scans and the poses the roster
//! announces for it go in, filter steps come out. The SLAM process moves
//! these between the bus and here; tests drive it directly.

use std::collections::BTreeMap;

use shoal_physics::{Command, MotionModel, Pose};

use crate::filter::{Bodies, FilterConfig, ParticleFilter, StepReport, mask_bodies};

/// Ticks of announced poses kept, to start the filter from and to judge
/// which beams hit robots.
const ANNOUNCED_TICKS: usize = 64;
/// Scans kept while the filter waits for the pose of their tick.
const WAITING_SCANS: usize = 16;

/// One range scan of the followed robot, and the command it executed
/// before taking it.
#[derive(Clone, Debug)]
pub struct Scan {
    pub tick: u64,
    pub sim_time: f64,
    /// `None` when the index named no command: the scan is skipped.
    pub command: Option<Command>,
    pub bumped: bool,
    pub ranges: Vec<f64>,
}

/// What one filter step gave.
pub struct Stepped<'a> {
    pub tick: u64,
    pub sim_time: f64,
    pub command: Command,
    pub report: StepReport,
    pub filter: &'a ParticleFilter,
    /// Filter steps so far, this one included.
    pub steps: u64,
}

/// The first scans of the robots one SLAM process follows, each with the
/// pose the roster announced for it: shared between their filters. A
/// swarm starts crowded, and a robot in the middle sees mostly its
/// neighbours; the walls that the few beams between them reach were in no
/// map yet, so nothing held the robot while its model was still wrong (the
/// demo's 20 robots followed offline: 0.34 m off over their first 10 s).
/// Each first scan was taken from a pose known in every filter's frame, so
/// every filter can map it: twenty views of the walls around the crowd
/// (0.17 m).
#[derive(Debug, Default)]
pub struct FirstLooks {
    looks: Vec<Look>,
}

#[derive(Debug)]
struct Look {
    robot: u32,
    pose: Pose,
    /// Beams that ended on robots masked.
    ranges: Vec<f64>,
}

/// Scans a follower may have waiting before the older ones are coasted
/// through ([`Follower::catch_up`]): 0.6 s at 5 Hz.
pub const CATCH_UP_AFTER_SCANS: usize = 3;

/// Scans waiting at which a follower sheds particles, so that it scores
/// more of its scans ([`Follower::catch_up`]).
pub const SHED_AT_SCANS: usize = 3;

/// What a shedding follower keeps of its particles.
const SHED_KEEPS: f64 = 0.8;

/// A follower that has kept up (nothing waiting beside the scan it steps)
/// for this many steps in a row takes back a tenth of its configured
/// particles: slowly, as each step shed and taken back at once cost
/// accuracy (the filter resampled every few steps).
const TAKE_BACK_AFTER_STEPS: u32 = 10;
const TAKE_BACK_SHARE: usize = 10;

/// The ticks the robot was announced on after `stepped` (the last scan
/// stepped) and before `tick`: scans that never reached the filter.
fn missed_between(announced: &BTreeMap<u64, Pose>, stepped: Option<u64>, tick: u64) -> u64 {
    // A scan older than the last stepped (out of order on the bus) misses
    // nothing, and an empty range must not be asked for backwards.
    stepped
        .filter(|&previous| tick > previous + 1)
        .map_or(0, |previous| {
            announced.range(previous + 1..tick).count() as u64
        })
}

pub struct Follower {
    id: u32,
    seed: u64,
    filter: Option<ParticleFilter>,
    start_model: MotionModel,
    config: FilterConfig,
    arena: [f64; 2],
    /// Where the roster said the robot stood, by tick.
    announced: BTreeMap<u64, Pose>,
    /// Scans that came before their tick's pose, while the filter waits to start.
    waiting: Vec<Scan>,
    steps: u64,
    /// The tick of the newest scan the filter stepped (or started on).
    stepped_tick: Option<u64>,
    /// Ticks the robot was announced on whose scans the filter never
    /// stepped: lost on the bus (a follower too slow for its buffer), so
    /// their motion is missing from the filter.
    scans_missed: u64,
    /// Scans whose command moved the particles without their scan being
    /// scored ([`Follower::coast`]): a follower catching up.
    scans_coasted: u64,
    /// Steps whose scan fitted far worse than usual from where the model
    /// led and that were matched again from turns it does not reach
    /// ([`crate::filter::StepReport::rematched`]).
    steps_rematched: u64,
    /// How many of the shared first looks the filter has mapped.
    looks_mapped: usize,
    /// Scans that waited after the last catch-up, and steps in a row taken
    /// with nothing else waiting: how the follower judges its pace.
    backlog_before: usize,
    kept_up_steps: u32,
    /// Steps stepped under each walk command (`walk(1)` to `walk(3)`):
    /// the stride a report holds against the truth is the one walked most.
    walks: [u64; 3],
}

impl Follower {
    /// Follows robot `id` of an `arena` (width, height) starting from
    /// `model`; the filter draws from `seed`.
    pub fn new(
        id: u32,
        seed: u64,
        model: MotionModel,
        config: FilterConfig,
        arena: [f64; 2],
    ) -> Self {
        Self {
            id,
            seed,
            filter: None,
            start_model: model,
            config,
            arena,
            announced: BTreeMap::new(),
            waiting: Vec::new(),
            steps: 0,
            stepped_tick: None,
            scans_missed: 0,
            scans_coasted: 0,
            steps_rematched: 0,
            looks_mapped: 0,
            backlog_before: 0,
            kept_up_steps: 0,
            walks: [0; 3],
        }
    }

    pub fn filter(&self) -> Option<&ParticleFilter> {
        self.filter.as_ref()
    }

    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Scans of ticks the robot was announced on that never reached the
    /// filter (see the field).
    /// The speed (1-3) of the walk command the filter stepped most (3, the
    /// full stride, before any): a wandering robot walks at `walk(2)`
    /// only, and a stride it never walked is never learned.
    pub fn most_walked(&self) -> u8 {
        (1..=3u8)
            .zip(self.walks)
            .rev()
            .max_by_key(|(_, count)| *count)
            .filter(|(_, count)| *count > 0)
            .map_or(crate::report::FULL_STRIDE_WALK, |(speed, _)| speed)
    }

    pub fn scans_missed(&self) -> u64 {
        self.scans_missed
    }

    /// Scans coasted through while catching up (see the field).
    pub fn scans_coasted(&self) -> u64 {
        self.scans_coasted
    }

    /// Steps matched again from turns the model does not reach (see the
    /// field).
    pub fn steps_rematched(&self) -> u64 {
        self.steps_rematched
    }

    /// Fits the follower's work to the time it has, before it steps the
    /// first of `pending`'s scans. With [`SHED_AT_SCANS`] or more waiting,
    /// and no fewer than at the last look, it sheds a fifth of its
    /// particles (down to [`FilterConfig::fewest_particles`]); after
    /// [`TAKE_BACK_AFTER_STEPS`] steps in a row with nothing else waiting
    /// it takes back a tenth of the configured count. A filter short of
    /// time does better with fewer particles than with fewer scans (the
    /// demo offline: 25 particles on every scan 0.20-0.25 m, 50 on every
    /// other scan 0.40-0.47 m, at about the same cost; EXPERIMENTS.md 10).
    /// Still behind, it moves the filter through the oldest scans
    /// ([`Follower::coast`]) until at most [`CATCH_UP_AFTER_SCANS`] wait:
    /// a scan stepped late is worth less than keeping up, and a command
    /// dropped would leave its motion out of the filter for good (on a
    /// machine at 40% of its speed the demo's filters fell 17 s behind and
    /// ended 2.8 m off). A scan it cannot coast through stays first in
    /// `pending`.
    pub fn catch_up(&mut self, pending: &mut std::collections::VecDeque<Scan>) {
        let configured = self.config.particles.max(1);
        let waiting = pending.len();
        if let Some(filter) = &mut self.filter {
            let held = filter.particle_count();
            if waiting >= SHED_AT_SCANS && waiting >= self.backlog_before {
                // Behind, and not catching up since the last look.
                let fewest = self.config.fewest_particles();
                filter.resize(((held as f64 * SHED_KEEPS) as usize).max(fewest).min(held));
                self.kept_up_steps = 0;
            } else if waiting == 1 {
                self.kept_up_steps += 1;
                if self.kept_up_steps >= TAKE_BACK_AFTER_STEPS && held < configured {
                    filter.resize((held + (configured / TAKE_BACK_SHARE).max(1)).min(configured));
                    self.kept_up_steps = 0;
                }
            } else if waiting > 1 {
                self.kept_up_steps = 0;
            }
        }
        while pending.len() > CATCH_UP_AFTER_SCANS {
            let Some(scan) = pending.pop_front() else {
                break;
            };
            if !self.coast(&scan) {
                pending.push_front(scan);
                break;
            }
        }
        self.backlog_before = pending.len();
    }

    /// Moves the filter through `scan`'s command without scoring its
    /// ranges (`ParticleFilter::coast`): what a follower that has fallen
    /// behind does with the scans before its newest, so that no command's
    /// motion goes missing while it catches up. False (nothing done) before
    /// the filter started, or for a scan without a command or not newer
    /// than the last one stepped: `on_scans` takes those.
    pub fn coast(&mut self, scan: &Scan) -> bool {
        let (Some(filter), Some(command)) = (&mut self.filter, scan.command) else {
            return false;
        };
        if self.stepped_tick.is_some_and(|t| scan.tick <= t) {
            return false;
        }
        self.scans_missed += missed_between(&self.announced, self.stepped_tick, scan.tick);
        filter.coast(command, scan.bumped);
        self.stepped_tick = Some(scan.tick);
        self.scans_coasted += 1;
        true
    }

    /// The tick of the newest scan the filter stepped: the tick its
    /// estimate is of.
    pub fn stepped_tick(&self) -> Option<u64> {
        self.stepped_tick
    }

    /// How many ticks the filter trails the newest pose the roster
    /// announced for its robot: what it still has to step to be current.
    pub fn ticks_behind(&self) -> Option<u64> {
        Some(self.newest_announced()?.saturating_sub(self.stepped_tick?))
    }

    /// The newest tick the roster announced for the robot. A robot
    /// publishes its scan before its pose, so once this pose is read and
    /// the scans after it stepped, the tick is done.
    pub fn newest_announced(&self) -> Option<u64> {
        self.announced.last_key_value().map(|(tick, _)| *tick)
    }

    /// The roster announced the robot at `pose` on `tick`.
    pub fn announced(&mut self, tick: u64, pose: Pose) {
        self.announced.insert(tick, pose);
        while self.announced.len() > ANNOUNCED_TICKS {
            self.announced.pop_first();
        }
    }

    /// Steps the filter through newly arrived `scans`, in order, calling
    /// `stepped` after each step (the filter as it is then). Beams that end
    /// on one of `bodies` are dropped. The filter shares its robot's first
    /// scan in `looks` when it starts, and maps the other robots' first
    /// looks that came since before it steps (`looks`: the same for every
    /// call, and for every robot the process follows).
    pub fn on_scans<E>(
        &mut self,
        scans: Vec<Scan>,
        bodies: &Bodies,
        looks: &mut FirstLooks,
        mut stepped: impl FnMut(Stepped<'_>) -> Result<(), E>,
    ) -> Result<(), E> {
        let mut scans = std::mem::take(&mut self.waiting)
            .into_iter()
            .chain(scans)
            .collect::<Vec<_>>();
        if self.filter.is_none() {
            match self.start(&scans, bodies, looks) {
                Some(first) => {
                    scans.drain(..=first);
                }
                None => {
                    // The roster may bring the scan's pose a moment later.
                    let keep = scans.len().saturating_sub(WAITING_SCANS);
                    self.waiting = scans.split_off(keep);
                    return Ok(());
                }
            }
        }
        self.map_new_looks(looks);
        for mut scan in scans {
            let Some(filter) = &mut self.filter else {
                break;
            };
            // Which beams end on robots is perception (a robot knows a robot
            // when it sees one), so it is judged from where the robot stood,
            // as the roster says, not from SLAM's own estimate: a wrong
            // estimate let robots into the map as walls, and the map then
            // held the estimate wrong (in a crowd of 20, 1.6 m against 0.7 m).
            let seen_from = self
                .announced
                .get(&scan.tick)
                .copied()
                .unwrap_or_else(|| filter.estimate());
            mask_bodies(
                &mut scan.ranges,
                &seen_from,
                &self.config.sensor,
                bodies.others_at(self.id, scan.tick),
            );
            let Some(command) = scan.command else {
                continue;
            };
            self.scans_missed += missed_between(&self.announced, self.stepped_tick, scan.tick);
            let report = filter.step(command, scan.bumped, &scan.ranges);
            self.steps_rematched += u64::from(report.rematched);
            if let Command::Walk(speed @ 1..=3) = command {
                self.walks[usize::from(speed - 1)] += 1;
            }
            self.steps += 1;
            self.stepped_tick = Some(scan.tick);
            stepped(Stepped {
                tick: scan.tick,
                sim_time: scan.sim_time,
                command,
                report,
                filter,
                steps: self.steps,
            })?;
        }
        Ok(())
    }

    /// Starts the filter at the announced pose of the newest scan that has
    /// one, mapping that scan; returns its index. The command that led to
    /// it is already in the pose and is not applied again. (Starting from
    /// the newest pose and stepping the first scan's command turned a
    /// formation robot, whose first command is a turn in place, by that
    /// turn twice: SLAM then ran 90 degrees off.)
    fn start(&mut self, scans: &[Scan], bodies: &Bodies, looks: &mut FirstLooks) -> Option<usize> {
        let first = scans
            .iter()
            .rposition(|s| self.announced.contains_key(&s.tick))?;
        let start = self.announced[&scans[first].tick];
        let mut ranges = scans[first].ranges.clone();
        // A swarm starts crowded: beams that end on another robot would put
        // it in the map as a wall for ever.
        mask_bodies(
            &mut ranges,
            &start,
            &self.config.sensor,
            bodies.others_at(self.id, scans[first].tick),
        );
        let mut filter = ParticleFilter::new(
            start,
            self.start_model.clone(),
            self.config.clone(),
            self.arena[0],
            self.arena[1],
            self.seed,
        );
        filter.observe_start(&ranges);
        self.filter = Some(filter);
        looks.looks.push(Look {
            robot: self.id,
            pose: start,
            ranges,
        });
        self.stepped_tick = Some(scans[first].tick);
        Some(first)
    }

    /// Maps the other robots' first looks shared since the last call into
    /// the filter. Before its first step the filter's particles still share
    /// one map, and each look is mapped once.
    fn map_new_looks(&mut self, looks: &FirstLooks) {
        let Some(filter) = &mut self.filter else {
            return;
        };
        for look in looks.looks.get(self.looks_mapped..).unwrap_or_default() {
            if look.robot != self.id {
                filter.observe_from(look.pose, &look.ranges);
            }
        }
        self.looks_mapped = looks.looks.len();
    }
}

/// The order a SLAM process steps its followed robots (`ids`, ascending)
/// in one pass: from `begins_at` (or the first id after it) on, then from
/// the lowest; and where the next pass begins, one robot further on. Each
/// pass steps one scan per robot, so a process that falls behind falls
/// behind on every robot alike; begun always at the lowest id, the robots
/// last in the pass found one more scan waiting at their turn (theirs
/// arrived while the others stepped), reached the backlog that sheds
/// particles first and held the fewest: in twelve demos at full speed
/// robots 16-19 went down to 10 particles in half the runs or more and
/// robots 0-13 in 0-3 each (55 filters of 240 in all); in twelve with
/// the pass turning, 6 of 240 did (EXPERIMENTS.md 10).
pub fn pass_order(ids: &std::collections::BTreeSet<u32>, begins_at: u32) -> (Vec<u32>, u32) {
    let order: Vec<u32> = ids
        .range(begins_at..)
        .chain(ids.range(..begins_at))
        .copied()
        .collect();
    let next = order.get(1).copied().unwrap_or(begins_at);
    (order, next)
}

/// The tick a SLAM process is done up to, which a lockstep launcher paces
/// its clock to so no scan is dropped, from each followed robot's newest
/// announced tick and the tick of its oldest scan still waiting to be
/// stepped: the oldest tick of the robots still stepping, short of any
/// waiting scan; a robot that is gone (announced two ticks behind the
/// swarm's `newest_roster`) is not waited for.
pub fn done_up_to(
    robots: impl Iterator<Item = (Option<u64>, Option<u64>)>,
    newest_roster: u64,
) -> u64 {
    robots
        .filter_map(|(announced, oldest_waiting)| {
            let announced = announced?;
            let done = oldest_waiting.map_or(announced, |w| w.saturating_sub(1).min(announced));
            (announced + 2 >= newest_roster).then_some(done)
        })
        .min()
        .unwrap_or(newest_roster)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec2;
    use shoal_scenario::Scenario;

    #[test]
    fn slam_is_done_short_of_its_oldest_waiting_scan_and_waits_for_no_gone_robot() {
        // Robot a announced tick 10 with a scan of tick 8 still waiting;
        // robot b announced 10 with none; robot c fell silent at tick 5.
        let robots = [(Some(10), Some(8)), (Some(10), None), (Some(5), None)];
        assert_eq!(done_up_to(robots.into_iter(), 10), 7);
        assert_eq!(done_up_to([(Some(10), None)].into_iter(), 11), 10);
        assert_eq!(
            done_up_to([(None, None)].into_iter(), 11),
            11,
            "nothing to wait for"
        );
    }

    fn follower() -> (Follower, Scenario) {
        follower_of(3)
    }

    fn follower_of(id: u32) -> (Follower, Scenario) {
        let scenario = Scenario::default_arena();
        let config = FilterConfig {
            particles: 20,
            sensor: scenario.sensor.clone(),
            ..FilterConfig::default()
        };
        let arena = [scenario.arena.width, scenario.arena.height];
        (
            Follower::new(id, u64::from(id), scenario.motion.clone(), config, arena),
            scenario,
        )
    }

    /// A walk of full strides, scanned on `tick`.
    fn walk(tick: u64, beams: usize) -> Scan {
        Scan {
            command: Some(Command::Walk(3)),
            ..scan(tick, beams)
        }
    }

    /// Starts `follower`'s filter at `start`, announced for `tick`, on
    /// that tick's scan.
    fn start_at(follower: &mut Follower, tick: u64, start: Pose, beams: usize) {
        follower.announced(tick, start);
        follower
            .on_scans(
                vec![scan(tick, beams)],
                &Bodies::new(3),
                &mut FirstLooks::default(),
                |_| Ok::<(), ()>(()),
            )
            .unwrap();
        assert!(follower.filter().is_some(), "started");
    }

    fn scan(tick: u64, beams: usize) -> Scan {
        Scan {
            tick,
            sim_time: tick as f64 * 0.2,
            command: Some(Command::Stand),
            bumped: false,
            ranges: vec![2.0; beams],
        }
    }

    #[test]
    fn the_stride_reported_is_of_the_walk_stepped_most() {
        let (mut follower, scenario) = follower();
        let beams = scenario.sensor.beams;
        assert_eq!(follower.most_walked(), 3, "the full stride before any walk");
        start_at(&mut follower, 1, Pose::new(4.0, 3.0, 0.0), beams);
        // A wandering robot: walk(2) and turns, one full stride.
        let command = |tick: u64| match tick % 3 {
            0 => Command::Turn(1),
            _ if tick == 4 => Command::Walk(3),
            _ => Command::Walk(2),
        };
        let scans: Vec<Scan> = (2..12)
            .map(|tick| Scan {
                command: Some(command(tick)),
                ..scan(tick, beams)
            })
            .collect();
        follower
            .on_scans(scans, &Bodies::new(3), &mut FirstLooks::default(), |_| {
                Ok::<(), ()>(())
            })
            .unwrap();
        assert_eq!(follower.most_walked(), 2);
    }

    #[test]
    fn scans_wait_for_their_pose_and_the_filter_starts_there_without_stepping_it() {
        let (mut follower, scenario) = follower();
        let beams = scenario.sensor.beams;
        let bodies = Bodies::new(3);
        let mut steps = Vec::new();
        let mut on_step = |s: Stepped<'_>| -> Result<(), ()> {
            steps.push(s.tick);
            Ok(())
        };
        follower
            .on_scans(
                vec![scan(1, beams), scan(2, beams)],
                &bodies,
                &mut FirstLooks::default(),
                &mut on_step,
            )
            .unwrap();
        assert!(follower.filter().is_none(), "no pose announced yet");
        let start = Pose::new(4.0, 3.0, 0.5);
        follower.announced(2, start);
        follower
            .on_scans(
                vec![scan(3, beams)],
                &bodies,
                &mut FirstLooks::default(),
                &mut on_step,
            )
            .unwrap();
        let filter = follower.filter().expect("started at tick 2's pose");
        assert!(filter.estimate().position().distance(DVec2::new(4.0, 3.0)) < 0.05);
        // Tick 1 came before the start and tick 2 is the start: only 3 steps.
        assert_eq!(steps, vec![3]);
        assert_eq!(follower.steps(), 1);
        assert_eq!(follower.newest_announced(), Some(2));
    }

    #[test]
    fn a_follower_behind_moves_through_a_waiting_scans_command_without_scoring_it() {
        let (mut follower, scenario) = follower();
        let beams = scenario.sensor.beams;
        let walk = |tick| walk(tick, beams);
        assert!(!follower.coast(&walk(1)), "no filter to move yet");
        let start = Pose::new(4.0, 3.0, 0.0);
        start_at(&mut follower, 1, start, beams);
        let model = follower.filter().expect("started").model().clone();
        for tick in 2..=4 {
            follower.announced(tick, start);
            assert!(follower.coast(&walk(tick)));
        }
        assert!(
            !follower.coast(&walk(3)),
            "an older scan is not moved through again"
        );
        let filter = follower.filter().expect("started");
        // Three full strides forward, by the model alone: learned nothing.
        let stride = model.full_stride();
        let moved = filter.estimate().x - start.x;
        assert!(
            (moved - 3.0 * stride).abs() < 0.5 * stride,
            "{moved} for {stride}"
        );
        assert_eq!(filter.model(), &model);
        assert_eq!(
            (follower.stepped_tick(), follower.scans_coasted()),
            (Some(4), 3)
        );
        assert_eq!((follower.steps(), follower.scans_missed()), (0, 0));
        // Five waiting: the oldest two are coasted through, three wait.
        let mut pending: std::collections::VecDeque<Scan> = (5..=9).map(walk).collect();
        follower.catch_up(&mut pending);
        assert_eq!(
            pending.iter().map(|s| s.tick).collect::<Vec<_>>(),
            [7, 8, 9]
        );
        assert_eq!(follower.scans_coasted(), 5);
    }

    #[test]
    fn each_pass_over_the_robots_begins_one_robot_further_on() {
        let ids: std::collections::BTreeSet<u32> = [0, 1, 5, 7].into();
        let mut begins_at = 0;
        let mut firsts = Vec::new();
        for _ in 0..5 {
            let (order, next) = pass_order(&ids, begins_at);
            assert_eq!(order.len(), 4, "every robot once a pass: {order:?}");
            firsts.push(order[0]);
            begins_at = next;
        }
        assert_eq!(firsts, [0, 1, 5, 7, 0]);
        assert_eq!(pass_order(&ids, 5).0, [5, 7, 0, 1]);
        // A robot that left: the pass begins at the next one.
        assert_eq!(pass_order(&ids, 6).0, [7, 0, 1, 5]);
        // One robot, or none.
        assert_eq!(pass_order(&[3].into(), 3), (vec![3], 3));
        assert_eq!(pass_order(&Default::default(), 2), (vec![], 2));
    }

    #[test]
    fn a_follower_behind_sheds_particles_and_takes_them_back_when_it_keeps_up() {
        let (mut follower, scenario) = follower();
        let beams = scenario.sensor.beams;
        let walk = |tick| walk(tick, beams);
        start_at(&mut follower, 0, Pose::new(4.0, 3.0, 0.0), beams);
        let count = |f: &Follower| f.filter().map(ParticleFilter::particle_count);
        // `follower_of`'s filter holds 20.
        let configured = 20;
        assert_eq!(count(&follower), Some(configured));
        // Two waiting: neither sheds nor takes back.
        let mut pending: std::collections::VecDeque<Scan> = (1..=2).map(walk).collect();
        follower.catch_up(&mut pending);
        assert_eq!((count(&follower), pending.len()), (Some(configured), 2));
        // Three waiting, step after step: a fifth shed each time, down to
        // a fifth of the configured count and no further.
        let mut held = Vec::new();
        for tick in 3..12 {
            let mut pending: std::collections::VecDeque<Scan> =
                (tick * 10..tick * 10 + 3).map(walk).collect();
            follower.catch_up(&mut pending);
            held.extend(count(&follower));
        }
        assert_eq!(held[..5], [16, 12, 9, 7, 5]);
        assert_eq!(held.last(), Some(&(configured / 5)));
        // Catching up (fewer waiting than at the last look): nothing shed.
        let mut pending: std::collections::VecDeque<Scan> = (100..102).map(walk).collect();
        follower.catch_up(&mut pending);
        assert_eq!(count(&follower), Some(configured / 5));
        // Caught up (only the scan about to be stepped waits): a tenth of
        // the configured count back every tenth step, up to it and no further.
        let mut held = Vec::new();
        for tick in 200..300 {
            let mut pending: std::collections::VecDeque<Scan> = [walk(tick)].into();
            follower.catch_up(&mut pending);
            held.extend(count(&follower));
        }
        assert_eq!(held[..10], [4, 4, 4, 4, 4, 4, 4, 4, 4, 6]);
        assert_eq!(held.last(), Some(&configured));
    }

    #[test]
    fn a_scan_naming_no_command_is_skipped() {
        let (mut follower, scenario) = follower();
        let bodies = Bodies::new(3);
        follower.announced(0, Pose::new(4.0, 3.0, 0.0));
        let mut bad = scan(1, scenario.sensor.beams);
        bad.command = None;
        follower
            .on_scans(
                vec![scan(0, scenario.sensor.beams), bad],
                &bodies,
                &mut FirstLooks::default(),
                |_| Err("no step expected"),
            )
            .unwrap();
        assert_eq!(follower.steps(), 0);
    }

    #[test]
    fn each_filter_maps_the_first_scans_of_the_other_robots_followed() {
        let bodies = Bodies::new(3);
        let mut looks = FirstLooks::default();
        // Robot 3 faces east and robot 4 west, from the same spot: each
        // sees a wall 2 m off that the other cannot.
        let (east, west) = (DVec2::new(6.0, 3.0), DVec2::new(2.0, 3.0));
        let mut robots = [(3, 0.0), (4, std::f64::consts::PI)].map(|(id, heading)| {
            let (mut follower, scenario) = follower_of(id);
            follower.announced(0, Pose::new(4.0, 3.0, heading));
            (follower, scenario.sensor.beams)
        });
        let occupied = |follower: &Follower, at: DVec2| {
            let map = &follower.filter().expect("started").particles[0].map;
            map.occupancy(map.cell_of(at).expect("inside the map"))
        };
        let scans_of = |follower: &mut Follower, scan: Scan, looks: &mut FirstLooks| {
            follower
                .on_scans(vec![scan], &bodies, looks, |_| Ok::<(), ()>(()))
                .unwrap();
        };
        // Robot 4's filter has not started when robot 3 shares its look:
        // it maps the look when it starts.
        let (follower, beams) = &mut robots[0];
        scans_of(follower, scan(0, *beams), &mut looks);
        assert!(occupied(follower, east) > 0.6, "its own look");
        assert!(occupied(follower, west) <= 0.5, "unseen yet");
        let (follower, beams) = &mut robots[1];
        scans_of(follower, scan(0, *beams), &mut looks);
        assert!(occupied(follower, west) > 0.6, "its own look");
        assert!(occupied(follower, east) > 0.6, "robot 3's look, held");
        // Robot 3 maps robot 4's look before its next step.
        let (follower, beams) = &mut robots[0];
        scans_of(follower, scan(1, *beams), &mut looks);
        assert_eq!(follower.steps(), 1);
        assert!(occupied(&robots[0].0, west) > 0.6, "robot 4's look");
    }
}

//! One clock for commands and poses. A bag times every message twice: its
//! header stamp, where the type has one (set by whoever made the message),
//! and its log time (when the recorder received it, on the recorder's wall
//! clock). The two disagree in every Gazebo bag (stamps in simulation time
//! from near 0, log times in Unix time), for a robot whose clock is off, and
//! where stamps were never set (zero). Commands and poses must be compared
//! on one clock: this chooses it, says why, and says what the choice means
//! for a delay fitted between command and motion.

/// What the user asked for (`--stamps`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StampsPreference {
    /// Choose from the data.
    #[default]
    Auto,
    /// Header stamps (a topic without them is carried into their clock).
    Header,
    /// The bag's log times for both topics.
    Log,
}

/// How one topic's messages are timed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Timing {
    /// The messages' own header stamps.
    HeaderStamps,
    /// The times the bag logged them.
    LogTimes,
    /// Log times carried into the stamps' clock through a reference that
    /// is on both: `/clock`, or the other topic's stamps against their own
    /// log times.
    MappedLogTimes(Reference),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reference {
    ClockTopic,
    OtherTopicsStamps,
}

impl std::fmt::Display for Timing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Timing::HeaderStamps => "header stamps",
            Timing::LogTimes => "the bag's log times",
            Timing::MappedLogTimes(Reference::ClockTopic) => {
                "log times mapped into simulation time through /clock"
            }
            Timing::MappedLogTimes(Reference::OtherTopicsStamps) => {
                "log times mapped into the other topic's stamp clock"
            }
        })
    }
}

/// The clock chosen, and what it means.
#[derive(Clone, Debug, PartialEq)]
pub struct ClockChoice {
    pub commands: Timing,
    pub poses: Timing,
    /// Why, in words.
    pub reason: String,
    /// What the choice means for a delay fitted between command and motion.
    pub delay_note: String,
}

/// One topic's message times: header stamp (None when the type has none or
/// it was never set) and log time, nanoseconds.
pub type Times = [(Option<i64>, i64)];

/// Two clocks closer than this are one: a message's transport to the
/// recorder rarely takes longer, and two clocks apart are further apart
/// (simulation time from 0 against Unix time, a robot clock a few seconds
/// off).
const SAME_CLOCK_NS: i64 = 500_000_000;
/// A simulation whose clock runs within this of real time is timed by log
/// times without mapping: the two then differ by transport only.
const REAL_TIME_RATE_TOLERANCE: f64 = 0.01;
/// A mapping through a reference whose spread (p95) is wider than this is
/// not used: the reference is itself unsteady.
const MAPPING_SPREAD_LIMIT_NS: i64 = 100_000_000;
/// Messages a mapping point summarises (medians): enough to smooth one
/// message's transport, few enough to follow a simulation that slows.
const MAPPING_WINDOW: usize = 25;

fn stamped(times: &Times) -> bool {
    !times.is_empty() && times.iter().all(|(s, _)| s.is_some())
}

/// The median of `stamp - log` over a topic: where its stamp clock sits
/// against the log clock.
fn offset(times: &Times) -> Option<i64> {
    let mut d: Vec<i64> = times.iter().filter_map(|(s, l)| s.map(|s| s - l)).collect();
    if d.is_empty() {
        return None;
    }
    d.sort_unstable();
    Some(d[d.len() / 2])
}

/// The p5-p95 range of `log - stamp` about its median, in milliseconds:
/// how much a topic's transport to the recorder varied.
fn transport_spread_ms(times: &Times) -> Option<f64> {
    let mut d: Vec<i64> = times.iter().filter_map(|(s, l)| s.map(|s| l - s)).collect();
    if d.len() < 20 {
        return None;
    }
    d.sort_unstable();
    let at = |q: f64| d[((d.len() - 1) as f64 * q).round() as usize];
    Some((at(0.95) - at(0.05)) as f64 * 1e-6)
}

fn seconds(ns: i64) -> String {
    let s = ns as f64 * 1e-9;
    if s.abs() >= 1e6 {
        format!("{:.3e} s", s)
    } else {
        format!("{s:.3} s")
    }
}

/// A piecewise-linear map from log time to another clock, through medians
/// of windows of (log, other) pairs.
#[derive(Clone, Debug)]
pub struct LogToClock {
    points: Vec<(f64, f64)>,
    /// p95 of |other - mapped(log)| over the pairs: how far the map is
    /// from the reference itself.
    pub spread_ns: i64,
    /// The other clock's rate against the log clock, end to end.
    pub rate: f64,
}

impl LogToClock {
    /// The map through `pairs` (log, other), sorted by log time; none for
    /// fewer than two windows' worth.
    pub fn through(pairs: &[(i64, i64)]) -> Option<Self> {
        let mut pairs = pairs.to_vec();
        pairs.sort_unstable();
        let window = MAPPING_WINDOW.min(pairs.len() / 2).max(1);
        if pairs.len() < 2 * window || pairs.len() < 4 {
            return None;
        }
        let median = |mut v: Vec<i64>| {
            v.sort_unstable();
            v[v.len() / 2] as f64
        };
        let points: Vec<(f64, f64)> = pairs
            .chunks(window)
            .filter(|c| c.len() * 2 >= window)
            .map(|c| {
                (
                    median(c.iter().map(|p| p.0).collect()),
                    median(c.iter().map(|p| p.1).collect()),
                )
            })
            .collect();
        if points.len() < 2 || points.windows(2).any(|w| w[1].0 <= w[0].0) {
            return None;
        }
        let (first, last) = (points[0], points[points.len() - 1]);
        let rate = (last.1 - first.1) / (last.0 - first.0);
        let mut map = Self {
            points,
            spread_ns: 0,
            rate,
        };
        let mut errors: Vec<i64> = pairs.iter().map(|&(l, o)| (o - map.map(l)).abs()).collect();
        errors.sort_unstable();
        map.spread_ns = errors[((errors.len() - 1) as f64 * 0.95).round() as usize];
        Some(map)
    }

    /// The other clock's time at log time `log`; past either end the
    /// nearest piece is extended.
    pub fn map(&self, log: i64) -> i64 {
        let x = log as f64;
        let i = self
            .points
            .partition_point(|p| p.0 <= x)
            .clamp(1, self.points.len() - 1);
        let (a, b) = (self.points[i - 1], self.points[i]);
        (a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0)).round() as i64
    }
}

/// Chooses the clock for `commands` and `poses` (their (stamp, log) times),
/// given the bag's `/clock` as (log, simulation time) pairs (empty when it
/// has none). Returns the choice and, for mapped log times, the map.
pub fn choose(
    commands: &Times,
    poses: &Times,
    clock: &[(i64, i64)],
    preference: StampsPreference,
) -> Result<(ClockChoice, Option<LogToClock>), String> {
    let (c_stamped, p_stamped) = (stamped(commands), stamped(poses));
    let (c_off, p_off) = (offset(commands), offset(poses));
    let spread = transport_spread_ms(poses);
    let log_both = |reason: String| log_times_for_both(reason, spread);
    if preference == StampsPreference::Log {
        return Ok(log_both("--stamps log".to_owned()));
    }
    match (c_stamped, p_stamped, c_off, p_off) {
        (true, true, Some(c), Some(p)) if (c - p).abs() <= SAME_CLOCK_NS => Ok((
            ClockChoice {
                commands: Timing::HeaderStamps,
                poses: Timing::HeaderStamps,
                reason: "both topics carry header stamps on one clock".to_owned(),
                delay_note: "both are stamped where they were made: a fitted delay is the \
                             robot's own response"
                    .to_owned(),
            },
            None,
        )),
        (true, true, Some(c), Some(p)) => {
            let reason = format!(
                "the topics' header stamps are on different clocks (the commands' {} and the \
                 poses' {} from the log times), so both are timed by the bag's log times, the \
                 clock they share",
                seconds(c),
                seconds(p)
            );
            if preference == StampsPreference::Header {
                return Err(format!("--stamps header: {reason}; use --stamps log"));
            }
            Ok(log_both(reason))
        }
        (false, true, _, Some(p)) => unstamped_commands(poses, p, clock, preference, log_both),
        (true, false, Some(c), _)
            if preference == StampsPreference::Header || c.abs() <= SAME_CLOCK_NS =>
        {
            if c.abs() > SAME_CLOCK_NS {
                return Err(
                    "--stamps header: the poses carry no header stamps and the commands' are \
                     on another clock than the bag's log times; use --stamps log"
                        .to_owned(),
                );
            }
            Ok((
                ClockChoice {
                    commands: Timing::HeaderStamps,
                    poses: Timing::LogTimes,
                    reason: format!(
                        "the poses carry no header stamps; the commands' stamps are on the \
                         bag's log clock (within {})",
                        seconds(c.abs())
                    ),
                    delay_note: "the poses are timed on arrival at the recorder: a fitted \
                                 delay is the robot's response plus the poses' transport (not \
                                 known here)"
                        .to_owned(),
                },
                None,
            ))
        }
        _ if preference == StampsPreference::Header => Err(
            "--stamps header: neither topic carries header stamps (or they were never set); \
             use --stamps log"
                .to_owned(),
        ),
        _ => Ok(log_both(
            "not every message carries a header stamp (or they were never set), so both \
             topics are timed by the bag's log times"
                .to_owned(),
        )),
    }
}

/// Both topics timed by the bag's log times, and what that means for a
/// delay, given how much the poses' transport varied (`spread`, ms).
fn log_times_for_both(reason: String, spread: Option<f64>) -> (ClockChoice, Option<LogToClock>) {
    let delay_note = match spread {
        Some(ms) => format!(
            "both are timed on arrival at the recorder: a fitted delay is the robot's \
             response plus the poses' transport less the commands'; the poses' transport \
             varied by {ms:.1} ms (p5-p95 of log time less stamp)"
        ),
        None => "both are timed on arrival at the recorder: a fitted delay is the robot's \
                 response plus the poses' transport less the commands' (neither is known \
                 here: the poses carry no stamps)"
            .to_owned(),
    };
    (
        ClockChoice {
            commands: Timing::LogTimes,
            poses: Timing::LogTimes,
            reason,
            delay_note,
        },
        None,
    )
}

/// The map from log time to simulation time through the bag's `/clock`,
/// if it has one that is steady and is the poses' clock.
fn clock_topic_map(clock: &[(i64, i64)], poses: &Times) -> Option<LogToClock> {
    if clock.len() < 4 {
        return None;
    }
    LogToClock::through(clock)
        .filter(|m| m.spread_ns <= MAPPING_SPREAD_LIMIT_NS)
        // The simulation clock must be the poses' clock.
        .filter(|m| {
            let (s, l) = poses[poses.len() / 2];
            s.is_some_and(|s| (m.map(l) - s).abs() <= SAME_CLOCK_NS)
        })
}

/// What a fitted delay means when the commands carry no stamps.
const UNKNOWN_COMMAND_TRANSPORT: &str = "a fitted delay is the robot's response less the \
     commands' transport to the recorder (not known here: commands carry no stamps)";

/// Unstamped commands by their log times, stamped poses by their stamps,
/// which are on the log clock (`pose_offset` apart).
fn poses_on_the_log_clock(pose_offset: i64) -> ClockChoice {
    ClockChoice {
        commands: Timing::LogTimes,
        poses: Timing::HeaderStamps,
        reason: format!(
            "the commands carry no header stamps; the poses' stamps are on the bag's \
             log clock (within {})",
            seconds(pose_offset.abs())
        ),
        delay_note: format!(
            "commands are timed on arrival at the recorder: {UNKNOWN_COMMAND_TRANSPORT}"
        ),
    }
}

/// Unstamped commands' log times mapped into simulation time through
/// `/clock` (`map`), poses by their stamps on another clock.
fn through_the_clock_topic(map: &LogToClock, other_clock: &str) -> ClockChoice {
    ClockChoice {
        commands: Timing::MappedLogTimes(Reference::ClockTopic),
        poses: Timing::HeaderStamps,
        reason: format!(
            "{other_clock}; the commands' log times were mapped into simulation time \
             through /clock (simulation ran at {:.2}x real time)",
            map.rate
        ),
        delay_note: format!(
            "{UNKNOWN_COMMAND_TRANSPORT}, within the mapping's {:.1} ms",
            map.spread_ns as f64 * 1e-6
        ),
    }
}

/// Stamped poses, unstamped commands (a `Twist` has no header).
fn unstamped_commands(
    poses: &Times,
    pose_offset: i64,
    clock: &[(i64, i64)],
    preference: StampsPreference,
    log_both: impl Fn(String) -> (ClockChoice, Option<LogToClock>),
) -> Result<(ClockChoice, Option<LogToClock>), String> {
    if pose_offset.abs() <= SAME_CLOCK_NS {
        return Ok((poses_on_the_log_clock(pose_offset), None));
    }
    let other_clock = format!(
        "the poses are stamped on another clock than the bag's log times ({} apart: \
         simulation time, or a robot clock that is off) and the commands carry no header stamps",
        seconds(pose_offset.abs())
    );
    if let Some(map) = clock_topic_map(clock, poses) {
        return Ok((through_the_clock_topic(&map, &other_clock), Some(map)));
    }
    let pairs: Vec<(i64, i64)> = poses
        .iter()
        .filter_map(|(s, l)| s.map(|s| (*l, s)))
        .collect();
    let through_poses =
        LogToClock::through(&pairs).filter(|m| m.spread_ns <= MAPPING_SPREAD_LIMIT_NS);
    match through_poses {
        Some(map)
            if preference == StampsPreference::Header
                || (map.rate - 1.0).abs() > REAL_TIME_RATE_TOLERANCE =>
        {
            let choice = ClockChoice {
                commands: Timing::MappedLogTimes(Reference::OtherTopicsStamps),
                poses: Timing::HeaderStamps,
                reason: format!(
                    "{other_clock}; the bag has no /clock, and the poses' stamps ran at {:.3}x \
                     their log times, so the commands' log times were mapped into the poses' \
                     clock through the poses' own stamps and log times",
                    map.rate
                ),
                delay_note: format!(
                    "{UNKNOWN_COMMAND_TRANSPORT}, and the poses' transport, within the mapping's {:.1} ms",
                    map.spread_ns as f64 * 1e-6
                ),
            };
            Ok((choice, Some(map)))
        }
        _ if preference == StampsPreference::Header => Err(format!(
            "--stamps header: {other_clock}, and neither /clock nor the poses' own times map \
             the commands into the poses' clock; use --stamps log"
        )),
        _ => Ok(log_both(format!(
            "{other_clock}; the bag has no /clock, and the poses' clock runs at the log \
             clock's rate, so both topics are timed by the bag's log times"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: i64 = 1_000_000_000;
    const WALL: i64 = 1_700_000_000 * S;

    /// Messages every `period` ns from `start` on the log clock, stamped on
    /// a clock at `stamp_offset` running at `rate`, arriving `transport` late.
    fn topic(
        n: usize,
        period: i64,
        stamp: Option<(i64, f64)>,
        transport: i64,
    ) -> Vec<(Option<i64>, i64)> {
        (0..n as i64)
            .map(|k| {
                let made = WALL + k * period;
                let jitter = (k * 7919 % 13) * 1_000_000;
                (
                    stamp.map(|(offset, rate)| offset + ((k * period) as f64 * rate) as i64),
                    made + transport + jitter,
                )
            })
            .collect()
    }

    #[test]
    fn stamps_on_one_clock_are_used() {
        let c = topic(200, S / 20, Some((WALL, 1.0)), 3_000_000);
        let p = topic(600, S / 60, Some((WALL, 1.0)), 2_000_000);
        let (choice, map) = choose(&c, &p, &[], StampsPreference::Auto).expect("choice");
        assert_eq!(
            (choice.commands, choice.poses),
            (Timing::HeaderStamps, Timing::HeaderStamps)
        );
        assert!(map.is_none());
    }

    #[test]
    fn gazebo_poses_in_simulation_time_with_unstamped_commands_go_through_clock() {
        // Simulation time from 12 s, at 0.8x real time; /clock at 100 Hz.
        let c = topic(200, S / 10, None, 1_000_000);
        let p = topic(600, S / 30, Some((12 * S, 0.8)), 4_000_000);
        let clock: Vec<(i64, i64)> = (0..2000_i64)
            .map(|k| {
                (
                    WALL + k * S / 100 + 1_000_000,
                    12 * S + (k * S / 100) * 4 / 5,
                )
            })
            .collect();
        let (choice, map) = choose(&c, &p, &clock, StampsPreference::Auto).expect("choice");
        assert_eq!(
            choice.commands,
            Timing::MappedLogTimes(Reference::ClockTopic)
        );
        assert_eq!(choice.poses, Timing::HeaderStamps);
        assert!(
            choice.reason.contains("0.80x real time"),
            "{}",
            choice.reason
        );
        let map = map.expect("a map");
        // A command logged 5 s in is at 12 + 4 s of simulation time.
        let at = map.map(WALL + 5 * S + 1_000_000);
        assert!((at - 16 * S).abs() < 5_000_000, "{at}");
    }

    #[test]
    fn without_clock_a_simulation_at_real_time_uses_log_times_and_a_slow_one_the_poses_stamps() {
        let c = topic(200, S / 10, None, 1_000_000);
        let real_time = topic(600, S / 30, Some((3 * S, 1.0)), 4_000_000);
        let (choice, map) = choose(&c, &real_time, &[], StampsPreference::Auto).expect("choice");
        assert_eq!(
            (choice.commands, choice.poses),
            (Timing::LogTimes, Timing::LogTimes)
        );
        assert!(map.is_none());
        assert!(
            choice.delay_note.contains("varied by"),
            "{}",
            choice.delay_note
        );
        let slow = topic(600, S / 30, Some((3 * S, 0.5)), 4_000_000);
        let (choice, map) = choose(&c, &slow, &[], StampsPreference::Auto).expect("choice");
        assert_eq!(
            choice.commands,
            Timing::MappedLogTimes(Reference::OtherTopicsStamps)
        );
        assert!((map.expect("a map").rate - 0.5).abs() < 0.01);
    }

    #[test]
    fn zero_stamps_and_the_users_word_are_honoured() {
        let c = topic(100, S / 10, None, 0);
        let unset = topic(300, S / 30, None, 0);
        let (choice, _) = choose(&c, &unset, &[], StampsPreference::Auto).expect("choice");
        assert_eq!(choice.poses, Timing::LogTimes);
        assert!(choose(&c, &unset, &[], StampsPreference::Header).is_err());
        let p = topic(300, S / 30, Some((WALL, 1.0)), 0);
        let (choice, _) = choose(&c, &p, &[], StampsPreference::Log).expect("choice");
        assert_eq!(
            (choice.commands, choice.poses),
            (Timing::LogTimes, Timing::LogTimes)
        );
        assert_eq!(choice.reason, "--stamps log");
    }

    #[test]
    fn stamps_on_two_clocks_fall_back_to_log_times_and_say_so() {
        let c = topic(100, S / 10, Some((WALL - 3 * S, 1.0)), 0);
        let p = topic(300, S / 30, Some((WALL, 1.0)), 0);
        let (choice, _) = choose(&c, &p, &[], StampsPreference::Auto).expect("choice");
        assert_eq!(choice.commands, Timing::LogTimes);
        assert!(
            choice.reason.contains("different clocks"),
            "{}",
            choice.reason
        );
        assert!(choose(&c, &p, &[], StampsPreference::Header).is_err());
    }
}

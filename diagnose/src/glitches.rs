//! The first stage: what in a recording is not the robot's motion, found by
//! physics and set aside before anything is fitted. A body cannot move
//! 0.2 m in 15 ms and back; a motion-capture system that swaps markers or
//! catches a reflection can. Fitted, such frames turn into invented physics
//! (a battery that fades 16% a minute), so they are found, set aside and
//! reported with their count and times, never fitted.
//!
//! - Jumps and returns: a pose no body could reach from the last good one
//!   (faster than the commands allow, with a generous margin, plus the
//!   tracker's own noise), until the track comes back within reach. A
//!   marker swap lasting several frames is one episode.
//! - Jumps without a return: the track resumes elsewhere (the tracker
//!   re-initialised, the robot was carried); no comparison spans it.
//! - Pose gaps: stretches without observations longer than
//!   the poses' gap limit (`Poses::gap_limit`); no comparison spans them.
//! - Command stalls: the command stream stops for many of its periods and
//!   resumes with a burst of commands repeated in a few milliseconds: a
//!   backlog, not commands given then, and what the robot did meanwhile is
//!   unknown. No comparison spans the stall or the burst. (A stream that
//!   only pauses is a robot holding its last command, and is compared.)
//! - Held in place: a robot that was driving as commanded stops dead while
//!   its command goes on (a wall, an obstacle, another robot in its way).
//!   Contact is the world's doing, not the body's: fitted, one bump of 0.8 s
//!   against an obstacle held a wandering robot's true speed scale of 1.2
//!   out of its diagnosis (EXPERIMENTS.md 7, "Contact set aside"). Only a
//!   stop from motion counts: a robot that does not start (a deadband, a
//!   latency, an acceleration limit) or slows as it goes (slip, a fading
//!   battery) is physics of its body, and is fitted.
//! - Stuck: a robot that stays where it is over a long drive at speeds it
//!   makes elsewhere in the recording, while it still turns as commanded
//!   (a robot pushing into its neighbours, walking and turning by turns,
//!   held from its first stride). Its turning says the body answers its
//!   commands; its speed, made elsewhere, says no deadband holds it; and a
//!   battery that fades to nothing stops the turns too.

use std::collections::VecDeque;

use serde::Serialize;

use crate::recording::{Commands, Poses, Recording};

/// A stretch set aside, in the run's seconds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Glitch {
    pub kind: GlitchKind,
    pub t_start: f64,
    pub t_end: f64,
    /// Observed poses set aside in it.
    pub frames: usize,
    /// How far the pose jumped from the track, metres (jumps); the
    /// commanded travel not made (held in place).
    pub size_m: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GlitchKind {
    JumpAndReturn,
    JumpWithoutReturn,
    PoseGap,
    CommandStall,
    HeldInPlace,
}

impl GlitchKind {
    /// `count` of this kind, in words: "3 pose jumps and returns (...)".
    pub fn describe(self, count: usize) -> String {
        let ((one, many), why) = match self {
            GlitchKind::JumpAndReturn => (
                ("pose jump and return", "pose jumps and returns"),
                "faster than any body moves",
            ),
            GlitchKind::JumpWithoutReturn => (
                (
                    "pose jump that never came back",
                    "pose jumps that never came back",
                ),
                "the track resumed elsewhere",
            ),
            GlitchKind::PoseGap => (
                ("gap without observed poses", "gaps without observed poses"),
                "",
            ),
            GlitchKind::CommandStall => (
                ("command stall", "command stalls"),
                "the stream stopped, then resumed in a burst",
            ),
            GlitchKind::HeldInPlace => (
                ("stop while driving", "stops while driving"),
                "held in place against the command: contact with a wall, an obstacle, another robot",
            ),
        };
        let what = if count == 1 { one } else { many };
        if why.is_empty() {
            format!("{count} {what}")
        } else {
            format!("{count} {what} ({why})")
        }
    }

    /// Every kind, in the order a report lists them.
    pub const ALL: [GlitchKind; 5] = [
        GlitchKind::JumpAndReturn,
        GlitchKind::JumpWithoutReturn,
        GlitchKind::PoseGap,
        GlitchKind::CommandStall,
        GlitchKind::HeldInPlace,
    ];
}

impl Glitch {
    /// Its size in words: how far the pose jumped, or how far the robot
    /// was commanded to drive and did not; empty for the others.
    pub fn size_text(&self) -> String {
        match self.kind {
            _ if self.size_m <= 0.0 => String::new(),
            GlitchKind::HeldInPlace => {
                format!("{:.2} m of commanded travel not made", self.size_m)
            }
            _ => format!("{:.2} m from the track", self.size_m),
        }
    }
}

/// A jump that has not come back within this long is the track resuming
/// elsewhere, not a glitch of a few frames.
const MAX_EXCURSION_S: f64 = 2.0;
/// The fastest a body may be taken to move: this many times the fastest
/// command, plus a floor (a robot faster than commanded, or pushed).
const SPEED_MARGIN: f64 = 2.0;
const SPEED_FLOOR_M_S: f64 = 0.5;
const TURN_FLOOR_RAD_S: f64 = 2.0;
/// The tracker's noise allowance: this many of its frame-to-frame standard
/// deviations, and at least the floors.
const NOISE_SIGMAS: f64 = 6.0;
const POSITION_TOLERANCE_FLOOR_M: f64 = 0.02;
const HEADING_TOLERANCE_FLOOR_RAD: f64 = 0.1;
/// A command stream silent for this many of its usual periods, and at least
/// this long, has stalled.
const STALL_PERIODS: f64 = 10.0;
const STALL_FLOOR_S: f64 = 0.5;
/// Commands after a stall closer together than this share of the usual
/// period are its backlog.
const BURST_SHARE: f64 = 0.2;
/// A silence followed by fewer backlogged commands than this is a stream
/// that paused: a robot holds its last command (MRCLAM's log pauses for up
/// to a second while its robots drive on), and that is what is compared.
const MIN_BURST: usize = 3;
/// Held in place: over a stretch commanded to drive at least
/// `HELD_MIN_TRAVEL_M` (one way), the robot stayed within this share of the
/// commanded travel of where it stood (plus the tracker's noise, at most
/// `HELD_NOISE_CAP_M`: at a few hertz the second differences hold the
/// gait's own variation, not the tracker's)...
const HELD_SHARE: f64 = 0.1;
const HELD_MIN_TRAVEL_M: f64 = 0.2;
const HELD_NOISE_SIGMAS: f64 = 3.0;
const HELD_NOISE_CAP_M: f64 = 0.01;
/// ... having driven, just before and for as long, at least this share of
/// what it was commanded (as the crow flies, so turns count against it),
/// commanded the same way, at least half `HELD_MIN_TRAVEL_M`, at a speed
/// (while the command drove) within this ratio of the stretch's: a robot
/// that slows to a crawl and stops may be meeting its deadband.
const HELD_MOVING_SHARE: f64 = 0.5;
const HELD_SPEED_RATIO: f64 = 2.0;
/// Stuck: within `HELD_SHARE * HELD_MIN_TRAVEL_M` of where it stood (plus
/// the tracker's noise) over at least this much commanded travel and
/// driving time, far beyond what a latency, a lag or an acceleration limit
/// holds a robot still for...
const STUCK_MIN_TRAVEL_M: f64 = 1.0;
const STUCK_MIN_DRIVING_S: f64 = 2.0;
/// ... commanded to turn and turning, at least this much...
const STUCK_MIN_TURN_RAD: f64 = 0.3;
/// ... at a speed (while driving) no less than the slowest at which it made
/// `HELD_MOVING_SHARE` of its commanded travel over `MADE_WINDOW_S`
/// somewhere, over this ratio: a deadband that lets the robot make half of
/// a speed lets it move at two thirds of that speed.
const STUCK_SPEED_RATIO: f64 = 1.5;
const MADE_WINDOW_S: f64 = 1.0;

/// The recording with its glitches set aside, and the glitches.
pub fn set_aside(recording: &Recording) -> (Recording, Vec<Glitch>) {
    let bounds = Bounds::of(recording);
    let mut glitches = Vec::new();
    let (mut poses, jumps) = without_jumps(&recording.poses, &bounds);
    glitches.extend(jumps);
    for stall in command_stalls(recording) {
        poses = without_span(&poses, stall.t_start, stall.t_end);
        glitches.push(stall);
    }
    glitches.extend(pose_gaps(&recording.poses));
    let mut held = held_in_place(&recording.commands, &poses);
    held.extend(stuck(&recording.commands, &poses));
    for held in merged(held, &recording.commands, &poses) {
        poses = without_span(&poses, held.t_start, held.t_end);
        glitches.push(held);
    }
    glitches.sort_by(|a, b| a.t_start.total_cmp(&b.t_start));
    (
        Recording {
            poses,
            ..recording.clone()
        },
        glitches,
    )
}

/// How far a body can move between two observations.
struct Bounds {
    speed: f64,
    turn_rate: f64,
    position_tolerance: f64,
    heading_tolerance: f64,
}

impl Bounds {
    fn of(recording: &Recording) -> Self {
        let c = &recording.commands;
        let fastest = c.v.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let fastest_turn = c.omega.iter().fold(0.0_f64, |m, w| m.max(w.abs()));
        let p = &recording.poses;
        Self {
            speed: SPEED_MARGIN * fastest + SPEED_FLOOR_M_S,
            turn_rate: SPEED_MARGIN * fastest_turn + TURN_FLOOR_RAD_S,
            position_tolerance: (NOISE_SIGMAS * frame_noise(&p.x).hypot(frame_noise(&p.y)))
                .max(POSITION_TOLERANCE_FLOOR_M),
            heading_tolerance: (NOISE_SIGMAS * frame_noise(&p.theta))
                .max(HEADING_TOLERANCE_FLOOR_RAD),
        }
    }

    fn reachable(&self, from: (f64, f64, f64, f64), to: (f64, f64, f64, f64)) -> bool {
        let dt = (to.0 - from.0).abs();
        let moved = (to.1 - from.1).hypot(to.2 - from.2);
        // Poses of positions only (headings not yet taken from the track)
        // are judged by where they are.
        let turned = (to.3 - from.3).abs();
        moved <= self.speed * dt + self.position_tolerance
            && (turned.is_nan() || turned <= self.turn_rate * dt + self.heading_tolerance)
    }
}

/// A tracker's frame-to-frame noise in one coordinate: from the second
/// differences (white noise of deviation s gives second differences of
/// deviation s * sqrt(6)), robustly (median absolute value), so that motion
/// (smooth) and glitches (rare) do not count.
fn frame_noise(values: &[f64]) -> f64 {
    let mut second: Vec<f64> = values
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .collect();
    if second.is_empty() {
        return 0.0;
    }
    second.sort_by(f64::total_cmp);
    1.4826 * second[second.len() / 2] / 6.0_f64.sqrt()
}

fn pose(p: &Poses, i: usize) -> (f64, f64, f64, f64) {
    (p.t[i], p.x[i], p.y[i], p.theta[i])
}

/// Walks the track keeping the last pose within reach; poses out of reach
/// are set aside until the track comes back. A track that does not come
/// back within `MAX_EXCURSION_S` resumes from where it went, and no
/// comparison spans the jump.
fn without_jumps(poses: &Poses, bounds: &Bounds) -> (Poses, Vec<Glitch>) {
    let n = poses.len();
    let gap_limit = poses.gap_limit();
    let mut keep = vec![true; n];
    let mut glitches = Vec::new();
    let mut last_good = 0;
    let mut i = 1;
    while i < n {
        if bounds.reachable(pose(poses, last_good), pose(poses, i)) {
            last_good = i;
            i += 1;
            continue;
        }
        // Out of reach: look for the return, a jump back to within reach
        // of the last good pose. (Reach alone is no return: given time,
        // a track that moved for good comes within reach too.)
        let from = pose(poses, last_good);
        let mut j = i + 1;
        while j < n
            && poses.t[j] - poses.t[i] <= MAX_EXCURSION_S
            && (!bounds.reachable(from, pose(poses, j))
                || bounds.reachable(pose(poses, j - 1), pose(poses, j)))
        {
            j += 1;
        }
        let size = (i..j.min(n))
            .map(|k| (poses.x[k] - from.1).hypot(poses.y[k] - from.2))
            .fold(0.0_f64, f64::max);
        let returned = j < n && poses.t[j] - poses.t[i] <= MAX_EXCURSION_S;
        if returned {
            for flag in &mut keep[i..j] {
                *flag = false;
            }
            glitches.push(Glitch {
                kind: GlitchKind::JumpAndReturn,
                t_start: poses.t[i],
                t_end: poses.t[j - 1],
                frames: j - i,
                size_m: size,
            });
            last_good = j;
            i = j + 1;
        } else {
            // The track resumed at i: cut it there, wide enough that no
            // comparison interpolates across the jump.
            let (cut_from, cut_to) = (
                poses.t[last_good] - 0.5 * gap_limit,
                poses.t[i] + 0.5 * gap_limit,
            );
            let mut frames = 0;
            for (k, flag) in keep.iter_mut().enumerate() {
                if (cut_from..=cut_to).contains(&poses.t[k]) && *flag {
                    *flag = false;
                    frames += 1;
                }
            }
            glitches.push(Glitch {
                kind: GlitchKind::JumpWithoutReturn,
                t_start: poses.t[i],
                t_end: poses.t[i],
                frames,
                size_m: (poses.x[i] - from.1).hypot(poses.y[i] - from.2),
            });
            last_good = i;
            i += 1;
        }
    }
    let mut kept = Poses::default();
    for k in (0..n).filter(|&k| keep[k]) {
        kept.push(poses.t[k], poses.x[k], poses.y[k], poses.theta[k]);
    }
    (kept, glitches)
}

/// The poses outside `[from, to]`, with the span widened so that no
/// comparison interpolates across it.
fn without_span(poses: &Poses, from: f64, to: f64) -> Poses {
    let pad = 0.5 * poses.gap_limit();
    let mut kept = Poses::default();
    for k in 0..poses.len() {
        if !(from - pad..=to + pad).contains(&poses.t[k]) {
            kept.push(poses.t[k], poses.x[k], poses.y[k], poses.theta[k]);
        }
    }
    kept
}

/// Stretches without observed poses that no comparison spans.
fn pose_gaps(poses: &Poses) -> Vec<Glitch> {
    let gap_limit = poses.gap_limit();
    poses
        .t
        .windows(2)
        .filter(|w| w[1] - w[0] > gap_limit)
        .map(|w| Glitch {
            kind: GlitchKind::PoseGap,
            t_start: w[0],
            t_end: w[1],
            frames: 0,
            size_m: 0.0,
        })
        .collect()
}

/// Silences of the command stream, each with the burst that ended it.
fn command_stalls(recording: &Recording) -> Vec<Glitch> {
    let t = &recording.commands.t;
    let mut periods: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if periods.len() < 10 {
        return Vec::new();
    }
    periods.sort_by(f64::total_cmp);
    let usual = periods[periods.len() / 2];
    let stall = (STALL_PERIODS * usual).max(STALL_FLOOR_S);
    let mut out = Vec::new();
    for k in 1..t.len() {
        if t[k] - t[k - 1] <= stall {
            continue;
        }
        // The backlog: commands that follow much faster than usual.
        let mut end = k;
        while end + 1 < t.len() && t[end + 1] - t[end] < BURST_SHARE * usual {
            end += 1;
        }
        if end - k + 1 < MIN_BURST {
            continue;
        }
        out.push(Glitch {
            kind: GlitchKind::CommandStall,
            t_start: t[k - 1],
            t_end: t[end],
            frames: 0,
            size_m: 0.0,
        });
    }
    out
}

/// What the commands asked from `a` to `b`, each command held until the
/// next, nothing before the first.
#[derive(Clone, Copy, Default)]
struct Commanded {
    /// Travel, metres, signed.
    travel: f64,
    /// Travel, metres, each way counted.
    travel_abs: f64,
    /// For how long the command drove, seconds.
    driving: f64,
    /// Turn, radians, each way counted.
    turn_abs: f64,
}

fn commanded(commands: &Commands, a: f64, b: f64) -> Commanded {
    let t = &commands.t;
    let first = t.partition_point(|&s| s <= a).saturating_sub(1);
    let mut asked = Commanded::default();
    for k in first..t.len() {
        let from = t[k].max(a);
        let to = t.get(k + 1).copied().unwrap_or(f64::INFINITY).min(b);
        if to > from {
            let dt = to - from;
            if commands.v[k] != 0.0 {
                asked.travel += commands.v[k] * dt;
                asked.travel_abs += commands.v[k].abs() * dt;
                asked.driving += dt;
            }
            asked.turn_abs += commands.omega[k].abs() * dt;
        }
        if t[k] >= b {
            break;
        }
    }
    asked
}

fn commanded_travel(commands: &Commands, a: f64, b: f64) -> f64 {
    commanded(commands, a, b).travel
}

/// Stretches in which the robot, driving as commanded, stopped dead while
/// its command went on (see the module's notes and the `HELD_` constants).
fn held_in_place(commands: &Commands, poses: &Poses) -> Vec<Glitch> {
    let n = poses.len();
    let gap_limit = poses.gap_limit();
    let noise = (HELD_NOISE_SIGMAS * frame_noise(&poses.x).hypot(frame_noise(&poses.y)))
        .min(HELD_NOISE_CAP_M);
    let mut out = Vec::new();
    let mut i = 0;
    while i + 1 < n {
        let (t0, x0, y0) = (poses.t[i], poses.x[i], poses.y[i]);
        // Extend while the robot stays put and the command drives on, one way.
        let mut end = i;
        let mut travel = 0.0;
        let mut first_speed: Option<f64> = None;
        for j in i + 1..n {
            if poses.t[j] - poses.t[j - 1] > gap_limit {
                break;
            }
            let dt = poses.t[j] - poses.t[j - 1];
            let step = commanded_travel(commands, poses.t[j - 1], poses.t[j]);
            if step == 0.0 || dt <= 0.0 {
                break;
            }
            // One command held on: the same way, at about the first
            // interval's speed (a command that jumps is met late by an
            // acceleration limit or a lag, and that is the body's).
            let speed = step / dt;
            if let Some(first) = first_speed
                && !(1.0 / HELD_SPEED_RATIO..=HELD_SPEED_RATIO).contains(&(speed / first))
            {
                break;
            }
            first_speed.get_or_insert(speed);
            let so_far = travel + step;
            let away = (poses.x[j] - x0).hypot(poses.y[j] - y0);
            if away > HELD_SHARE * so_far.abs() + noise {
                break;
            }
            (end, travel) = (j, so_far);
        }
        // The share of travel allowed lets the stretch run on into the
        // first moments of driving again: those are motion, not contact.
        while end > i {
            let moved = (poses.x[end] - poses.x[end - 1]).hypot(poses.y[end] - poses.y[end - 1]);
            let step = commanded_travel(commands, poses.t[end - 1], poses.t[end]);
            if moved < HELD_MOVING_SHARE * step.abs() {
                break;
            }
            travel -= step;
            end -= 1;
        }
        if end == i {
            i += 1;
            continue;
        }
        let t1 = poses.t[end];
        let held = travel.abs() >= HELD_MIN_TRAVEL_M && {
            // Just before, for as long: driving the same way at about the
            // same speed while it drove (a robot that walks and turns in
            // place drives part of the time), at least half the stretch's
            // least travel, and the robot went at least half as far.
            let before = t0 - (t1 - t0);
            let Commanded {
                travel: travel_before,
                driving: driving_before,
                ..
            } = commanded(commands, before, t0);
            let speed_ratio =
                (travel_before / driving_before.max(f64::MIN_POSITIVE)) / (travel / (t1 - t0));
            travel_before * travel.signum() >= 0.5 * HELD_MIN_TRAVEL_M
                && (1.0 / HELD_SPEED_RATIO..=HELD_SPEED_RATIO).contains(&speed_ratio)
                && poses.at(before).is_some_and(|p| {
                    (x0 - p.x).hypot(y0 - p.y) >= HELD_MOVING_SHARE * travel_before.abs()
                })
        };
        if held {
            out.push(Glitch {
                kind: GlitchKind::HeldInPlace,
                t_start: t0,
                t_end: t1,
                frames: end - i + 1,
                size_m: travel.abs(),
            });
        }
        // A later start within the same still stretch has a shorter
        // stretch and a still robot before it: no better.
        i = end.max(i + 1);
    }
    out
}

/// The slowest commanded speed (while driving) at which the robot made at
/// least `HELD_MOVING_SHARE` of its commanded travel over `MADE_WINDOW_S`;
/// `None` if it never did.
fn slowest_speed_made(commands: &Commands, poses: &Poses) -> Option<f64> {
    let gap_limit = poses.gap_limit();
    let gap_before = |k: usize| poses.t[k] - poses.t[k - 1] > gap_limit;
    let mut slowest: Option<f64> = None;
    // The window is poses i..=j; `gaps` counts the gaps within it, kept as
    // both ends move forward so the scan stays linear in the recording.
    let (mut j, mut gaps) = (0, 0usize);
    for i in 0..poses.len() {
        if i > 0 && i <= j && gap_before(i) {
            gaps -= 1;
        }
        j = j.max(i);
        while j < poses.len() && poses.t[j] < poses.t[i] + MADE_WINDOW_S {
            j += 1;
            if j < poses.len() && gap_before(j) {
                gaps += 1;
            }
        }
        if j == poses.len() {
            break;
        }
        if gaps > 0 {
            continue;
        }
        let asked = commanded(commands, poses.t[i], poses.t[j]);
        let moved = (poses.x[j] - poses.x[i]).hypot(poses.y[j] - poses.y[i]);
        if asked.travel.abs() >= 0.5 * HELD_MIN_TRAVEL_M
            && moved >= HELD_MOVING_SHARE * asked.travel.abs()
        {
            let speed = asked.travel.abs() / asked.driving;
            slowest = Some(slowest.map_or(speed, |s| s.min(speed)));
        }
    }
    slowest
}

/// Stretches in which the robot, turning as commanded, stayed where it was
/// over a long drive at speeds it makes elsewhere (see the module's notes
/// and the `STUCK_` constants). Each still stretch is the longest run of
/// poses whose bounding box fits within the tolerance.
fn stuck(commands: &Commands, poses: &Poses) -> Vec<Glitch> {
    let n = poses.len();
    let gap_limit = poses.gap_limit();
    let Some(slowest_made) = slowest_speed_made(commands, poses) else {
        return Vec::new();
    };
    let noise = (HELD_NOISE_SIGMAS * frame_noise(&poses.x).hypot(frame_noise(&poses.y)))
        .min(HELD_NOISE_CAP_M);
    let tolerance = HELD_SHARE * HELD_MIN_TRAVEL_M + noise;
    // What the commands asked up to each pose, to judge any stretch at once.
    let mut asked_to = vec![Commanded::default(); n];
    for j in 1..n {
        let step = commanded(commands, poses.t[j - 1], poses.t[j]);
        let before = asked_to[j - 1];
        asked_to[j] = Commanded {
            travel: before.travel + step.travel,
            travel_abs: before.travel_abs + step.travel_abs,
            driving: before.driving + step.driving,
            turn_abs: before.turn_abs + step.turn_abs,
        };
    }
    let heading = unwrapped(&poses.theta);
    let judge = |a: usize, b: usize| -> Option<Glitch> {
        let travel = asked_to[b].travel_abs - asked_to[a].travel_abs;
        let driving = asked_to[b].driving - asked_to[a].driving;
        let turn = asked_to[b].turn_abs - asked_to[a].turn_abs;
        let span = &heading[a..=b];
        let turned = span.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - span.iter().copied().fold(f64::INFINITY, f64::min);
        let held = travel >= STUCK_MIN_TRAVEL_M
            && driving >= STUCK_MIN_DRIVING_S
            && travel / driving >= slowest_made / STUCK_SPEED_RATIO
            && turn >= STUCK_MIN_TURN_RAD
            && turned >= STUCK_MIN_TURN_RAD;
        if !held {
            return None;
        }
        // From the first pose after which it was commanded to drive, to
        // the last before which it was: standing and turning around the
        // drive is no contact.
        let first = (a..b).find(|&k| asked_to[k + 1].travel_abs > asked_to[k].travel_abs)?;
        let last = (first + 1..=b)
            .rev()
            .find(|&k| asked_to[k].travel_abs > asked_to[k - 1].travel_abs)?;
        Some(Glitch {
            kind: GlitchKind::HeldInPlace,
            t_start: poses.t[first],
            t_end: poses.t[last],
            frames: last - first + 1,
            size_m: asked_to[last].travel_abs - asked_to[first].travel_abs,
        })
    };
    // The longest still stretch ending at each pose, by a sliding window
    // with its bounding box kept in monotonic queues; a stretch is judged
    // when the next pose would shorten it from the start.
    let mut out = Vec::new();
    let mut box_ = StillBox::default();
    let mut start = 0;
    for end in 0..n {
        let gap = end > 0 && poses.t[end] - poses.t[end - 1] > gap_limit;
        box_.push(end, poses);
        let new_start = if gap {
            end
        } else {
            let mut s = start;
            while box_.diagonal(s, poses) > tolerance {
                s += 1;
            }
            s
        };
        if new_start > start && end > start + 1 {
            out.extend(judge(start, end - 1));
        }
        start = new_start;
        box_.forget_before(start);
    }
    if n > start + 1 {
        out.extend(judge(start, n - 1));
    }
    out
}

/// Monotonic queues of pose indices over a sliding window, for its bounding
/// box.
#[derive(Default)]
struct StillBox {
    x_min: VecDeque<usize>,
    x_max: VecDeque<usize>,
    y_min: VecDeque<usize>,
    y_max: VecDeque<usize>,
}

impl StillBox {
    fn push(&mut self, k: usize, poses: &Poses) {
        let keep = |q: &mut VecDeque<usize>, v: &[f64], below: bool| {
            while q
                .back()
                .is_some_and(|&j| if below { v[j] >= v[k] } else { v[j] <= v[k] })
            {
                q.pop_back();
            }
            q.push_back(k);
        };
        keep(&mut self.x_min, &poses.x, true);
        keep(&mut self.x_max, &poses.x, false);
        keep(&mut self.y_min, &poses.y, true);
        keep(&mut self.y_max, &poses.y, false);
    }

    fn forget_before(&mut self, start: usize) {
        for q in [
            &mut self.x_min,
            &mut self.x_max,
            &mut self.y_min,
            &mut self.y_max,
        ] {
            while q.front().is_some_and(|&j| j < start) {
                q.pop_front();
            }
        }
    }

    /// The box's diagonal over the window from `start`.
    fn diagonal(&mut self, start: usize, poses: &Poses) -> f64 {
        self.forget_before(start);
        let first = |q: &VecDeque<usize>, v: &[f64]| q.front().map(|&j| v[j]);
        match (
            first(&self.x_min, &poses.x),
            first(&self.x_max, &poses.x),
            first(&self.y_min, &poses.y),
            first(&self.y_max, &poses.y),
        ) {
            (Some(x0), Some(x1), Some(y0), Some(y1)) => (x1 - x0).hypot(y1 - y0),
            _ => 0.0,
        }
    }
}

/// Headings without their wraps, so that a range measures how far it turned.
fn unwrapped(theta: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(theta.len());
    for (k, &th) in theta.iter().enumerate() {
        out.push(match k {
            0 => th,
            _ => {
                let last = out[k - 1];
                let step = (th - theta[k - 1] + std::f64::consts::PI)
                    .rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                last + step
            }
        });
    }
    out
}

/// Time spans, overlapping ones joined, in time order: each joined span
/// with the index (in `spans`) of the span it starts with.
fn spans_joined(spans: &[(f64, f64)]) -> Vec<(usize, f64, f64)> {
    let mut order: Vec<usize> = (0..spans.len()).collect();
    order.sort_by(|&a, &b| spans[a].0.total_cmp(&spans[b].0));
    let mut out: Vec<(usize, f64, f64)> = Vec::new();
    for k in order {
        let (start, end) = spans[k];
        match out.last_mut() {
            Some(last) if start <= last.2 => last.2 = last.2.max(end),
            _ => out.push((k, start, end)),
        }
    }
    out
}

fn spans_of(glitches: &[Glitch]) -> Vec<(f64, f64)> {
    glitches.iter().map(|g| (g.t_start, g.t_end)).collect()
}

/// How long the glitches set aside in all, seconds: stretches of
/// different kinds may overlap, and are counted once.
pub fn seconds_set_aside(glitches: &[Glitch]) -> f64 {
    spans_joined(&spans_of(glitches))
        .iter()
        .map(|(_, start, end)| end - start)
        .sum()
}

/// Held stretches found by either rule, overlapping ones made one.
fn merged(held: Vec<Glitch>, commands: &Commands, poses: &Poses) -> Vec<Glitch> {
    let mut out: Vec<Glitch> = spans_joined(&spans_of(&held))
        .into_iter()
        .map(|(first, _, end)| Glitch {
            t_end: end,
            ..held[first].clone()
        })
        .collect();
    for g in &mut out {
        g.frames = poses
            .t
            .iter()
            .filter(|t| (g.t_start..=g.t_end).contains(*t))
            .count();
        g.size_m = g
            .size_m
            .max(commanded(commands, g.t_start, g.t_end).travel_abs);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A robot driving at 0.3 m/s, observed at 67 Hz with 1 mm noise.
    fn run(seconds: f64) -> Recording {
        let mut commands = Commands::default();
        let mut k = 0.0;
        while k <= seconds {
            commands.hold(k, 0.3, 0.0);
            k += 0.05;
        }
        let mut poses = Poses::default();
        let dt = 1.0 / 67.0;
        for i in 0..(seconds / dt) as usize {
            let t = i as f64 * dt;
            let noise = ((i * 7919) % 13) as f64 / 13.0 - 0.5;
            poses.push(t, 0.3 * t + 0.002 * noise, 0.001 * noise, 0.0);
        }
        Recording::of(commands, poses)
    }

    /// Commands `command(t)` held at 20 Hz, and a robot driving straight
    /// along x at `speed(t)`, observed at 67 Hz with 1 mm noise.
    fn driven(seconds: f64, command: impl Fn(f64) -> f64, speed: impl Fn(f64) -> f64) -> Recording {
        let mut commands = Commands::default();
        let mut k = 0.0;
        while k <= seconds {
            commands.hold(k, command(k), 0.0);
            k += 0.05;
        }
        let mut poses = Poses::default();
        let dt = 1.0 / 67.0;
        let mut x = 0.0;
        for i in 0..(seconds / dt) as usize {
            let t = i as f64 * dt;
            let noise = ((i * 7919) % 13) as f64 / 13.0 - 0.5;
            poses.push(t, x + 0.002 * noise, 0.001 * noise, 0.0);
            x += speed(t) * dt;
        }
        Recording::of(commands, poses)
    }

    fn held_stops(recording: &Recording) -> Vec<Glitch> {
        set_aside(recording)
            .1
            .into_iter()
            .filter(|g| g.kind == GlitchKind::HeldInPlace)
            .collect()
    }

    #[test]
    fn a_robot_that_stops_dead_while_driving_is_set_aside_as_held_in_place() {
        // Driving at 0.3 m/s as commanded, held against a wall from 20 s
        // to 21.5 s while the command goes on, then driving again.
        let r = driven(
            60.0,
            |_| 0.3,
            |t| if (20.0..21.5).contains(&t) { 0.0 } else { 0.3 },
        );
        let (kept, glitches) = set_aside(&r);
        let held: Vec<&Glitch> = glitches
            .iter()
            .filter(|g| g.kind == GlitchKind::HeldInPlace)
            .collect();
        assert_eq!(held.len(), 1, "{glitches:?}");
        assert!(
            (held[0].t_start - 20.0).abs() < 0.05 && (held[0].t_end - 21.5).abs() < 0.05,
            "{held:?}"
        );
        // The commanded travel it did not make: 1.5 s at 0.3 m/s.
        assert!((held[0].size_m - 0.45).abs() < 0.03, "{held:?}");
        assert!(held[0].size_text().contains("commanded travel not made"));
        assert!(!kept.poses.t.iter().any(|t| (20.0..21.5).contains(t)));
        // A stop half as long (0.23 m commanded) is found too.
        let short = driven(
            60.0,
            |_| 0.3,
            |t| if (30.0..30.75).contains(&t) { 0.0 } else { 0.3 },
        );
        assert_eq!(held_stops(&short).len(), 1);
        // A robot that drives and stands by turns (a legged robot walking
        // and turning in place, 0.2 s each) is judged by its speed while
        // it drove: held 1.2 s from 30 s, it was driving before.
        let by_turns = |t: f64| ((t * 5.0) as i64 % 2 == 0) || (30.0..31.2).contains(&t);
        let alternating = driven(
            60.0,
            |t| if by_turns(t) { 0.3 } else { 0.0 },
            |t| {
                if by_turns(t) && !(30.0..31.2).contains(&t) {
                    0.3
                } else {
                    0.0
                }
            },
        );
        let stops = held_stops(&alternating);
        assert_eq!(stops.len(), 1, "{stops:?}");
        assert!((stops[0].t_start - 30.0).abs() < 0.05, "{stops:?}");
    }

    /// A legged robot walking (0.4 s at `speed(t)` m/s) and turning in
    /// place (0.4 s at 1 rad/s) by turns, commands at 20 Hz, observed at 67
    /// Hz with 1 mm noise; where `goes(t)` is false it still turns but its
    /// strides take it nowhere.
    fn walking_and_turning(
        seconds: f64,
        speed: impl Fn(f64) -> f64,
        goes: impl Fn(f64) -> bool,
    ) -> Recording {
        let walking = |t: f64| (t / 0.4) as i64 % 2 == 0;
        let mut commands = Commands::default();
        let mut k = 0.0;
        while k <= seconds {
            if walking(k) {
                commands.hold(k, speed(k), 0.0);
            } else {
                commands.hold(k, 0.0, 1.0);
            }
            k += 0.05;
        }
        let mut poses = Poses::default();
        let dt = 1.0 / 67.0;
        let (mut x, mut y, mut theta) = (0.0, 0.0, 0.0_f64);
        for i in 0..(seconds / dt) as usize {
            let t = i as f64 * dt;
            let noise = ((i * 7919) % 13) as f64 / 13.0 - 0.5;
            poses.push(t, x + 0.002 * noise, y + 0.001 * noise, theta);
            if walking(t) {
                if goes(t) {
                    x += speed(t) * theta.cos() * dt;
                    y += speed(t) * theta.sin() * dt;
                }
            } else {
                theta += dt;
            }
        }
        Recording::of(commands, poses)
    }

    #[test]
    fn a_robot_that_turns_but_goes_nowhere_for_long_is_set_aside_however_it_got_there() {
        // Held from 30 s to the end, each stride after a turn in place: no
        // free driving just before any of its stops.
        let held = held_stops(&walking_and_turning(60.0, |_| 0.3, |t| t < 30.0));
        assert_eq!(held.len(), 1, "{held:?}");
        assert!(
            (held[0].t_start - 30.0).abs() < 0.5 && held[0].t_end > 59.0,
            "{held:?}"
        );
        // Half of 30 s at 0.3 m/s.
        assert!((held[0].size_m - 4.5).abs() < 0.3, "{held:?}");
        // Walking and turning freely, nothing is set aside.
        assert!(held_stops(&walking_and_turning(60.0, |_| 0.3, |_| true)).is_empty());
    }

    #[test]
    fn a_robot_that_starts_late_crawls_or_fades_is_fitted_not_set_aside() {
        // From rest, a command met 0.6 s late (a latency, an actuator lag).
        let late = driven(
            60.0,
            |t| if t < 10.0 { 0.0 } else { 0.3 },
            |t| if t < 10.6 { 0.0 } else { 0.3 },
        );
        assert!(held_stops(&late).is_empty(), "{:?}", held_stops(&late));
        // Slowed to a crawl below its deadband: commanded 0.02 m/s for 20 s
        // after driving at 0.3, it does not move.
        let crawl = driven(
            60.0,
            |t| if (20.0..40.0).contains(&t) { 0.02 } else { 0.3 },
            |t| if (20.0..40.0).contains(&t) { 0.0 } else { 0.3 },
        );
        assert!(held_stops(&crawl).is_empty(), "{:?}", held_stops(&crawl));
        // A battery that fades to nothing under a steady command.
        let fading = driven(60.0, |_| 0.3, |t| 0.3 * (1.0 - t / 40.0).max(0.0));
        assert!(held_stops(&fading).is_empty(), "{:?}", held_stops(&fading));
        // Walking and turning, commanded 0.1 m/s from 20 s to 60 s (2 m),
        // below its deadband: it turns, but the slowest speed it made is
        // 0.3 m/s.
        let slow = |t: f64| (20.0..60.0).contains(&t);
        let deadband = walking_and_turning(60.0, |t| if slow(t) { 0.1 } else { 0.3 }, |t| !slow(t));
        assert!(
            held_stops(&deadband).is_empty(),
            "{:?}",
            held_stops(&deadband)
        );
        // A command that jumps from slow to fast, met by an acceleration
        // limit after a stretch the noise held still.
        let jump = driven(
            60.0,
            |t| if t < 20.0 { 0.05 } else { 0.3 },
            |t| {
                if t < 19.0 {
                    0.05
                } else if t < 20.5 {
                    0.0
                } else {
                    0.3
                }
            },
        );
        assert!(held_stops(&jump).is_empty(), "{:?}", held_stops(&jump));
    }

    #[test]
    fn a_clean_run_has_no_glitches() {
        let clean = run(60.0);
        let (kept, glitches) = set_aside(&clean);
        assert!(glitches.is_empty(), "{glitches:?}");
        assert_eq!(kept.poses.len(), clean.poses.len());
    }

    #[test]
    fn jumps_that_return_are_set_aside_one_episode_each() {
        let mut r = run(120.0);
        // Marker swaps: 0.2 m away for one, two and four frames, every 5 s
        // from 30 s to 90 s.
        let mut expected = 0;
        for (n, start) in (0..12).map(|n| (n, 30.0 + 5.0 * n as f64)) {
            let first = r.poses.t.iter().position(|t| *t >= start).expect("frame");
            let frames = [1, 2, 4][n % 3];
            for k in first..first + frames {
                r.poses.y[k] += 0.2;
            }
            expected += frames;
        }
        let (kept, glitches) = set_aside(&r);
        assert_eq!(glitches.len(), 12, "{glitches:?}");
        assert!(glitches.iter().all(|g| g.kind == GlitchKind::JumpAndReturn));
        assert!(
            glitches.iter().all(|g| (g.size_m - 0.2).abs() < 0.01),
            "{glitches:?}"
        );
        assert_eq!(kept.poses.len(), r.poses.len() - expected);
        assert!(kept.poses.y.iter().all(|y| y.abs() < 0.01));
    }

    #[test]
    fn a_track_that_resumes_elsewhere_is_cut_not_fitted() {
        let mut r = run(60.0);
        let at = r.poses.t.iter().position(|t| *t >= 20.0).expect("frame");
        for y in &mut r.poses.y[at..] {
            *y += 1.0;
        }
        let (kept, glitches) = set_aside(&r);
        assert_eq!(glitches.len(), 1, "{glitches:?}");
        assert_eq!(glitches[0].kind, GlitchKind::JumpWithoutReturn);
        // No observed poses within the gap's reach on either side.
        assert!(
            kept.poses
                .t
                .windows(2)
                .any(|w| w[1] - w[0] > kept.poses.gap_limit())
        );
    }

    #[test]
    fn a_command_stream_that_only_pauses_is_compared() {
        let mut r = run(60.0);
        let mut commands = Commands::default();
        for k in 0..r.commands.t.len() {
            let t = r.commands.t[k];
            if !(20.0..21.0).contains(&t) {
                commands.hold(t, 0.3, 0.0);
            }
        }
        r.commands = commands;
        let (_, glitches) = set_aside(&r);
        assert!(glitches.is_empty(), "{glitches:?}");
    }

    #[test]
    fn a_stalled_command_stream_and_its_burst_are_set_aside() {
        let mut r = run(60.0);
        let mut commands = Commands::default();
        for k in 0..r.commands.t.len() {
            let t = r.commands.t[k];
            // Silent from 20 to 23 s, then the backlog within 10 ms.
            if (20.0..23.0).contains(&t) {
                continue;
            }
            commands.hold(t, 0.3, 0.0);
            if (t - 23.0).abs() < 1e-9 {
                for b in 1..10 {
                    commands.hold(23.0 + 0.001 * f64::from(b), 0.3, 0.0);
                }
            }
        }
        r.commands = commands;
        let (kept, glitches) = set_aside(&r);
        let stalls: Vec<&Glitch> = glitches
            .iter()
            .filter(|g| g.kind == GlitchKind::CommandStall)
            .collect();
        assert_eq!(stalls.len(), 1, "{glitches:?}");
        assert!(
            (stalls[0].t_start - 19.95).abs() < 1e-6 && (stalls[0].t_end - 23.009).abs() < 1e-6,
            "{stalls:?}"
        );
        assert!(!kept.poses.t.iter().any(|t| (20.0..23.0).contains(t)));
    }
}

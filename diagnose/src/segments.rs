//! The unit of comparison: a short stretch of the run. Each segment starts
//! the model from the observed pose and asks where it predicts the robot one
//! horizon later; errors therefore do not accumulate across the run, and
//! segments are close to independent.

use shoal_physics::{CommandGrid, Pose};

use crate::recording::Recording;

#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    /// Grid steps `from..to` of the command grid.
    pub from: usize,
    pub to: usize,
    pub t_start: f64,
    pub t_end: f64,
    pub start: Pose,
    pub end: Pose,
    /// Mean commanded |v| and omega over the segment.
    pub speed: f64,
    pub turn: f64,
    /// Commanded distance over the segment, metres.
    pub distance: f64,
    /// Observed midpoint of the segment.
    pub mid: [f64; 2],
}

/// The command grid for `recording`: fine enough for the physics, coarse
/// enough that an hour of data fits in a few milliseconds per evaluation.
pub fn command_grid(recording: &Recording, dt: f64) -> CommandGrid {
    let c = &recording.commands;
    CommandGrid::from_held(&c.t, &c.v, &c.omega, dt)
}

/// Cuts the run into back-to-back segments of `horizon` seconds wherever
/// both ends were observed.
pub fn segments(recording: &Recording, grid: &CommandGrid, horizon: f64) -> Vec<Segment> {
    let steps = ((horizon / grid.dt).round() as usize).max(1);
    (0..grid.len().saturating_sub(1) / steps)
        .filter_map(|k| segment(recording, grid, k * steps, (k + 1) * steps))
        .collect()
}

/// Cuts each stretch over which the robot was commanded to move and the
/// command held one value into back-to-back segments of `steps` grid steps
/// from where the value was given, wherever both ends were observed: each
/// replays one command, chosen before any of its segments' noise.
pub fn held_segments(recording: &Recording, grid: &CommandGrid, steps: usize) -> Vec<Segment> {
    holds(grid)
        .into_iter()
        .filter(|hold| moving(grid, hold.start))
        .flat_map(|hold| {
            let count = hold.len() / steps.max(1);
            (0..count).map(move |k| (hold.start + k * steps, hold.start + (k + 1) * steps))
        })
        .filter(|&(_, to)| to < grid.len())
        .filter_map(|(from, to)| segment(recording, grid, from, to))
        .collect()
}

/// The grid's stretches of one command value: a new stretch wherever speed
/// or turn rate changes (beyond rounding of the grid's time-weighted means).
pub fn holds(grid: &CommandGrid) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..=grid.len() {
        let changed = i == grid.len()
            || !same(grid.v[i], grid.v[start])
            || !same(grid.omega[i], grid.omega[start]);
        if changed {
            out.push(start..i);
            start = i;
        }
    }
    out
}

/// One command value, but for the rounding of the grid's time-weighted
/// means (a command given off the grid leaves a trace of the one before).
fn same(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
}

/// Whether the command at grid step `at` asks the robot to move.
pub fn moving(grid: &CommandGrid, at: usize) -> bool {
    !same(grid.v[at], 0.0) || !same(grid.omega[at], 0.0)
}

/// Poses slower than this (a localisation at 2 Hz, a GPS at 1 Hz) are
/// compared where they were observed: the ends of each segment at least
/// half as long as their usual interval move to the grid steps of the
/// observations nearest them (so at 0.5 Hz, segments of 1 s become 2 s).
/// Between observations so far apart, a pose interpolated on a straight
/// line cuts the robot's arc, and a model compared with it looks slowed,
/// like an actuator lag. Shorter segments (the feedback stage's, of a few
/// hundredths of a second) would shrink to nothing: they and faster
/// streams are interpolated.
pub const SNAPPED_INTERVAL_S: f64 = 0.05;

/// How far, in usual intervals, a segment's end moves to an observation:
/// half an interval, and a little more for a stream whose intervals vary.
const SNAP_REACH: f64 = 0.6;

/// The segment over grid steps `from..to`, if both its ends were observed.
fn segment(recording: &Recording, grid: &CommandGrid, from: usize, to: usize) -> Option<Segment> {
    let usual = recording.poses.usual_interval();
    let snapped =
        usual > SNAPPED_INTERVAL_S && grid.time(to) - grid.time(from) >= 0.5 * usual - 1e-9;
    let (from, to) = if snapped {
        // Never across a gap (a segment's end there is no segment), and
        // only to an observation about as near as the stream's rate puts
        // one: where a pose is missing, the end stays and is interpolated,
        // so a segment that starts where a command was given still does.
        let snap = |step: usize| {
            let t = grid.time(step);
            recording.poses.at(t)?;
            let near = |seen: &f64| (seen - t).abs() <= SNAP_REACH * usual;
            match recording.poses.nearest(t).filter(near) {
                Some(seen) => {
                    let snapped = ((seen - grid.t0) / grid.dt).round().max(0.0) as usize;
                    Some(snapped.min(grid.len().saturating_sub(1)))
                }
                None => Some(step),
            }
        };
        (snap(from)?, snap(to)?)
    } else {
        (from, to)
    };
    if to <= from {
        return None;
    }
    let (t_start, t_end) = (grid.time(from), grid.time(to));
    let start = recording.poses.at(t_start)?;
    let end = recording.poses.at(t_end)?;
    let steps = (to - from) as f64;
    let speed = grid.v[from..to].iter().map(|v| v.abs()).sum::<f64>() / steps;
    let turn = grid.omega[from..to].iter().sum::<f64>() / steps;
    Some(Segment {
        from,
        to,
        t_start,
        t_end,
        start,
        end,
        speed,
        turn,
        distance: speed * (t_end - t_start),
        mid: [0.5 * (start.x + end.x), 0.5 * (start.y + end.y)],
    })
}

/// The held-out blocks of `segments`: one per recording where several were
/// joined (a block starts at each of `joins`), else `folds` equal stretches.
pub fn blocks(segments: &[Segment], joins: &[f64], folds: usize) -> Vec<std::ops::Range<usize>> {
    let n = segments.len();
    if !joins.is_empty() {
        let mut starts: Vec<usize> = std::iter::once(0)
            .chain(
                joins
                    .iter()
                    .map(|&t| segments.partition_point(|s| s.t_start < t)),
            )
            .collect();
        starts.dedup();
        return starts
            .iter()
            .zip(starts.iter().skip(1).chain([&n]))
            .map(|(&a, &b)| a..b)
            .filter(|r| !r.is_empty())
            .collect();
    }
    let folds = folds.clamp(2, n.max(2));
    (0..folds)
        .map(|f| f * n / folds..(f + 1) * n / folds)
        .filter(|r| !r.is_empty())
        .collect()
}

/// Every k-th segment, at most `count` of them.
pub(crate) fn subsample(segments: &[Segment], count: usize) -> Vec<Segment> {
    let every = segments.len().div_ceil(count.max(1)).max(1);
    segments.iter().step_by(every).cloned().collect()
}

//! A real run as diagnosis sees it: the commands sent and the poses observed.

use shoal_physics::{Pose, wrap_angle};

/// Commands, each held until the next: seconds, m/s, rad/s.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Commands {
    pub t: Vec<f64>,
    pub v: Vec<f64>,
    pub omega: Vec<f64>,
}

/// Observed poses at any rate. Headings are unwrapped so they interpolate.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Poses {
    pub t: Vec<f64>,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub theta: Vec<f64>,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recording {
    pub commands: Commands,
    pub poses: Poses,
    /// Seconds subtracted from every time, so the run starts at 0.
    pub t_origin: f64,
    /// Where each later recording of the same robot starts, when several
    /// were joined into one run (`Recording::joined`): each is a held-out
    /// block of its own.
    pub joins: Vec<f64>,
}

/// Observations further apart than this leave a gap that no segment spans,
/// in a stream at 5 Hz or faster (`Poses::gap_limit` widens it for slower
/// ones).
pub const MAX_OBSERVATION_GAP_S: f64 = 0.5;

/// A gap between poses is at least this many of their usual intervals
/// (and at least `MAX_OBSERVATION_GAP_S`): a slow stream (a GPS at 1 Hz, a
/// localisation at 2 Hz) is read as it was sent, and one at 5 Hz or faster
/// is cut at 0.5 s as before.
const SLOW_STREAM_INTERVALS: f64 = 2.5;

/// Intervals sampled, evenly over the recording, for its usual interval.
const INTERVALS_SAMPLED: usize = 101;

impl Commands {
    /// Each command as (t, v, omega).
    pub fn rows(&self) -> Vec<(f64, f64, f64)> {
        (0..self.t.len())
            .map(|i| (self.t[i], self.v[i], self.omega[i]))
            .collect()
    }

    /// Appends a command read from a file, in time order. Of two commands
    /// at one time, the later one is what the robot kept.
    pub fn hold(&mut self, t: f64, v: f64, omega: f64) {
        if self.t.last() == Some(&t) {
            self.t.pop();
            self.v.pop();
            self.omega.pop();
        }
        self.t.push(t);
        self.v.push(v);
        self.omega.push(omega);
    }
}

impl Poses {
    /// Each pose as (t, x, y, theta).
    pub fn rows(&self) -> Vec<(f64, f64, f64, f64)> {
        (0..self.t.len())
            .map(|i| (self.t[i], self.x[i], self.y[i], self.theta[i]))
            .collect()
    }

    /// Appends a pose read from a file, in time order; a second observation
    /// at a time already seen is dropped.
    pub fn observe(&mut self, t: f64, x: f64, y: f64, theta: f64) {
        if self.t.last() != Some(&t) {
            self.push(t, x, y, theta);
        }
    }

    pub fn push(&mut self, t: f64, x: f64, y: f64, theta: f64) {
        let theta = match self.theta.last() {
            Some(&previous) => previous + wrap_angle(theta - previous),
            None => theta,
        };
        self.t.push(t);
        self.x.push(x);
        self.y.push(y);
        self.theta.push(theta);
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Observations further apart than this leave a gap that no segment
    /// spans: `MAX_OBSERVATION_GAP_S`, or `SLOW_STREAM_INTERVALS` of the
    /// poses' usual interval where they come slower. The usual interval is
    /// the median of intervals sampled evenly, so gaps do not lengthen it.
    pub fn gap_limit(&self) -> f64 {
        MAX_OBSERVATION_GAP_S.max(SLOW_STREAM_INTERVALS * self.usual_interval())
    }

    /// The seconds between consecutive poses, as usual (0 for fewer than
    /// two).
    pub fn usual_interval(&self) -> f64 {
        let n = self.t.len();
        if n < 2 {
            return 0.0;
        }
        let samples = INTERVALS_SAMPLED.min(n - 1);
        let mut intervals: Vec<f64> = (0..samples)
            .map(|k| {
                let i = k * (n - 2) / samples.saturating_sub(1).max(1);
                self.t[i + 1] - self.t[i]
            })
            .collect();
        intervals.sort_by(f64::total_cmp);
        intervals[intervals.len() / 2]
    }

    /// The observation nearest `t` (ties to the earlier); `None` if empty.
    pub fn nearest(&self, t: f64) -> Option<f64> {
        let after = self.t.partition_point(|&s| s < t);
        let before = after.checked_sub(1).map(|i| self.t[i]);
        let next = self.t.get(after).copied();
        match (before, next) {
            (Some(b), Some(a)) => Some(if t - b <= a - t { b } else { a }),
            (b, a) => b.or(a),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The observed pose at `t`, interpolated; `None` outside the
    /// observations or across a gap.
    pub fn at(&self, t: f64) -> Option<Pose> {
        let after = self.t.partition_point(|&s| s < t);
        if after == 0 {
            return (self.t.first() == Some(&t)).then(|| self.pose(0));
        }
        if after >= self.t.len() {
            return None;
        }
        let before = after - 1;
        let (t0, t1) = (self.t[before], self.t[after]);
        if t1 - t0 > self.gap_limit() {
            return None;
        }
        let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        let lerp = |a: &[f64]| a[before] + f * (a[after] - a[before]);
        Some(Pose::new(lerp(&self.x), lerp(&self.y), lerp(&self.theta)))
    }

    /// The poses without gross observation outliers (a swapped marker, a
    /// reflection), and how many were dropped. A body cannot jump within a
    /// few frames, so a pose far from the median of its neighbours (a
    /// Hampel filter: more than 8 robust standard deviations of all such
    /// distances, and more than 2 cm) is the camera's error, not motion.
    pub fn without_outliers(&self) -> (Poses, usize) {
        const HALF_WINDOW: usize = 5;
        const THRESHOLD: f64 = 8.0;
        const FLOOR_M: f64 = 0.02;
        let n = self.len();
        if n < 2 * HALF_WINDOW + 1 {
            return (self.clone(), 0);
        }
        let median = |values: &mut Vec<f64>| {
            values.sort_by(f64::total_cmp);
            let m = values.len() / 2;
            if values.len() % 2 == 1 {
                values[m]
            } else {
                0.5 * (values[m - 1] + values[m])
            }
        };
        let mut window = Vec::with_capacity(2 * HALF_WINDOW);
        let distances: Vec<f64> = (0..n)
            .map(|i| {
                let (lo, hi) = (i.saturating_sub(HALF_WINDOW), (i + HALF_WINDOW + 1).min(n));
                let mut centre = [0.0; 2];
                for (axis, values) in [&self.x, &self.y].into_iter().enumerate() {
                    window.clear();
                    window.extend((lo..hi).filter(|&j| j != i).map(|j| values[j]));
                    centre[axis] = median(&mut window);
                }
                (self.x[i] - centre[0]).hypot(self.y[i] - centre[1])
            })
            .collect();
        let scale = 1.4826 * median(&mut distances.clone());
        let limit = (THRESHOLD * scale).max(FLOOR_M);
        let mut kept = Poses::default();
        let mut dropped = 0;
        for (i, &distance) in distances.iter().enumerate() {
            if distance > limit {
                dropped += 1;
            } else {
                kept.push(self.t[i], self.x[i], self.y[i], self.theta[i]);
            }
        }
        (kept, dropped)
    }

    fn pose(&self, i: usize) -> Pose {
        Pose::new(self.x[i], self.y[i], self.theta[i])
    }
}

impl Recording {
    /// The times the commands and the poses cover, on the files' own clock,
    /// in words: where they do not overlap, how far apart, since two clocks
    /// (a Unix time against seconds from a capture's start) are the usual
    /// reason.
    pub fn spans(&self) -> String {
        let span = |t: &[f64]| {
            t.first()
                .zip(t.last())
                .map(|(a, b)| (a + self.t_origin, b + self.t_origin))
        };
        let (Some(commands), Some(poses)) = (span(&self.commands.t), span(&self.poses.t)) else {
            return "The commands or the poses hold no rows.".to_owned();
        };
        let apart = (commands.0 - poses.1).max(poses.0 - commands.1);
        let overlap = if apart > 0.0 {
            format!(
                ": they do not overlap, {apart:.1} s apart{}",
                if apart > 1e6 {
                    " (one a Unix time, the other seconds from a recording's start? Put both on one clock)"
                } else {
                    ""
                }
            )
        } else {
            String::new()
        };
        format!(
            "The commands cover {:.3}-{:.3} s, the poses {:.3}-{:.3} s{overlap}.",
            commands.0, commands.1, poses.0, poses.1
        )
    }

    /// One recording of `commands` and `poses`, its times as they are.
    pub fn of(commands: Commands, poses: Poses) -> Self {
        Self {
            commands,
            poses,
            t_origin: 0.0,
            joins: Vec::new(),
        }
    }

    /// The run with gross pose outliers set aside (see
    /// [`Poses::without_outliers`]), and how many were.
    pub fn without_pose_outliers(&self) -> (Self, usize) {
        let (poses, outliers) = self.poses.without_outliers();
        (
            Self {
                poses,
                ..self.clone()
            },
            outliers,
        )
    }

    /// Shifts every time so the first command is at 0 s.
    pub fn from_absolute(mut commands: Commands, mut poses: Poses) -> Self {
        let t_origin = commands.t.first().copied().unwrap_or(0.0);
        commands.t.iter_mut().for_each(|t| *t -= t_origin);
        poses.t.iter_mut().for_each(|t| *t -= t_origin);
        Self {
            commands,
            poses,
            t_origin,
            joins: Vec::new(),
        }
    }

    /// Several recordings of one robot as one run on one clock: each
    /// keeps its own times after the first's start (a clock that spans
    /// them, for effects that change with time, such as a battery's fade),
    /// or, where their clocks overlap or are unknown (CSV files from 0 s),
    /// follows the one before it after a gap. No comparison spans a join.
    pub fn joined(recordings: Vec<Recording>) -> Recording {
        let mut runs: Vec<Recording> = recordings
            .into_iter()
            .filter(|r| !r.commands.t.is_empty())
            .collect();
        runs.sort_by(|a, b| a.t_origin.total_cmp(&b.t_origin));
        let Some(first_origin) = runs.first().map(|r| r.t_origin) else {
            return Recording::default();
        };
        let mut out = Recording {
            t_origin: first_origin,
            ..Recording::default()
        };
        // A gap wider than any comparison may span.
        let gap = 2.0
            * runs
                .iter()
                .map(|r| r.poses.gap_limit())
                .fold(MAX_OBSERVATION_GAP_S, f64::max);
        for (k, run) in runs.into_iter().enumerate() {
            let end_so_far = out
                .commands
                .t
                .last()
                .copied()
                .into_iter()
                .chain(out.poses.t.last().copied())
                .fold(f64::NEG_INFINITY, f64::max);
            let on_shared_clock = run.t_origin - first_origin;
            let shift = if k == 0 {
                0.0
            } else if on_shared_clock > end_so_far + gap {
                on_shared_clock
            } else {
                end_so_far + gap
            };
            if k > 0 {
                out.joins.push(shift);
            }
            for i in 0..run.commands.t.len() {
                out.commands.hold(
                    run.commands.t[i] + shift,
                    run.commands.v[i],
                    run.commands.omega[i],
                );
            }
            for i in 0..run.poses.t.len() {
                out.poses.observe(
                    run.poses.t[i] + shift,
                    run.poses.x[i],
                    run.poses.y[i],
                    run.poses.theta[i],
                );
            }
        }
        out
    }

    /// The run as the two CSV files diagnosis reads (see [`csv_lines`]).
    pub fn to_csv(&self) -> (String, String) {
        let c = &self.commands;
        let mut commands = String::from(csv_lines::COMMANDS_HEADER);
        for i in 0..c.t.len() {
            commands.push_str(&csv_lines::command(c.t[i], c.v[i], c.omega[i]));
        }
        let p = &self.poses;
        let mut poses = String::from(csv_lines::POSES_HEADER);
        for i in 0..p.t.len() {
            poses.push_str(&csv_lines::pose(p.t[i], p.x[i], p.y[i], p.theta[i]));
        }
        (commands, poses)
    }

    pub fn duration(&self) -> f64 {
        self.commands.t.last().copied().unwrap_or(0.0)
    }
}

/// The lines of the two CSV files diagnosis reads: one home for their
/// format, for [`Recording::to_csv`] and for the recorder that writes them
/// as a swarm runs.
pub mod csv_lines {
    use shoal_physics::wrap_angle;

    /// Commands: time, forward speed (m/s), turn rate (rad/s).
    pub const COMMANDS_HEADER: &str = "t,v,omega\n";
    /// Poses: time, position (m), heading (rad).
    pub const POSES_HEADER: &str = "t,x,y,theta\n";

    pub fn command(t: f64, v: f64, omega: f64) -> String {
        format!("{t:.3},{v:.6},{omega:.6}\n")
    }

    /// A pose line; the heading is wrapped to (-pi, pi].
    pub fn pose(t: f64, x: f64, y: f64, theta: f64) -> String {
        format!("{t:.4},{x:.6},{y:.6},{:.6}\n", wrap_angle(theta))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn poses_at(times: impl Iterator<Item = f64>) -> Poses {
        let mut poses = Poses::default();
        for t in times {
            poses.observe(t, t, 0.0, 0.0);
        }
        poses
    }

    #[test]
    fn a_slow_stream_is_read_as_sent_and_a_fast_ones_gap_is_a_gap() {
        // A GPS at 1 Hz: a second between poses is its rate, not a gap.
        let gps = poses_at((0..60).map(f64::from));
        assert!((gps.gap_limit() - 2.5).abs() < 1e-9);
        assert!(gps.at(10.5).is_some());
        // Motion capture at 100 Hz that lost the robot for 2 s of 10.
        let mocap = poses_at(
            (0..1000)
                .map(|k| f64::from(k) * 0.01)
                .filter(|t| !(4.0..6.0).contains(t)),
        );
        assert_eq!(mocap.gap_limit(), MAX_OBSERVATION_GAP_S);
        assert!(mocap.at(5.0).is_none() && mocap.at(3.0).is_some());
        assert_eq!(gps.nearest(10.4), Some(10.0));
        assert_eq!(gps.nearest(10.6), Some(11.0));
        assert_eq!(gps.nearest(-3.0), Some(0.0));
        assert_eq!(Poses::default().nearest(1.0), None);
    }

    #[test]
    fn a_marker_swap_is_dropped_and_smooth_motion_kept() {
        let mut poses = Poses::default();
        for i in 0..1000 {
            let t = i as f64 * 0.01;
            let jump = if i == 500 || i == 730 { 0.15 } else { 0.0 };
            poses.push(t, 0.3 * t + jump, 0.1 * (t * 2.0).sin(), 0.2 * t);
        }
        let (kept, dropped) = poses.without_outliers();
        assert_eq!(dropped, 2);
        assert_eq!(kept.len(), 998);
    }

    /// A command log in Unix time beside an export timed from the capture's
    /// start: both spans said, on the files' own clocks, and the likely cause.
    #[test]
    fn spans_say_where_two_clocks_do_not_meet() {
        let mut commands = Commands::default();
        for k in 0..3 {
            commands.t.push(1.7e9 + k as f64);
            commands.v.push(0.1);
            commands.omega.push(0.0);
        }
        let recording = Recording::from_absolute(commands, poses_at((0..5).map(f64::from)));
        let said = recording.spans();
        assert!(
            said.contains(
                "The commands cover 1700000000.000-1700000002.000 s, the poses 0.000-4.000 s"
            ),
            "{said}"
        );
        assert!(
            said.contains("do not overlap") && said.contains("Unix time"),
            "{said}"
        );
        let same = Recording::from_absolute(Commands::default(), Poses::default());
        assert_eq!(same.spans(), "The commands or the poses hold no rows.");
    }
}

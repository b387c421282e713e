//! A controller's command timeout, found before anything is fitted. Many
//! robots stop when no command has come for a while (ros2_control's
//! `diff_drive_controller` stops after its `cmd_vel_timeout`, 0.5 s by
//! default), while a recording holds each command until the next. A
//! teleoperator who publishes only when a key changes leaves pauses in the
//! command stream through which the recording says "drive on" and the robot
//! stands: compared as held, those pauses read as a robot that drives at a
//! quarter of its commanded speed (invented physics). So the pauses in which
//! the robot was commanded to move are looked at first; if it stood still in
//! nearly all of them, the robot has a timeout, its length is measured from
//! when the robot stopped (apart from how late it acts on a command), and
//! each command is taken to end that long after it was given. A robot that drove on through its
//! pauses holds its commands, as the recording says, and nothing changes.

use serde::Serialize;

use shoal_physics::{Effect, ScopedEffect};

use crate::fit::nll_of;
use crate::prepared::Options;
use crate::recording::{Commands, Recording};
use crate::segments::{command_grid, segments};

/// A pause of the command stream this long, or longer, shows whether the
/// robot holds its command or stops: longer than any common timeout
/// (ros2_control's default is 0.5 s) with time to see it stand.
const PAUSE_S: f64 = 1.5;

/// Pauses needed before the robot is said to stop in them: fewer say too
/// little about a controller.
const MIN_PAUSES: usize = 5;

/// The share of the pauses in which the robot must have stood still.
const STOPPED_SHARE: f64 = 0.8;

/// A command moves the robot if it asks for this much speed or turn rate.
const MOVING_M_PER_S: f64 = 0.03;
const MOVING_RAD_PER_S: f64 = 0.1;

/// Seen over the second after the longest timeout looked for, a robot
/// that moves less than this share of what the held command asks has
/// stopped; one that moves more than `HELD_SHARE` of it holds the command.
const STOPPED_MOTION_SHARE: f64 = 0.25;
const HELD_SHARE: f64 = 0.6;

/// The longest timeout looked for: the part of a pause after it shows
/// whether the robot stands.
const LONGEST_TIMEOUT_S: f64 = 1.0;

/// The longest response delay the stops are measured apart from, and how
/// finely.
const LONGEST_DELAY_S: f64 = 0.3;
const DELAY_STEP_S: f64 = 0.01;

/// How finely the stop in a pause is looked for.
const STOP_STEP_S: f64 = 0.005;

/// What the command stream's pauses showed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CommandTimeout {
    /// How long after a command the robot stopped, when no other came:
    /// the median over the pauses in which it stopped.
    pub seconds: f64,
    /// The robot's response delay the stops were measured apart from: a
    /// robot that acts on each command late stops that much later too.
    pub delay_s: f64,
    /// Pauses of the command stream of at least `PAUSE_S` under a command
    /// that moves the robot.
    pub pauses: usize,
    /// Of those, the pauses in which the robot stood still.
    pub stopped: usize,
    /// Commands now taken to end `seconds` after they were given.
    pub commands_ended: usize,
    /// The held-out position error (m) of the model diagnosed against,
    /// with each command held until the next (as a simulation without the
    /// timeout drives) and with the commands ended by it; set by
    /// `diagnose`, which knows the model.
    pub heldout_rmse_pos_m_held: Option<f64>,
    pub heldout_rmse_pos_m_ended: Option<f64>,
}

impl CommandTimeout {
    /// `recording` with each command not followed within the timeout
    /// ended then, as diagnosis compares it.
    pub fn applied_to(&self, recording: &Recording) -> Recording {
        ended_recording(recording, self.seconds)
    }

    pub fn sentence(&self) -> String {
        let apart = if self.delay_s > 0.0 {
            format!(
                ", {:.2} s after its last command (the timeout, and the {:.2} s it takes to act on a command)",
                self.seconds + self.delay_s,
                self.delay_s
            )
        } else {
            String::new()
        };
        let fit = match (self.heldout_rmse_pos_m_held, self.heldout_rmse_pos_m_ended) {
            (Some(held), Some(ended)) => format!(
                " With it, the model's held-out position error is {:.1} mm, against {:.1} mm with each command held.",
                ended * 1e3,
                held * 1e3
            ),
            _ => String::new(),
        };
        format!(
            "The robot stops when no command has come for {:.2} s (a controller's command timeout, as ros2_control's \
             cmd_vel_timeout): it stood still in {} of the {} pauses of {PAUSE_S} s or more in the command \
             stream{apart}. So each of the {} commands not followed within that time is taken to end then, not held \
             until the next.{fit}",
            self.seconds, self.stopped, self.pauses, self.commands_ended
        )
    }
}

/// How the robot moved through one pause of the command stream.
enum Pause {
    Stopped { after_s: f64 },
    Held,
    Unclear,
}

/// The recording with its commands ended by a timeout, if its pauses show
/// one (see the module's documentation), and the timeout.
pub fn with_timeout(
    recording: &Recording,
    options: &Options,
) -> Option<(Recording, CommandTimeout)> {
    let pauses: Vec<Pause> = pauses(&recording.commands)
        .filter_map(|k| pause(recording, k))
        .collect();
    let stopped_after: Vec<f64> = pauses
        .iter()
        .filter_map(|p| match p {
            Pause::Stopped { after_s } => Some(*after_s),
            _ => None,
        })
        .collect();
    let judged = pauses
        .iter()
        .filter(|p| !matches!(p, Pause::Unclear))
        .count();
    if judged < MIN_PAUSES || (stopped_after.len() as f64) < STOPPED_SHARE * judged as f64 {
        return None;
    }
    let stopped = stopped_after.len();
    let (seconds, delay_s) = apart_from_delay(recording, median(stopped_after), options);
    let timeout = CommandTimeout {
        seconds,
        delay_s,
        pauses: judged,
        stopped,
        commands_ended: ended(&recording.commands, seconds).1,
        heldout_rmse_pos_m_held: None,
        heldout_rmse_pos_m_ended: None,
    };
    Some((timeout.applied_to(recording), timeout))
}

/// The indices of commands that move the robot and are followed by a
/// pause of at least `PAUSE_S`.
fn pauses(commands: &Commands) -> impl Iterator<Item = usize> + '_ {
    (0..commands.t.len().saturating_sub(1)).filter(|&k| {
        commands.t[k + 1] - commands.t[k] >= PAUSE_S
            && (commands.v[k].abs() >= MOVING_M_PER_S
                || commands.omega[k].abs() >= MOVING_RAD_PER_S)
    })
}

/// How the robot moved through the pause after command `k`: over its
/// part after `LONGEST_TIMEOUT_S`, against what the command asks; if it
/// stood, how long after the command it stopped.
fn pause(recording: &Recording, k: usize) -> Option<Pause> {
    let c = &recording.commands;
    let (start, end) = (c.t[k], c.t[k + 1]);
    let (v, omega) = (c.v[k].abs(), c.omega[k].abs());
    let poses = &recording.poses;
    // A second of it, so that a held turn does not come round to where
    // it started.
    let (late_from, late_to) = (
        start + LONGEST_TIMEOUT_S,
        end.min(start + 2.0 * LONGEST_TIMEOUT_S),
    );
    let (from, to) = (poses.at(late_from)?, poses.at(late_to)?);
    let late = late_to - late_from;
    // The share of the commanded motion the robot made late in the pause:
    // of the distance, or of the turn for a turn in place.
    let driving = v >= MOVING_M_PER_S;
    let share = if driving {
        (to.position() - from.position()).length() / (v * late)
    } else {
        (to.theta - from.theta).abs() / (omega * late)
    };
    // A turn in place among poses of positions only says nothing.
    if share.is_nan() {
        return None;
    }
    if share > HELD_SHARE {
        return Some(Pause::Held);
    }
    if share >= STOPPED_MOTION_SHARE {
        return Some(Pause::Unclear);
    }
    // When it stopped: the knee of a line that rises and then stays flat,
    // fitted by least squares to how far it went (or turned) in the
    // pause's first `LONGEST_TIMEOUT_S`. The rise's slope is free, so a
    // speed gain does not move the knee.
    let origin = poses.at(start)?;
    let toward = (from.position() - origin.position()).normalize_or_zero();
    let first = poses.t.partition_point(|&t| t < start);
    let last = poses.t.partition_point(|&t| t <= late_from);
    let progress: Vec<(f64, f64)> = (first..last)
        .map(|i| {
            let gone = if driving {
                (poses.x[i] - origin.x) * toward.x + (poses.y[i] - origin.y) * toward.y
            } else {
                (poses.theta[i] - origin.theta).abs()
            };
            (poses.t[i] - start, gone)
        })
        .collect();
    let after_s = (1..)
        .map(|i| i as f64 * STOP_STEP_S)
        .take_while(|&knee| knee < LONGEST_TIMEOUT_S)
        .map(|knee| (knee_misfit(&progress, knee), knee))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map_or(LONGEST_TIMEOUT_S, |(_, knee)| knee);
    Some(Pause::Stopped { after_s })
}

/// The squared misfit of the least-squares line through `progress` (t,
/// distance) against `min(t, knee)`.
fn knee_misfit(progress: &[(f64, f64)], knee: f64) -> f64 {
    let n = progress.len() as f64;
    if n < 3.0 {
        return f64::INFINITY;
    }
    let xs: Vec<f64> = progress.iter().map(|p| p.0.min(knee)).collect();
    let mean_x = xs.iter().sum::<f64>() / n;
    let mean_y = progress.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = xs.iter().map(|x| (x - mean_x).powi(2)).sum();
    let sxy: f64 = xs
        .iter()
        .zip(progress)
        .map(|(x, p)| (x - mean_x) * (p.1 - mean_y))
        .sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    xs.iter()
        .zip(progress)
        .map(|(x, p)| (p.1 - mean_y - slope * (x - mean_x)).powi(2))
        .sum()
}

/// The timeout and the response delay, apart: a robot that acts on its
/// commands `delay` late also stops that late, so the stops seen `stopped`
/// after each command are the timeout plus the delay. Of the delays up to
/// `LONGEST_DELAY_S` (each with the timeout it leaves), the one under which
/// the plain model delayed so predicts the run best. Without this, a
/// robot 0.1 s late with a 0.5 s timeout was compared as stopping 0.61 s
/// after its commands and then 0.1 s later again, and named a fading
/// battery and a surface zone for the difference.
fn apart_from_delay(recording: &Recording, stopped: f64, options: &Options) -> (f64, f64) {
    let delays: Vec<f64> = (0..)
        .map(|i| i as f64 * DELAY_STEP_S)
        .take_while(|d| *d <= LONGEST_DELAY_S.min(stopped - DELAY_STEP_S))
        .collect();
    // The segments are cut once, where every command stream tried reaches.
    let shortest = ended_recording(recording, stopped - delays.last().copied().unwrap_or(0.0));
    let segments = segments(
        &shortest,
        &command_grid(&shortest, options.grid_dt),
        options.horizon_s,
    );
    delays
        .into_iter()
        .map(|delay| {
            let grid = command_grid(
                &ended_recording(recording, stopped - delay),
                options.grid_dt,
            );
            let late = [ScopedEffect::always(Effect::Latency { seconds: delay })];
            (nll_of(&grid, &segments, &late), delay)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map_or((stopped, 0.0), |(_, delay)| (stopped - delay, delay))
}

/// `recording` with its commands ended `seconds` after each not followed
/// within that time ([`ended`]).
fn ended_recording(recording: &Recording, seconds: f64) -> Recording {
    Recording {
        commands: ended(&recording.commands, seconds).0,
        ..recording.clone()
    }
}

/// `commands` with a stop inserted `seconds` after every command not
/// followed within that time, and how many were ended so.
fn ended(commands: &Commands, seconds: f64) -> (Commands, usize) {
    let mut out = Commands::default();
    let mut count = 0;
    for k in 0..commands.t.len() {
        out.hold(commands.t[k], commands.v[k], commands.omega[k]);
        let moving = commands.v[k] != 0.0 || commands.omega[k] != 0.0;
        let next = commands.t.get(k + 1).copied();
        if moving && next.is_some_and(|n| n - commands.t[k] > seconds) {
            out.hold(commands.t[k] + seconds, 0.0, 0.0);
            count += 1;
        }
    }
    (out, count)
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::Poses;

    /// A robot given a new command every 3 s (a teleoperator who
    /// publishes only when a key changes) that drives each at its speed
    /// for `timeout` seconds and then stands, or holds it if `None`.
    fn teleoperated(timeout: Option<f64>) -> Recording {
        let mut commands = Commands::default();
        let mut poses = Poses::default();
        let (mut x, mut y, mut theta) = (0.0, 0.0, 0.0);
        let dt = 0.01;
        for k in 0..40 {
            let t0 = 3.0 * k as f64;
            let (v, omega) = if k % 2 == 0 { (0.2, 0.1) } else { (0.15, -0.2) };
            commands.hold(t0, v, omega);
            for i in 0..300 {
                let t = t0 + i as f64 * dt;
                if i % 3 == 0 {
                    poses.observe(t, x, y, theta);
                }
                if timeout.is_none_or(|s| t - t0 < s) {
                    x += v * theta.cos() * dt;
                    y += v * theta.sin() * dt;
                    theta += omega * dt;
                }
            }
        }
        commands.hold(120.0, 0.0, 0.0);
        Recording::of(commands, poses)
    }

    #[test]
    fn a_robot_that_stands_in_the_pauses_of_its_commands_has_a_timeout_and_its_length_is_measured()
    {
        let (recording, timeout) =
            with_timeout(&teleoperated(Some(0.5)), &Options::default()).expect("a timeout");
        assert!((timeout.seconds - 0.5).abs() < 0.02, "{timeout:?}");
        assert_eq!((timeout.pauses, timeout.stopped), (40, 40), "{timeout:?}");
        assert_eq!(timeout.commands_ended, 40);
        // Each command now ends with a stop half a second after it.
        assert_eq!(recording.commands.t.len(), 81);
        assert!((recording.commands.t[1] - 0.5).abs() < 0.02);
        assert_eq!(
            (recording.commands.v[1], recording.commands.omega[1]),
            (0.0, 0.0)
        );
    }

    #[test]
    fn a_robot_that_drives_on_through_its_pauses_holds_its_commands() {
        assert_eq!(with_timeout(&teleoperated(None), &Options::default()), None);
    }
}

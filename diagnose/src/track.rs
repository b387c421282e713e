//! The heading of poses that carry none: a GPS, a tracker that follows one
//! marker, a file of positions. A wheeled robot drives where it points, so
//! where it moves fast enough for its direction to be known, the heading is
//! the direction of its track (turned half round where it was commanded to
//! drive backwards). Where it stands, turns on the spot, or its commanded
//! turn rate changes within the window (which the fit would smooth into an
//! error that is not noise), its heading is unknown, and the pose is left
//! out, as a dropout is. A tracked point off the axle moves askew of the
//! body in turns: its turns on the spot measure how far, and bound the
//! turns whose headings are kept.

use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::recording::{Commands, Poses, Recording};

/// How well a heading taken from the track must be known (its standard
/// error, radians): about a degree, what a motion-capture rig's own heading
/// is good to. A looser bar keeps slower poses, whose headings' noise would
/// be fitted as the robot's.
pub const HEADING_STANDARD_ERROR_RAD: f64 = 0.02;

/// The shortest window's half-width, in the poses' usual intervals: eight
/// or nine poses, from which a cubic's slope and its residuals' spread
/// (on ten degrees of freedom or so) can be taken.
const SHORTEST_HALF_WINDOW_INTERVALS: f64 = 4.0;

/// The longest half-width a slow pose's window may grow to (seconds, or the
/// shortest window where poses come slower): a window of a segment's
/// length, beyond which the heading is an average over turns.
const LONGEST_HALF_WINDOW_S: f64 = 0.5;

/// The kinds of effect a track cannot show: each turns the direction the
/// tracked point moves away from where the body points, and a heading taken
/// from the track follows the point. They are not tried.
pub const UNSEEN_FROM_THE_TRACK: [&str; 2] = ["crab_angle", "turn_centre_offset"];

/// The least position noise assumed (metres): a track without noise (a
/// simulator's) still bends within a window, which no noise would excuse.
const NOISE_FLOOR_M: f64 = 1e-4;

/// How surely a window's cubic must explain its positions: its residuals
/// may exceed the noise as often as chance would at this level. Where the
/// robot stops short or starts at once (a kink), the cubic smooths over it,
/// and the direction it gives is not where the body points.
const QUADRATIC_FITS_LEVEL: f64 = 0.99;

/// What taking headings from the track did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrackHeadings {
    /// Poses without a heading.
    pub poses: usize,
    /// Of them, those whose track gave one.
    pub headed: usize,
    /// Of those, the ones turned half round: commanded backwards.
    pub reversed: usize,
    /// The windows' half-widths, shortest and longest used, seconds.
    pub half_window_s: [f64; 2],
    /// The positions' noise, as the shortest windows' residuals show it, metres.
    pub position_noise_m: f64,
    /// How far the tracked point is from the axle, as turns on the spot
    /// show it (metres; none where the robot never turned on the spot),
    /// and the sharpest turn (rad per metre driven) whose headings were
    /// kept for it.
    pub off_axle_m: Option<f64>,
    pub sharpest_turn_rad_per_m: Option<f64>,
}

impl TrackHeadings {
    /// In words, for the report.
    pub fn sentence(&self) -> String {
        let off_axle = match (self.off_axle_m, self.sharpest_turn_rad_per_m) {
            (Some(d), Some(sharpest)) => format!(
                "; its turns on the spot put the tracked point {:.0} mm from the axle, which bends a heading by about that distance times the turn rate over the speed, so only turns gentler than {sharpest:.1} rad a metre are kept",
                d * 1e3
            ),
            (Some(_), None) => "; its turns on the spot put the tracked point on the axle".to_owned(),
            (None, _) => "; the robot never turned on the spot for long, so how far the tracked point is from the axle is unknown: if it is off it, tight turns bend these headings".to_owned(),
        };
        format!(
            "the poses hold positions only; each heading is the direction of the track (a cubic fitted over ±{:.2}-{:.2} s), kept where it is known within {:.0} mrad: {} of {} poses ({} of them driving backwards). The other {} (standing, turning on the spot or sharply, the commanded turn rate changing within the window, stopping or starting at once, or too slow for the {:.1} mm of position noise) are left out as dropouts{off_axle}. A crab angle or a point off the axle turns the track from where the body points, so neither is tried",
            self.half_window_s[0],
            self.half_window_s[1],
            HEADING_STANDARD_ERROR_RAD * 1e3,
            self.headed,
            self.poses,
            self.reversed,
            self.poses - self.headed,
            self.position_noise_m * 1e3,
        )
    }
}

/// `recording` with the headings it lacks (NaN) taken from its track, and
/// what was done; `None` where every pose has its heading.
pub fn headed(recording: &Recording) -> Option<(Recording, TrackHeadings)> {
    let poses = &recording.poses;
    let missing = poses.theta.iter().filter(|theta| theta.is_nan()).count();
    if missing == 0 {
        return None;
    }
    let windows = Windows::of(poses);
    let off_axle_m = off_axle(recording, &windows);
    // Where the point is off the axle, only turns gentle enough for it to
    // bend the heading by no more than the heading's own error.
    let sharpest_turn = off_axle_m.map_or(f64::INFINITY, |d| HEADING_STANDARD_ERROR_RAD / d);
    let mut kept = Poses::default();
    let (mut headed, mut reversed) = (0, 0);
    let mut used = [f64::INFINITY, 0.0_f64];
    for i in 0..poses.len() {
        let theta = if poses.theta[i].is_nan() {
            let Some((heading, half)) = heading_at(poses, i, &windows) else {
                continue;
            };
            if !turn_held(recording, poses.t[i], half) {
                continue;
            }
            let heading = match driven_way(recording, poses.t[i], windows.longest(), sharpest_turn)
            {
                Some(Way::Forwards) => heading,
                Some(Way::Backwards) => {
                    reversed += 1;
                    heading + std::f64::consts::PI
                }
                None => continue,
            };
            used = [used[0].min(half), used[1].max(half)];
            headed += 1;
            heading
        } else {
            poses.theta[i]
        };
        kept.push(poses.t[i], poses.x[i], poses.y[i], theta);
    }
    if headed == 0 {
        used = [windows.halves[0], windows.longest()];
    }
    Some((
        Recording {
            poses: kept,
            ..recording.clone()
        },
        TrackHeadings {
            poses: missing,
            headed,
            reversed,
            half_window_s: used,
            position_noise_m: windows.noise_variances[0].sqrt(),
            off_axle_m,
            sharpest_turn_rad_per_m: sharpest_turn.is_finite().then_some(sharpest_turn),
        },
    ))
}

enum Way {
    Forwards,
    Backwards,
}

/// Half the time a pose's direction of travel is read over, for the axis
/// check (seconds): the chord between the poses this far either side.
/// The chord of a turn of steady rate points where the body did at its
/// middle.
const AXIS_CHORD_HALF_S: f64 = 0.5;

/// The shortest chord read (metres): over it a tracker's millimetre of
/// noise turns the direction by a few degrees, far under the eighth of a
/// turn the check must tell apart. MRCLAM's robots drive 0.07 m/s.
const AXIS_CHORD_M: f64 = 0.02;

/// The most poses the axis check reads, spread evenly over the run.
const AXIS_SAMPLES: usize = 5000;

/// The fewest chords that may turn the headings, and the share of them
/// that must agree on the quarter turn.
const AXIS_FEWEST_CHORDS: usize = 50;
const AXIS_AGREEING_SHARE: f64 = 0.8;

/// Where the poses' headings were turned to the way the robot drives.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeadingAxis {
    /// How far every heading was turned, counterclockwise: a multiple of
    /// a quarter turn, radians.
    pub turned_rad: f64,
    /// Stretches of driving compared, and those whose direction of travel
    /// lay within an eighth of a turn of the turned heading.
    pub compared: usize,
    pub agreeing: usize,
}

impl HeadingAxis {
    /// In words, for the report.
    pub fn sentence(&self) -> String {
        let degrees = self.turned_rad.to_degrees();
        format!(
            "the poses' heading is not the way the robot drives: in {} of {} half-second stretches of driving it moved {:.0}° to the {} of it, as a motion-capture body defined with other axes than the robot's does; every heading is turned by {degrees:+.0}°, and what is left askew is tried as a crab angle",
            self.agreeing,
            self.compared,
            degrees.abs(),
            if degrees > 0.0 { "left" } else { "right" },
        )
    }
}

/// `recording` with its headings turned by the quarter turns that make
/// them the way the robot drives, where they are not: a motion-capture
/// rigid body takes the world's axes when it is defined (OptiTrack's,
/// Vicon's), so its x axis points wherever the robot's front did not. Only
/// whole quarter turns: a smaller angle is a crab angle, which diagnosis
/// names and fits. `None` where the headings need no turn, hold none, or
/// the robot drove too little, or too unlike one axis, to say.
pub fn driving_axis(recording: &Recording) -> Option<(Recording, HeadingAxis)> {
    let poses = &recording.poses;
    let step = (poses.len() / AXIS_SAMPLES).max(1);
    let mut quarters = [0usize; 4];
    for i in (0..poses.len()).step_by(step) {
        let (t, theta) = (poses.t[i], poses.theta[i]);
        if !theta.is_finite() {
            continue;
        }
        let from = poses.t.partition_point(|&s| s < t - AXIS_CHORD_HALF_S);
        let to = poses.t.partition_point(|&s| s <= t + AXIS_CHORD_HALF_S);
        let Some(to) = to.checked_sub(1).filter(|&to| to > from) else {
            continue;
        };
        // The chord's middle in time must be the pose's: both ends near
        // their bounds (no gap on one side).
        if t - poses.t[from] < 0.8 * AXIS_CHORD_HALF_S || poses.t[to] - t < 0.8 * AXIS_CHORD_HALF_S
        {
            continue;
        }
        let (dx, dy) = (poses.x[to] - poses.x[from], poses.y[to] - poses.y[from]);
        if dx.hypot(dy) < AXIS_CHORD_M {
            continue;
        }
        let within = poses.t[to] - poses.t[from] + LONGEST_DELAY_S;
        let travel = match driven_way(recording, poses.t[to], within, f64::INFINITY) {
            Some(Way::Forwards) => dy.atan2(dx),
            Some(Way::Backwards) => dy.atan2(dx) + std::f64::consts::PI,
            None => continue,
        };
        let off = shoal_physics::wrap_angle(travel - theta);
        quarters[(off / std::f64::consts::FRAC_PI_2).round().rem_euclid(4.0) as usize] += 1;
    }
    let compared: usize = quarters.iter().sum();
    tracing::debug!(
        "axis check: of {compared} stretches of driving, the direction of travel lay ahead of the heading in {}, left of it in {}, behind it in {}, right of it in {}",
        quarters[0],
        quarters[1],
        quarters[2],
        quarters[3]
    );
    let (quarter, &agreeing) = quarters.iter().enumerate().max_by_key(|(_, n)| **n)?;
    if quarter == 0
        || compared < AXIS_FEWEST_CHORDS
        || (agreeing as f64) < AXIS_AGREEING_SHARE * compared as f64
    {
        return None;
    }
    let turned_rad = shoal_physics::wrap_angle(quarter as f64 * std::f64::consts::FRAC_PI_2);
    let mut turned = recording.clone();
    for theta in turned.poses.theta.iter_mut().filter(|t| t.is_finite()) {
        *theta = shoal_physics::wrap_angle(*theta + turned_rad);
    }
    Some((
        turned,
        HeadingAxis {
            turned_rad,
            compared,
            agreeing,
        },
    ))
}

/// The longest a command is taken to wait before the robot answers it
/// (seconds): a window is judged by the commands up to this much before it.
const LONGEST_DELAY_S: f64 = 0.5;

/// How much of a heading's allowed error a change of turn rate within its
/// window may bend it by. The bend is no noise: it falls the same way at
/// every change, and a controller that steers back towards its path makes
/// the changes follow the turns, so over hundreds of segments it reads as
/// physics that is not there. With half the error allowed, 8 to 18 of 20
/// null runs of a waypoint follower named a steering play or a turn scale
/// from their positions; with a tenth, none of 20 (EXPERIMENTS.md 6b).
const TURN_CHANGE_SHARE: f64 = 0.1;

/// Whether the commanded turn rate held steady enough through the window
/// of `half` seconds around `t` (and the [`LONGEST_DELAY_S`] before it,
/// for a robot that answers late): a cubic follows a turn rate that
/// changes steadily, but smooths a change of it by about a quarter of the
/// change times the half-width, which may bend the heading by
/// [`TURN_CHANGE_SHARE`] of its allowed error, no more.
fn turn_held(recording: &Recording, t: f64, half: f64) -> bool {
    let c = &recording.commands;
    let turns = &c.omega[held_over(c, t - half - LONGEST_DELAY_S, t + half)];
    let (least, most) = turns
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &w| {
            (a.min(w), b.max(w))
        });
    turns.is_empty()
        || 0.25 * (most - least) * half <= TURN_CHANGE_SHARE * HEADING_STANDARD_ERROR_RAD
}

/// The commands that acted from `from` to `to` seconds: the one held at
/// `from` (if any was given by then) and those given after it.
fn held_over(c: &Commands, from: f64, to: f64) -> std::ops::Range<usize> {
    let given = |t: f64| c.t.partition_point(|&s| s <= t);
    given(from).saturating_sub(1)..given(to)
}

/// How far the tracked point is from the axle, as turns on the spot show
/// it: the track's speed over the turn rate (over a window of about half
/// a second)
/// where the commands turned the robot without driving it through that
/// window and one before it (the median over such poses); `None` where fewer than [`FEWEST_TURNS_ON_THE_SPOT`]
/// poses turned so.
fn off_axle(recording: &Recording, windows: &Windows) -> Option<f64> {
    let (c, poses) = (&recording.commands, &recording.poses);
    // The longest window no longer than a quarter second: turns on the
    // spot are often short.
    let level = windows
        .halves
        .iter()
        .rposition(|&h| h <= SPOT_TURN_HALF_WINDOW_S)
        .unwrap_or(0);
    let (half, noise_variance) = (windows.halves[level], windows.noise_variances[level]);
    let mut distances: Vec<f64> = (0..poses.len())
        .filter_map(|i| {
            // Turning on the spot through the window, and for a window
            // before it (a delay, a lag).
            let t = poses.t[i];
            if c.t.first().is_none_or(|&first| first > t - 2.0 * half) {
                return None;
            }
            let span = held_over(c, t - 2.0 * half, t + half);
            let turns = c.v[span.clone()]
                .iter()
                .zip(&c.omega[span])
                .map(|(v, w)| (v.abs() < STANDING_M_PER_S).then_some(w.abs()))
                .collect::<Option<Vec<f64>>>()?;
            let slowest = turns.iter().copied().fold(f64::INFINITY, f64::min);
            if slowest < TURNING_RAD_PER_S {
                return None;
            }
            let fit = slope_at(poses, i, half)?;
            // The noise's own share of the speed squared taken out.
            let squared = fit.velocity[0].powi(2) + fit.velocity[1].powi(2)
                - 2.0 * noise_variance * fit.slope_variance_factor;
            Some(squared.max(0.0).sqrt() / slowest)
        })
        .collect();
    if distances.len() < FEWEST_TURNS_ON_THE_SPOT {
        return None;
    }
    distances.sort_by(f64::total_cmp);
    Some(distances[distances.len() / 2])
}

/// The half-width of the windows a turn on the spot is measured over, at
/// most (seconds).
const SPOT_TURN_HALF_WINDOW_S: f64 = 0.25;

/// A command that drives slower than this stands (m/s), and one that turns
/// faster than this turns (rad/s), for [`off_axle`].
const STANDING_M_PER_S: f64 = 1e-3;
const TURNING_RAD_PER_S: f64 = 0.1;

/// The fewest poses turning on the spot that say how far the tracked point
/// is from the axle.
const FEWEST_TURNS_ON_THE_SPOT: usize = 20;

/// Which way the commands of the `within` seconds up to `t` drove: one
/// way, or none where they drove both (the robot reversing, or still
/// moving the way it was told before a delay), none at all, or turned
/// more sharply than `sharpest_turn` (rad per metre).
fn driven_way(recording: &Recording, t: f64, within: f64, sharpest_turn: f64) -> Option<Way> {
    let c = &recording.commands;
    let span = held_over(c, t - within, t);
    let held = &c.v[span.clone()];
    // A tracked point off the axle moves askew of the body by about its
    // distance times the turn rate over the speed.
    if c.omega[span]
        .iter()
        .zip(held)
        .any(|(w, v)| w.abs() > sharpest_turn * v.abs())
    {
        return None;
    }
    let forwards = held.iter().any(|&v| v > 0.0);
    let backwards = held.iter().any(|&v| v < 0.0);
    match (forwards, backwards) {
        (true, false) => Some(Way::Forwards),
        (false, true) => Some(Way::Backwards),
        _ => None,
    }
}

/// The windows a heading may be taken over: half-widths from the shortest,
/// doubling up to the longest, and the residuals' variance usual at each.
struct Windows {
    halves: Vec<f64>,
    /// At each half-width, the median of the cubics' residual
    /// variances: the noise as windows of that width see it. A tracker's
    /// noise is seldom white (a rig's jitter wanders over tenths of a
    /// second), so a window is judged against windows of its own width.
    noise_variances: Vec<f64>,
}

impl Windows {
    fn of(poses: &Poses) -> Self {
        let shortest = SHORTEST_HALF_WINDOW_INTERVALS * poses.usual_interval();
        let longest = LONGEST_HALF_WINDOW_S.max(shortest);
        // Fewer than two poses have no interval: one window, the longest.
        let mut halves = vec![if shortest > 0.0 { shortest } else { longest }];
        while halves[halves.len() - 1] < longest {
            halves.push((2.0 * halves[halves.len() - 1]).min(longest));
        }
        let noise_variances = halves
            .iter()
            .map(|&half| {
                let mut variances: Vec<f64> = (0..poses.len())
                    .filter_map(|i| slope_at(poses, i, half))
                    .map(|fit| fit.residual_variance)
                    .collect();
                variances.sort_by(f64::total_cmp);
                variances
                    .get(variances.len() / 2)
                    .copied()
                    .unwrap_or(0.0)
                    .max(NOISE_FLOOR_M.powi(2))
            })
            .collect();
        Self {
            halves,
            noise_variances,
        }
    }

    fn longest(&self) -> f64 {
        self.halves[self.halves.len() - 1]
    }
}

/// Pose `i`'s direction of travel and the half-width it was taken over:
/// from the shortest window up until the direction is known within
/// [`HEADING_STANDARD_ERROR_RAD`]; `None` if it never is, or if the first
/// window that knows it holds a kink.
fn heading_at(poses: &Poses, i: usize, windows: &Windows) -> Option<(f64, f64)> {
    for (&half, &noise_variance) in windows.halves.iter().zip(&windows.noise_variances) {
        let Some(fit) = slope_at(poses, i, half) else {
            continue;
        };
        let speed = fit.velocity[0].hypot(fit.velocity[1]);
        let standard_error = (noise_variance * fit.slope_variance_factor).sqrt() / speed;
        if speed > 0.0 && standard_error <= HEADING_STANDARD_ERROR_RAD {
            // A longer window will not mend a kink this one holds.
            return fit
                .explained(noise_variance)
                .then(|| (fit.velocity[1].atan2(fit.velocity[0]), half));
        }
    }
    None
}

/// A cubic in time fitted to the positions within `half` seconds of pose
/// `i`, on each axis: a turn rate that changes steadily (a controller
/// steering back to its path) bends a quadratic's slope by the change's
/// rate times a tenth of the window squared, a cubic's not.
struct Slope {
    /// Its slope at pose `i`'s time: the velocity, m/s.
    velocity: [f64; 2],
    /// The slope's variance per unit of the positions' noise variance.
    slope_variance_factor: f64,
    /// The residuals' variance over both axes (the positions' noise, where
    /// the motion is a cubic over the window).
    residual_variance: f64,
    /// Its degrees of freedom: two axes of poses less four coefficients.
    degrees_of_freedom: f64,
}

impl Slope {
    /// Whether the cubic explains the window's positions: its residuals
    /// no larger than noise of `noise_variance` leaves by chance.
    fn explained(&self, noise_variance: f64) -> bool {
        let bound = ChiSquared::new(self.degrees_of_freedom)
            .map(|chi| chi.inverse_cdf(QUADRATIC_FITS_LEVEL))
            .unwrap_or(f64::INFINITY);
        self.residual_variance * self.degrees_of_freedom / noise_variance <= bound
    }
}

/// The cubic fit around pose `i`; `None` with fewer than six poses in the
/// window or where their times cannot fix a cubic.
fn slope_at(poses: &Poses, i: usize, half: f64) -> Option<Slope> {
    const TERMS: usize = 4;
    let t0 = poses.t[i];
    let from = poses.t.partition_point(|&t| t < t0 - half);
    let to = poses.t.partition_point(|&t| t <= t0 + half);
    let n = to - from;
    if n < TERMS + 2 {
        return None;
    }
    // Normal equations in tau = t - t0 (scaled by `half`, so that they are
    // well conditioned at any window): sums of tau^k.
    let mut s = [0.0; 2 * TERMS - 1];
    let mut sx = [0.0; TERMS];
    let mut sy = [0.0; TERMS];
    for j in from..to {
        let tau = (poses.t[j] - t0) / half;
        let (x, y) = (poses.x[j] - poses.x[i], poses.y[j] - poses.y[i]);
        let mut power = 1.0;
        for (k, sk) in s.iter_mut().enumerate() {
            *sk += power;
            if k < TERMS {
                sx[k] += power * x;
                sy[k] += power * y;
            }
            power *= tau;
        }
    }
    let normal = glam::DMat4::from_cols_array(&[
        s[0], s[1], s[2], s[3], //
        s[1], s[2], s[3], s[4], //
        s[2], s[3], s[4], s[5], //
        s[3], s[4], s[5], s[6],
    ]);
    if normal.determinant().abs() < 1e-12 * s[0].powi(4) {
        return None;
    }
    let inverse = normal.inverse();
    let cx = inverse * glam::DVec4::from_array(sx);
    let cy = inverse * glam::DVec4::from_array(sy);
    let mut squares = 0.0;
    for j in from..to {
        let tau = (poses.t[j] - t0) / half;
        let (x, y) = (poses.x[j] - poses.x[i], poses.y[j] - poses.y[i]);
        let at = |c: glam::DVec4| c.x + tau * (c.y + tau * (c.z + tau * c.w));
        squares += (x - at(cx)).powi(2) + (y - at(cy)).powi(2);
    }
    let degrees_of_freedom = 2 * (n - TERMS);
    Some(Slope {
        velocity: [cx.y / half, cy.y / half],
        slope_variance_factor: inverse.y_axis.y / (half * half),
        residual_variance: squares / degrees_of_freedom as f64,
        degrees_of_freedom: degrees_of_freedom as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A robot driving a circle of radius 1 m at 0.2 m/s for 10 s, backwards
    /// for the next 5 s, then turning on the spot for 5 s, observed at 100
    /// Hz with `noise` metres of noise on each axis (a fixed pattern).
    fn positions_only(noise: f64, ahead: f64) -> (Recording, Vec<f64>) {
        let mut commands = Commands::default();
        commands.hold(0.0, 0.2, 0.2);
        commands.hold(10.0, -0.2, 0.0);
        commands.hold(15.0, 0.0, 0.5);
        let mut poses = Poses::default();
        let mut truth = Vec::new();
        let (mut x, mut y, mut theta) = (0.0, 0.0, 0.3_f64);
        let dt = 0.01;
        for k in 0..2000 {
            let t = k as f64 * dt;
            let wobble = noise * ((k * 7919 % 101) as f64 / 50.0 - 1.0);
            let wobble_y = noise * ((k * 104_729 % 97) as f64 / 48.0 - 1.0);
            let (sin, cos) = theta.sin_cos();
            poses.push(
                t,
                x + ahead * cos + wobble,
                y + ahead * sin + wobble_y,
                f64::NAN,
            );
            truth.push(theta);
            let (v, omega) = match t {
                t if t < 10.0 => (0.2, 0.2),
                t if t < 15.0 => (-0.2, 0.0),
                _ => (0.0, 0.5),
            };
            x += v * theta.cos() * dt;
            y += v * theta.sin() * dt;
            theta += omega * dt;
        }
        (Recording::of(commands, poses), truth)
    }

    #[test]
    fn headings_a_quarter_turn_off_the_way_driven_are_turned_and_a_small_angle_is_not() {
        let (recording, truth) = positions_only(0.001, 0.0);
        let with_headings = |offset: f64| {
            let mut r = recording.clone();
            r.poses.theta = truth
                .iter()
                .map(|theta| shoal_physics::wrap_angle(theta + offset))
                .collect();
            r
        };
        // A body defined with its x axis at the robot's left: turned back
        // by -90°, forwards and backwards alike.
        let (turned, how) =
            driving_axis(&with_headings(std::f64::consts::FRAC_PI_2 + 0.1)).expect("a quarter off");
        assert!(
            (how.turned_rad + std::f64::consts::FRAC_PI_2).abs() < 1e-12,
            "{how:?}"
        );
        assert_eq!(how.agreeing, how.compared);
        assert!(how.compared > 1000, "{how:?}");
        assert!(shoal_physics::wrap_angle(turned.poses.theta[500] - truth[500] - 0.1).abs() < 1e-9);
        assert!(
            how.sentence().contains("90° to the right"),
            "{}",
            how.sentence()
        );
        // Half round: the same.
        let (_, how) = driving_axis(&with_headings(std::f64::consts::PI)).expect("half round");
        assert!((how.turned_rad.abs() - std::f64::consts::PI).abs() < 1e-12);
        // A crab angle, and the truth, are left to diagnosis.
        assert!(driving_axis(&with_headings(0.3)).is_none());
        assert!(driving_axis(&with_headings(0.0)).is_none());
        // Positions only: nothing to turn.
        assert!(driving_axis(&recording).is_none());
    }

    #[test]
    fn the_heading_is_the_tracks_direction_backwards_turned_round_and_unknown_on_the_spot() {
        let (recording, truth) = positions_only(0.001, 0.0);
        let (headed, done) = headed(&recording).expect("the poses lack headings");
        assert_eq!(done.poses, 2000);
        // Driving forwards and backwards (15 s less the windows' edges at
        // the changes), none turning on the spot.
        assert!(
            (1400..=1500).contains(&done.headed),
            "{} poses headed",
            done.headed
        );
        assert!(
            (400..=500).contains(&done.reversed),
            "{} reversed",
            done.reversed
        );
        assert!(headed.poses.t.iter().all(|&t| t < 15.2));
        assert!(
            (0.0004..0.0015).contains(&done.position_noise_m),
            "noise {} m",
            done.position_noise_m
        );
        let mut worst = 0.0_f64;
        for (k, &t) in headed.poses.t.iter().enumerate() {
            let i = (t / 0.01).round() as usize;
            let error = shoal_physics::wrap_angle(headed.poses.theta[k] - truth[i]);
            worst = worst.max(error.abs());
        }
        assert!(worst < 0.1, "worst heading error {worst} rad");
        assert!(done.off_axle_m.is_some_and(|d| d < 0.003), "{done:?}");
        let said = done.sentence();
        assert!(
            said.starts_with("the poses hold positions only")
                && said.contains(&format!("{} of 2000 poses", done.headed)),
            "{said}"
        );
        let typical: f64 = headed
            .poses
            .t
            .iter()
            .enumerate()
            .map(|(k, &t)| {
                let i = (t / 0.01).round() as usize;
                shoal_physics::wrap_angle(headed.poses.theta[k] - truth[i]).powi(2)
            })
            .sum::<f64>()
            / headed.poses.len() as f64;
        assert!(
            typical.sqrt() < HEADING_STANDARD_ERROR_RAD,
            "RMS {} rad",
            typical.sqrt()
        );
    }

    #[test]
    fn a_point_off_the_axle_is_measured_on_the_spot_and_keeps_only_gentle_turns() {
        // 5 cm ahead of the axle: on the circle (0.2 rad/s at 0.2 m/s, 1
        // rad a metre) its track runs 0.05 rad askew of the body.
        let (recording, _) = positions_only(0.001, 0.05);
        let (_, done) = headed(&recording).expect("the poses lack headings");
        let d = done.off_axle_m.expect("it turned on the spot");
        assert!((0.04..0.06).contains(&d), "{d} m off the axle");
        // Gentler than 1 rad a metre: the circle's headings are left out,
        // the straight drive backwards kept.
        assert!(
            done.sharpest_turn_rad_per_m.is_some_and(|k| k < 1.0),
            "{done:?}"
        );
        assert!((400..=500).contains(&done.headed), "{} headed", done.headed);
        assert!(done.sentence().contains("from the axle"));
    }

    #[test]
    fn a_single_pose_without_a_heading_gets_none_and_ends() {
        let mut poses = Poses::default();
        poses.push(0.0, 0.0, 0.0, f64::NAN);
        let (headed, done) =
            headed(&Recording::of(Commands::default(), poses)).expect("it lacks a heading");
        assert_eq!((headed.poses.len(), done.headed), (0, 0));
    }

    #[test]
    fn poses_with_their_headings_are_left_as_they_are() {
        let mut poses = Poses::default();
        for k in 0..100 {
            poses.push(k as f64 * 0.1, 0.01 * k as f64, 0.0, 0.0);
        }
        assert!(headed(&Recording::of(Commands::default(), poses)).is_none());
    }
}

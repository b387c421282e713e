//! A wheeled robot driven by (v, omega) commands: the plain unicycle plus
//! whatever effects of [`crate::effects`] its model carries. The same code
//! moves the simulated body and predicts motion in `shoal diagnose`, so a
//! model that diagnosis writes is exactly what the simulator runs.

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::effects::{Effect, ScopedEffect};
use crate::pose::{Pose, wrap_angle};
use crate::toml_file::{ScenarioError, parse_toml};

/// A unicycle model with effects; `effects = []` is the plain model.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnicycleModel {
    #[serde(default)]
    pub effects: Vec<ScopedEffect>,
}

/// Commands held until the next one, sampled on a fixed time grid.
#[derive(Clone, Debug, PartialEq)]
pub struct CommandGrid {
    pub t0: f64,
    pub dt: f64,
    pub v: Vec<f64>,
    pub omega: Vec<f64>,
}

/// What the actuators executed at each grid step, before the effects that
/// depend on where the robot is.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Executed {
    pub v: Vec<f64>,
    pub omega: Vec<f64>,
}

impl CommandGrid {
    /// Commands given at sorted `times` (each held until the next), as the
    /// body receives them over each step of `dt`: the time-weighted mean of
    /// what was held during the step. Sampled at the step's start instead, a
    /// command given a microsecond after a grid point (a real robot's are
    /// never on the grid) would act a whole step late, and a latency fitted
    /// to it would be off by up to a step.
    pub fn from_held(times: &[f64], v: &[f64], omega: &[f64], dt: f64) -> Self {
        let (Some(&first), Some(&last)) = (times.first(), times.last()) else {
            return Self {
                t0: 0.0,
                dt,
                v: Vec::new(),
                omega: Vec::new(),
            };
        };
        let steps = ((last - first) / dt).floor() as usize + 1;
        let mut grid = Self {
            t0: first,
            dt,
            v: Vec::with_capacity(steps),
            omega: Vec::with_capacity(steps),
        };
        let mut row = 0;
        for i in 0..steps {
            let (start, end) = (first + i as f64 * dt, first + (i + 1) as f64 * dt);
            while row + 1 < times.len() && times[row + 1] <= start {
                row += 1;
            }
            // Each command held within [start, end), weighted by how long.
            let (mut sum_v, mut sum_omega, mut from, mut r) = (0.0, 0.0, start, row);
            loop {
                let until = times
                    .get(r + 1)
                    .map_or(end, |&next| next.min(end))
                    .max(from);
                sum_v += (until - from) * v[r];
                sum_omega += (until - from) * omega[r];
                from = until;
                if from >= end {
                    break;
                }
                r += 1;
            }
            grid.v.push(sum_v / (end - start));
            grid.omega.push(sum_omega / (end - start));
        }
        grid
    }

    pub fn len(&self) -> usize {
        self.v.len()
    }

    pub fn is_empty(&self) -> bool {
        self.v.is_empty()
    }

    pub fn time(&self, index: usize) -> f64 {
        self.t0 + index as f64 * self.dt
    }

    /// The command at time `t`, interpolated between grid steps so that a
    /// fitted latency moves the prediction smoothly; before the first
    /// command the robot stands.
    pub fn at(&self, t: f64) -> (f64, f64) {
        let position = (t - self.t0) / self.dt;
        if position < 0.0 || self.v.is_empty() {
            return (0.0, 0.0);
        }
        // Truncation is the floor here: position is not negative.
        let i = position as usize;
        if i + 1 >= self.v.len() {
            let last = self.v.len() - 1;
            return (self.v[last], self.omega[last]);
        }
        let f = position - i as f64;
        (
            self.v[i] + f * (self.v[i + 1] - self.v[i]),
            self.omega[i] + f * (self.omega[i + 1] - self.omega[i]),
        )
    }
}

/// The actuators' memory: the steering's held rate and the last speed.
#[derive(Clone, Copy, Debug, Default)]
pub struct Actuators {
    held_omega: f64,
    last_v: f64,
    /// What a lagging actuator executes now (v, omega).
    lagged: (f64, f64),
}

impl Actuators {
    /// Actuators that have been holding (`v`, `omega`) for a while.
    pub fn settled(v: f64, omega: f64) -> Self {
        Self {
            held_omega: omega,
            last_v: v,
            lagged: (v, omega),
        }
    }

    /// What the actuators execute at grid step `i` under `model`; only looks
    /// back in time, so a body can extend the grid as commands arrive.
    /// Seconds of the run count from the grid's start.
    pub fn execute(&mut self, model: &UnicycleModel, grid: &CommandGrid, i: usize) -> (f64, f64) {
        let t = grid.time(i);
        let run_s = t - grid.t0;
        let (mut v, mut omega) = (grid.v[i], grid.omega[i]);
        for effect in model.active(run_s) {
            if let Effect::Latency { seconds } = *effect {
                (v, omega) = grid.at(t - seconds);
            }
        }
        // The controller clamps the command before the motors follow it.
        for effect in model.active(run_s) {
            if let Effect::SpeedLimit { pace_s_per_m } = *effect {
                let top = crate::effects::top_speed(pace_s_per_m);
                v = v.clamp(-top, top);
            }
        }
        for effect in model.active(run_s) {
            if let Effect::ActuatorLag { seconds } = *effect
                && seconds > 0.0
            {
                let follow = 1.0 - (-grid.dt / seconds).exp();
                let (lv, lo) = self.lagged;
                self.lagged = (lv + follow * (v - lv), lo + follow * (omega - lo));
                (v, omega) = self.lagged;
            }
        }
        let moving = v != 0.0 || omega != 0.0;
        let mut accel_limit = f64::INFINITY;
        for effect in model.active(run_s) {
            match *effect {
                Effect::Hysteresis { play_rad_per_s } => {
                    self.held_omega = self
                        .held_omega
                        .clamp(omega - play_rad_per_s, omega + play_rad_per_s);
                    omega = self.held_omega;
                }
                Effect::SpeedScale { factor } => v *= factor,
                Effect::TurnScale { factor } => omega *= factor,
                Effect::TurnBias { rad_per_s } if moving => omega += rad_per_s,
                Effect::Slip { per_m_per_s } => v *= (1.0 - per_m_per_s * v.abs()).max(0.0),
                Effect::BatteryFade { per_minute } => {
                    let gain = (1.0 - per_minute * run_s / 60.0).max(0.0);
                    v *= gain;
                    omega *= gain;
                }
                Effect::AccelLimit { m_per_s2 } => accel_limit = m_per_s2,
                _ => {}
            }
        }
        // The turn that costs speed is the one executed, after every gain.
        for effect in model.active(run_s) {
            if let Effect::TurnSpeedLoss { per_rad_per_s } = *effect {
                v *= (1.0 - per_rad_per_s * omega.abs()).max(0.0);
            }
        }
        let max_change = accel_limit * grid.dt;
        v = self.last_v + (v - self.last_v).clamp(-max_change, max_change);
        self.last_v = v;
        (v, omega)
    }
}

/// One step of the body: its velocity in its own frame (along, across the
/// heading, m/s), the turn over the step (rad) and the world's flow (m/s).
struct BodyMotion {
    velocity: DVec2,
    turn: f64,
    flow: DVec2,
}

impl BodyMotion {
    /// Midpoint integration from `pose`, whose heading at the step's middle
    /// is the unit vector `mid_heading`; the heading is left unwrapped so
    /// that long predictions need no wrapping per step.
    fn advance(&self, pose: Pose, mid_heading: DVec2, dt: f64) -> Pose {
        let moved = (mid_heading.rotate(self.velocity) + self.flow) * dt;
        Pose {
            x: pose.x + moved.x,
            y: pose.y + moved.y,
            theta: pose.theta + self.turn,
        }
    }
}

/// Below this a turn's half is rotated by [`small_rotation`]'s series.
const SMALL_ANGLE_RAD: f64 = 0.1;

/// The unit vector at `angle` from the x axis, for the small angles one
/// step turns: Taylor series whose first terms left out are below 3e-17
/// at [`SMALL_ANGLE_RAD`], an eighth of a double's spacing at 1, so
/// it equals `DVec2::from_angle` to the last bit or so, for a few
/// multiplications (a `sin_cos` per step was a third of a diagnosis's
/// time; BENCHMARKS.md 3). Larger angles take `from_angle`.
#[inline]
fn small_rotation(angle: f64) -> DVec2 {
    if angle.abs() > SMALL_ANGLE_RAD {
        return DVec2::from_angle(angle);
    }
    // Horner's form with the factorials' reciprocals folded into constants:
    // divisions cost several times a multiplication.
    const S3: f64 = -1.0 / 6.0;
    const S5: f64 = 1.0 / 120.0;
    const S7: f64 = -1.0 / 5040.0;
    const S9: f64 = 1.0 / 362_880.0;
    const C2: f64 = -1.0 / 2.0;
    const C4: f64 = 1.0 / 24.0;
    const C6: f64 = -1.0 / 720.0;
    const C8: f64 = 1.0 / 40_320.0;
    let a2 = angle * angle;
    let sin = angle * (1.0 + a2 * (S3 + a2 * (S5 + a2 * (S7 + a2 * S9))));
    let cos = 1.0 + a2 * (C2 + a2 * (C4 + a2 * (C6 + a2 * C8)));
    DVec2::new(cos, sin)
}

impl UnicycleModel {
    pub fn plain() -> Self {
        Self::default()
    }

    pub fn with_effects(effects: Vec<ScopedEffect>) -> Self {
        Self { effects }
    }

    /// Reads a model file; errors name the file, line and field.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, ScenarioError> {
        let model: Self = parse_toml(text, file)?;
        for (index, scoped) in model.effects.iter().enumerate() {
            let finite = scoped.effect.params().iter().all(|(_, v)| v.is_finite());
            if !finite || !scoped.effect.in_bounds() {
                let field = format!("effects[{index}]");
                return Err(ScenarioError {
                    file: file.to_owned(),
                    line: crate::toml_file::line_of_nth_table(text, "effects", index),
                    field: Some(field),
                    message: format!(
                        "{} has parameters outside what is physical: {:?}",
                        scoped.effect.kind(),
                        scoped.effect.params()
                    ),
                });
            }
        }
        Ok(model)
    }

    /// The model as a model file. An error, never an empty file, if it
    /// cannot be written (a parameter TOML has no number for).
    pub fn to_toml(&self) -> Result<String, toml::ser::Error> {
        toml::to_string_pretty(self)
    }

    fn active(&self, t: f64) -> impl Iterator<Item = &Effect> {
        self.effects
            .iter()
            .filter(move |e| e.active_at(t))
            .map(|e| &e.effect)
    }

    /// Runs the actuators over the whole grid: latency, hysteresis, gains
    /// and the acceleration limit.
    pub fn execute(&self, grid: &CommandGrid) -> Executed {
        let mut actuators = Actuators::default();
        let (v, omega) = (0..grid.len())
            .map(|i| actuators.execute(self, grid, i))
            .unzip();
        Executed { v, omega }
    }

    /// One integration step of `dt` from `pose`: the body's motion
    /// ([`Self::body_motion`]) integrated at the step's middle heading, the
    /// heading wrapped.
    pub fn step(&self, pose: Pose, v: f64, omega: f64, run_s: f64, dt: f64) -> Pose {
        let motion = self.body_motion(&pose, v, omega, run_s, dt);
        let mid_heading = DVec2::from_angle(pose.theta + 0.5 * motion.turn);
        let mut next = motion.advance(pose, mid_heading, dt);
        next.theta = wrap_angle(next.theta);
        next
    }

    /// What the body does over one step of `dt` from `pose` with the
    /// executed `v`, `omega` at `run_s` seconds into the run: the effects
    /// that depend on place and distance.
    fn body_motion(&self, pose: &Pose, v: f64, omega: f64, run_s: f64, dt: f64) -> BodyMotion {
        let mut speed = v;
        let mut turn = omega * dt;
        let mut flow = DVec2::ZERO;
        for effect in self.active(run_s) {
            match *effect {
                Effect::SurfaceZone {
                    region: [x0, y0, x1, y1],
                    speed_factor,
                    turn_factor,
                } if pose.x >= x0 && pose.x <= x1 && pose.y >= y0 && pose.y <= y1 => {
                    speed *= speed_factor;
                    turn *= turn_factor;
                }
                Effect::ExternalFlow { vx, vy } => flow = DVec2::new(vx, vy),
                _ => {}
            }
        }
        for effect in self.active(run_s) {
            if let Effect::HeadingDrift { rad_per_m } = *effect {
                turn += rad_per_m * speed * dt;
            }
        }
        // The observed point's own velocity in the body frame, beyond the
        // turning centre's (along, across), m/s.
        let mut swing = (0.0, 0.0);
        let rate = turn / dt;
        for effect in self.active(run_s) {
            match *effect {
                Effect::TurnCentreOffset { forward_m, left_m } => {
                    // omega x r for r = (forward, left): (-omega left, omega forward).
                    swing.0 -= rate * left_m;
                    swing.1 += rate * forward_m;
                }
                // A forward-Euler step of h drives along a heading h/2 old
                // on average: to first order, sideways at -v omega h/2 (a
                // semi-implicit one, h < 0 here, along one h/2 ahead).
                Effect::EulerStep { seconds, .. } => swing.1 -= speed * rate * 0.5 * seconds,
                _ => {}
            }
        }
        let mut ahead = DVec2::X;
        for effect in self.active(run_s) {
            if let Effect::CrabAngle { rad } = *effect {
                ahead = DVec2::from_angle(rad);
            }
        }
        BodyMotion {
            velocity: ahead * speed + DVec2::new(swing.0, swing.1),
            turn,
            flow,
        }
    }

    /// Whether what the actuators execute depends on their history (a lag,
    /// play in the steering, an acceleration limit), not only on the
    /// commands at one time.
    pub fn has_actuator_memory(&self) -> bool {
        self.effects.iter().any(|e| {
            matches!(
                e.effect,
                Effect::ActuatorLag { .. } | Effect::Hysteresis { .. } | Effect::AccelLimit { .. }
            )
        })
    }

    /// Predicts many stretches at once: for each `(start, from, to)` (in time
    /// order) the pose at grid step `to` from `start` at step `from`, the
    /// cost of each independent of how long the run is. The
    /// actuators run on through consecutive stretches, so their state is the
    /// one the whole history gives; where stretches leave a gap (or overlap)
    /// they are warmed up afresh over `warmup` steps.
    pub fn predict_stretches(
        &self,
        grid: &CommandGrid,
        stretches: impl IntoIterator<Item = (Pose, usize, usize)>,
        warmup: usize,
    ) -> Vec<Pose> {
        self.trace_stretches(grid, stretches, warmup, |_, _, _| {})
    }

    /// [`Self::predict_stretches`], also handing `on_step` every pose on the
    /// way: the stretch's index, the grid step just executed and the pose
    /// after it (for showing predictions, not only scoring their ends).
    pub fn trace_stretches(
        &self,
        grid: &CommandGrid,
        stretches: impl IntoIterator<Item = (Pose, usize, usize)>,
        warmup: usize,
        mut on_step: impl FnMut(usize, usize, Pose),
    ) -> Vec<Pose> {
        let mut actuators = Actuators::default();
        // The next grid step the actuators would execute.
        let mut cursor = usize::MAX;
        let mut out = Vec::new();
        for (index, (start, from, to)) in stretches.into_iter().enumerate() {
            let to = to.min(grid.len());
            let first = from.saturating_sub(warmup);
            if cursor > from || cursor < first {
                cursor = first;
                if let (Some(&v), Some(&omega)) = (grid.v.get(first), grid.omega.get(first)) {
                    actuators = Actuators::settled(v, omega);
                }
            }
            let mut pose = start;
            // The heading as a unit vector, turned by each step's half turn
            // twice (to the step's middle, then its end) rather than taken
            // from a sine and cosine per step.
            let mut heading = DVec2::from_angle(pose.theta);
            while cursor < to {
                let (v, omega) = actuators.execute(self, grid, cursor);
                if cursor >= from {
                    let motion =
                        self.body_motion(&pose, v, omega, grid.time(cursor) - grid.t0, grid.dt);
                    let half_turn = small_rotation(0.5 * motion.turn);
                    let mid_heading = half_turn.rotate(heading);
                    pose = motion.advance(pose, mid_heading, grid.dt);
                    heading = half_turn.rotate(mid_heading);
                    on_step(index, cursor, pose);
                }
                cursor += 1;
            }
            pose.theta = wrap_angle(pose.theta);
            out.push(pose);
        }
        out
    }

    /// Integrates from `start` at grid step `from` to grid step `to`.
    pub fn integrate(
        &self,
        grid: &CommandGrid,
        executed: &Executed,
        start: Pose,
        from: usize,
        to: usize,
    ) -> Pose {
        let mut pose = start;
        for i in from..to.min(executed.v.len()) {
            let run_s = grid.time(i) - grid.t0;
            pose = self.step(pose, executed.v[i], executed.omega[i], run_s, grid.dt);
        }
        pose
    }

    /// How much larger than the plain model's the motion noise variance is
    /// at `speed` m/s.
    pub fn noise_multiplier(&self, speed: f64, run_s: f64) -> f64 {
        self.active(run_s)
            .map(|e| 1.0 + e.noise_growth_at(speed))
            .product()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_rotation_is_the_sine_and_cosine_to_the_last_bits() {
        for k in -2000..=2000 {
            let angle = k as f64 * 0.6e-4;
            let (fast, exact) = (small_rotation(angle), DVec2::from_angle(angle));
            assert!(
                (fast - exact).abs().max_element() <= 2.0 * f64::EPSILON,
                "{angle}: {fast} against {exact}"
            );
        }
        // Past the series' range it is the sine and cosine themselves.
        assert_eq!(small_rotation(0.3), DVec2::from_angle(0.3));
    }

    /// Predicting stretches turns the heading by rotations; stepping pose
    /// by pose takes a sine and cosine each step: both must end in one place,
    /// whatever the body does, over turns small and large.
    #[test]
    fn predicted_stretches_end_where_stepping_pose_by_pose_does() {
        let model = UnicycleModel::with_effects(
            [
                Effect::ActuatorLag { seconds: 0.2 },
                Effect::Latency { seconds: 0.05 },
                Effect::HeadingDrift { rad_per_m: 0.05 },
                Effect::TurnCentreOffset {
                    forward_m: 0.03,
                    left_m: -0.02,
                },
                Effect::ExternalFlow {
                    vx: 0.01,
                    vy: -0.02,
                },
                Effect::SurfaceZone {
                    region: [0.5, -1.0, 1.5, 1.0],
                    speed_factor: 0.6,
                    turn_factor: 0.8,
                },
            ]
            .into_iter()
            .map(ScopedEffect::always)
            .collect(),
        );
        // Standing (so the actuators start as `execute` starts them),
        // gentle turns, a spin of 0.15 rad a step (past the series' range)
        // and straight driving; the stretches follow on from one another,
        // so the actuators run on through them.
        let times = [0.0, 0.5, 2.5, 3.5, 5.5, 8.5];
        let grid = CommandGrid::from_held(
            &times,
            &[0.0, 0.4, 0.0, 0.3, 0.5, 0.5],
            &[0.0, 0.5, 15.0, -0.8, 0.0, 0.0],
            0.01,
        );
        let starts = [(0, 200), (200, 370), (370, 750)];
        let start = Pose::new(0.2, -0.1, 0.4);
        let executed = model.execute(&grid);
        let predicted =
            model.predict_stretches(&grid, starts.iter().map(|&(from, to)| (start, from, to)), 0);
        for (&(from, to), end) in starts.iter().zip(predicted) {
            let stepped = model.integrate(&grid, &executed, start, from, to);
            assert!(
                (end.x - stepped.x).abs() < 1e-12
                    && (end.y - stepped.y).abs() < 1e-12
                    && crate::pose::wrap_angle(end.theta - stepped.theta).abs() < 1e-12,
                "{from}-{to}: {end:?} against {stepped:?}"
            );
        }
    }

    fn straight(seconds: f64, v: f64, omega: f64) -> CommandGrid {
        CommandGrid::from_held(&[0.0, seconds], &[v, v], &[omega, omega], 0.01)
    }

    #[test]
    fn a_command_counts_for_the_share_of_the_step_it_was_held() {
        // A command given a quarter into the second step.
        let grid = CommandGrid::from_held(
            &[0.0, 0.0125, 0.1],
            &[0.0, 0.4, 0.4],
            &[0.0, -0.8, -0.8],
            0.01,
        );
        assert_eq!(grid.v[0], 0.0);
        assert!((grid.v[1] - 0.3).abs() < 1e-12, "{}", grid.v[1]);
        assert!((grid.omega[1] + 0.6).abs() < 1e-12);
        assert!((grid.v[2] - 0.4).abs() < 1e-12);
        // A command a hair after a grid point acts from that step, as one on it.
        let on = CommandGrid::from_held(&[0.0, 0.02, 0.1], &[0.0, 0.4, 0.4], &[0.0; 3], 0.01);
        let after =
            CommandGrid::from_held(&[0.0, 0.02 + 1e-12, 0.1], &[0.0, 0.4, 0.4], &[0.0; 3], 0.01);
        assert!(on.v.iter().zip(&after.v).all(|(a, b)| (a - b).abs() < 1e-9));
    }

    fn drive(model: &UnicycleModel, grid: &CommandGrid) -> Pose {
        let executed = model.execute(grid);
        model.integrate(grid, &executed, Pose::default(), 0, grid.len())
    }

    #[test]
    fn a_point_ahead_of_the_axle_swings_on_a_circle_when_the_robot_turns_in_place() {
        let model =
            UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::TurnCentreOffset {
                forward_m: 0.1,
                left_m: 0.0,
            })]);
        // Half a turn in place: the point 0.1 m ahead ends 0.2 m behind
        // where it started, facing back.
        let end = drive(&model, &straight(std::f64::consts::PI, 0.0, 1.0));
        assert!((end.x + 0.2).abs() < 1e-3 && end.y.abs() < 1e-3, "{end:?}");
        assert!(
            (end.theta.abs() - std::f64::consts::PI).abs() < 0.01,
            "{end:?}"
        );
        // Driving straight it changes nothing.
        let grid = straight(2.0, 0.5, 0.0);
        assert_eq!(drive(&model, &grid), drive(&UnicycleModel::plain(), &grid));
    }

    #[test]
    fn a_forward_euler_step_drives_where_a_simulator_stepping_so_does() {
        // A simulator's forward Euler: each 0.1 s step drives along the
        // heading the step started with, then turns.
        let (v, omega, step) = (0.5, 1.0, 0.1);
        let mut euler = Pose::default();
        for _ in 0..20 {
            euler.x += v * euler.theta.cos() * step;
            euler.y += v * euler.theta.sin() * step;
            euler.theta += omega * step;
        }
        let grid = straight(2.0, v, omega);
        let stepped = drive(
            &UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::EulerStep {
                seconds: step,
                longest_s: 0.5,
            })]),
            &grid,
        );
        let plain = drive(&UnicycleModel::plain(), &grid);
        let off = |p: &Pose| (p.x - euler.x).hypot(p.y - euler.y);
        // The plain body ends 5 cm from the simulator's, the stepped one
        // within the 5 mm of the grid's one more step (the grid holds the
        // last command a step longer) and the step taken to first order.
        assert!(off(&plain) > 0.04, "plain {plain:?}, Euler {euler:?}");
        assert!(
            off(&stepped) < 0.007,
            "stepped {stepped:?}, Euler {euler:?}"
        );
    }

    #[test]
    fn a_crabbing_body_drives_at_its_angle_to_its_heading_and_turns_as_it_would() {
        let model = UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::CrabAngle {
            rad: -0.1,
        })]);
        // Two metres ahead, facing east: 0.2 m to the right of the heading.
        let end = drive(&model, &straight(4.0, 0.5, 0.0));
        let plain = drive(&UnicycleModel::plain(), &straight(4.0, 0.5, 0.0));
        let along = plain.x;
        assert!(
            (end.x - along * 0.1f64.cos()).abs() < 1e-9
                && (end.y + along * 0.1f64.sin()).abs() < 1e-9,
            "{end:?}"
        );
        // Turning in place it turns as the plain body does.
        let turn = straight(1.0, 0.0, 1.0);
        assert_eq!(drive(&model, &turn), drive(&UnicycleModel::plain(), &turn));
    }

    #[test]
    fn a_speed_limit_clamps_faster_commands_and_leaves_slower_ones() {
        let limited = UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::SpeedLimit {
            pace_s_per_m: 1.0 / 0.22,
        })]);
        // Commanded 0.5 m/s, it drives as the plain body commanded 0.22.
        let fast = drive(&limited, &straight(4.0, 0.5, 0.0));
        let top = drive(&UnicycleModel::plain(), &straight(4.0, 0.22, 0.0));
        assert!(
            (fast.x - top.x).abs() < 1e-9 && top.x > 0.8,
            "{fast:?} {top:?}"
        );
        // At 0.2 m/s, below it, as the plain body.
        let slow = straight(4.0, 0.2, 0.3);
        assert_eq!(
            drive(&limited, &slow),
            drive(&UnicycleModel::plain(), &slow)
        );
        // No limit at the plain model's pace.
        assert_eq!(crate::effects::top_speed(0.0), f64::INFINITY);
    }

    #[test]
    fn a_simulators_step_is_bounded_by_how_often_it_published_poses() {
        let step = Effect::identity("euler_step", [0.0; 4]).expect("a kind");
        assert_eq!(
            step.within_pose_period(0.01).ranges(),
            vec![(-0.015, 0.015)]
        );
        assert_eq!(step.within_pose_period(2.0).ranges(), vec![(-0.5, 0.5)]);
        let speed = Effect::SpeedScale { factor: 1.0 };
        assert_eq!(speed.within_pose_period(0.01), speed);
    }

    #[test]
    fn the_plain_model_drives_a_circle_exactly() {
        let grid = straight(std::f64::consts::PI, 0.5, 1.0);
        let end = drive(&UnicycleModel::plain(), &grid);
        // Half a circle of radius 0.5 m ends 1 m to the left, heading back
        // (the grid holds the last command for up to one more step).
        assert!(end.x.abs() < 0.005 && (end.y - 1.0).abs() < 1e-3, "{end:?}");
    }

    #[test]
    fn turning_costs_speed_and_driving_straight_does_not() {
        let model =
            UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::TurnSpeedLoss {
                per_rad_per_s: 0.5,
            })]);
        let straight_on = model.execute(&straight(2.0, 0.2, 0.0));
        assert_eq!(straight_on.v[100], 0.2);
        let turning = model.execute(&straight(2.0, 0.2, 0.4));
        assert!(
            (turning.v[100] - 0.2 * 0.8).abs() < 1e-12,
            "{}",
            turning.v[100]
        );
        let backwards_turn = model.execute(&straight(2.0, 0.2, -0.4));
        assert_eq!(backwards_turn.v[100], turning.v[100]);
    }

    #[test]
    fn a_play_in_the_steering_is_remembered_across_consecutive_stretches() {
        // Play holds the turn rate until the command next changes, however
        // long ago: stretches predicted one after another must carry that
        // state, as one long prediction does.
        let model = UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::Hysteresis {
            play_rad_per_s: 0.1,
        })]);
        let grid =
            CommandGrid::from_held(&[0.0, 1.0, 6.0], &[0.2, 0.2, 0.2], &[0.0, 0.5, 0.5], 0.01);
        let stretches: Vec<(Pose, usize, usize)> = (0..6)
            .map(|k| (Pose::default(), k * 100, (k + 1) * 100))
            .collect();
        // One call over consecutive stretches: the last one turns at the
        // held 0.4 rad/s, as the whole run does.
        let carried = model.predict_stretches(&grid, stretches.iter().copied(), 0);
        assert!((carried[5].theta - 0.4).abs() < 1e-9, "{:?}", carried[5]);
        // The last stretch alone, without warm-up, cannot know the play
        // and turns at the commanded 0.5.
        let alone = model.predict_stretches(&grid, [stretches[5]], 0);
        assert!((alone[0].theta - 0.5).abs() < 1e-9, "{:?}", alone[0]);
    }

    #[test]
    fn effects_change_the_motion_as_named() {
        let grid = straight(10.0, 0.2, 0.0);
        let plain = drive(&UnicycleModel::plain(), &grid);
        let scaled = drive(
            &UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::SpeedScale {
                factor: 0.9,
            })]),
            &grid,
        );
        assert!((scaled.x - 0.9 * plain.x).abs() < 1e-9);
        let drifting = drive(
            &UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::HeadingDrift {
                rad_per_m: 0.1,
            })]),
            &grid,
        );
        assert!(
            (drifting.theta - 0.1 * plain.x).abs() < 1e-3,
            "{drifting:?}"
        );
        let late = UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::Latency {
            seconds: 0.5,
        })]);
        let executed = late.execute(&straight(2.0, 0.2, 0.0));
        assert_eq!(executed.v[10], 0.0, "nothing happens before the latency");
        assert_eq!(executed.v[60], 0.2);
        let inert = UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::AccelLimit {
            m_per_s2: 0.1,
        })]);
        let executed = inert.execute(&straight(2.0, 0.2, 0.0));
        assert!((executed.v[99] - 0.1).abs() < 1e-9, "{}", executed.v[99]);
    }

    #[test]
    fn an_effect_scoped_to_a_span_acts_only_there() {
        let grid = straight(10.0, 0.2, 0.0);
        let model = UnicycleModel::with_effects(vec![ScopedEffect {
            effect: Effect::SpeedScale { factor: 0.5 },
            during: Some([5.0, 10.0]),
        }]);
        let executed = model.execute(&grid);
        assert_eq!(executed.v[100], 0.2);
        assert_eq!(executed.v[700], 0.1);
    }

    #[test]
    fn a_model_file_round_trips_and_bad_values_name_the_line() {
        let model = UnicycleModel::with_effects(vec![
            ScopedEffect::always(Effect::Latency { seconds: 0.18 }),
            ScopedEffect {
                effect: Effect::SurfaceZone {
                    region: [1.0, 1.0, 2.0, 2.0],
                    speed_factor: 0.7,
                    turn_factor: 0.9,
                },
                during: Some([10.0, 20.0]),
            },
        ]);
        let text = model.to_toml().expect("a model writes as TOML");
        assert_eq!(UnicycleModel::from_toml(&text, "m.toml").ok(), Some(model));
        let bad = "[[effects]]\nkind = \"latency\"\nseconds = 0.1\n\n[[effects]]\nkind = \"speed_scale\"\nfactor = -3.0\n";
        let error = UnicycleModel::from_toml(bad, "m.toml").expect_err("negative scale");
        assert_eq!(error.line, Some(5), "{error}");
        // Files written before zones slowed turning still load, turning as commanded.
        let older = "[[effects]]\nkind = \"surface_zone\"\nregion = [0.0, 0.0, 1.0, 1.0]\nspeed_factor = 0.5\n";
        let loaded = UnicycleModel::from_toml(older, "m.toml").expect("older zone");
        assert_eq!(
            loaded.effects[0].effect.params(),
            vec![("speed_factor", 0.5), ("turn_factor", 1.0)]
        );
        let unknown = "[[effects]]\nkind = \"teleport\"\n";
        let error = UnicycleModel::from_toml(unknown, "m.toml").expect_err("unknown kind");
        assert!(error.to_string().contains("teleport"), "{error}");
    }
}

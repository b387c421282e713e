//! Synthetic runs with known physics: a wheeled body driven by the same
//! [`UnicycleModel`] as the simulator, with motion noise, observed by a
//! motion-capture system. Used to prove that diagnosis finds what it should
//! and nothing else.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use shoal_physics::{Actuators, CommandGrid, Pose, UnicycleModel, wrap_angle};

use shoal_diagnose::recording::{Commands, Poses, Recording};

#[derive(Clone, Debug)]
pub struct Settings {
    pub duration_s: f64,
    pub command_hz: f64,
    pub pose_hz: f64,
    /// The operator keeps the robot inside [-half, half] square metres.
    pub arena_half_m: f64,
    pub max_speed: f64,
    pub max_turn: f64,
    /// Motion noise: random walk in distance (m per sqrt s) and heading (rad per sqrt s).
    pub along_noise: f64,
    pub turn_noise: f64,
    /// Motion-capture noise per observation.
    pub observation_noise_m: f64,
    pub observation_noise_rad: f64,
    /// Where the operator turns rather than drives straight (a confound).
    pub turn_inside: Option<[f64; 4]>,
    /// Coloured motion noise, which diagnosis does not assume: each term an
    /// Ornstein-Uhlenbeck process added to the executed speed and turn rate.
    pub coloured: Vec<ColouredNoise>,
    /// Share of motion-capture frames lost.
    pub dropout: f64,
    /// Standard deviation of the observation timestamps' error, seconds.
    pub timestamp_jitter_s: f64,
    /// Share of frames that are gross outliers (a marker swap: 5-30 cm off).
    pub outliers: f64,
    /// How the operator chooses commands.
    pub operator: Operator,
    /// How the motion noise depends on the motion.
    pub noise_law: NoiseLaw,
    pub seed: u64,
}

/// How the operator chooses commands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Operator {
    /// Random speeds and turn rates, each held for 0.5-3 s, with pauses: the
    /// bench's own.
    Held,
    /// A waypoint follower, as a navigation stack drives: it steers to
    /// random points of the arena with a proportional controller, slows down
    /// to turn and to arrive, and sends a new command every message, so
    /// speed and turn rate are never held and always move together. It
    /// steers on where the body is, so its commands respond to the motion
    /// noise (closed loop), as a navigation stack's do.
    Waypoints,
    /// The same waypoint follower steering on where its commands alone
    /// would have taken the body (dead reckoning without noise): its
    /// commands never respond to the motion noise (open loop). Beside
    /// `Waypoints` it shows what a controller's feedback does to diagnosis.
    WaypointsOpenLoop,
}

/// How motion noise depends on the motion. Diagnosis assumes `Constant`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum NoiseLaw {
    /// A random walk in time, moving or not.
    Constant,
    /// Wheel slip: no noise standing still; along the heading it grows with
    /// speed, in heading with speed and turn rate together.
    WhileMoving,
    /// Noise that grows with speed alone, in both components: a robot
    /// turning on the spot turns exactly.
    SpeedOnly,
}

impl NoiseLaw {
    /// Factors on the along and turn noise's standard deviations at
    /// executed speed `v` and turn rate `omega`; 1 at half the top speed
    /// (and half the top turn rate), so every law is about as noisy where
    /// the robot usually drives.
    fn factors(self, v: f64, omega: f64, settings: &Settings) -> [f64; 2] {
        let speed = 2.0 * v.abs() / settings.max_speed;
        let turn = 2.0 * omega.abs() / settings.max_turn;
        match self {
            NoiseLaw::Constant => [1.0, 1.0],
            NoiseLaw::WhileMoving => [speed, 0.5 * (speed + turn)],
            NoiseLaw::SpeedOnly => [speed, speed],
        }
    }
}

/// One Ornstein-Uhlenbeck term of motion noise: correlated over
/// `time_constant_s`, with these stationary standard deviations.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ColouredNoise {
    pub time_constant_s: f64,
    pub along_m_per_s: f64,
    pub turn_rad_per_s: f64,
}

impl ColouredNoise {
    /// The value after `dt`, from `now`, drawing with `unit` normals.
    fn step(&self, now: [f64; 2], dt: f64, unit: [f64; 2]) -> [f64; 2] {
        let decay = (-dt / self.time_constant_s).exp();
        let spread = (1.0 - decay * decay).sqrt();
        [
            now[0] * decay + self.along_m_per_s * spread * unit[0],
            now[1] * decay + self.turn_rad_per_s * spread * unit[1],
        ]
    }
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            duration_s: 600.0,
            command_hz: 50.0,
            pose_hz: 67.0,
            arena_half_m: 2.5,
            max_speed: 0.3,
            max_turn: 0.8,
            along_noise: 0.01,
            turn_noise: 0.02,
            observation_noise_m: 0.002,
            observation_noise_rad: 0.005,
            turn_inside: None,
            coloured: Vec::new(),
            dropout: 0.0,
            timestamp_jitter_s: 0.0,
            outliers: 0.0,
            operator: Operator::Held,
            noise_law: NoiseLaw::Constant,
            seed: 1,
        }
    }
}

/// The physics' own step: finer than any command rate.
const BODY_DT: f64 = 0.005;

fn inside(region: &[f64; 4], pose: &Pose) -> bool {
    pose.x >= region[0] && pose.x <= region[2] && pose.y >= region[1] && pose.y <= region[3]
}

/// What the operator is doing between commands.
#[derive(Default)]
struct OperatorState {
    /// The command held, and until when.
    v: f64,
    omega: f64,
    hold_until: f64,
    /// The waypoint follower's goal and the share of top speed it drives
    /// there at.
    goal: Option<(f64, f64, f64)>,
}

/// Within this of its goal the waypoint follower has arrived.
const ARRIVED_M: f64 = 0.15;

impl OperatorState {
    /// The bench's operator: random commands held 0.5-3 s, pauses, and a
    /// way home from outside the arena.
    fn held(&mut self, pose: &Pose, t: f64, settings: &Settings, rng: &mut StdRng) -> (f64, f64) {
        if t < self.hold_until {
            return (self.v, self.omega);
        }
        let half = settings.arena_half_m;
        let outside = pose.x.abs() > half || pose.y.abs() > half;
        let turning_zone = settings.turn_inside.is_some_and(|r| inside(&r, pose));
        if outside {
            let home = (-pose.y).atan2(-pose.x);
            self.v = 0.5 * settings.max_speed;
            self.omega =
                (2.0 * wrap_angle(home - pose.theta)).clamp(-settings.max_turn, settings.max_turn);
            self.hold_until = t + 0.5;
        } else if rng.random_bool(0.1) {
            (self.v, self.omega) = (0.0, 0.0);
            self.hold_until = t + rng.random_range(0.5..2.0);
        } else {
            self.v = rng.random_range(0.05..1.0) * settings.max_speed;
            self.omega = rng.random_range(-1.0..1.0) * settings.max_turn;
            if turning_zone {
                self.omega = self.omega.signum() * settings.max_turn;
            }
            self.hold_until = t + rng.random_range(0.5..3.0);
        }
        (self.v, self.omega)
    }

    /// A waypoint follower: steer to the goal in proportion to the heading
    /// error, slow down to turn and to arrive, pause now and then at a goal.
    fn waypoints(
        &mut self,
        pose: &Pose,
        t: f64,
        settings: &Settings,
        rng: &mut StdRng,
    ) -> (f64, f64) {
        if t < self.hold_until {
            return (0.0, 0.0);
        }
        let arrived = self
            .goal
            .is_none_or(|(x, y, _)| (x - pose.x).hypot(y - pose.y) < ARRIVED_M);
        if arrived {
            let reach = 0.9 * settings.arena_half_m;
            self.goal = Some((
                rng.random_range(-reach..reach),
                rng.random_range(-reach..reach),
                rng.random_range(0.3..1.0),
            ));
            if rng.random_bool(0.2) {
                self.hold_until = t + rng.random_range(0.5..2.0);
                return (0.0, 0.0);
            }
        }
        let Some((x, y, share)) = self.goal else {
            return (0.0, 0.0);
        };
        let error = wrap_angle((y - pose.y).atan2(x - pose.x) - pose.theta);
        let distance = (x - pose.x).hypot(y - pose.y);
        let omega = (1.5 * error).clamp(-settings.max_turn, settings.max_turn);
        let v =
            share * settings.max_speed * error.cos().max(0.0).powi(2) * (distance / 0.6).min(1.0);
        (v, omega)
    }
}

/// The speed and turn rate the body makes of the executed `(v, omega)`
/// at run time `t`: white and coloured motion noise (`colour` holds each
/// coloured term's state), scaled by the noise law and the model's
/// multiplier.
fn with_noise(
    truth: &UnicycleModel,
    settings: &Settings,
    (ev, eomega, t): (f64, f64, f64),
    colour: &mut [[f64; 2]],
    rng: &mut StdRng,
) -> (f64, f64) {
    let unit = StandardNormal;
    let m = truth.noise_multiplier(ev, t).sqrt();
    let [along_law, turn_law] = settings.noise_law.factors(ev, eomega, settings);
    let (mut coloured_v, mut coloured_omega) = (0.0, 0.0);
    for (term, now) in settings.coloured.iter().zip(colour.iter_mut()) {
        let draws: [f64; 2] = [unit.sample(rng), unit.sample(rng)];
        *now = term.step(*now, BODY_DT, draws);
        coloured_v += now[0];
        coloured_omega += now[1];
    }
    let white_v: f64 = unit.sample(rng);
    let noisy_v =
        ev + m * along_law * (settings.along_noise * white_v / BODY_DT.sqrt() + coloured_v);
    let white_omega: f64 = unit.sample(rng);
    let noisy_omega = eomega
        + m * turn_law * (settings.turn_noise * white_omega / BODY_DT.sqrt() + coloured_omega);
    (noisy_v, noisy_omega)
}

/// Motion capture's observation of `pose` at `at` seconds: jittered stamp,
/// noise, now and then a marker swap or a dropped frame.
// 3.14, not PI: the range every seeded run was drawn from; PI would
// redraw every run the experiments' figures were measured on.
#[allow(clippy::approx_constant)]
fn observe(pose: &Pose, at: f64, settings: &Settings, observed: &mut Poses, rng: &mut StdRng) {
    let unit = StandardNormal;
    let jitter: f64 = unit.sample(rng);
    let stamp = at + settings.timestamp_jitter_s * jitter;
    let (nx, ny): (f64, f64) = (unit.sample(rng), unit.sample(rng));
    let (mut x, mut y) = (
        pose.x + settings.observation_noise_m * nx,
        pose.y + settings.observation_noise_m * ny,
    );
    if settings.outliers > 0.0 && rng.random_bool(settings.outliers) {
        let (off, angle) = (rng.random_range(0.05..0.3), rng.random_range(-3.14..3.14));
        x += off * f64::cos(angle);
        y += off * f64::sin(angle);
    }
    let dropped = settings.dropout > 0.0 && rng.random_bool(settings.dropout);
    // Jittered stamps may fall out of order; a real logger keeps order.
    if !dropped && observed.t.last().is_none_or(|&last| stamp > last) {
        let heading_noise: f64 = unit.sample(rng);
        observed.push(
            stamp,
            x,
            y,
            pose.theta + settings.observation_noise_rad * heading_noise,
        );
    }
}

/// Drives `truth` for `settings.duration_s` and returns what was commanded and observed.
// 3.14, not PI: the range every seeded run was drawn from; PI would
// redraw every run the experiments' figures were measured on.
#[allow(clippy::approx_constant)]
pub fn generate(truth: &UnicycleModel, settings: &Settings) -> Recording {
    let mut rng = StdRng::seed_from_u64(settings.seed);
    let steps = (settings.duration_s / BODY_DT) as usize;
    let command_every = ((1.0 / settings.command_hz) / BODY_DT).round().max(1.0) as usize;
    let pose_every = 1.0 / settings.pose_hz;

    // The operator picks commands from where the robot truly is, so the
    // commands must be chosen while the body moves.
    let mut commanded = Commands::default();
    let mut observed = Poses::default();
    let mut pose = Pose::new(0.0, 0.0, rng.random_range(-3.14..3.14));
    let mut operator = OperatorState::default();
    // Where the commands alone take the body: what an open-loop operator sees.
    let mut plan = pose;
    let (mut v, mut omega) = (0.0, 0.0);
    let mut actuators = Actuators::default();
    let mut next_observation = rng.random_range(0.0..pose_every);
    let mut colour = vec![[0.0; 2]; settings.coloured.len()];
    // The body executes on its own fine grid, extended as commands arrive.
    let mut grid = CommandGrid {
        t0: 0.0,
        dt: BODY_DT,
        v: Vec::with_capacity(steps),
        omega: Vec::with_capacity(steps),
    };
    for i in 0..steps {
        let t = i as f64 * BODY_DT;
        if i % command_every == 0 {
            (v, omega) = match settings.operator {
                Operator::Held => operator.held(&pose, t, settings, &mut rng),
                Operator::Waypoints => operator.waypoints(&pose, t, settings, &mut rng),
                Operator::WaypointsOpenLoop => operator.waypoints(&plan, t, settings, &mut rng),
            };
            commanded.t.push(t);
            commanded.v.push(v);
            commanded.omega.push(omega);
        }
        grid.v.push(v);
        grid.omega.push(omega);
        let (ev, eomega) = actuators.execute(truth, &grid, i);
        let (noisy_v, noisy_omega) =
            with_noise(truth, settings, (ev, eomega, t), &mut colour, &mut rng);
        pose = truth.step(pose, noisy_v, noisy_omega, t, BODY_DT);
        plan = truth.step(plan, ev, eomega, t, BODY_DT);
        while next_observation <= t + BODY_DT {
            observe(&pose, next_observation, settings, &mut observed, &mut rng);
            next_observation += pose_every;
        }
    }
    Recording::from_absolute(commanded, observed)
}

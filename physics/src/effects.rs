//! The library of physical effects a wheeled body can have and a simulation
//! model can leave out. Each is a small parametric term; the identity value
//! of every parameter is the plain unicycle.

use serde::{Deserialize, Serialize};

/// One physical effect with its parameters, named as `shoal diagnose` reports them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Effect {
    /// Commands take effect this late.
    Latency { seconds: f64 },
    /// Speed and turn rate follow the command as a first-order lag with
    /// this time constant (motor and controller dynamics).
    ActuatorLag { seconds: f64 },
    /// Forward speed is this multiple of the command.
    SpeedScale { factor: f64 },
    /// Turn rate is this multiple of the command.
    TurnScale { factor: f64 },
    /// A constant turn rate added to every command.
    TurnBias { rad_per_s: f64 },
    /// Heading turns by this much per metre driven (unequal wheels).
    HeadingDrift { rad_per_m: f64 },
    /// Forward speed cannot change faster than this (inertia).
    AccelLimit { m_per_s2: f64 },
    /// Forward speed never exceeds a top speed: faster commands are
    /// clamped (a controller's velocity limit, a robot's firmware). Given
    /// as its inverse, the top speed's pace in seconds per metre, so that
    /// the plain model (no limit) is 0 and a fit changes it smoothly.
    SpeedLimit { pace_s_per_m: f64 },
    /// The fraction of speed lost grows with speed: v (1 - k |v|).
    Slip { per_m_per_s: f64 },
    /// Speed and turn gain lose this fraction per minute since the start.
    BatteryFade { per_minute: f64 },
    /// Inside the region [xmin, ymin, xmax, ymax] speed and turn rate are
    /// multiplied by their factors (mud, carpet, a ramp: a soft floor slows
    /// turning as well as driving). Model files written before the turn
    /// factor existed load with turning unchanged.
    SurfaceZone {
        region: [f64; 4],
        speed_factor: f64,
        #[serde(default = "unchanged")]
        turn_factor: f64,
    },
    /// A constant drift in the world frame (slope, current, wind), m/s.
    ExternalFlow { vx: f64, vy: f64 },
    /// Play in the steering: the executed turn rate only follows the command
    /// once it differs by more than this (backlash; depends on history).
    Hysteresis { play_rad_per_s: f64 },
    /// Motion noise grows with speed: at `at_m_per_s` (the robot's usual
    /// speed) this share of its variance comes from driving, the rest is
    /// there standing still. At rest the variance is the plain model's, at
    /// speed v it is `1 + share / (1 - share) * (v / at_m_per_s)^exponent`
    /// times that. The exponent is one of the two laws bodies follow
    /// ([`SPEED_NOISE_EXPONENTS`]), chosen by the likelihood, not fitted:
    /// noise that accrues per metre driven (a random walk in distance)
    /// grows the variance linearly (1), wheel noise in proportion to wheel
    /// speed (as the odometry models of Thrun et al. assume) with speed
    /// squared (2). A share in [0, 1) cannot run away as a per-m/s
    /// coefficient does on a slow robot, and says what it means at the
    /// robot's speed.
    SpeedNoise {
        driving_share: f64,
        #[serde(default = "per_metre")]
        exponent: f64,
        at_m_per_s: f64,
    },
    /// Forward speed drops while turning: v (1 - k |omega|). A differential
    /// drive whose wheels scrub, or whose controller slows both wheels to
    /// keep the outer one within its limit, loses speed in every turn.
    TurnSpeedLoss { per_rad_per_s: f64 },
    /// The point whose pose is observed (a motion-capture marker, the
    /// robot's frame origin) lies `forward_m` ahead of and `left_m` to the
    /// left of the point the robot turns about (the middle of a
    /// differential drive's axle): in every turn it swings sideways by
    /// `forward_m` and back by `left_m` per radian.
    TurnCentreOffset { forward_m: f64, left_m: f64 },
    /// The body moves `rad` to the left of the heading observed (right
    /// when negative), sideways at speed times its sine: a motion-capture
    /// body or a frame whose heading was set askew of the robot's, or
    /// wheels that crab. The two are the same in poses.
    CrabAngle { rad: f64 },
    /// The observed body moves as one a simulator steps by Euler every
    /// `seconds`. Forward Euler (`seconds` > 0) drives each step along the
    /// heading the step started with, so in every turn the path slips to
    /// the inside by half a step's turn, sideways at speed times turn rate
    /// times half the step; semi-implicit Euler (the turn first, then the
    /// step along the new heading: `seconds` < 0) slips to the outside as
    /// much. What a simulator so integrating records is the recording's
    /// integration, not physics (`shoal diagnose` says it apart from the
    /// effects). A simulator's state changes once a step, so it publishes
    /// poses at most once a step: `longest_s`, from the recording's pose
    /// period, bounds the step either way (not fitted). Without the bound
    /// a real robot filmed every 10 ms (MRCLAM's robot 3) was taken for a
    /// simulator stepping every 0.26 s (EXPERIMENTS.md 5c).
    EulerStep {
        seconds: f64,
        #[serde(default = "longest_step")]
        longest_s: f64,
    },
}

/// The top speed of a speed limit's pace; infinite for no limit.
pub fn top_speed(pace_s_per_m: f64) -> f64 {
    if pace_s_per_m > 0.0 {
        1.0 / pace_s_per_m
    } else {
        f64::INFINITY
    }
}

fn unchanged() -> f64 {
    1.0
}

/// Speed noise written before it had an exponent grew linearly: the first
/// law, the identity's.
fn per_metre() -> f64 {
    SPEED_NOISE_EXPONENTS[0]
}

/// The laws of speed-dependent noise tried: variance growing as speed
/// (noise per metre driven) and as its square (noise in proportion to wheel
/// speed). A fitted exponent was tried first: on a real robot's stretch
/// (MRCLAM robot 3, the third of four blocks) it went to 3, the mismatch
/// still unnamed taken for noise, and the weights it gave the held-out
/// blocks refused every effect there (EXPERIMENTS.md 5c, "Laps"). The
/// first is the law [`Effect::identity`] starts from.
pub const SPEED_NOISE_EXPONENTS: [f64; 2] = [1.0, 2.0];

/// A simulator stepping slower than 2 Hz is not simulating a robot.
fn longest_step() -> f64 {
    0.5
}

/// The kinds, in the order `shoal diagnose` tries them.
pub const EFFECT_KINDS: [&str; 18] = [
    "latency",
    "actuator_lag",
    "speed_scale",
    "turn_scale",
    "turn_bias",
    "heading_drift",
    "accel_limit",
    "speed_limit",
    "slip",
    "battery_fade",
    "surface_zone",
    "external_flow",
    "hysteresis",
    "speed_noise",
    "turn_speed_loss",
    "turn_centre_offset",
    "crab_angle",
    "euler_step",
];

impl Effect {
    /// The law an effect follows where its kind has several, different
    /// physics rather than variants of one (speed-dependent noise: the
    /// power of speed its variance grows as, [`SPEED_NOISE_EXPONENTS`]);
    /// none where the kind has one.
    pub fn law(&self) -> Option<f64> {
        match *self {
            Effect::SpeedNoise { exponent, .. } => Some(exponent),
            _ => None,
        }
    }

    /// Whether the effect changes only how noisy motion is, not where the
    /// robot is predicted to go.
    pub fn only_noise(&self) -> bool {
        matches!(self, Effect::SpeedNoise { .. })
    }

    /// Whether the effect is how the recording was made (a simulator's
    /// integration step), not the body's physics.
    pub fn of_the_recording(&self) -> bool {
        matches!(self, Effect::EulerStep { .. })
    }

    pub fn kind(&self) -> &'static str {
        match self {
            Effect::Latency { .. } => "latency",
            Effect::ActuatorLag { .. } => "actuator_lag",
            Effect::SpeedScale { .. } => "speed_scale",
            Effect::TurnScale { .. } => "turn_scale",
            Effect::TurnBias { .. } => "turn_bias",
            Effect::HeadingDrift { .. } => "heading_drift",
            Effect::AccelLimit { .. } => "accel_limit",
            Effect::SpeedLimit { .. } => "speed_limit",
            Effect::Slip { .. } => "slip",
            Effect::BatteryFade { .. } => "battery_fade",
            Effect::SurfaceZone { .. } => "surface_zone",
            Effect::ExternalFlow { .. } => "external_flow",
            Effect::Hysteresis { .. } => "hysteresis",
            Effect::SpeedNoise { .. } => "speed_noise",
            Effect::TurnSpeedLoss { .. } => "turn_speed_loss",
            Effect::TurnCentreOffset { .. } => "turn_centre_offset",
            Effect::CrabAngle { .. } => "crab_angle",
            Effect::EulerStep { .. } => "euler_step",
        }
    }

    /// The fitted parameters as (name, value), in a fixed order. The region
    /// of a surface zone is located, not fitted, so it is not among them.
    pub fn params(&self) -> Vec<(&'static str, f64)> {
        match *self {
            Effect::Latency { seconds }
            | Effect::ActuatorLag { seconds }
            | Effect::EulerStep { seconds, .. } => {
                vec![("seconds", seconds)]
            }
            Effect::SpeedScale { factor } => vec![("factor", factor)],
            Effect::TurnScale { factor } => vec![("factor", factor)],
            Effect::TurnBias { rad_per_s } => vec![("rad_per_s", rad_per_s)],
            Effect::HeadingDrift { rad_per_m } => vec![("rad_per_m", rad_per_m)],
            Effect::AccelLimit { m_per_s2 } => vec![("m_per_s2", m_per_s2)],
            Effect::SpeedLimit { pace_s_per_m } => vec![("pace_s_per_m", pace_s_per_m)],
            Effect::Slip { per_m_per_s } => vec![("per_m_per_s", per_m_per_s)],
            Effect::BatteryFade { per_minute } => vec![("per_minute", per_minute)],
            Effect::SurfaceZone {
                speed_factor,
                turn_factor,
                ..
            } => vec![("speed_factor", speed_factor), ("turn_factor", turn_factor)],
            Effect::ExternalFlow { vx, vy } => vec![("vx", vx), ("vy", vy)],
            Effect::Hysteresis { play_rad_per_s } => vec![("play_rad_per_s", play_rad_per_s)],
            Effect::SpeedNoise { driving_share, .. } => vec![("driving_share", driving_share)],
            Effect::TurnSpeedLoss { per_rad_per_s } => vec![("per_rad_per_s", per_rad_per_s)],
            Effect::TurnCentreOffset { forward_m, left_m } => {
                vec![("forward_m", forward_m), ("left_m", left_m)]
            }
            Effect::CrabAngle { rad } => vec![("rad", rad)],
        }
    }

    /// The same effect with its fitted parameters replaced by `values`
    /// (as many as [`Effect::params`] returns).
    pub fn with_params(&self, values: &[f64]) -> Effect {
        let v = |i: usize| values.get(i).copied().unwrap_or(f64::NAN);
        match *self {
            Effect::Latency { .. } => Effect::Latency { seconds: v(0) },
            Effect::ActuatorLag { .. } => Effect::ActuatorLag { seconds: v(0) },
            Effect::SpeedScale { .. } => Effect::SpeedScale { factor: v(0) },
            Effect::TurnScale { .. } => Effect::TurnScale { factor: v(0) },
            Effect::TurnBias { .. } => Effect::TurnBias { rad_per_s: v(0) },
            Effect::HeadingDrift { .. } => Effect::HeadingDrift { rad_per_m: v(0) },
            Effect::AccelLimit { .. } => Effect::AccelLimit { m_per_s2: v(0) },
            Effect::SpeedLimit { .. } => Effect::SpeedLimit { pace_s_per_m: v(0) },
            Effect::Slip { .. } => Effect::Slip { per_m_per_s: v(0) },
            Effect::BatteryFade { .. } => Effect::BatteryFade { per_minute: v(0) },
            Effect::SurfaceZone { region, .. } => Effect::SurfaceZone {
                region,
                speed_factor: v(0),
                turn_factor: v(1),
            },
            Effect::ExternalFlow { .. } => Effect::ExternalFlow { vx: v(0), vy: v(1) },
            Effect::Hysteresis { .. } => Effect::Hysteresis {
                play_rad_per_s: v(0),
            },
            Effect::SpeedNoise {
                exponent,
                at_m_per_s,
                ..
            } => Effect::SpeedNoise {
                driving_share: v(0),
                exponent,
                at_m_per_s,
            },
            Effect::TurnSpeedLoss { .. } => Effect::TurnSpeedLoss {
                per_rad_per_s: v(0),
            },
            Effect::TurnCentreOffset { .. } => Effect::TurnCentreOffset {
                forward_m: v(0),
                left_m: v(1),
            },
            Effect::CrabAngle { .. } => Effect::CrabAngle { rad: v(0) },
            Effect::EulerStep { longest_s, .. } => Effect::EulerStep {
                seconds: v(0),
                longest_s,
            },
        }
    }

    /// The effect of `kind` at its identity (the plain model), or `None` for
    /// an unknown kind. A surface zone needs a region, given here.
    pub fn identity(kind: &str, region: [f64; 4]) -> Option<Effect> {
        Some(match kind {
            "latency" => Effect::Latency { seconds: 0.0 },
            "actuator_lag" => Effect::ActuatorLag { seconds: 0.0 },
            "speed_scale" => Effect::SpeedScale { factor: 1.0 },
            "turn_scale" => Effect::TurnScale { factor: 1.0 },
            "turn_bias" => Effect::TurnBias { rad_per_s: 0.0 },
            "heading_drift" => Effect::HeadingDrift { rad_per_m: 0.0 },
            "accel_limit" => Effect::AccelLimit { m_per_s2: 5.0 },
            "speed_limit" => Effect::SpeedLimit { pace_s_per_m: 0.0 },
            "slip" => Effect::Slip { per_m_per_s: 0.0 },
            "battery_fade" => Effect::BatteryFade { per_minute: 0.0 },
            "surface_zone" => Effect::SurfaceZone {
                region,
                speed_factor: 1.0,
                turn_factor: 1.0,
            },
            "external_flow" => Effect::ExternalFlow { vx: 0.0, vy: 0.0 },
            "hysteresis" => Effect::Hysteresis {
                play_rad_per_s: 0.0,
            },
            "speed_noise" => Effect::SpeedNoise {
                driving_share: 0.0,
                exponent: per_metre(),
                at_m_per_s: 1.0,
            },
            "turn_speed_loss" => Effect::TurnSpeedLoss { per_rad_per_s: 0.0 },
            "turn_centre_offset" => Effect::TurnCentreOffset {
                forward_m: 0.0,
                left_m: 0.0,
            },
            "crab_angle" => Effect::CrabAngle { rad: 0.0 },
            "euler_step" => Effect::EulerStep {
                seconds: 0.0,
                longest_s: longest_step(),
            },
            _ => return None,
        })
    }

    /// The same physics stated at another reference speed: only speed
    /// noise has one (its share of the variance from driving is a share at
    /// a speed); every other effect is returned as it is.
    pub fn at_reference_speed(&self, speed_m_per_s: f64) -> Effect {
        match *self {
            Effect::SpeedNoise { exponent, .. } if speed_m_per_s > 0.0 => {
                let growth = self.noise_growth_at(speed_m_per_s);
                Effect::SpeedNoise {
                    driving_share: growth / (1.0 + growth),
                    exponent,
                    at_m_per_s: speed_m_per_s,
                }
            }
            _ => self.clone(),
        }
    }

    /// The same effect for a recording whose poses come every `period_s`:
    /// only a simulator's step has a bound there (see
    /// [`Effect::EulerStep`]), half as long again as the period, so that
    /// a step equal to the period is fitted inside the bound, not on it;
    /// every other effect is returned as it is.
    pub fn within_pose_period(&self, period_s: f64) -> Effect {
        match *self {
            Effect::EulerStep { seconds, .. } if period_s > 0.0 => Effect::EulerStep {
                seconds,
                longest_s: (1.5 * period_s).min(longest_step()),
            },
            _ => self.clone(),
        }
    }

    /// How much the motion-noise variance has grown at `speed` m/s, as a
    /// multiple of the resting variance: `share / (1 - share) * (speed /
    /// at_m_per_s)^exponent` for speed noise, 0 for every other effect.
    pub fn noise_growth_at(&self, speed: f64) -> f64 {
        match *self {
            Effect::SpeedNoise {
                driving_share,
                exponent,
                at_m_per_s,
            } => {
                let share = driving_share.clamp(0.0, 0.999);
                share / (1.0 - share) * (speed.abs() / at_m_per_s.max(1e-3)).powf(exponent)
            }
            _ => 0.0,
        }
    }

    /// The physical range of each parameter, in the order of
    /// [`Effect::params`]. Signs are physics: a battery only loses charge,
    /// slip only loses speed, noise only grows with speed. A fit that ends
    /// on an edge is reported as unexplained, not as physics.
    pub fn ranges(&self) -> Vec<(f64, f64)> {
        match *self {
            Effect::Latency { .. } => vec![(0.0, 1.0)],
            Effect::ActuatorLag { .. } => vec![(0.0, 2.0)],
            Effect::SpeedScale { .. } | Effect::TurnScale { .. } => vec![(0.2, 5.0)],
            Effect::TurnBias { .. } => vec![(-2.0, 2.0)],
            Effect::HeadingDrift { .. } => vec![(-2.0, 2.0)],
            Effect::AccelLimit { .. } => vec![(0.01, 50.0)],
            // A top speed under 2 cm/s is a robot that does not drive.
            Effect::SpeedLimit { .. } => vec![(0.0, 50.0)],
            Effect::Slip { .. } => vec![(0.0, 3.0)],
            Effect::BatteryFade { .. } => vec![(0.0, 0.5)],
            Effect::SurfaceZone { .. } => vec![(0.05, 3.0), (0.05, 3.0)],
            Effect::ExternalFlow { .. } => vec![(-2.0, 2.0), (-2.0, 2.0)],
            Effect::Hysteresis { .. } => vec![(0.0, 2.0)],
            // At 0.99, standing still the noise is a hundredth of what it
            // is at the usual speed: anything more is not motion noise.
            Effect::SpeedNoise { .. } => vec![(0.0, 0.99)],
            // At 3 per rad/s a robot turning at 0.33 rad/s stops driving.
            Effect::TurnSpeedLoss { .. } => vec![(0.0, 3.0)],
            // Within a robot's body: a point half a metre from the axle is
            // not on a robot of the size this library is for.
            Effect::TurnCentreOffset { .. } => vec![(-0.5, 0.5), (-0.5, 0.5)],
            // A body more than 45 degrees askew is mounted wrong, not askew.
            Effect::CrabAngle { .. } => vec![(-0.8, 0.8)],
            // Never longer than the poses' period, either scheme.
            Effect::EulerStep { longest_s, .. } => vec![(-longest_s, longest_s)],
        }
    }

    /// Whether every parameter lies in its physical range.
    pub fn in_bounds(&self) -> bool {
        self.params()
            .iter()
            .zip(self.ranges())
            .all(|((_, v), (lo, hi))| (lo..=hi).contains(v))
    }

    /// One sentence for the user, stated where the robot usually drives:
    /// at `speed` m/s and `turn` rad/s, over a run of `duration_s` seconds.
    /// Effects whose size depends on speed are given as what they do there,
    /// not as a coefficient that means nothing on its own.
    pub fn sentence_at(&self, speed: f64, turn: f64, duration_s: f64) -> String {
        let percent = |fraction: f64| (fraction * 100.0).abs();
        match *self {
            Effect::SpeedScale { factor } => format!(
                "At its usual {speed:.2} m/s the robot drives {:.0}% {} than commanded, at every speed (speed scale {factor:.3}).",
                percent(1.0 - factor),
                if factor < 1.0 { "slower" } else { "faster" }
            ),
            // The body loses at most all of its speed (`unicycle`), so a
            // loss past the whole command is said as standing still.
            Effect::Slip { per_m_per_s } if per_m_per_s * speed >= 1.0 => format!(
                "At its usual {speed:.2} m/s the robot does not move: it loses speed in proportion to its speed, all of it from {:.2} m/s (slip).",
                1.0 / per_m_per_s
            ),
            Effect::Slip { per_m_per_s } => format!(
                "At its usual {speed:.2} m/s the robot drives {:.0}% slower than commanded, and the loss grows with speed ({:.0}% at {:.2} m/s) (slip).",
                percent(per_m_per_s * speed),
                percent((per_m_per_s * 2.0 * speed).min(1.0)),
                2.0 * speed
            ),
            Effect::TurnScale { factor } => format!(
                "At its usual {turn:.2} rad/s the robot turns {:.0}% {} than commanded (turn scale {factor:.3}).",
                percent(1.0 - factor),
                if factor < 1.0 { "less" } else { "more" }
            ),
            Effect::BatteryFade { per_minute } => format!(
                "Speed and turn gain fade as the run goes on: {:.1}% lost after {:.0} minutes (battery).",
                percent(per_minute * duration_s / 60.0),
                duration_s / 60.0
            ),
            Effect::SpeedNoise {
                driving_share,
                exponent,
                at_m_per_s,
            } => format!(
                "At its usual {at_m_per_s:.2} m/s, {:.0}% of the robot's motion noise variance comes from driving: that part grows as speed to the power {exponent:.0}{}, and standing still the noise is {:.2} times as large as at that speed (speed-dependent noise).",
                percent(driving_share),
                match exponent {
                    p if (0.75..1.5).contains(&p) =>
                        ", as noise that accrues per metre driven does",
                    p if (1.5..2.5).contains(&p) => ", as noise in proportion to wheel speed does",
                    _ => "",
                },
                (1.0 - driving_share).sqrt()
            ),
            Effect::TurnSpeedLoss { per_rad_per_s } => format!(
                "While turning at its usual {turn:.2} rad/s the robot drives {:.0}% slower than commanded, {:.0}% at twice that rate; driving straight it loses nothing (speed lost in turns: wheel scrub or a wheel-speed limit).",
                percent(per_rad_per_s * turn),
                percent(per_rad_per_s * 2.0 * turn)
            ),
            Effect::HeadingDrift { rad_per_m } => format!(
                "The heading drifts {:.1}° per metre driven, to the {} (unequal wheels); at its usual {speed:.2} m/s that is {:.1}° per minute.",
                rad_per_m.abs().to_degrees(),
                if rad_per_m > 0.0 { "left" } else { "right" },
                (rad_per_m * speed * 60.0).abs().to_degrees()
            ),
            _ => self.sentence(),
        }
    }

    /// One sentence for the user.
    pub fn sentence(&self) -> String {
        match *self {
            Effect::Latency { seconds } => {
                format!("Commands take effect {seconds:.2} s late (actuation latency).")
            }
            Effect::ActuatorLag { seconds } => format!(
                "Speed and turn rate follow a command with a time constant of {seconds:.2} s (first-order actuator lag)."
            ),
            Effect::SpeedScale { factor } => format!(
                "The robot drives at {:.0}% of the commanded speed (speed scale error).",
                factor * 100.0
            ),
            Effect::TurnScale { factor } => format!(
                "The robot turns at {:.0}% of the commanded rate (turn scale error).",
                factor * 100.0
            ),
            Effect::TurnBias { rad_per_s } => format!(
                "The robot turns {:.3} rad/s {} than commanded (turn bias).",
                rad_per_s.abs(),
                if rad_per_s > 0.0 {
                    "more to the left"
                } else {
                    "more to the right"
                }
            ),
            Effect::HeadingDrift { rad_per_m } => format!(
                "The heading drifts {:.3} rad per metre driven, to the {} (unequal wheels).",
                rad_per_m.abs(),
                if rad_per_m > 0.0 { "left" } else { "right" }
            ),
            Effect::AccelLimit { m_per_s2 } => {
                format!("Speed changes at most {m_per_s2:.2} m/s² (inertia).")
            }
            Effect::SpeedLimit { pace_s_per_m } => format!(
                "The robot never drives faster than {:.2} m/s: faster commands are clamped (a speed limit in its controller or firmware).",
                top_speed(pace_s_per_m)
            ),
            Effect::Slip { per_m_per_s } => format!(
                "The robot loses {:.0}% of its speed per m/s of speed (slip).",
                per_m_per_s * 100.0
            ),
            Effect::BatteryFade { per_minute } => format!(
                "Speed and turn gain fade by {:.2}% per minute (battery).",
                per_minute * 100.0
            ),
            Effect::SurfaceZone {
                region: [x0, y0, x1, y1],
                speed_factor,
                turn_factor,
            } => format!(
                "In [{x0:.1}, {y0:.1}] to [{x1:.1}, {y1:.1}] m the robot drives at {:.0}% of the commanded speed and turns at {:.0}% of the commanded rate (surface zone).",
                speed_factor * 100.0,
                turn_factor * 100.0
            ),
            Effect::ExternalFlow { vx, vy } => format!(
                "The robot drifts at ({vx:.3}, {vy:.3}) m/s in the world frame (slope, current or wind)."
            ),
            Effect::Hysteresis { play_rad_per_s } => format!(
                "The turn rate lags changes of the command by a play of {play_rad_per_s:.3} rad/s (hysteresis)."
            ),
            Effect::SpeedNoise { .. } => self.sentence_at(0.0, 0.0, 0.0),
            Effect::TurnSpeedLoss { per_rad_per_s } => format!(
                "Forward speed drops by {:.0}% per rad/s of turning (speed lost in turns).",
                per_rad_per_s * 100.0
            ),
            Effect::TurnCentreOffset { forward_m, left_m } => format!(
                "The robot turns about a point {:.0} mm {} and {:.0} mm {} of the point observed, so the observed point swings sideways in every turn (turning centre offset: the marker or frame origin is not over the axle).",
                forward_m.abs() * 1e3,
                if forward_m >= 0.0 { "behind" } else { "ahead" },
                left_m.abs() * 1e3,
                if left_m >= 0.0 {
                    "to the right"
                } else {
                    "to the left"
                }
            ),
            Effect::CrabAngle { rad } => format!(
                "The robot moves {:.1}° to the {} of the heading observed (crab angle: the observed heading is set askew of the robot's, as a motion-capture body defined askew is, or its wheels crab).",
                rad.abs().to_degrees(),
                if rad > 0.0 { "left" } else { "right" }
            ),
            Effect::EulerStep { seconds, .. } if seconds >= 0.0 => format!(
                "The poses move as a body stepped by forward Euler every {seconds:.3} s: each step drives along the heading it started with, so the path slips to the inside of every turn (a simulator's integration step: how the recording was made, not the body's physics)."
            ),
            Effect::EulerStep { seconds, .. } => format!(
                "The poses move as a body stepped by semi-implicit Euler every {:.3} s: each step turns first and drives along the heading it ends with, so the path slips to the outside of every turn (a simulator's integration step: how the recording was made, not the body's physics).",
                -seconds
            ),
        }
    }
}

/// An effect, optionally active only during `[t_start, t_end]` seconds of the run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScopedEffect {
    #[serde(flatten)]
    pub effect: Effect,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub during: Option<[f64; 2]>,
}

impl ScopedEffect {
    pub fn always(effect: Effect) -> Self {
        Self {
            effect,
            during: None,
        }
    }

    pub fn active_at(&self, t: f64) -> bool {
        self.during.is_none_or(|[a, b]| t >= a && t <= b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::UnicycleModel;

    fn multiplier(effect: &Effect, speed: f64) -> f64 {
        UnicycleModel::with_effects(vec![ScopedEffect::always(effect.clone())])
            .noise_multiplier(speed, 0.0)
    }

    #[test]
    fn speed_noise_is_the_same_physics_at_any_reference_speed() {
        let noise = Effect::SpeedNoise {
            driving_share: 0.75,
            exponent: 1.0,
            at_m_per_s: 0.5,
        };
        // Three quarters of the variance at 0.5 m/s is from driving.
        assert!((multiplier(&noise, 0.0) - 1.0).abs() < 1e-12);
        assert!((multiplier(&noise, 0.5) - 4.0).abs() < 1e-12);
        let slow = noise.at_reference_speed(0.08);
        let Effect::SpeedNoise { driving_share, .. } = slow else {
            panic!("{slow:?}");
        };
        // At 0.08 m/s the variance is 1 + 6 * 0.08 times the resting one.
        assert!((driving_share - 0.48 / 1.48).abs() < 1e-12);
        for speed in [0.0, 0.08, 0.3, 1.2] {
            assert!((multiplier(&noise, speed) - multiplier(&slow, speed)).abs() < 1e-9);
        }
        assert!(slow.in_bounds());
        // Wheel noise in proportion to wheel speed: the growth goes as its
        // square, whatever speed it is stated at.
        let wheels = Effect::SpeedNoise {
            driving_share: 0.75,
            exponent: 2.0,
            at_m_per_s: 0.5,
        };
        assert!((multiplier(&wheels, 1.0) - 13.0).abs() < 1e-12);
        let fast = wheels.at_reference_speed(1.0);
        for speed in [0.0, 0.08, 0.3, 1.2] {
            assert!((multiplier(&wheels, speed) - multiplier(&fast, speed)).abs() < 1e-9);
        }
    }

    /// A model written before the exponent was fitted grew linearly.
    #[test]
    fn speed_noise_written_without_an_exponent_grows_linearly() {
        let read: Effect =
            toml::from_str("kind = \"speed_noise\"\ndriving_share = 0.5\nat_m_per_s = 0.2")
                .expect("an older model file");
        assert_eq!(
            read,
            Effect::SpeedNoise {
                driving_share: 0.5,
                exponent: 1.0,
                at_m_per_s: 0.2,
            }
        );
    }

    /// A body whose slip takes all of its speed stands still
    /// (`unicycle`); its sentence says so, not a loss above 100%.
    #[test]
    fn a_slip_past_the_whole_command_is_said_as_standing_still() {
        let slip = Effect::Slip { per_m_per_s: 0.913 };
        let jammed = slip.sentence_at(1.2, 0.0, 90.0);
        assert!(
            jammed.contains("does not move") && jammed.contains("from 1.10 m/s"),
            "{jammed}"
        );
        let slow = slip.sentence_at(0.22, 0.0, 90.0);
        assert!(
            slow.contains("20% slower") && slow.contains("(40% at 0.44 m/s)"),
            "{slow}"
        );
        let doubled = slip.sentence_at(0.8, 0.0, 90.0);
        assert!(
            doubled.contains("73% slower") && doubled.contains("(100% at 1.60 m/s)"),
            "{doubled}"
        );
    }
}

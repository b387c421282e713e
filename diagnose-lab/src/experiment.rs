//! The proof on concealed effects: runs generated with each effect hidden
//! (smaller than the per-step noise, present in part of the run or map, or
//! confounded with turning), null runs and pairs, each diagnosed blind.

use serde::Serialize;
use shoal_physics::{Effect, ScopedEffect, UnicycleModel};

use crate::generate::{ColouredNoise, NoiseLaw, Operator, Settings, generate};
use shoal_diagnose::diagnosis::FoundEffect;
use shoal_diagnose::entry::{EntryTest, strength_of_truth};
use shoal_diagnose::{Options, diagnose};

pub struct Case {
    pub name: &'static str,
    /// How the effect is hidden.
    pub concealment: &'static str,
    pub truth: Vec<ScopedEffect>,
    pub turn_inside: Option<[f64; 4]>,
}

const ZONE: [f64; 4] = [0.5, 0.5, 2.0, 2.0];

/// A case of one name and concealment, outside any zone.
fn case(name: &'static str, concealment: &'static str, truth: Vec<ScopedEffect>) -> Case {
    Case {
        name,
        concealment,
        truth,
        turn_inside: None,
    }
}

fn always(effect: Effect) -> Vec<ScopedEffect> {
    vec![ScopedEffect::always(effect)]
}

/// The cases: every effect of the library, concealed, then two pairs.
pub fn cases(duration_s: f64) -> Vec<Case> {
    let mut out = bench_single_effects(duration_s);
    out.extend(bench_pairs());
    out
}

/// The bench's cases of one effect each, and its null case.
fn bench_single_effects(duration_s: f64) -> Vec<Case> {
    let mut out = bench_gains_and_response(duration_s);
    out.extend(bench_time_place_and_body());
    out
}

/// Effects far below the per-step noise.
const TINY: &str = "per-step effect far below the per-step noise";

/// The null case and the bench's effects on how the robot answers its
/// commands: a delay, gains, a bias, a drift, a limit, a slip.
fn bench_gains_and_response(duration_s: f64) -> Vec<Case> {
    let tiny = TINY;
    vec![
        case("null", "no effect", vec![]),
        case("latency", tiny, always(Effect::Latency { seconds: 0.12 })),
        case(
            "speed_scale",
            tiny,
            always(Effect::SpeedScale { factor: 0.96 }),
        ),
        case(
            "turn_scale",
            tiny,
            always(Effect::TurnScale { factor: 0.94 }),
        ),
        case(
            "turn_bias",
            "only in the second half of the run",
            vec![ScopedEffect {
                effect: Effect::TurnBias { rad_per_s: 0.015 },
                during: Some([duration_s / 2.0, duration_s]),
            }],
        ),
        case(
            "heading_drift",
            tiny,
            always(Effect::HeadingDrift { rad_per_m: 0.04 }),
        ),
        case(
            "accel_limit",
            tiny,
            always(Effect::AccelLimit { m_per_s2: 0.4 }),
        ),
        case("slip", tiny, always(Effect::Slip { per_m_per_s: 0.3 })),
    ]
}

/// The bench's effects of time (a fading battery), place (a zone, a flow)
/// and body (play, noise, speed lost in turns, where the marker sits).
fn bench_time_place_and_body() -> Vec<Case> {
    let tiny = TINY;
    vec![
        case(
            "battery_fade",
            "grows slowly over the run",
            always(Effect::BatteryFade { per_minute: 0.008 }),
        ),
        Case {
            turn_inside: Some(ZONE),
            ..case(
                "surface_zone",
                "only in part of the map, visited mostly while turning",
                always(Effect::SurfaceZone {
                    region: ZONE,
                    speed_factor: 0.8,
                    turn_factor: 0.75,
                }),
            )
        },
        case(
            "external_flow",
            tiny,
            always(Effect::ExternalFlow {
                vx: 0.006,
                vy: -0.004,
            }),
        ),
        case(
            "hysteresis",
            tiny,
            always(Effect::Hysteresis {
                play_rad_per_s: 0.08,
            }),
        ),
        // Variance 1 + 6 |v|: at 0.5 m/s, three quarters from driving.
        case(
            "speed_noise",
            "noise only, no bias",
            always(Effect::SpeedNoise {
                driving_share: 0.75,
                exponent: 1.0,
                at_m_per_s: 0.5,
            }),
        ),
        case(
            "turn_speed_loss",
            tiny,
            always(Effect::TurnSpeedLoss {
                per_rad_per_s: 0.15,
            }),
        ),
        // A marker 4 cm ahead of the axle and 1 cm to its right.
        case(
            "turn_centre_offset",
            tiny,
            always(Effect::TurnCentreOffset {
                forward_m: 0.04,
                left_m: -0.01,
            }),
        ),
    ]
}

/// The bench's two pairs of effects acting together.
fn bench_pairs() -> Vec<Case> {
    let pair = "two effects together";
    vec![
        case(
            "latency+heading_drift",
            pair,
            vec![
                ScopedEffect::always(Effect::Latency { seconds: 0.12 }),
                ScopedEffect::always(Effect::HeadingDrift { rad_per_m: 0.04 }),
            ],
        ),
        case(
            "speed_scale+external_flow",
            pair,
            vec![
                ScopedEffect::always(Effect::SpeedScale { factor: 0.96 }),
                ScopedEffect::always(Effect::ExternalFlow {
                    vx: 0.006,
                    vy: -0.004,
                }),
            ],
        ),
    ]
}

/// Who generates the runs. The bench's own generator is the one the
/// diagnosis was developed against; the others share none of its choices
/// (operator, rates, speeds, how noise depends on the motion, which way and
/// how large the effects are, which act together), so a method tuned to the
/// bench shows it on them.
#[derive(Clone, Debug)]
pub struct Generator {
    pub name: &'static str,
    /// The cases it runs, for a run of this many seconds.
    pub cases_of: fn(f64) -> Vec<Case>,
    pub operator: Operator,
    pub noise_law: NoiseLaw,
    pub command_hz: f64,
    pub pose_hz: f64,
    pub max_speed: f64,
    pub max_turn: f64,
}

impl Generator {
    /// The generator the diagnosis was developed against.
    pub fn bench() -> Self {
        let bench = Settings::default();
        Self {
            name: "bench",
            cases_of: cases,
            operator: Operator::Held,
            noise_law: NoiseLaw::Constant,
            command_hz: bench.command_hz,
            pose_hz: bench.pose_hz,
            max_speed: bench.max_speed,
            max_turn: bench.max_turn,
        }
    }

    /// Every generator, the bench's first.
    pub fn all() -> Vec<Self> {
        vec![
            Self::bench(),
            // A navigation stack's robot: a waypoint follower at 20 Hz,
            // motion capture at 120 Hz, wheel-slip noise only while moving.
            Self {
                name: "waypoints",
                cases_of: independent_cases,
                operator: Operator::Waypoints,
                noise_law: NoiseLaw::WhileMoving,
                command_hz: 20.0,
                pose_hz: 120.0,
                max_speed: 0.5,
                max_turn: 1.2,
            },
            // The same robot and follower, steering open loop: its
            // commands never respond to the motion noise.
            Self {
                name: "waypoints-open",
                cases_of: independent_cases,
                operator: Operator::WaypointsOpenLoop,
                noise_law: NoiseLaw::WhileMoving,
                command_hz: 20.0,
                pose_hz: 120.0,
                max_speed: 0.5,
                max_turn: 1.2,
            },
            // A slow teleoperated robot: held commands at 10 Hz, poses at
            // 30 Hz, noise that grows with speed but not with turn rate.
            Self {
                name: "speed-only",
                cases_of: independent_cases,
                operator: Operator::Held,
                noise_law: NoiseLaw::SpeedOnly,
                command_hz: 10.0,
                pose_hz: 30.0,
                max_speed: 0.22,
                max_turn: 1.0,
            },
        ]
    }

    /// The generator called `name`, for the command line; the error lists
    /// the known ones.
    pub fn parse(name: &str) -> Result<Self, String> {
        let all = Self::all();
        let known: Vec<&str> = all.iter().map(|g| g.name).collect();
        let known = known.join(", ");
        all.into_iter()
            .find(|g| g.name == name)
            .ok_or_else(|| format!("unknown generator `{name}`; known: {known}"))
    }

    /// The cases this generator runs, for a run of `duration_s`.
    pub fn cases(&self, duration_s: f64) -> Vec<Case> {
        (self.cases_of)(duration_s)
    }

    /// Whether this generator's motion noise grows with speed, so that
    /// naming speed-dependent noise is a true statement about it.
    pub fn noise_grows_with_speed(&self) -> bool {
        self.noise_law != NoiseLaw::Constant
    }

    fn apply(&self, settings: Settings) -> Settings {
        Settings {
            operator: self.operator,
            noise_law: self.noise_law,
            command_hz: self.command_hz,
            pose_hz: self.pose_hz,
            max_speed: self.max_speed,
            max_turn: self.max_turn,
            ..settings
        }
    }
}

/// Cases unlike the bench's: gains above 1 where the bench's are below,
/// other sizes and signs, a zone that speeds the robot up, and effects
/// that act three and two at a time, in the combinations real robots show
/// (a fading battery with a wrong turn gain; latency with turn losses).
pub fn independent_cases(duration_s: f64) -> Vec<Case> {
    let mut out = independent_single_effects();
    out.extend(independent_scoped(duration_s));
    out.extend(independent_together());
    out
}

/// The independent cases of one effect each, and the null case.
fn independent_single_effects() -> Vec<Case> {
    let above = "a gain above 1";
    let other = "another size and sign than the bench's";
    vec![
        case("null", "no effect", vec![]),
        case(
            "speed_scale",
            above,
            always(Effect::SpeedScale { factor: 1.05 }),
        ),
        case(
            "turn_scale",
            above,
            always(Effect::TurnScale { factor: 1.08 }),
        ),
        case("latency", other, always(Effect::Latency { seconds: 0.08 })),
        case(
            "accel_limit",
            other,
            always(Effect::AccelLimit { m_per_s2: 0.5 }),
        ),
        case("slip", other, always(Effect::Slip { per_m_per_s: 0.25 })),
        case(
            "heading_drift",
            other,
            always(Effect::HeadingDrift { rad_per_m: -0.03 }),
        ),
        case(
            "battery_fade",
            other,
            always(Effect::BatteryFade { per_minute: 0.012 }),
        ),
        case(
            "external_flow",
            other,
            always(Effect::ExternalFlow {
                vx: -0.005,
                vy: 0.006,
            }),
        ),
        case(
            "hysteresis",
            other,
            always(Effect::Hysteresis {
                play_rad_per_s: 0.06,
            }),
        ),
        case(
            "turn_speed_loss",
            other,
            always(Effect::TurnSpeedLoss {
                per_rad_per_s: 0.12,
            }),
        ),
        case(
            "turn_centre_offset",
            other,
            always(Effect::TurnCentreOffset {
                forward_m: -0.03,
                left_m: 0.015,
            }),
        ),
    ]
}

/// An effect in part of the run, and a zone of the floor.
fn independent_scoped(duration_s: f64) -> Vec<Case> {
    vec![
        case(
            "turn_bias",
            "only in the first third of the run",
            vec![ScopedEffect {
                effect: Effect::TurnBias { rad_per_s: -0.02 },
                during: Some([0.0, duration_s / 3.0]),
            }],
        ),
        case(
            "surface_zone",
            "a zone where the robot drives faster than commanded and turns less",
            always(Effect::SurfaceZone {
                region: [-2.0, -2.0, -0.5, -0.5],
                speed_factor: 1.2,
                turn_factor: 0.85,
            }),
        ),
    ]
}

/// Effects acting together, in the combinations real robots show.
fn independent_together() -> Vec<Case> {
    let together = "effects acting together";
    vec![
        case(
            "latency+turn_scale+turn_speed_loss",
            together,
            vec![
                ScopedEffect::always(Effect::Latency { seconds: 0.08 }),
                ScopedEffect::always(Effect::TurnScale { factor: 1.06 }),
                ScopedEffect::always(Effect::TurnSpeedLoss {
                    per_rad_per_s: 0.12,
                }),
            ],
        ),
        case(
            "battery_fade+turn_scale",
            together,
            vec![
                ScopedEffect::always(Effect::BatteryFade { per_minute: 0.012 }),
                ScopedEffect::always(Effect::TurnScale { factor: 0.93 }),
            ],
        ),
        case(
            "speed_scale+accel_limit",
            together,
            vec![
                ScopedEffect::always(Effect::SpeedScale { factor: 1.05 }),
                ScopedEffect::always(Effect::AccelLimit { m_per_s2: 0.5 }),
            ],
        ),
        case(
            "slip+heading_drift",
            together,
            vec![
                ScopedEffect::always(Effect::Slip { per_m_per_s: 0.25 }),
                ScopedEffect::always(Effect::HeadingDrift { rad_per_m: -0.03 }),
            ],
        ),
    ]
}

/// Motion and observation noise the runs are generated with. Only `white`
/// is what diagnosis assumes (a random walk); the others are coloured, with
/// the time constants real robots show, and observed through motion
/// capture with dropped frames, timestamp jitter and marker swaps.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseColour {
    pub name: &'static str,
    pub coloured: Vec<ColouredNoise>,
    pub dropout: f64,
    pub timestamp_jitter_s: f64,
    pub outliers: f64,
}

impl NoiseColour {
    /// Every colour the bench knows, the tool's own assumption first.
    pub fn all() -> Vec<Self> {
        let ou = |time_constant_s: f64, along_m_per_s: f64, turn_rad_per_s: f64| ColouredNoise {
            time_constant_s,
            along_m_per_s,
            turn_rad_per_s,
        };
        let plain = |name, coloured| Self {
            name,
            coloured,
            dropout: 0.02,
            timestamp_jitter_s: 0.001,
            outliers: 0.0,
        };
        vec![
            Self {
                dropout: 0.0,
                timestamp_jitter_s: 0.0,
                ..plain("white", vec![])
            },
            plain("ou-0.2s", vec![ou(0.2, 0.02, 0.04)]),
            plain("ou-2s", vec![ou(2.0, 0.01, 0.02)]),
            plain("ou-5s", vec![ou(5.0, 0.008, 0.015)]),
            Self {
                outliers: 0.002,
                ..plain("mixed", vec![ou(0.3, 0.01, 0.02), ou(3.0, 0.008, 0.015)])
            },
        ]
    }

    /// The colour called `name`, for the command line; the error lists the
    /// known ones.
    pub fn parse(name: &str) -> Result<Self, String> {
        let all = Self::all();
        let known: Vec<&str> = all.iter().map(|c| c.name).collect();
        let known = known.join(", ");
        all.into_iter()
            .find(|c| c.name == name)
            .ok_or_else(|| format!("unknown noise colour `{name}`; known: {known}"))
    }

    /// `settings` with this colour's noise.
    pub fn apply(&self, settings: Settings) -> Settings {
        Settings {
            coloured: self.coloured.clone(),
            dropout: self.dropout,
            timestamp_jitter_s: self.timestamp_jitter_s,
            outliers: self.outliers,
            ..settings
        }
    }
}

/// Wilson's 95% interval for `k` successes in `n` trials.
pub fn wilson_interval(k: usize, n: usize) -> [f64; 2] {
    if n == 0 {
        return [0.0, 1.0];
    }
    let (n, p, z) = (n as f64, k as f64 / n as f64, 1.959_964);
    let centre = (p + z * z / (2.0 * n)) / (1.0 + z * z / n);
    let half = z * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt() / (1.0 + z * z / n);
    [(centre - half).max(0.0), (centre + half).min(1.0)]
}

#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub name: String,
    /// The generator and the noise colour the runs were generated with.
    pub generator: String,
    pub noise: String,
    pub concealment: String,
    pub runs: usize,
    /// Share of runs in which every true effect was named.
    pub detection_rate: f64,
    /// Share of runs where each true effect was named or tied with the
    /// named one (an equally good explanation of these data).
    pub named_or_tied_rate: f64,
    /// Share of runs whose data show every true effect: the entry test at
    /// the true parameters passes (see `strength_of_truth`). What a
    /// diagnosis could at best name.
    pub shown_rate: f64,
    /// Share of those runs in which every true effect was named.
    pub named_when_shown_rate: f64,
    /// Share of runs naming an effect that is not there (one named with the
    /// true effect as its stated alternative is a tie, not this).
    pub false_positive_rate: f64,
    /// Wilson's 95% interval of that share.
    pub false_positive_interval: [f64; 2],
    /// Share of runs that name an effect not there or locate a difference
    /// in the motion (its mean: along, across or heading) that no true
    /// effect explains; for null runs, any statement beyond the noise.
    pub beyond_noise_rate: f64,
    /// Wilson's 95% interval of that share.
    pub beyond_noise_interval: [f64; 2],
    /// Mean relative error of the true effects' parameters, where found.
    pub param_error: Option<f64>,
    pub heldout_rmse_pos_m_before: f64,
    pub heldout_rmse_pos_m_after: f64,
    pub seconds_per_run: f64,
    /// How often each kind was named over the runs.
    pub named: std::collections::BTreeMap<String, usize>,
    /// The true effects over the runs (a run of two counts two), and how
    /// many of them were named.
    pub effects_concealed: usize,
    pub effects_named: usize,
    /// What each run named, seed by seed: a wrong finding can be reproduced.
    pub per_run: Vec<RunFindings>,
}

#[derive(Clone, Debug, Serialize)]
pub struct RunFindings {
    pub seed: u64,
    /// Each effect named, as `kind name=value ...`.
    pub effects: Vec<String>,
    /// Each difference located in the motion, as `family component`.
    pub located_in_motion: Vec<String>,
    /// Each mismatch no effect of the library explained within physical
    /// limits, as the effect tried and the edge its fit ended on: a null
    /// run that says one counts as beyond the noise, so it is listed.
    pub unexplained: Vec<String>,
    /// Each effect said undecided from the controller's answer, as `kind
    /// name=value ...`: a null run that says one counts as beyond the noise.
    pub undecided: Vec<String>,
    #[serde(skip)]
    outcome: Outcome,
}

/// How one run's diagnosis compares with the truth.
#[derive(Clone, Debug, Default)]
struct Outcome {
    detected: bool,
    /// How many of the true effects were named.
    true_named: usize,
    shown: bool,
    named_or_tied: bool,
    false_positive: bool,
    beyond_noise: bool,
    param_errors: Vec<f64>,
    before: f64,
    after: f64,
    seconds: f64,
}

/// Relative error of `found`'s parameters against `truth`'s.
fn param_error(truth: &Effect, found: &Effect) -> f64 {
    let t = truth.params();
    let reference = match *truth {
        Effect::SpeedNoise { at_m_per_s, .. } => at_m_per_s,
        _ => 0.0,
    };
    let f = found.at_reference_speed(reference).params();
    let scale = t.iter().map(|(_, v)| v.abs()).fold(0.0, f64::max).max(1e-9);
    let identity = Effect::identity(truth.kind(), [0.0; 4])
        .map(|e| e.params())
        .unwrap_or_default();
    // Scale errors relative to the effect's size (distance from identity).
    let size = t
        .iter()
        .zip(&identity)
        .map(|((_, v), (_, i))| (v - i).abs())
        .fold(0.0, f64::max)
        .max(1e-9 * scale);
    t.iter()
        .zip(&f)
        .map(|((_, a), (_, b))| (a - b).abs())
        .fold(0.0, f64::max)
        / size
}

/// The case of `generator` called `name`; the error lists the known ones.
pub fn case_named(generator: &Generator, name: &str, duration_s: f64) -> Result<Case, String> {
    let all = generator.cases(duration_s);
    let known: Vec<&str> = all.iter().map(|c| c.name).collect();
    let known = known.join(", ");
    all.into_iter().find(|c| c.name == name).ok_or_else(|| {
        format!(
            "generator `{}` has no case `{name}`; known: {known}",
            generator.name
        )
    })
}

/// The generator's settings for one run: `case`'s operator (if any), under
/// `noise`.
pub fn run_settings(
    generator: &Generator,
    case: Option<&Case>,
    noise: &NoiseColour,
    seed: u64,
    duration_s: f64,
) -> Settings {
    noise.apply(generator.apply(Settings {
        duration_s,
        seed,
        turn_inside: case.and_then(|c| c.turn_inside),
        ..Settings::default()
    }))
}

/// `e` as `kind name=value ... [during a-b s]`.
fn effect_text(e: &FoundEffect) -> String {
    scoped_text(&e.scoped)
}

/// `scoped` as `kind name=value ... [during a-b s]`.
fn scoped_text(scoped: &ScopedEffect) -> String {
    let params: Vec<String> = scoped
        .effect
        .params()
        .iter()
        .map(|(name, value)| format!("{name}={value:.4}"))
        .collect();
    let during = scoped
        .during
        .map(|[a, b]| format!(" during {a:.0}-{b:.0} s"))
        .unwrap_or_default();
    format!("{} {}{during}", scoped.effect.kind(), params.join(" "))
}

/// One run of `case` as the experiment generates it: its true effects and
/// operator, under `noise`, for `seed`.
pub fn case_run(
    generator: &Generator,
    case: &Case,
    noise: &NoiseColour,
    seed: u64,
    duration_s: f64,
) -> shoal_diagnose::Recording {
    let truth = UnicycleModel::with_effects(case.truth.clone());
    generate(
        &truth,
        &run_settings(generator, Some(case), noise, seed, duration_s),
    )
}

/// [`case_run`] by the names the experiment's options use, 600 s long,
/// diagnosed against the plain model with the default options: a test's
/// way to one run of the experiment and what diagnosis makes of it.
pub fn diagnosed_run(
    generator: &str,
    case: &str,
    noise: &str,
    seed: u64,
) -> Result<shoal_diagnose::Diagnosis, String> {
    const DURATION_S: f64 = 600.0;
    let generator = Generator::parse(generator)?;
    let case = case_named(&generator, case, DURATION_S)?;
    let noise = NoiseColour::parse(noise)?;
    let run = case_run(&generator, &case, &noise, seed, DURATION_S);
    Ok(diagnose(&run, &UnicycleModel::plain(), &Options::default()))
}

/// What of each pose the experiment's runs observe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Observed {
    /// Position and heading, as a motion-capture rig gives them.
    Poses,
    /// Positions only, as a GPS or a one-marker tracker gives them: each
    /// heading is left for diagnosis to take from the track.
    Positions,
}

/// Generates and diagnoses one run of `case`, and compares with the truth.
fn run_one(
    generator: &Generator,
    case: &Case,
    noise: &NoiseColour,
    seed: u64,
    duration_s: f64,
    options: &Options,
    observed: Observed,
) -> RunFindings {
    let mut recording = case_run(generator, case, noise, seed, duration_s);
    if observed == Observed::Positions {
        recording.poses.theta.fill(f64::NAN);
    }
    let started = std::time::Instant::now();
    let diagnosis = diagnose(&recording, &UnicycleModel::plain(), options);
    let seconds = started.elapsed().as_secs_f64();
    let true_kinds: Vec<&str> = case.truth.iter().map(|e| e.effect.kind()).collect();
    // Noise that grows with speed is a true statement where the generator's does.
    let is_true = |kind: &str| {
        true_kinds.contains(&kind) || (kind == "speed_noise" && generator.noise_grows_with_speed())
    };
    let shown = !case.truth.is_empty()
        && strength_of_truth(&recording, &UnicycleModel::plain(), &case.truth, options)
            .iter()
            .all(EntryTest::passed);
    let kinds: Vec<&str> = diagnosis.effects.iter().map(|e| e.kind).collect();
    let tied: Vec<&str> = diagnosis
        .effects
        .iter()
        .flat_map(|e| e.indistinguishable_from.iter().copied())
        .collect();
    let located_in_motion: Vec<String> = diagnosis
        .located
        .iter()
        .filter(|l| l.component != "spread")
        .map(|l| format!("{} {}", l.family, l.component))
        .collect();
    // These generators step their bodies finely (midpoint, 5 ms): a
    // simulator's integration step said of one of their runs is wrong.
    let false_positive = diagnosis.integration.is_some()
        || diagnosis.effects.iter().any(|e| {
            !is_true(e.kind) && !e.alternatives.iter().any(|a| true_kinds.contains(&a.kind))
        });
    // A located difference is explained when a true effect was named.
    let unexplained_motion = (!located_in_motion.is_empty() || !diagnosis.unexplained.is_empty())
        && !kinds.iter().any(|k| true_kinds.contains(k));
    // An effect said possible, undecided from the controller's answer, is
    // a statement beyond the noise where it is not there.
    let undecided_not_there = diagnosis
        .not_feedback_free
        .iter()
        .any(|n| n.undecided && !is_true(n.kind));
    let outcome = Outcome {
        detected: !true_kinds.is_empty() && true_kinds.iter().all(|k| kinds.contains(k)),
        true_named: true_kinds.iter().filter(|k| kinds.contains(k)).count(),
        shown,
        named_or_tied: !true_kinds.is_empty()
            && true_kinds
                .iter()
                .all(|k| kinds.contains(k) || tied.contains(k)),
        false_positive,
        beyond_noise: false_positive || unexplained_motion || undecided_not_there,
        param_errors: case
            .truth
            .iter()
            .filter_map(|t| {
                let found = diagnosis
                    .effects
                    .iter()
                    .find(|f| f.kind == t.effect.kind())?;
                Some(param_error(&t.effect, &found.scoped.effect))
            })
            .collect(),
        before: diagnosis.baseline.heldout_rmse_pos_m,
        after: diagnosis.improved.heldout_rmse_pos_m,
        seconds,
    };
    RunFindings {
        seed,
        effects: diagnosis
            .integration
            .iter()
            .chain(&diagnosis.effects)
            .map(effect_text)
            .collect(),
        located_in_motion,
        unexplained: diagnosis
            .unexplained
            .iter()
            .map(|u| format!("{}: {}", u.tried, u.reason))
            .collect(),
        undecided: diagnosis
            .not_feedback_free
            .iter()
            .filter(|n| n.undecided)
            .map(|n| scoped_text(&n.scoped))
            .collect(),
        outcome,
    }
}

/// Diagnoses `case` blind on every seed of `seeds` (in parallel) and
/// counts what was named against the truth.
pub fn run_case(
    generator: &Generator,
    case: &Case,
    noise: &NoiseColour,
    seeds: std::ops::Range<u64>,
    duration_s: f64,
    options: &Options,
    observed: Observed,
) -> Row {
    use rayon::prelude::*;
    let per_run: Vec<RunFindings> = seeds
        .into_par_iter()
        .map(|seed| run_one(generator, case, noise, seed, duration_s, options, observed))
        .collect();
    let runs = per_run.len();
    let count = |f: fn(&Outcome) -> bool| per_run.iter().filter(|r| f(&r.outcome)).count();
    let n = runs.max(1) as f64;
    let mean = |f: fn(&Outcome) -> f64| per_run.iter().map(|r| f(&r.outcome)).sum::<f64>() / n;
    let errors: Vec<f64> = per_run
        .iter()
        .flat_map(|r| r.outcome.param_errors.iter().copied())
        .collect();
    let mut named = std::collections::BTreeMap::new();
    for effect in per_run.iter().flat_map(|r| &r.effects) {
        let kind = effect.split(' ').next().unwrap_or_default();
        *named.entry(kind.to_owned()).or_insert(0) += 1;
    }
    let (false_positive, beyond_noise) = (count(|o| o.false_positive), count(|o| o.beyond_noise));
    Row {
        name: case.name.to_owned(),
        generator: generator.name.to_owned(),
        noise: noise.name.to_owned(),
        concealment: case.concealment.to_owned(),
        runs,
        detection_rate: count(|o| o.detected) as f64 / n,
        shown_rate: count(|o| o.shown) as f64 / n,
        named_when_shown_rate: count(|o| o.shown && o.detected) as f64
            / count(|o| o.shown).max(1) as f64,
        named_or_tied_rate: count(|o| o.named_or_tied) as f64 / n,
        false_positive_rate: false_positive as f64 / n,
        false_positive_interval: wilson_interval(false_positive, runs),
        beyond_noise_rate: beyond_noise as f64 / n,
        beyond_noise_interval: wilson_interval(beyond_noise, runs),
        param_error: (!errors.is_empty()).then(|| errors.iter().sum::<f64>() / errors.len() as f64),
        heldout_rmse_pos_m_before: mean(|o| o.before),
        heldout_rmse_pos_m_after: mean(|o| o.after),
        seconds_per_run: mean(|o| o.seconds),
        named,
        effects_concealed: case.truth.len() * runs,
        effects_named: per_run.iter().map(|r| r.outcome.true_named).sum(),
        per_run,
    }
}

#[cfg(test)]
mod tests {
    use super::wilson_interval;

    #[test]
    fn wilson_interval_matches_published_values() {
        // 0 of 40: [0, 0.0876]; 2 of 40: [0.0138, 0.1650].
        let [lo, hi] = wilson_interval(0, 40);
        assert!(lo == 0.0 && (hi - 0.0876).abs() < 1e-3, "{lo} {hi}");
        let [lo, hi] = wilson_interval(2, 40);
        assert!(
            (lo - 0.0138).abs() < 1e-3 && (hi - 0.1650).abs() < 1e-3,
            "{lo} {hi}"
        );
    }
}

//! Fuzzing every parser of user files and every check of bus samples.
//!
//! Text inputs are made by mutating valid files (numbers swapped for NaN,
//! infinities, huge and negative values; lines deleted, doubled and
//! swapped; files cut short; random bytes inserted), so most inputs get
//! past the first few bytes and reach the checks deep inside a parser. Bus
//! samples are random bytes laid over the wire type, which is what a rogue
//! publisher can put into shared memory. A target passes when no input
//! panics and every rejection is a clear error: it names the file (text) or
//! the field (bus).

use std::panic::{AssertUnwindSafe, catch_unwind};

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use shoal_broker::Wire;

/// What one input did.
enum Outcome {
    Accepted,
    /// Rejected with a message; `clear` when it names what it must, and
    /// `line` when it also names a line.
    Rejected {
        clear: bool,
        line: bool,
        message: String,
    },
}

/// One parser or check, fed one kind of input.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Target {
    /// `shoal up --scenario`: a scenario TOML.
    Scenario,
    /// `shoal slam --initial-model`: a legged motion model TOML.
    MotionModel,
    /// `shoal-diagnose generate --truth`: an effects model TOML.
    EffectsModel,
    /// `shoal diagnose --commands`: CSV `t,v,omega`.
    CommandsCsv,
    /// `shoal diagnose --poses`: CSV `t,x,y,theta`.
    PosesCsv,
    /// `shoal diagnose --poses`: a TUM trajectory (`t x y z qx qy qz qw`).
    PosesTum,
    /// `shoal diagnose --poses`: an OptiTrack Motive CSV export.
    PosesMotive,
    /// `shoal diagnose --poses`: a Vicon CSV export.
    PosesVicon,
    /// `shoal diagnose --mrclam`: `RobotN_Odometry.dat`.
    MrclamOdometry,
    /// `shoal diagnose --mrclam`: `RobotN_Groundtruth.dat`.
    MrclamGroundtruth,
    /// Every wire type's check, on random bytes.
    Pose,
    ClockTick,
    HelperProgress,
    Scan,
    Estimate,
    ModelUpdate,
    SlamParticles,
    SlamMap,
    /// `shoal diagnose --bag`: a ROS 2 bag (MCAP, CDR), bytes mutated.
    RosBag,
    /// A pose message from another host (`shoal-link`), bytes mutated:
    /// decoded, shifted into this host's clock and checked as a bus sample.
    LinkPose,
    /// A host's summary from another host (`shoal-link`), JSON mutated.
    HostSummary,
}

impl Target {
    pub const ALL: [Target; 21] = [
        Target::Scenario,
        Target::MotionModel,
        Target::EffectsModel,
        Target::CommandsCsv,
        Target::PosesCsv,
        Target::PosesTum,
        Target::PosesMotive,
        Target::PosesVicon,
        Target::MrclamOdometry,
        Target::MrclamGroundtruth,
        Target::Pose,
        Target::ClockTick,
        Target::HelperProgress,
        Target::Scan,
        Target::Estimate,
        Target::ModelUpdate,
        Target::SlamParticles,
        Target::SlamMap,
        Target::RosBag,
        Target::LinkPose,
        Target::HostSummary,
    ];

    fn is_text(self) -> bool {
        (self as usize) < (Target::Pose as usize)
    }

    fn name(self) -> String {
        format!("{self:?}")
    }

    /// The file name errors must carry.
    const FILE: &'static str = "fuzzed-input";

    fn run_one(self, rng: &mut StdRng, seeds: &Seeds) -> Outcome {
        use shoal_diagnose::input;
        match self {
            Target::Scenario => parse_mutated(rng, &seeds.scenario, |text, file| {
                shoal_scenario::Scenario::from_toml(text, file).map(|_| ())
            }),
            Target::MotionModel => parse_mutated(rng, &seeds.motion_model, |text, file| {
                shoal_physics::MotionModel::from_toml(text, file).map(|_| ())
            }),
            Target::EffectsModel => parse_mutated(rng, &seeds.effects_model, |text, file| {
                shoal_physics::UnicycleModel::from_toml(text, file).map(|_| ())
            }),
            Target::CommandsCsv => parse_mutated(rng, &seeds.commands_csv, |text, file| {
                input::commands_csv(text, file).map(|_| ())
            }),
            Target::PosesCsv => parse_mutated(rng, &seeds.poses_csv, |text, file| {
                // The outlier filter, and headings from the track where a
                // mutation left the file without its heading, run on
                // whatever parsed.
                input::poses_csv(text, file).map(|poses| {
                    let _ = poses.data.without_outliers();
                    let mut positions = poses.data;
                    positions.theta.fill(f64::NAN);
                    let _ = shoal_diagnose::track::headed(&shoal_diagnose::Recording::of(
                        shoal_diagnose::recording::Commands::default(),
                        positions,
                    ));
                })
            }),
            Target::PosesTum => parse_mutated(rng, &seeds.poses_tum, |text, file| {
                input::poses_file(text, file, None).map(|_| ())
            }),
            Target::PosesMotive => parse_mutated(rng, &seeds.poses_motive, |text, file| {
                input::poses_file(text, file, Some("robot")).map(|_| ())
            }),
            Target::PosesVicon => parse_mutated(rng, &seeds.poses_vicon, |text, file| {
                input::poses_file(text, file, Some("robot")).map(|_| ())
            }),
            Target::MrclamOdometry => parse_mutated(rng, &seeds.mrclam_odometry, |text, file| {
                input::mrclam_odometry(text, file).map(|_| ())
            }),
            Target::MrclamGroundtruth => {
                parse_mutated(rng, &seeds.mrclam_groundtruth, |text, file| {
                    input::mrclam_groundtruth(text, file).map(|_| ())
                })
            }
            Target::Pose => wire_outcome::<shoal_broker::PoseSample>(rng),
            Target::ClockTick => wire_outcome::<shoal_broker::ClockTick>(rng),
            Target::HelperProgress => wire_outcome::<shoal_broker::HelperProgress>(rng),
            Target::Scan => wire_outcome::<shoal_broker::ScanSample>(rng),
            Target::Estimate => wire_outcome::<shoal_broker::EstimateSample>(rng),
            Target::ModelUpdate => wire_outcome::<shoal_broker::ModelUpdate>(rng),
            Target::SlamParticles => wire_outcome::<shoal_broker::SlamParticles>(rng),
            Target::SlamMap => wire_outcome::<shoal_broker::SlamMap>(rng),
            Target::RosBag => bag_outcome(rng, &seeds.ros_bag),
            Target::LinkPose => link_pose_outcome(rng, &seeds.link_pose),
            Target::HostSummary => message_outcome(
                serde_json::from_str::<shoal_link::wire::HostSummary>(&mutate(
                    rng,
                    &seeds.host_summary,
                ))
                .map(|_| ())
                .map_err(|e| e.to_string()),
            ),
        }
    }
}

/// Parses a mutation of the text file `seed` and judges the outcome.
fn parse_mutated<E: std::fmt::Display>(
    rng: &mut StdRng,
    seed: &str,
    parse: impl FnOnce(&str, &str) -> Result<(), E>,
) -> Outcome {
    text_outcome(parse(&mutate(rng, seed), Target::FILE))
}

/// Reads a mutation of the bag `seed` as a run.
fn bag_outcome(rng: &mut StdRng, seed: &[u8]) -> Outcome {
    text_outcome(
        shoal_bags::read_run(
            &shoal_bags::Bag::from_bytes(
                std::path::Path::new(Target::FILE),
                mutate_bytes(rng, seed),
            ),
            &shoal_bags::Selection {
                commands_topic: shoal_bags::write::WRITTEN_COMMANDS_TOPIC,
                poses_topic: shoal_bags::write::WRITTEN_POSES_TOPIC,
                ..Default::default()
            },
            shoal_bags::StampsPreference::Auto,
        )
        .map(|_| ()),
    )
}

/// Decodes a mutation of the remote pose `seed` as the link does: the
/// message, its time on this host's clock, the sample's checks.
fn link_pose_outcome(rng: &mut StdRng, seed: &[u8]) -> Outcome {
    let bytes = mutate_bytes(rng, seed);
    message_outcome(
        shoal_link::wire::RemotePose::decode(&bytes)
            .map_err(|e| e.to_string())
            .and_then(|pose| {
                pose.in_local_time(pose.epoch_unix_ms, 0.2)
                    .ok_or_else(|| "a time before this host's clock".to_owned())
            })
            .and_then(|sample| sample.check().map_err(|e| e.to_string())),
    )
}

/// Judges a network message's rejection: it must say what is wrong.
fn message_outcome(result: Result<(), String>) -> Outcome {
    match result {
        Ok(()) => Outcome::Accepted,
        Err(message) => Outcome::Rejected {
            clear: !message.is_empty(),
            line: false,
            message,
        },
    }
}

/// Judges a parser's answer: a rejection must name the file it was given.
fn text_outcome<E: std::fmt::Display>(result: Result<(), E>) -> Outcome {
    match result {
        Ok(()) => Outcome::Accepted,
        Err(e) => {
            let message = e.to_string();
            let file = Target::FILE.to_string();
            let after_file = message.strip_prefix(&file);
            Outcome::Rejected {
                clear: after_file.is_some_and(|rest| rest.len() > 2),
                line: after_file.is_some_and(|rest| {
                    rest.strip_prefix(':')
                        .is_some_and(|r| r.starts_with(|c: char| c.is_ascii_digit()))
                }),
                message,
            }
        }
    }
}

/// Random bytes laid over a wire type, then checked. Every Shoal wire type
/// is plain old data (integers, floats and arrays of them), so any bytes
/// are a value of it, just as any bytes in shared memory are.
fn wire_outcome<T: Wire + Copy + Example>(rng: &mut StdRng) -> Outcome {
    let size = std::mem::size_of::<T>();
    let example = T::example();
    // SAFETY: a T is plain old data, readable as its size_of bytes.
    let mut bytes =
        unsafe { std::slice::from_raw_parts((&raw const example).cast::<u8>(), size) }.to_vec();
    if rng.random_bool(0.5) {
        // A valid sample with a few bytes overwritten reaches every check.
        for _ in 0..rng.random_range(1..=8) {
            let at = rng.random_range(0..size);
            bytes[at] = rng.random();
        }
    } else {
        // Wholly random bytes, with a random share zeroed so counts are
        // often small and floats often ordinary.
        rng.fill(&mut bytes[..]);
        let zeroed = rng.random_range(0.0..1.0);
        for b in bytes.iter_mut() {
            if rng.random_bool(zeroed) {
                *b = 0;
            }
        }
    }
    // SAFETY: `bytes` holds size_of::<T>() bytes and T is plain old data
    // (checked by the wire layout test), so every bit pattern is a T;
    // read_unaligned makes no alignment assumption.
    let sample: T = unsafe { std::ptr::read_unaligned(bytes.as_ptr().cast::<T>()) };
    match sample.check() {
        Ok(()) => Outcome::Accepted,
        Err(rejection) => {
            let message = rejection.to_string();
            Outcome::Rejected {
                clear: !message.is_empty(),
                line: false,
                message,
            }
        }
    }
}

/// A valid sample of a wire type, the starting point of mutation.
trait Example {
    fn example() -> Self;
}

impl Example for shoal_broker::PoseSample {
    fn example() -> Self {
        let mut pose = Self::standing(3, 1234, 50, 2.0, 3.0, 0.5);
        pose.sim_time = 5.0;
        pose.neighbour_count = 2;
        pose.neighbours[..2].copy_from_slice(&[1, 2]);
        pose
    }
}

impl Example for shoal_broker::ClockTick {
    fn example() -> Self {
        Self {
            tick: 50,
            sim_time: 5.0,
            period_s: 0.1,
        }
    }
}

impl Example for shoal_broker::HelperProgress {
    fn example() -> Self {
        Self { tick: 50 }
    }
}

impl Example for shoal_broker::ScanSample {
    fn example() -> Self {
        Self {
            agent_id: 3,
            pid: 1234,
            tick: 50,
            sim_time: 5.0,
            command: 2,
            bumped: 0,
            beam_count: 181,
            reserved: 0,
            field_of_view: std::f64::consts::PI,
            max_range: 4.0,
            ranges: [1.5; shoal_broker::MAX_BEAMS],
        }
    }
}

impl Example for shoal_broker::EstimateSample {
    fn example() -> Self {
        Self {
            agent_id: 3,
            reserved: 0,
            tick: 50,
            x: 2.0,
            y: 3.0,
            theta: 0.5,
            effective_particles: 80.0,
        }
    }
}

impl Example for shoal_broker::ModelUpdate {
    fn example() -> Self {
        Self {
            agent_id: 3,
            command: 2,
            param: 0,
            reserved: 0,
            step: 7,
            weights: [0.25, 0.75],
            means: [0.12, 0.15],
            variances: [1e-4, 2e-4],
        }
    }
}

impl Example for shoal_broker::SlamParticles {
    fn example() -> Self {
        Self {
            agent_id: 3,
            count: 200,
            tick: 50,
            sim_time: 5.0,
            xy: [[2.0, 3.0]; shoal_broker::MAX_SHOWN_PARTICLES],
        }
    }
}

impl Example for shoal_broker::SlamMap {
    fn example() -> Self {
        Self {
            agent_id: 3,
            width: 60,
            height: 80,
            cell_size: 0.05,
            origin: [0.0, 0.0],
            tick: 50,
            sim_time: 5.0,
            cells: [255; shoal_broker::MAX_MAP_SIDE * shoal_broker::MAX_MAP_SIDE],
        }
    }
}

/// Values that break careless parsers.
const NASTY: [&str; 18] = [
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e309",
    "4.9e-324",
    "-0",
    "0",
    "-1",
    "18446744073709551616",
    "9223372036854775807",
    "-9223372036854775808",
    "1e10",
    "",
    "\"x\"",
    "[]",
];

/// One to four random edits of `seed`.
fn mutate(rng: &mut StdRng, seed: &str) -> String {
    let mut text = seed.to_owned();
    for _ in 0..rng.random_range(1..=4) {
        text = match rng.random_range(0..7) {
            0 | 1 => replace_number(rng, &text),
            2 => edit_lines(rng, &text),
            3 => cut(rng, &text),
            4 => insert_bytes(rng, &text),
            5 => replace_char(rng, &text),
            _ => duplicate_span(rng, &text),
        };
    }
    text
}

fn char_boundary(text: &str, at: usize) -> usize {
    (0..=at.min(text.len()))
        .rev()
        .find(|i| text.is_char_boundary(*i))
        .unwrap_or(0)
}

/// Swaps one number of the text for a nasty value.
fn replace_number(rng: &mut StdRng, text: &str) -> String {
    let bytes = text.as_bytes();
    let starts: Vec<usize> = (0..bytes.len())
        .filter(|&i| bytes[i].is_ascii_digit() && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric()))
        .collect();
    let Some(&start) = starts.get(rng.random_range(0..starts.len().max(1))) else {
        return text.to_owned();
    };
    let end = (start..bytes.len())
        .find(|&i| !(bytes[i].is_ascii_digit() || matches!(bytes[i], b'.' | b'e' | b'-' | b'+')))
        .unwrap_or(bytes.len());
    let nasty = NASTY[rng.random_range(0..NASTY.len())];
    format!("{}{nasty}{}", &text[..start], &text[end..])
}

/// Deletes, doubles or swaps whole lines.
fn edit_lines(rng: &mut StdRng, text: &str) -> String {
    let mut lines: Vec<&str> = text.split_inclusive('\n').collect();
    if lines.is_empty() {
        return text.to_owned();
    }
    let a = rng.random_range(0..lines.len());
    let b = rng.random_range(0..lines.len());
    match rng.random_range(0..3) {
        0 => {
            lines.remove(a);
        }
        1 => {
            let line = lines[a];
            lines.insert(b, line);
        }
        _ => lines.swap(a, b),
    }
    lines.concat()
}

/// Cuts the file short.
fn cut(rng: &mut StdRng, text: &str) -> String {
    let at = char_boundary(text, rng.random_range(0..=text.len()));
    text[..at].to_owned()
}

/// Inserts random bytes (mostly the characters a format gives meaning to).
fn insert_bytes(rng: &mut StdRng, text: &str) -> String {
    const MEANINGFUL: &[u8] = b"\n,=[]{}\"'#.-+eE0123456789 \t\r";
    let at = char_boundary(text, rng.random_range(0..=text.len()));
    let mut inserted = String::new();
    for _ in 0..rng.random_range(1..8) {
        if rng.random_bool(0.8) {
            inserted.push(MEANINGFUL[rng.random_range(0..MEANINGFUL.len())] as char);
        } else {
            inserted.push(char::from_u32(rng.random_range(0..0x11000)).unwrap_or('\u{fffd}'));
        }
    }
    format!("{}{inserted}{}", &text[..at], &text[at..])
}

fn replace_char(rng: &mut StdRng, text: &str) -> String {
    if text.is_empty() {
        return String::new();
    }
    let at = char_boundary(text, rng.random_range(0..text.len()));
    let mut rest = text[at..].chars();
    rest.next();
    let new = char::from_u32(rng.random_range(0x20..0x7f)).unwrap_or('?');
    format!("{}{new}{}", &text[..at], rest.as_str())
}

/// Repeats a span, growing counts and arrays.
fn duplicate_span(rng: &mut StdRng, text: &str) -> String {
    let a = char_boundary(text, rng.random_range(0..=text.len()));
    let b = char_boundary(text, rng.random_range(a..=text.len()));
    format!("{}{}", &text[..b], &text[a..])
}

/// One to four random edits of binary `seed`: bytes overwritten (most
/// often), the file cut short, random bytes inserted, a span repeated.
fn mutate_bytes(rng: &mut StdRng, seed: &[u8]) -> Vec<u8> {
    let mut bytes = seed.to_vec();
    for _ in 0..rng.random_range(1..=4) {
        let at = rng.random_range(0..=bytes.len());
        match rng.random_range(0..6) {
            0..=2 => {
                if let Some(b) = bytes.get_mut(at) {
                    *b = rng.random();
                }
            }
            3 => bytes.truncate(at),
            4 => {
                let inserted: Vec<u8> = (0..rng.random_range(1..8)).map(|_| rng.random()).collect();
                bytes.splice(at..at, inserted);
            }
            _ => {
                let end = rng.random_range(at..=bytes.len());
                let span = bytes[at..end].to_vec();
                bytes.splice(end..end, span);
            }
        }
    }
    bytes
}

/// Valid files of every format, the starting points of mutation.
pub struct Seeds {
    ros_bag: Vec<u8>,
    scenario: String,
    motion_model: String,
    effects_model: String,
    commands_csv: String,
    poses_csv: String,
    poses_tum: String,
    poses_motive: String,
    poses_vicon: String,
    mrclam_odometry: String,
    mrclam_groundtruth: String,
    link_pose: Vec<u8>,
    host_summary: String,
}

impl Seeds {
    /// The valid files mutations start from; one that cannot be built is an
    /// error (fuzzing an empty seed would test nothing and say it passed).
    pub fn new() -> anyhow::Result<Self> {
        use anyhow::Context as _;
        let (commands, poses, poses_tum, odometry, truth) = run_seeds();
        // The bag holds the CSV seeds' run; both parse, as the unit tests show.
        let run = shoal_diagnose::input::commands_csv(&commands, "seed")
            .and_then(|c| Ok((c, shoal_diagnose::input::poses_csv(&poses, "seed")?)))
            .map(|(c, p)| shoal_diagnose::Recording::from_absolute(c.data, p.data))
            .context("the CSV seeds")?;
        Ok(Self {
            ros_bag: shoal_bags::write::write_bag(&run.commands.rows(), &run.poses.rows())
                .map_err(anyhow::Error::msg)
                .context("the ROS 2 bag seed")?,
            scenario: scenario_seed().to_toml().context("the scenario seed")?,
            motion_model: toml::to_string(&shoal_physics::MotionModel::legged_default())
                .context("the motion model seed")?,
            effects_model: effects_seed().to_toml().context("the effects model seed")?,
            commands_csv: commands,
            poses_csv: poses,
            poses_tum,
            poses_motive: motive_seed(),
            poses_vicon: vicon_seed(),
            mrclam_odometry: odometry,
            mrclam_groundtruth: truth,
            link_pose: shoal_link::wire::RemotePose {
                epoch_unix_ms: 1_764_000_000_000,
                sample: shoal_broker::PoseSample::example(),
            }
            .encode(),
            host_summary: serde_json::to_string(&host_summary_seed())
                .context("the host summary seed")?,
        })
    }
}

/// A Motive export of two rigid bodies and a marker, Y up, millimetres,
/// with a frame where the robot was lost.
fn motive_seed() -> String {
    let mut text = String::from(
        "Format Version,1.23,Take Name,seed,Capture Frame Rate,120.000000,Rotation Type,Quaternion,Length Units,Millimeters,Coordinate Space,Global\r\n\r\n",
    );
    text += ",Type,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Marker,Marker,Marker\r\n";
    text += ",Name,dock,dock,dock,dock,dock,dock,dock,robot,robot,robot,robot,robot,robot,robot,m,m,m\r\n";
    text += ",ID,1,1,1,1,1,1,1,2,2,2,2,2,2,2,3,3,3\r\n";
    text += ",,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Position,Position,Position\r\n";
    text += "Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,X,Y,Z,W,X,Y,Z,X,Y,Z\r\n";
    for frame in 0..40 {
        let t = f64::from(frame) / 120.0;
        let half = 0.005 * t;
        let robot = if frame == 20 {
            ",,,,,,".to_owned()
        } else {
            format!(
                "0,{:.6},0,{:.6},{:.3},61.5,{:.3}",
                half.sin(),
                half.cos(),
                20.0 * t,
                -t
            )
        };
        text += &format!("{frame},{t:.6},0,0,0,1,500,60,500,{robot},1,2,3\r\n");
    }
    text
}

/// A Vicon export: a `Segments` section of two subjects, with a frame
/// where the robot was lost, then a `Trajectories` section.
fn vicon_seed() -> String {
    let mut text = String::from(
        "Segments\r\n100\r\n,,dock:dock,,,,,,robot:robot,,,,,\r\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\r\n,,deg,deg,deg,mm,mm,mm,deg,deg,deg,mm,mm,mm\r\n",
    );
    for frame in 1..=40 {
        let t = f64::from(frame) / 100.0;
        let robot = if frame == 20 {
            ",,,,,".to_owned()
        } else {
            format!("0.1,-0.2,{:.3},{:.3},{:.3},85", 10.0 * t, 20.0 * t, 3.0 * t)
        };
        text += &format!("{frame},0,0,0,0,500,-400,85,{robot}\r\n");
    }
    text + "\r\nTrajectories\r\n100\r\n,,robot:M1,,\r\nFrame,Sub Frame,X,Y,Z\r\n,,mm,mm,mm\r\n1,0,1,2,3\r\n"
}

/// A scenario with a surface that changes in time.
fn scenario_seed() -> shoal_scenario::Scenario {
    let mut scenario = shoal_scenario::Scenario::default_arena();
    scenario.arena.surfaces.push(shoal_physics::Surface {
        name: "mud".into(),
        region: [1.0, 1.0, 3.0, 2.0],
        along_scale: 0.5,
        across_scale: 1.0,
        turn_scale: 0.8,
        from_s: 10.0,
    });
    scenario
}

/// One effect of every shape of parameter: scalars, a region, a vector, a span.
fn effects_seed() -> shoal_physics::UnicycleModel {
    use shoal_physics::{Effect, ScopedEffect, UnicycleModel};
    UnicycleModel::with_effects(vec![
        ScopedEffect::always(Effect::ActuatorLag { seconds: 0.12 }),
        ScopedEffect::always(Effect::Slip { per_m_per_s: 0.3 }),
        ScopedEffect::always(Effect::ExternalFlow {
            vx: 0.01,
            vy: -0.02,
        }),
        ScopedEffect {
            effect: Effect::SurfaceZone {
                region: [0.5, 0.5, 3.0, 2.5],
                speed_factor: 0.6,
                turn_factor: 0.8,
            },
            during: Some([5.0, 30.0]),
        },
        ScopedEffect::always(Effect::TurnBias { rad_per_s: 0.02 }),
    ])
}

/// A short run as CSV commands and poses, and as MRCLAM odometry and
/// ground truth.
fn run_seeds() -> (String, String, String, String, String) {
    let mut commands = String::from("t,v,omega\n");
    let mut poses = String::from("t,x,y,theta\n");
    let mut tum = String::from("# timestamp tx ty tz qx qy qz qw\n");
    let mut odometry =
        String::from("# Time [s]\tforward velocity [m/s]\tangular velocity[rad/s]\n");
    let mut truth = String::from("# Time [s]\tx [m]\ty [m]\torientation [rad]\n");
    for i in 0..40 {
        let t = f64::from(i) * 0.1;
        commands.push_str(&format!("{t:.2},0.2,0.1\n"));
        poses.push_str(&format!(
            "{t:.2},{:.4},{:.4},{:.4}\n",
            0.02 * t,
            0.001 * t,
            0.01 * t
        ));
        let half = 0.005 * t;
        tum.push_str(&format!(
            "{t:.2} {:.4} {:.4} 0 0 0 {:.6} {:.6}\n",
            0.02 * t,
            0.001 * t,
            half.sin(),
            half.cos()
        ));
        odometry.push_str(&format!("{:.3}\t0.2\t-0.05\n", 1248272272.841 + t));
        truth.push_str(&format!(
            "{:.3}\t{:.4}\t{:.4}\t{:.4}\n",
            1248272272.841 + t,
            1.0 + 0.02 * t,
            -2.0,
            3.1
        ));
    }
    (commands, poses, tum, odometry, truth)
}

/// A host's summary as the link sends it.
fn host_summary_seed() -> shoal_link::wire::HostSummary {
    shoal_link::wire::HostSummary {
        host: "b".into(),
        epoch_unix_ms: 1_764_000_000_000,
        robots: vec![shoal_link::report::RemoteRobot {
            id: 100,
            pid: 4321,
            x: 3.5,
            y: 2.0,
            theta: 0.25,
            tick: 80,
            neighbours: vec![101, 3],
            missed_periods: 0,
            neighbour_age_ms: 210,
        }],
    }
}

/// What fuzzing one target found.
#[derive(Debug, Serialize)]
pub struct TargetReport {
    pub target: String,
    pub inputs: u64,
    pub accepted: u64,
    pub rejected: u64,
    pub panics: u64,
    /// Rejections whose message does not name the file (text) or is empty (bus).
    pub unclear: u64,
    /// Text rejections that also name a line.
    pub with_line: u64,
    pub seconds: f64,
    /// The first panic's message and input seed, to reproduce it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_panic: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_unclear: Option<String>,
    /// One text rejection that names no line, to show what such errors are.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub example_without_line: Option<String>,
}

impl TargetReport {
    pub fn passed(&self) -> bool {
        self.panics == 0 && self.unclear == 0
    }
}

/// Feeds `inputs` generated inputs to `target`; input `i` comes from seed
/// `seed + i`, so one failing input can be replayed alone.
pub fn fuzz(target: Target, inputs: u64, seed: u64, seeds: &Seeds) -> TargetReport {
    let started = std::time::Instant::now();
    let mut report = TargetReport {
        target: target.name(),
        inputs,
        accepted: 0,
        rejected: 0,
        panics: 0,
        unclear: 0,
        with_line: 0,
        seconds: 0.0,
        first_panic: None,
        first_unclear: None,
        example_without_line: None,
    };
    for i in 0..inputs {
        let input_seed = seed.wrapping_add(i);
        let mut rng = StdRng::seed_from_u64(input_seed);
        match catch_unwind(AssertUnwindSafe(|| target.run_one(&mut rng, seeds))) {
            Ok(Outcome::Accepted) => report.accepted += 1,
            Ok(Outcome::Rejected {
                clear,
                line,
                message,
            }) => {
                report.rejected += 1;
                report.with_line += u64::from(line);
                if !line && target.is_text() {
                    report
                        .example_without_line
                        .get_or_insert_with(|| format!("input seed {input_seed}: {message}"));
                }
                if !clear {
                    report.unclear += 1;
                    report
                        .first_unclear
                        .get_or_insert_with(|| format!("input seed {input_seed}: {message:?}"));
                }
            }
            Err(panic) => {
                report.panics += 1;
                let message = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                    .unwrap_or_default();
                report
                    .first_panic
                    .get_or_insert_with(|| format!("input seed {input_seed}: {message}"));
            }
        }
    }
    report.seconds = started.elapsed().as_secs_f64();
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_wire_example_passes_its_check() {
        use shoal_broker::*;
        assert_eq!(PoseSample::example().check(), Ok(()));
        assert_eq!(ClockTick::example().check(), Ok(()));
        assert_eq!(HelperProgress::example().check(), Ok(()));
        assert_eq!(ScanSample::example().check(), Ok(()));
        assert_eq!(EstimateSample::example().check(), Ok(()));
        assert_eq!(ModelUpdate::example().check(), Ok(()));
        assert_eq!(SlamParticles::example().check(), Ok(()));
        assert_eq!(SlamMap::example().check(), Ok(()));
    }

    #[test]
    fn every_seed_is_a_valid_file() {
        let seeds = Seeds::new().expect("seeds");
        let file = Target::FILE;
        shoal_scenario::Scenario::from_toml(&seeds.scenario, file).expect("scenario");
        shoal_physics::MotionModel::from_toml(&seeds.motion_model, file).expect("motion model");
        shoal_physics::UnicycleModel::from_toml(&seeds.effects_model, file).expect("effects");
        shoal_diagnose::input::commands_csv(&seeds.commands_csv, file).expect("commands");
        shoal_diagnose::input::poses_csv(&seeds.poses_csv, file).expect("poses");
        shoal_diagnose::input::poses_tum(&seeds.poses_tum, file).expect("TUM poses");
        let (motive, _) =
            shoal_diagnose::input::poses_file(&seeds.poses_motive, file, Some("robot"))
                .expect("Motive export");
        assert_eq!(motive.data.len(), 39);
        let (vicon, _) = shoal_diagnose::input::poses_file(&seeds.poses_vicon, file, Some("robot"))
            .expect("Vicon export");
        assert_eq!(vicon.data.len(), 39);
        shoal_diagnose::input::mrclam_odometry(&seeds.mrclam_odometry, file).expect("odometry");
        shoal_diagnose::input::mrclam_groundtruth(&seeds.mrclam_groundtruth, file).expect("truth");
    }

    #[test]
    fn the_judge_tells_a_clear_error_from_an_unclear_one() {
        let named = text_outcome::<String>(Err(format!("{}:3: field x: NaN", Target::FILE)));
        assert!(matches!(
            named,
            Outcome::Rejected {
                clear: true,
                line: true,
                ..
            }
        ));
        let bare = text_outcome::<String>(Err("invalid float".into()));
        assert!(matches!(bare, Outcome::Rejected { clear: false, .. }));
    }
}

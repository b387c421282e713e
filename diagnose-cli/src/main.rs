//! `shoal-diagnose`: why a simulator disagrees with a robot.

mod load;
mod plot;
mod report;
mod rrd;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use shoal_diagnose::replay::replay;
use shoal_diagnose::{Options, diagnose};
use shoal_diagnose_lab::experiment::{
    Generator, NoiseColour, Observed, case_named, run_case, run_settings,
};
use shoal_diagnose_lab::generate::generate;
use shoal_physics::UnicycleModel;
use shoal_runtime::process_main::{StdoutClosed, print_out};

#[derive(Parser)]
#[command(
    version,
    about = "Find where a simulation and a real run differ, name the physics the simulation left out, fit it and show the fit improve",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Commands>,
    #[command(flatten)]
    diagnose: DiagnoseArgs,
}

#[derive(Args)]
struct DiagnoseArgs {
    /// A Shoal recording (run.rrd, with --robot N), a run directory
    /// holding commands.csv and poses.csv, an MRCLAM dataset folder (with
    /// --robot N, unless it holds one robot), or a ROS 2 bag (.mcap, .db3, or a bag folder with
    /// metadata.yaml; as --bag). Several recordings of one
    /// robot are fitted as one: each is a held-out block, and an effect is
    /// kept only if it predicts the recordings it was not fitted on better.
    #[arg(value_name = "RUN")]
    run: Vec<PathBuf>,
    /// Commands sent: CSV with header t,v,omega (held until the next row).
    #[arg(long, requires = "poses", conflicts_with_all = ["run", "mrclam"])]
    commands: Option<PathBuf>,
    /// Observed poses: CSV with header t,x,y,theta (or t,x,y: positions
    /// only), a TUM trajectory (timestamp tx ty tz qx qy qz qw), or an
    /// OptiTrack Motive or Vicon (Nexus, Tracker) CSV export (a body's;
    /// --frame NAME of several), at any rate.
    #[arg(long, requires = "commands")]
    poses: Option<PathBuf>,
    /// An MRCLAM dataset directory (e.g. shared/data/mrclam-d6); with --robot.
    #[arg(long, requires = "robot", conflicts_with = "run")]
    mrclam: Option<PathBuf>,
    /// Which robot: a Shoal robot id in a .rrd recording, or MRCLAM's 1-5.
    #[arg(long)]
    robot: Option<u32>,
    /// A ROS 2 bag: an MCAP or sqlite3 (.db3) file, or a bag folder (split
    /// bags, with metadata.yaml); compressed files, chunks and messages are
    /// read. Commands from --commands-topic, poses from --poses-topic;
    /// without the topics, lists the bag's topics.
    #[arg(long, value_name = "BAG", conflicts_with_all = ["run", "mrclam", "commands"])]
    bag: Option<PathBuf>,
    /// The bag's velocity commands: geometry_msgs/msg/Twist or TwistStamped.
    #[arg(long, value_name = "TOPIC")]
    commands_topic: Option<String>,
    /// The bag's observed poses: geometry_msgs/msg/PoseStamped,
    /// TransformStamped (motion-capture bridges), PoseWithCovarianceStamped,
    /// Pose (ros_gz_bridge), nav_msgs/msg/Odometry, turtlesim/msg/Pose, or with --frame
    /// tf2_msgs/msg/TFMessage or gazebo_msgs/msg/ModelStates or LinkStates.
    #[arg(long, value_name = "TOPIC")]
    poses_topic: Option<String>,
    /// Which of a bag's clocks times commands and poses: `auto` chooses the
    /// one both topics share and says why (header stamps on one clock; log
    /// times; simulation time through /clock), `header` or `log` insist.
    #[arg(long, value_enum, default_value_t = load::Stamps::Auto)]
    stamps: load::Stamps,
    /// With a TF poses topic: the robot's frame (the transform's child);
    /// with Gazebo's model (or link) states: the robot's model (or link);
    /// with a Motive or Vicon export of several bodies: the robot's.
    #[arg(long, value_name = "NAME")]
    frame: Option<String>,
    /// With a TF poses topic: only transforms from this parent frame;
    /// where none joins it to --frame, the chain of transforms that does
    /// (with /tf_static's), composed as tf2 looks it up (e.g. --frame
    /// base_link --parent map through map -> odom -> base_link).
    #[arg(long, requires = "frame", value_name = "FRAME")]
    parent: Option<String>,
    /// The simulation model (TOML); default: the plain unicycle.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Print one JSON object instead of the report.
    #[arg(long)]
    json: bool,
    /// Write model.toml and fit.png here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the diagnosis as a Rerun recording: the observed path, the
    /// input and fitted models' predictions of every segment, located
    /// regions as boxes, residuals and held-out errors over time.
    #[arg(long, value_name = "FILE")]
    rrd: Option<PathBuf>,
    /// Seconds each comparison predicts ahead.
    #[arg(long, default_value_t = 1.0)]
    horizon: f64,
    /// Stretches one recording is cut into for the held-out checks: each
    /// is held out in turn, and an effect must predict every one better
    /// (several recordings given: each is one block).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u16).range(2..=50))]
    blocks: u16,
    #[command(flatten)]
    naming: Naming,
}

/// How sure diagnosis must be before it names an effect.
#[derive(clap::Args)]
struct Naming {
    /// Family-wise level of the test an effect must pass to be named
    /// (Bonferroni over the library's kinds): the share of recordings
    /// without a mismatch that may name one.
    #[arg(long, default_value_t = Options::default().select_alpha, value_parser = level)]
    select_alpha: f64,
}

impl Naming {
    fn options(&self) -> Options {
        Options {
            select_alpha: self.select_alpha,
            ..Options::default()
        }
    }
}

/// A probability strictly between 0 and 1, for clap.
fn level(text: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(p) if p > 0.0 && p < 1.0 => Ok(p),
        _ => Err(format!(
            "expected a level between 0 and 1 (e.g. 0.01), got {text:?}"
        )),
    }
}

#[derive(Subcommand)]
enum Commands {
    /// Write a synthetic run (commands.csv, poses.csv) whose body has the effects of --truth.
    Generate(GenerateArgs),
    /// Detection, false positives and parameter error over many seeds, per effect.
    Experiment(ExperimentArgs),
}

/// Fewer segments than this say nothing either way.
const MIN_SEGMENTS: usize = 20;

use load::read;

/// Writes `path` by having `write` fill a file beside it and renaming that
/// into place: an interrupted run leaves the earlier result whole, never
/// half of one. Says so when it replaces an earlier file.
fn write_into_place(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    if path.exists() {
        eprintln!("shoal diagnose: replacing the earlier {}", path.display());
    }
    // The extension stays last: the PNG encoder picks its format by it.
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let partial = match path.extension() {
        Some(ext) => path.with_file_name(format!("{stem}.partial.{}", ext.to_string_lossy())),
        None => path.with_file_name(format!("{stem}.partial")),
    };
    // A write that fails leaves the earlier file as it was, and no partial one.
    let written = write(&partial).and_then(|()| {
        std::fs::rename(&partial, path).with_context(|| format!("cannot write {}", path.display()))
    });
    if written.is_err() {
        let _ = std::fs::remove_file(&partial);
    }
    written
}

/// Writes `model.toml` (the input model, less any effect of it set aside
/// as not holding here, with the effects found, to load with `--model`)
/// and `fit.png` into `dir`, each whole or not at all.
fn write_out(
    dir: &std::path::Path,
    recording: &shoal_diagnose::Recording,
    diagnosis: &shoal_diagnose::Diagnosis,
) -> Result<(Option<PathBuf>, Option<PathBuf>)> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let path = dir.join("model.toml");
    let text = format!(
        "# Written by shoal diagnose: the input model (less what did not hold here) plus the effects it found.\n# Load it with --model, or as the body of a simulated robot.\n{}",
        diagnosis
            .model
            .to_toml()
            .context("writing the fitted model")?
    );
    write_into_place(&path, |partial| {
        std::fs::write(partial, text).with_context(|| format!("cannot write {}", partial.display()))
    })?;
    let png = dir.join("fit.png");
    write_into_place(&png, |partial| plot::fit_png(partial, recording, diagnosis))?;
    Ok((Some(path), Some(png)))
}

fn run_diagnose(args: &DiagnoseArgs) -> Result<()> {
    let load::Loaded { recording, notes } = load::load(args)?;
    let model = match &args.model {
        Some(path) => UnicycleModel::from_toml(&read(path)?, &path.display().to_string())?,
        None => UnicycleModel::plain(),
    };
    let options = Options {
        horizon_s: args.horizon,
        folds: usize::from(args.blocks),
        ..args.naming.options()
    };
    let diagnosis = diagnose(&recording, &model, &options);
    if diagnosis.segments < MIN_SEGMENTS {
        let clock = notes.clock.as_ref().map_or_else(String::new, |c| {
            format!(
                " (commands timed by {}, poses by {}: {})",
                c.commands, c.poses, c.reason
            )
        });
        // Positions only: the poses left without a heading are the likelier
        // reason, and what they were is said.
        let why = match &diagnosis.heading_from_track {
            Some(track) => format!(". Headings: {}", track.sentence()),
            None => format!(
                "; do the commands and the poses cover the same stretch of time? {}{clock}",
                recording.spans()
            ),
        };
        bail!(
            "too little to compare: {} segments of {} s with observed poses at both ends (at least {MIN_SEGMENTS} needed){why}",
            diagnosis.segments,
            options.horizon_s
        );
    }
    let mut written = Written::default();
    if let Some(dir) = &args.out {
        (written.model_out, written.plot) = write_out(dir, &recording, &diagnosis)?;
    }
    let report = report::report_text(&diagnosis, &notes);
    if let Some(path) = &args.rrd {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("cannot create {}", parent.display()))?;
        }
        // Replayed on the commands as diagnosis compared them.
        let compared = diagnosis
            .command_timeout
            .as_ref()
            .map(|timeout| timeout.applied_to(&recording));
        let segments = replay(
            compared.as_ref().unwrap_or(&recording),
            &model,
            &diagnosis.model,
            &options,
        );
        write_into_place(path, |partial| {
            rrd::write(partial, &recording, &diagnosis, &segments, &report)
        })?;
        written.rrd = Some(path.clone());
    }
    let files = [
        ("model_out", "Model", &written.model_out),
        ("plot", "Plot", &written.plot),
        ("rrd", "Recording", &written.rrd),
    ];
    if args.json {
        let mut value = serde_json::to_value(&diagnosis)?;
        value["summary"] = serde_json::json!(report::headline(&diagnosis));
        value["input"] = serde_json::to_value(&notes)?;
        for (key, _, path) in files {
            value[key] = serde_json::json!(path.as_ref().map(|p| p.display().to_string()));
        }
        print_out(|out| writeln!(out, "{value}"))
    } else {
        print_out(|out| {
            write!(out, "{report}")?;
            for (_, what, path) in files {
                if let Some(path) = path {
                    writeln!(out, "{what} written to {}", path.display())?;
                }
            }
            Ok(())
        })
    }
}

/// The files a diagnosis wrote besides its report.
#[derive(Default)]
struct Written {
    model_out: Option<PathBuf>,
    plot: Option<PathBuf>,
    rrd: Option<PathBuf>,
}

fn run_generate(args: &GenerateArgs) -> Result<()> {
    let (out, duration) = (&args.out, args.duration);
    let case = args
        .case
        .as_deref()
        .map(|name| case_named(&args.generator, name, duration).map_err(anyhow::Error::msg))
        .transpose()?;
    let model = match (&args.truth, &case) {
        (Some(path), _) => UnicycleModel::from_toml(&read(path)?, &path.display().to_string())?,
        (None, Some(case)) => UnicycleModel::with_effects(case.truth.clone()),
        (None, None) => UnicycleModel::plain(),
    };
    let recording = generate(
        &model,
        &run_settings(
            &args.generator,
            case.as_ref(),
            &args.noise,
            args.seed,
            duration,
        ),
    );
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let (commands, poses) = recording.to_csv();
    let write = |name: &str, text: &str| {
        let path = out.join(name);
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))
    };
    write("commands.csv", &commands)?;
    write("poses.csv", &poses)?;
    write(
        "truth.toml",
        &model.to_toml().context("writing the true model")?,
    )?;
    if args.bag {
        let bytes =
            shoal_bags::write::write_bag(&recording.commands.rows(), &recording.poses.rows())
                .map_err(anyhow::Error::msg)?;
        let path = out.join("run.mcap");
        std::fs::write(&path, bytes).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}

#[derive(clap::Args)]
struct GenerateArgs {
    /// A model file with the true effects; default: none.
    #[arg(long, conflicts_with = "case")]
    truth: Option<PathBuf>,
    /// One of the experiment's cases (e.g. surface_zone): its effects and
    /// its operator, so a run of the experiment can be reproduced.
    #[arg(long)]
    case: Option<String>,
    /// The experiment's noise colour to generate with.
    #[arg(long, value_parser = NoiseColour::parse, default_value = "white")]
    noise: NoiseColour,
    /// The experiment's generator: bench, waypoints, waypoints-open or speed-only.
    #[arg(long, value_parser = Generator::parse, default_value = "bench")]
    generator: Generator,
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[arg(long, default_value_t = 600.0)]
    duration: f64,
    /// Also write the run as a ROS 2 bag, run.mcap (Twist on /cmd_vel,
    /// PoseStamped on /mocap/pose).
    #[arg(long)]
    bag: bool,
}

#[derive(clap::Args)]
struct ExperimentArgs {
    /// Runs per concealed effect and noise colour.
    #[arg(long, default_value_t = 5)]
    seeds: u64,
    /// Null runs (no effect) per noise colour: the false-positive rate.
    #[arg(long, default_value_t = 40)]
    nulls: u64,
    #[arg(long, default_value_t = 600.0)]
    duration: f64,
    /// Noise colours: white (what diagnosis assumes), ou-0.2s, ou-2s,
    /// ou-5s (coloured motion noise with 2% dropped frames and 1 ms
    /// jitter), mixed (two time constants and marker swaps).
    #[arg(
        long,
        value_delimiter = ',',
        value_parser = NoiseColour::parse,
        default_value = "white,ou-0.2s,ou-2s,ou-5s,mixed"
    )]
    noise: Vec<NoiseColour>,
    /// Generators: bench (the one diagnosis was developed against, with its
    /// concealed cases), waypoints (a waypoint follower at 20 Hz, poses at
    /// 120 Hz, noise only while moving, steering on where the body is),
    /// waypoints-open (the same, steering open loop) and speed-only (held
    /// commands at 10 Hz, poses at 30 Hz, noise growing with speed, not
    /// turn rate);
    /// all but the bench run the independent cases: gains above 1, other sizes
    /// and signs, effects acting together.
    #[arg(
        long,
        value_delimiter = ',',
        value_parser = Generator::parse,
        default_value = "bench"
    )]
    generator: Vec<Generator>,
    /// Only these cases (e.g. null,latency); default: all.
    #[arg(long, value_delimiter = ',')]
    cases: Vec<String>,
    /// The first run's seed; runs take the seeds after it. A method tuned
    /// on one range of seeds is checked on another.
    #[arg(long, default_value_t = 1000)]
    first_seed: u64,
    /// Observe positions only (each heading left for diagnosis to take
    /// from the track), as a GPS or a one-marker tracker does.
    #[arg(long)]
    positions_only: bool,
    #[command(flatten)]
    naming: Naming,
    #[arg(long)]
    json: bool,
}

fn run_experiment(args: &ExperimentArgs) -> Result<()> {
    let mut rows = Vec::new();
    let options = args.naming.options();
    for generator in &args.generator {
        for noise in &args.noise {
            for case in generator.cases(args.duration) {
                if !args.cases.is_empty() && !args.cases.iter().any(|c| c == case.name) {
                    continue;
                }
                let n = if case.truth.is_empty() {
                    args.nulls
                } else {
                    args.seeds
                };
                let row = run_case(
                    generator,
                    &case,
                    noise,
                    args.first_seed..args.first_seed + n,
                    args.duration,
                    &options,
                    if args.positions_only {
                        Observed::Positions
                    } else {
                        Observed::Poses
                    },
                );
                eprintln!(
                    "{} / {} / {}: detected {:.0}%, runs naming an effect not there {:.0}%, beyond the noise {:.0}%",
                    row.generator,
                    row.noise,
                    row.name,
                    row.detection_rate * 100.0,
                    row.false_positive_rate * 100.0,
                    row.beyond_noise_rate * 100.0
                );
                rows.push(row);
            }
        }
    }
    if args.json {
        let value = serde_json::json!({ "duration_s": args.duration, "cases": rows });
        return print_out(|out| writeln!(out, "{value}"));
    }
    print_out(|out| report::experiment_table(out, &rows))
}

fn main() -> ExitCode {
    // Why selection named or passed over each effect, on request
    // (`RUST_LOG=shoal_diagnose=debug`); warnings otherwise.
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let outcome = match &cli.command {
        Some(Commands::Generate(args)) => run_generate(args),
        Some(Commands::Experiment(args)) => run_experiment(args),
        None => run_diagnose(&cli.diagnose),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<StdoutClosed>() => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("shoal diagnose: {e:#}");
            ExitCode::FAILURE
        }
    }
}

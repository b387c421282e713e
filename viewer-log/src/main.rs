//! `shoal-viewer-log`: records a running swarm into one `.rrd` file. It is a
//! subscriber like any other; if it falls behind, the bus drops samples for
//! it, and it counts them in the recording.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::Parser;
use shoal_broker::{Bus, BusLimits, RosterReader, SampleCheck, SwarmRuntime, names};
use shoal_physics::Scenario;
use shoal_viewer_log::recorder::Recorder;

/// The recording is flushed to disk at least this often, so a recorder killed
/// with SIGKILL leaves a file readable up to the last flush.
const FLUSH_EVERY: Duration = Duration::from_secs(1);
/// How often the bus is read.
const POLL: Duration = Duration::from_millis(20);

#[derive(Parser)]
#[command(version, about = "Record a running Shoal swarm into a Rerun .rrd file")]
struct Args {
    /// Where to write the recording.
    out: PathBuf,
    #[arg(long, default_value = "default")]
    swarm: String,
    /// Also write each robot's true and believed trajectory as TUM files here.
    #[arg(long)]
    tum: Option<PathBuf>,
    /// Stop after this many seconds (wall clock).
    #[arg(long)]
    duration: Option<f64>,
}

fn run(args: Args) -> Result<()> {
    let runtime = SwarmRuntime::locate(&args.swarm);
    let meta = runtime.read_meta()?;
    let scenario = Scenario::from_file(&runtime.scenario_path())?;
    let bus = Bus::join(
        &args.swarm,
        &names::tool_node(&args.swarm, &format!("recorder-{}", std::process::id())),
        BusLimits::default(),
    )?;
    let roster = RosterReader::new(&bus)?;
    let progress = shoal_broker::robot_streams::progress_publisher(&bus, "recorder")?;
    let mut slam_views = shoal_viewer_log::slam::SlamViews::new(&bus)?;
    // Chunks are cut once a second rather than every few milliseconds: each
    // chunk carries overhead, and a second is what the flush promises anyway.
    let batching = rerun::log::ChunkBatcherConfig {
        flush_tick: FLUSH_EVERY,
        ..rerun::log::ChunkBatcherConfig::DEFAULT
    };
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating the folder of {}", args.out.display()))?;
    }
    let rec = rerun::RecordingStreamBuilder::new("shoal")
        .batcher_config(batching)
        .save(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let mut recorder = Recorder::new(rec, &scenario, args.tum.as_deref())?;
    recorder.event(&format!(
        "recording swarm `{}` ({})",
        args.swarm,
        if meta.lockstep {
            "lockstep"
        } else {
            "real time"
        }
    ))?;
    let mut check = SampleCheck::for_map(scenario.arena.width, scenario.arena.height, 1.0);
    let silent_ticks = (scenario.timing.stale_periods.ceil() as u64).max(1) + 1;
    let started = Instant::now();
    let mut last_flush = Instant::now();
    let mut newest_tick = 0;
    while !bus.termination_requested()
        && args
            .duration
            .is_none_or(|d| started.elapsed().as_secs_f64() < d)
    {
        roster.receive(|sample| {
            if check.accept(&sample) {
                newest_tick = newest_tick.max(sample.tick);
                recorder.add(sample);
            }
        })?;
        // A lockstep launcher paces its clock to this, so no tick is missed.
        progress.publish(&shoal_broker::HelperProgress { tick: newest_tick })?;
        recorder.log_complete()?;
        slam_views.poll(&bus, recorder.stream())?;
        recorder.set_rejected(check.rejected + roster.rejected() + slam_views.rejected());
        recorder.forget_silent(newest_tick, silent_ticks)?;
        if last_flush.elapsed() >= FLUSH_EVERY {
            last_flush = Instant::now();
            recorder.flush()?;
        }
        std::thread::sleep(POLL);
    }
    recorder.log_all()?;
    let stats = recorder.stats;
    recorder.event(&format!(
        "recording stopped: {} frames, {} samples, {} dropped by the bus, {} rejected",
        stats.frames, stats.samples, stats.dropped, stats.rejected
    ))?;
    recorder.flush()?;
    eprintln!(
        "shoal-viewer-log: wrote {} ({} frames, {} dropped, {} rejected)",
        args.out.display(),
        stats.frames,
        stats.dropped,
        stats.rejected
    );
    Ok(())
}

fn main() -> std::process::ExitCode {
    shoal_broker::process_main::run_main("shoal-viewer-log", "warn", || run(Args::parse()))
}

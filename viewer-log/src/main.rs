//! `shoal-viewer-log`: records a running swarm into one `.rrd` file. It is a
//! subscriber like any other; if it falls behind, the bus drops samples for
//! it, and it counts them in the recording.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::Parser;
use shoal_broker::{Bus, BusLimits, SampleCheck, names};
use shoal_runtime::SwarmRuntime;
use shoal_viewer_log::recorder::Recorder;

/// The recording is flushed to disk at least this often, so a recorder killed
/// with SIGKILL leaves a file readable up to the last flush.
const FLUSH_EVERY: Duration = Duration::from_secs(1);
/// How often the bus is read.
const POLL: Duration = Duration::from_millis(20);

#[derive(Parser)]
#[command(
    version,
    about = "Record a running Shoal swarm into a Rerun .rrd file, a live Rerun viewer, or both"
)]
struct Args {
    /// Where to write the recording.
    #[arg(required_unless_present_any = ["viewer", "connect"])]
    out: Option<PathBuf>,
    /// Stream the run live to a Rerun viewer started now (`rerun` on PATH;
    /// one already running on its port is reused).
    #[arg(long)]
    viewer: bool,
    /// Stream the run live to a Rerun viewer already running at this
    /// address (HOST:PORT, or a rerun+http://HOST:PORT/proxy URL).
    #[arg(long, value_name = "ADDR", conflicts_with = "viewer")]
    connect: Option<String>,
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
    let scenario = runtime.read_scenario()?;
    let bus = Bus::join(
        &args.swarm,
        &names::tool_node(&args.swarm, &format!("recorder-{}", std::process::id())),
        BusLimits::default(),
    )?;
    let roster = shoal_broker::roster::reader(&bus)?;
    let progress = shoal_broker::robot_streams::progress_publisher(&bus, "recorder")?;
    let mut slam_views = shoal_viewer_log::slam::SlamViews::new(&bus)?;
    // Chunks are cut once a second rather than every few milliseconds: each
    // chunk carries overhead, and a second is what the flush promises anyway.
    let batching = rerun::log::ChunkBatcherConfig {
        flush_tick: FLUSH_EVERY,
        ..rerun::log::ChunkBatcherConfig::DEFAULT
    };
    let live = live_url(args.viewer, args.connect.as_deref())?;
    let mut sinks: Vec<Box<dyn rerun::sink::LogSink>> = Vec::new();
    if let Some(out) = &args.out {
        if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating the folder of {}", out.display()))?;
        }
        sinks.push(Box::new(
            rerun::sink::FileSink::new(out)
                .with_context(|| format!("creating {}", out.display()))?,
        ));
    }
    if let Some(url) = &live {
        sinks.push(Box::new(rerun::sink::GrpcSink::new(url.clone())));
        eprintln!("shoal-viewer-log: streaming live to the Rerun viewer at {url}");
    }
    let rec = rerun::RecordingStreamBuilder::new("shoal")
        .batcher_config(batching)
        .set_sinks(sinks)
        .context("starting the recording")?;
    let mut recorder = Recorder::new(rec, &scenario, args.tum.as_deref(), live.is_some())?;
    recorder.event(&format!(
        "recording swarm `{}` ({})",
        args.swarm,
        if meta.lockstep {
            "lockstep"
        } else {
            "real time"
        }
    ))?;
    let mut check = SampleCheck::for_scenario(&scenario);
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
            if let Some(link) = runtime.read_link_report() {
                recorder.set_remote_hosts(
                    link.pid,
                    link.robots()
                        .map(|(host, r)| (r.id, host.to_owned()))
                        .collect(),
                );
            }
            recorder.flush()?;
            if !runtime.is_up() {
                recorder.event(&format!("swarm `{}` stopped", args.swarm))?;
                break;
            }
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
        "shoal-viewer-log: {} ({} frames, {} dropped, {} rejected)",
        match &args.out {
            Some(out) => format!("wrote {}", out.display()),
            None => "streamed live".to_owned(),
        },
        stats.frames,
        stats.dropped,
        stats.rejected
    );
    Ok(())
}

/// Where to stream live, if anywhere: a viewer started now (`--viewer`), or
/// one already running (`--connect`).
fn live_url(
    viewer: bool,
    connect: Option<&str>,
) -> Result<Option<rerun::external::re_uri::ProxyUri>> {
    use std::str::FromStr as _;
    let text = if viewer {
        let spawned = rerun::spawn(&rerun::SpawnOptions::default()).map_err(|e| {
            anyhow::anyhow!(
                "--viewer: cannot start the Rerun viewer: {e}\n\
                 (or record with --record run.rrd and open it later with `rerun run.rrd`)"
            )
        })?;
        format!("rerun+http://127.0.0.1:{}/proxy", spawned.port)
    } else if let Some(addr) = connect {
        if addr.contains("://") {
            addr.to_owned()
        } else {
            format!("rerun+http://{addr}/proxy")
        }
    } else {
        return Ok(None);
    };
    rerun::external::re_uri::ProxyUri::from_str(&text)
        .map(Some)
        .map_err(|e| anyhow::anyhow!("--connect {text}: not a Rerun viewer address (HOST:PORT or rerun+http://HOST:PORT/proxy): {e}"))
}

fn main() -> std::process::ExitCode {
    shoal_runtime::process_main::run_main("shoal-viewer-log", "warn", || run(Args::parse()))
}

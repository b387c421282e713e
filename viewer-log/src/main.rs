//! `shoal-viewer-log`: records a running swarm into one `.rrd` file. It is a
//! subscriber like any other; if it falls behind, the bus drops samples for
//! it, and it counts them in the recording.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::Parser;
use shoal_broker::{Bus, BusLimits, SampleCheck};
use shoal_runtime::SwarmRuntime;
use shoal_viewer_log::recorder::{Frame, Recorder};
use shoal_viewer_log::rrd_file::{RrdFileSink, RrdFileState, WriteFault};
use shoal_viewer_log::space::{self, SpaceWatch};

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
    #[arg(required_unless_present_any = ["viewer", "connect", "repair"])]
    out: Option<PathBuf>,
    /// Cut a partly written last message off a recording whose recorder
    /// was killed or lost power mid-write, so every reader reads it to its
    /// last whole message; then exit.
    #[arg(long, value_name = "FILE", exclusive = true)]
    repair: Option<PathBuf>,
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
    /// How long the run is expected to last, in simulated seconds (from
    /// `shoal up --duration`): the recorder warns at the start when the
    /// disk will not hold it.
    #[arg(long, hide = true)]
    expected_seconds: Option<f64>,
}

/// Cuts the partial tail off `path` and says what it did.
fn repair(path: &std::path::Path) -> Result<()> {
    let cut = shoal_viewer_log::rrd_file::cut_partial_tail(path)?;
    if cut == 0 {
        eprintln!(
            "shoal-viewer-log: {} ends on a whole message; nothing to cut",
            path.display()
        );
    } else {
        eprintln!(
            "shoal-viewer-log: cut a partly written last message ({cut} bytes) off {}; \
             it now reads to its last whole message",
            path.display()
        );
    }
    Ok(())
}

/// The error for a recording that cannot be written: what failed, what the
/// file holds, and what to do.
fn fault_error(fault: &WriteFault, kept: Option<Frame>) -> anyhow::Error {
    let holds = match kept {
        Some(frame) => format!(
            "the file holds the run up to tick {} ({:.1} s simulated) and reads to its end",
            frame.tick, frame.sim_time
        ),
        None => "the file holds no frame of the run yet".to_owned(),
    };
    anyhow::Error::new(RecordingLost(format!("{fault}; {holds}. {WHAT_TO_DO}")))
}

/// A recording that cannot be written, said with what it holds and what to
/// do: an error that needs no more context.
#[derive(Debug)]
struct RecordingLost(String);

impl std::fmt::Display for RecordingLost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for RecordingLost {}

/// What a user does about a recording that cannot be written.
const WHAT_TO_DO: &str = "The swarm goes on without its recording: free space on that file \
     system (or make it writable), or record to another with --record PATH (`shoal record \
     PATH` joins a running swarm)";

fn run(args: Args) -> Result<()> {
    if let Some(path) = &args.repair {
        return repair(path);
    }
    let mut session = Session::open(&args)?;
    let started = Instant::now();
    let mut last_flush = Instant::now();
    while !session.bus.termination_requested()
        && args
            .duration
            .is_none_or(|d| started.elapsed().as_secs_f64() < d)
    {
        session.poll().map_err(|e| session.failed(e))?;
        if last_flush.elapsed() >= FLUSH_EVERY {
            last_flush = Instant::now();
            if !session.each_second().map_err(|e| session.failed(e))? {
                break;
            }
        }
        std::thread::sleep(POLL);
    }
    session.finish(args.out.as_deref())
}

/// One recording of a running swarm: what it reads from the bus, what it
/// writes, and what the file is known to hold.
struct Session {
    swarm: String,
    runtime: SwarmRuntime,
    bus: Bus,
    roster: shoal_broker::RosterReader,
    progress: shoal_broker::Sender<shoal_broker::HelperProgress>,
    slam_views: shoal_viewer_log::slam::SlamViews,
    recorder: Recorder,
    check: SampleCheck,
    silent_ticks: u64,
    newest_tick: u64,
    file: Option<RrdFileState>,
    /// The newest frame the file is known to hold (flushed without a fault).
    kept: Option<Frame>,
    space_watch: Option<SpaceWatch>,
    /// How long the run lasts, if known, for the estimate of its size,
    /// made once the first second is written.
    expected_seconds: Option<f64>,
    robots: usize,
    estimated: bool,
    /// Whether the user was told a flush did not complete.
    told_flush_stalled: bool,
    /// Whether the user was told the link's report cannot be read.
    unreadable_link_report_said: bool,
}

impl Session {
    fn open(args: &Args) -> Result<Self> {
        let runtime = SwarmRuntime::locate(&args.swarm);
        let meta = runtime.read_meta()?;
        // Off the recording's path: a swarm killed whole may have left
        // many nodes, and a lockstep clock waits for this recorder.
        std::thread::spawn(
            || match shoal_broker::liveness::remove_dead_nodes_of_abandoned_swarms() {
                Ok(swept) => {
                    if let Some(swept) = shoal_broker::liveness::describe_swept(&swept) {
                        eprintln!("shoal-viewer-log: {swept}");
                    }
                }
                Err(e) => tracing::warn!("sweeping the dead nodes of abandoned swarms: {e}"),
            },
        );
        let scenario = runtime.read_scenario()?;
        let bus = Bus::join_tool(
            &args.swarm,
            &format!("recorder-{}", std::process::id()),
            BusLimits::default(),
        )?;
        let (rec, file, live) = open_stream(args)?;
        let recorder = Recorder::new(rec, &scenario, args.tum.as_deref(), live)?;
        recorder.event(&format!(
            "recording swarm `{}` ({})",
            args.swarm,
            if meta.lockstep {
                "lockstep"
            } else {
                "real time"
            }
        ))?;
        Ok(Self {
            swarm: args.swarm.clone(),
            roster: shoal_broker::roster::reader(&bus)?,
            progress: shoal_broker::robot_streams::progress_publisher(
                &bus,
                shoal_broker::robot_streams::RECORDER_PROGRESS,
            )?,
            slam_views: shoal_viewer_log::slam::SlamViews::new(&bus)?,
            recorder,
            check: SampleCheck::for_scenario(&scenario),
            silent_ticks: (scenario.timing.stale_periods.ceil() as u64).max(1) + 1,
            newest_tick: 0,
            space_watch: args.out.as_deref().map(SpaceWatch::new),
            file,
            kept: None,
            expected_seconds: args.expected_seconds.or(args.duration),
            robots: scenario.agents.count,
            estimated: false,
            told_flush_stalled: false,
            unreadable_link_report_said: false,
            runtime,
            bus,
        })
    }

    /// Where the recording is, for an error's context.
    fn at(&self) -> String {
        match self.recorder.last_frame {
            Some(f) => format!(
                "recording swarm `{}` at tick {} ({:.1} s simulated)",
                self.swarm, f.tick, f.sim_time
            ),
            None => format!("recording swarm `{}` before its first tick", self.swarm),
        }
    }

    /// An error of the loop, with where the recording was; one of storage
    /// (a TUM file on a disk that failed) also says what the recording
    /// holds and what to do, as a fault of the `.rrd` itself does.
    fn failed(&self, error: anyhow::Error) -> anyhow::Error {
        let storage = error.chain().any(|cause| cause.is::<std::io::Error>());
        let error = error.context(self.at());
        if !storage || error.chain().any(|c| c.is::<RecordingLost>()) {
            return error;
        }
        let holds = match self.kept {
            Some(f) => format!("up to tick {} ({:.1} s simulated)", f.tick, f.sim_time),
            None => "no frame yet".to_owned(),
        };
        anyhow::Error::new(RecordingLost(format!(
            "{error:#}; the recording holds the run {holds}. {WHAT_TO_DO}"
        )))
    }

    /// Tells the recorder which robots this host's link stands in for, and
    /// for which hosts. A link report that cannot be read costs the
    /// recording only its robots' host tags: said once, and the recording
    /// goes on.
    fn read_link_report(&mut self) {
        let link = self
            .runtime
            .read_report::<shoal_link::report::LinkReport>()
            .unwrap_or_else(|e| {
                if !self.unreadable_link_report_said {
                    tracing::warn!("robots of other hosts are not tagged with their host: {e}");
                    self.unreadable_link_report_said = true;
                }
                None
            });
        self.recorder.set_remote_hosts(link.map(|link| {
            let remote = link
                .robots()
                .map(|(host, r)| (r.id, host.to_owned()))
                .collect();
            (link.pid, remote)
        }));
    }

    /// Reads the bus and logs every tick that is complete.
    fn poll(&mut self) -> Result<()> {
        let (check, recorder, newest_tick) =
            (&mut self.check, &mut self.recorder, &mut self.newest_tick);
        self.roster.receive(|sample| {
            if check.accept(&sample) {
                *newest_tick = (*newest_tick).max(sample.tick);
                recorder.add(sample);
            }
        })?;
        if self.recorder.hosts_stale() {
            self.read_link_report();
        }
        // A lockstep launcher paces its clock to this, so no tick is missed.
        self.progress.publish(&shoal_broker::HelperProgress {
            tick: self.newest_tick,
        })?;
        self.recorder.log_complete()?;
        self.slam_views.poll(&self.bus, self.recorder.stream())?;
        self.recorder.set_rejected(
            self.check.rejected + self.roster.rejected() + self.slam_views.rejected(),
        );
        self.recorder
            .forget_silent(self.newest_tick, self.silent_ticks)
    }

    /// Flushes and checks the file and its disk; false once the swarm has
    /// stopped.
    fn each_second(&mut self) -> Result<bool> {
        self.read_link_report();
        self.flush()?;
        if let Some(file) = self.file.clone() {
            let warning = self
                .space_watch
                .as_mut()
                .and_then(|w| w.check(Instant::now(), file.written()));
            if let Some(warning) = warning.or_else(|| self.estimate_once()) {
                eprintln!(
                    "shoal-viewer-log: warning: {}: {warning}",
                    file.path().display()
                );
            }
        }
        if !self.runtime.is_up() {
            self.recorder
                .event(&format!("swarm `{}` stopped", self.swarm))?;
            return Ok(false);
        }
        Ok(true)
    }

    /// Flushes; a file that cannot be written ends the recording with an
    /// error, a flush that stalls is said once.
    fn flush(&mut self) -> Result<()> {
        let logged = self.recorder.last_frame;
        let stalled = self.recorder.flush()?;
        if let Some(fault) = self.file.as_ref().and_then(RrdFileState::fault) {
            return Err(fault_error(&fault, self.kept));
        }
        match stalled {
            Some(reason) if !self.told_flush_stalled => {
                self.told_flush_stalled = true;
                eprintln!(
                    "shoal-viewer-log: warning: {} did not take the recording in time ({reason}); \
                     recording goes on",
                    if self.file.is_some() {
                        "the disk or the live viewer"
                    } else {
                        "the live viewer"
                    }
                );
            }
            Some(_) => {}
            None => self.kept = logged,
        }
        Ok(())
    }

    /// Once the first second is written (the arena and the first frames):
    /// the warning when the run's expected size will not fit.
    fn estimate_once(&mut self) -> Option<String> {
        if self.estimated {
            return None;
        }
        self.estimated = true;
        let file = self.file.as_ref()?;
        let free = space::free_bytes(&space::folder_of(file.path()))?;
        space::estimate_warning(free, file.written(), self.robots, self.expected_seconds?)
    }

    /// Logs what is left, ends the file and says what was written.
    fn finish(mut self, out: Option<&std::path::Path>) -> Result<()> {
        self.recorder.log_all().with_context(|| self.at())?;
        let stats = self.recorder.stats;
        self.recorder.event(&format!(
            "recording stopped: {} frames, {} samples, {} dropped by the bus, {} rejected",
            stats.frames, stats.samples, stats.dropped, stats.rejected
        ))?;
        self.flush().with_context(|| self.at())?;
        let (file, kept) = (self.file.clone(), self.kept);
        // Dropping the stream ends the file: its footer, within the sink's limit.
        drop(self);
        if let Some(fault) = file.as_ref().and_then(RrdFileState::fault) {
            return Err(fault_error(&fault, kept));
        }
        eprintln!(
            "shoal-viewer-log: {} ({} frames, {} dropped, {} rejected)",
            match out {
                Some(out) => format!("wrote {}", out.display()),
                None => "streamed live".to_owned(),
            },
            stats.frames,
            stats.dropped,
            stats.rejected
        );
        Ok(())
    }
}

/// The recording stream, its file (if any) and whether it streams live.
fn open_stream(args: &Args) -> Result<(rerun::RecordingStream, Option<RrdFileState>, bool)> {
    // Chunks are cut once a second rather than every few milliseconds: each
    // chunk carries overhead, and a second is what the flush promises anyway.
    let batching = rerun::log::ChunkBatcherConfig {
        flush_tick: FLUSH_EVERY,
        ..rerun::log::ChunkBatcherConfig::DEFAULT
    };
    let live = live_url(args.viewer, args.connect.as_deref())?;
    let mut sinks: Vec<Box<dyn rerun::sink::LogSink>> = Vec::new();
    let mut file = None;
    if let Some(out) = &args.out {
        if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating the folder of {}", out.display()))?;
        }
        let (sink, state) = RrdFileSink::create(out)?;
        sinks.push(Box::new(sink));
        file = Some(state);
    }
    if let Some(url) = &live {
        sinks.push(Box::new(rerun::sink::GrpcSink::new(url.clone())));
        eprintln!("shoal-viewer-log: streaming live to the Rerun viewer at {url}");
    }
    let rec = rerun::RecordingStreamBuilder::new("shoal")
        .batcher_config(batching)
        .set_sinks(sinks)
        .context("starting the recording")?;
    Ok((rec, file, live.is_some()))
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

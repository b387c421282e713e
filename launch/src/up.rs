//! `shoal up`: start a swarm and watch it until Ctrl-C or the duration ends.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use shoal_scenario::Scenario;
use shoal_slam::follow::{Follow, SlamSection};

use shoal_swarm::observer::Timeliness;
use shoal_swarm::{Launch, RecordOptions, RunningSwarm};

pub struct UpOptions {
    pub swarm: String,
    pub scenario: Option<PathBuf>,
    pub agents: Option<usize>,
    pub seed: Option<u64>,
    /// Clock mode, robot ids and the link to other hosts.
    pub launch: Launch,
    pub duration_s: Option<f64>,
    pub json: bool,
    pub record: RecordOptions,
    /// Robots a SLAM process follows (added to the scenario's `[slam]
    /// follow`), all of them, or none whatever the scenario says.
    pub slam: Option<SlamAsked>,
}

/// What `shoal up --slam` asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum SlamAsked {
    /// These robots followed too, beside the scenario's.
    Follow(Follow),
    /// No SLAM process, whatever the scenario's `[slam]` says: the swarm
    /// alone, with SLAM started beside it by hand (`shoal slam`), as a
    /// benchmark of SLAM against a live swarm runs it.
    None,
}

impl SlamAsked {
    /// Whom SLAM follows, the scenario asking for `scenario`'s robots.
    pub fn applied_to(&self, scenario: Follow) -> Follow {
        match self {
            SlamAsked::Follow(more) => scenario.and(more),
            SlamAsked::None => Follow::default(),
        }
    }
}

impl std::str::FromStr for SlamAsked {
    type Err = String;

    /// `none`, `all`, or robot ids separated by commas (`0,3`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        if text.trim() == "none" {
            return Ok(SlamAsked::None);
        }
        text.parse::<Follow>()
            .map(SlamAsked::Follow)
            .map_err(|e| format!("{e}, or `none`"))
    }
}

/// Fails before anything starts when `--viewer` cannot work: the Rerun
/// viewer is the `rerun` program, which Shoal does not ship.
fn check_viewer_installed() -> Result<()> {
    let found = std::env::var_os("PATH").is_some_and(|path| {
        std::env::split_paths(&path).any(|dir| {
            std::fs::metadata(dir.join("rerun")).is_ok_and(|m| {
                m.is_file()
                    && std::os::unix::fs::PermissionsExt::mode(&m.permissions()) & 0o111 != 0
            })
        })
    });
    if !found {
        bail!(
            "--viewer needs the Rerun viewer, the program `rerun`, on PATH, and there is none; \
             install it with `pip install rerun-sdk==0.36.3` (or `cargo binstall rerun-cli@0.36.3`), \
             or record with --record run.rrd and open that later with `rerun run.rrd`"
        );
    }
    Ok(())
}

#[derive(Debug, Serialize)]
pub struct UpSummary {
    pub swarm: String,
    pub lockstep: bool,
    pub ticks: u64,
    pub sim_time_s: f64,
    pub agents: usize,
    pub components: usize,
    pub spacing_ratio: f64,
    pub spacing_cv: f64,
    /// When the formation last became (and stayed) formed, in simulated seconds.
    pub converge_s: Option<f64>,
    pub rejected_samples: u64,
    /// Whether real time held once every robot had joined (in lockstep,
    /// ages are in simulated time).
    #[serde(flatten)]
    pub timeliness: Timeliness,
}

pub fn load_scenario(path: Option<&PathBuf>) -> Result<Scenario> {
    Ok(match path {
        Some(path) => shoal_runtime::read_scenario(path)?,
        None => Scenario::default_arena(),
    })
}

/// Stops the swarm and says how it ended; an error if a robot or helper
/// crashed during the run.
/// The run's summary: JSON on stdout, or lines on stderr beside the
/// launcher's other lines.
fn print_summary(summary: &UpSummary, json: bool) -> Result<()> {
    if json {
        let line = serde_json::to_string(&summary)?;
        shoal_runtime::process_main::print_out(|out| writeln!(out, "{line}"))?;
    } else {
        eprintln!(
            "shoal: {} robots, {} group(s), spacing {:.2} x spread (cv {:.2}), formed since {}",
            summary.agents,
            summary.components,
            summary.spacing_ratio,
            summary.spacing_cv,
            summary
                .converge_s
                .map_or_else(|| "never".to_owned(), |t| format!("{t:.1} s"))
        );
        if !summary.lockstep {
            let t = &summary.timeliness;
            let ms = |age: Option<u32>| age.map_or_else(|| "-".to_owned(), |a| format!("{a} ms"));
            let counted = t.counted_from_s.map_or_else(
                || "since the launch (not every robot was heard)".to_owned(),
                |s| format!("once every robot had joined ({s:.1} s after the launch)"),
            );
            eprintln!(
                "shoal: real time, {counted}: {:.2} missed periods per robot \
                 (at most {}); the oldest neighbour pose a robot acted on was {} old at p50, {} at p99",
                t.missed_periods_mean,
                t.missed_periods_max,
                ms(t.neighbour_age_p50_ms),
                ms(t.neighbour_age_p99_ms)
            );
        }
    }
    Ok(())
}

fn stop(
    mut swarm: RunningSwarm,
    options: &UpOptions,
    converged_since: Option<f64>,
) -> Result<UpSummary> {
    let spread = swarm.scenario.formation.spread;
    let metrics = swarm.observer.metrics(spread);
    let summary = UpSummary {
        swarm: swarm.name.clone(),
        lockstep: swarm.lockstep(),
        ticks: swarm
            .clock
            .as_ref()
            .map_or(swarm.observer.newest_tick, |c| c.tick),
        sim_time_s: swarm.sim_time(),
        agents: metrics.agents,
        components: metrics.components,
        spacing_ratio: metrics.spacing_ratio,
        spacing_cv: metrics.spacing_cv,
        converge_s: converged_since,
        rejected_samples: swarm.rejected_samples(),
        timeliness: swarm.observer.timeliness(),
    };
    eprintln!("shoal: stopping swarm `{}`", swarm.name);
    swarm.shutdown()?;
    for death in swarm.take_deaths() {
        eprintln!("shoal: {death}");
    }
    for note in swarm.stop_notes() {
        eprintln!("shoal: {note}");
    }
    if let Some(out) = &options.record.out
        && !swarm
            .deaths()
            .iter()
            .any(|d| d.crashed && d.who == shoal_swarm::RECORDER_BINARY)
    {
        eprintln!(
            "shoal: recording in {}; to watch it: pip install rerun-sdk, then rerun {}",
            out.display(),
            out.display()
        );
    }
    print_summary(&summary, options.json)?;
    let crashed: Vec<&shoal_swarm::Death> = swarm.deaths().iter().filter(|d| d.crashed).collect();
    if !crashed.is_empty() {
        // Said when it happened, and again here, where a user reads last.
        let said: Vec<String> = crashed.iter().map(|d| d.to_string()).collect();
        bail!(
            "{} during the run:\n  {}\ntheir logs are kept in {}",
            if crashed.len() == 1 {
                "a process died"
            } else {
                "processes died"
            },
            said.join("\n  "),
            swarm.runtime.dir.display()
        );
    }
    if !swarm.deaths().is_empty() {
        eprintln!(
            "shoal: the logs of robots killed during the run are kept in {}",
            swarm.runtime.dir.display()
        );
    }
    Ok(summary)
}

/// From this many robots on, where iceoryx2 keeps its files shows in the
/// start-up time.
const MANY_ROBOTS: usize = 200;

/// Says how to start a big swarm faster when iceoryx2 keeps its files on a
/// disk. iceoryx2 writes a file into a node's folder for every port and
/// service a robot opens, and deletes it when the port goes: tens of
/// thousands for 1000 robots. On this machine's ext4 (no journal) that was
/// a third of start-up: 1000 robots started in 22-29 s with iceoryx2's
/// default `/tmp/iceoryx2`, 7.8 s with its root in `/dev/shm`
/// (BENCHMARKS.md, "Start-up"). The root is the user's to choose: every
/// iceoryx2 program of the machine, Python ones included, must agree on it.
fn warn_if_iceoryx_on_disk(robots: usize) {
    if robots < MANY_ROBOTS {
        return;
    }
    let root = shoal_broker::bus::iceoryx_root();
    if shoal_broker::bus::in_memory(&root) == Some(false) {
        eprintln!(
            "shoal: iceoryx2 keeps its node and service files in {} on a disk file system; \
             {robots} robots start several times faster with iceoryx2's root in memory: \
             write `[global]` and `root-path = \"/dev/shm/iceoryx2/\"` into \
             ~/.config/iceoryx2/iceoryx2.toml (every iceoryx2 program of this user then \
             uses it; README, \"Many robots\")",
            root.display()
        );
    }
}

/// The scenario `shoal up` runs: the file given (or the default arena),
/// with the command line's robot count, seed and SLAM robots.
fn scenario_for(options: &UpOptions) -> Result<Scenario> {
    let mut scenario = match (&options.scenario, options.agents) {
        (None, Some(count)) => {
            let scenario = Scenario::default_for(count);
            if scenario.arena != Scenario::default_arena().arena {
                eprintln!(
                    "shoal: {count} robots do not fit the default arena's start region; \
                     using an open {:.0} x {:.0} m arena (--scenario FILE chooses another)",
                    scenario.arena.width, scenario.arena.height
                );
            }
            scenario
        }
        (path, count) => {
            let mut scenario = load_scenario(path.as_ref())?;
            if let Some(count) = count {
                scenario.agents.count = count;
            }
            let crowded = scenario.crowded_starts();
            if crowded > 0 {
                tracing::warn!(
                    "{crowded} of {} robots find no free place in agents.start_region {:?} \
                     and start overlapping; a larger region holds them",
                    scenario.agents.count,
                    scenario.agents.start_region
                );
            }
            scenario
        }
    };
    if let Some(seed) = options.seed {
        scenario.agents.seed = seed;
    }
    if let Some(asked) = &options.slam {
        let mut slam: SlamSection = scenario.section()?;
        slam.follow = asked.applied_to(slam.follow);
        scenario.set_section(&slam)?;
    }
    Ok(scenario)
}

/// Where `shoal up` tells the user how the swarm is doing: a spinner line
/// on a terminal, a line every few seconds otherwise.
struct Status {
    bar: Option<ProgressBar>,
    last_update: Instant,
    last_line: Instant,
}

impl Status {
    fn new() -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let bar = ProgressBar::new_spinner();
            bar.set_style(
                ProgressStyle::with_template("{spinner} {elapsed} {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner()),
            );
            bar.enable_steady_tick(Duration::from_millis(200));
            bar
        });
        Self {
            bar,
            last_update: Instant::now(),
            last_line: Instant::now(),
        }
    }

    /// A line that must be seen (a death), above the spinner.
    fn say(&self, line: &str) {
        match &self.bar {
            Some(bar) => bar.suspend(|| eprintln!("shoal: {line}")),
            None => eprintln!("shoal: {line}"),
        }
    }

    /// A line a helper wrote for the user, as it wrote it.
    fn relay(&self, line: &str) {
        match &self.bar {
            Some(bar) => bar.suspend(|| eprintln!("{line}")),
            None => eprintln!("{line}"),
        }
    }

    /// The swarm's state now; shown 4 times a second, or every 5 s as a line.
    fn update(&mut self, message: impl FnOnce() -> String) {
        if self.last_update.elapsed() < Duration::from_millis(250) {
            return;
        }
        self.last_update = Instant::now();
        match &self.bar {
            Some(bar) => bar.set_message(message()),
            None if self.last_line.elapsed() >= Duration::from_secs(5) => {
                self.last_line = Instant::now();
                eprintln!("shoal: {}", message());
            }
            None => {}
        }
    }

    fn finish(self) {
        if let Some(bar) = self.bar {
            bar.finish_and_clear();
        }
    }
}

/// Refuses counts and ranges that cannot make a run, before anything is
/// said or started (the command line checks each value alone).
fn check_command_line(options: &UpOptions) -> Result<()> {
    if options.agents == Some(0) {
        bail!("--agents 0: a swarm needs at least one robot");
    }
    if let Some(count) = options.agents {
        shoal_swarm::process::check_id_range(options.launch.first_id, count)?;
    }
    Ok(())
}

pub fn up(options: UpOptions) -> Result<UpSummary> {
    check_command_line(&options)?;
    if options.record.viewer {
        check_viewer_installed()?;
    }
    let scenario = scenario_for(&options)?;
    warn_if_iceoryx_on_disk(scenario.agents.count);
    let follow = scenario.section::<SlamSection>()?.follow;
    let spread = scenario.formation.spread;
    let mut swarm = RunningSwarm::launch_with(&options.swarm, scenario, &options.launch)?;
    let robots = swarm.scenario.agents.count;
    swarm.observer.reset_timeliness_once_heard(robots);
    if options.record.wanted() {
        swarm.record(&options.record)?;
    }
    if !follow.is_empty() {
        swarm.follow_with_slam(&follow, &[])?;
    }
    let mut status = Status::new();
    eprintln!(
        "shoal: swarm `{}` up with {} robots ({}); Ctrl-C stops it",
        swarm.name,
        swarm.scenario.agents.count,
        if swarm.lockstep() {
            "lockstep"
        } else {
            "real time"
        }
    );
    let mut converged_since: Option<f64> = None;
    loop {
        if swarm.termination_requested() {
            break;
        }
        if options.duration_s.is_some_and(|d| swarm.sim_time() >= d) {
            break;
        }
        swarm.advance()?;
        for death in swarm.take_deaths() {
            status.say(&death.to_string());
        }
        for warning in swarm.take_helper_warnings() {
            status.relay(&warning);
        }
        if swarm.running_children() == 0 && swarm.observer.is_empty() && !swarm.deaths().is_empty()
        {
            eprintln!("shoal: every robot of swarm `{}` has stopped", swarm.name);
            break;
        }
        let metrics = swarm.observer.metrics(spread);
        match (metrics.is_formed(), converged_since) {
            (true, None) => converged_since = Some(swarm.sim_time()),
            (false, Some(_)) => converged_since = None,
            _ => {}
        }
        status.update(|| {
            format!(
                "robots {} | tick {} | t {:.1} s | groups {} | spacing {:.2} x spread | cv {:.2}",
                swarm.observer.len(),
                swarm.observer.newest_tick,
                swarm.sim_time(),
                metrics.components,
                metrics.spacing_ratio,
                metrics.spacing_cv
            )
        });
    }
    status.finish();
    stop(swarm, &options, converged_since)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slam_none_starts_no_slam_whatever_the_scenario_asks_and_ids_add_to_it() {
        let none: SlamAsked = "none".parse().expect("a word it knows");
        assert!(none.applied_to(Follow::All).is_empty());
        let some: SlamAsked = "0,3".parse().expect("ids");
        assert_eq!(
            some.applied_to(Follow::Robots(vec![3, 5])),
            Follow::Robots(vec![3, 5, 0])
        );
        let wrong = "nobody".parse::<SlamAsked>().expect_err("not a choice");
        assert!(wrong.contains("`none`"), "{wrong}");
    }
}

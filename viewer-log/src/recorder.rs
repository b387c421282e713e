//! Turns what the bus carries into a Rerun recording, tick by tick. Who
//! joined and left is `presence`'s to say, the files beside the recording
//! `run_files`' to write.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use glam::DVec2;
use rerun::RecordingStream;
use shoal_broker::{Health, PoseSample};
use shoal_physics::metrics::formation_metrics;
use shoal_scenario::Scenario;

use crate::presence::Presence;
use crate::run_files::RunFiles;

/// Trails are logged every this many ticks; positions every tick.
const TRAIL_EVERY_TICKS: u64 = 5;
/// How long a flush waits for a live viewer before the recorder moves on.
const LIVE_FLUSH_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(1);

/// Counts of what the recorder saw, also written into the recording.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RecorderStats {
    pub frames: u64,
    pub samples: u64,
    /// Samples the bus overwrote before the recorder read them (it fell behind).
    pub dropped: u64,
    /// Samples rejected as malformed.
    pub rejected: u64,
}

/// The newest frame logged: a tick and its simulated time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Frame {
    pub tick: u64,
    pub sim_time: f64,
}

pub struct Recorder {
    rec: RecordingStream,
    spread: f64,
    presence: Presence,
    pending: BTreeMap<u64, Vec<PoseSample>>,
    last_health: HashMap<u32, u32>,
    files: Option<RunFiles>,
    /// The model the robots ran with: what their executed commands mean.
    motion: shoal_physics::MotionModel,
    period_s: f64,
    /// This host's name, and the host of each robot that runs on another
    /// (`shoal up --link`): a linked recording holds every host's robots.
    own_host: String,
    remote_hosts: HashMap<u32, String>,
    /// The link's pid: the pid its stand-ins for other hosts' robots carry.
    link_pid: Option<u32>,
    /// The host last logged for each robot.
    logged_hosts: HashMap<u32, String>,
    /// The pid each robot had when its host was last looked at: a robot
    /// seen with another (new, restarted, or now a stand-in) needs the
    /// link's report read before it is tagged, or a stand-in seen before
    /// the next periodic read would be tagged with this host.
    looked_at_pids: HashMap<u32, u32>,
    hosts_stale: bool,
    /// Streaming to a viewer, which may be closed at any time.
    live: bool,
    pub stats: RecorderStats,
    /// The newest frame logged, if any.
    pub last_frame: Option<Frame>,
}

impl Recorder {
    pub fn new(
        rec: RecordingStream,
        scenario: &Scenario,
        tum_dir: Option<&Path>,
        live: bool,
    ) -> anyhow::Result<Self> {
        crate::arena::log_arena(&rec, &scenario.arena)?;
        crate::motion::log_period(&rec, scenario.timing.period_s)?;
        let files = tum_dir.map(RunFiles::new).transpose()?;
        Ok(Self {
            rec,
            spread: scenario.formation.spread,
            presence: Presence::default(),
            pending: BTreeMap::new(),
            last_health: HashMap::new(),
            files,
            motion: scenario.motion.clone(),
            period_s: scenario.timing.period_s,
            own_host: shoal_runtime::host::current().name.clone(),
            remote_hosts: HashMap::new(),
            link_pid: None,
            logged_hosts: HashMap::new(),
            looked_at_pids: HashMap::new(),
            hosts_stale: false,
            live,
            stats: RecorderStats::default(),
            last_frame: None,
        })
    }

    /// Which robots run on other hosts, and where, from this host's link
    /// report (`None`: no link runs here).
    pub fn set_remote_hosts(&mut self, link: Option<(u32, HashMap<u32, String>)>) {
        self.hosts_stale = false;
        if let Some((link_pid, remote)) = link {
            self.link_pid = Some(link_pid);
            self.remote_hosts = remote;
        }
    }

    /// Whether a robot was seen with a pid its host was not looked at for
    /// since the link's report was last read.
    pub fn hosts_stale(&self) -> bool {
        self.hosts_stale
    }

    /// Takes one sample that passed the bus checks.
    pub fn add(&mut self, sample: PoseSample) {
        self.stats.samples += 1;
        if self.looked_at_pids.get(&sample.agent_id) != Some(&sample.pid) {
            self.hosts_stale = true;
        }
        self.pending.entry(sample.tick).or_default().push(sample);
    }

    pub fn stream(&self) -> &RecordingStream {
        &self.rec
    }

    /// Notes how many samples the bus readers have rejected so far.
    pub fn set_rejected(&mut self, rejected: u64) {
        self.stats.rejected = rejected;
    }

    /// Logs every tick older than the newest one seen (those are complete).
    pub fn log_complete(&mut self) -> anyhow::Result<()> {
        let Some(&newest) = self.pending.keys().next_back() else {
            return Ok(());
        };
        let complete: Vec<u64> = self
            .pending
            .keys()
            .copied()
            .filter(|t| *t < newest)
            .collect();
        for tick in complete {
            if let Some(samples) = self.pending.remove(&tick) {
                self.log_frame(tick, samples)?;
            }
        }
        Ok(())
    }

    /// Logs everything still pending (on the way out).
    pub fn log_all(&mut self) -> anyhow::Result<()> {
        let pending = std::mem::take(&mut self.pending);
        for (tick, samples) in pending {
            self.log_frame(tick, samples)?;
        }
        Ok(())
    }

    /// Robots not heard of for `silent_ticks` ticks are logged as gone.
    pub fn forget_silent(&mut self, now_tick: u64, silent_ticks: u64) -> anyhow::Result<()> {
        for (id, text) in self.presence.fell_silent(now_tick, silent_ticks) {
            if let Some(files) = &mut self.files {
                files.close(id)?;
            }
            self.event(&text)?;
        }
        Ok(())
    }

    pub fn event(&self, text: &str) -> anyhow::Result<()> {
        self.rec.log(
            "events",
            &rerun::TextLog::new(text).with_level(rerun::TextLogLevel::INFO),
        )?;
        Ok(())
    }

    fn log_frame(&mut self, tick: u64, samples: Vec<PoseSample>) -> anyhow::Result<()> {
        let Some(first) = samples.first() else {
            return Ok(());
        };
        self.rec.set_time_sequence("tick", tick as i64);
        self.rec
            .set_duration_secs(crate::motion::TIMELINE, first.sim_time);
        for sample in &samples {
            if let Some(text) = self.presence.saw(sample) {
                self.event(&text)?;
            }
        }
        self.stats.dropped = self.presence.dropped;
        self.stats.frames += 1;
        self.last_frame = Some(Frame {
            tick,
            sim_time: first.sim_time,
        });
        let robots: Vec<&PoseSample> = samples.iter().collect();
        self.log_robots(tick, &robots)?;
        self.log_tags(&robots)?;
        self.log_swarm(&robots)?;
        crate::motion::log_tick(&self.rec, &self.motion, self.period_s, &robots)?;
        if let Some(files) = &mut self.files {
            for s in &robots {
                files.write(
                    s,
                    crate::motion::executed_velocity(&self.motion, self.period_s, s),
                    self.period_s,
                )?;
            }
        }
        Ok(())
    }

    /// Where each robot truly is (by health), where it believes it is, its
    /// heading, its links to its neighbours, and now and then its trail.
    fn log_robots(&mut self, tick: u64, robots: &[&PoseSample]) -> anyhow::Result<()> {
        let true_positions: Vec<[f32; 2]> =
            robots.iter().map(|s| [s.x as f32, s.y as f32]).collect();
        let labels: Vec<String> = robots.iter().map(|s| s.agent_id.to_string()).collect();
        let colors: Vec<rerun::Color> = robots.iter().map(|s| health_color(s.health)).collect();
        self.rec.log(
            "world/robots/true",
            &rerun::Points2D::new(true_positions.clone())
                .with_radii(robots.iter().map(|_| 0.15f32))
                .with_colors(colors)
                .with_labels(labels)
                .with_show_labels(true),
        )?;
        self.rec.log(
            "world/robots/believed",
            &rerun::Points2D::new(
                robots
                    .iter()
                    .map(|s| [s.believed_x as f32, s.believed_y as f32]),
            )
            .with_radii(robots.iter().map(|_| 0.05f32))
            .with_colors([rerun::Color::from_rgb(255, 170, 0)]),
        )?;
        self.rec.log(
            "world/robots/heading",
            &rerun::Arrows2D::from_vectors(
                robots
                    .iter()
                    .map(|s| [0.3 * s.theta.cos() as f32, 0.3 * s.theta.sin() as f32]),
            )
            .with_origins(true_positions.clone()),
        )?;
        let by_id: HashMap<u32, [f32; 2]> = robots
            .iter()
            .map(|s| (s.agent_id, [s.x as f32, s.y as f32]))
            .collect();
        let mut links: Vec<Vec<[f32; 2]>> = Vec::new();
        for s in robots {
            let from = [s.x as f32, s.y as f32];
            links.extend(
                s.neighbour_ids()
                    .iter()
                    .filter_map(|n| by_id.get(n).map(|to| vec![from, *to])),
            );
        }
        self.rec.log(
            "world/links",
            &rerun::LineStrips2D::new(links).with_colors([rerun::Color::from_rgb(90, 160, 255)]),
        )?;
        if tick.is_multiple_of(TRAIL_EVERY_TICKS) {
            let trails: Vec<Vec<[f32; 2]>> = self.presence.trails().collect();
            self.rec
                .log("world/robots/trails", &rerun::LineStrips2D::new(trails))?;
        }
        Ok(())
    }

    /// Each robot's host and health, logged only when they change.
    fn log_tags(&mut self, robots: &[&PoseSample]) -> anyhow::Result<()> {
        for s in robots {
            // Each robot is tagged with its host when first seen and when
            // that changes (a robot id restarted on another host).
            // A robot of another host is untagged until the link has named
            // its host.
            self.looked_at_pids.insert(s.agent_id, s.pid);
            let host = if Some(s.pid) == self.link_pid {
                self.remote_hosts.get(&s.agent_id)
            } else {
                Some(&self.own_host)
            };
            if let Some(host) = host
                && self.logged_hosts.get(&s.agent_id) != Some(host)
            {
                self.rec.log(
                    format!("robots/{}/host", s.agent_id),
                    &rerun::TextDocument::new(host.as_str()),
                )?;
                self.logged_hosts.insert(s.agent_id, host.clone());
            }
            // Health rarely changes; logging it only then keeps the file small.
            if self.last_health.insert(s.agent_id, s.health) != Some(s.health) {
                self.rec.log(
                    format!("robots/{}/health", s.agent_id),
                    &rerun::Scalars::new([f64::from(s.health)]),
                )?;
            }
        }
        Ok(())
    }

    /// The formation's quality and what the recorder dropped or refused.
    fn log_swarm(&mut self, robots: &[&PoseSample]) -> anyhow::Result<()> {
        let positions: Vec<DVec2> = robots.iter().map(|s| DVec2::new(s.x, s.y)).collect();
        let metrics = formation_metrics(&positions, self.spread);
        self.rec.log(
            "swarm/agents",
            &rerun::Scalars::new([metrics.agents as f64]),
        )?;
        self.rec.log(
            "swarm/components",
            &rerun::Scalars::new([metrics.components as f64]),
        )?;
        self.rec.log(
            "swarm/spacing_ratio",
            &rerun::Scalars::new([metrics.spacing_ratio]),
        )?;
        self.rec.log(
            "recorder/dropped_samples",
            &rerun::Scalars::new([self.stats.dropped as f64]),
        )?;
        self.rec.log(
            "recorder/rejected_samples",
            &rerun::Scalars::new([self.stats.rejected as f64]),
        )?;
        Ok(())
    }

    /// Writes what is logged out: the TUM files, then the stream's sinks
    /// (the file, a live viewer), waiting a bounded time. Neither a viewer
    /// the user closed nor a disk that does not answer may stop the
    /// recorder: a flush that did not complete is returned as its reason,
    /// for the caller to tell apart from a file that cannot be written.
    pub fn flush(&mut self) -> anyhow::Result<Option<String>> {
        if let Some(files) = &mut self.files {
            files.flush()?;
        }
        let limit = if self.live {
            LIVE_FLUSH_TIMEOUT
        } else {
            crate::rrd_file::FLUSH_LIMIT
        };
        Ok(self
            .rec
            .flush_with_timeout(limit)
            .err()
            .map(|e| e.to_string()))
    }
}

fn health_color(health: u32) -> rerun::Color {
    if health & Health::REJECTED_INPUT != 0 || health & Health::CELL_FULL != 0 {
        rerun::Color::from_rgb(230, 60, 60)
    } else if health & Health::ISOLATED != 0 {
        rerun::Color::from_rgb(160, 160, 160)
    } else if health & Health::BUMPED != 0 {
        rerun::Color::from_rgb(240, 200, 40)
    } else {
        rerun::Color::from_rgb(60, 200, 120)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A recorder writing to memory, for the bookkeeping alone.
    fn recorder() -> Recorder {
        let (rec, _storage) = rerun::RecordingStreamBuilder::new("recorder-test")
            .memory()
            .expect("a recording in memory");
        Recorder::new(rec, &Scenario::default_arena(), None, false).expect("a recorder")
    }

    /// The link's stand-ins carry the link's pid: a robot first seen with
    /// one, or seen again with another pid, has the link's report read
    /// before it is tagged, or it would be tagged with this host (the
    /// two-hosts test's wrong tag). A robot seen again with its pid needs
    /// no read.
    #[test]
    fn a_robot_seen_with_a_new_pid_has_the_links_report_read_before_it_is_tagged() {
        let (link_pid, remote) = (500, HashMap::from([(7, "b".to_owned())]));
        let mut recorder = recorder();
        assert!(!recorder.hosts_stale());
        recorder.add(PoseSample::standing(7, link_pid, 1, 0.0, 0.0, 0.0));
        assert!(recorder.hosts_stale(), "a pid never looked at");
        recorder.set_remote_hosts(Some((link_pid, remote.clone())));
        assert!(!recorder.hosts_stale());
        // Until it is tagged, its pid has not been looked at.
        recorder.add(PoseSample::standing(7, link_pid, 2, 0.0, 0.0, 0.0));
        assert!(recorder.hosts_stale(), "tick 1 not yet logged");
        recorder.set_remote_hosts(Some((link_pid, remote)));
        recorder.log_complete().expect("logged");
        assert_eq!(recorder.logged_hosts.get(&7).map(String::as_str), Some("b"));
        recorder.add(PoseSample::standing(7, link_pid, 3, 0.0, 0.0, 0.0));
        assert!(!recorder.hosts_stale(), "the same pid, looked at");
        // Robot 7 restarted here, with its own pid: this host.
        recorder.add(PoseSample::standing(7, 42, 4, 0.0, 0.0, 0.0));
        assert!(recorder.hosts_stale(), "a new pid");
        recorder.set_remote_hosts(None);
        recorder.add(PoseSample::standing(7, 42, 5, 0.0, 0.0, 0.0));
        recorder.log_complete().expect("logged");
        assert_eq!(
            recorder.logged_hosts.get(&7),
            Some(&recorder.own_host),
            "tagged with this host once it runs here"
        );
    }
}

//! Turns what the bus carries into a Rerun recording, tick by tick.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use glam::DVec2;
use rerun::RecordingStream;
use shoal_broker::{Health, PoseSample};
use shoal_physics::Scenario;
use shoal_physics::metrics::formation_metrics;

/// Positions kept for each robot's trail.
const TRAIL_LENGTH: usize = 50;
/// Trails are logged every this many ticks; positions every tick.
const TRAIL_EVERY_TICKS: u64 = 5;
/// How long a flush waits for a live viewer before the recorder moves on.
const LIVE_FLUSH_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(1);

struct Robot {
    pid: u32,
    last_tick: u64,
    latest: PoseSample,
    trail: VecDeque<[f32; 2]>,
}

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

pub struct Recorder {
    rec: RecordingStream,
    spread: f64,
    robots: BTreeMap<u32, Robot>,
    /// The last pid of robots that fell silent: one that comes back was
    /// restarted, not a newcomer.
    gone: HashMap<u32, u32>,
    pending: BTreeMap<u64, Vec<PoseSample>>,
    last_health: HashMap<u32, u32>,
    tum: Option<TumWriter>,
    /// The model the robots ran with: what their executed commands mean.
    motion: shoal_physics::MotionModel,
    period_s: f64,
    /// Streaming to a viewer, which may be closed at any time.
    live: bool,
    /// Whether the user was told the viewer is unreachable.
    told_viewer_gone: bool,
    pub stats: RecorderStats,
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
        let tum = tum_dir.map(TumWriter::new).transpose()?;
        Ok(Self {
            rec,
            spread: scenario.formation.spread,
            robots: BTreeMap::new(),
            gone: HashMap::new(),
            pending: BTreeMap::new(),
            last_health: HashMap::new(),
            tum,
            motion: scenario.motion.clone(),
            period_s: scenario.timing.period_s,
            live,
            told_viewer_gone: false,
            stats: RecorderStats::default(),
        })
    }

    /// Takes one sample that passed the bus checks.
    pub fn add(&mut self, sample: PoseSample) {
        self.stats.samples += 1;
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
        let gone: Vec<u32> = self
            .robots
            .iter()
            .filter(|(_, r)| r.last_tick + silent_ticks < now_tick)
            .map(|(id, _)| *id)
            .collect();
        for id in gone {
            if let Some(tum) = &mut self.tum {
                tum.close(id)?;
            }
            if let Some(robot) = self.robots.remove(&id) {
                self.gone.insert(id, robot.pid);
                self.event(&format!(
                    "robot {id} (pid {}) fell silent after tick {}",
                    robot.pid, robot.last_tick
                ))?;
            }
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
            self.track(sample)?;
        }
        self.stats.frames += 1;
        let robots: Vec<&PoseSample> = samples.iter().collect();
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
        for s in &robots {
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
            let trails: Vec<Vec<[f32; 2]>> = self
                .robots
                .values()
                .map(|r| r.trail.iter().copied().collect())
                .collect();
            self.rec
                .log("world/robots/trails", &rerun::LineStrips2D::new(trails))?;
        }
        for s in &robots {
            // Health rarely changes; logging it only then keeps the file small.
            if self.last_health.insert(s.agent_id, s.health) != Some(s.health) {
                self.rec.log(
                    format!("robots/{}/health", s.agent_id),
                    &rerun::Scalars::new([f64::from(s.health)]),
                )?;
            }
        }
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
        crate::motion::log_tick(&self.rec, &self.motion, self.period_s, &robots)?;
        if let Some(tum) = &mut self.tum {
            for s in &robots {
                tum.write(
                    s,
                    crate::motion::executed_velocity(&self.motion, self.period_s, s),
                    self.period_s,
                )?;
            }
        }
        Ok(())
    }

    /// Notes joins, restarts and samples the bus dropped.
    fn track(&mut self, sample: &PoseSample) -> anyhow::Result<()> {
        let point = [sample.x as f32, sample.y as f32];
        let event = match self.robots.get_mut(&sample.agent_id) {
            Some(robot) if robot.pid == sample.pid => {
                if sample.tick > robot.last_tick + 1 {
                    self.stats.dropped += sample.tick - robot.last_tick - 1;
                }
                robot.last_tick = robot.last_tick.max(sample.tick);
                robot.latest = *sample;
                robot.trail.push_back(point);
                if robot.trail.len() > TRAIL_LENGTH {
                    robot.trail.pop_front();
                }
                None
            }
            Some(robot) => Some(format!(
                "robot {} restarted (pid {} -> {})",
                sample.agent_id, robot.pid, sample.pid
            )),
            None => Some(match self.gone.remove(&sample.agent_id) {
                // A process stalled longer than the staleness, not restarted.
                Some(old_pid) if old_pid == sample.pid => format!(
                    "robot {} (pid {}) heard again at ({:.2}, {:.2})",
                    sample.agent_id, sample.pid, sample.x, sample.y
                ),
                Some(old_pid) => format!(
                    "robot {} restarted (pid {old_pid} -> {}) at ({:.2}, {:.2})",
                    sample.agent_id, sample.pid, sample.x, sample.y
                ),
                None => format!(
                    "robot {} (pid {}) joined at ({:.2}, {:.2})",
                    sample.agent_id, sample.pid, sample.x, sample.y
                ),
            }),
        };
        if let Some(text) = event {
            self.robots.insert(
                sample.agent_id,
                Robot {
                    pid: sample.pid,
                    last_tick: sample.tick,
                    latest: *sample,
                    trail: VecDeque::from([point]),
                },
            );
            self.event(&text)?;
        }
        Ok(())
    }

    pub fn flush(&mut self) -> anyhow::Result<()> {
        if let Some(tum) = &mut self.tum {
            tum.flush()?;
        }
        if !self.live {
            self.rec.flush_blocking()?;
            return Ok(());
        }
        // A viewer the user closed must not stop the recording: the file
        // (flushed with it) is still written, and the user is told once.
        if let Err(e) = self.rec.flush_with_timeout(LIVE_FLUSH_TIMEOUT)
            && !self.told_viewer_gone
        {
            self.told_viewer_gone = true;
            eprintln!("shoal-viewer-log: the live viewer does not answer ({e}); recording goes on");
        }
        Ok(())
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

/// Each robot's true and believed trajectory, one TUM file each, and what
/// `shoal diagnose` reads: `robot-<id>/commands.csv` (the executed command's
/// expected motion under the model the robot was run with, as v and omega)
/// and `robot-<id>/poses.csv` (its true poses).
struct TumWriter {
    dir: PathBuf,
    /// Open only for robots heard from lately: a long run with many
    /// restarts and spawns would otherwise run out of file descriptors.
    files: HashMap<(u32, &'static str), BufWriter<File>>,
    /// Files this recording created; a robot that comes back appends to them.
    created: std::collections::HashSet<(u32, &'static str)>,
}

impl TumWriter {
    fn new(dir: &Path) -> anyhow::Result<Self> {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))?;
        Ok(Self {
            dir: dir.to_owned(),
            files: HashMap::new(),
            created: std::collections::HashSet::new(),
        })
    }

    fn file(&mut self, id: u32, kind: &'static str) -> anyhow::Result<&mut BufWriter<File>> {
        match self.files.entry((id, kind)) {
            std::collections::hash_map::Entry::Occupied(e) => Ok(e.into_mut()),
            std::collections::hash_map::Entry::Vacant(e) => {
                let (path, header) = match kind {
                    "commands" | "poses" => {
                        let folder = self.dir.join(format!("robot-{id}"));
                        std::fs::create_dir_all(&folder).map_err(|err| {
                            anyhow::anyhow!("creating {}: {err}", folder.display())
                        })?;
                        let header = if kind == "commands" {
                            "t,v,omega\n"
                        } else {
                            "t,x,y,theta\n"
                        };
                        (folder.join(format!("{kind}.csv")), header)
                    }
                    _ => (self.dir.join(format!("robot-{id}-{kind}.tum")), ""),
                };
                let again = !self.created.insert((id, kind));
                let file = std::fs::OpenOptions::new()
                    .write(true)
                    .create(true)
                    .append(again)
                    .truncate(!again)
                    .open(&path)
                    .map_err(|err| anyhow::anyhow!("opening {}: {err}", path.display()))?;
                let mut writer = BufWriter::new(file);
                if !again {
                    writer.write_all(header.as_bytes())?;
                }
                Ok(e.insert(writer))
            }
        }
    }

    /// Writes one sample; `executed` is its command's velocity (v, omega),
    /// held over the `period_s` before it.
    fn write(
        &mut self,
        s: &PoseSample,
        executed: Option<(f64, f64)>,
        period_s: f64,
    ) -> anyhow::Result<()> {
        for (kind, x, y, theta) in [
            ("true", s.x, s.y, s.theta),
            ("estimated", s.believed_x, s.believed_y, s.believed_theta),
        ] {
            let line = crate::tum::line(s.sim_time, x, y, theta);
            self.file(s.agent_id, kind)?.write_all(line.as_bytes())?;
        }
        // The command a pose carries moved the robot there over the period before it.
        if let Some((v, omega)) = executed {
            let line = format!("{:.3},{v:.6},{omega:.6}\n", s.sim_time - period_s);
            self.file(s.agent_id, "commands")?
                .write_all(line.as_bytes())?;
        }
        let line = format!("{:.3},{:.6},{:.6},{:.6}\n", s.sim_time, s.x, s.y, s.theta);
        self.file(s.agent_id, "poses")?.write_all(line.as_bytes())?;
        Ok(())
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        for file in self.files.values_mut() {
            file.flush()?;
        }
        Ok(())
    }

    /// Closes robot `id`'s files; they are reopened to append if it returns.
    fn close(&mut self, id: u32) -> anyhow::Result<()> {
        let keys: Vec<_> = self
            .files
            .keys()
            .filter(|(i, _)| *i == id)
            .copied()
            .collect();
        for key in keys {
            if let Some(mut file) = self.files.remove(&key) {
                file.flush()?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_robot_that_falls_silent_closes_its_files_and_appends_when_it_returns() {
        let dir = std::env::temp_dir().join(format!("shoal-tum-test-{}", std::process::id()));
        let mut tum = TumWriter::new(&dir).expect("writer");
        // Many robots come and go; only those heard from lately hold files.
        for id in 0..300 {
            tum.write(&PoseSample::standing(id, 1, 1, 1.0, 2.0, 0.0), None, 0.1)
                .expect("write");
            tum.close(id).expect("close");
        }
        assert!(tum.files.is_empty());
        tum.write(&PoseSample::standing(7, 2, 5, 3.0, 4.0, 0.0), None, 0.1)
            .expect("write again");
        tum.flush().expect("flush");
        let poses = std::fs::read_to_string(dir.join("robot-7/poses.csv")).expect("poses");
        assert_eq!(poses.lines().collect::<Vec<_>>().len(), 3, "{poses}");
        assert_eq!(poses.matches("t,x,y,theta").count(), 1, "{poses}");
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }
}

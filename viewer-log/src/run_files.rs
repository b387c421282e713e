//! The files a recording writes beside the `.rrd` (`--tum DIR`): each
//! robot's true and believed trajectory as TUM files for evo, and what
//! `shoal diagnose` reads: `robot-<id>/commands.csv` (the executed command's
//! expected motion under the model the robot was run with) and
//! `robot-<id>/poses.csv` (its true poses).

use std::collections::{HashMap, HashSet};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::Context;
use shoal_broker::PoseSample;
use shoal_diagnose::recording::csv_lines;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Kind {
    /// The true trajectory, TUM.
    True,
    /// The trajectory the robot believed, TUM.
    Estimated,
    /// Diagnosis input: executed commands.
    Commands,
    /// Diagnosis input: true poses.
    Poses,
}

impl Kind {
    fn path(self, dir: &Path, id: u32) -> PathBuf {
        match self {
            Self::True => dir.join(format!("robot-{id}-true.tum")),
            Self::Estimated => dir.join(format!("robot-{id}-estimated.tum")),
            Self::Commands => dir.join(format!("robot-{id}")).join("commands.csv"),
            Self::Poses => dir.join(format!("robot-{id}")).join("poses.csv"),
        }
    }

    fn header(self) -> &'static str {
        match self {
            Self::True | Self::Estimated => "",
            Self::Commands => csv_lines::COMMANDS_HEADER,
            Self::Poses => csv_lines::POSES_HEADER,
        }
    }
}

pub struct RunFiles {
    dir: PathBuf,
    /// Open only for robots heard from lately: a long run with many
    /// restarts and spawns would otherwise run out of file descriptors.
    open: HashMap<(u32, Kind), BufWriter<File>>,
    /// Files this recording created; a robot that comes back appends to them.
    created: HashSet<(u32, Kind)>,
}

impl RunFiles {
    pub fn new(dir: &Path) -> anyhow::Result<Self> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Self {
            dir: dir.to_owned(),
            open: HashMap::new(),
            created: HashSet::new(),
        })
    }

    fn file(&mut self, id: u32, kind: Kind) -> anyhow::Result<&mut BufWriter<File>> {
        if !self.open.contains_key(&(id, kind)) {
            let path = kind.path(&self.dir, id);
            if let Some(folder) = path.parent() {
                std::fs::create_dir_all(folder)
                    .with_context(|| format!("creating {}", folder.display()))?;
            }
            let again = !self.created.insert((id, kind));
            let file = std::fs::OpenOptions::new()
                .write(true)
                .create(true)
                .append(again)
                .truncate(!again)
                .open(&path)
                .with_context(|| format!("opening {}", path.display()))?;
            let mut writer = BufWriter::new(file);
            if !again {
                writer
                    .write_all(kind.header().as_bytes())
                    .with_context(|| format!("writing {}", path.display()))?;
            }
            self.open.insert((id, kind), writer);
        }
        self.open
            .get_mut(&(id, kind))
            .context("a file just opened is open")
    }

    /// Writes one sample; `executed` is its command's velocity (v, omega),
    /// held over the `period_s` before it.
    pub fn write(
        &mut self,
        s: &PoseSample,
        executed: Option<(f64, f64)>,
        period_s: f64,
    ) -> anyhow::Result<()> {
        for (kind, x, y, theta) in [
            (Kind::True, s.x, s.y, s.theta),
            (
                Kind::Estimated,
                s.believed_x,
                s.believed_y,
                s.believed_theta,
            ),
        ] {
            self.append(s.agent_id, kind, &crate::tum::line(s.sim_time, x, y, theta))?;
        }
        // The command a pose carries moved the robot there over the period before it.
        if let Some((v, omega)) = executed {
            let line = csv_lines::command(s.sim_time - period_s, v, omega);
            self.append(s.agent_id, Kind::Commands, &line)?;
        }
        let line = csv_lines::pose(s.sim_time, s.x, s.y, s.theta);
        self.append(s.agent_id, Kind::Poses, &line)
    }

    /// Appends `line` to robot `id`'s file of `kind`; an error names the file.
    fn append(&mut self, id: u32, kind: Kind, line: &str) -> anyhow::Result<()> {
        let path = kind.path(&self.dir, id);
        self.file(id, kind)?
            .write_all(line.as_bytes())
            .with_context(|| format!("writing {}", path.display()))
    }

    pub fn flush(&mut self) -> anyhow::Result<()> {
        for ((id, kind), file) in &mut self.open {
            file.flush()
                .with_context(|| format!("writing {}", kind.path(&self.dir, *id).display()))?;
        }
        Ok(())
    }

    /// Closes robot `id`'s files; they are reopened to append if it returns.
    pub fn close(&mut self, id: u32) -> anyhow::Result<()> {
        let keys: Vec<_> = self
            .open
            .keys()
            .filter(|(i, _)| *i == id)
            .copied()
            .collect();
        for key in keys {
            if let Some(mut file) = self.open.remove(&key) {
                file.flush()
                    .with_context(|| format!("writing {}", key.1.path(&self.dir, id).display()))?;
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
        let mut files = RunFiles::new(&dir).expect("writer");
        // Many robots come and go; only those heard from lately hold files.
        for id in 0..300 {
            files
                .write(&PoseSample::standing(id, 1, 1, 1.0, 2.0, 0.0), None, 0.1)
                .expect("write");
            files.close(id).expect("close");
        }
        assert!(files.open.is_empty());
        for tick in [5, 6] {
            let sample = PoseSample {
                sim_time: tick as f64 * 0.1,
                ..PoseSample::standing(7, 2, tick, 3.0, 4.0, 0.0)
            };
            files
                .write(&sample, Some((0.1, 0.0)), 0.1)
                .expect("write again");
        }
        files.flush().expect("flush");
        let poses = std::fs::read_to_string(dir.join("robot-7/poses.csv")).expect("poses");
        assert_eq!(poses.lines().collect::<Vec<_>>().len(), 4, "{poses}");
        assert_eq!(poses.matches("t,x,y,theta").count(), 1, "{poses}");
        // What the recorder writes, diagnosis reads.
        let commands = std::fs::read_to_string(dir.join("robot-7/commands.csv")).expect("commands");
        let read = shoal_diagnose::input::commands_csv(&commands, "commands.csv");
        assert!(read.is_ok(), "{read:?}");
        let read = shoal_diagnose::input::poses_csv(&poses, "poses.csv");
        assert!(read.is_ok(), "{read:?}");
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }
}

//! Scenarios: the arena, the robots and the formation parameters, read from TOML.

use std::fmt;
use std::path::Path;

use glam::DVec2;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::arena::{Arena, Obstacle, Surface, Wall};
use crate::formation::FormationParams;
use crate::legged::MotionModel;
use crate::pose::Pose;
use crate::range::RangeSensor;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    #[serde(default = "default_name")]
    pub name: String,
    pub arena: Arena,
    #[serde(default)]
    pub agents: AgentsSection,
    #[serde(default)]
    pub formation: FormationParams,
    #[serde(default)]
    pub timing: TimingSection,
    #[serde(default)]
    pub bus: BusSection,
    /// Every robot's range sensor.
    #[serde(default)]
    pub sensor: RangeSensor,
    /// Robots a SLAM process follows when the swarm starts.
    #[serde(default)]
    pub slam: SlamSection,
    /// The body's true motion distributions; the robot's own (believed) model starts equal to them.
    #[serde(default = "MotionModel::legged_default")]
    pub motion: MotionModel,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlamSection {
    /// Ids of the robots to follow; empty starts no SLAM process.
    pub follow: Vec<u32>,
}

fn default_name() -> String {
    "default".to_owned()
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AgentsSection {
    pub count: usize,
    /// Where robots start, `[xmin, ymin, xmax, ymax]`.
    pub start_region: [f64; 4],
    /// Body radius, metres.
    pub radius: f64,
    /// Seeds the start poses and every robot's noise.
    pub seed: u64,
    /// `formation` (the default) or `wander`: explore alone, as SLAM
    /// experiments need.
    pub behaviour: Behaviour,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Behaviour {
    #[default]
    Formation,
    Wander,
}

impl Default for AgentsSection {
    fn default() -> Self {
        Self {
            count: 12,
            start_region: [6.0, 6.0, 14.0, 14.0],
            radius: 0.15,
            seed: 1,
            behaviour: Behaviour::Formation,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TimingSection {
    /// The control period T: one command per period.
    pub period_s: f64,
    /// A robot not heard from for this many periods is dropped by its neighbours.
    pub stale_periods: f64,
}

impl Default for TimingSection {
    fn default() -> Self {
        Self {
            period_s: 0.2,
            stale_periods: 2.0,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BusSection {
    /// Side of a spatial cell: a robot publishes into its own cell and listens
    /// to the cells around it, so its cost follows local density, not swarm size.
    pub cell_size: f64,
    /// How many rings of cells a robot widens its listening to when it sees
    /// fewer robots than it tracks.
    pub max_ring: u32,
    /// The most robots that may publish in one cell at once.
    pub max_per_cell: usize,
    /// The most robots that may listen to one cell at once.
    pub max_listeners_per_cell: usize,
}

impl Default for BusSection {
    fn default() -> Self {
        Self {
            cell_size: 3.5,
            max_ring: 3,
            max_per_cell: 24,
            max_listeners_per_cell: 216,
        }
    }
}

/// A scenario that could not be used, with the place it went wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct ScenarioError {
    pub file: String,
    pub line: Option<usize>,
    pub field: Option<String>,
    pub message: String,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ": field `{field}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl Scenario {
    /// A 3 x 4 m room with a box and a post, and one robot that wanders
    /// near the bottom wall: where SLAM is tested and measured.
    pub fn room() -> Self {
        let mut scenario = Self::default_arena();
        scenario.name = "room".into();
        scenario.arena = Arena {
            width: 3.0,
            height: 4.0,
            walls: vec![],
            obstacles: vec![
                Obstacle::Box {
                    min: [2.0, 2.6],
                    max: [2.6, 3.0],
                },
                Obstacle::Disc {
                    center: [0.9, 1.2],
                    radius: 0.15,
                },
            ],
            surfaces: vec![],
        };
        scenario.agents.count = 1;
        scenario.agents.start_region = [1.3, 0.5, 1.7, 0.7];
        scenario.agents.behaviour = Behaviour::Wander;
        scenario
    }

    /// The default world: a walled 20 x 20 m arena with a few obstacles, an
    /// interior wall and two surfaces (carpet and a slippery tile patch).
    pub fn default_arena() -> Self {
        Self {
            name: default_name(),
            arena: Arena {
                width: 20.0,
                height: 20.0,
                walls: vec![Wall {
                    from: [3.0, 16.0],
                    to: [8.0, 16.0],
                }],
                obstacles: vec![
                    Obstacle::Disc {
                        center: [4.0, 4.0],
                        radius: 0.6,
                    },
                    Obstacle::Disc {
                        center: [16.0, 15.0],
                        radius: 0.8,
                    },
                    Obstacle::Box {
                        min: [15.0, 3.0],
                        max: [17.0, 4.0],
                    },
                    Obstacle::Box {
                        min: [2.0, 9.0],
                        max: [3.0, 12.0],
                    },
                ],
                surfaces: vec![
                    Surface {
                        name: "carpet".into(),
                        region: [0.0, 0.0, 20.0, 20.0],
                        along_scale: 1.0,
                        across_scale: 1.0,
                        turn_scale: 1.0,
                        from_s: 0.0,
                    },
                    Surface {
                        name: "tile".into(),
                        region: [11.0, 0.0, 20.0, 9.0],
                        along_scale: 1.25,
                        across_scale: 1.6,
                        turn_scale: 0.85,
                        from_s: 0.0,
                    },
                ],
            },
            agents: AgentsSection::default(),
            formation: FormationParams::default(),
            timing: TimingSection::default(),
            bus: BusSection::default(),
            sensor: RangeSensor::default(),
            slam: SlamSection::default(),
            motion: MotionModel::legged_default(),
        }
    }

    /// Reads and checks a scenario file.
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ScenarioError {
            file: file.clone(),
            line: None,
            field: None,
            message: format!("cannot read: {e}"),
        })?;
        Self::from_toml(&text, &file)
    }

    /// Parses and checks scenario text; `file` names it in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, ScenarioError> {
        let error = |line, field: Option<String>, message: String| ScenarioError {
            file: file.to_owned(),
            line,
            field,
            message,
        };
        let scenario: Scenario = parse_toml(text, file)?;
        scenario
            .validate()
            .map_err(|(field, message)| error(line_of_field(text, &field), Some(field), message))?;
        Ok(scenario)
    }

    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_default()
    }

    /// Checks what the types alone cannot; errors name the field.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let positive = |field: &str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err((
                    field.to_owned(),
                    format!("{value} must be a positive number"),
                ))
            }
        };
        positive("arena.width", self.arena.width)?;
        positive("arena.height", self.arena.height)?;
        positive("agents.radius", self.agents.radius)?;
        positive("timing.period_s", self.timing.period_s)?;
        positive("timing.stale_periods", self.timing.stale_periods)?;
        positive("bus.cell_size", self.bus.cell_size)?;
        if self.bus.max_per_cell == 0 {
            return Err(("bus.max_per_cell".into(), "must be at least 1".into()));
        }
        if self.bus.max_listeners_per_cell < self.bus.max_per_cell {
            return Err((
                "bus.max_listeners_per_cell".into(),
                "must be at least bus.max_per_cell".into(),
            ));
        }
        let [x0, y0, x1, y1] = self.agents.start_region;
        if !(x0 < x1
            && y0 < y1
            && x0 >= 0.0
            && y0 >= 0.0
            && x1 <= self.arena.width
            && y1 <= self.arena.height)
        {
            return Err((
                "agents.start_region".into(),
                format!(
                    "{:?} must be [xmin, ymin, xmax, ymax] inside the arena",
                    self.agents.start_region
                ),
            ));
        }
        for (i, surface) in self.arena.surfaces.iter().enumerate() {
            let scales = [
                surface.along_scale,
                surface.across_scale,
                surface.turn_scale,
            ];
            if scales.iter().any(|s| !s.is_finite() || *s < 0.0) {
                return Err((
                    format!("arena.surfaces[{i}]"),
                    "scales must be finite and not negative".into(),
                ));
            }
        }
        self.formation
            .validate()
            .map_err(|(field, message)| (format!("formation.{field}"), message))?;
        self.motion
            .validate()
            .map_err(|message| ("motion".to_owned(), message))?;
        Ok(())
    }

    /// Deterministic start poses for robots `first..first + count`: inside the
    /// start region, clear of walls, obstacles and each other.
    pub fn start_poses(&self, first: u32, count: usize) -> Vec<Pose> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(self.agents.seed ^ 0x5eed_0000);
        let [x0, y0, x1, y1] = self.agents.start_region;
        let clearance = 2.5 * self.agents.radius;
        let mut placed: Vec<DVec2> = Vec::new();
        let mut poses = Vec::new();
        for index in 0..(first as usize + count) {
            let mut candidate = DVec2::new(rng.random_range(x0..x1), rng.random_range(y0..y1));
            for _ in 0..1000 {
                let free = !self.arena.blocks(candidate, self.agents.radius)
                    && placed.iter().all(|p| p.distance(candidate) > clearance);
                if free {
                    break;
                }
                candidate = DVec2::new(rng.random_range(x0..x1), rng.random_range(y0..y1));
            }
            let theta = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
            placed.push(candidate);
            if index >= first as usize {
                poses.push(Pose::new(candidate.x, candidate.y, theta));
            }
        }
        poses
    }
}

fn line_of_offset(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

/// The line where `section.key` is written, for errors found after parsing.
/// Parses TOML `text` into `T`; errors name `file`, the line and the field.
pub fn parse_toml<T: serde::de::DeserializeOwned>(
    text: &str,
    file: &str,
) -> Result<T, ScenarioError> {
    let error = |line, field: Option<String>, message: String| ScenarioError {
        file: file.to_owned(),
        line,
        field,
        message,
    };
    let deserializer = toml::Deserializer::parse(text).map_err(|e| {
        error(
            e.span().map(|s| line_of_offset(text, s.start)),
            None,
            e.message().to_owned(),
        )
    })?;
    serde_path_to_error::deserialize(deserializer).map_err(|e| {
        let field = e.path().to_string();
        let inner = e.into_inner();
        let line = inner.span().map(|s| line_of_offset(text, s.start));
        let line = line.or_else(|| line_of_field(text, &field));
        error(line, Some(field), inner.message().to_owned())
    })
}

/// The line of the `index`-th `[[name]]` table in `text`.
pub(crate) fn line_of_nth_table(text: &str, name: &str, index: usize) -> Option<usize> {
    let header = format!("[[{name}]]");
    text.lines()
        .enumerate()
        .filter(|(_, line)| line.trim() == header)
        .nth(index)
        .map(|(number, _)| number + 1)
}

pub(crate) fn line_of_field(text: &str, field: &str) -> Option<usize> {
    let (section, key) = match field.rsplit_once('.') {
        Some((section, key)) => (section, key),
        None => ("", field),
    };
    let key = key.split('[').next().unwrap_or(key);
    let mut current = String::new();
    let mut section_line = None;
    for (index, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if let Some(header) = line.strip_prefix('[') {
            current = header
                .trim_start_matches('[')
                .trim_end_matches(']')
                .trim()
                .to_owned();
            if current == section || (section.is_empty() && current == key) {
                section_line = Some(index + 1);
            }
            continue;
        }
        let written_key = line.split('=').next().unwrap_or("").trim();
        if current == section && written_key == key {
            return Some(index + 1);
        }
    }
    section_line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_scenario_round_trips_through_toml() {
        let scenario = Scenario::default_arena();
        let text = scenario.to_toml();
        let parsed = Scenario::from_toml(&text, "default.toml").expect("valid");
        assert_eq!(parsed.arena, scenario.arena);
        assert_eq!(parsed.formation, scenario.formation);
        assert_eq!(parsed.motion, scenario.motion);
    }

    #[test]
    fn a_type_error_names_file_line_and_field() {
        let text = "[arena]\nwidth = 10.0\nheight = 10.0\n\n[formation]\nneighbours = \"four\"\n";
        let error = Scenario::from_toml(text, "bad.toml").unwrap_err();
        assert_eq!(error.line, Some(6), "{error}");
        assert_eq!(
            error.field.as_deref(),
            Some("formation.neighbours"),
            "{error}"
        );
        assert!(
            error
                .to_string()
                .starts_with("bad.toml:6: field `formation.neighbours`"),
            "{error}"
        );
    }

    #[test]
    fn a_bad_value_names_file_line_and_field() {
        let text = "[arena]\nwidth = 10.0\nheight = 10.0\n[agents]\ncount = 3\nstart_region = [1.0, 1.0, 9.0, 9.0]\n[formation]\nspread = -1.0\n";
        let error = Scenario::from_toml(text, "bad.toml").unwrap_err();
        assert_eq!(error.field.as_deref(), Some("formation.spread"));
        assert_eq!(error.line, Some(8), "{error}");
    }

    #[test]
    fn unknown_fields_and_broken_syntax_are_rejected() {
        let unknown = "[arena]\nwidth = 10.0\nheight = 10.0\nwidht = 3.0\n";
        let error = Scenario::from_toml(unknown, "typo.toml").unwrap_err();
        assert!(error.message.contains("widht"), "{error}");
        assert_eq!(error.line, Some(4), "{error}");
        let broken = "[arena]\nwidth = 10.0\nheight = \n";
        let error = Scenario::from_toml(broken, "cut.toml").unwrap_err();
        assert_eq!(error.line, Some(3), "{error}");
    }

    #[test]
    fn start_poses_are_deterministic_and_clear() {
        let scenario = Scenario::default_arena();
        let poses = scenario.start_poses(0, 20);
        assert_eq!(poses, scenario.start_poses(0, 20));
        assert_eq!(&poses[5..], &scenario.start_poses(5, 15)[..]);
        for (i, a) in poses.iter().enumerate() {
            assert!(!scenario.arena.blocks(a.position(), scenario.agents.radius));
            for b in &poses[i + 1..] {
                assert!(a.position().distance(b.position()) > 2.0 * scenario.agents.radius);
            }
        }
    }
}

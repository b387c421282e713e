//! Scenarios: the arena, the robots and the formation parameters, read from TOML.

use glam::DVec2;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use shoal_physics::arena::{Arena, Obstacle, Surface, Wall};
use shoal_physics::formation::FormationParams;
use shoal_physics::legged::MotionModel;
use shoal_physics::pose::Pose;
use shoal_physics::range::RangeSensor;
pub use shoal_physics::toml_file::ScenarioError;
use shoal_physics::toml_file::{line_of_field, parse_toml};

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
    /// The bus's section, which the broker reads ([`Scenario::section`]).
    #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
    bus: toml::Table,
    /// Every robot's range sensor.
    #[serde(default)]
    pub sensor: RangeSensor,
    /// SLAM's section (the robots it follows when the swarm starts), which
    /// SLAM reads.
    #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
    slam: toml::Table,
    /// Where the scenario was read from, for errors in its sections.
    #[serde(skip)]
    source: Source,
    /// The body's true motion distributions; the robot's own (believed) model starts equal to them.
    #[serde(default = "MotionModel::legged_default")]
    pub motion: MotionModel,
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

impl TimingSection {
    /// How long a process that watches robots without stepping with them
    /// (the launcher, a host's link) keeps one that fell silent, seconds:
    /// the robots' stale period, but never under two periods, since such a
    /// process does not wake on the robots' ticks.
    pub fn observer_stale_s(&self) -> f64 {
        self.period_s * self.stale_periods.max(2.0)
    }
}

impl Default for TimingSection {
    fn default() -> Self {
        Self {
            period_s: 0.2,
            stale_periods: 2.0,
        }
    }
}

/// A section of the scenario that the crate it configures owns: its
/// fields and defaults (serde), its name in the file, and its ranges.
pub trait Section: Serialize + serde::de::DeserializeOwned {
    /// The section's name in the scenario file, `bus` for `[bus]`.
    const NAME: &'static str;
    /// Checks the range of every field, naming fields within the section.
    fn check(&self, check: &mut RangeCheck);
}

/// The file a scenario was read from and its text, for the line of an
/// error in a section read later. Where a scenario came from is not part
/// of what it says, so any two are equal.
#[derive(Clone, Debug, Default)]
struct Source(Option<(String, String)>);

impl PartialEq for Source {
    fn eq(&self, _: &Self) -> bool {
        true
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

    /// How many robots the start region holds at the density the default
    /// worlds start them at: a little sparser than their lattice.
    pub fn start_capacity(&self) -> usize {
        let [x0, y0, x1, y1] = self.agents.start_region;
        let spacing = self.formation.spread * START_SPACING_OF_SPREAD;
        ((x1 - x0) * (y1 - y0) / (spacing * spacing)).round() as usize
    }

    /// An open square arena big enough for `agents` at the default spacing,
    /// starting them a little sparser than their lattice, at random.
    pub fn open_arena(agents: usize) -> Self {
        let mut scenario = Self::default_arena();
        let spread = scenario.formation.spread;
        let start_side = (agents as f64).sqrt() * spread * START_SPACING_OF_SPREAD;
        let side = (start_side * 2.0 + 10.0).max(20.0);
        scenario.arena = Arena {
            width: side,
            height: side,
            walls: vec![],
            obstacles: vec![],
            surfaces: vec![],
        };
        let (lo, hi) = ((side - start_side) / 2.0, (side + start_side) / 2.0);
        scenario.agents.start_region = [lo, lo, hi, hi];
        scenario.agents.count = agents;
        scenario
    }

    /// The world for `agents` robots when the user names none: the default
    /// arena while its start region holds them, else an open arena sized for
    /// them. Crowding hundreds of robots into the default 8 x 8 m start
    /// region would have each hear every other and bump from the first period.
    pub fn default_for(agents: usize) -> Self {
        let mut scenario = Self::default_arena();
        if agents > scenario.start_capacity() {
            return Self::open_arena(agents);
        }
        scenario.agents.count = agents;
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
            bus: toml::Table::new(),
            sensor: RangeSensor::default(),
            slam: toml::Table::new(),
            source: Source::default(),
            motion: MotionModel::legged_default(),
        }
    }

    /// Parses and checks scenario text; `file` names it in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, ScenarioError> {
        let error = |line, field: Option<String>, message: String| ScenarioError {
            file: file.to_owned(),
            line,
            field,
            message,
        };
        let mut scenario: Scenario = parse_toml(text, file)?;
        scenario
            .validate()
            .map_err(|(field, message)| error(line_of_field(text, &field), Some(field), message))?;
        scenario.source = Source(Some((file.to_owned(), text.to_owned())));
        Ok(scenario)
    }

    /// The section `S` as the scenario gives it (its defaults where it says
    /// nothing), with the range of every field checked. Errors name the
    /// file, line and field where the scenario was read from a file.
    pub fn section<S: Section>(&self) -> Result<S, ScenarioError> {
        let (file, text) = self.source.0.clone().unwrap_or_default();
        let error = |field: String, message: String| ScenarioError {
            file: if file.is_empty() {
                "scenario".to_owned()
            } else {
                file.clone()
            },
            line: line_of_field(&text, &field),
            field: Some(field),
            message,
        };
        let raw = self.raw(S::NAME).cloned().unwrap_or_default();
        let section: S =
            serde_path_to_error::deserialize(toml::Value::Table(raw)).map_err(|e| {
                let field = format!("{}.{}", S::NAME, e.path());
                error(field, e.into_inner().to_string())
            })?;
        let mut check = RangeCheck {
            section: S::NAME,
            first: None,
        };
        section.check(&mut check);
        match check.first {
            Some((field, message)) => Err(error(field, message)),
            None => Ok(section),
        }
    }

    /// Sets the section `S` (a swarm's launcher adds the robots SLAM follows).
    pub fn set_section<S: Section>(&mut self, section: &S) -> Result<(), ScenarioError> {
        let error = |message: String| ScenarioError {
            file: "scenario".to_owned(),
            line: None,
            field: Some(S::NAME.to_owned()),
            message,
        };
        let table = toml::Table::try_from(section).map_err(|e| error(e.to_string()))?;
        match S::NAME {
            "bus" => self.bus = table,
            "slam" => self.slam = table,
            other => return Err(error(format!("a scenario has no section `{other}`"))),
        }
        Ok(())
    }

    /// The raw table of the section called `name`, if a scenario has one.
    fn raw(&self, name: &str) -> Option<&toml::Table> {
        match name {
            "bus" => Some(&self.bus),
            "slam" => Some(&self.slam),
            _ => None,
        }
    }

    /// The scenario as a scenario file. An error, never an empty file, if
    /// it cannot be written.
    pub fn to_toml(&self) -> Result<String, toml::ser::Error> {
        toml::to_string_pretty(self)
    }

    /// Checks what the types alone cannot: every number lies in a range a
    /// real swarm can have (finite, signed right, not absurdly large), so a
    /// bad file is refused here instead of killing every robot at start.
    /// Errors name the field.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let mut check = RangeCheck::default();
        check_arena(&mut check, &self.arena);
        check_agents(&mut check, &self.agents, &self.arena);
        check_timing(&mut check, &self.timing);
        check_sensor(&mut check, &self.sensor);
        check_formation(&mut check, &self.formation);
        if let Some(error) = check.first {
            return Err(error);
        }
        self.motion
            .validate()
            .map_err(|message| ("motion".to_owned(), message))?;
        Ok(())
    }

    /// Deterministic start poses for robots `first..first + count`: inside the
    /// start region, clear of walls, obstacles and each other.
    pub fn start_poses(&self, first: u32, count: usize) -> Vec<Pose> {
        let (poses, _) = self.place_starts(first as usize + count);
        poses.into_iter().skip(first as usize).collect()
    }

    /// How many of the scenario's robots find no free start in their
    /// region and start overlapping a wall, an obstacle or another robot.
    pub fn crowded_starts(&self) -> usize {
        self.place_starts(self.agents.count).1
    }

    /// Start poses for the first `count` robots, and how many of them found
    /// no free place.
    fn place_starts(&self, count: usize) -> (Vec<Pose>, usize) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(self.agents.seed ^ 0x5eed_0000);
        let [x0, y0, x1, y1] = self.agents.start_region;
        let clearance = 2.5 * self.agents.radius;
        let mut placed: Vec<DVec2> = Vec::new();
        let mut poses = Vec::new();
        let mut crowded = 0;
        for _ in 0..count {
            let mut candidate = DVec2::new(rng.random_range(x0..x1), rng.random_range(y0..y1));
            let mut free = false;
            for _ in 0..1000 {
                free = !self.arena.blocks(candidate, self.agents.radius)
                    && placed.iter().all(|p| p.distance(candidate) > clearance);
                if free {
                    break;
                }
                candidate = DVec2::new(rng.random_range(x0..x1), rng.random_range(y0..y1));
            }
            crowded += usize::from(!free);
            let theta = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
            placed.push(candidate);
            poses.push(Pose::new(candidate.x, candidate.y, theta));
        }
        (poses, crowded)
    }
}

/// Start spacing of the default worlds, in formation spreads.
const START_SPACING_OF_SPREAD: f64 = 1.3;

/// Upper bounds on what a scenario may ask for. They are far beyond any
/// swarm Shoal runs, and only there to refuse typos and overflow (a period of
/// 1e300 s, a billion beams) with a clear message.
/// The largest arena side (and coordinate), metres.
pub const MAX_ARENA_M: f64 = 100_000.0;
const MAX_RADIUS_M: f64 = 10.0;
const MAX_SURFACE_SCALE: f64 = 100.0;
const MAX_SECONDS: f64 = 1.0e7;
const MAX_AGENTS: usize = 10_000;
const MIN_PERIOD_S: f64 = 0.001;
const MAX_PERIOD_S: f64 = 60.0;
const MAX_STALE_PERIODS: f64 = 1000.0;
const MAX_BEAMS: usize = 4096;
const MAX_SENSOR_RANGE_M: f64 = 1000.0;
const MAX_SENSOR_NOISE: f64 = 10.0;
const MAX_NEIGHBOURS: usize = 16;
const MAX_SPREAD_M: f64 = 1000.0;
const MAX_GAIN: f64 = 1.0e6;

/// The arena: its size, walls, obstacles and surfaces.
fn check_arena(check: &mut RangeCheck, arena: &Arena) {
    check.number("arena.width", arena.width, 0.0, false, MAX_ARENA_M);
    check.number("arena.height", arena.height, 0.0, false, MAX_ARENA_M);
    for (i, wall) in arena.walls.iter().enumerate() {
        check.point(&format!("arena.walls[{i}].from"), wall.from);
        check.point(&format!("arena.walls[{i}].to"), wall.to);
    }
    for (i, obstacle) in arena.obstacles.iter().enumerate() {
        let field = format!("arena.obstacles[{i}]");
        match obstacle {
            Obstacle::Disc { center, radius } => {
                check.point(&format!("{field}.center"), *center);
                check.number(&format!("{field}.radius"), *radius, 0.0, false, MAX_ARENA_M);
            }
            Obstacle::Box { min, max } => {
                check.region(&format!("{field}.min"), [min[0], min[1], max[0], max[1]]);
            }
        }
    }
    for (i, surface) in arena.surfaces.iter().enumerate() {
        let field = format!("arena.surfaces[{i}]");
        check.region(&format!("{field}.region"), surface.region);
        for (name, scale) in [
            ("along_scale", surface.along_scale),
            ("across_scale", surface.across_scale),
            ("turn_scale", surface.turn_scale),
        ] {
            check.number(
                &format!("{field}.{name}"),
                scale,
                0.0,
                true,
                MAX_SURFACE_SCALE,
            );
        }
        check.number(
            &format!("{field}.from_s"),
            surface.from_s,
            0.0,
            true,
            MAX_SECONDS,
        );
    }
}

/// The robots: how many, how large, and a start region inside the arena.
fn check_agents(check: &mut RangeCheck, agents: &AgentsSection, arena: &Arena) {
    check.count("agents.count", agents.count, 1, MAX_AGENTS);
    check.number("agents.radius", agents.radius, 0.0, false, MAX_RADIUS_M);
    let [x0, y0, x1, y1] = agents.start_region;
    let inside =
        x0 < x1 && y0 < y1 && x0 >= 0.0 && y0 >= 0.0 && x1 <= arena.width && y1 <= arena.height;
    if !inside {
        check.fail(
            "agents.start_region",
            format!(
                "{:?} must be [xmin, ymin, xmax, ymax] inside the arena",
                agents.start_region
            ),
        );
    }
}

/// The control period and when a neighbour counts as gone.
fn check_timing(check: &mut RangeCheck, timing: &TimingSection) {
    check.number(
        "timing.period_s",
        timing.period_s,
        MIN_PERIOD_S,
        true,
        MAX_PERIOD_S,
    );
    check.number(
        "timing.stale_periods",
        timing.stale_periods,
        1.0,
        true,
        MAX_STALE_PERIODS,
    );
}

/// The range sensor.
fn check_sensor(check: &mut RangeCheck, sensor: &RangeSensor) {
    check.count("sensor.beams", sensor.beams, 1, MAX_BEAMS);
    check.number(
        "sensor.field_of_view",
        sensor.field_of_view,
        0.0,
        false,
        std::f64::consts::TAU,
    );
    check.number(
        "sensor.max_range",
        sensor.max_range,
        0.0,
        false,
        MAX_SENSOR_RANGE_M,
    );
    check.number(
        "sensor.noise_per_m",
        sensor.noise_per_m,
        0.0,
        true,
        MAX_SENSOR_NOISE,
    );
    check.number("sensor.dropout", sensor.dropout, 0.0, true, 1.0);
}

/// The formation controller's gains.
fn check_formation(check: &mut RangeCheck, formation: &FormationParams) {
    check.count(
        "formation.neighbours",
        formation.neighbours,
        1,
        MAX_NEIGHBOURS,
    );
    check.number(
        "formation.spread",
        formation.spread,
        0.0,
        false,
        MAX_SPREAD_M,
    );
    check.number("formation.gain", formation.gain, 0.0, false, MAX_GAIN);
    check.number(
        "formation.dead_band",
        formation.dead_band,
        0.0,
        true,
        MAX_GAIN,
    );
    check.number(
        "formation.goal_gain",
        formation.goal_gain,
        0.0,
        true,
        MAX_GAIN,
    );
}

/// Collects the first out-of-range field of a scenario or of one section.
#[derive(Default)]
pub struct RangeCheck {
    /// The section checked, which prefixes its fields' names ("" for the
    /// scenario's own checks, which name fields whole).
    section: &'static str,
    first: Option<(String, String)>,
}

impl RangeCheck {
    pub fn fail(&mut self, field: &str, message: String) {
        if self.first.is_none() {
            let field = if self.section.is_empty() {
                field.to_owned()
            } else {
                format!("{}.{field}", self.section)
            };
            self.first = Some((field, message));
        }
    }

    /// `value` must be finite, above `low` (or equal to it when
    /// `low_allowed`) and at most `high`.
    pub fn number(&mut self, field: &str, value: f64, low: f64, low_allowed: bool, high: f64) {
        let above = if low_allowed {
            value >= low
        } else {
            value > low
        };
        if !(value.is_finite() && above && value <= high) {
            let bracket = if low_allowed { '[' } else { '(' };
            self.fail(field, format!("{value} is outside {bracket}{low}, {high}]"));
        }
    }

    pub fn count(&mut self, field: &str, value: usize, low: usize, high: usize) {
        if !(low..=high).contains(&value) {
            self.fail(field, format!("{value} is outside {low}..={high}"));
        }
    }

    pub fn point(&mut self, field: &str, point: [f64; 2]) {
        if point
            .iter()
            .any(|v| !v.is_finite() || v.abs() > MAX_ARENA_M)
        {
            self.fail(
                field,
                format!("{point:?} must be finite coordinates in metres"),
            );
        }
    }

    /// `[xmin, ymin, xmax, ymax]` with finite corners, min below max.
    pub fn region(&mut self, field: &str, region: [f64; 4]) {
        let [x0, y0, x1, y1] = region;
        let finite = region
            .iter()
            .all(|v| v.is_finite() && v.abs() <= MAX_ARENA_M);
        if !(finite && x0 < x1 && y0 < y1) {
            self.fail(
                field,
                format!("{region:?} must be [xmin, ymin, xmax, ymax] with min below max"),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_scenario_round_trips_through_toml() {
        let scenario = Scenario::default_arena();
        let text = scenario.to_toml().expect("a scenario writes as TOML");
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
    fn every_number_is_range_checked_naming_its_line() {
        let base = "[arena]\nwidth = 10.0\nheight = 10.0\n[agents]\ncount = 3\nstart_region = [1.0, 1.0, 9.0, 9.0]\n";
        let cases = [
            ("[sensor]\nmax_range = nan\n", "sensor.max_range", 8),
            ("[sensor]\nbeams = 100000000\n", "sensor.beams", 8),
            ("[timing]\nperiod_s = inf\n", "timing.period_s", 8),
            (
                "[timing]\nstale_periods = -2.0\n",
                "timing.stale_periods",
                8,
            ),
            (
                "[[arena.surfaces]]\nname = \"a\"\nregion = [0.0, 0.0, 1.0, 1.0]\n[[arena.surfaces]]\nname = \"b\"\nregion = [0.0, 0.0, 1.0, 1.0]\nturn_scale = nan\n",
                "arena.surfaces[1].turn_scale",
                13,
            ),
        ];
        for (extra, field, line) in cases {
            let text = format!("{base}{extra}");
            let error = Scenario::from_toml(&text, "s.toml").unwrap_err();
            assert_eq!(error.field.as_deref(), Some(field), "{error}");
            assert_eq!(error.line, Some(line), "{error}");
        }
        let many = base.replace("count = 3", "count = 100000000");
        let error = Scenario::from_toml(&many, "s.toml").unwrap_err();
        assert_eq!(error.field.as_deref(), Some("agents.count"), "{error}");
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

    #[test]
    fn a_large_swarm_gets_an_arena_it_fits_in() {
        let small = Scenario::default_for(20);
        assert_eq!(
            small.arena,
            Scenario::default_arena().arena,
            "20 robots fit the default"
        );
        assert_eq!(small.agents.count, 20);
        let crowded = Scenario {
            agents: AgentsSection {
                count: 1000,
                ..Scenario::default_arena().agents
            },
            ..Scenario::default_arena()
        };
        assert!(
            crowded.crowded_starts() > 0,
            "1000 robots cannot start 8 x 8 m apart"
        );
        let large = Scenario::default_for(1000);
        assert_eq!(large.agents.count, 1000);
        assert!(large.start_capacity() >= 1000);
        assert_eq!(large.crowded_starts(), 0);
        assert!(large.validate().is_ok());
    }
}

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::fmt;

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::mixture::Mixture2;

/// A discrete command of a legged robot (the thesis used Sony AIBOs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Command {
    Stand,
    /// Forward at speed 1..=3.
    Walk(u8),
    /// Turn on the spot; positive is counter-clockwise, magnitude 1..=3.
    Turn(i8),
    /// Sideways; positive is to the left, magnitude 1..=2.
    Strafe(i8),
}

impl Command {
    pub const ALL: [Command; 14] = [
        Command::Stand,
        Command::Walk(1),
        Command::Walk(2),
        Command::Walk(3),
        Command::Turn(-3),
        Command::Turn(-2),
        Command::Turn(-1),
        Command::Turn(1),
        Command::Turn(2),
        Command::Turn(3),
        Command::Strafe(-2),
        Command::Strafe(-1),
        Command::Strafe(1),
        Command::Strafe(2),
    ];

    /// Position in [`Command::ALL`]; also the wire code.
    pub fn index(self) -> usize {
        Self::ALL.iter().position(|c| *c == self).unwrap_or(0)
    }

    pub fn from_index(index: usize) -> Option<Self> {
        Self::ALL.get(index).copied()
    }

    pub fn parse(text: &str) -> Option<Self> {
        Self::ALL
            .iter()
            .copied()
            .find(|c| c.to_string() == text.trim())
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Command::Stand => write!(f, "stand"),
            Command::Walk(n) => write!(f, "walk({n})"),
            Command::Turn(n) => write!(f, "turn({n})"),
            Command::Strafe(n) => write!(f, "strafe({n})"),
        }
    }
}

/// The three motion parameters of one step: along the heading (D), across it (C), turn (T).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Param {
    D,
    C,
    T,
}

impl Param {
    pub const ALL: [Param; 3] = [Param::D, Param::C, Param::T];

    /// Where the parameter stands in [`Param::ALL`], as on the wire.
    pub fn index(self) -> usize {
        self as usize
    }
}

/// The distributions of D, C and T for one command.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CommandModel {
    pub d: Mixture2,
    pub c: Mixture2,
    pub t: Mixture2,
}

impl CommandModel {
    pub fn param(&self, param: Param) -> &Mixture2 {
        match param {
            Param::D => &self.d,
            Param::C => &self.c,
            Param::T => &self.t,
        }
    }

    pub fn param_mut(&mut self, param: Param) -> &mut Mixture2 {
        match param {
            Param::D => &mut self.d,
            Param::C => &mut self.c,
            Param::T => &mut self.t,
        }
    }
}

/// One drawn step: what a command did this time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionSample {
    pub command: Command,
    pub along: f64,
    pub across: f64,
    pub turn: f64,
}

/// A legged robot's motion model: per command, per parameter, a two-Gaussian mixture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    try_from = "BTreeMap<String, CommandModel>",
    into = "BTreeMap<String, CommandModel>"
)]
pub struct MotionModel {
    commands: Vec<CommandModel>,
}

impl MotionModel {
    /// The same model with every command's step scaled: along the heading
    /// by `along`, across it by `across`, its turn by `turn` (a floor, or a
    /// model deliberately wrong).
    pub fn scaled(&self, along: f64, across: f64, turn: f64) -> Self {
        let mut scaled = self.clone();
        for command in Command::ALL {
            let m = scaled.command_mut(command);
            m.d = m.d.scaled(along);
            m.c = m.c.scaled(across);
            m.t = m.t.scaled(turn);
        }
        scaled
    }

    /// How far a full stride (`walk(3)`) carries on average, metres.
    pub fn full_stride(&self) -> f64 {
        self.mean(Command::Walk(3)).along
    }

    /// An AIBO-like model with the thesis's shapes: walk(2)'s stride is bimodal
    /// around 14.6 cm, walk(3) drifts sideways with a skewed tail, turn(1) and
    /// turn(2) rotate 30 and 60 degrees.
    pub fn legged_default() -> Self {
        let commands = Command::ALL
            .iter()
            .map(|command| match *command {
                Command::Stand => CommandModel {
                    d: Mixture2::gaussian(0.0, 0.003),
                    c: Mixture2::gaussian(0.0, 0.003),
                    t: Mixture2::gaussian(0.0, 0.01),
                },
                Command::Walk(n) => {
                    let n = f64::from(n);
                    CommandModel {
                        d: Mixture2::bimodal(0.073 * n, 0.03 * n, 0.006 * n),
                        c: Mixture2::skewed(0.0, 0.004 * n, 0.008 * n),
                        t: Mixture2::gaussian(0.0, 0.02 * n),
                    }
                }
                Command::Turn(n) => {
                    let n = f64::from(n);
                    CommandModel {
                        d: Mixture2::gaussian(0.0, 0.008),
                        c: Mixture2::gaussian(0.0, 0.008),
                        t: Mixture2::skewed(n * PI / 6.0, 0.04 * n.abs(), 0.05 * n),
                    }
                }
                Command::Strafe(n) => {
                    let n = f64::from(n);
                    CommandModel {
                        d: Mixture2::gaussian(0.0, 0.01),
                        c: Mixture2::bimodal(0.05 * n, 0.02 * n.abs(), 0.006 * n.abs()),
                        t: Mixture2::gaussian(0.0, 0.03),
                    }
                }
            })
            .collect();
        Self { commands }
    }

    pub fn command(&self, command: Command) -> &CommandModel {
        &self.commands[command.index()]
    }

    pub fn command_mut(&mut self, command: Command) -> &mut CommandModel {
        &mut self.commands[command.index()]
    }

    /// Draws one step of `command`.
    pub fn sample(&self, command: Command, rng: &mut impl Rng) -> MotionSample {
        let model = self.command(command);
        MotionSample {
            command,
            along: model.d.sample(rng),
            across: model.c.sample(rng),
            turn: model.t.sample(rng),
        }
    }

    /// The expected step of `command`, used for planning and dead reckoning.
    pub fn mean(&self, command: Command) -> MotionSample {
        let model = self.command(command);
        MotionSample {
            command,
            along: model.d.mean(),
            across: model.c.mean(),
            turn: model.t.mean(),
        }
    }

    /// Parses a model file (tables keyed by command, as `["walk(2)"]`, each
    /// with `d`, `c` and `t` mixtures); errors name `file`, the line and the entry.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, crate::ScenarioError> {
        toml::from_str(text).map_err(|e: toml::de::Error| {
            // A model that parses but breaks an invariant is checked as a
            // whole; its message names `command.param`, which leads back to
            // the line.
            let line = line_of_entry(text, e.message()).or_else(|| {
                e.span()
                    .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1)
            });
            crate::ScenarioError {
                file: file.to_owned(),
                line,
                field: None,
                message: e.message().to_owned(),
            }
        })
    }

    /// How far this model lies from `reference`: the mean over commands and
    /// parameters of the shift of the mixture mean in units of the
    /// reference's standard deviation.
    pub fn distance_from(&self, reference: &MotionModel) -> f64 {
        self.distance_over(reference, &Command::ALL)
    }

    /// [`MotionModel::distance_from`] over `commands` only.
    pub fn distance_over(&self, reference: &MotionModel, commands: &[Command]) -> f64 {
        let mut total = 0.0;
        let mut count = 0.0;
        for &command in commands {
            for param in Param::ALL {
                let (a, b) = (
                    self.command(command).param(param),
                    reference.command(command).param(param),
                );
                total += (a.mean() - b.mean()).abs() / b.variance().sqrt().max(1e-9);
                count += 1.0;
            }
        }
        if count > 0.0 { total / count } else { 0.0 }
    }

    pub fn validate(&self) -> Result<(), String> {
        for command in Command::ALL {
            for param in Param::ALL {
                self.command(command).param(param).validate().map_err(|e| {
                    format!("{command}.{}: {e}", format!("{param:?}").to_lowercase())
                })?;
            }
        }
        Ok(())
    }
}

/// The line of `param = ...` under the `["command"]` table that a message
/// like `turn(1).t: ...` names.
fn line_of_entry(text: &str, message: &str) -> Option<usize> {
    let (command, param) = message.split(':').next()?.rsplit_once('.')?;
    // The message names the array at fault ("weight 1 is ...").
    let key = ["weights", "means", "variances"]
        .into_iter()
        .find(|k| message.contains(k.trim_end_matches('s')));
    let mut inside = false;
    // A table of its own (`["walk(1)".t]`), as serialisers write it: its line.
    let mut param_table: Option<usize> = None;
    for (index, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.starts_with('[') {
            if param_table.is_some() {
                break;
            }
            inside = line.contains(command);
            let header = line.trim_end_matches(']').trim_end_matches('"');
            if inside && header.ends_with(&format!(".{param}")) {
                param_table = Some(index + 1);
            }
        } else if param_table.is_some() {
            if key.is_some_and(|k| line.split('=').next().map(str::trim) == Some(k)) {
                return Some(index + 1);
            }
        } else if inside && line.split('=').next().map(str::trim) == Some(param) {
            return Some(index + 1);
        }
    }
    param_table
}

impl TryFrom<BTreeMap<String, CommandModel>> for MotionModel {
    type Error = String;

    /// Commands a file leaves out keep the default model, so a file can
    /// override just the commands it measured.
    fn try_from(entries: BTreeMap<String, CommandModel>) -> Result<Self, Self::Error> {
        let mut model = Self::legged_default();
        for (name, entry) in entries {
            let command = Command::parse(&name).ok_or_else(|| {
                format!("unknown command `{name}` (expected stand, walk(1..3), turn(+-1..3), strafe(+-1..2))")
            })?;
            *model.command_mut(command) = entry;
        }
        model.validate()?;
        Ok(model)
    }
}

impl From<MotionModel> for BTreeMap<String, CommandModel> {
    fn from(model: MotionModel) -> Self {
        Command::ALL
            .iter()
            .map(|c| (c.to_string(), *model.command(*c)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_model_file_with_bad_weights_names_the_line_of_the_entry() {
        let text = "[\"turn(1)\"]\n\
            d = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n\
            c = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n\
            t = { weights = [0.5, 0.7], means = [0.1, 0.2], variances = [1e-4, 1e-4] }\n";
        let error = MotionModel::from_toml(text, "m.toml").expect_err("weights sum to 1.2");
        // Serialisers write each parameter as a table of its own; the line is still found.
        let mixture = "weights = [0.5, 0.5]\nmeans = [0.0, 0.0]\nvariances = [0.1, 0.1]\n";
        let tables = format!(
            "[\"walk(1)\".d]\n{mixture}[\"walk(1)\".c]\n{mixture}[\"walk(1)\".t]\n{}",
            mixture.replace("[0.1, 0.1]", "[-1.0, 0.1]")
        );
        let in_table = MotionModel::from_toml(&tables, "m.toml").expect_err("negative variance");
        assert_eq!(in_table.line, Some(12), "{in_table}");
        assert_eq!(error.line, Some(4), "{error}");
        assert!(
            error.to_string().contains("turn(1).t: weights sum to 1.2"),
            "{error}"
        );
    }

    #[test]
    fn a_model_is_as_far_from_another_as_its_means_moved_in_standard_deviations() {
        let reference = MotionModel::legged_default();
        assert_eq!(reference.distance_from(&reference), 0.0);
        let mut moved = reference.clone();
        let d = moved.command_mut(Command::Walk(2)).param_mut(Param::D);
        let std = d.variance().sqrt();
        d.means = d.means.map(|m| m + std);
        // One of 14 x 3 parameters moved by one standard deviation.
        assert!((moved.distance_from(&reference) - 1.0 / 42.0).abs() < 1e-9);
    }

    #[test]
    fn commands_round_trip_through_their_names_and_indices() {
        for command in Command::ALL {
            assert_eq!(Command::parse(&command.to_string()), Some(command));
            assert_eq!(Command::from_index(command.index()), Some(command));
        }
    }

    #[test]
    fn walk_two_is_bimodal_around_the_thesis_stride() {
        let model = MotionModel::legged_default();
        let d = model.command(Command::Walk(2)).d;
        assert!((d.mean() - 0.146).abs() < 1e-9);
        assert!(d.pdf(0.146) < d.pdf(0.116));
    }

    #[test]
    fn a_model_file_overrides_only_the_commands_it_names() {
        let text = r#"
            ["turn(1)"]
            d = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }
            c = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }
            t = { weights = [0.5, 0.5], means = [1.0, 1.0], variances = [1e-3, 1e-3] }
        "#;
        let model: MotionModel = toml::from_str(text).expect("valid model");
        assert!((model.mean(Command::Turn(1)).turn - 1.0).abs() < 1e-12);
        assert_eq!(
            model.command(Command::Walk(2)),
            MotionModel::legged_default().command(Command::Walk(2))
        );
    }

    #[test]
    fn a_model_file_with_negative_variance_is_rejected() {
        let text = r#"
            ["walk(1)"]
            d = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [-1e-4, 1e-4] }
            c = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }
            t = { weights = [0.5, 0.5], means = [1.0, 1.0], variances = [1e-3, 1e-3] }
        "#;
        let error = toml::from_str::<MotionModel>(text).unwrap_err().to_string();
        assert!(error.contains("walk(1).d: variance 0"), "{error}");
    }
}

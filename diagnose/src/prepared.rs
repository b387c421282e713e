//! What every stage of the diagnosis works on: its options, the run
//! prepared into a command grid and segments with their held-out blocks,
//! where the robot usually drives, and the findings the stages share.
//! Apart from `diagnosis`, which runs the stages, so that no stage imports
//! the module that calls it.

use std::collections::BTreeMap;
use std::sync::Arc;

use serde::Serialize;
use shoal_physics::{CommandGrid, Effect, ScopedEffect};

use crate::recording::Recording;
use crate::segments::{Segment, blocks, command_grid, segments};

#[derive(Clone, Debug)]
pub struct Options {
    /// Seconds each segment predicts ahead.
    pub horizon_s: f64,
    /// The command grid's step.
    pub grid_dt: f64,
    /// A narrower scope (part of the run, a region) replaces an effect
    /// acting everywhere when it lowers BIC by more than this.
    pub min_scope_bic_gain: f64,
    /// Family-wise level of the test an effect must pass to enter: its
    /// calibrated likelihood-ratio statistic against the library's kinds,
    /// Bonferroni-corrected (see [`entry_threshold`]).
    pub select_alpha: f64,
    pub max_effects: usize,
    /// Family-wise level of the locating tests.
    pub alpha: f64,
    pub folds: usize,
    pub max_iters: u64,
    /// How many segments rank the candidates of a round.
    pub screen_segments: usize,
    /// How many of the best-ranked candidates are fitted on every segment.
    pub confirm: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            horizon_s: 1.0,
            grid_dt: 0.02,
            min_scope_bic_gain: 10.0,
            select_alpha: 0.01,
            max_effects: 4,
            alpha: 0.01,
            folds: 5,
            max_iters: 120,
            screen_segments: 400,
            confirm: 3,
        }
    }
}

/// Another effect that explains the same mismatch about as well.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alternative {
    pub kind: &'static str,
    pub params: BTreeMap<&'static str, f64>,
    pub delta_bic: f64,
    pub sentence: String,
    /// Where it was ranked below the effect named by a controller's answer
    /// to noise that lasts: the z of its gain over the named effect where
    /// no command answered the noise (not shown worse there, so said).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub where_no_command_answered: Option<f64>,
}

/// A mismatch the library could only fit with a parameter on the edge of
/// what is physical: not reported as physics.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Unexplained {
    /// The effect that was tried, and where its fit ended.
    pub tried: &'static str,
    pub params: BTreeMap<&'static str, f64>,
    pub reason: String,
    /// The fit on the edge, for the checks a named effect faces too.
    #[serde(skip)]
    pub scoped: ScopedEffect,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Heldout {
    pub heldout_rmse_pos_m: f64,
    pub heldout_rmse_theta_rad: f64,
    /// Mean negative log-likelihood per held-out segment.
    pub heldout_nll: f64,
}

/// The prepared run: grid and segments.
pub struct Prepared {
    pub grid: CommandGrid,
    pub segments: Vec<Segment>,
    /// Observed poses set aside as gross outliers before segmenting.
    pub pose_outliers: usize,
    /// Stretches set aside as not the body's own motion (`glitches::set_aside`).
    pub glitches: Vec<crate::glitches::Glitch>,
    /// Where the poses held positions only: how their headings were taken
    /// from the track (`track::headed`).
    pub heading_from_track: Option<crate::track::TrackHeadings>,
    /// Where the poses' headings were turned by quarter turns to the way
    /// the robot drives (`track::driving_axis`).
    pub heading_axis: Option<crate::track::HeadingAxis>,
    /// The held-out blocks, as ranges of `segments`: one per recording
    /// joined, or `Options::folds` equal stretches of time.
    pub blocks: Vec<std::ops::Range<usize>>,
    /// How often poses come: the median interval between observed poses
    /// (what is left after the cleaning above), seconds.
    pub pose_period_s: f64,
    /// The run as cleaned above, which another cut of it starts from
    /// ([`Prepared::recut`]): the cleaning is the same for every cut.
    cleaned: Arc<Recording>,
}

impl Prepared {
    /// Whether this run can show an effect of `kind`: not one that only
    /// turns where the body points from where it moves, where headings
    /// were taken from the track.
    pub(crate) fn can_show(&self, kind: &str) -> bool {
        self.heading_from_track.is_none() || !crate::track::UNSEEN_FROM_THE_TRACK.contains(&kind)
    }
}

/// The run as diagnosis compares it: what not the body's own motion explains set
/// aside (`glitches::set_aside`), then gross pose outliers (see
/// `Poses::without_outliers`), headings taken from the track where the
/// poses hold none (`track::headed`: after the cleaning, so that no jump
/// bends a heading), commands on a grid, segments started at the observed
/// poses.
pub fn prepare(recording: &Recording, options: &Options) -> Prepared {
    prepare_cut(recording, options, |recording, grid| {
        segments(recording, grid, options.horizon_s)
    })
}

/// [`prepare`], with the segments cut by `cut` from the cleaned run and its
/// grid.
pub fn prepare_cut(
    recording: &Recording,
    options: &Options,
    cut: impl Fn(&Recording, &CommandGrid) -> Vec<Segment>,
) -> Prepared {
    let (recording, glitches) = crate::glitches::set_aside(recording);
    let (recording, pose_outliers) = recording.without_pose_outliers();
    let (recording, heading_axis) = match crate::track::driving_axis(&recording) {
        Some((turned, how)) => (turned, Some(how)),
        None => (recording, None),
    };
    let (recording, heading_from_track) = match crate::track::headed(&recording) {
        Some((headed, how)) => (headed, Some(how)),
        None => (recording, None),
    };
    let cleaned = Arc::new(recording);
    let (grid, segments, blocks, pose_period_s) = cut_cleaned(&cleaned, options, cut);
    Prepared {
        grid,
        segments,
        pose_outliers,
        glitches,
        heading_from_track,
        heading_axis,
        blocks,
        pose_period_s,
        cleaned,
    }
}

impl Prepared {
    /// The same cleaned run, its segments cut by `cut` on the grid of
    /// `options`.
    pub(crate) fn recut(
        &self,
        options: &Options,
        cut: impl Fn(&Recording, &CommandGrid) -> Vec<Segment>,
    ) -> Prepared {
        let (grid, segments, blocks, pose_period_s) = cut_cleaned(&self.cleaned, options, cut);
        Prepared {
            grid,
            segments,
            pose_outliers: self.pose_outliers,
            glitches: self.glitches.clone(),
            heading_from_track: self.heading_from_track.clone(),
            heading_axis: self.heading_axis.clone(),
            blocks,
            pose_period_s,
            cleaned: Arc::clone(&self.cleaned),
        }
    }
}

/// A cleaned run's grid, its segments cut by `cut`, their held-out blocks
/// and the poses' median interval.
fn cut_cleaned(
    recording: &Recording,
    options: &Options,
    cut: impl Fn(&Recording, &CommandGrid) -> Vec<Segment>,
) -> (CommandGrid, Vec<Segment>, Vec<std::ops::Range<usize>>, f64) {
    let grid = command_grid(recording, options.grid_dt);
    let segments = cut(recording, &grid);
    let blocks = blocks(&segments, &recording.joins, options.folds);
    let mut intervals: Vec<f64> = recording.poses.t.windows(2).map(|w| w[1] - w[0]).collect();
    intervals.sort_by(f64::total_cmp);
    let pose_period_s = intervals.get(intervals.len() / 2).copied().unwrap_or(0.0);
    (grid, segments, blocks, pose_period_s)
}

/// Where the robot usually drives: the median commanded speed and turn
/// rate of the segments in which it moves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct OperatingPoint {
    pub speed_m_per_s: f64,
    pub turn_rad_per_s: f64,
}

impl OperatingPoint {
    /// `effect` in one sentence, stated here.
    pub(crate) fn sentence(&self, effect: &Effect, duration: f64) -> String {
        effect.sentence_at(self.speed_m_per_s, self.turn_rad_per_s, duration)
    }

    pub(crate) fn of(segments: &[Segment]) -> Self {
        let median = |mut values: Vec<f64>| {
            values.sort_by(f64::total_cmp);
            values.get(values.len() / 2).copied().unwrap_or(0.0)
        };
        Self {
            speed_m_per_s: median(
                segments
                    .iter()
                    .filter(|s| s.speed >= 0.01)
                    .map(|s| s.speed)
                    .collect(),
            ),
            turn_rad_per_s: median(
                segments
                    .iter()
                    .filter(|s| s.turn.abs() >= 0.02)
                    .map(|s| s.turn.abs())
                    .collect(),
            ),
        }
    }
}

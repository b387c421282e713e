//! The feedback stage: every effect named must also predict better where no
//! command could have answered the noise it is scored on.
//!
//! A segment's prediction replays the commands of its horizon. A controller
//! that steers on the body's pose (a navigation stack, a waypoint follower)
//! turns each bit of motion noise into later commands of the same segment,
//! so the commands correlate with the residual the model must explain, and
//! an effect that damps the model's response to command changes (a play, a
//! lag, a delay) explains part of the noise: the closed-loop identification
//! bias of the direct method. Closed-loop identification is free of it
//! where the loop holds a delay: here, on segments cut at the commands, one
//! command period long, each replaying one command chosen before its noise.
//! At such a horizon the pose noise hides a weak effect's fit, but not a
//! held effect's prediction: the effect keeps the parameters fitted at the
//! long horizon and is only scored at the short one, each held-out block
//! with the noise estimated on the others, as the held-out stage scores.
//!
//! Two bounds keep the check honest. A fit of noise onto anything the
//! commands carry explains at most the noise's own variance, so an effect
//! that moves the long horizon's predictions by more than the noise's
//! spread is beyond any controller's answer and is kept even where the
//! short horizon cannot confirm it (a legged body's gait is no unicycle
//! within a tenth of a second). And the check reports the gain a real
//! effect of the fitted size would show at the short horizon, so a reader
//! sees whether that horizon contradicts the effect or is too short to say.

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::Serialize;
use shoal_physics::{ScopedEffect, UnicycleModel};

use crate::covariates::correlation;
use crate::fit::all_but;
use crate::heldout::{on_folds, predict_block, refit_on};
use crate::likelihood::{
    estimate_noise, lagged_products, long_run_factor, residuals, segment_nll, standardised,
};
use crate::prepared::{Options, Prepared};
use crate::recording::Recording;
use crate::segments::{Segment, command_grid, held_segments, holds, moving, segments};

/// The one-sided z an effect's short-horizon held-out gain must reach on
/// one horizon: a 5% test. An effect already passed its entry test on the
/// long horizon; this asks only that its gain there is not the
/// controller's. Scored on several horizons, the level is Simes' for all
/// of them together ([`z_needed`]).
pub const MIN_Z: f64 = 1.645;

/// The z the best of `zs` (one per horizon) must reach for an effect to be
/// confirmed at 5% over all the horizons: Simes' test of the hypothesis
/// that it gains nothing at any of them, valid for the positively
/// dependent gains of one effect on one run. Sorted best first, the k-th
/// must reach the one-sided quantile of 5% k / n for some k: on two
/// horizons, the best at 2.5% (z 1.96), or both at 5% (z 1.645). Returns
/// the level met, or the best's (5% / n) if none is.
pub fn z_needed(zs: &[f64]) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal};
    let n = zs.len().max(1);
    let level = |k: usize| Normal::standard().inverse_cdf(1.0 - 0.05 * k as f64 / n as f64);
    let mut sorted = zs.to_vec();
    sorted.sort_by(|a, b| b.total_cmp(a));
    (1..=sorted.len())
        .rev()
        .map(|k| (level(k), sorted[k - 1]))
        .find(|(needed, z)| z >= needed)
        .map_or(level(1), |(needed, _)| needed)
}

/// The largest effect, in the noise's standard deviations, that a fit can
/// make of noise: all of it (a correlation of 1 with the commands).
pub const MAX_FEEDBACK_SIZE: f64 = 1.0;

/// Why an effect is kept at the feedback-free horizon
/// ([`FeedbackFree::confirmation`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Confirmation {
    /// It predicts better there, at the z needed.
    Shown,
    /// It moves the prediction by more than a controller's answer to the
    /// noise can ([`MAX_FEEDBACK_SIZE`]).
    BeyondFeedback,
    /// No command answers the pose (open loop) and the effect builds up
    /// between command changes: the horizon does not contradict it.
    OpenLoopUncontradicted,
}

/// Writes a check with the reason it was kept beside its figures
/// (`kept_because`), so a reader of the JSON need not re-derive
/// [`FeedbackFree::confirmation`] from them.
pub fn serialize_with_confirmation<S: serde::Serializer>(
    check: &Option<FeedbackFree>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct WithConfirmation<'a> {
        #[serde(flatten)]
        check: &'a FeedbackFree,
        kept_because: Option<Confirmation>,
    }
    check
        .as_ref()
        .map(|check| WithConfirmation {
            check,
            kept_because: check.confirmation(),
        })
        .serialize(serializer)
}

/// How an effect predicts at the feedback-free horizon.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FeedbackFree {
    pub horizon_s: f64,
    /// Held-out log-likelihood gain over the model without the effect, in
    /// nats, summed over the segments.
    pub gain: f64,
    /// The gain over its standard error (segment gains' spread, inflated by
    /// their correlation in time).
    pub z: f64,
    /// The z it must reach: [`MIN_Z`] on one horizon, more on several.
    pub z_needed: f64,
    /// The gain a real effect of the fitted size would show there: below a
    /// few nats the short horizon cannot tell it from the controller's
    /// answer either way.
    pub expected_gain: f64,
    /// How far the gain falls short of that, over the same standard error:
    /// far below zero, the short horizon contradicts the effect.
    pub z_against_expected: f64,
    /// How far the effect moves the long horizon's predictions, in the
    /// noise's standard deviations (root mean square over segments and
    /// components). A fit of noise onto anything the commands carry explains
    /// at most the noise's own variance, so a controller's answer to the
    /// noise makes only effects smaller than this bound.
    pub size_in_noise: f64,
    /// Nats that a controller's answer to noise that lasts could make an
    /// effect of the fitted size gain at this horizon ([`LastingNoise`],
    /// `answer_for_size`): the gain is counted from it (`z` is the gain
    /// less it, over the standard error). 0 where the commands do
    /// not answer the pose, the noise does not last past a command, or the
    /// effect does not respond to command changes.
    pub lasting_answer: f64,
    /// What that answer could make any effect gain, whatever its size
    /// ([`LastingNoise`]): more than 0 only where the commands answer the
    /// pose, the noise lasts past a command and the effect responds to
    /// command changes.
    pub answer_allowance: f64,
    /// Whether on some horizon the commands answer the pose
    /// ([`LastingNoise::commands_answer`]): the recording is closed loop.
    pub commands_answer: bool,
    /// Whether the effect acts where a command changes (a delay, a lag, a
    /// play, an acceleration limit).
    pub acts_at_command_changes: bool,
}

impl FeedbackFree {
    /// Confirmed where no command answered the noise, or too large for any
    /// controller's answer to the noise, or, where the commands do not
    /// answer the pose at all, an effect that builds up between command
    /// changes (a drift, a bias, a scale) not contradicted there. Open
    /// loop, the long horizon's gain holds no answer to the noise, and for
    /// such an effect the short horizon, with a tenth of its power or less,
    /// can only say the effect is not what it sees: asked to confirm as
    /// well, it dropped small heading drifts under coloured noise that the
    /// long horizon had shown. An effect that acts at command changes is
    /// seen best one command period after one, and is still asked to show
    /// there: lags of 10 ms that helped nothing held out, on a simulator
    /// stepping every 20 ms, stayed out only so (EXPERIMENTS.md 5c, "Open
    /// loop").
    pub fn confirmed(&self) -> bool {
        self.confirmation().is_some()
    }

    /// Why the effect is kept at this horizon, or `None` where it is not:
    /// the one place [`Self::confirmed`]'s three ways are told apart, so
    /// the report says the one that held.
    pub fn confirmation(&self) -> Option<Confirmation> {
        if self.z >= self.z_needed {
            Some(Confirmation::Shown)
        } else if self.beyond_feedback() {
            Some(Confirmation::BeyondFeedback)
        } else if !self.commands_answer && !self.acts_at_command_changes && !self.contradicted() {
            Some(Confirmation::OpenLoopUncontradicted)
        } else {
            None
        }
    }

    /// Confirmed on this horizon's own evidence, open loop or closed: what
    /// a mismatch said on a round's test alone, with no held-out blocks
    /// behind it, must show.
    pub fn confirmed_there(&self) -> bool {
        matches!(
            self.confirmation(),
            Some(Confirmation::Shown | Confirmation::BeyondFeedback)
        )
    }

    /// The gain lies so far below what a real effect of the fitted size
    /// would show that this horizon speaks against it.
    pub fn contradicted(&self) -> bool {
        self.z_against_expected <= -self.z_needed
    }

    /// Larger than any effect a controller's answer to the noise can make.
    pub fn beyond_feedback(&self) -> bool {
        self.size_in_noise >= MAX_FEEDBACK_SIZE
    }

    /// Unconfirmed, yet leaning towards the effect: a real effect of the
    /// fitted size would gain more here than any answer to the noise could
    /// (so this horizon can tell them apart in principle), and the gain lies
    /// nearer that than the answer's bound. The test lacked the power to
    /// decide, and the recording cannot tell the effect from the
    /// controller's answer: the report says so, rather than that the motion
    /// matches the model. Only where the answer has an allowance (the
    /// commands answer the pose, the noise lasts, the effect responds to
    /// command changes): elsewhere the horizon is free of the answer, and
    /// an effect it cannot confirm is not said (a speed scale leaned so in
    /// a null bench run). Never true of an effect the horizon contradicts
    /// (its gain would lie more than `z_needed` below the expected, and so
    /// more than `z_needed` above the bound, confirmed) nor of one whose
    /// whole gain an answer to the noise could make.
    pub fn undecided(&self) -> bool {
        self.answer_allowance > 0.0
            && !self.confirmed()
            && self.expected_gain > self.lasting_answer
            && self.gain > 0.5 * (self.expected_gain + self.lasting_answer)
    }

    /// The allowance for an answer to noise that lasts, in words: empty
    /// where there is none.
    pub fn lasting_allowance_words(&self) -> String {
        if self.lasting_answer > 0.0 {
            format!(
                ", counted from the {:.1} nats a controller's answer to noise that lasts past a command could make an effect of its size gain",
                self.lasting_answer
            )
        } else {
            String::new()
        }
    }

    /// Why an unconfirmed effect was dropped, in words.
    pub fn why_unconfirmed(&self) -> String {
        let what = if self.contradicted() {
            "contradicts it"
        } else if self.undecided() {
            "leans towards the effect, but has not the power to decide"
        } else {
            "is too short to tell it from the controller's answer"
        };
        format!(
            "held out on {:.2} s segments, where no command answered the noise, it gains {:+.1} nats (z {:.2}, {:.2} needed{}) where a real effect of its size would gain about {:+.1}: that horizon {what}",
            self.horizon_s,
            self.gain,
            self.z,
            self.z_needed,
            self.lasting_allowance_words(),
            self.expected_gain
        )
    }
}

/// An effect dropped because it predicts no better at the feedback-free
/// horizon: what a controller steering on the pose would make.
#[derive(Clone, Debug, Serialize)]
pub struct NotFeedbackFree {
    pub kind: &'static str,
    pub params: BTreeMap<&'static str, f64>,
    pub sentence: String,
    pub check: FeedbackFree,
    /// [`FeedbackFree::undecided`]: the recording cannot tell it from the
    /// controller's answer either way.
    pub undecided: bool,
    /// The effect as it was fitted when dropped.
    #[serde(skip)]
    pub scoped: ScopedEffect,
}

/// A recording cut at its feedback-free horizons and prepared, one run per
/// horizon: the same whatever model is checked on it, so a diagnosis cuts
/// it once for all its checks.
pub(crate) struct ShortRuns {
    cuts: Vec<FeedbackFreeCut>,
    shorts: Vec<Prepared>,
}

impl ShortRuns {
    /// `recording`, as `prepared` cleaned it, cut at its feedback-free
    /// horizons.
    pub(crate) fn of(recording: &Recording, prepared: &Prepared, options: &Options) -> Self {
        let cuts = feedback_free_cuts(recording, options.grid_dt, options.horizon_s);
        tracing::debug!(?cuts, "feedback-free segments");
        // Each horizon is cut on its own: in parallel.
        let shorts = cuts
            .par_iter()
            .map(|cut| cut.prepare(prepared, options))
            .collect();
        Self { cuts, shorts }
    }
}

/// The feedback-free runs of a recording (one per horizon), and on each
/// how the noise lasts past a command and whether the commands answer it.
pub(crate) struct Horizons<'a> {
    runs: &'a ShortRuns,
    lasting: Vec<LastingNoise>,
}

impl<'a> Horizons<'a> {
    /// `runs` with the lasting noise measured with the residuals of
    /// `fixed` and `found`.
    pub(crate) fn of(runs: &'a ShortRuns, fixed: &[ScopedEffect], found: &[ScopedEffect]) -> Self {
        let whole = UnicycleModel::with_effects(fixed.iter().chain(found).cloned().collect());
        let lasting: Vec<LastingNoise> = runs
            .shorts
            .par_iter()
            .map(|short| LastingNoise::of(short, &whole))
            .collect();
        tracing::debug!(
            ?lasting,
            "noise that lasts past a command, and commands that answer it"
        );
        Self { runs, lasting }
    }

    /// Whether on some horizon the commands answer noise that lasts past
    /// them: there the long segments' ranking of rival effects carries the
    /// controller's answer.
    pub(crate) fn answered(&self) -> bool {
        self.lasting.iter().any(LastingNoise::answers_lasting_noise)
    }

    /// Whether on some horizon the commands answer the pose, lasting noise
    /// or not: elsewhere the recording is open loop.
    pub(crate) fn commands_answer(&self) -> bool {
        self.lasting.iter().any(LastingNoise::commands_answer)
    }

    /// The short runs, one per horizon, in the order cut.
    pub(crate) fn shorts(&self) -> Vec<&Prepared> {
        self.runs.shorts.iter().collect()
    }
}

/// Each effect of `found` that moves the prediction, checked at the
/// feedback-free horizons beside the others; noise effects get `None`.
pub(crate) fn check_each(
    horizons: &Horizons,
    prepared: &Prepared,
    options: &Options,
    fixed: &[ScopedEffect],
    found: &[ScopedEffect],
) -> Vec<Option<FeedbackFree>> {
    (0..found.len())
        .map(|k| {
            let runs: Vec<(f64, &Prepared, f64)> = horizons
                .runs
                .cuts
                .iter()
                .zip(&horizons.runs.shorts)
                .zip(&horizons.lasting)
                .map(|((cut, short), lasting)| {
                    (cut.horizon_s, short, lasting.answer_per_segment(&found[k]))
                })
                .collect();
            let check = if found[k].effect.only_noise() {
                None
            } else {
                feedback_free_check(
                    prepared,
                    &runs,
                    (fixed, found, k),
                    horizons.commands_answer(),
                    options,
                )
            };
            tracing::debug!(effect = ?found[k].effect, ?check, "feedback-free check");
            check
        })
        .collect()
}

/// The finest grid the check traces on.
const MIN_GRID_DT: f64 = 0.005;

/// The commands' usual period: the median interval between them.
fn command_period(recording: &Recording) -> Option<f64> {
    let t = &recording.commands.t;
    let mut gaps: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|g| *g > 0.0)
        .collect();
    if gaps.is_empty() {
        return None;
    }
    gaps.sort_by(f64::total_cmp);
    Some(gaps[gaps.len() / 2])
}

/// Where the feedback stage scores: segments of `horizon_s` on a command
/// grid of `grid_dt`, cut at every command or only within held ones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeedbackFreeCut {
    pub horizon_s: f64,
    pub grid_dt: f64,
    /// Each segment lies within one stretch over which the command held one
    /// value (`segments::held_segments`); else segments run back to back
    /// from one command to the next.
    pub within_holds: bool,
}

impl FeedbackFreeCut {
    /// The run of `prepared` cut into this cut's segments.
    fn prepare(&self, prepared: &Prepared, options: &Options) -> Prepared {
        let options = Options {
            horizon_s: self.horizon_s,
            grid_dt: self.grid_dt,
            ..options.clone()
        };
        let steps = ((self.horizon_s / self.grid_dt).round() as usize).max(1);
        prepared.recut(&options, |recording, grid| {
            if self.within_holds {
                held_segments(recording, grid, steps)
            } else {
                segments(recording, grid, options.horizon_s)
            }
        })
    }
}

/// The feedback-free segments, one cut or two.
///
/// The first is one command period, on a grid that divides it (no coarser
/// than `grid_dt`), so that the grid (which starts at the first command)
/// cuts segments from one command to the next and each replays one
/// command, chosen before the segment's noise.
///
/// Where the commands hold one value over several periods (an operator's
/// held commands, a script's), a segment within the hold replays one
/// command as much, and a longer one can say more: at the bench's 50 Hz
/// one period (0.02 s) left true heading drifts unconfirmed that 1 s
/// within holds confirms. It is not better for every effect under every
/// noise (a speed scale under slow coloured noise is seen better at 0.02 s),
/// so the held cut is a second horizon, not a replacement: the multiple of
/// the period, up to `long_horizon_s`, with the most moving time covered by
/// segments that fit within holds, weighted by their length. A controller
/// that answers the pose with a new value every command (a navigation
/// stack) holds nothing, and has one period only.
pub fn feedback_free_cuts(
    recording: &Recording,
    grid_dt: f64,
    long_horizon_s: f64,
) -> Vec<FeedbackFreeCut> {
    let Some(period) = command_period(recording) else {
        return vec![FeedbackFreeCut {
            horizon_s: grid_dt,
            grid_dt,
            within_holds: false,
        }];
    };
    // Commands faster than this would make the grid, and the segments, too
    // many to trace: the horizon then holds a few commands.
    let period = period.max(MIN_GRID_DT);
    let steps = (period / grid_dt - 1e-9).ceil().max(1.0);
    let step = period / steps;
    let one_period = FeedbackFreeCut {
        horizon_s: period,
        grid_dt: step,
        within_holds: false,
    };
    let grid = command_grid(recording, step);
    let holds: Vec<usize> = holds(&grid)
        .into_iter()
        .filter(|hold| moving(&grid, hold.start))
        .map(|hold| hold.len())
        .collect();
    let moving_steps: usize = holds.iter().sum();
    let most = ((long_horizon_s / period + 1e-9).floor() as usize).max(1);
    // Moving time covered, weighted by the horizon, in grid steps times periods.
    let worth = |k: usize| -> usize {
        if k == 1 {
            return moving_steps;
        }
        let length = k * steps as usize;
        k * holds.iter().map(|h| h / length * length).sum::<usize>()
    };
    let best = (1..=most).fold(1, |best, k| if worth(k) > worth(best) { k } else { best });
    if best == 1 {
        return vec![one_period];
    }
    vec![
        one_period,
        FeedbackFreeCut {
            horizon_s: best as f64 * period,
            grid_dt: step,
            within_holds: true,
        },
    ]
}

/// How `found[k]` predicts the short-horizon runs of `shorts` (each with
/// its horizon), against the model of `fixed` and the other effects of
/// `found`, and how large it is against the noise of the long-horizon run
/// `long`: the horizon that predicts it best speaks for it, at the level
/// that pays for the choice ([`z_needed`]). The held-out blocks are the
/// first run's; each other run is scored on its segments that lie within a
/// block's span, so that the refits outside each block serve every horizon.
/// None without a run to score.
pub fn feedback_free_check(
    long: &Prepared,
    shorts: &[(f64, &Prepared, f64)],
    (fixed, found, k): (&[ScopedEffect], &[ScopedEffect], usize),
    commands_answer: bool,
    options: &Options,
) -> Option<FeedbackFree> {
    let &(_, first, _) = shorts.first()?;
    let others = all_but(found, k);
    let short_runs: Vec<&Prepared> = shorts.iter().map(|&(_, short, _)| short).collect();
    let per_block = blocks_compared(long, first, &short_runs, fixed, (found, &others), options);
    let with = UnicycleModel::with_effects(fixed.iter().chain(found).cloned().collect());
    let without = UnicycleModel::with_effects(fixed.iter().chain(&others).cloned().collect());
    let size = size_in_noise(long, &with, &without);
    // Each horizon's gain and z first: the level they must reach depends
    // on all of them (Simes').
    let scored: Vec<(f64, f64, f64, f64, f64)> = shorts
        .iter()
        .enumerate()
        .map(|(c, &(horizon_s, _, answer_per_segment))| {
            let blocks = || per_block.iter().map(|b| &b[c]);
            let expected_gain: f64 = blocks().map(|b| b.expected).sum();
            let gains: Vec<f64> = blocks().flat_map(|b| b.gains.iter().copied()).collect();
            let scored: Vec<Segment> = blocks().flat_map(|b| b.test.iter().cloned()).collect();
            (
                horizon_s,
                gains.iter().sum(),
                sd_of_sum(&scored, &gains),
                expected_gain,
                answer_per_segment * gains.len() as f64,
            )
        })
        .collect();
    let z = |x: f64, sd: f64| if sd > 0.0 { x / sd } else { 0.0 };
    let zs: Vec<f64> = scored
        .iter()
        .map(|&(_, gain, sd, expected, allowance)| {
            z(gain - answer_for_size(allowance, expected), sd)
        })
        .collect();
    let needed = z_needed(&zs);
    let checks: Vec<FeedbackFree> = scored
        .into_iter()
        .map(|(horizon_s, gain, sd, expected_gain, allowance)| {
            let answer = answer_for_size(allowance, expected_gain);
            FeedbackFree {
                horizon_s,
                gain,
                z: z(gain - answer, sd),
                z_needed: needed,
                expected_gain,
                z_against_expected: z(gain - expected_gain, sd),
                size_in_noise: size,
                lasting_answer: answer,
                answer_allowance: allowance,
                commands_answer,
                acts_at_command_changes: acts_at_command_changes(&found[k]),
            }
        })
        .collect();
    tracing::debug!(?checks, "feedback-free check on each horizon");
    checks.into_iter().max_by(|a, b| a.z.total_cmp(&b.z))
}

/// Per held-out block of `first`, per run of `shorts`, the gains of the
/// model of `with` over that of `without` (each beside `fixed`). Each block
/// is held out from the parameters too: the effects that move the
/// prediction are refitted on the long segments outside it, so that one
/// fitted to a stretch of noise (a scope, a slow drift) gains nothing for
/// having seen it. Effects on the noise alone weigh the segments of both
/// models alike, as fitted on the whole run (taken from `with`): refitted
/// beside each, they would take up what the other model lacks and weigh
/// the two differently. Each run is scored on its segments that lie within
/// a block's span, so that the refits outside each block serve every
/// horizon.
fn blocks_compared(
    long: &Prepared,
    first: &Prepared,
    shorts: &[&Prepared],
    fixed: &[ScopedEffect],
    (with, without): (&[ScopedEffect], &[ScopedEffect]),
    options: &Options,
) -> Vec<Vec<BlockGains>> {
    let (noise_effects, with_moving): (Vec<ScopedEffect>, Vec<ScopedEffect>) =
        with.iter().cloned().partition(|e| e.effect.only_noise());
    let without_moving: Vec<ScopedEffect> = without
        .iter()
        .filter(|e| !e.effect.only_noise())
        .cloned()
        .collect();
    let held: Vec<ScopedEffect> = fixed.iter().chain(&noise_effects).cloned().collect();
    let outside = |segments: &[Segment], from: f64, to: f64| -> Vec<Segment> {
        segments
            .iter()
            .filter(|s| s.t_end <= from || s.t_start >= to)
            .cloned()
            .collect()
    };
    on_folds(first, |_, block| {
        let (from, to) = (
            block.first().map_or(0.0, |s| s.t_start),
            block.last().map_or(0.0, |s| s.t_end),
        );
        let long_train = outside(&long.segments, from, to);
        let with =
            UnicycleModel::with_effects(refit_on(long, &long_train, &held, &with_moving, options));
        let without = UnicycleModel::with_effects(refit_on(
            long,
            &long_train,
            &held,
            &without_moving,
            options,
        ));
        shorts
            .iter()
            .map(|short| {
                let test: Vec<Segment> = short
                    .segments
                    .iter()
                    .filter(|s| s.t_start >= from && s.t_end <= to)
                    .cloned()
                    .collect();
                let train = outside(&short.segments, from, to);
                block_gains(short, &train, test, &with, &without)
            })
            .collect()
    })
}

/// Whether a rival explanation, in place of `found[k]`, predicts worse
/// where no command answered the noise: the z of its gain over `found[k]`
/// on the short horizons (the one that favours the rival most), each block
/// held out as [`feedback_free_check`] holds it. None without a run to
/// score.
///
/// On a run whose controller answers noise that lasts, the long segments
/// rank rivals with the answer in them: laps of an oval behind a 0.15 s
/// motor lag named a latency of 0.16 s (its runner-up the lag), and on
/// the short horizon the lag predicts better (z 2.0 for it). Where that
/// horizon does not show the rival worse, it is said beside the chosen,
/// never left out silently. That horizon is not wholly free of an answer
/// to noise lasting longer than a command either: wheels 6% large on the
/// same oval are named a turn bias over their turn scale on both
/// horizons (EXPERIMENTS.md 5c, "Laps").
pub(crate) fn rival_against_chosen(
    long: &Prepared,
    shorts: &[&Prepared],
    (fixed, found, k): (&[ScopedEffect], &[ScopedEffect], usize),
    rival: &ScopedEffect,
    options: &Options,
) -> Option<f64> {
    let &first = shorts.first()?;
    let mut with_rival = all_but(found, k);
    with_rival.push(rival.clone());
    let per_block = blocks_compared(long, first, shorts, fixed, (&with_rival, found), options);
    (0..shorts.len())
        .map(|c| {
            let blocks = || per_block.iter().map(|b| &b[c]);
            let gains: Vec<f64> = blocks().flat_map(|b| b.gains.iter().copied()).collect();
            let scored: Vec<Segment> = blocks().flat_map(|b| b.test.iter().cloned()).collect();
            let sd = sd_of_sum(&scored, &gains);
            let gain: f64 = gains.iter().sum();
            if sd > 0.0 { gain / sd } else { 0.0 }
        })
        .max_by(f64::total_cmp)
}

/// How far `with` moves the prediction of `long`'s segments from `without`'s,
/// in the noise's standard deviations (the root mean square of the
/// standardised difference, per component, with `with`'s noise).
fn size_in_noise(long: &Prepared, with: &UnicycleModel, without: &UnicycleModel) -> f64 {
    let segs = &long.segments;
    if segs.is_empty() {
        return 0.0;
    }
    let r_with = residuals(with, &long.grid, segs);
    let noise = estimate_noise(with, segs, &r_with);
    let a = standardised(with, &noise, segs, &r_with);
    let b = standardised(with, &noise, segs, &residuals(without, &long.grid, segs));
    let squares: f64 = a
        .iter()
        .zip(&b)
        .map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>())
        .sum();
    (squares / (3 * segs.len()) as f64).sqrt()
}

/// One held-out block at the short horizon.
struct BlockGains {
    /// The segments scored.
    test: Vec<Segment>,
    /// Each test segment's log-likelihood gain of `with` over `without`.
    gains: Vec<f64>,
    /// What the gain would be on average were `with` the truth: half the
    /// squared standardised difference of the two predictions, summed (the
    /// Kullback-Leibler divergence of the two models' predictive densities).
    expected: f64,
}

/// Fewest segments a block's noise is estimated from: three variances and
/// a growth, each within about half of itself (relative error sqrt(2/n)).
const MIN_NOISE_SEGMENTS: usize = 10;

/// [`BlockGains`] of `test`, both models scored with the noise `with` leaves
/// on `train`; none when `train` shows no noise to score with.
fn block_gains(
    prepared: &Prepared,
    train: &[Segment],
    test: Vec<Segment>,
    with: &UnicycleModel,
    without: &UnicycleModel,
) -> BlockGains {
    let with_block = predict_block(&prepared.grid, train, &test, with);
    // Held commands may all lie in one block: the others then hold too few
    // segments, or only a robot standing still whose residuals are exactly
    // zero, and a noise "estimated" there is the variance floor, against
    // which any residual costs without bound (a mud robot's gain read
    // 1.3e12 nats). Such a block tells nothing and is not scored.
    if train.len() < MIN_NOISE_SEGMENTS || with_block.noise.at_floor() {
        return BlockGains {
            test: Vec::new(),
            gains: Vec::new(),
            expected: 0.0,
        };
    }
    let without_residuals = residuals(without, &prepared.grid, &test);
    // Both models are scored with the noise estimated beside the effect, as
    // the gain a real effect would show is. Each with its own noise, the
    // model without the effect took the mismatch into a wider noise, and
    // where the noise is not the same everywhere (a legged gait's stride
    // noise, larger on the carpet than on the sand) that wider noise scored
    // better than the effect: Shoal's own demo robots lost the sand they
    // walked on (EXPERIMENTS.md 5c).
    let noise = &with_block.noise;
    let without_nll = segment_nll(with, noise, &test, &without_residuals);
    let a = standardised(with, noise, &test, &with_block.residuals);
    let b = standardised(with, noise, &test, &without_residuals);
    BlockGains {
        test,
        gains: without_nll
            .iter()
            .zip(&with_block.nll)
            .map(|(a, b)| a - b)
            .collect(),
        expected: a
            .iter()
            .zip(&b)
            .map(|(a, b)| (0..3).map(|c| 0.5 * (a[c] - b[c]).powi(2)).sum::<f64>())
            .sum(),
    }
}

/// Noise that lasts past a command, and commands that answer the pose: what
/// the one-period horizon cannot make free of feedback.
///
/// A segment one command long holds only noise that came after its command
/// was chosen, and where the motion noise is white no command can have
/// answered it. Where the noise lasts (slip that persists, a wheel that
/// runs fast for a second: a real body's noise is coloured), the segment's
/// noise continues what the controller saw, its command answers that, and
/// an effect that damps the response to command changes (a steering play,
/// a lag, a delay) explains part of the answer at any horizon. Laps of a
/// course under pure pursuit, each wheel's noise lasting 0.5 s, had a
/// steering play named in 51 of 66 runs (EXPERIMENTS.md 5c, "Laps"); with
/// white wheel noise in none. Scoring innovations instead (each residual
/// less what the ones before predict) made it worse: the controller knows
/// the pose better than a motion capture's noisy residuals tell it, and the
/// residuals it answered, brought into the score, carry its answer in.
///
/// So the answer is bounded instead. What an answer to the noise can
/// explain of a segment's residual is the part the noise's past predicts
/// (per component, the lasting motion noise's share of the residual's
/// variance times its memory squared, from the autocovariances at lags
/// 0-2: the seams' observation error, shared by neighbours, reaches lag 1
/// only), and of that past only what the commands carry (how well the
/// residual predicts the next command change). Explaining a share `p` of a
/// unit variance gains at most `p / 2` nats a segment. That allowance
/// applies where the commands answer the pose, and to effects that respond
/// to command changes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LastingNoise {
    /// Per component, the share of the standardised residual's variance
    /// that its past predicts and the commands carry: what an answer to
    /// the noise could explain.
    pub predictable: [f64; 3],
    /// How strongly the residuals predict the next command change: the
    /// largest |z| of the correlations of each component with the next
    /// change of speed and of turn rate.
    pub answer_z: f64,
}

/// The |z| of a residual's correlation with the next command change above
/// which the commands answer the pose: 3.5 (six correlations at about 0.1%
/// each, Bonferroni's 0.5%); pure pursuit's answer on laps reads 9-19.
const ANSWERS_Z: f64 = 3.5;

/// The motion noise's memory from one segment to the next is taken as at
/// most this: noise that never forgets is a mismatch, not noise.
const MAX_MEMORY: f64 = 0.98;

impl LastingNoise {
    /// Measured on `short`'s segments, with the residuals of `model`.
    fn of(short: &Prepared, model: &UnicycleModel) -> Self {
        let segments = &short.segments;
        let r = residuals(model, &short.grid, segments);
        let noise = estimate_noise(model, segments, &r);
        let z = standardised(model, &noise, segments, &r);
        // Autocovariances at lags 0-2 over segments back to back, per
        // component.
        let gammas: [[f64; 3]; 3] = std::array::from_fn(|c| {
            let series: Vec<f64> = z.iter().map(|z| z[c]).collect();
            std::array::from_fn(|lag| match lagged_products(segments, &series, lag) {
                (_, 0) => 0.0,
                (sum, pairs) => sum / pairs as f64,
            })
        });
        let gamma = |lag: usize, c: usize| gammas[c][lag];
        let fitted: [(f64, f64); 3] =
            std::array::from_fn(|c| fit_memory(gamma(0, c), gamma(1, c), gamma(2, c)));
        // Each residual against the change of command at its segment's end:
        // how much of the noise the controller's next command answers.
        let grid = &short.grid;
        let change = |s: &Segment, of: &[f64]| -> Option<f64> {
            Some(of.get(s.to)? - of.get(s.to.checked_sub(1)?)?)
        };
        // Only the part of the change the commands at the segment's end do
        // not predict: open-loop commands that revert to a mean change
        // against their level, and a residual that grows with the command
        // (a speed scale not yet named) then predicts the change without
        // any answer (a null bench run under mixed noise read z 7.9).
        let level = |s: &Segment| -> Option<[f64; 2]> {
            let at = s.to.checked_sub(1)?;
            Some([*grid.v.get(at)?, *grid.omega.get(at)?])
        };
        let mut answered = [0.0f64; 3];
        let mut answer_z: f64 = 0.0;
        for of in [&grid.v, &grid.omega] {
            let rows: Vec<([f64; 3], f64, [f64; 2])> = segments
                .iter()
                .zip(&z)
                .filter_map(|(s, z)| Some((*z, change(s, of)?, level(s)?)))
                .collect();
            let levels: Vec<[f64; 2]> = rows.iter().map(|r| r.2).collect();
            let changes = unpredicted(&levels, rows.iter().map(|r| r.1).collect());
            let pairs: Vec<([f64; 3], f64)> = rows
                .iter()
                .map(|r| r.0)
                .zip(changes.iter().copied())
                .collect();
            for c in 0..3 {
                let component: Vec<f64> = pairs.iter().map(|(z, _)| z[c]).collect();
                let r = correlation(&component, &changes).unwrap_or(0.0);
                answered[c] = answered[c].max(r * r);
                answer_z = answer_z.max(r.abs() * (pairs.len() as f64).sqrt());
            }
        }
        let predictable = std::array::from_fn(|c| {
            let (memory, motion) = fitted[c];
            let g0 = gamma(0, c);
            if g0 <= 0.0 || motion <= 0.0 {
                return 0.0;
            }
            // The lasting noise's share of the residual that its past
            // predicts, times how much of that past the commands carry: one
            // command's answer carries r^2 of the residual, r^2 / share of
            // its motion noise, and the answers of the commands before add
            // what the memory keeps of theirs (a geometric sum).
            let lasting = memory * memory * motion / g0;
            let carried = (answered[c] * g0 / motion / (1.0 - memory * memory)).min(1.0);
            (lasting * carried).clamp(0.0, 1.0)
        });
        Self {
            predictable,
            answer_z,
        }
    }

    /// Whether the residuals predict the next command change: the
    /// controller steers on the pose.
    fn commands_answer(&self) -> bool {
        self.answer_z >= ANSWERS_Z
    }

    /// Whether the commands answer the pose and some of the noise they
    /// answer lasts past a command.
    fn answers_lasting_noise(&self) -> bool {
        self.commands_answer() && self.predictable.iter().any(|&p| p > 0.0)
    }

    /// Nats a segment that an answer to this noise could make `effect`
    /// gain: none unless the effect responds to command changes and the
    /// commands answer the pose.
    fn answer_per_segment(&self, effect: &ScopedEffect) -> f64 {
        if !acts_at_command_changes(effect) || !self.answers_lasting_noise() {
            return 0.0;
        }
        0.5 * self.predictable.iter().sum::<f64>()
    }
}

/// Whether `effect` acts where a command changes (a delay, a lag, a play,
/// an acceleration limit): what a controller's answer to noise that lasts
/// can stand in for, and what one command period, cut at the commands,
/// sees best.
fn acts_at_command_changes(effect: &ScopedEffect) -> bool {
    use shoal_physics::Effect;
    matches!(
        effect.effect,
        Effect::Latency { .. }
            | Effect::ActuatorLag { .. }
            | Effect::Hysteresis { .. }
            | Effect::AccelLimit { .. }
    )
}

/// What a controller's answer to the noise can make an effect of the fitted
/// size gain, where it could make any effect gain at most `allowance` nats
/// and the effect would gain `expected` were it real.
///
/// A segment's gain, in its standardised residual `r` and the effect's
/// standardised change of the prediction `d`, is `r d - d^2 / 2`. Of `r`,
/// an answer carries at most a share `p` of the variance, so it gains at
/// most `sqrt(p) |d| - d^2 / 2`: at most `p / 2` over every `d` (the
/// allowance, `sum p / 2`), but the effect's `d` is fixed where it is
/// scored (its parameters are fitted on the long segments outside the
/// block), and summed over segments and components, by Cauchy-Schwarz,
/// `sum sqrt(p) |d| <= sqrt(sum p * sum d^2) = 2 sqrt(allowance * expected)`.
/// So the bound is `2 sqrt(allowance * expected) - expected`: the allowance
/// where the effect is as large as the answer could be, less where it is
/// smaller or larger, none where it is four times as large (its
/// prediction then departs further than any answer reaches). A laps run
/// with a true 0.1 s delay gained +139 nats against an allowance of 43,
/// expecting +122: the bound for its size is 23.
fn answer_for_size(allowance: f64, expected: f64) -> f64 {
    if allowance <= 0.0 {
        return 0.0;
    }
    (2.0 * (allowance * expected.max(0.0)).sqrt() - expected).clamp(0.0, allowance)
}

/// `y` less its least-squares fit on an intercept and the two columns of
/// `levels` (each column taken only where it varies, the second only as far
/// as it differs from the first).
fn unpredicted(levels: &[[f64; 2]], mut y: Vec<f64>) -> Vec<f64> {
    let centred = |x: Vec<f64>| -> Vec<f64> {
        let mean = x.iter().sum::<f64>() / x.len().max(1) as f64;
        x.into_iter().map(|v| v - mean).collect()
    };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
    // Gram-Schmidt on the centred columns: each regressor made orthogonal
    // to the ones before, then taken out of `y`.
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for c in 0..2 {
        let mut x = centred(levels.iter().map(|l| l[c]).collect());
        for b in &basis {
            let k = dot(&x, b) / dot(b, b);
            x.iter_mut().zip(b).for_each(|(x, b)| *x -= k * b);
        }
        if dot(&x, &x) > 1e-12 * x.len() as f64 {
            basis.push(x);
        }
    }
    y = centred(y);
    for b in &basis {
        let k = dot(&y, b) / dot(b, b);
        y.iter_mut().zip(b).for_each(|(y, b)| *y -= k * b);
    }
    y
}

/// The memory and the motion variance whose residual autocovariances best
/// match `g0`, `g1` and `g2` (lags 0-2), for a residual made of motion
/// noise that carries over from one segment to the next (an AR(1) with
/// memory `a`, variance `m`) and the observation errors at its two ends
/// (variance `o` each, shared with its neighbours): g0 = m + 2o,
/// g1 = a m - o, g2 = a^2 m. White noise gives (0, g0).
fn fit_memory(g0: f64, g1: f64, g2: f64) -> (f64, f64) {
    if g0 <= 0.0 {
        return (0.0, 0.0);
    }
    let mut best = (f64::INFINITY, (0.0, g0));
    for step in 0..=100 {
        let a = (step as f64 / 100.0).min(MAX_MEMORY);
        // Given a, the observation variance that matches lag 1 best.
        let o = ((a * g0 - g1) / (2.0 * a + 1.0)).clamp(0.0, 0.5 * g0);
        let m = g0 - 2.0 * o;
        let miss = (g1 - (a * m - o)).powi(2) + (g2 - a * a * m).powi(2);
        if miss < best.0 {
            best = (miss, (a, m));
        }
    }
    best.1
}

/// The standard error of the sum of `gains`: their spread about their mean,
/// inflated by their correlation in time (a HAC variance); 0 when flat.
fn sd_of_sum(segments: &[Segment], gains: &[f64]) -> f64 {
    let n = gains.len();
    if n < 2 {
        return 0.0;
    }
    let mean = gains.iter().sum::<f64>() / n as f64;
    let variance = gains.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let factor = long_run_factor(segments, gains).factor;
    (n as f64 * variance * factor).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prepared::prepare;
    use crate::recording::{Commands, Poses};

    /// `n` commands `period` apart, each value given by `value(i)`.
    fn commands(period: f64, n: usize, value: impl Fn(usize) -> (f64, f64)) -> Recording {
        let mut commands = Commands::default();
        for i in 0..n {
            let (v, omega) = value(i);
            commands.t.push(i as f64 * period);
            commands.v.push(v);
            commands.omega.push(omega);
        }
        Recording::from_absolute(commands, Poses::default())
    }

    /// Commands that change with every message, as a controller's do.
    fn commands_every(period: f64, n: usize) -> Recording {
        commands(period, n, |i| (0.1 + 0.001 * i as f64, 0.0))
    }

    fn check(z: f64, size_in_noise: f64) -> FeedbackFree {
        FeedbackFree {
            horizon_s: 0.02,
            gain: z * 3.0,
            z,
            z_needed: MIN_Z,
            expected_gain: 3.5,
            z_against_expected: (z * 3.0 - 3.5) / 3.0,
            size_in_noise,
            lasting_answer: 0.0,
            answer_allowance: 0.0,
            commands_answer: true,
            acts_at_command_changes: false,
        }
    }

    /// 60 s straight at 0.2 m/s as commanded, the observed poses off by
    /// `jitter` (metres and radians, a fixed pattern), prepared.
    fn straight(jitter: f64) -> Prepared {
        let held = commands(0.1, 600, |_| (0.2, 0.0));
        let mut poses = Poses::default();
        for i in 0..=600 {
            let t = i as f64 * 0.1;
            let wobble = jitter * (1.7 * i as f64).sin();
            poses.t.push(t);
            poses.x.push(0.2 * t + wobble);
            poses.y.push(wobble);
            poses.theta.push(wobble);
        }
        prepare(
            &Recording::from_absolute(held.commands, poses),
            &Options::default(),
        )
    }

    /// Without noise to score with, a block's gains would be any residual
    /// over the variance floor: a mud robot's read 1.3e12 nats.
    #[test]
    fn a_block_whose_others_show_no_noise_is_not_scored() {
        let plain = UnicycleModel::default();
        let slower = UnicycleModel::with_effects(vec![ScopedEffect::always(
            shoal_physics::Effect::SpeedScale { factor: 0.9 },
        )]);
        let gains = |prepared: &Prepared, train: usize, with: &UnicycleModel, without| {
            let (others, block) = prepared.segments.split_at(prepared.segments.len() / 2);
            assert!(others.len() >= train && !block.is_empty());
            block_gains(prepared, &others[..train], block.to_vec(), with, without).gains
        };
        // The others' residuals are all zero: no noise, nothing scored.
        let exact = straight(0.0);
        assert!(gains(&exact, 20, &plain, &slower).is_empty());
        // Too few others: nothing scored either.
        let jittered = straight(0.005);
        assert!(gains(&jittered, MIN_NOISE_SEGMENTS - 1, &plain, &slower).is_empty());
        // Enough, with noise: every segment scored, the true model ahead.
        let scored = gains(&jittered, MIN_NOISE_SEGMENTS, &plain, &slower);
        assert!(!scored.is_empty() && scored.iter().all(|g| g.is_finite()));
        assert!(scored.iter().sum::<f64>() > 0.0, "{scored:?}");
    }

    /// The lasting motion noise is told from the seams' observation error by
    /// its autocovariances: white noise has no memory, and a memory of 0.8
    /// under observation error that makes neighbours anticorrelated is found.
    /// A change that reverts to the mean of the commands before it is
    /// predicted by them in full; what they do not predict is left whole.
    #[test]
    fn a_change_is_taken_less_what_the_commands_before_it_predict() {
        let levels: Vec<[f64; 2]> = (0..200)
            .map(|i| {
                [
                    0.2 + 0.1 * (i as f64 * 0.37).sin(),
                    0.3 * (i as f64 * 0.11).cos(),
                ]
            })
            .collect();
        let answer: Vec<f64> = (0..200)
            .map(|i| if i % 2 == 0 { 0.01 } else { -0.01 })
            .collect();
        let change: Vec<f64> = levels
            .iter()
            .zip(&answer)
            .map(|(l, a)| 0.5 * (0.2 - l[0]) - 0.2 * l[1] + a)
            .collect();
        let left = unpredicted(&levels, change);
        let r = correlation(&left, &answer).expect("varies");
        assert!(r > 0.99, "what the levels do not predict: r {r}");
        for c in 0..2 {
            let level: Vec<f64> = levels.iter().map(|l| l[c]).collect();
            let r = correlation(&left, &level).expect("varies");
            assert!(r.abs() < 1e-9, "column {c}: r {r}");
        }
    }

    #[test]
    fn the_noise_memory_is_read_from_three_autocovariances() {
        assert_eq!(fit_memory(1.0, 0.0, 0.0), (0.0, 1.0));
        // a 0.8, motion 0.3, observation 0.35 at each end.
        let (memory, motion) = fit_memory(0.3 + 0.7, 0.8 * 0.3 - 0.35, 0.64 * 0.3);
        assert!((memory - 0.8).abs() < 0.011, "{memory}");
        assert!((motion - 0.3).abs() < 0.02, "{motion}");
        // Observation error alone: the neighbours' -1/2, no memory.
        let (memory, motion) = fit_memory(1.0, -0.5, 0.0);
        assert!(memory < 0.011 && motion < 0.02, "{memory} {motion}");
    }

    /// The allowance is for effects that respond to command changes, where
    /// the commands answer the pose; never for a scale, never in open loop.
    #[test]
    fn an_answer_to_lasting_noise_is_allowed_for_only_where_commands_answer() {
        use shoal_physics::Effect;
        let lasting = LastingNoise {
            predictable: [0.01, 0.0, 0.03],
            answer_z: 19.0,
        };
        let play = ScopedEffect::always(Effect::Hysteresis {
            play_rad_per_s: 0.01,
        });
        let scale = ScopedEffect::always(Effect::TurnScale { factor: 0.9 });
        assert!((lasting.answer_per_segment(&play) - 0.02).abs() < 1e-12);
        assert_eq!(lasting.answer_per_segment(&scale), 0.0);
        let open_loop = LastingNoise {
            answer_z: 1.0,
            ..lasting
        };
        assert_eq!(open_loop.answer_per_segment(&play), 0.0);
    }

    #[test]
    fn an_effect_stays_if_confirmed_or_larger_than_any_answer_to_the_noise() {
        assert!(check(2.0, 0.1).confirmed());
        assert!(!check(0.3, 0.1).confirmed());
        assert!(check(0.3, 1.4).confirmed(), "larger than the noise");
        assert!(
            check(0.3, 0.1)
                .why_unconfirmed()
                .contains("too short to tell")
        );
        assert!(check(-1.0, 0.1).why_unconfirmed().contains("contradicts"));
    }

    /// A bench heading drift under coloured noise: the short horizon,
    /// with little power, neither confirms it nor speaks against it. A lag
    /// is still asked to show there.
    #[test]
    fn open_loop_an_effect_is_dropped_only_where_the_short_horizon_contradicts_it() {
        let open_loop = |z: f64| FeedbackFree {
            commands_answer: false,
            ..check(z, 0.1)
        };
        assert!(!check(0.3, 0.1).confirmed(), "closed loop: unconfirmed");
        assert!(open_loop(0.3).confirmed(), "open loop: not contradicted");
        assert!(!open_loop(0.3).confirmed_there());
        let lag = FeedbackFree {
            acts_at_command_changes: true,
            ..open_loop(0.3)
        };
        assert!(!lag.confirmed(), "seen best one period after a change");
        let against = open_loop(-1.0);
        assert!(against.contradicted() && !against.confirmed());
        assert!(against.why_unconfirmed().contains("contradicts"));
    }

    fn near(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-3
    }

    #[test]
    fn an_answer_to_the_noise_gains_most_for_an_effect_of_its_own_size() {
        assert!(near(answer_for_size(43.0, 43.0), 43.0));
        // The laps delay's figures: counted from 22.7 nats, not 43.
        assert!(near(answer_for_size(43.0, 122.3), 22.736));
        assert!(answer_for_size(43.0, 122.3) < 43.0 && answer_for_size(174.1, 40.1) < 174.1);
        assert!(
            answer_for_size(174.1, 40.1) > 40.1,
            "above a real effect's own gain"
        );
        assert_eq!(answer_for_size(43.0, 4.0 * 43.0), 0.0);
        assert_eq!(answer_for_size(0.0, 10.0), 0.0);
        assert_eq!(answer_for_size(10.0, 0.0), 0.0);
    }

    /// The figures of a laps run with a true 0.1 s delay (EXPERIMENTS.md 5c)
    /// and of a null laps run's play.
    #[test]
    fn an_effect_is_undecided_only_where_a_real_one_would_gain_past_the_answer_and_it_nearly_does()
    {
        let with = |gain: f64, sd: f64, expected: f64, answer: f64| FeedbackFree {
            gain,
            z: (gain - answer) / sd,
            expected_gain: expected,
            z_against_expected: (gain - expected) / sd,
            lasting_answer: answer,
            answer_allowance: answer,
            ..check(0.0, 0.1)
        };
        let delay = with(139.4, 59.0, 122.3, 43.0);
        assert!(!delay.confirmed() && delay.undecided());
        assert!(delay.why_unconfirmed().contains("not the power to decide"));
        // The whole gain is within what the controller's answer could make.
        assert!(!with(73.4, 9.4, 40.1, 174.1).undecided(), "null play");
        // Nearer the answer's bound than what a real effect would gain.
        assert!(!with(60.0, 59.0, 122.3, 43.0).undecided());
        // A gain far past the bound is confirmed, not undecided.
        assert!(!with(250.0, 59.0, 122.3, 43.0).undecided());
        // In open loop there is no answer to be undecided from.
        let open_loop = FeedbackFree {
            answer_allowance: 0.0,
            lasting_answer: 0.0,
            ..delay
        };
        assert!(!open_loop.undecided());
    }

    #[test]
    fn the_horizon_is_one_command_period_on_a_grid_that_divides_it() {
        let close = |cuts: Vec<FeedbackFreeCut>, want: (f64, f64)| {
            cuts.len() == 1
                && !cuts[0].within_holds
                && (cuts[0].horizon_s - want.0).abs() < 1e-12
                && (cuts[0].grid_dt - want.1).abs() < 1e-12
        };
        let at = |period| feedback_free_cuts(&commands_every(period, 100), 0.02, 1.0);
        assert!(close(at(0.05), (0.05, 0.05 / 3.0)), "{:?}", at(0.05));
        assert!(close(at(0.1), (0.1, 0.02)), "{:?}", at(0.1));
        assert!(close(at(0.04), (0.04, 0.02)), "{:?}", at(0.04));
        // Commands faster than the grid: one period, on a grid as fine.
        assert!(close(at(0.01), (0.01, 0.01)), "{:?}", at(0.01));
        // Faster still: the finest grid, a few commands a segment.
        assert!(close(at(0.001), (0.005, 0.005)), "{:?}", at(0.001));
    }

    #[test]
    fn commands_held_over_many_periods_are_also_scored_within_their_holds() {
        // 50 Hz, a new value every second: one period, and one second
        // within each hold.
        let held = commands(0.02, 1000, |i| (0.1 + 0.01 * (i / 50) as f64, 0.0));
        let cuts = feedback_free_cuts(&held, 0.02, 1.0);
        assert_eq!(cuts.len(), 2, "{cuts:?}");
        assert!(!cuts[0].within_holds && (cuts[0].horizon_s - 0.02).abs() < 1e-9);
        assert!(cuts[1].within_holds && (cuts[1].horizon_s - 1.0).abs() < 1e-9);
        // Never longer than the long horizon.
        assert!(feedback_free_cuts(&held, 0.02, 0.5)[1].horizon_s <= 0.5 + 1e-9);
        // A controller that answers every message and only holds its
        // pauses: the pauses show no motion to score, so one period.
        let paused = commands(0.02, 1000, |i| {
            if (i / 100) % 2 == 0 {
                (0.0, 0.0)
            } else {
                (0.1 + 0.001 * i as f64, 0.2)
            }
        });
        let cuts = feedback_free_cuts(&paused, 0.02, 1.0);
        assert_eq!(cuts.len(), 1, "{cuts:?}");
        // Two horizons pay for the choice: the best at 2.5%, or both at 5%.
        assert!(near(z_needed(&[0.3]), MIN_Z), "{}", z_needed(&[0.3]));
        assert!(near(z_needed(&[1.9, 0.5]), 1.960));
        assert!(near(z_needed(&[1.9, 1.7]), MIN_Z));
        assert!(near(z_needed(&[1.5, 2.5]), 1.960));
    }
}

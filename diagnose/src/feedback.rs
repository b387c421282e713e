//! The feedback stage: every effect named must also predict better where no
//! command could have answered the noise it is scored on.
//!
//! A segment's prediction replays the commands of its horizon. A controller
//! that steers on the body's pose (a navigation stack, a waypoint follower)
//! turns each bit of motion noise into later commands of the same segment,
//! so the commands correlate with the residual the model must explain, and
//! an effect that damps the model's response to command changes (a play, a
//! lag, a delay) explains part of the noise: the closed-loop identification
//! bias of the direct method. It is free of that bias only where each
//! segment's commands were chosen before its noise (Ljung, System
//! Identification, 13.4): a horizon shorter than the commands' period. At
//! such a horizon the pose noise hides a weak effect's fit, but not a held
//! effect's prediction: the effect keeps the parameters fitted at the long
//! horizon and is only scored at the short one, each held-out block with the
//! noise estimated on the others, as the held-out stage scores.

use std::collections::BTreeMap;

use serde::Serialize;
use shoal_physics::{ScopedEffect, UnicycleModel};

use crate::fit::fit;
use crate::heldout::on_folds;
use crate::likelihood::{estimate_noise, long_run_factor, residuals, segment_nll};
use crate::prepared::{Options, Prepared, prepare};
use crate::recording::Recording;
use crate::segments::Segment;

/// The one-sided z an effect's short-horizon held-out gain must reach: a
/// 5% test. An effect already passed its entry test on the long horizon; this
/// asks only that its gain there is not the controller's.
pub const MIN_Z: f64 = 1.645;

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
}

impl FeedbackFree {
    pub fn confirmed(&self) -> bool {
        self.z >= MIN_Z
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
}

/// Each effect of `found` that moves the prediction, checked at the
/// feedback-free horizon beside the others; noise effects get `None`.
pub(crate) fn check_each(
    recording: &Recording,
    options: &Options,
    fixed: &[ScopedEffect],
    found: &[ScopedEffect],
) -> Vec<Option<FeedbackFree>> {
    if found.iter().all(|e| e.effect.only_noise()) {
        return vec![None; found.len()];
    }
    let horizon_s = feedback_free_horizon(recording, options.grid_dt);
    let short = prepare(
        recording,
        &Options {
            horizon_s,
            ..options.clone()
        },
    );
    (0..found.len())
        .map(|k| {
            let check = (!found[k].effect.only_noise())
                .then(|| feedback_free_gain(&short, horizon_s, fixed, found, k));
            tracing::debug!(effect = ?found[k].effect, ?check, "feedback-free check");
            check
        })
        .collect()
}

/// `found` without the effects `checks` does not confirm, refitted together
/// if any was dropped, each kept one's index into `found`, and the dropped.
pub(crate) fn without_unconfirmed(
    prepared: &Prepared,
    fixed: &[ScopedEffect],
    found: &[ScopedEffect],
    checks: &[Option<FeedbackFree>],
    options: &Options,
) -> (Vec<ScopedEffect>, Vec<usize>, Vec<usize>) {
    let (kept, dropped): (Vec<usize>, Vec<usize>) =
        (0..found.len()).partition(|&k| checks[k].is_none_or(|c| c.confirmed()));
    let kept_effects: Vec<ScopedEffect> = kept.iter().map(|&k| found[k].clone()).collect();
    if dropped.is_empty() || kept_effects.is_empty() {
        return (kept_effects, kept, dropped);
    }
    let refitted = fit(
        &prepared.grid,
        &prepared.segments,
        fixed,
        &kept_effects,
        options.max_iters,
    );
    (refitted.effects, kept, dropped)
}

/// The longest horizon, in whole grid steps, of at most half the commands'
/// usual period (their median interval), so that at least half the segments
/// see no new command and none sees more than one; one grid step when
/// commands come faster than that. A command that does arrive within a
/// segment answers only the noise of the part before it, which shrinks with
/// the horizon.
pub fn feedback_free_horizon(recording: &Recording, grid_dt: f64) -> f64 {
    let t = &recording.commands.t;
    let mut gaps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).filter(|g| *g > 0.0).collect();
    if gaps.is_empty() {
        return grid_dt;
    }
    gaps.sort_by(f64::total_cmp);
    let period = gaps[gaps.len() / 2];
    let steps = (0.5 * period / grid_dt + 1e-9).floor().max(1.0);
    steps * grid_dt
}

/// The run prepared at the feedback-free horizon, with the same held-out
/// blocks' count as `options` asks.
pub fn prepare_feedback_free(recording: &Recording, options: &Options) -> Prepared {
    let short = Options {
        horizon_s: feedback_free_horizon(recording, options.grid_dt),
        ..options.clone()
    };
    prepare(recording, &short)
}

/// How `found[k]` predicts the short-horizon run `short`, against the model
/// of `fixed` and the other effects of `found`.
pub fn feedback_free_gain(
    short: &Prepared,
    horizon_s: f64,
    fixed: &[ScopedEffect],
    found: &[ScopedEffect],
    k: usize,
) -> FeedbackFree {
    let with: Vec<ScopedEffect> = fixed.iter().chain(found).cloned().collect();
    let without: Vec<ScopedEffect> = fixed
        .iter()
        .chain(found.iter().enumerate().filter(|(i, _)| *i != k).map(|(_, e)| e))
        .cloned()
        .collect();
    let per_block: Vec<Vec<f64>> = on_folds(short, |train, test| {
        let nll_without = heldout_segment_nll(short, train, test, without.clone());
        let nll_with = heldout_segment_nll(short, train, test, with.clone());
        nll_without.iter().zip(&nll_with).map(|(a, b)| a - b).collect()
    });
    let gains: Vec<f64> = per_block.into_iter().flatten().collect();
    FeedbackFree {
        horizon_s,
        gain: gains.iter().sum(),
        z: z_of_sum(&short.segments, &gains),
    }
}

/// Each test segment's negative log-likelihood under `effects`, with the
/// noise estimated on `train`.
fn heldout_segment_nll(
    prepared: &Prepared,
    train: &[Segment],
    test: &[Segment],
    effects: Vec<ScopedEffect>,
) -> Vec<f64> {
    let model = UnicycleModel::with_effects(effects);
    let noise = estimate_noise(&model, train, &residuals(&model, &prepared.grid, train));
    segment_nll(&model, &noise, test, &residuals(&model, &prepared.grid, test))
}

/// The sum of `gains` over its standard error: their spread about their mean,
/// inflated by their correlation in time (a HAC variance).
fn z_of_sum(segments: &[Segment], gains: &[f64]) -> f64 {
    let n = gains.len();
    if n < 2 {
        return 0.0;
    }
    let sum: f64 = gains.iter().sum();
    let mean = sum / n as f64;
    let variance = gains.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    if variance <= 0.0 {
        return 0.0;
    }
    let factor = long_run_factor(segments, gains).factor;
    sum / (n as f64 * variance * factor).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::{Commands, Poses};

    fn commands_every(period: f64, n: usize) -> Recording {
        let mut commands = Commands::default();
        for i in 0..n {
            commands.t.push(i as f64 * period);
            commands.v.push(0.1);
            commands.omega.push(0.0);
        }
        Recording::from_absolute(commands, Poses::default())
    }

    #[test]
    fn the_horizon_is_at_most_half_the_commands_period_in_whole_grid_steps() {
        assert!((feedback_free_horizon(&commands_every(0.05, 100), 0.02) - 0.02).abs() < 1e-12);
        assert!((feedback_free_horizon(&commands_every(0.1, 100), 0.02) - 0.04).abs() < 1e-12);
        assert!((feedback_free_horizon(&commands_every(0.2, 100), 0.02) - 0.1).abs() < 1e-12);
        // Commands faster than two grid steps: one step.
        assert!((feedback_free_horizon(&commands_every(0.01, 100), 0.02) - 0.02).abs() < 1e-12);
    }
}

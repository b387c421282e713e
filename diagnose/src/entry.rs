//! The entry test: whether an effect's gain is more than effects fitted to
//! noise reach, corrected for the noise's correlation in time and for noise
//! the model gets wrong, over all the library's kinds.

use serde::Serialize;
use shoal_physics::effects::EFFECT_KINDS;
use shoal_physics::{CommandGrid, Effect, ScopedEffect, UnicycleModel};
use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor};

use crate::candidates::extra_params;
use crate::likelihood::{
    LongRun, component_nll, estimate_noise, long_run_factor, long_run_of_components, residuals,
    segment_nll, standardised,
};
use crate::prepared::{Options, prepare};
use crate::recording::Recording;
use crate::segments::Segment;

/// The figures of the test an effect passed to be named (see [`entry_test`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct EntryTest {
    /// The likelihood-ratio statistic corrected for correlation in time:
    /// the smaller of the two corrections.
    pub chi2: f64,
    /// Its degrees of freedom: the effect's parameters, plus two where it
    /// acts in part of the run or the map.
    pub dof: usize,
    /// What `chi2` had to exceed at `level`.
    pub needed: f64,
    /// The family-wise level (`--select-alpha`).
    pub level: f64,
    /// The p-value, Bonferroni-adjusted over the library's kinds.
    pub p_adjusted: f64,
    /// Whether the effect also lowers the calibrated BIC (reported as the
    /// finding's `delta_bic`).
    #[serde(skip)]
    pub(crate) lowers_bic: bool,
}

impl EntryTest {
    /// An effect enters when it passes the test and lowers BIC.
    pub fn passed(&self) -> bool {
        self.chi2 > self.needed && self.lowers_bic
    }
}

/// The entry test each of `truth`'s effects would face at its true
/// parameters, with the others in the model: how strongly the run shows
/// it, which bounds what any diagnosis of this run could name. For the
/// lab, where the truth is known: an effect a run cannot show is a limit
/// of the run, not a miss of the method.
pub fn strength_of_truth(
    recording: &Recording,
    model: &UnicycleModel,
    truth: &[ScopedEffect],
    options: &Options,
) -> Vec<EntryTest> {
    let prepared = prepare(recording, options);
    let (grid, segs) = (&prepared.grid, &prepared.segments);
    (0..truth.len())
        .map(|k| {
            let base: Vec<ScopedEffect> = model
                .effects
                .iter()
                .cloned()
                .chain(crate::fit::all_but(truth, k))
                .collect();
            let candidate = &truth[k];
            let long_runs = factors_with(grid, segs, &base, candidate);
            let factors = long_runs.map(|l| l.factor);
            let base_nll = components_of(grid, segs, &base);
            let delta_bic = calibrated_gain(grid, segs, base_nll, &base, candidate, factors);
            entry_test(
                grid,
                segs,
                &base,
                candidate,
                (delta_bic, long_runs),
                options,
            )
        })
        .collect()
}

/// How much correlation in time inflates each residual component of the
/// model `base` plus `candidate` (see [`long_run_of_components`]), with the
/// estimates' degrees of freedom.
pub(crate) fn factors_with(
    grid: &CommandGrid,
    segs: &[Segment],
    base: &[ScopedEffect],
    candidate: &ScopedEffect,
) -> [LongRun; 3] {
    factors_of(
        grid,
        segs,
        &base
            .iter()
            .cloned()
            .chain([candidate.clone()])
            .collect::<Vec<_>>(),
    )
}

/// The residual components' long-run variance under `effects`.
pub(crate) fn factors_of(
    grid: &CommandGrid,
    segs: &[Segment],
    effects: &[ScopedEffect],
) -> [LongRun; 3] {
    let model = UnicycleModel::with_effects(effects.to_vec());
    let r = residuals(&model, grid, segs);
    let noise = estimate_noise(&model, segs, &r);
    long_run_of_components(segs, &standardised(&model, &noise, segs, &r))
}

/// BIC gain of adding `candidate` (already fitted) to `base`, with the
/// likelihood gain of each component divided by how much that component's
/// correlation in time inflates it (`factors`, see [`long_run_of_components`]),
/// and the penalty counted on the effective number of observations.
/// Negative is better. One round judges all its candidates with the same
/// factors, estimated from the residuals of its best-fitting candidate: an
/// effect that is there does not count as correlated noise against itself,
/// and rival explanations of one mismatch are weighed on one scale.
pub(crate) fn calibrated_gain(
    grid: &CommandGrid,
    segs: &[Segment],
    base_nll: [f64; 3],
    base: &[ScopedEffect],
    candidate: &ScopedEffect,
    factors: [f64; 3],
) -> f64 {
    let with: Vec<ScopedEffect> = base.iter().cloned().chain([candidate.clone()]).collect();
    calibrated_gain_of_move(grid, segs, base_nll, &with, candidate, factors)
}

/// [`calibrated_gain`] of a move from the model whose components' NLL is
/// `without_nll` to the model `with`, which adds `candidate` and may have
/// refitted the rest.
pub(crate) fn calibrated_gain_of_move(
    grid: &CommandGrid,
    segs: &[Segment],
    without_nll: [f64; 3],
    with: &[ScopedEffect],
    candidate: &ScopedEffect,
    factors: [f64; 3],
) -> f64 {
    let nll = components_of(grid, segs, with);
    let gain: f64 = (0..3).map(|c| (nll[c] - without_nll[c]) / factors[c]).sum();
    2.0 * gain + extra_params(candidate) as f64 * log_n_eff(segs, factors)
}

/// The log of the effective number of observations BIC's penalty counts:
/// three components per segment, shrunk by their correlation in time.
pub(crate) fn log_n_eff(segs: &[Segment], factors: [f64; 3]) -> f64 {
    let n_eff = 3.0 * segs.len() as f64 / (factors.iter().sum::<f64>() / 3.0);
    n_eff.max(2.0).ln()
}

/// The entry test of `candidate`, judged `delta_bic` (see
/// [`calibrated_gain`]) with the residual components' `long_runs`: its
/// calibrated likelihood-ratio statistic must exceed what `dof`
/// parameters fitted to noise reach with probability `select_alpha` over
/// all the library's kinds. The test's level, unlike BIC's penalty, does
/// not tighten as the recording grows: a longer recording can name a
/// smaller effect, while null runs stay at the same rate (shown in
/// EXPERIMENTS.md 5b).
pub(crate) fn entry_test(
    grid: &CommandGrid,
    segs: &[Segment],
    base: &[ScopedEffect],
    candidate: &ScopedEffect,
    judged: (f64, [LongRun; 3]),
    options: &Options,
) -> EntryTest {
    let with: Vec<ScopedEffect> = base.iter().cloned().chain([candidate.clone()]).collect();
    entry_test_of_move(grid, segs, (base, &with), candidate, judged, options)
}

/// [`entry_test`] of a move from `without` to `with`, which adds
/// `candidate` and may have refitted the rest beside it.
pub(crate) fn entry_test_of_move(
    grid: &CommandGrid,
    segs: &[Segment],
    (without, with): (&[ScopedEffect], &[ScopedEffect]),
    candidate: &ScopedEffect,
    (delta_bic, long_runs): (f64, [LongRun; 3]),
    options: &Options,
) -> EntryTest {
    let factors = long_runs.map(|l| l.factor);
    let dof = extra_params(candidate);
    // The statistic with each residual component's factor, as the round
    // judged it, and with the factor of the effect's own gain: the smaller
    // counts, as either kernel estimate can fall short of a persistent
    // noise's long-run variance.
    let by_components = dof as f64 * log_n_eff(segs, factors) - delta_bic;
    let robust = robust_chi2(grid, segs, (without, with), candidate);
    // Each statistic is held to the fixed-b threshold of its estimate (see
    // [`LongRun::dof`]; for the components', the roughest of the three):
    // stated on the χ² scale, it is shrunk by how much that threshold
    // exceeds χ²'s.
    let needed = entry_threshold(dof, options.select_alpha);
    let on_chi2_scale = |statistic: f64, estimate_dof: f64| {
        statistic * needed / fixed_b_threshold(dof, options.select_alpha, estimate_dof)
    };
    let roughest = long_runs
        .iter()
        .map(|l| l.dof)
        .fold(f64::INFINITY, f64::min);
    let chi2 = robust
        .iter()
        .map(|(statistic, long_run)| on_chi2_scale(*statistic, long_run.dof))
        .fold(on_chi2_scale(by_components, roughest), f64::min);
    let p = ChiSquared::new(dof.max(1) as f64).map_or(1.0, |d| d.sf(chi2.max(0.0)));
    EntryTest {
        chi2,
        dof,
        needed,
        level: options.select_alpha,
        p_adjusted: (p * EFFECT_KINDS.len() as f64).min(1.0),
        lowers_bic: delta_bic < 0.0,
    }
}

/// Two statistics of the move from `without` to `with` (which adds
/// `candidate`), each with how its variance was estimated; the entry test
/// takes the smaller. The first is robust to correlation in time: twice
/// the log-likelihood gain divided by the long-run variance factor of the
/// gain's own per-segment series. To first order that series is the
/// candidate's score along the fitted change, so this is the HAC
/// correction of the test for this effect: an effect whose signal changes
/// sign with the turn rate is not charged for the slow drift of the noise,
/// and one that follows the speed is charged for exactly the drift it can
/// absorb. The second is robust to noise the model gets wrong (see
/// [`sandwich_wald`]).
pub(crate) fn robust_chi2(
    grid: &CommandGrid,
    segs: &[Segment],
    (without, with): (&[ScopedEffect], &[ScopedEffect]),
    candidate: &ScopedEffect,
) -> [(f64, LongRun); 2] {
    let per_segment = |effects: Vec<ScopedEffect>| {
        let model = UnicycleModel::with_effects(effects);
        let r = residuals(&model, grid, segs);
        let noise = estimate_noise(&model, segs, &r);
        segment_nll(&model, &noise, segs, &r)
    };
    let gains: Vec<f64> = per_segment(without.to_vec())
        .iter()
        .zip(per_segment(with.to_vec()))
        .map(|(a, b)| a - b)
        .collect();
    let long_run = long_run_factor(segs, &gains);
    let likelihood_ratio = 2.0 * gains.iter().sum::<f64>();
    [
        (likelihood_ratio / long_run.factor, long_run),
        sandwich_wald(grid, segs, with, candidate),
    ]
}

/// The step, as a share of the candidate's fitted change from the plain
/// model, over which [`misspecification`] takes its derivatives.
const SANDWICH_STEP: f64 = 0.1;

/// The parameters of `effect` as fitted and as the effect that changes
/// nothing (`None` for a kind without one): the change the Wald statistic
/// is taken along.
fn change_of(effect: &Effect) -> Option<(Vec<f64>, Vec<f64>)> {
    let region = match effect {
        Effect::SurfaceZone { region, .. } => *region,
        _ => [0.0; 4],
    };
    let identity = Effect::identity(effect.kind(), region)?;
    let values = |e: &Effect| e.params().iter().map(|(_, v)| *v).collect();
    Some((values(effect), values(&identity)))
}

/// The robust Wald statistic of the candidate along its fitted change, and
/// how the score's long-run variance was estimated: the squared distance
/// from the plain model to the fit over its sandwich variance J / I^2, with
/// I the likelihood's curvature and J the score's long-run variance (HAC,
/// so correlation in time counts too), both at the fit (Huber 1967, White
/// 1982). Where the model's noise is right
/// and white, the scores' spread equals the likelihood's curvature; noise
/// that the model gets wrong (growing with the square of the speed, larger
/// in some stretches) makes a few segments carry the evidence, and the
/// statistic shrinks by as much. Taken at the fit, not at the plain model,
/// whose unexplained mismatch would count as noise (mud that slows a robot
/// would count against the mud); from the score, whose mean there is zero,
/// not from the likelihood gains, whose long-run variance a patch the
/// robot stays in for a while inflates by itself; and as a Wald statistic,
/// not a likelihood ratio divided by J / I, which for a large effect stops
/// growing once the noise estimate of the model without it absorbs it.
pub(crate) fn sandwich_wald(
    grid: &CommandGrid,
    segs: &[Segment],
    with: &[ScopedEffect],
    candidate: &ScopedEffect,
) -> (f64, LongRun) {
    // Without a direction to test along, the statistic says nothing.
    let plain = LongRun {
        factor: 1.0,
        dof: segs.len() as f64,
    };
    let Some(at) = with.iter().position(|e| e == candidate) else {
        return (f64::INFINITY, plain);
    };
    let Some((fitted, identity)) = change_of(&candidate.effect) else {
        return (f64::INFINITY, plain);
    };
    if fitted
        .iter()
        .zip(&identity)
        .all(|(a, b)| (a - b).abs() < 1e-12)
    {
        return (0.0, plain);
    }
    let ranges = candidate.effect.ranges();
    let model = UnicycleModel::with_effects(with.to_vec());
    let noise = estimate_noise(&model, segs, &residuals(&model, grid, segs));
    // Per-segment NLL with the candidate moved `share` of its change along
    // its direction, the noise held at the fit's.
    let moved = |share: f64| {
        // Held within the physical ranges: a step past an edge is no model.
        let values: Vec<f64> = fitted
            .iter()
            .zip(&identity)
            .zip(&ranges)
            .map(|((f, p), (lo, hi))| (f + share * (f - p)).clamp(*lo, *hi))
            .collect();
        let mut effects = with.to_vec();
        effects[at] = ScopedEffect {
            effect: candidate.effect.with_params(&values),
            during: candidate.during,
        };
        let model = UnicycleModel::with_effects(effects);
        segment_nll(&model, &noise, segs, &residuals(&model, grid, segs))
    };
    let (ahead, here, behind) = (moved(SANDWICH_STEP), moved(0.0), moved(-SANDWICH_STEP));
    let scores: Vec<f64> = ahead
        .iter()
        .zip(&behind)
        .map(|(a, b)| (a - b) / (2.0 * SANDWICH_STEP))
        .collect();
    let curvature: f64 = ahead
        .iter()
        .zip(&here)
        .zip(&behind)
        .map(|((a, h), b)| (a + b - 2.0 * h) / (SANDWICH_STEP * SANDWICH_STEP))
        .sum();
    // Correlation in time is the other statistic's to correct (the gains'
    // long-run factor); counted here too, a robot that stays in a patch
    // for a while would pay for it twice.
    let long_run = plain;
    let spread: f64 = scores.iter().map(|s| s * s).sum::<f64>();
    if curvature.is_nan() || curvature <= 0.0 {
        return (0.0, long_run);
    }
    // The Wald statistic of the step from the plain model (share 0) to the
    // fit (share 1), with the sandwich variance J / I^2 of the share; never
    // more than the curvature alone, so noise the model overstates does not
    // count for the effect.
    (curvature / (spread / curvature).max(1.0), long_run)
}

/// [`entry_threshold`] for a statistic whose long-run variance was
/// estimated with `estimate_dof` degrees of freedom: dof x F(dof,
/// m - dof + 1) x m / (m - dof + 1) at the same level (Sun 2014). It
/// approaches the χ² threshold as the estimate's degrees of freedom grow.
pub(crate) fn fixed_b_threshold(dof: usize, alpha: f64, estimate_dof: f64) -> f64 {
    let k = dof.max(1) as f64;
    let m = estimate_dof.max(k + 1.0);
    FisherSnedecor::new(k, m - k + 1.0)
        .map(|f| k * f.inverse_cdf(1.0 - per_kind(alpha)) * m / (m - k + 1.0))
        .unwrap_or(f64::INFINITY)
}

/// Each kind's share of the family-wise level `alpha` (Bonferroni).
pub(crate) fn per_kind(alpha: f64) -> f64 {
    alpha / EFFECT_KINDS.len() as f64
}

/// The χ² an entering effect with `dof` parameters must exceed:
/// Bonferroni over the library's kinds at family-wise level `alpha`.
pub(crate) fn entry_threshold(dof: usize, alpha: f64) -> f64 {
    ChiSquared::new(dof.max(1) as f64)
        .map(|d| d.inverse_cdf(1.0 - per_kind(alpha)))
        .unwrap_or(f64::INFINITY)
}

pub(crate) fn components_of(
    grid: &CommandGrid,
    segs: &[Segment],
    effects: &[ScopedEffect],
) -> [f64; 3] {
    let model = UnicycleModel::with_effects(effects.to_vec());
    component_nll(&model, segs, &residuals(&model, grid, segs))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_entry_test_is_bonferroni_over_the_library_at_its_level() {
        // One parameter at 1% over the library's kinds: the two-sided
        // normal quantile squared, z(1 - 0.01 / (2 K))^2.
        let per_kind = 0.01 / EFFECT_KINDS.len() as f64;
        let z = statrs::distribution::Normal::standard().inverse_cdf(1.0 - per_kind / 2.0);
        assert!((entry_threshold(1, 0.01) - z * z).abs() < 1e-6);
        // More parameters and a stricter level ask for more.
        assert!(entry_threshold(2, 0.01) > entry_threshold(1, 0.01));
        assert!(entry_threshold(1, 0.001) > entry_threshold(1, 0.01));
    }

    #[test]
    fn the_fixed_b_threshold_is_chi2_for_a_precise_estimate_and_higher_for_a_rough_one() {
        let chi2 = entry_threshold(1, 0.01);
        assert!((fixed_b_threshold(1, 0.01, 1e7) - chi2).abs() < 0.01);
        // A 5 s noise on a 10-minute run: bandwidth about 28 of 600.
        let rough = fixed_b_threshold(1, 0.01, 600.0 / (29.0 * 2.0 / 3.0));
        assert!(rough > chi2 + 2.0, "{rough} against {chi2}");
        assert!(fixed_b_threshold(2, 0.01, 31.0) > fixed_b_threshold(1, 0.01, 31.0));
    }
}

//! The whole diagnosis: locate the mismatch, name it by forward selection
//! of effects (each must pass a calibrated test, lower BIC and predict
//! held-out, time-blocked folds better), and measure the fit before and after.

use std::collections::BTreeMap;

use serde::Serialize;
use shoal_physics::effects::EFFECT_KINDS;
use shoal_physics::{CommandGrid, Effect, ScopedEffect, UnicycleModel};
use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor};

use crate::covariates::{self, Covariate};
use crate::fit::{Fitted, fit, nll_of};
use crate::likelihood::{
    LongRun, component_nll, estimate_noise, long_run_factor, long_run_factors_of_noise,
    long_run_of_components, residuals, segment_nll, standardised,
};
use crate::heldout::{
    BlockReport, CONTRADICTION_NATS, block_reports, heldout, heldout_gain, must_transfer,
    transferable,
};
use crate::locate::{Located, locate};
use crate::recording::Recording;
use crate::segments::{Segment, command_grid, segments};

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

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Where {
    pub t_start: f64,
    pub t_end: f64,
    pub region: Option<[f64; 4]>,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FoundEffect {
    pub kind: &'static str,
    pub params: BTreeMap<&'static str, f64>,
    pub stderr: BTreeMap<&'static str, Option<f64>>,
    #[serde(rename = "where")]
    pub place: Where,
    pub delta_bic: f64,
    /// The test that let it in.
    pub test: EntryTest,
    pub sentence: String,
    /// Other kinds that explain the run as well (within 2 of BIC): this
    /// data cannot tell them apart, so they are one finding. The kinds of
    /// `alternatives`, kept for readers of the earlier JSON.
    pub indistinguishable_from: Vec<&'static str>,
    /// The same, with each alternative's fitted parameters and sentence.
    pub alternatives: Vec<Alternative>,
    /// Held-out (time-blocked) gain in log-likelihood from adding it.
    pub heldout_gain: f64,
    #[serde(skip)]
    pub scoped: ScopedEffect,
}

/// Another effect that explains the same mismatch about as well.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alternative {
    pub kind: &'static str,
    pub params: BTreeMap<&'static str, f64>,
    pub delta_bic: f64,
    pub sentence: String,
}

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
    lowers_bic: bool,
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
                .chain(truth.iter().enumerate().filter(|(i, _)| *i != k).map(|(_, e)| e))
                .cloned()
                .collect();
            let candidate = &truth[k];
            let long_runs = factors_with(grid, segs, &base, candidate);
            let factors = long_runs.map(|l| l.factor);
            let base_nll = components_of(grid, segs, &base);
            let delta_bic = calibrated_gain(grid, segs, base_nll, &base, candidate, factors);
            entry_test(grid, segs, &base, candidate, (delta_bic, long_runs), options)
        })
        .collect()
}

/// A mismatch the library could only fit with a parameter on the edge of
/// what is physical: not reported as physics.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Unexplained {
    /// The effect that was tried, and where its fit ended.
    pub tried: &'static str,
    pub params: BTreeMap<&'static str, f64>,
    pub reason: String,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Heldout {
    pub heldout_rmse_pos_m: f64,
    pub heldout_rmse_theta_rad: f64,
    /// Mean negative log-likelihood per held-out segment.
    pub heldout_nll: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct Diagnosis {
    pub mismatch: bool,
    pub located: Vec<Located>,
    pub effects: Vec<FoundEffect>,
    /// Mismatches no effect of the library explains physically.
    pub unexplained: Vec<Unexplained>,
    /// What the residuals of the model with the effects found still
    /// follow, strongest evidence first: a clue where no effect explains
    /// the mismatch, and a check where one does.
    pub residual_covariates: Vec<Covariate>,
    /// How much the plain model's residuals' correlation in time inflates
    /// the variance of sums (along, across, heading): 1 for white noise.
    pub noise_correlation: [f64; 3],
    /// Where the robot usually drives; sentences state effects there.
    pub operating_point: OperatingPoint,
    /// Observed poses set aside as gross outliers (see `Poses::without_outliers`).
    pub pose_outliers: usize,
    /// What was set aside as no body's motion before anything was fitted:
    /// jumps and returns, jumps without a return, pose gaps, command stalls.
    pub glitches: Vec<crate::glitches::Glitch>,
    /// Candidates that passed BIC but did not improve held-out prediction,
    /// or that a held-out block contradicted.
    pub rejected_heldout: Vec<&'static str>,
    /// Effects selected on the whole run that made the final model predict
    /// a held-out block worse than the model diagnosed: physics of one
    /// stretch that does not transfer to another, dropped.
    pub not_transferring: Vec<NotTransferring>,
    /// Each held-out block (a recording, or a stretch of one) and how well
    /// the model diagnosed and the fitted one predicted it.
    pub blocks: Vec<BlockReport>,
    pub baseline: Heldout,
    pub improved: Heldout,
    pub segments: usize,
    pub horizon_s: f64,
    /// Seconds subtracted from the input's times; reported times count from it.
    pub t_origin: f64,
    /// The input model plus what was found, ready to write as model.toml.
    #[serde(skip)]
    pub model: UnicycleModel,
    /// Per held-out segment: start time, plain and improved position error.
    #[serde(skip)]
    pub heldout_errors: Vec<(f64, f64, f64)>,
}

/// The prepared run: grid and segments.
pub struct Prepared {
    pub grid: CommandGrid,
    pub segments: Vec<Segment>,
    /// Observed poses set aside as gross outliers before segmenting.
    pub pose_outliers: usize,
    /// Stretches set aside as no body's motion (`glitches::set_aside`).
    pub glitches: Vec<crate::glitches::Glitch>,
    /// The held-out blocks, as ranges of `segments`: one per recording
    /// joined, or `Options::folds` equal stretches of time.
    pub blocks: Vec<std::ops::Range<usize>>,
}

/// The run as diagnosis compares it: what no body's motion explains set
/// aside (`glitches::set_aside`), then gross pose outliers (see
/// `Poses::without_outliers`), commands on a grid, segments started at the
/// observed poses.
pub fn prepare(recording: &Recording, options: &Options) -> Prepared {
    let (recording, glitches) = crate::glitches::set_aside(recording);
    let (recording, pose_outliers) = recording.without_pose_outliers();
    let grid = command_grid(&recording, options.grid_dt);
    let segments = segments(&recording, &grid, options.horizon_s);
    let blocks = crate::heldout::blocks(&segments, &recording.joins, options.folds);
    Prepared {
        grid,
        segments,
        pose_outliers,
        glitches,
        blocks,
    }
}

/// Extra BIC parameters for where an effect acts: a located span or
/// region was picked among a few, not fitted freely.
const WHERE_PARAMS: usize = 2;

/// How many of the residuals' strongest covariates a diagnosis lists.
const COVARIATES_REPORTED: usize = 5;

fn candidates(located: &[Located], segments: &[Segment], duration: f64) -> Vec<ScopedEffect> {
    // Speed noise is stated at the robot's usual speed.
    let usual_speed = OperatingPoint::of(segments).speed_m_per_s;
    let mut out: Vec<ScopedEffect> = EFFECT_KINDS
        .iter()
        .filter(|k| **k != "surface_zone")
        .filter_map(|k| Effect::identity(k, [0.0; 4]))
        .map(|e| ScopedEffect::always(e.at_reference_speed(usual_speed)))
        .collect();
    let spans = located
        .iter()
        .filter(|l| l.family == "time" && l.t_end - l.t_start < 0.8 * duration)
        .take(2);
    for span in spans {
        // A mismatch in one stretch of time may be a place the robot was
        // in then: where it drove during the span is a zone to try, its
        // edges fitted later.
        if let Some(region) = region_driven(segments, [span.t_start, span.t_end])
            && let Some(effect) = Effect::identity("surface_zone", region)
        {
            out.push(ScopedEffect::always(effect));
        }
        for kind in [
            "speed_scale",
            "turn_scale",
            "turn_bias",
            "heading_drift",
            "latency",
            "external_flow",
        ] {
            if let Some(effect) = Effect::identity(kind, [0.0; 4]) {
                out.push(ScopedEffect {
                    effect,
                    during: Some([span.t_start, span.t_end]),
                });
            }
        }
    }
    for place in located.iter().filter(|l| l.family == "place").take(3) {
        if let Some(region) = place.region
            && let Some(effect) = Effect::identity("surface_zone", at_least_min_side(region))
        {
            out.push(ScopedEffect::always(effect));
        }
    }
    out
}

fn extra_params(candidate: &ScopedEffect) -> usize {
    let located =
        candidate.during.is_some() || matches!(candidate.effect, Effect::SurfaceZone { .. });
    candidate.effect.params().len() + if located { WHERE_PARAMS } else { 0 }
}

/// Fits every candidate on two threads; returns them in the same order.
fn fit_all(
    grid: &CommandGrid,
    segments: &[Segment],
    fixed: &[ScopedEffect],
    candidates: &[ScopedEffect],
    max_iters: u64,
) -> Vec<Fitted> {
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(candidates.len().max(1));
    let mut results: Vec<Option<Fitted>> = vec![None; candidates.len()];
    std::thread::scope(|scope| {
        let chunks: Vec<_> = results
            .chunks_mut(candidates.len().div_ceil(workers).max(1))
            .enumerate()
            .map(|(w, slots)| {
                let chunk = candidates.len().div_ceil(workers).max(1);
                scope.spawn(move || {
                    for (k, slot) in slots.iter_mut().enumerate() {
                        let candidate = &candidates[w * chunk + k];
                        *slot = Some(fit(
                            grid,
                            segments,
                            fixed,
                            std::slice::from_ref(candidate),
                            max_iters,
                        ));
                    }
                })
            })
            .collect();
        for handle in chunks {
            joined(handle.join());
        }
    });
    // Every worker filled its slots, or its panic went on above.
    results.into_iter().flatten().collect()
}

/// A worker's result, or its panic carried on in this thread: a fit that
/// panicked is a bug to see, and dropping its result would pair the other
/// fits with the wrong candidates or folds.
pub(crate) fn joined<T>(result: std::thread::Result<T>) -> T {
    result.unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

/// An effect dropped because it does not transfer between blocks.
#[derive(Clone, Debug, Serialize)]
pub struct NotTransferring {
    pub kind: &'static str,
    pub params: BTreeMap<&'static str, f64>,
    pub sentence: String,
    /// The held-out block it predicted worse than the model diagnosed.
    pub block_t_start: f64,
    pub block_t_end: f64,
}

/// The found effects that transfer between the held-out blocks (see
/// `heldout::transferable`), refitted together if any was dropped; their
/// evidence; and the dropped ones.
fn transferring(
    prepared: &Prepared,
    fixed: &[ScopedEffect],
    found: Vec<ScopedEffect>,
    evidence: Vec<Evidence>,
    duration: f64,
    options: &Options,
) -> (Vec<ScopedEffect>, Vec<Evidence>, Vec<NotTransferring>) {
    if found.is_empty() {
        return (found, evidence, Vec::new());
    }
    let (kept, dropped) = transferable(prepared, fixed, &found, options);
    if dropped.is_empty() {
        return (found, evidence, Vec::new());
    }
    let at = OperatingPoint::of(&prepared.segments);
    let not_transferring = dropped
        .iter()
        .map(|(k, block)| NotTransferring {
            kind: found[*k].effect.kind(),
            params: found[*k].effect.params().into_iter().collect(),
            sentence: at.sentence(&found[*k].effect, duration),
            block_t_start: prepared.segments[block.start].t_start,
            block_t_end: prepared.segments[block.end - 1].t_end,
        })
        .collect();
    let mut evidence: Vec<Option<Evidence>> = evidence.into_iter().map(Some).collect();
    let kept_effects: Vec<ScopedEffect> = kept.iter().map(|&k| found[k].clone()).collect();
    let kept_evidence: Vec<Evidence> = kept.iter().filter_map(|&k| evidence[k].take()).collect();
    let refitted = if kept_effects.is_empty() {
        kept_effects
    } else {
        fit(&prepared.grid, &prepared.segments, fixed, &kept_effects, options.max_iters).effects
    };
    (refitted, kept_evidence, not_transferring)
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
    fn sentence(&self, effect: &Effect, duration: f64) -> String {
        effect.sentence_at(self.speed_m_per_s, self.turn_rad_per_s, duration)
    }

    fn of(segments: &[Segment]) -> Self {
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

/// What selection learned of an effect it accepted.
struct Evidence {
    delta_bic: f64,
    test: EntryTest,
    heldout_gain: f64,
    alternatives: Vec<Alternative>,
}

fn describe(
    scoped: &ScopedEffect,
    stderr: &[f64],
    evidence: Evidence,
    duration: f64,
    at: OperatingPoint,
) -> FoundEffect {
    let params = scoped.effect.params();
    let region = match scoped.effect {
        Effect::SurfaceZone { region, .. } => Some(region),
        _ => None,
    };
    let [t_start, t_end] = scoped.during.unwrap_or([0.0, duration]);
    let mut sentence = at.sentence(&scoped.effect, duration);
    if let Some([a, b]) = scoped.during {
        sentence = format!(
            "{}, only from {a:.0} s to {b:.0} s.",
            sentence.trim_end_matches('.')
        );
    }
    FoundEffect {
        kind: scoped.effect.kind(),
        params: params.iter().copied().collect(),
        stderr: params
            .iter()
            .zip(stderr.iter().chain(std::iter::repeat(&f64::NAN)))
            .map(|((name, _), &se)| (*name, se.is_finite().then_some(se)))
            .collect(),
        place: Where {
            t_start,
            t_end,
            region,
        },
        delta_bic: evidence.delta_bic,
        test: evidence.test,
        sentence,
        indistinguishable_from: evidence.alternatives.iter().map(|a| a.kind).collect(),
        alternatives: evidence.alternatives,
        heldout_gain: evidence.heldout_gain,
        scoped: scoped.clone(),
    }
}

/// An effect found over the whole run may act only in part of it: tries
/// it on the first or last part of the run, split at tenths and then
/// refined, on `screen`; returns the best narrower scope to confirm.
fn narrower_scope(
    grid: &CommandGrid,
    screen: &[Segment],
    base: &[ScopedEffect],
    global: &ScopedEffect,
    duration: f64,
    options: &Options,
) -> Option<ScopedEffect> {
    let scopable = !matches!(
        global.effect,
        Effect::SurfaceZone { .. }
            | Effect::BatteryFade { .. }
            | Effect::SpeedNoise { .. }
            | Effect::TurnCentreOffset { .. }
    );
    if !scopable || global.during.is_some() {
        return None;
    }
    let spans = |cuts: &[f64]| -> Vec<ScopedEffect> {
        cuts.iter()
            .filter(|&&c| c > 0.0 && c < duration)
            .flat_map(|&c| [[0.0, c], [c, duration]])
            .map(|during| ScopedEffect {
                effect: global.effect.clone(),
                during: Some(during),
            })
            .collect()
    };
    let mut best: Option<(ScopedEffect, f64)> = None;
    let mut step = duration / 10.0;
    let mut cuts: Vec<f64> = (1..10).map(|k| k as f64 * step).collect();
    for _ in 0..2 {
        let tries = spans(&cuts);
        let fits = fit_all(grid, screen, base, &tries, options.max_iters / 2);
        for f in &fits {
            if best.as_ref().is_none_or(|(_, nll)| f.nll < *nll) {
                best = Some((f.effects[0].clone(), f.nll));
            }
        }
        let (scoped, _) = best.as_ref()?;
        let [a, b] = scoped.during.unwrap_or([0.0, duration]);
        let cut = if a > 0.0 { a } else { b };
        step /= 4.0;
        cuts = vec![cut - 2.0 * step, cut - step, cut + step, cut + 2.0 * step];
    }
    best.map(|(scoped, _)| scoped)
}

/// Where the robot drove during a speed or turn effect's span, as a
/// region; `None` for other effects.
fn zone_of_span(segments: &[Segment], scoped: &ScopedEffect) -> Option<[f64; 4]> {
    let during = scoped.during?;
    if !matches!(
        scoped.effect,
        Effect::SpeedScale { .. } | Effect::Slip { .. } | Effect::TurnScale { .. }
    ) {
        return None;
    }
    region_driven(segments, during)
}

/// A surface zone that holds more of the robot's driving than this is the
/// whole floor: a speed or turn gain everywhere, which the library names as
/// such. Named as a zone, one global mismatch would read as a place (and,
/// with a fading battery beside it, hide the fade behind the zone's mean).
const MAX_ZONE_SHARE: f64 = 0.75;

/// The share of the moving segments whose midpoint lies in `region`.
fn zone_share(segments: &[Segment], region: &[f64; 4]) -> f64 {
    let moving = segments.iter().filter(|s| s.speed > 0.01);
    let (mut inside, mut all) = (0usize, 0usize);
    for s in moving {
        all += 1;
        let [x, y] = s.mid;
        if x >= region[0] && x <= region[2] && y >= region[1] && y <= region[3] {
            inside += 1;
        }
    }
    inside as f64 / all.max(1) as f64
}

/// Whether `effect` is a surface zone that covers the whole floor (see
/// [`MAX_ZONE_SHARE`]).
fn is_whole_floor(segments: &[Segment], effect: &Effect) -> bool {
    matches!(effect, Effect::SurfaceZone { region, .. } if zone_share(segments, region) > MAX_ZONE_SHARE)
}

/// The narrowest side a surface zone may have. A patch of floor narrower
/// than a robot's footprint is crossed in a fraction of a second and cannot
/// be told from an event that happened there; a fit that shrinks a zone to a
/// sliver has found a few odd segments, not a surface.
const MIN_ZONE_SIDE_M: f64 = 0.3;

/// `region` widened about its centre until each side is at least
/// [`MIN_ZONE_SIDE_M`].
fn at_least_min_side(region: [f64; 4]) -> [f64; 4] {
    let widen = |lo: f64, hi: f64| {
        let missing = (MIN_ZONE_SIDE_M - (hi - lo)).max(0.0);
        (lo - missing / 2.0, hi + missing / 2.0)
    };
    let (x0, x1) = widen(region[0], region[2]);
    let (y0, y1) = widen(region[1], region[3]);
    [x0, y0, x1, y1]
}

/// The box the robot drove in during `[a, b]` seconds (at least
/// [`MIN_ZONE_SIDE_M`] a side), if it drove there for at least a few
/// segments.
fn region_driven(segments: &[Segment], [a, b]: [f64; 2]) -> Option<[f64; 4]> {
    let inside: Vec<&Segment> = segments
        .iter()
        .filter(|s| s.t_start >= a && s.t_end <= b && s.speed > 0.01)
        .collect();
    if inside.len() < 5 {
        return None;
    }
    let mut region = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for s in inside {
        for p in [&s.start, &s.end] {
            region = [
                region[0].min(p.x),
                region[1].min(p.y),
                region[2].max(p.x),
                region[3].max(p.y),
            ];
        }
    }
    Some(at_least_min_side(region))
}

/// How much correlation in time inflates each residual component of the
/// model `base` plus `candidate` (see [`long_run_of_components`]), with the
/// estimates' degrees of freedom.
fn factors_with(
    grid: &CommandGrid,
    segs: &[Segment],
    base: &[ScopedEffect],
    candidate: &ScopedEffect,
) -> [LongRun; 3] {
    let model =
        UnicycleModel::with_effects(base.iter().cloned().chain([candidate.clone()]).collect());
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
fn calibrated_gain(
    grid: &CommandGrid,
    segs: &[Segment],
    base_nll: [f64; 3],
    base: &[ScopedEffect],
    candidate: &ScopedEffect,
    factors: [f64; 3],
) -> f64 {
    let nll = components_of(
        grid,
        segs,
        &base
            .iter()
            .cloned()
            .chain([candidate.clone()])
            .collect::<Vec<_>>(),
    );
    let gain: f64 = (0..3).map(|c| (nll[c] - base_nll[c]) / factors[c]).sum();
    2.0 * gain + extra_params(candidate) as f64 * log_n_eff(segs, factors)
}

/// The log of the effective number of observations BIC's penalty counts:
/// three components per segment, shrunk by their correlation in time.
fn log_n_eff(segs: &[Segment], factors: [f64; 3]) -> f64 {
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
fn entry_test(
    grid: &CommandGrid,
    segs: &[Segment],
    base: &[ScopedEffect],
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
    let (robust, long_run) = robust_chi2(grid, segs, base, candidate);
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
    let chi2 = on_chi2_scale(by_components, roughest).min(on_chi2_scale(robust, long_run.dof));
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

/// The likelihood-ratio statistic of adding `candidate` to `base`, made
/// robust to correlation in time: twice the log-likelihood gain divided by
/// the long-run variance factor of the gain's own per-segment series. To
/// first order that series is the candidate's score along the fitted
/// change, so this is the sandwich (HAC) correction of the test for this
/// effect: an effect whose signal changes sign with the turn rate is not
/// charged for the slow drift of the noise, and one that follows the
/// speed is charged for exactly the drift it can absorb.
fn robust_chi2(
    grid: &CommandGrid,
    segs: &[Segment],
    base: &[ScopedEffect],
    candidate: &ScopedEffect,
) -> (f64, LongRun) {
    let per_segment = |effects: Vec<ScopedEffect>| {
        let model = UnicycleModel::with_effects(effects);
        let r = residuals(&model, grid, segs);
        let noise = estimate_noise(&model, segs, &r);
        segment_nll(&model, &noise, segs, &r)
    };
    let without = per_segment(base.to_vec());
    let with = per_segment(base.iter().cloned().chain([candidate.clone()]).collect());
    let gains: Vec<f64> = without.iter().zip(&with).map(|(a, b)| a - b).collect();
    let long_run = long_run_factor(segs, &gains);
    let total: f64 = gains.iter().sum();
    (
        2.0 * total / (long_run.factor * misspecification(&gains, total)),
        long_run,
    )
}

/// How much more the per-segment gains vary than the noise model says they
/// should, at least 1. Where the model's noise is right, the gains' spread
/// is twice their sum, for an effect of any number of parameters (each
/// gain is, to first order, the score along the fitted change). Noise that
/// the model gets wrong (growing with the square of the speed, or larger in
/// some stretches) makes a few segments' gains dominate the sum; dividing
/// by this ratio is the sandwich correction for it (Huber 1967, White
/// 1982), the part the correlation in time does not already cover.
fn misspecification(gains: &[f64], total: f64) -> f64 {
    if total <= 0.0 || gains.is_empty() {
        return 1.0;
    }
    let mean = total / gains.len() as f64;
    let spread: f64 = gains.iter().map(|g| (g - mean).powi(2)).sum();
    (spread / (2.0 * total)).max(1.0)
}

/// [`entry_threshold`] for a statistic whose long-run variance was
/// estimated with `estimate_dof` degrees of freedom: dof x F(dof,
/// m - dof + 1) x m / (m - dof + 1) at the same level (Sun 2014). It
/// approaches the χ² threshold as the estimate's degrees of freedom grow.
fn fixed_b_threshold(dof: usize, alpha: f64, estimate_dof: f64) -> f64 {
    let k = dof.max(1) as f64;
    let m = estimate_dof.max(k + 1.0);
    FisherSnedecor::new(k, m - k + 1.0)
        .map(|f| k * f.inverse_cdf(1.0 - per_kind(alpha)) * m / (m - k + 1.0))
        .unwrap_or(f64::INFINITY)
}

/// Each kind's share of the family-wise level `alpha` (Bonferroni).
fn per_kind(alpha: f64) -> f64 {
    alpha / EFFECT_KINDS.len() as f64
}

/// The χ² an entering effect with `dof` parameters must exceed:
/// Bonferroni over the library's kinds at family-wise level `alpha`.
fn entry_threshold(dof: usize, alpha: f64) -> f64 {
    ChiSquared::new(dof.max(1) as f64)
        .map(|d| d.inverse_cdf(1.0 - per_kind(alpha)))
        .unwrap_or(f64::INFINITY)
}

fn components_of(grid: &CommandGrid, segs: &[Segment], effects: &[ScopedEffect]) -> [f64; 3] {
    let model = UnicycleModel::with_effects(effects.to_vec());
    component_nll(&model, segs, &residuals(&model, grid, segs))
}

/// A fitted parameter this close to an edge of its physical range (as a
/// share of the scale on which the parameter matters), where the edge is not
/// the plain model, is the fitter pushing against physics, not a measurement.
const ON_BOUND: f64 = 0.1;

/// Why `scoped`'s fit is not physics, if it ended on an edge of its range.
fn on_bound(scoped: &ScopedEffect) -> Option<String> {
    let identity = Effect::identity(scoped.effect.kind(), [0.0; 4])?;
    let plain: Vec<f64> = identity.params().into_iter().map(|(_, v)| v).collect();
    let ranges = scoped.effect.ranges();
    for (((name, value), (lo, hi)), plain) in
        scoped.effect.params().into_iter().zip(ranges).zip(plain)
    {
        let margin = ON_BOUND * crate::fit::step_of(&scoped.effect, name);
        for edge in [lo, hi] {
            if (value - edge).abs() <= margin && (plain - edge).abs() > margin {
                return Some(format!(
                    "{name} = {value:.4} ended on the edge of its physical range [{lo}, {hi}]"
                ));
            }
        }
    }
    None
}

/// Fits a surface zone's region edge by edge: each edge in turn moves to
/// where the likelihood is best, the factors held, then the factors are
/// refitted inside the new edges; coarse steps (a tenth of the zone's
/// size), then fine ones. A box of where the robot drove, or of coarse
/// located cells, becomes the zone's own edges. Other effects pass through.
fn refine_zone(
    grid: &CommandGrid,
    segs: &[Segment],
    base: &[ScopedEffect],
    mut zone: ScopedEffect,
    max_iters: u64,
) -> ScopedEffect {
    let Effect::SurfaceZone { region, .. } = zone.effect else {
        return zone;
    };
    let size = (region[2] - region[0]).max(region[3] - region[1]).max(0.1);
    for step in [0.1 * size, 0.03 * size] {
        let with = |effect: &Effect| {
            let mut effects = base.to_vec();
            effects.push(ScopedEffect::always(effect.clone()));
            nll_of(grid, segs, &effects)
        };
        let mut best = with(&zone.effect);
        for edge in 0..4 {
            for shift in [-3.0, -2.0, -1.0, 1.0, 2.0, 3.0] {
                let Effect::SurfaceZone {
                    region,
                    speed_factor,
                    turn_factor,
                } = zone.effect
                else {
                    return zone;
                };
                let mut moved = region;
                moved[edge] += shift * step;
                if moved[2] - moved[0] < MIN_ZONE_SIDE_M
                    || moved[3] - moved[1] < MIN_ZONE_SIDE_M
                    || zone_share(segs, &moved) > MAX_ZONE_SHARE
                {
                    continue;
                }
                let candidate = Effect::SurfaceZone {
                    region: moved,
                    speed_factor,
                    turn_factor,
                };
                let nll = with(&candidate);
                if nll < best {
                    (best, zone.effect) = (nll, candidate);
                }
            }
        }
        zone = fit(grid, segs, base, std::slice::from_ref(&zone), max_iters).effects[0].clone();
    }
    zone
}

/// Every k-th segment, at most `count` of them.
pub(crate) fn subsample(segments: &[Segment], count: usize) -> Vec<Segment> {
    let every = segments.len().div_ceil(count.max(1)).max(1);
    segments.iter().step_by(every).cloned().collect()
}

/// What one round of forward selection decided.
enum Round {
    /// No candidate lowers the calibrated BIC enough: selection ends.
    Done,
    /// The best candidate, and the candidates later rounds may still try.
    Chosen {
        chosen: ScopedEffect,
        delta_bic: f64,
        test: EntryTest,
        /// Rival explanations within 2 of BIC.
        tied: Vec<(f64, ScopedEffect)>,
        remaining: Vec<ScopedEffect>,
    },
}

/// One diagnosis's data and settings, shared by its stages.
struct Selection<'a> {
    prepared: &'a Prepared,
    /// An even subsample of the segments that ranks candidates, so the
    /// cost of a round stops growing with the length of the run.
    screen: Vec<Segment>,
    /// The effects of the model under diagnosis.
    fixed: Vec<ScopedEffect>,
    /// Noise that grows with speed, fitted to the model under diagnosis but
    /// never named by itself (see [`Selection::judged_with`]).
    lens: Option<ScopedEffect>,
    duration: f64,
    options: &'a Options,
}

/// Below this share of the noise from driving, the lens is left out: the
/// noise hardly grows with speed.
const LENS_MIN_SHARE: f64 = 0.05;

impl Selection<'_> {
    /// `base` as tests judge a candidate against it: with noise that grows
    /// with speed, unless `base` already has a noise effect. Mean effects
    /// are named before noise ones (see [`select`]), so without the lens a
    /// robot whose noise grows with its speed would have every candidate
    /// judged by a noise model that weighs its fast, noisy seconds like its
    /// slow ones: its per-segment gains then swing, and one held-out block
    /// can seem to contradict a true effect (feasible generalised least
    /// squares: estimate the variance first, then weigh by it).
    fn judged_with(&self, base: &[ScopedEffect], candidate: &ScopedEffect) -> Vec<ScopedEffect> {
        let mut out = base.to_vec();
        if let Some(lens) = &self.lens
            && !candidate.effect.only_noise()
            && !base.iter().any(|e| e.effect.only_noise())
        {
            out.push(lens.clone());
        }
        out
    }

    /// Fits the lens: speed-dependent noise on the model under diagnosis.
    fn fit_lens(&mut self) {
        let usual_speed = OperatingPoint::of(self.segs()).speed_m_per_s;
        let Some(identity) = Effect::identity("speed_noise", [0.0; 4]) else {
            return;
        };
        let start = ScopedEffect::always(identity.at_reference_speed(usual_speed));
        let fitted = fit(
            self.grid(),
            &self.screen,
            &self.fixed,
            std::slice::from_ref(&start),
            self.options.max_iters,
        );
        self.lens = fitted.effects.into_iter().next().filter(|lens| {
            matches!(lens.effect, Effect::SpeedNoise { driving_share, .. } if driving_share > LENS_MIN_SHARE)
        });
    }

    fn grid(&self) -> &CommandGrid {
        &self.prepared.grid
    }

    fn segs(&self) -> &[Segment] {
        &self.prepared.segments
    }

    /// One round: candidates are ranked on the screen, the best few fitted
    /// on every segment (zones edge by edge) and judged with calibrated
    /// gains; the best may then act in part of the run only.
    fn round(&self, base: &[ScopedEffect], remaining: &[ScopedEffect]) -> Round {
        let (grid, segs, options) = (self.grid(), self.segs(), self.options);
        let base_nll = components_of(grid, segs, base);
        let screen_current = nll_of(grid, &self.screen, base);
        let screen_log_n = ((3 * self.screen.len()).max(2) as f64).ln();
        let screened = fit_all(grid, &self.screen, base, remaining, options.max_iters);
        // Ranking only: the screen's plain BIC orders the candidates; the
        // decision below is made on all segments with calibrated gains.
        let mut ranked: Vec<(f64, ScopedEffect)> = screened
            .iter()
            .zip(remaining)
            .map(|(f, c)| {
                let gain = 2.0 * (f.nll - screen_current) + extra_params(c) as f64 * screen_log_n;
                (gain, f.effects[0].clone())
            })
            .filter(|(g, _)| *g < 0.0)
            .collect();
        ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
        ranked.truncate(options.confirm);
        let top: Vec<ScopedEffect> = ranked.into_iter().map(|(_, c)| c).collect();
        let mut confirmed = fit_all(grid, segs, base, &top, options.max_iters / 2);
        for fitted in &mut confirmed {
            let zone = refine_zone(
                grid,
                segs,
                base,
                fitted.effects[0].clone(),
                options.max_iters / 2,
            );
            if zone != fitted.effects[0] {
                let effects: Vec<ScopedEffect> =
                    base.iter().cloned().chain([zone.clone()]).collect();
                fitted.nll = nll_of(grid, segs, &effects);
                fitted.effects = vec![zone];
            }
        }
        confirmed.retain(|f| !is_whole_floor(segs, &f.effects[0].effect));
        let Some(best_fit) = confirmed.iter().min_by(|a, b| a.nll.total_cmp(&b.nll)) else {
            return Round::Done;
        };
        let long_runs = factors_with(grid, segs, base, &best_fit.effects[0]);
        let factors = long_runs.map(|l| l.factor);
        let judge = |c: &ScopedEffect| calibrated_gain(grid, segs, base_nll, base, c, factors);
        let mut judged: Vec<(f64, ScopedEffect)> = confirmed
            .iter()
            .map(|f| (judge(&f.effects[0]), f.effects[0].clone()))
            .collect();
        judged.sort_by(|a, b| a.0.total_cmp(&b.0));
        let Some((delta_bic, chosen)) = judged.first().cloned() else {
            return Round::Done;
        };
        // Explanations within 2 of BIC are not worth more than a bare
        // mention apart (Kass and Raftery): one finding, with alternatives.
        let mut tied: Vec<(f64, ScopedEffect)> = judged[1..]
            .iter()
            .filter(|(g, c)| *g < delta_bic + 2.0 && c.effect.kind() != chosen.effect.kind())
            .cloned()
            .collect();
        let test = entry_test(
            grid,
            segs,
            &self.judged_with(base, &chosen),
            &chosen,
            (delta_bic, long_runs),
            options,
        );
        if !test.passed() {
            return Round::Done;
        }
        let (scoped, delta_bic) = self.scoped(base, chosen.clone(), delta_bic, &judge, &mut tied);
        let test = if scoped == chosen {
            test
        } else {
            let judged_base = self.judged_with(base, &scoped);
            entry_test(grid, segs, &judged_base, &scoped, (delta_bic, long_runs), options)
        };
        let chosen = scoped;
        let tied_kinds: Vec<&'static str> = tied.iter().map(|(_, c)| c.effect.kind()).collect();
        // Later rounds only try what helped on its own (an effect that did
        // not lower the likelihood alone is rarely needed in company), and
        // never an alternative of what was found: that would name one
        // mismatch twice.
        let remaining = remaining
            .iter()
            .zip(&screened)
            .filter(|(c, f)| {
                let kind = c.effect.kind();
                f.nll < screen_current - 1.0
                    && kind != chosen.effect.kind()
                    && !tied_kinds.contains(&kind)
            })
            .map(|(c, _)| c.clone())
            .collect();
        Round::Chosen {
            chosen,
            delta_bic,
            test,
            tied,
            remaining,
        }
    }

    /// An effect may act in part of the run only. Trying that is not left
    /// to the locating tests alone: the held-out check that follows keeps a
    /// narrower scope from fitting noise. A robot that drives into a zone
    /// and stays there shows a change in time that is as much a change in
    /// place, so the region it drove in over that span is tried as a zone.
    fn scoped(
        &self,
        base: &[ScopedEffect],
        chosen: ScopedEffect,
        delta_bic: f64,
        judge: &impl Fn(&ScopedEffect) -> f64,
        tied: &mut Vec<(f64, ScopedEffect)>,
    ) -> (ScopedEffect, f64) {
        let (grid, segs, options) = (self.grid(), self.segs(), self.options);
        let Some(scoped) =
            narrower_scope(grid, &self.screen, base, &chosen, self.duration, options)
        else {
            return (chosen, delta_bic);
        };
        let confirm = |candidate: &ScopedEffect| {
            let full = fit(
                grid,
                segs,
                base,
                std::slice::from_ref(candidate),
                options.max_iters / 2,
            );
            let fitted = full.effects[0].clone();
            let gain = judge(&fitted);
            (fitted, gain)
        };
        let (scoped_fit, scoped_gain) = confirm(&scoped);
        if scoped_gain >= delta_bic - options.min_scope_bic_gain {
            return (chosen, delta_bic);
        }
        if let Some(zone) = zone_of_span(segs, &scoped_fit)
            && let Some(zone_effect) = Effect::identity("surface_zone", zone)
        {
            let (zone_fit, _) = confirm(&ScopedEffect::always(zone_effect));
            let zone_fit = refine_zone(grid, segs, base, zone_fit, options.max_iters / 2);
            let zone_gain = judge(&zone_fit);
            if zone_gain < scoped_gain + 2.0 && !is_whole_floor(segs, &zone_fit.effect) {
                tied.push((scoped_gain, scoped_fit));
                return (zone_fit, zone_gain);
            }
        }
        (scoped_fit, scoped_gain)
    }

    /// Refits `found` together, then drops any effect the others, refitted,
    /// do as well without (a turn scale standing in for steering play, once
    /// the play joined); `evidence` follows index for index.
    fn refit_and_prune(&self, found: &mut Vec<ScopedEffect>, evidence: &mut Vec<Evidence>) {
        let (grid, segs, options, fixed) = (self.grid(), self.segs(), self.options, &self.fixed);
        *found = fit(grid, segs, fixed, found, options.max_iters * 2).effects;
        let mut k = 0;
        while found.len() >= 2 && k < found.len() {
            let others: Vec<ScopedEffect> = found
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != k)
                .map(|(_, e)| e.clone())
                .collect();
            let refit = fit(grid, segs, fixed, &others, options.max_iters);
            let rest: Vec<ScopedEffect> =
                fixed.iter().cloned().chain(refit.effects.clone()).collect();
            let long_runs = factors_with(grid, segs, &rest, &found[k]);
            let rest_nll = components_of(grid, segs, &rest);
            let factors = long_runs.map(|l| l.factor);
            let needed = calibrated_gain(grid, segs, rest_nll, &rest, &found[k], factors);
            if !entry_test(grid, segs, &self.judged_with(&rest, &found[k]), &found[k], (needed, long_runs), options).passed() {
                *found = refit.effects;
                evidence.remove(k);
            } else {
                k += 1;
            }
        }
    }
}

/// What forward selection concluded.
#[derive(Default)]
struct Selected {
    found: Vec<ScopedEffect>,
    /// What selection learned of each effect in `found`, index for index.
    evidence: Vec<Evidence>,
    unexplained: Vec<Unexplained>,
    rejected_heldout: Vec<&'static str>,
}

/// Forward selection: round after round, the best candidate enters if its
/// fit is physical and it predicts held-out time blocks better.
fn select(selection: &Selection, located: &[Located], at: OperatingPoint) -> Selected {
    let segs = selection.segs();
    let mut out = Selected::default();
    // Where the robot goes is explained first, how noisy it is after: a
    // mismatch of the mean (mud, a drift) otherwise passes for noise that
    // grows with speed, and the noise model it leaves behind then judges
    // the true explanation unlikely (feasible GLS orders them the same way).
    let (mean_candidates, noise_candidates): (Vec<ScopedEffect>, Vec<ScopedEffect>) =
        candidates(located, segs, selection.duration)
            .into_iter()
            .partition(|c| !c.effect.only_noise());
    for mut remaining in [mean_candidates, noise_candidates] {
        while out.found.len() < selection.options.max_effects
            && !remaining.is_empty()
            && segs.len() >= 20
        {
            let base: Vec<ScopedEffect> =
                selection.fixed.iter().chain(&out.found).cloned().collect();
            let Round::Chosen {
                chosen,
                delta_bic,
                test,
                tied,
                remaining: next,
            } = selection.round(&base, &remaining)
            else {
                break;
            };
            remaining = next;
            if let Some(reason) = on_bound(&chosen) {
                out.unexplained.push(Unexplained {
                    tried: chosen.effect.kind(),
                    params: chosen.effect.params().into_iter().collect(),
                    reason: format!(
                        "{reason}; the mismatch is real (BIC {delta_bic:.0}) but no effect of the library explains it within physical limits"
                    ),
                });
                continue;
            }
            // It must predict the held-out blocks better in all, and, if it
            // is physics of the body (`heldout::must_transfer`), no block
            // may contradict it (`heldout::CONTRADICTION_NATS`).
            let gains = heldout_gain(
                selection.prepared,
                &selection.judged_with(&base, &chosen),
                &chosen,
                selection.options,
            );
            let gain_heldout: f64 = gains.iter().sum();
            let worst = gains.iter().copied().fold(f64::INFINITY, f64::min);
            let contradicted = must_transfer(&chosen) && worst < -CONTRADICTION_NATS;
            if !(gain_heldout > 0.0) || contradicted {
                out.rejected_heldout.push(chosen.effect.kind());
                continue;
            }
            out.found.push(chosen);
            out.evidence.push(Evidence {
                delta_bic,
                test,
                heldout_gain: gain_heldout,
                // An alternative fitted onto a physical edge is no explanation.
                alternatives: tied
                    .iter()
                    .filter(|(_, c)| on_bound(c).is_none())
                    .map(|(g, c)| Alternative {
                        kind: c.effect.kind(),
                        params: c.effect.params().into_iter().collect(),
                        delta_bic: *g,
                        sentence: at.sentence(&c.effect, selection.duration),
                    })
                    .collect(),
            });
            selection.refit_and_prune(&mut out.found, &mut out.evidence);
        }
    }
    out
}

/// What the standardised residuals of `model` still follow, strongest first.
fn residual_covariates_of(
    model: &UnicycleModel,
    grid: &CommandGrid,
    segs: &[Segment],
) -> Vec<Covariate> {
    let r = residuals(model, grid, segs);
    let noise = estimate_noise(model, segs, &r);
    let z = standardised(model, &noise, segs, &r);
    covariates::strongest(
        segs,
        &z,
        long_run_factors_of_noise(segs, &z),
        COVARIATES_REPORTED,
    )
}

/// Diagnoses `recording` against `model`.
pub fn diagnose(recording: &Recording, model: &UnicycleModel, options: &Options) -> Diagnosis {
    let prepared = prepare(recording, options);
    let (grid, segs) = (&prepared.grid, &prepared.segments);
    let duration = recording.duration();
    let plain_residuals = residuals(model, grid, segs);
    let noise = estimate_noise(model, segs, &plain_residuals);
    let plain_standardised = standardised(model, &noise, segs, &plain_residuals);
    let noise_correlation = long_run_factors_of_noise(segs, &plain_standardised);
    let operating_point = OperatingPoint::of(segs);
    let located = locate(segs, &plain_standardised, noise_correlation, options.alpha);
    let mut selection = Selection {
        prepared: &prepared,
        screen: subsample(segs, options.screen_segments),
        fixed: model.effects.clone(),
        lens: None,
        duration,
        options,
    };
    selection.fit_lens();
    let Selected {
        found,
        evidence,
        unexplained,
        rejected_heldout,
    } = select(&selection, &located, operating_point);
    let fixed = &selection.fixed;
    let (found, evidence, not_transferring) = transferring(&prepared, fixed, found, evidence, duration, options);

    let stderr = if found.is_empty() {
        Vec::new()
    } else {
        fit(grid, segs, fixed, &found, options.max_iters).stderr
    };
    let mut offset = 0;
    let effects: Vec<FoundEffect> = found
        .iter()
        .zip(evidence)
        .map(|(scoped, evidence)| {
            let count = scoped.effect.params().len();
            let se = &stderr[offset.min(stderr.len())..(offset + count).min(stderr.len())];
            offset += count;
            describe(scoped, se, evidence, duration, operating_point)
        })
        .collect();
    let final_model = UnicycleModel::with_effects(fixed.iter().chain(&found).cloned().collect());
    let (baseline, plain_errors, baseline_blocks) = heldout(&prepared, fixed, &[], options);
    let (improved, improved_errors, improved_blocks) = if found.is_empty() {
        (baseline, plain_errors.clone(), baseline_blocks.clone())
    } else {
        heldout(&prepared, fixed, &found, options)
    };
    Diagnosis {
        mismatch: !effects.is_empty() || !located.is_empty() || !unexplained.is_empty(),
        located,
        effects,
        unexplained,
        residual_covariates: residual_covariates_of(&final_model, grid, segs),
        noise_correlation,
        operating_point,
        pose_outliers: prepared.pose_outliers,
        glitches: prepared.glitches.clone(),
        rejected_heldout,
        not_transferring,
        blocks: block_reports(&prepared, &baseline_blocks, &improved_blocks),
        baseline,
        improved,
        segments: segs.len(),
        horizon_s: options.horizon_s,
        t_origin: recording.t_origin,
        model: final_model,
        heldout_errors: plain_errors
            .iter()
            .zip(&improved_errors)
            .map(|(&(t, plain), &(_, better))| (t, plain, better))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_zone_is_never_narrower_than_a_robot() {
        let sliver = at_least_min_side([2.40, 2.75, 2.43, 2.99]);
        assert!((sliver[2] - sliver[0] - MIN_ZONE_SIDE_M).abs() < 1e-12);
        assert!((sliver[3] - sliver[1] - MIN_ZONE_SIDE_M).abs() < 1e-12);
        // Widened about its centre.
        assert!(((sliver[0] + sliver[2]) / 2.0 - 2.415).abs() < 1e-12);
        // A zone wide enough already is left as it is.
        assert_eq!(
            at_least_min_side([0.0, 0.0, 1.0, 2.0]),
            [0.0, 0.0, 1.0, 2.0]
        );
    }

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

//! The whole diagnosis: locate the mismatch, name it by forward selection
//! of effects (each must pass a calibrated test, lower BIC and predict
//! held-out, time-blocked folds better), and measure the fit before and after.
//! The stages live in their own modules: `candidates` (what a round tries),
//! `zones` (surface zones' edges), `entry` (the entry test), `selection`
//! (the rounds, pruning), `heldout` (folds, blocks and transfer) and
//! `feedback` (each effect held out where no command answered the noise),
//! and what they share in `prepared` (options, the prepared run); this one runs
//! them in order and states the findings.

use std::cell::OnceCell;
use std::collections::BTreeMap;

use serde::Serialize;
use shoal_physics::{CommandGrid, Effect, ScopedEffect, UnicycleModel};

use crate::covariates::{self, Covariate};
pub use crate::entry::EntryTest;
use crate::feedback::{self, FeedbackFree, Horizons, NotFeedbackFree, ShortRuns};
use crate::fit::{all_but, fit};
use crate::heldout::{BlockReport, HeldoutRun, block_reports, heldout, transferable};
use crate::likelihood::{estimate_noise, long_run_factors_of_noise, residuals, standardised};
use crate::locate::{Located, locate};
pub use crate::prepared::{
    Alternative, Heldout, OperatingPoint, Options, Prepared, Unexplained, prepare,
};
use crate::recording::Recording;
use crate::segments::Segment;
use crate::segments::subsample;
use crate::selection::{Evidence, Selected, Selection, reselected, select};
use crate::timeout::{CommandTimeout, with_timeout};

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
    /// Other kinds that explain the run as well (within 2 of BIC, or
    /// neither adding beside the other): this data cannot tell them apart,
    /// so they are one finding. The kinds of `alternatives`, kept for
    /// readers of the earlier JSON.
    pub indistinguishable_from: Vec<&'static str>,
    /// The same, with each alternative's fitted parameters and sentence.
    pub alternatives: Vec<Alternative>,
    /// Held-out (time-blocked) gain in log-likelihood from adding it.
    pub heldout_gain: f64,
    /// How it predicts where no command answered the noise it is scored
    /// on (`feedback`), and why it was kept there (`kept_because` in the
    /// JSON); none for an effect on the noise alone.
    #[serde(serialize_with = "crate::feedback::serialize_with_confirmation")]
    pub feedback_free: Option<FeedbackFree>,
    #[serde(skip)]
    pub scoped: ScopedEffect,
}

#[derive(Clone, Debug, Serialize)]
pub struct Diagnosis {
    pub mismatch: bool,
    pub located: Vec<Located>,
    pub effects: Vec<FoundEffect>,
    /// How the recording was made, found as an effect is and said apart
    /// from the body's physics: the poses move as a body a simulator steps
    /// by Euler (`euler_step`, forward or semi-implicit). The plain model
    /// the effects are measured against steps so too.
    pub integration: Option<FoundEffect>,
    /// The robot stops when no command has come for a while (a
    /// controller's command timeout), as the pauses of its command stream
    /// showed before anything was fitted: each command is compared as
    /// ending then (`timeout`).
    pub command_timeout: Option<CommandTimeout>,
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
    /// Where the poses held positions only: how their headings were taken
    /// from the track.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heading_from_track: Option<crate::track::TrackHeadings>,
    /// Where the poses' headings were turned by quarter turns to the way
    /// the robot drives (a motion-capture body defined with other axes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heading_axis: Option<crate::track::HeadingAxis>,
    /// What was set aside as not the body's own motion before anything was fitted:
    /// jumps and returns, jumps without a return, pose gaps, command stalls.
    pub glitches: Vec<crate::glitches::Glitch>,
    /// Candidates that passed BIC but did not improve held-out prediction,
    /// or that a held-out block contradicted.
    pub rejected_heldout: Vec<&'static str>,
    /// Effects selected on the whole run that made the final model predict
    /// a held-out block worse than the model diagnosed: physics of one
    /// stretch that does not transfer to another, dropped.
    pub not_transferring: Vec<NotTransferring>,
    /// Effects selected on the whole run that predict no better where no
    /// command answered the noise (`feedback`): what a controller steering
    /// on the pose makes of motion noise, dropped.
    pub not_feedback_free: Vec<NotFeedbackFree>,
    /// Each held-out block (a recording, or a stretch of one) and how well
    /// the model diagnosed and the fitted one predicted it.
    pub blocks: Vec<BlockReport>,
    pub baseline: Heldout,
    pub improved: Heldout,
    /// How the model diagnosed against predicts this recording beside the
    /// plain model, when one was given (`--model`).
    pub given_model: Option<GivenModel>,
    pub segments: usize,
    pub horizon_s: f64,
    /// The segments' median length: the horizon, or longer where slow
    /// poses moved their ends to where they were observed
    /// (`segments::SNAPPED_INTERVAL_S`).
    pub segment_s: f64,
    /// Seconds subtracted from the input's times; reported times count from it.
    pub t_origin: f64,
    /// The input model plus what was found, ready to write as model.toml.
    #[serde(skip)]
    pub model: UnicycleModel,
    /// Per held-out segment: start time, plain and improved position error.
    #[serde(skip)]
    pub heldout_errors: Vec<(f64, f64, f64)>,
}

impl Diagnosis {
    /// The effect named of `kind`, if one was.
    pub fn effect(&self, kind: &str) -> Option<&FoundEffect> {
        self.effects.iter().find(|e| e.kind == kind)
    }
}

/// How a model given to diagnose against (another stretch's `model.toml`,
/// say) predicts this recording beside the plain model. Physics fitted on
/// one stretch of a robot may not hold on another (a stretch that turned
/// one way cannot tell a marker off the axle from speed lost in turns;
/// EXPERIMENTS.md 6b): a given model that predicts the recording worse
/// than no model at all is said, and the effects it predicts better
/// without are set aside, so the recording is diagnosed against what holds
/// on it and the model written (`--out`) carries only that.
#[derive(Clone, Debug, Serialize)]
pub struct GivenModel {
    /// The plain model's held-out fit (no effects at all).
    pub plain: Heldout,
    /// The given model's held-out fit, every effect of it kept.
    pub given: Heldout,
    /// Whether the given model's held-out position error is larger than
    /// the plain model's.
    pub worse_than_plain: bool,
    /// When it is worse: the given effects without which it predicts this
    /// recording better held out.
    pub not_holding: Vec<NotHolding>,
    /// The given effects left out of the diagnosis, in the order they were:
    /// while what is kept predicts worse than the plain model, the effect
    /// whose absence predicts best goes. The diagnosis's baseline is what
    /// is left.
    pub set_aside: Vec<&'static str>,
}

/// An effect of the given model that does not hold on this recording.
#[derive(Clone, Debug, Serialize)]
pub struct NotHolding {
    pub kind: &'static str,
    /// Held-out position error of the given model without it.
    pub heldout_rmse_pos_m_without: f64,
}

/// [`GivenModel`] for the effects `given`, the effects to diagnose
/// against (all of them, or those left once the ones that do not hold are
/// set aside) and their held-out run, the diagnosis's baseline. `None` for
/// the plain model.
fn given_model(
    prepared: &Prepared,
    given: &[ScopedEffect],
    options: &Options,
) -> Option<(GivenModel, Vec<ScopedEffect>, HeldoutRun)> {
    if given.is_empty() {
        return None;
    }
    let error = |effects: &[ScopedEffect]| heldout(prepared, effects, &[], options);
    // Each effect's absence from `effects`, judged held out.
    let without_each = |effects: &[ScopedEffect]| -> Vec<HeldoutRun> {
        (0..effects.len())
            .map(|k| error(&all_but(effects, k)))
            .collect()
    };
    let plain = error(&[]).0;
    let fit = error(given);
    let worse = |run: &HeldoutRun| run.0.heldout_rmse_pos_m > plain.heldout_rmse_pos_m;
    let worse_than_plain = worse(&fit);
    // The given model's first round of absences serves both what is said
    // (`not_holding`) and the first effect set aside.
    let mut withouts = if worse_than_plain {
        without_each(given)
    } else {
        Vec::new()
    };
    let not_holding = withouts
        .iter()
        .enumerate()
        .filter(|(_, without)| without.0.heldout_rmse_pos_m < fit.0.heldout_rmse_pos_m)
        .map(|(k, without)| NotHolding {
            kind: given[k].effect.kind(),
            heldout_rmse_pos_m_without: without.0.heldout_rmse_pos_m,
        })
        .collect();
    let given_fit = fit.0;
    let (mut kept, mut kept_fit, mut set_aside) = (given.to_vec(), fit, Vec::new());
    while worse(&kept_fit) {
        let Some((k, without)) = withouts.into_iter().enumerate().min_by(|a, b| {
            a.1.0
                .heldout_rmse_pos_m
                .total_cmp(&b.1.0.heldout_rmse_pos_m)
        }) else {
            break;
        };
        set_aside.push(kept.remove(k).effect.kind());
        kept_fit = without;
        withouts = if worse(&kept_fit) {
            without_each(&kept)
        } else {
            Vec::new()
        };
    }
    Some((
        GivenModel {
            plain,
            given: given_fit,
            worse_than_plain,
            not_holding,
            set_aside,
        },
        kept,
        kept_fit,
    ))
}

/// How many times the effects the feedback stage kept are judged again
/// without what it dropped: each pass bars the kinds dropped so far, so a
/// pass can only name kinds not yet refused.
const RESELECTIONS: usize = 3;

/// What the stages after selection dropped, and why.
#[derive(Default)]
struct Dropped {
    not_transferring: Vec<NotTransferring>,
    not_feedback_free: Vec<NotFeedbackFree>,
}

/// What selection named, kept where it transfers between the run's stretches
/// (`transferring`) and predicts where no command answered the noise
/// (`feedback_checked`). An effect admitted beside one the feedback stage
/// then dropped was judged against a model that is no longer the diagnosis:
/// the rest are judged again without the dropped kinds
/// (`selection::reselected`; from none, where every effect was dropped),
/// and what changed faces these stages as the first choice did, until they
/// drop nothing more (at most `RESELECTIONS` times).
fn through_later_stages(
    selection: &Selection,
    runs: &FeedbackRuns,
    mut selected: Selected,
    at: OperatingPoint,
) -> (Selected, Dropped) {
    let mut dropped = Dropped::default();
    let mut dropped_by_feedback = checked_once(selection, runs, &mut selected, &mut dropped);
    for _ in 0..RESELECTIONS {
        if dropped_by_feedback == 0 {
            break;
        }
        let barred: Vec<&'static str> = dropped
            .not_feedback_free
            .iter()
            .map(|d| d.kind)
            .chain(dropped.not_transferring.iter().map(|d| d.kind))
            .collect();
        let dropped_effects: Vec<ScopedEffect> = dropped
            .not_feedback_free
            .iter()
            .map(|d| d.scoped.clone())
            .collect();
        let before: Vec<&'static str> = selected.found.iter().map(|e| e.effect.kind()).collect();
        let again = reselected(
            selection,
            std::mem::take(&mut selected.found),
            std::mem::take(&mut selected.evidence),
            (&barred, &dropped_effects),
            at,
        );
        selected.rejected_heldout.extend(again.rejected_heldout);
        (selected.found, selected.evidence) = (again.found, again.evidence);
        if selected.found.iter().map(|e| e.effect.kind()).eq(before) {
            break;
        }
        dropped_by_feedback = checked_once(selection, runs, &mut selected, &mut dropped);
    }
    (selected, dropped)
}

/// `selected` through the transfer and feedback stages once, what they drop
/// added to `dropped`; returns how many the feedback stage dropped.
fn checked_once(
    selection: &Selection,
    runs: &FeedbackRuns,
    selected: &mut Selected,
    dropped: &mut Dropped,
) -> usize {
    let (prepared, fixed, options) = (selection.prepared, &selection.fixed, selection.options);
    let (kept, kept_evidence, more) = transferring(
        prepared,
        fixed,
        std::mem::take(&mut selected.found),
        std::mem::take(&mut selected.evidence),
        selection.duration,
        options,
    );
    dropped.not_transferring.extend(more);
    let (kept, kept_evidence, more) = feedback_checked(runs, fixed, kept, kept_evidence);
    let by_feedback = more.len();
    dropped.not_feedback_free.extend(more);
    (selected.found, selected.evidence) = (kept, kept_evidence);
    by_feedback
}

/// The recording the feedback stage checks each model on, as prepared for
/// the diagnosis and cut at its feedback-free horizons the first time a
/// check asks ([`ShortRuns`]): the cut is the same for every model
/// checked, and a run whose effects are all noise never asks.
struct FeedbackRuns<'a> {
    recording: &'a Recording,
    prepared: &'a Prepared,
    options: &'a Options,
    cut: OnceCell<ShortRuns>,
}

impl<'a> FeedbackRuns<'a> {
    fn new(recording: &'a Recording, prepared: &'a Prepared, options: &'a Options) -> Self {
        Self {
            recording,
            prepared,
            options,
            cut: OnceCell::new(),
        }
    }

    fn cut(&self) -> &ShortRuns {
        self.cut
            .get_or_init(|| ShortRuns::of(self.recording, self.prepared, self.options))
    }
}

/// How many of the residuals' strongest covariates a diagnosis lists.
const COVARIATES_REPORTED: usize = 5;

/// The found effects the feedback stage confirms (`feedback::check_each`),
/// refitted together if any was dropped, with their evidence carrying the
/// check; and the dropped ones.
fn feedback_checked(
    runs: &FeedbackRuns,
    fixed: &[ScopedEffect],
    found: Vec<ScopedEffect>,
    evidence: Vec<Evidence>,
) -> (Vec<ScopedEffect>, Vec<Evidence>, Vec<NotFeedbackFree>) {
    let (prepared, options) = (runs.prepared, runs.options);
    if found.iter().all(|e| e.effect.only_noise()) {
        return (found, evidence, Vec::new());
    }
    let horizons = Horizons::of(runs.cut(), fixed, &found);
    let checks = feedback::check_each(&horizons, prepared, options, fixed, &found);
    let (kept, dropped): (Vec<usize>, Vec<usize>) =
        (0..found.len()).partition(|&k| checks[k].is_none_or(|c| c.confirmed()));
    let at = OperatingPoint::of(&prepared.segments);
    let duration = runs.recording.duration();
    let not_feedback_free = dropped
        .iter()
        .filter_map(|&k| Some(NotFeedbackFree::of(&found[k], checks[k]?, &at, duration)))
        .collect();
    let (kept_found, mut kept_evidence) = if dropped.is_empty() {
        (found, evidence)
    } else {
        kept_refitted(prepared, fixed, &found, evidence, &kept, options)
    };
    for (e, &k) in kept_evidence.iter_mut().zip(&kept) {
        e.feedback_free = checks[k];
    }
    let said = Said { at: &at, duration };
    rivals_at_horizon(
        &horizons,
        prepared,
        fixed,
        &kept_found,
        &mut kept_evidence,
        said,
        options,
    );
    (kept_found, kept_evidence, not_feedback_free)
}

/// Where an effect's sentence is said: the run's operating point and length.
#[derive(Clone, Copy)]
struct Said<'a> {
    at: &'a OperatingPoint,
    duration: f64,
}

/// On a run whose controller answers noise that lasts past a command, each
/// effect's runners-up from the round that chose it, compared with it where
/// no command answered the noise: one not shown worse there is said beside
/// it as an alternative (`feedback::rival_against_chosen`). Elsewhere the
/// long segments' ranking stands, free of any answer. Each runner-up is
/// compared once.
fn rivals_at_horizon(
    horizons: &Horizons,
    prepared: &Prepared,
    fixed: &[ScopedEffect],
    found: &[ScopedEffect],
    evidence: &mut [Evidence],
    said: Said,
    options: &Options,
) {
    if !horizons.answered() {
        return;
    }
    let shorts = horizons.shorts();
    for (k, chosen) in found.iter().enumerate() {
        let runners_up = std::mem::take(&mut evidence[k].runners_up);
        if chosen.effect.only_noise() {
            continue;
        }
        for (delta_bic, rival) in runners_up {
            let kind = rival.effect.kind();
            if rival.effect.only_noise()
                || found.iter().any(|e| e.effect.kind() == kind)
                || evidence[k].alternatives.iter().any(|a| a.kind == kind)
            {
                continue;
            }
            let Some(z) = feedback::rival_against_chosen(
                prepared,
                &shorts,
                (fixed, found, k),
                &rival,
                options,
            ) else {
                continue;
            };
            tracing::debug!(
                chosen = chosen.effect.kind(),
                rival = kind,
                z,
                "feedback: a runner-up in place of the chosen where no command answered the noise"
            );
            if z > -feedback::MIN_Z {
                evidence[k].alternatives.push(Alternative {
                    kind,
                    params: rival.effect.params().into_iter().collect(),
                    delta_bic,
                    sentence: said.at.sentence(&rival.effect, said.duration),
                    where_no_command_answered: Some(z),
                });
            }
        }
    }
}

/// The mismatches said real but fitted only on the edge of what is
/// physical that the feedback stage confirms beside the effects named
/// (`base`: the fixed ones and those found); the others join
/// `not_feedback_free`. Said on the round's test alone, where a named
/// effect must also pass this stage, 2 of 60 open-loop null runs of
/// `waypoints-open` reported one (a semi-implicit step on the edge of its
/// range: EXPERIMENTS.md 5c), and neither gains on one command period. So
/// such a mismatch must be confirmed there even in open loop, where a
/// named effect, held out in blocks already, need only not be
/// contradicted ([`FeedbackFree::confirmed_there`]).
fn unexplained_checked(
    runs: &FeedbackRuns,
    (fixed, found): (&[ScopedEffect], &[ScopedEffect]),
    unexplained: Vec<Unexplained>,
    not_feedback_free: &mut Vec<NotFeedbackFree>,
) -> Vec<Unexplained> {
    let (prepared, options) = (runs.prepared, runs.options);
    if unexplained.is_empty() {
        return unexplained;
    }
    let base: Vec<ScopedEffect> = fixed.iter().chain(found).cloned().collect();
    let at = OperatingPoint::of(&prepared.segments);
    unexplained
        .into_iter()
        .filter(|u| {
            let horizons = Horizons::of(runs.cut(), &base, std::slice::from_ref(&u.scoped));
            let check = feedback::check_each(
                &horizons,
                prepared,
                options,
                &base,
                std::slice::from_ref(&u.scoped),
            )
            .into_iter()
            .next()
            .flatten();
            match check {
                Some(check) if !check.confirmed_there() => {
                    not_feedback_free.push(NotFeedbackFree::of(
                        &u.scoped,
                        check,
                        &at,
                        runs.recording.duration(),
                    ));
                    false
                }
                _ => true,
            }
        })
        .collect()
}

impl NotFeedbackFree {
    /// `scoped`, dropped by `check`, with its sentence at the operating point.
    fn of(scoped: &ScopedEffect, check: FeedbackFree, at: &OperatingPoint, duration: f64) -> Self {
        Self {
            kind: scoped.effect.kind(),
            params: scoped.effect.params().into_iter().collect(),
            sentence: at.sentence(&scoped.effect, duration),
            check,
            undecided: check.undecided(),
            scoped: scoped.clone(),
        }
    }
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
    let (refitted, kept_evidence) =
        kept_refitted(prepared, fixed, &found, evidence, &kept, options);
    (refitted, kept_evidence, not_transferring)
}

/// The effects of `found` at `kept`, refitted together on every segment,
/// and their evidence: what a stage that dropped some hands on.
fn kept_refitted(
    prepared: &Prepared,
    fixed: &[ScopedEffect],
    found: &[ScopedEffect],
    evidence: Vec<Evidence>,
    kept: &[usize],
    options: &Options,
) -> (Vec<ScopedEffect>, Vec<Evidence>) {
    let mut evidence: Vec<Option<Evidence>> = evidence.into_iter().map(Some).collect();
    let kept_effects: Vec<ScopedEffect> = kept.iter().map(|&k| found[k].clone()).collect();
    let kept_evidence: Vec<Evidence> = kept.iter().filter_map(|&k| evidence[k].take()).collect();
    let refitted = if kept_effects.is_empty() {
        kept_effects
    } else {
        fit(
            &prepared.grid,
            &prepared.segments,
            fixed,
            &kept_effects,
            options.max_iters,
        )
        .effects
    };
    (refitted, kept_evidence)
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
        feedback_free: evidence.feedback_free,
        scoped: scoped.clone(),
    }
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

/// Where the run differs from `model` (its residuals' tests by time,
/// place, command and speed), and the residuals' long-run variance factors
/// the tests were divided by.
fn where_it_differs(
    model: &UnicycleModel,
    grid: &CommandGrid,
    segs: &[Segment],
    options: &Options,
) -> (Vec<Located>, [f64; 3]) {
    let residuals = residuals(model, grid, segs);
    let noise = estimate_noise(model, segs, &residuals);
    let z = standardised(model, &noise, segs, &residuals);
    let factors = long_run_factors_of_noise(segs, &z);
    (locate(segs, &z, factors, options.alpha), factors)
}

/// Diagnoses `recording` against the model `given`, less any effect of it
/// that does not hold on the recording (see [`GivenModel`]).
pub fn diagnose(recording: &Recording, given: &UnicycleModel, options: &Options) -> Diagnosis {
    let as_recorded = recording;
    let timed_out = with_timeout(recording, options);
    let (recording, mut command_timeout) = match &timed_out {
        Some((ended, timeout)) => (ended, Some(timeout.clone())),
        None => (recording, None),
    };
    let prepared = prepare(recording, options);
    let (given_model, model, given_run) = match given_model(&prepared, &given.effects, options) {
        Some((report, kept, run)) => (Some(report), UnicycleModel::with_effects(kept), Some(run)),
        None => (None, given.clone(), None),
    };
    let model = &model;
    let (grid, segs) = (&prepared.grid, &prepared.segments);
    let duration = recording.duration();
    let (located, noise_correlation) = where_it_differs(model, grid, segs, options);
    let operating_point = OperatingPoint::of(segs);
    let selection = Selection {
        prepared: &prepared,
        screen: subsample(segs, options.screen_segments),
        fixed: model.effects.clone(),
        usual_speed: operating_point.speed_m_per_s,
        duration,
        options,
    };
    let fixed = &selection.fixed;
    let feedback_runs = FeedbackRuns::new(recording, &prepared, options);
    let (
        Selected {
            found,
            evidence,
            unexplained,
            rejected_heldout,
        },
        Dropped {
            not_transferring,
            mut not_feedback_free,
        },
    ) = through_later_stages(
        &selection,
        &feedback_runs,
        select(&selection, &located, operating_point),
        operating_point,
    );
    let unexplained = unexplained_checked(
        &feedback_runs,
        (fixed, &found),
        unexplained,
        &mut not_feedback_free,
    );

    let stderr = if found.is_empty() {
        Vec::new()
    } else {
        fit(grid, segs, fixed, &found, options.max_iters).stderr
    };
    let mut offset = 0;
    let named: Vec<&'static str> = found.iter().map(|e| e.effect.kind()).collect();
    // A runner-up said beside an effect for how it predicts where no
    // command answered the noise is no explanation where that stage found
    // it the controller's own answer.
    let answered_kinds: Vec<&'static str> = not_feedback_free.iter().map(|d| d.kind).collect();
    let (integration, effects): (Vec<FoundEffect>, Vec<FoundEffect>) = found
        .iter()
        .zip(evidence)
        .map(|(scoped, mut evidence)| {
            // A kind said beside one effect and named in its own right later
            // (it added something there) is a finding, not an alternative.
            evidence.alternatives.retain(|a| {
                let answered =
                    a.where_no_command_answered.is_some() && answered_kinds.contains(&a.kind);
                !named.contains(&a.kind) && !answered
            });
            let count = scoped.effect.params().len();
            let se = &stderr[offset.min(stderr.len())..(offset + count).min(stderr.len())];
            offset += count;
            describe(scoped, se, evidence, duration, operating_point)
        })
        .partition(|e| e.scoped.effect.of_the_recording());
    let final_model = UnicycleModel::with_effects(fixed.iter().chain(&found).cloned().collect());
    // How the recording was made (a simulator's integration step) is found
    // as an effect is, beside the physics it could be taken for, and then
    // held as the recording's: the plain model the physics is measured
    // against, and what the residuals are located on, both move as the
    // recording does.
    let (made, found): (Vec<ScopedEffect>, Vec<ScopedEffect>) =
        found.into_iter().partition(|e| e.effect.of_the_recording());
    let fixed = &fixed.iter().chain(&made).cloned().collect::<Vec<_>>();
    let (located, noise_correlation) = if made.is_empty() {
        (located, noise_correlation)
    } else {
        where_it_differs(
            &UnicycleModel::with_effects(fixed.clone()),
            grid,
            segs,
            options,
        )
    };
    // What the given model's check already held out is the baseline.
    let (baseline, plain_errors, baseline_blocks) = match given_run {
        Some(run) if made.is_empty() => run,
        _ => heldout(&prepared, fixed, &[], options),
    };
    let (improved, improved_errors, improved_blocks) = if found.is_empty() {
        (baseline, plain_errors.clone(), baseline_blocks.clone())
    } else {
        heldout(&prepared, fixed, &found, options)
    };
    // The timeout is a difference the model lacks: how much it explains
    // is the model's held-out error with the commands held, as recorded,
    // against the same with them ended.
    if let Some(timeout) = &mut command_timeout {
        let held = heldout(&prepare(as_recorded, options), fixed, &[], options).0;
        timeout.heldout_rmse_pos_m_held = Some(held.heldout_rmse_pos_m);
        timeout.heldout_rmse_pos_m_ended = Some(baseline.heldout_rmse_pos_m);
    }
    Diagnosis {
        mismatch: !effects.is_empty()
            || !located.is_empty()
            || !unexplained.is_empty()
            || command_timeout.is_some(),
        located,
        integration: integration.into_iter().next(),
        command_timeout,
        effects,
        unexplained,
        residual_covariates: residual_covariates_of(&final_model, grid, segs),
        noise_correlation,
        operating_point,
        pose_outliers: prepared.pose_outliers,
        glitches: prepared.glitches.clone(),
        heading_from_track: prepared.heading_from_track.clone(),
        heading_axis: prepared.heading_axis.clone(),
        rejected_heldout,
        not_transferring,
        not_feedback_free,
        blocks: block_reports(&prepared, &baseline_blocks, &improved_blocks),
        given_model,
        baseline,
        improved,
        segments: segs.len(),
        horizon_s: options.horizon_s,
        segment_s: median_length(segs).unwrap_or(options.horizon_s),
        t_origin: recording.t_origin,
        model: final_model,
        heldout_errors: plain_errors
            .iter()
            .zip(&improved_errors)
            .map(|(&(t, plain), &(_, better))| (t, plain, better))
            .collect(),
    }
}

/// The median of the segments' lengths, in seconds.
fn median_length(segments: &[Segment]) -> Option<f64> {
    let mut lengths: Vec<f64> = segments.iter().map(|s| s.t_end - s.t_start).collect();
    lengths.sort_by(f64::total_cmp);
    lengths.get(lengths.len() / 2).copied()
}

//! The candidates of a round: every effect of the library, effects scoped
//! to the stretches and places where the residuals differ, and the fitting
//! of them all in parallel; then whether the chosen one acts in part of
//! the run only.

use rayon::prelude::*;
use shoal_physics::effects::{EFFECT_KINDS, SPEED_NOISE_EXPONENTS};
use shoal_physics::{CommandGrid, Effect, ScopedEffect};

use crate::fit::{Fitted, fit};
use crate::locate::Located;
use crate::prepared::Options;
use crate::segments::Segment;
use crate::zones::{at_least_min_side, region_driven};

/// Extra parameters for when an effect acts: the cut of a span (fitted,
/// coarse then fine) and which side of it, first or last part of the run.
const SPAN_PARAMS: usize = 2;

/// Extra parameters for where a surface zone acts: its four edges, each
/// moved to where the likelihood is best ([`crate::zones::refine_zone`]).
/// Counted as fewer, a zone fitted to a few odd segments under coloured
/// noise passed a test meant for two factors (EXPERIMENTS.md, "Sim versus
/// real on generators diagnosis was not developed against").
const ZONE_EDGE_PARAMS: usize = 4;

/// `effect` over the whole run as this recording tries it: speed noise
/// stated at the robot's usual speed, a speed limit started above it, a
/// simulator's step bounded by the poses' period.
pub(crate) fn whole_run(effect: Effect, usual_speed: f64, pose_period_s: f64) -> ScopedEffect {
    // A speed limit at the plain model's (none) clamps nothing, and a fit
    // from there has no slope to follow: it starts a little above the
    // robot's usual speed, from where it moves either way.
    let effect = match effect {
        Effect::SpeedLimit { pace_s_per_m } if pace_s_per_m == 0.0 && usual_speed > 0.0 => {
            Effect::SpeedLimit {
                pace_s_per_m: 1.0 / (SPEED_LIMIT_START * usual_speed),
            }
        }
        other => other,
    };
    ScopedEffect::always(
        effect
            .at_reference_speed(usual_speed)
            .within_pose_period(pose_period_s),
    )
}

/// Where a speed limit's fit starts, as a multiple of the robot's usual
/// speed.
const SPEED_LIMIT_START: f64 = 1.3;

pub(crate) fn candidates(
    located: &[Located],
    segments: &[Segment],
    duration: f64,
    usual_speed: f64,
    pose_period_s: f64,
) -> Vec<ScopedEffect> {
    let mut out: Vec<ScopedEffect> = EFFECT_KINDS
        .iter()
        .filter(|k| **k != "surface_zone")
        .filter_map(|k| Effect::identity(k, [0.0; 4]))
        .map(|e| whole_run(e, usual_speed, pose_period_s))
        .collect();
    // Speed-dependent noise under each law beside the identity's (the
    // first); the round ranks them all and keeps the best as the kind's.
    for exponent in SPEED_NOISE_EXPONENTS.into_iter().skip(1) {
        let noise = Effect::SpeedNoise {
            driving_share: 0.0,
            exponent,
            at_m_per_s: 1.0,
        };
        out.push(whole_run(noise, usual_speed, pose_period_s));
    }
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

/// The parameters `candidate` fits: its effect's, and where and when it acts.
pub(crate) fn extra_params(candidate: &ScopedEffect) -> usize {
    let zone = if matches!(candidate.effect, Effect::SurfaceZone { .. }) {
        ZONE_EDGE_PARAMS
    } else {
        0
    };
    let span = if candidate.during.is_some() {
        SPAN_PARAMS
    } else {
        0
    };
    candidate.effect.params().len() + zone + span
}

/// Fits every candidate, in parallel (each fit is independent and
/// deterministic, so the result does not depend on the threads); returns
/// them in the same order.
pub(crate) fn fit_all(
    grid: &CommandGrid,
    segments: &[Segment],
    fixed: &[ScopedEffect],
    candidates: &[ScopedEffect],
    max_iters: u64,
) -> Vec<Fitted> {
    candidates
        .par_iter()
        .map(|candidate| {
            fit(
                grid,
                segments,
                fixed,
                std::slice::from_ref(candidate),
                max_iters,
            )
        })
        .collect()
}

/// An effect found over the whole run may act only in part of it: tries
/// it on the first or last part of the run, split at tenths and then
/// refined, on `screen`; returns the best narrower scope to confirm.
pub(crate) fn narrower_scope(
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
            | Effect::EulerStep { .. }
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

//! Forward selection: round after round the best candidate enters if it
//! passes the entry test, is physical, and predicts held-out blocks better;
//! effects that others do as well without are pruned.

use shoal_physics::{CommandGrid, Effect, ScopedEffect};

use crate::candidates::{candidates, extra_params, fit_all, narrower_scope};
use crate::diagnosis::{Alternative, OperatingPoint, Options, Prepared, Unexplained};
use crate::entry::{EntryTest, calibrated_gain, components_of, entry_test, factors_with};
use crate::fit::{fit, nll_of};
use crate::heldout::{CONTRADICTION_NATS, heldout_gain, must_transfer};
use crate::locate::Located;
use crate::segments::Segment;
use crate::zones::{is_whole_floor, refine_zone, zone_of_span};

/// What selection learned of an effect it accepted.
pub(crate) struct Evidence {
    pub(crate) delta_bic: f64,
    pub(crate) test: EntryTest,
    pub(crate) heldout_gain: f64,
    pub(crate) alternatives: Vec<Alternative>,
}

/// A fitted parameter this close to an edge of its physical range (as a
/// share of the scale on which the parameter matters), where the edge is not
/// the plain model, is the fitter pushing against physics, not a measurement.
pub(crate) const ON_BOUND: f64 = 0.1;

/// Why `scoped`'s fit is not physics, if it ended on an edge of its range.
pub(crate) fn on_bound(scoped: &ScopedEffect) -> Option<String> {
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

/// Every k-th segment, at most `count` of them.
pub(crate) fn subsample(segments: &[Segment], count: usize) -> Vec<Segment> {
    let every = segments.len().div_ceil(count.max(1)).max(1);
    segments.iter().step_by(every).cloned().collect()
}

/// What one round of forward selection decided.
pub(crate) enum Round {
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
pub(crate) struct Selection<'a> {
    pub(crate) prepared: &'a Prepared,
    /// An even subsample of the segments that ranks candidates, so the
    /// cost of a round stops growing with the length of the run.
    pub(crate) screen: Vec<Segment>,
    /// The effects of the model under diagnosis.
    pub(crate) fixed: Vec<ScopedEffect>,
    /// Noise that grows with speed, fitted to the model under diagnosis but
    /// never named by itself (see [`Selection::judged_with`]).
    pub(crate) lens: Option<ScopedEffect>,
    pub(crate) duration: f64,
    pub(crate) options: &'a Options,
}

/// Below this share of the noise from driving, the lens is left out: the
/// noise hardly grows with speed.
pub(crate) const LENS_MIN_SHARE: f64 = 0.05;

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
    pub(crate) fn fit_lens(&mut self) {
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
            entry_test(
                grid,
                segs,
                &judged_base,
                &scoped,
                (delta_bic, long_runs),
                options,
            )
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
            if !entry_test(
                grid,
                segs,
                &self.judged_with(&rest, &found[k]),
                &found[k],
                (needed, long_runs),
                options,
            )
            .passed()
            {
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
pub(crate) struct Selected {
    pub(crate) found: Vec<ScopedEffect>,
    /// What selection learned of each effect in `found`, index for index.
    pub(crate) evidence: Vec<Evidence>,
    pub(crate) unexplained: Vec<Unexplained>,
    pub(crate) rejected_heldout: Vec<&'static str>,
}

/// Forward selection: round after round, the best candidate enters if its
/// fit is physical and it predicts held-out time blocks better.
pub(crate) fn select(selection: &Selection, located: &[Located], at: OperatingPoint) -> Selected {
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

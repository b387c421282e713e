//! Forward selection: round after round the best candidate enters if it
//! passes the entry test, is physical, and predicts held-out blocks better;
//! effects that others do as well without are pruned.

use rayon::prelude::*;
use shoal_physics::effects::EFFECT_KINDS;
use shoal_physics::{CommandGrid, Effect, ScopedEffect};

use crate::candidates::{candidates, extra_params, fit_all, narrower_scope, whole_run};
use crate::entry::{
    EntryTest, calibrated_gain, calibrated_gain_of_move, components_of, entry_test_of_move,
    factors_of, factors_with,
};
use crate::fit::{Fitted, all_but, fit, nll_of};
use crate::heldout::{heldout_gain, heldout_gain_of_joint, holds_out_by};
use crate::likelihood::LongRun;
use crate::locate::Located;
use crate::prepared::{Alternative, OperatingPoint, Options, Prepared, Unexplained};
use crate::segments::Segment;
use crate::zones::{is_whole_floor, refine_zone, zone_of_span};

/// What selection learned of an effect it accepted.
#[derive(Clone)]
pub(crate) struct Evidence {
    pub(crate) delta_bic: f64,
    pub(crate) test: EntryTest,
    pub(crate) heldout_gain: f64,
    pub(crate) alternatives: Vec<Alternative>,
    /// The round's next best of other kinds that lowered BIC alone beside
    /// the same effects (each with its ΔBIC), not said as alternatives: on
    /// a run whose controller answers noise that lasts, their ranking
    /// carries the answer, and the feedback stage compares them where no
    /// command answered it (`diagnosis::rivals_at_horizon`).
    pub(crate) runners_up: Vec<(f64, ScopedEffect)>,
    /// How it predicts where no command answered the noise (set by the
    /// feedback stage; none for noise effects).
    pub(crate) feedback_free: Option<crate::feedback::FeedbackFree>,
}

/// A fitted parameter this close to an edge of its physical range (as a
/// share of the scale on which the parameter matters), where the edge is not
/// the plain model, is the fitter pushing against physics, not a measurement.
pub(crate) const ON_BOUND: f64 = 0.1;

/// Why `scoped`'s fit is not physics, if it ended on an edge of its range.
pub(crate) fn on_bound(scoped: &ScopedEffect) -> Option<String> {
    // A noise effect's range is no physics: its upper edge (a share of
    // 0.99 of the noise growing with speed) says that all of it does, as
    // it does for a body whose noise comes only while it moves. Said as
    // "no effect explains a real mismatch", it read as physics to find
    // (6 of 60 null runs of a waypoint follower seen by positions only).
    if scoped.effect.only_noise() {
        return None;
    }
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

/// How many of a round's next best of other kinds an effect keeps as
/// [`Evidence::runners_up`].
const RUNNERS_UP: usize = 2;

/// What one round of forward selection decided.
pub(crate) enum Round {
    /// No candidate lowers the calibrated BIC enough: selection ends.
    Done,
    /// The best candidate, and the candidates later rounds may still try.
    Chosen {
        chosen: Box<Tested>,
        /// Rival explanations within 2 of BIC.
        tied: Vec<(f64, ScopedEffect)>,
        /// [`Evidence::runners_up`].
        runners_up: Vec<(f64, ScopedEffect)>,
        /// The chosen effect over part of the run, where the run prefers it
        /// by less than a narrower scope must win by and it passes its own
        /// entry test: tried if the whole run fails the held-out check.
        part: Option<Box<Tested>>,
        remaining: Vec<ScopedEffect>,
    },
}

/// An effect with its gain (ΔBIC) and its entry test.
pub(crate) struct Tested {
    pub(crate) effect: ScopedEffect,
    pub(crate) delta_bic: f64,
    pub(crate) test: EntryTest,
}

/// One diagnosis's data and settings, shared by its stages.
pub(crate) struct Selection<'a> {
    pub(crate) prepared: &'a Prepared,
    /// An even subsample of the segments that ranks candidates, so the
    /// cost of a round stops growing with the length of the run.
    pub(crate) screen: Vec<Segment>,
    /// The effects of the model under diagnosis.
    pub(crate) fixed: Vec<ScopedEffect>,
    /// Where speed-dependent noise starts its fit (see [`Selection::lensed`]).
    pub(crate) usual_speed: f64,
    pub(crate) duration: f64,
    pub(crate) options: &'a Options,
}

/// Below this share of the noise from driving, the lens is left out: the
/// noise hardly grows with speed.
pub(crate) const LENS_MIN_SHARE: f64 = 0.05;

/// An effect that explains the run about as well as the one named, with
/// its ΔBIC, if any.
type Equivalent = Option<(f64, ScopedEffect)>;

impl Selection<'_> {
    /// `effects` as tests judge them when `candidate` is tried: with noise
    /// that grows with speed, fitted to these effects, unless they already
    /// have a noise effect or the candidate is one. Mean effects are named
    /// before noise ones (see [`select`]), so without the lens a robot whose
    /// noise grows with its speed would have every candidate judged by a
    /// noise model that weighs its fast, noisy seconds like its slow ones:
    /// its per-segment gains then swing, and one held-out block can seem to
    /// contradict a true effect (feasible generalised least squares:
    /// estimate the variance, then weigh by it). Both models of a test are
    /// weighed through the lens fitted with the candidate: fitted without
    /// it, speed noise takes a mud patch's lost speed for noise, and the
    /// model without the patch would explain the mud as noise.
    fn lensed(&self, effects: &[ScopedEffect], candidate: &ScopedEffect) -> Vec<ScopedEffect> {
        let mut out = effects.to_vec();
        if candidate.effect.only_noise() || effects.iter().any(|e| e.effect.only_noise()) {
            return out;
        }
        let Some(identity) = Effect::identity("speed_noise", [0.0; 4]) else {
            return out;
        };
        let start = whole_run(identity, self.usual_speed, self.prepared.pose_period_s);
        let fitted = fit(
            self.grid(),
            &self.screen,
            effects,
            std::slice::from_ref(&start),
            self.options.max_iters,
        );
        out.extend(fitted.effects.into_iter().filter(|lens| {
            matches!(lens.effect, Effect::SpeedNoise { driving_share, .. } if driving_share > LENS_MIN_SHARE)
        }));
        out
    }

    /// The entry test of the move from `without` to `with` (which adds
    /// `candidate`), each through its own lens.
    fn entry_through_lens(
        &self,
        (without, with): (&[ScopedEffect], &[ScopedEffect]),
        candidate: &ScopedEffect,
        judged: (f64, [LongRun; 3]),
    ) -> EntryTest {
        let lens = self.lens_of(with, candidate);
        let through = |effects: &[ScopedEffect]| -> Vec<ScopedEffect> {
            effects.iter().chain(&lens).cloned().collect()
        };
        entry_test_of_move(
            self.grid(),
            self.segs(),
            (&through(without), &through(with)),
            candidate,
            judged,
            self.options,
        )
    }

    /// The held-out gain of adding `candidate` to `base` (see
    /// [`heldout_gain`]), each model through its own lens.
    fn heldout_through_lens(&self, base: &[ScopedEffect], candidate: &ScopedEffect) -> Vec<f64> {
        let with: Vec<ScopedEffect> = base.iter().cloned().chain([candidate.clone()]).collect();
        let through: Vec<ScopedEffect> = base
            .iter()
            .cloned()
            .chain(self.lens_of(&with, candidate))
            .collect();
        heldout_gain(self.prepared, &through, candidate, self.options)
    }

    /// The lens alone that `lensed` would add to `effects`, if any.
    fn lens_of(&self, effects: &[ScopedEffect], candidate: &ScopedEffect) -> Vec<ScopedEffect> {
        self.lensed(effects, candidate).split_off(effects.len())
    }

    /// [`Selection::entry_through_lens`] of adding `candidate` to `base`.
    fn entry_of(
        &self,
        base: &[ScopedEffect],
        candidate: &ScopedEffect,
        judged: (f64, [LongRun; 3]),
    ) -> EntryTest {
        let with: Vec<ScopedEffect> = base.iter().cloned().chain([candidate.clone()]).collect();
        self.entry_through_lens((base, &with), candidate, judged)
    }

    fn grid(&self) -> &CommandGrid {
        &self.prepared.grid
    }

    fn segs(&self) -> &[Segment] {
        &self.prepared.segments
    }

    /// The plain ΔBIC on the screen of `candidate` fitted to `nll` against
    /// `nll_before` without it: what candidates are ranked by (each
    /// segment's three residual components counted as observations).
    fn screen_delta_bic(&self, nll: f64, nll_before: f64, candidate: &ScopedEffect) -> f64 {
        let screen_log_n = ((3 * self.screen.len()).max(2) as f64).ln();
        2.0 * (nll - nll_before) + extra_params(candidate) as f64 * screen_log_n
    }

    /// The best few candidates of different kinds, by their fit on the
    /// screen (each already fitted there, in `screened`), that lower its
    /// plain BIC. Ranking only: the decision is made on all segments with
    /// calibrated gains.
    fn ranked(
        &self,
        screened: &[Fitted],
        remaining: &[ScopedEffect],
        screen_current: f64,
    ) -> Vec<ScopedEffect> {
        let mut ranked: Vec<(f64, ScopedEffect)> = screened
            .iter()
            .zip(remaining)
            .map(|(f, c)| {
                (
                    self.screen_delta_bic(f.nll, screen_current, c),
                    f.effects[0].clone(),
                )
            })
            .filter(|(g, _)| *g < 0.0)
            .collect();
        ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
        // The best of each kind: variants of one kind (over the whole run,
        // over located spans) would otherwise fill every place, and a kind
        // ranked below them (a rarely visited zone) would never be tested.
        let mut kinds: Vec<&'static str> = Vec::new();
        ranked.retain(|(_, c)| {
            let new_kind = !kinds.contains(&c.effect.kind());
            kinds.push(c.effect.kind());
            new_kind
        });
        ranked.truncate(self.options.confirm);
        tracing::debug!(
            ranked = ?ranked.iter().map(|(g, c)| (c.effect.kind(), *g)).collect::<Vec<_>>(),
            "round: best of each kind on the screen (ΔBIC)"
        );
        let mut top: Vec<ScopedEffect> = ranked.into_iter().map(|(_, c)| c).collect();
        // The laws of speed-dependent noise (per metre driven, in
        // proportion to wheel speed) are different physics, not variants
        // of one: the screen's subsample may rank the wrong one first (a
        // weak per-metre noise on the bench lost its entry test so,
        // EXPERIMENTS.md 5c), so every law of a kept kind is fitted on
        // every segment, and the round keeps the better.
        let other_laws: Vec<ScopedEffect> = screened
            .iter()
            .map(|f| &f.effects[0])
            .filter(|law| {
                top.iter().any(|kept| {
                    kept.effect.kind() == law.effect.kind()
                        && kept.during == law.during
                        && kept.effect.law().is_some()
                        && kept.effect.law() != law.effect.law()
                })
            })
            .cloned()
            .collect();
        top.extend(other_laws);
        top
    }

    /// `top` fitted on every segment beside `base`, zones edge by edge; a
    /// zone over the whole floor is dropped (it is no place).
    fn confirmed(&self, base: &[ScopedEffect], top: &[ScopedEffect]) -> Vec<Fitted> {
        let (grid, segs, options) = (self.grid(), self.segs(), self.options);
        let mut confirmed = fit_all(grid, segs, base, top, options.max_iters / 2);
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
        confirmed.retain(|f| {
            let whole = is_whole_floor(segs, &f.effects[0].effect);
            if whole {
                tracing::debug!(zone = ?f.effects[0].effect, "round: a zone over the whole floor is no place");
            }
            !whole
        });
        confirmed
    }

    /// One round: candidates are ranked on the screen, the best few fitted
    /// on every segment (zones edge by edge) and judged with calibrated
    /// gains; the best may then act in part of the run only.
    fn round(&self, base: &[ScopedEffect], remaining: &[ScopedEffect]) -> Round {
        let (grid, segs, options) = (self.grid(), self.segs(), self.options);
        let base_nll = components_of(grid, segs, base);
        let screen_current = nll_of(grid, &self.screen, base);
        let screened = fit_all(grid, &self.screen, base, remaining, options.max_iters);
        let top = self.ranked(&screened, remaining, screen_current);
        let confirmed = self.confirmed(base, &top);
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
        tracing::debug!(
            judged = ?judged.iter().map(|(g, c)| (c.effect.kind(), *g, c.effect.params())).collect::<Vec<_>>(),
            factors = ?factors,
            "round: confirmed on every segment, judged with the long-run factors (ΔBIC)"
        );
        let (passing, tied_in_part) = match self.first_passing(base, &judged, long_runs) {
            Some(passing) => (passing, Vec::new()),
            None => match self.passing_in_part(base, &judged, long_runs, &judge) {
                Some(found) => found,
                None => return Round::Done,
            },
        };
        let (
            Passing {
                index,
                tested:
                    Tested {
                        effect: chosen,
                        delta_bic,
                        test,
                    },
                long_runs,
            },
            equivalent,
            beside,
        ) = self.encompassing(base, &judged, passing);
        // Explanations within 2 of BIC are not worth more than a bare
        // mention apart (Kass and Raftery): one finding, with alternatives
        // among those ranked after it (those before it failed their test).
        let mut tied: Vec<(f64, ScopedEffect)> = judged[index + 1..]
            .iter()
            .filter(|(g, c)| *g < delta_bic + 2.0 && c.effect.kind() != chosen.effect.kind())
            .cloned()
            .chain(equivalent)
            .chain(tied_in_part)
            .collect();
        let (scoped, delta_bic, unchosen_part) =
            self.scoped(base, chosen.clone(), delta_bic, &judge, &mut tied);
        let test = if scoped == chosen {
            test
        } else {
            self.entry_of(base, &scoped, (delta_bic, long_runs))
        };
        let part = unchosen_part.and_then(|(effect, delta_bic)| {
            let test = self.part_entry(
                base,
                &effect,
                (delta_bic, long_runs),
                "the chosen, in reserve if the whole run fails held out",
            );
            test.passed().then(|| {
                Box::new(Tested {
                    effect,
                    delta_bic,
                    test,
                })
            })
        });
        let chosen = scoped;
        let tied_kinds: Vec<&'static str> = tied.iter().map(|(_, c)| c.effect.kind()).collect();
        let runners_up = judged
            .iter()
            .filter(|(g, c)| {
                let kind = c.effect.kind();
                *g < 0.0
                    && kind != chosen.effect.kind()
                    && !tied_kinds.contains(&kind)
                    && beside.as_ref().is_none_or(|b| b.1.effect.kind() != kind)
                    && on_bound(c).is_none()
            })
            .take(RUNNERS_UP)
            .cloned()
            .collect();
        // Said beside, but free to enter later: it added nothing beside the
        // chosen on its own, and may beside what enters next (a drift over
        // the part of the run a bias does not cover). Named later, it is
        // no longer said as an alternative (`diagnosis::diagnose`).
        if let Some(beside) = beside
            && !tied_kinds.contains(&beside.1.effect.kind())
        {
            tied.push(beside);
        }
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
            chosen: Box::new(Tested {
                effect: chosen,
                delta_bic,
                test,
            }),
            tied,
            runners_up,
            part,
            remaining,
        }
    }

    /// The best-ranked of `judged` (gain, candidate) that passes the entry
    /// test, with its index, gain, test and long-run factors (the first
    /// candidate's are `first_long_runs`). Each kind is tested at the level
    /// corrected for all the library's kinds, so one that ranks first and
    /// fails does not keep the next from its test (a rarely visited zone
    /// that explains more than a turn gain, but fails, left the turn gain's
    /// failure to end the diagnosis).
    fn first_passing(
        &self,
        base: &[ScopedEffect],
        judged: &[(f64, ScopedEffect)],
        first_long_runs: [LongRun; 3],
    ) -> Option<Passing> {
        let (grid, segs) = (self.grid(), self.segs());
        for (index, (delta_bic, candidate)) in judged.iter().enumerate() {
            let long_runs = if index == 0 {
                first_long_runs
            } else {
                factors_with(grid, segs, base, candidate)
            };
            let test = self.entry_of(base, candidate, (*delta_bic, long_runs));
            tracing::debug!(
                kind = candidate.effect.kind(),
                rank = index,
                delta_bic,
                chi2 = test.chi2,
                needed = test.needed,
                passed = test.passed(),
                "round: candidate"
            );
            if test.passed() {
                return Some(Passing {
                    index,
                    tested: Tested {
                        effect: candidate.clone(),
                        delta_bic: *delta_bic,
                        test,
                    },
                    long_runs,
                });
            }
        }
        None
    }

    /// When every candidate fails over the whole run, the best of them may
    /// still act in part of it: a legged robot that walked onto sand 13 s
    /// into a 90 s run loses 46% of its stride there, and over the whole
    /// run that mismatch is diluted below the test (robot 14 of a demo
    /// recording: χ² 11.2 where 11.9 is needed), while nothing is located
    /// in time to try it scoped. The best is tried over the first or last
    /// part of the run and faces the entry test with the span's two
    /// parameters counted, and after it the held-out and feedback stages,
    /// as every effect named. Returns it with what `scoped` tied to it.
    fn passing_in_part(
        &self,
        base: &[ScopedEffect],
        judged: &[(f64, ScopedEffect)],
        long_runs: [LongRun; 3],
        judge: &impl Fn(&ScopedEffect) -> f64,
    ) -> Option<(Passing, Vec<(f64, ScopedEffect)>)> {
        let (whole_bic, best) = judged.first()?;
        let mut tied = Vec::new();
        let (candidate, delta_bic, _) =
            self.scoped(base, best.clone(), *whole_bic, judge, &mut tied);
        if candidate == *best {
            return None;
        }
        let test = self.part_entry(
            base,
            &candidate,
            (delta_bic, long_runs),
            "the best, failed over the whole run",
        );
        test.passed().then(|| {
            let passing = Passing {
                index: 0,
                tested: Tested {
                    effect: candidate,
                    delta_bic,
                    test,
                },
                long_runs,
            };
            (passing, tied)
        })
    }

    /// The entry test of `part`, an effect over part of the run gaining
    /// `delta_bic`, logged with `which` it is.
    fn part_entry(
        &self,
        base: &[ScopedEffect],
        part: &ScopedEffect,
        (delta_bic, long_runs): (f64, [LongRun; 3]),
        which: &'static str,
    ) -> EntryTest {
        let test = self.entry_of(base, part, (delta_bic, long_runs));
        tracing::debug!(
            which,
            kind = part.effect.kind(),
            during = ?part.during,
            delta_bic,
            chi2 = test.chi2,
            needed = test.needed,
            passed = test.passed(),
            "round: tried over part of the run"
        );
        test
    }

    /// The passing candidate, or a rival that encompasses it. Two kinds can
    /// explain one mismatch alike over the conditions a run holds: a marker
    /// off the axle (a turning-centre offset) and speed lost in turns are
    /// one curve in the along residual while the robot turns one way only,
    /// and opposite curves when it turns the other way. Ranked by ΔBIC
    /// alone, the one the run's noise favours is named, and on a stretch that
    /// turned left only, the offset was: it predicted the robot's other
    /// stretches worse than no model at all (EXPERIMENTS.md 6b, "Physics
    /// that transfers", eight blocks). The encompassing principle of
    /// non-nested model choice settles it: the chosen effect must add
    /// something the entry test accepts beside each rival that passes alone
    /// (the two refitted together); a rival that encompasses it and adds
    /// beside it what it lacks is named instead; of two that encompass each
    /// other, a rival with fewer parameters is named and the chosen listed
    /// as explaining the run about as well, and with as many the chosen
    /// stays and the rival is listed, whatever their ΔBIC apart: a turn
    /// bias and a heading drift on a robot that seldom stops differ by a
    /// few of ΔBIC, and neither adds beside the other.
    /// Returns the one named, the equivalent it was named over, and the
    /// equivalent named beside (each with its ΔBIC), as alternatives.
    fn encompassing(
        &self,
        base: &[ScopedEffect],
        judged: &[(f64, ScopedEffect)],
        passing: Passing,
    ) -> (Passing, Equivalent, Equivalent) {
        /// Rivals tried beside the chosen: the next best of other kinds.
        const RIVALS: usize = 2;
        let chosen = &passing.tested.effect;
        let (grid, segs) = (self.grid(), self.segs());
        let rivals = judged
            .iter()
            .enumerate()
            .skip(passing.index + 1)
            .filter(|(_, (g, c))| *g < 0.0 && c.effect.kind() != chosen.effect.kind())
            .take(RIVALS);
        let mut equal = None;
        for (index, (rival_bic, rival)) in rivals {
            if self.adds_beside(base, chosen, rival) {
                continue;
            }
            let rival_adds = self.adds_beside(base, rival, chosen);
            let simpler = extra_params(rival) < extra_params(chosen);
            tracing::debug!(
                chosen = chosen.effect.kind(),
                rival = rival.effect.kind(),
                rival_adds,
                simpler,
                "round: the chosen adds nothing beside a rival"
            );
            let rival_runs = factors_with(grid, segs, base, rival);
            let rival_test = self.entry_of(base, rival, (*rival_bic, rival_runs));
            if !rival_test.passed() {
                continue;
            }
            if !rival_adds && !simpler {
                // Neither adds beside the other: the data cannot tell them
                // apart, however far apart their ΔBIC, so the rival is said.
                equal.get_or_insert((*rival_bic, rival.clone()));
                continue;
            }
            let equivalent = (!rival_adds).then(|| (passing.tested.delta_bic, chosen.clone()));
            let rival = Passing {
                index,
                tested: Tested {
                    effect: rival.clone(),
                    delta_bic: *rival_bic,
                    test: rival_test,
                },
                long_runs: rival_runs,
            };
            return (rival, equivalent, None);
        }
        (passing, None, equal)
    }

    /// Whether `candidate` adds what the entry test accepts beside `other`
    /// (already fitted beside `base`), the two refitted together.
    fn adds_beside(
        &self,
        base: &[ScopedEffect],
        candidate: &ScopedEffect,
        other: &ScopedEffect,
    ) -> bool {
        let (grid, segs, options) = (self.grid(), self.segs(), self.options);
        let rest: Vec<ScopedEffect> = base.iter().cloned().chain([other.clone()]).collect();
        let pair = fit(
            grid,
            segs,
            base,
            &[other.clone(), candidate.clone()],
            options.max_iters / 2,
        );
        let joint: Vec<ScopedEffect> = base.iter().cloned().chain(pair.effects.clone()).collect();
        self.entry_of_move(&rest, &joint, &pair.effects[1])
            .1
            .passed()
    }

    /// The calibrated ΔBIC and entry test of the move from `without` to
    /// `with`, which adds `candidate` and may have refitted the rest: the
    /// long-run factors are `with`'s residuals'.
    fn entry_of_move(
        &self,
        without: &[ScopedEffect],
        with: &[ScopedEffect],
        candidate: &ScopedEffect,
    ) -> (f64, EntryTest) {
        let (grid, segs) = (self.grid(), self.segs());
        let long_runs = factors_of(grid, segs, with);
        let factors = long_runs.map(|l| l.factor);
        let without_nll = components_of(grid, segs, without);
        let delta_bic = calibrated_gain_of_move(grid, segs, without_nll, with, candidate, factors);
        let test = self.entry_through_lens((without, with), candidate, (delta_bic, long_runs));
        (delta_bic, test)
    }

    /// An effect may act in part of the run only. Trying that is not left
    /// to the locating tests alone: the held-out check that follows keeps a
    /// narrower scope from fitting noise. A robot that drives into a zone
    /// and stays there shows a change in time that is as much a change in
    /// place, so the region it drove in over that span is tried as a zone.
    /// Where the whole run is kept but BIC prefers the best part, if by less
    /// than a narrower scope must win by, the part is returned beside it
    /// with its gain, for the held-out check to try if the whole run fails.
    fn scoped(
        &self,
        base: &[ScopedEffect],
        chosen: ScopedEffect,
        delta_bic: f64,
        judge: &impl Fn(&ScopedEffect) -> f64,
        tied: &mut Vec<(f64, ScopedEffect)>,
    ) -> (ScopedEffect, f64, Option<(ScopedEffect, f64)>) {
        let (grid, segs, options) = (self.grid(), self.segs(), self.options);
        let Some(scoped) =
            narrower_scope(grid, &self.screen, base, &chosen, self.duration, options)
        else {
            return (chosen, delta_bic, None);
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
        tracing::debug!(
            kind = scoped_fit.effect.kind(),
            during = ?scoped_fit.during,
            part = scoped_gain,
            whole = delta_bic,
            "round: the best part of the run against the whole run (ΔBIC)"
        );
        if !self.part_beats_whole(scoped_gain, delta_bic) {
            // The part is kept in reserve only where the run prefers it,
            // its span's parameters paid: a part that merely leaves out
            // the block of noise that contradicts the whole run's fit (a
            // slip "from 0 to 525 s" of a 600 s run) is not.
            let reserve = (scoped_gain < delta_bic).then_some((scoped_fit, scoped_gain));
            return (chosen, delta_bic, reserve);
        }
        if let Some(zone) = zone_of_span(segs, &scoped_fit)
            && let Some(zone_effect) = Effect::identity("surface_zone", zone)
        {
            let (zone_fit, _) = confirm(&ScopedEffect::always(zone_effect));
            let zone_fit = refine_zone(grid, segs, base, zone_fit, options.max_iters / 2);
            let zone_gain = judge(&zone_fit);
            if zone_gain < scoped_gain + 2.0 && !is_whole_floor(segs, &zone_fit.effect) {
                tied.push((scoped_gain, scoped_fit));
                return (zone_fit, zone_gain, None);
            }
        }
        (scoped_fit, scoped_gain, None)
    }

    /// Whether an effect over part of the run, gaining `part` (ΔBIC, lower
    /// is better), beats it over the whole run, gaining `whole`, by enough
    /// (`min_scope_bic_gain`) to say it acts only there.
    fn part_beats_whole(&self, part: f64, whole: f64) -> bool {
        part < whole - self.options.min_scope_bic_gain
    }

    /// The entry test of `found[k]` as the move from the others, refitted
    /// without it, to `found` as fitted together; with the others' refit.
    fn entry_beside_others(
        &self,
        found: &[ScopedEffect],
        k: usize,
    ) -> (Vec<ScopedEffect>, (f64, EntryTest)) {
        let (grid, segs, options, fixed) = (self.grid(), self.segs(), self.options, &self.fixed);
        let refit = fit(grid, segs, fixed, &all_but(found, k), options.max_iters).effects;
        let rest: Vec<ScopedEffect> = fixed.iter().chain(&refit).cloned().collect();
        let joint: Vec<ScopedEffect> = fixed.iter().chain(found).cloned().collect();
        let entry = self.entry_of_move(&rest, &joint, &found[k]);
        (refit, entry)
    }

    /// Refits `found` together, then drops any effect the others, refitted,
    /// do as well without (a turn scale standing in for steering play, once
    /// the play joined); `evidence` follows index for index. Each effect is
    /// judged by the move from the others refitted without it to the joint
    /// fit, the test an effect entering beside them faces: the joint value
    /// of one effect added to the others' refit without it is no model the
    /// data were fitted to, and judged that way a turn loss the others
    /// only half absorb was dropped although it entered again at once.
    fn refit_and_prune(&self, found: &mut Vec<ScopedEffect>, evidence: &mut Vec<Evidence>) {
        let (grid, segs, options, fixed) = (self.grid(), self.segs(), self.options, &self.fixed);
        *found = fit(grid, segs, fixed, found, options.max_iters * 2).effects;
        let mut k = 0;
        while found.len() >= 2 && k < found.len() {
            let (refit, (needed, test)) = self.entry_beside_others(found, k);
            if !test.passed() {
                tracing::debug!(
                    kind = found[k].effect.kind(),
                    chi2 = test.chi2,
                    needed = test.needed,
                    delta_bic = needed,
                    "pruned: the others do as well"
                );
                *found = refit;
                evidence.remove(k);
            } else {
                k += 1;
            }
        }
    }
}

/// What one step of the completion pass did.
enum CompletionStep {
    /// The best kind beside the named effects entered, and pruning ran.
    Entered,
    /// The best kind was passed over unjudged, as the twin of an effect a
    /// later stage refused: the next kind is tried.
    PassedOver,
    /// Nothing more enters: the pass ends.
    Done,
}

/// A completion's candidate fitted beside the named effects, and its entry.
struct Completion {
    /// The named effects as refitted beside it.
    joint: Vec<ScopedEffect>,
    tested: Tested,
    /// Everything the prediction holds with it: the fixed effects, `joint`
    /// and the candidate.
    with: Vec<ScopedEffect>,
}

impl Completion {
    /// Whether it may enter: it passes its test and fits inside its
    /// physical range.
    fn enters(&self) -> bool {
        self.tested.test.passed() && on_bound(&self.tested.effect).is_none()
    }
}

/// A round's candidate that passed its entry test: its index among those
/// judged, it with its calibrated ΔBIC and test, and the residuals' long
/// runs with it.
struct Passing {
    index: usize,
    tested: Tested,
    long_runs: [LongRun; 3],
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
/// The held-out gain of adding `chosen` to `base`, if it holds out
/// (`heldout::holds_out_by`).
fn holds_out(selection: &Selection, base: &[ScopedEffect], chosen: &ScopedEffect) -> Option<f64> {
    let gains = selection.heldout_through_lens(base, chosen);
    let held = holds_out_by(&gains, chosen);
    tracing::debug!(
        kind = chosen.effect.kind(),
        ?gains,
        held = held.is_some(),
        "round: held out"
    );
    held
}

pub(crate) fn select(selection: &Selection, located: &[Located], at: OperatingPoint) -> Selected {
    let segs = selection.segs();
    let mut out = Selected::default();
    // Where the robot goes is explained first, how noisy it is after: a
    // mismatch of the mean (mud, a drift) otherwise passes for noise that
    // grows with speed, and the noise model it leaves behind then judges
    // the true explanation unlikely (feasible GLS orders them the same way).
    let (mean_candidates, noise_candidates): (Vec<ScopedEffect>, Vec<ScopedEffect>) = candidates(
        located,
        segs,
        selection.duration,
        selection.usual_speed,
        selection.prepared.pose_period_s,
    )
    .into_iter()
    .filter(|c| selection.prepared.can_show(c.effect.kind()))
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
                tied,
                runners_up,
                part,
                remaining: next,
            } = selection.round(&base, &remaining)
            else {
                break;
            };
            remaining = next;
            if let Some(reason) = on_bound(&chosen.effect) {
                let Tested {
                    effect, delta_bic, ..
                } = *chosen;
                out.unexplained.push(Unexplained {
                    tried: effect.effect.kind(),
                    params: effect.effect.params().into_iter().collect(),
                    reason: format!(
                        "{reason}; the mismatch is real (BIC {delta_bic:.0}) but no effect of the library explains it within physical limits"
                    ),
                    scoped: effect,
                });
                continue;
            }
            // A whole-run effect the held-out blocks contradict may act in
            // part of the run only: a turn bias from the middle of the run,
            // under coloured noise, gains too little over its half to be
            // chosen over the whole run, and the blocks before it then
            // contradict the whole run's fit. Its part, which passed its
            // own entry test, faces the same held-out check.
            let kind = chosen.effect.effect.kind();
            let heldout = holds_out(selection, &base, &chosen.effect)
                .map(|gain| (*chosen, gain))
                .or_else(|| {
                    let part = part.filter(|p| on_bound(&p.effect).is_none())?;
                    holds_out(selection, &base, &part.effect).map(|gain| (*part, gain))
                });
            let Some((
                Tested {
                    effect: chosen,
                    delta_bic,
                    test,
                },
                gain_heldout,
            )) = heldout
            else {
                out.rejected_heldout.push(kind);
                continue;
            };
            out.found.push(chosen);
            out.evidence.push(Evidence {
                feedback_free: None,
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
                        where_no_command_answered: None,
                    })
                    .collect(),
                runners_up,
            });
            selection.refit_and_prune(&mut out.found, &mut out.evidence);
        }
    }
    // Each kind is tried once: one that pruning then drops is not tried
    // again. Then no effect stays only because of the order it entered in.
    if !out.found.is_empty() {
        selection.completed(&mut out, at, (&[], &[]));
        selection.widened(&mut out);
        selection.swap_each(&mut out, at, (&[], &[]));
    }
    out
}

/// The effects a later stage kept, judged again without the ones it
/// dropped: an effect that entered beside a dropped one was tested against
/// a model that is no longer the diagnosis (a turning-centre offset that
/// entered beside an actuator lag, which the feedback stage then dropped,
/// where the simulator's Euler step would have explained both). They are
/// pruned against one another, the completion pass runs again with the
/// dropped kinds barred (from none, where a later stage dropped every
/// effect: the kinds it did not drop still get their chance), and each is
/// taken out in turn (`swap_each`).
pub(crate) fn reselected(
    selection: &Selection,
    found: Vec<ScopedEffect>,
    evidence: Vec<Evidence>,
    (barred, refused): (&[&'static str], &[ScopedEffect]),
    at: OperatingPoint,
) -> Selected {
    let mut out = Selected {
        found,
        evidence,
        ..Selected::default()
    };
    if !out.found.is_empty() {
        selection.refit_and_prune(&mut out.found, &mut out.evidence);
    }
    selection.completed(&mut out, at, (barred, refused));
    selection.widened(&mut out);
    selection.swap_each(&mut out, at, (barred, refused));
    out
}

impl Selection<'_> {
    /// The completion pass run on `out` until no kind enters, the `barred`
    /// kinds not tried, nor a kind that adds nothing beside an effect a
    /// later stage `refused`: that is the refused effect under another name
    /// (a latency where an actuator lag was dropped as the controller's).
    fn completed(
        &self,
        out: &mut Selected,
        at: OperatingPoint,
        (barred, refused): (&[&'static str], &[ScopedEffect]),
    ) {
        let mut tried = barred.to_vec();
        while out.found.len() < self.options.max_effects
            && !matches!(
                self.complete(out, at, &mut tried, refused),
                CompletionStep::Done
            )
        {}
    }

    /// BIC of `found` fitted on every segment, beside the fixed effects.
    fn bic_of(&self, found: &[ScopedEffect]) -> f64 {
        let (grid, segs, options, fixed) = (self.grid(), self.segs(), self.options, &self.fixed);
        let nll = if found.is_empty() {
            nll_of(grid, segs, fixed)
        } else {
            fit(grid, segs, fixed, found, options.max_iters).nll
        };
        self.bic_at(found, nll)
    }

    /// BIC of `found` where its fit on every segment reached `nll`.
    fn bic_at(&self, found: &[ScopedEffect], nll: f64) -> f64 {
        let params: usize = found.iter().map(extra_params).sum();
        2.0 * nll + params as f64 * (self.segs().len() as f64).ln()
    }

    /// Each effect named over part of the run tried again over the whole
    /// run, once the set is complete: whether it acts only there was judged
    /// beside the effects named before it, and an effect that entered
    /// before its partner can take part of it. A fading battery fitted
    /// before a turn scale takes some of the turn's loss, fades too fast,
    /// and leaves the turn scale a span where it beats the whole run; a
    /// speed scale over the later part then makes up for the fade on the
    /// speed (EXPERIMENTS.md 5c, "An effect scoped beside one that
    /// entered before it"). With the set complete the scope is judged by the rule a
    /// round judges it by (`part_beats_whole`), the others refitted beside
    /// the whole run; the widened effect must pass its entry test and hold
    /// out as one entering would, and pruning then drops what it made
    /// redundant.
    fn widened(&self, out: &mut Selected) {
        let (grid, segs, options, fixed) = (self.grid(), self.segs(), self.options, &self.fixed);
        if out.found.iter().all(|e| e.during.is_none()) {
            return;
        }
        let mut current = self.bic_of(&out.found);
        let mut k = 0;
        while k < out.found.len() {
            if out.found[k].during.is_none() {
                k += 1;
                continue;
            }
            let mut trial = out.found.clone();
            trial[k].during = None;
            let fitted = fit(grid, segs, fixed, &trial, options.max_iters);
            let whole_bic = self.bic_at(&fitted.effects, fitted.nll);
            let trial = fitted.effects;
            let widens = !self.part_beats_whole(current, whole_bic);
            tracing::debug!(
                kind = trial[k].effect.kind(),
                during = ?out.found[k].during,
                part = current,
                whole = whole_bic,
                widens,
                "widen: a scoped effect over the whole run, the set complete"
            );
            if !widens {
                k += 1;
                continue;
            }
            let (_, (delta_bic, test)) = self.entry_beside_others(&trial, k);
            let others = all_but(&trial, k);
            let gains = heldout_gain_of_joint(self.prepared, fixed, &others, &trial[k], options);
            let held = holds_out_by(&gains, &trial[k]);
            tracing::debug!(
                kind = trial[k].effect.kind(),
                delta_bic,
                passed = test.passed(),
                ?gains,
                held = held.is_some(),
                "widen: the whole run's entry"
            );
            let Some(heldout_gain) = held.filter(|_| test.passed()) else {
                k += 1;
                continue;
            };
            out.evidence[k].delta_bic = delta_bic;
            out.evidence[k].test = test;
            out.evidence[k].heldout_gain = heldout_gain;
            out.found = trial;
            self.refit_and_prune(&mut out.found, &mut out.evidence);
            current = self.bic_of(&out.found);
            k = 0;
        }
    }

    /// Each effect of `out` taken out in turn, the others refitted, and the
    /// completion pass run from them; whichever set explains the run better
    /// by BIC on every segment is kept. Forward selection admits an effect
    /// beside what is named when it enters, so the order decides what a
    /// later effect is judged against: a surface zone of 106% speed and
    /// turn over most of the floor entered before a speed scale and a turn
    /// scale (one effect against two), a second zone took the rest of the
    /// floor, and pruning dropped the scales; and once a later stage has
    /// dropped an effect, one admitted beside it may stand where another
    /// kind, never tried without it, explains as much. What the round
    /// judged the taken effect's equal (its alternatives) is not tried in
    /// its place: the encompassing rule chose between them, and says both.
    fn swap_each(
        &self,
        out: &mut Selected,
        at: OperatingPoint,
        (barred, refused): (&[&'static str], &[ScopedEffect]),
    ) {
        let (grid, segs, options, fixed) = (self.grid(), self.segs(), self.options, &self.fixed);
        let kinds = |found: &[ScopedEffect]| -> Vec<&'static str> {
            let mut kinds: Vec<_> = found.iter().map(|e| e.effect.kind()).collect();
            kinds.sort_unstable();
            kinds
        };
        let mut current = self.bic_of(&out.found);
        let mut k = 0;
        while k < out.found.len() {
            let taken = out.found[k].effect.kind();
            let others = all_but(&out.found, k);
            // A kind the round judged the taken effect's equal does not
            // replace it: which of two equals is named was decided there, by
            // the encompassing rule, with both said.
            let not_tried: Vec<&'static str> = barred
                .iter()
                .copied()
                .chain(out.evidence[k].alternatives.iter().map(|a| a.kind))
                .collect();
            // Tried only where another kind ranks above the one taken out
            // beside the others (`best_beside` frees them beside each kind,
            // so they need no refit first). Where it still ranks first the
            // completion pass would start by putting it back; going on from
            // there can still end elsewhere (a zone and speed-dependent
            // noise give way to the two scales on one controller run), but
            // doing it for every effect doubled the run time (EXPERIMENTS.md
            // 5c, "Each named effect taken out in turn").
            if self
                .best_beside(&others, at, &not_tried)
                .is_some_and(|best| best.effect.kind() == taken)
            {
                k += 1;
                continue;
            }
            let mut trial = Selected {
                found: if others.is_empty() {
                    others
                } else {
                    fit(grid, segs, fixed, &others, options.max_iters).effects
                },
                evidence: all_but(&out.evidence, k),
                ..Selected::default()
            };
            self.completed(&mut trial, at, (&not_tried, refused));
            // The same kinds back is the same set: no fit on every segment.
            let better = (kinds(&trial.found) != kinds(&out.found))
                .then(|| self.bic_of(&trial.found))
                .filter(|b| *b < current);
            tracing::debug!(
                taken,
                into = ?kinds(&trial.found),
                swapped = better.is_some(),
                "swap: one taken out, the completion run from the others"
            );
            if let Some(lower) = better {
                out.rejected_heldout.extend(trial.rejected_heldout);
                out.found = trial.found;
                out.evidence = trial.evidence;
                current = lower;
                k = 0;
            } else {
                k += 1;
            }
        }
    }

    /// The kind of the library, not named in `found` and not yet `tried`,
    /// that fits best with `found` free beside it, ranked on the screen as
    /// a round's candidates are; none if none lowers the screen's BIC.
    fn best_beside(
        &self,
        found: &[ScopedEffect],
        at: OperatingPoint,
        tried: &[&'static str],
    ) -> Option<ScopedEffect> {
        let (grid, options, fixed) = (self.grid(), self.options, &self.fixed);
        let named: Vec<&str> = found.iter().map(|e| e.effect.kind()).collect();
        let without: Vec<ScopedEffect> = fixed.iter().chain(found).cloned().collect();
        let screen_without = nll_of(grid, &self.screen, &without);
        // Ranked by ΔBIC on the screen, as a round ranks: by the likelihood
        // alone a kind of two parameters outranked the one-parameter kind
        // that explained as much, failed its entry test, and ended the pass.
        let candidates: Vec<ScopedEffect> = EFFECT_KINDS
            .iter()
            .filter(|k| **k != "surface_zone" && !named.contains(k) && !tried.contains(k))
            .filter(|k| self.prepared.can_show(k))
            .filter_map(|k| Effect::identity(k, [0.0; 4]))
            .filter(|e| !e.only_noise())
            .map(|e| whole_run(e, at.speed_m_per_s, self.prepared.pose_period_s))
            .collect();
        // Each kind is fitted with every named effect free beside it: the
        // costliest fits of a diagnosis, independent of one another, so in
        // parallel; the best is then chosen in the library's order.
        let scored: Vec<(f64, ScopedEffect)> = candidates
            .into_par_iter()
            .map(|c| {
                let together: Vec<ScopedEffect> =
                    found.iter().cloned().chain([c.clone()]).collect();
                let nll = fit(grid, &self.screen, fixed, &together, options.max_iters).nll;
                (self.screen_delta_bic(nll, screen_without, &c), c)
            })
            .collect();
        scored
            .into_iter()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .filter(|(gain, _)| *gain < 0.0)
            .map(|(_, c)| c)
    }

    /// Effects that act together. A round fits its candidate with the
    /// effects already named held where they fitted alone, and two effects
    /// that act together can hide each other there: a turn gain fitted
    /// alone takes the mean of a turn gain and a fading battery, and the
    /// fade then no longer fits beside it (a speed gain over part of the
    /// run stands in for it). So after the rounds, each kind of the library
    /// not yet named is fitted once more with the named effects free beside
    /// it; the best enters on the same entry test and held-out check as in a
    /// round, judged against the named effects as they were, and pruning
    /// then drops what it makes redundant.
    fn complete(
        &self,
        out: &mut Selected,
        at: OperatingPoint,
        tried: &mut Vec<&'static str>,
        refused: &[ScopedEffect],
    ) -> CompletionStep {
        let (grid, segs) = (self.grid(), self.segs());
        if segs.len() < 20 {
            return CompletionStep::Done;
        }
        let Some(best) = self.best_beside(&out.found, at, tried) else {
            return CompletionStep::Done;
        };
        tried.push(best.effect.kind());
        let base: Vec<ScopedEffect> = self.fixed.iter().chain(&out.found).cloned().collect();
        if let Some(twin) = refused.iter().find(|r| !self.adds_beside(&base, &best, r)) {
            tracing::debug!(
                kind = best.effect.kind(),
                refused = twin.effect.kind(),
                "completion: adds nothing beside a refused effect"
            );
            return CompletionStep::PassedOver;
        }
        let Some(whole) = self.completion_entry(&out.found, &best) else {
            return CompletionStep::Done;
        };
        // As in a round, the effect may act in part of the run only (a
        // turn bias in the first third, fitted to the whole run, was
        // contradicted by the blocks after it and never named): the part
        // is tried on the screen and kept if it enters and beats the whole
        // run on every segment (`part_beats_whole`); and as in a round, it
        // is tried too when the whole run fails its test, where the part
        // is diluted by the rest.
        let refitted: Vec<ScopedEffect> = self.fixed.iter().chain(&whole.joint).cloned().collect();
        let narrower = narrower_scope(
            grid,
            &self.screen,
            &refitted,
            &whole.tested.effect,
            self.duration,
            self.options,
        )
        .and_then(|scoped| self.completion_entry(&out.found, &scoped))
        .filter(|part| {
            part.enters() && self.part_beats_whole(part.tested.delta_bic, whole.tested.delta_bic)
        });
        let chosen = match narrower {
            Some(part) => part,
            None if whole.enters() => whole,
            None => return CompletionStep::Done,
        };
        let Completion {
            joint,
            tested:
                Tested {
                    effect: candidate,
                    delta_bic,
                    test,
                },
            with,
        } = chosen;
        let through: Vec<ScopedEffect> = self
            .fixed
            .iter()
            .cloned()
            .chain(self.lens_of(&with, &candidate))
            .collect();
        let gains = heldout_gain_of_joint(
            self.prepared,
            &through,
            &out.found,
            &candidate,
            self.options,
        );
        tracing::debug!(
            kind = candidate.effect.kind(),
            during = ?candidate.during,
            ?gains,
            "completion: held out"
        );
        let Some(heldout_gain) = holds_out_by(&gains, &candidate) else {
            out.rejected_heldout.push(candidate.effect.kind());
            return CompletionStep::Done;
        };
        out.found = joint;
        out.found.push(candidate);
        out.evidence.push(Evidence {
            feedback_free: None,
            delta_bic,
            test,
            heldout_gain,
            alternatives: Vec::new(),
            runners_up: Vec::new(),
        });
        self.refit_and_prune(&mut out.found, &mut out.evidence);
        CompletionStep::Entered
    }

    /// `candidate` fitted beside the named `found` (all free), and its
    /// entry test against `found` as they were (see [`Completion::enters`]).
    fn completion_entry(
        &self,
        found: &[ScopedEffect],
        candidate: &ScopedEffect,
    ) -> Option<Completion> {
        let (grid, segs, options, fixed) = (self.grid(), self.segs(), self.options, &self.fixed);
        let together: Vec<ScopedEffect> =
            found.iter().cloned().chain([candidate.clone()]).collect();
        let without: Vec<ScopedEffect> = fixed.iter().chain(found).cloned().collect();
        let mut joint = fit(grid, segs, fixed, &together, options.max_iters).effects;
        let candidate = joint.pop()?;
        let with: Vec<ScopedEffect> = fixed
            .iter()
            .chain(&joint)
            .chain([&candidate])
            .cloned()
            .collect();
        let (delta_bic, test) = self.entry_of_move(&without, &with, &candidate);
        tracing::debug!(
            kind = candidate.effect.kind(),
            during = ?candidate.during,
            delta_bic,
            passed = test.passed(),
            on_bound = on_bound(&candidate).is_some(),
            "completion: best beside the named"
        );
        Some(Completion {
            joint,
            tested: Tested {
                effect: candidate,
                delta_bic,
                test,
            },
            with,
        })
    }
}

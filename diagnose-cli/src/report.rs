//! The report a person reads: printed, and the diagnosis recording's document.

use shoal_diagnose::Diagnosis;
use shoal_diagnose::diagnosis::FoundEffect;
use shoal_diagnose::feedback::Confirmation;
use shoal_diagnose::glitches::{Glitch, GlitchKind, seconds_set_aside};
use shoal_diagnose::locate::Located;
use shoal_diagnose_lab::experiment::Row;

use crate::load::InputNotes;

/// Below this corrected p-value a residual covariate is reported as one
/// the residuals still follow.
const SIGNIFICANT: f64 = 0.01;

/// The report a person reads: printed, and the recording's document.
/// Each effect named, with the test that let it in and the alternatives the
/// data cannot tell from it; then what the residuals still follow.
fn effects_text(d: &Diagnosis) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = |text: String| lines.push(text);
    for e in &d.effects {
        line(format!(
            "  {} ({}; p {:.1e} after correcting for the library's kinds; ΔBIC {:.0})",
            e.sentence,
            entry_test_text(e),
            e.test.p_adjusted,
            e.delta_bic
        ));
        if let Some(check) = &e.feedback_free {
            // An effect named is confirmed (`Diagnosis` keeps no other), so
            // `None` cannot reach here; it says nothing rather than panic.
            let size = match check.confirmation() {
                Some(Confirmation::Shown) | None => String::new(),
                Some(Confirmation::BeyondFeedback) => format!(
                    "; not confirmed there, but it moves the prediction by {:.1} noise standard deviations, more than a controller's answer to the noise can",
                    check.size_in_noise
                ),
                Some(Confirmation::OpenLoopUncontradicted) => {
                    "; not confirmed there, nor contradicted, and no command answers the pose (the residuals do not predict the next command), so the longer segments' gain holds no controller's answer".to_string()
                }
            };
            line(format!(
                "    where no command answered the noise (held out on {:.2} s segments): {:+.1} nats, z {:.1} ({:.2} needed{}; a real effect of its size: about {:+.1}){size}",
                check.horizon_s,
                check.gain,
                check.z,
                check.z_needed,
                check.lasting_allowance_words(),
                check.expected_gain
            ));
        }
        // An effect the data cannot tell from another is one finding with
        // both fits, never a choice made silently.
        for a in &e.alternatives {
            line(match a.where_no_command_answered {
                None => format!(
                    "    these data explain it about as well (ΔBIC {:.0} against {:.0}) as: {}",
                    a.delta_bic, e.delta_bic, a.sentence
                ),
                Some(z) => format!(
                    "    or, where no command answered the noise, about as well (z {z:.1} for it; ranked ΔBIC {:.0} against {:.0} on segments the controller's answer weighs in): {}",
                    a.delta_bic, e.delta_bic, a.sentence
                ),
            });
        }
    }
    let following: Vec<String> = d
        .residual_covariates
        .iter()
        .filter(|c| c.significance < SIGNIFICANT)
        .map(|c| {
            format!(
                "{} residual with {} (r {:+.2}, p {:.1e})",
                c.component, c.covariate, c.correlation, c.significance
            )
        })
        .collect();
    if !following.is_empty() {
        line(format!(
            "What is left still follows: {}.",
            following.join("; ")
        ));
    }
    lines
}

/// The entry test that let `e` in, as the report states it.
fn entry_test_text(e: &FoundEffect) -> String {
    format!(
        "χ² {:.1} on {} parameters, {:.1} needed at {}",
        e.test.chi2, e.test.dof, e.test.needed, e.test.level
    )
}

/// What an effect of `kind` is, as a noun a sentence can list.
fn effect_noun(kind: &str) -> String {
    match kind {
        "latency" => "a response delay (latency)",
        "actuator_lag" => "an actuator lag",
        "speed_scale" => "a speed scale",
        "turn_scale" => "a turn scale",
        "turn_bias" => "a turn bias",
        "heading_drift" => "a heading drift",
        "accel_limit" => "an acceleration limit",
        "speed_limit" => "a speed limit",
        "slip" => "slip growing with speed",
        "battery_fade" => "a fading battery",
        "surface_zone" => "a surface zone",
        "external_flow" => "an external flow (wind, current or a slope)",
        "hysteresis" => "a steering play",
        "speed_noise" => "noise growing with speed",
        "turn_speed_loss" => "speed lost in turns",
        "turn_centre_offset" => "a turning-centre offset",
        "crab_angle" => "a crab angle",
        "euler_step" => "an integration step",
        other => return other.replace('_', " "),
    }
    .to_owned()
}

/// Whether a difference was located in the motion (along, across or
/// heading), not only in the size of the noise.
fn motion_differs(d: &Diagnosis) -> bool {
    d.located.iter().any(in_motion)
}

/// A difference located in the motion, not only in the residuals' spread.
fn in_motion(l: &Located) -> bool {
    l.component != "spread"
}

/// The report's first line, and the JSON's `summary`: what the diagnosis
/// found, in one sentence, so that a reader knows before the evidence what
/// it is evidence for.
pub fn headline(d: &Diagnosis) -> String {
    let motion_differs = motion_differs(d);
    // An effect on the noise alone moves no prediction: said apart.
    let (moving, noise): (Vec<&FoundEffect>, Vec<&FoundEffect>) = d
        .effects
        .iter()
        .partition(|e| !e.scoped.effect.only_noise());
    let nouns = |effects: &[&FoundEffect]| -> Vec<String> {
        effects
            .iter()
            .map(|e| {
                let mut noun = effect_noun(e.kind);
                if !e.alternatives.is_empty() {
                    let others: Vec<String> =
                        e.alternatives.iter().map(|a| effect_noun(a.kind)).collect();
                    noun.push_str(&format!(
                        " (or {}: the data cannot tell them apart)",
                        others.join(" or ")
                    ));
                }
                noun
            })
            .collect()
    };
    let (named, noise) = (nouns(&moving), nouns(&noise));
    let undecided = undecided_nouns(d);
    let undecided_words = || {
        format!(
            "{} may explain the motion, but a controller steering on the pose could make {} too, and this recording cannot tell them apart (below)",
            undecided.join(" or "),
            if undecided.len() == 1 { "it" } else { "them" }
        )
    };
    let and_noise = if noise.is_empty() {
        String::new()
    } else {
        format!("; beside the motion, its noise: {}", noise.join("; "))
    };
    let (before, after) = (
        d.baseline.heldout_rmse_pos_m * 1e3,
        d.improved.heldout_rmse_pos_m * 1e3,
    );
    if !d.mismatch {
        return "In short: no significant mismatch; the model explains the run within its noise."
            .into();
    }
    if !named.is_empty() {
        let lower = if before > 0.0 {
            let change = 100.0 * (1.0 - after / before);
            if change >= 0.0 {
                format!(" ({change:.0}% lower)")
            } else {
                format!(" ({:.0}% higher)", -change)
            }
        } else {
            String::new()
        };
        let and_undecided = if undecided.is_empty() {
            String::new()
        } else {
            format!("; undecided: {}", undecided_words())
        };
        return format!(
            "In short: {} named: {}; with {} the held-out position error goes {before:.1} -> {after:.1} mm{lower}{and_noise}{and_undecided}.",
            match named.len() {
                1 => "one effect".to_owned(),
                n => format!("{n} effects"),
            },
            named.join("; "),
            if named.len() == 1 { "it" } else { "them" },
        );
    }
    if !undecided.is_empty() {
        return format!(
            "In short: no effect confirmed; {}{and_noise}.",
            undecided_words()
        );
    }
    if !noise.is_empty() && !motion_differs {
        return format!(
            "In short: the motion matches the model; its noise differs: {}.",
            noise.join("; ")
        );
    }
    if motion_differs || !d.unexplained.is_empty() {
        return "In short: the motion differs from the model, but no effect of the library explains it (where, below).".into();
    }
    if d.command_timeout.is_some() {
        return "In short: the robot stops when its commands pause (below); beside that, the motion matches the model.".into();
    }
    "In short: the motion matches the model; only the size of its noise differs.".into()
}

pub fn report_text(d: &Diagnosis, notes: &InputNotes) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    // Writing into a String cannot fail.
    let mut line = |text: String| {
        let _ = writeln!(out, "{text}");
    };
    let motion_differs = motion_differs(d);
    line(headline(d));
    let pose_chain = notes
        .clock
        .as_ref()
        .and_then(|c| c.pose_chain.as_ref())
        .map(|chain| format!("Poses: {chain}."));
    for text in clock_text(notes)
        .into_iter()
        .chain(notes.units.iter().map(|note| format!("Units: {note}.")))
        .chain(notes.order.iter().map(|note| format!("Order: {note}.")))
        .chain(
            notes
                .dropouts
                .iter()
                .map(|note| format!("Dropouts: {note}.")),
        )
        .chain(pose_chain)
        .chain(set_aside_text(&d.glitches))
        .chain(
            d.heading_axis
                .as_ref()
                .map(|how| format!("Headings: {}.", how.sentence())),
        )
        .chain(
            d.heading_from_track
                .as_ref()
                .map(|how| format!("Headings: {}.", how.sentence())),
        )
    {
        line(text);
    }
    line(if (d.segment_s - d.horizon_s).abs() < 0.05 {
        format!("{} segments of {:.1} s compared.", d.segments, d.horizon_s)
    } else {
        format!(
            "{} segments of {:.1} s compared (from one observed pose to another, as near {:.1} s apart as the poses allow).",
            d.segments, d.segment_s, d.horizon_s
        )
    });
    if let Some(timeout) = &d.command_timeout {
        line(format!(
            "How the robot took its commands: {}",
            timeout.sentence()
        ));
    }
    if let Some(made) = &d.integration {
        line(format!(
            "How the recording was made: {} ({}; ΔBIC {:.0}). The plain model below steps so too; what follows is measured against it.",
            made.sentence,
            entry_test_text(made),
            made.delta_bic
        ));
    }
    let nothing_more = !motion_differs
        && d.effects.is_empty()
        && d.unexplained.is_empty()
        && !d.not_feedback_free.iter().any(|n| n.undecided);
    // No mismatch is said by the headline alone.
    if d.mismatch && nothing_more && d.command_timeout.is_some() {
        line(if d.located.is_empty() {
            "Beside the timeout, the model explains the run within its noise.".into()
        } else {
            "Beside the timeout, the motion matches the model. Only the size of its noise differs:"
                .into()
        });
    } else if d.mismatch && nothing_more {
        line("The motion matches the model: no difference in where the robot went. Only the size of its noise differs:".into());
    }
    // A difference in the residuals' spread is about the noise, not the
    // motion: said as such, apart from the differences in the motion.
    let (motion, noise): (Vec<&Located>, Vec<&Located>) =
        d.located.iter().take(8).partition(|l| in_motion(l));
    for l in motion {
        line(format!("  differs by {}", located_text(l)));
    }
    // Said before the effects only where nothing else is: beside effects,
    // the noise's size is the least of what a reader came for.
    let noise_lines: Vec<String> = noise
        .iter()
        .map(|l| format!("  by {}", located_text(l)))
        .collect();
    if nothing_more {
        noise_lines.iter().cloned().for_each(&mut line);
    }
    if motion_differs && d.effects.is_empty() {
        line("The mismatch is significant but no effect of the library explains it.".into());
    }
    for u in &d.unexplained {
        line(format!("  not explained: tried {}: {}", u.tried, u.reason));
    }
    for text in effects_text(d) {
        line(text);
    }
    for text in transfer_text(d).into_iter().chain(feedback_text(d)) {
        line(text);
    }
    if !nothing_more && !noise.is_empty() {
        line("Where the size of the noise differs (not the motion):".into());
        noise_lines.into_iter().for_each(&mut line);
    }
    line(format!(
        "Held-out position error {:.1} mm -> {:.1} mm, heading {:.2} -> {:.2} deg, NLL {:.2} -> {:.2} per segment.",
        d.baseline.heldout_rmse_pos_m * 1e3,
        d.improved.heldout_rmse_pos_m * 1e3,
        d.baseline.heldout_rmse_theta_rad.to_degrees(),
        d.improved.heldout_rmse_theta_rad.to_degrees(),
        d.baseline.heldout_nll,
        d.improved.heldout_nll
    ));
    if let Some(text) = given_model_text(d) {
        line(text);
    }
    out
}

/// What the report says of a given model (`--model`) that predicts the
/// recording worse than the plain model.
fn given_model_text(d: &Diagnosis) -> Option<String> {
    let given = d.given_model.as_ref().filter(|g| g.worse_than_plain)?;
    let without: Vec<String> = given
        .not_holding
        .iter()
        .map(|n| {
            format!(
                "without its {} it predicts {:.1} mm",
                n.kind.replace('_', " "),
                n.heldout_rmse_pos_m_without * 1e3
            )
        })
        .collect();
    let which = if without.is_empty() {
        String::new()
    } else {
        format!(" ({})", without.join("; "))
    };
    let set_aside = if given.set_aside.is_empty() {
        String::new()
    } else {
        let kinds: Vec<String> = given
            .set_aside
            .iter()
            .map(|kind| kind.replace('_', " "))
            .collect();
        format!(
            " Its {} set aside and the recording diagnosed against the rest ({:.1} mm held out).",
            kinds.join(" and ") + if kinds.len() == 1 { " was" } else { " were" },
            d.baseline.heldout_rmse_pos_m * 1e3
        )
    };
    Some(format!(
        "The model given predicts this recording worse than the plain model: {:.1} mm against {:.1} mm held out. Physics fitted elsewhere does not hold here{which}.{set_aside} Diagnose the recordings together to keep what transfers.",
        given.given.heldout_rmse_pos_m * 1e3,
        given.plain.heldout_rmse_pos_m * 1e3,
    ))
}

/// A located difference: where, when, under which commands, how strong.
fn located_text(l: &Located) -> String {
    let place = l
        .region
        .map(|r| {
            format!(
                " in [{:.1}, {:.1}]-[{:.1}, {:.1}] m",
                r[0], r[1], r[2], r[3]
            )
        })
        .unwrap_or_default();
    format!(
        "{}: {:.0}-{:.0} s{place}, {} ({} residual, z {:.1}, p {:.1e})",
        l.family, l.t_start, l.t_end, l.commands, l.component, l.z, l.significance
    )
}

fn capitalised(text: &str) -> String {
    let mut chars = text.chars();
    chars
        .next()
        .map(|c| c.to_uppercase().chain(chars).collect())
        .unwrap_or_default()
}

/// One sentence per kind of stretch set aside: how many, when, how large.
fn set_aside_text(glitches: &[Glitch]) -> Option<String> {
    if glitches.is_empty() {
        return None;
    }
    let mut parts = Vec::new();
    for kind in GlitchKind::ALL {
        let of: Vec<&Glitch> = glitches.iter().filter(|g| g.kind == kind).collect();
        let (Some(first), Some(last)) = (of.first(), of.last()) else {
            continue;
        };
        let frames: usize = of.iter().map(|g| g.frames).sum();
        let largest = of
            .iter()
            .max_by(|a, b| a.size_m.total_cmp(&b.size_m))
            .map(|g| g.size_text())
            .unwrap_or_default();
        let times: Vec<String> = of
            .iter()
            .take(5)
            .map(|g| format!("{:.1} s", g.t_start))
            .collect();
        parts.push(format!(
            "{} ({}{}, from {:.1} to {:.1} s: {}{})",
            kind.describe(of.len()),
            if frames > 0 {
                format!("{frames} poses")
            } else {
                "no poses".to_owned()
            },
            if largest.is_empty() {
                largest
            } else {
                format!(", up to {largest}")
            },
            first.t_start,
            last.t_end,
            times.join(", "),
            if of.len() > 5 { ", ..." } else { "" }
        ));
    }
    Some(format!(
        "Set aside before fitting, as not the body's own motion: {}; {:.1} s in all.",
        parts.join("; "),
        seconds_set_aside(glitches)
    ))
}

/// Which clock a bag's topics were compared on, why, and what it means.
fn clock_text(notes: &InputNotes) -> Option<String> {
    let clock = notes.clock.as_ref()?;
    Some(format!(
        "Clock: {} timed by {}, {} by {}: {}. {}.",
        clock.commands_topic,
        clock.commands,
        clock.poses_topic,
        clock.poses,
        clock.reason,
        capitalised(&clock.delay)
    ))
}

/// What was dropped as a controller's feedback rather than physics.
fn feedback_text(d: &Diagnosis) -> Vec<String> {
    let mut out: Vec<String> = d
        .not_feedback_free
        .iter()
        .map(|n| {
            let status = if n.undecided {
                "undecided, it or a controller steering on the pose"
            } else {
                "dropped, a controller steering on the pose can make it"
            };
            format!(
                "  {status}: {} ({})",
                n.sentence.trim_end_matches('.'),
                n.check.why_unconfirmed()
            )
        })
        .collect();
    if d.not_feedback_free.iter().any(|n| n.undecided) {
        out.push("  To tell them apart, record a stretch driven open loop (commands not chosen from the pose, e.g. a fixed sequence of speeds and turns) and diagnose it.".into());
    }
    out
}

/// The nouns of the effects the feedback stage could not tell from the
/// controller's answer.
fn undecided_nouns(d: &Diagnosis) -> Vec<String> {
    d.not_feedback_free
        .iter()
        .filter(|n| n.undecided)
        .map(|n| effect_noun(n.kind))
        .collect()
}

/// What did not transfer between the held-out stretches, and how each
/// stretch was predicted.
fn transfer_text(d: &Diagnosis) -> Vec<String> {
    let mut out: Vec<String> = d
        .not_transferring
        .iter()
        .map(|n| {
            format!(
                "  dropped, it does not transfer: {} (with it the held-out stretch {:.0}-{:.0} s was predicted worse than without)",
                n.sentence, n.block_t_start, n.block_t_end
            )
        })
        .collect();
    if d.blocks.len() > 1 {
        let each: Vec<String> = d
            .blocks
            .iter()
            .map(|b| {
                format!(
                    "{:.0}-{:.0} s {:.1} -> {:.1} mm",
                    b.t_start,
                    b.t_end,
                    b.input_rmse_pos_m * 1e3,
                    b.fitted_rmse_pos_m * 1e3
                )
            })
            .collect();
        out.push(format!(
            "Each stretch held out in turn (fitted on the others): {}.",
            each.join("; ")
        ));
    }
    out
}

/// The experiment's rows as a Markdown table, then the totals per generator.
pub fn experiment_table(out: &mut dyn std::io::Write, rows: &[Row]) -> std::io::Result<()> {
    use shoal_diagnose_lab::experiment::wilson_interval;
    let percent = |[lo, hi]: [f64; 2]| format!("{:.0}-{:.0}%", lo * 100.0, hi * 100.0);
    writeln!(
        out,
        "| generator | noise | case | concealed | runs | shown by the run | named | named or tied | runs naming an effect not there (95% CI) | beyond the noise (95% CI) | param error | held-out pos RMSE before → after | s/run |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|---|---|")?;
    for r in rows {
        writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.0}% | {:.0}% | {:.0}% | {:.0}% ({}) | {:.0}% ({}) | {} | {:.1} → {:.1} mm | {:.1} |",
            r.generator,
            r.noise,
            r.name,
            r.concealment,
            r.runs,
            r.shown_rate * 100.0,
            r.detection_rate * 100.0,
            r.named_or_tied_rate * 100.0,
            r.false_positive_rate * 100.0,
            percent(r.false_positive_interval),
            r.beyond_noise_rate * 100.0,
            percent(r.beyond_noise_interval),
            r.param_error
                .map_or("-".into(), |e| format!("{:.0}%", e * 100.0)),
            r.heldout_rmse_pos_m_before * 1e3,
            r.heldout_rmse_pos_m_after * 1e3,
            r.seconds_per_run
        )?;
    }
    // The totals the floors are stated in: effects named, runs
    // naming one not there, null runs saying more than the noise.
    writeln!(out)?;
    writeln!(
        out,
        "| generator | concealed effects named | named or tied | shown by the run (truth passes the entry test) | named where shown | runs naming an effect not there (95% CI) | null runs beyond the noise (95% CI) | counted by effect (a run of two counts two) |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|")?;
    let mut generators: Vec<&str> = rows.iter().map(|r| r.generator.as_str()).collect();
    generators.dedup();
    for generator in generators {
        let of: Vec<_> = rows.iter().filter(|r| r.generator == generator).collect();
        let count = |f: &dyn Fn(&Row) -> f64, nulls: bool| {
            of.iter()
                .filter(|r| (r.name == "null") == nulls)
                .map(|r| (f(r) * r.runs as f64).round() as usize)
                .sum::<usize>()
        };
        let (effect_runs, null_runs) = (count(&|_| 1.0, false), count(&|_| 1.0, true));
        let all_runs = effect_runs + null_runs;
        let shown = count(&|r| r.shown_rate, false);
        let named_where_shown = count(&|r| r.shown_rate * r.named_when_shown_rate, false);
        let false_positive =
            count(&|r| r.false_positive_rate, false) + count(&|r| r.false_positive_rate, true);
        let beyond = count(&|r| r.beyond_noise_rate, true);
        let share =
            |k: usize, n: usize| format!("{k} of {n} ({:.0}%)", 100.0 * k as f64 / n.max(1) as f64);
        writeln!(
            out,
            "| {generator} | {} | {} | {} | {} | {}, {} | {}, {} | {} |",
            share(count(&|r| r.detection_rate, false), effect_runs),
            share(count(&|r| r.named_or_tied_rate, false), effect_runs),
            share(shown, effect_runs),
            share(named_where_shown, shown),
            share(false_positive, all_runs),
            percent(wilson_interval(false_positive, all_runs)),
            share(beyond, null_runs),
            percent(wilson_interval(beyond, null_runs)),
            share(
                of.iter().map(|r| r.effects_named).sum(),
                of.iter().map(|r| r.effects_concealed).sum()
            ),
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn glitch(kind: GlitchKind, t_start: f64, t_end: f64) -> Glitch {
        Glitch {
            kind,
            t_start,
            t_end,
            frames: 10,
            size_m: 0.5,
        }
    }

    #[test]
    fn the_time_set_aside_counts_overlapping_stretches_once() {
        let text = set_aside_text(&[
            glitch(GlitchKind::PoseGap, 10.0, 14.0),
            glitch(GlitchKind::HeldInPlace, 12.0, 20.0),
            glitch(GlitchKind::HeldInPlace, 30.0, 31.5),
        ])
        .expect("a sentence");
        assert!(text.ends_with("; 11.5 s in all."), "{text}");
        assert!(text.contains("2 stops while driving"), "{text}");
        assert!(set_aside_text(&[]).is_none());
    }
}

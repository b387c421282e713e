//! An effect found beside the ones already named may act in part of the run
//! only: the completion pass tries that part, as a round does.

use shoal_diagnose_lab::experiment::diagnosed_run;

/// The turn bias named in run `seed` of `generator`'s `turn_bias` case
/// under `noise`: its span, its rate (rad/s) and its sentence. Panics if
/// it is not named, or named for the whole run.
fn turn_bias_named(generator: &str, noise: &str, seed: u64) -> ([f64; 2], f64, String) {
    let diagnosis = diagnosed_run(generator, "turn_bias", noise, seed).expect("a known run");
    let bias = diagnosis.effect("turn_bias").unwrap_or_else(|| {
        panic!(
            "the turn bias is named: {:?}",
            diagnosis.effects.iter().map(|e| e.kind).collect::<Vec<_>>()
        )
    });
    let during = bias
        .scoped
        .during
        .unwrap_or_else(|| panic!("named for part of the run: {}", bias.sentence));
    (during, bias.params["rad_per_s"], bias.sentence.clone())
}

/// The slow teleoperated robot (`speed-only`), a turn bias of -0.02 rad/s in
/// the first 200 s of 600, coloured noise that grows with speed: the bias
/// of run `seed` must be named for that third.
fn first_third_bias_named(seed: u64) {
    let ([from, to], rate, sentence) = turn_bias_named("speed-only", "ou-2s", seed);
    assert!(
        from < 20.0 && (150.0..250.0).contains(&to),
        "the first third (0-200 s): {sentence}"
    );
    assert!((rate + 0.02).abs() < 0.007, "{sentence}");
}

#[test]
fn a_turn_bias_in_the_first_third_found_beside_the_noise_is_named_for_that_third() {
    // The bias enters only beside the speed-dependent noise (the
    // completion pass); fitted to the whole run, the blocks after 200 s
    // contradicted it and it went unnamed (EXPERIMENTS.md 5c).
    first_third_bias_named(1000);
}

#[test]
fn a_part_of_the_run_is_tried_when_the_whole_run_fails_beside_the_noise() {
    // Here the bias fitted to the whole run fails its entry test beside the
    // noise (ΔBIC -0.8, diluted by the 400 s without it), and the pass
    // ended with nothing named; over its part it enters at ΔBIC -31.
    first_third_bias_named(1001);
}

#[test]
fn a_part_the_run_prefers_is_named_when_the_whole_run_is_contradicted_held_out() {
    // The bench's turn bias of 0.015 rad/s in the second half of the run,
    // under coloured noise (seed 1002). Over the whole run it enters (ΔBIC
    // -13.9); from 360 s it does better (-19.8), but not by the 10 of BIC a
    // narrower scope must win by to be chosen, and the whole run's fit was
    // then contradicted by the first held-out block (-18.9 nats): nothing
    // was named. The part, which the run prefers, is tried held out in turn.
    let ([from, to], rate, sentence) = turn_bias_named("bench", "ou-2s", 1002);
    assert!(
        (250.0..400.0).contains(&from) && to > 580.0,
        "the second half (300-600 s): {sentence}"
    );
    assert!((rate - 0.015).abs() < 0.007, "{sentence}");
}

#[test]
fn an_effect_scoped_beside_one_that_entered_before_it_is_tried_over_the_whole_run_again() {
    // A battery fading 1.2% a minute and a turn scale of 0.93 on the slow
    // teleoperated robot, white noise (seed 1000). The fade entered first,
    // took part of the turn's loss (0.019 a minute), and left the turn
    // scale a span, 0-345 s, where it beat the whole run by 36 of BIC; a
    // speed scale of 1.05 from 135 s, not there, then made up for the
    // fade's excess on the speed. Once the set is complete the turn scale
    // is tried over the whole run again, the others refitted beside it
    // (EXPERIMENTS.md 5c, "An effect scoped beside one that entered before it").
    let diagnosis =
        diagnosed_run("speed-only", "battery_fade+turn_scale", "white", 1000).expect("a known run");
    let kinds: Vec<&str> = diagnosis.effects.iter().map(|e| e.kind).collect();
    let turn = diagnosis
        .effect("turn_scale")
        .unwrap_or_else(|| panic!("the turn scale is named: {kinds:?}"));
    assert!(
        turn.scoped.during.is_none(),
        "the turn scale acts over the whole run: {}",
        turn.sentence
    );
    assert!(
        (turn.params["factor"] - 0.93).abs() < 0.015,
        "{}",
        turn.sentence
    );
    let fade = diagnosis
        .effect("battery_fade")
        .unwrap_or_else(|| panic!("the fade is named: {kinds:?}"));
    assert!(
        (fade.params["per_minute"] - 0.012).abs() < 0.004,
        "{}",
        fade.sentence
    );
    assert!(
        !kinds.contains(&"speed_scale"),
        "no speed scale that is not there: {kinds:?}"
    );
}

//! An effect found beside the ones already named may act in part of the run
//! only: the completion pass tries that part, as a round does.

use shoal_diagnose_lab::experiment::diagnosed_run;

#[test]
fn a_turn_bias_in_the_first_third_found_beside_the_noise_is_named_for_that_third() {
    // The slow teleoperated robot (`speed-only`), a turn bias of -0.02
    // rad/s in the first 200 s of 600, coloured noise that grows with
    // speed. The bias enters only beside the speed-dependent noise (the
    // completion pass); fitted to the whole run, the blocks after 200 s
    // contradicted it and it went unnamed (EXPERIMENTS.md 5c).
    let diagnosis = diagnosed_run("speed-only", "turn_bias", "ou-2s", 1000).expect("a known run");
    let bias = diagnosis.effect("turn_bias").unwrap_or_else(|| {
        panic!(
            "the turn bias is named: {:?}",
            diagnosis.effects.iter().map(|e| e.kind).collect::<Vec<_>>()
        )
    });
    let [from, to] = bias
        .scoped
        .during
        .unwrap_or_else(|| panic!("named for part of the run: {}", bias.sentence));
    assert!(
        from < 20.0 && (150.0..250.0).contains(&to),
        "the first third (0-200 s): {}",
        bias.sentence
    );
    let rate = bias.params["rad_per_s"];
    assert!((rate + 0.02).abs() < 0.007, "{}", bias.sentence);
}

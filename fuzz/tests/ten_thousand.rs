//! The CI share of the fuzzing: 10^4 generated inputs per parser and per bus
//! check (EXPERIMENTS.md has 10^6 each: `shoal-fuzz --inputs 1000000`).

use shoal_fuzz::{Seeds, Target, fuzz};

#[test]
fn ten_thousand_inputs_per_target_neither_panic_nor_get_an_unclear_error() {
    let seeds = Seeds::new().expect("every seed builds");
    for target in Target::ALL {
        let report = fuzz(target, 10_000, 1, &seeds);
        assert!(report.passed(), "{report:#?}");
        // The generators must reach past the first check: some inputs pass.
        assert!(
            report.accepted > 0,
            "no input was ever accepted: {report:#?}"
        );
        assert!(
            report.rejected > 0,
            "no input was ever rejected: {report:#?}"
        );
    }
}

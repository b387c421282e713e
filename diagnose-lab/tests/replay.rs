//! The replay of a diagnosis draws exactly what the likelihood scored.

use shoal_diagnose::diagnosis::{Options, prepare};
use shoal_diagnose::likelihood::residuals;
use shoal_diagnose::replay::{SegmentReplay, replay};
use shoal_diagnose_lab::generate::{Settings, generate};
use shoal_physics::{Effect, ScopedEffect, UnicycleModel};

#[test]
fn the_replay_predicts_what_diagnosis_scored() {
    let truth = UnicycleModel::with_effects(vec![ScopedEffect::always(Effect::SpeedScale {
        factor: 0.8,
    })]);
    let recording = generate(
        &truth,
        &Settings {
            duration_s: 60.0,
            ..Settings::default()
        },
    );
    let options = Options::default();
    let segments = replay(&recording, &UnicycleModel::plain(), &truth, &options);
    assert!(segments.len() > 30, "{} segments", segments.len());

    // The ends are exactly the residuals the likelihood scores.
    let prepared = prepare(&recording, &options);
    let scored = residuals(&truth, &prepared.grid, &prepared.segments);
    for (s, r) in segments.iter().zip(&scored) {
        assert_eq!(&s.fitted.residual, r);
    }
    // A path runs from the segment's start to its end, a pose a step.
    let s = &segments[10];
    assert_eq!(s.input.t.first(), Some(&s.t_start));
    assert!((s.input.t.last().copied().unwrap_or(0.0) - s.t_end).abs() < 1e-6);
    assert_eq!(s.input.t.len(), s.input.path.len());
    // The plain model overshoots a body that drives at 80%: its along
    // residual is negative and far larger than the true model's.
    let mean_along =
        |f: fn(&SegmentReplay) -> f64| segments.iter().map(f).sum::<f64>() / segments.len() as f64;
    let input = mean_along(|s| s.input.residual[0]);
    let fitted = mean_along(|s| s.fitted.residual[0]);
    assert!(input < -0.005, "plain along residual {input}");
    assert!(
        fitted.abs() < input.abs() / 5.0,
        "fitted {fitted} vs plain {input}"
    );
}

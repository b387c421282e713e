//! What the residuals still follow once the effects found are in the model.
//!
//! A mismatch no effect of the library explains is still worth a clue: if
//! the heading residual follows the turn rate, or the spread of the
//! residuals follows speed, an engineer knows where to look. Each residual
//! component is correlated with each quantity the run records, and each
//! correlation is tested with an effective sample size, so that coloured
//! noise does not make chance correlations look strong.

use serde::Serialize;
use statrs::distribution::{ContinuousCDF, Normal};

use crate::segments::Segment;

/// One residual component's correlation with one recorded quantity.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Covariate {
    /// `along`, `across`, `heading`, or `spread` (the size of all three).
    pub component: &'static str,
    pub covariate: &'static str,
    /// Pearson's correlation over the segments.
    pub correlation: f64,
    /// Holm-corrected over every pair tried.
    pub significance: f64,
}

/// A quantity of segment `i`.
type OfSegment = fn(&[Segment], usize) -> f64;

/// The quantities residuals are correlated with, by name.
const COVARIATES: [(&str, OfSegment); 9] = [
    ("commanded speed", |s, i| s[i].speed),
    ("commanded turn rate", |s, i| s[i].turn),
    ("size of the turn rate", |s, i| s[i].turn.abs()),
    ("change of commanded speed", |s, i| {
        previous(s, i).map_or(0.0, |p| s[i].speed - s[p].speed)
    }),
    ("time", |s, i| s[i].t_start),
    ("x", |s, i| s[i].mid[0]),
    ("y", |s, i| s[i].mid[1]),
    ("heading (east-west)", |s, i| s[i].start.theta.cos()),
    ("heading (north-south)", |s, i| s[i].start.theta.sin()),
];

/// The segment just before `i`, if it ends where `i` starts.
fn previous(segments: &[Segment], i: usize) -> Option<usize> {
    let p = i.checked_sub(1)?;
    (segments[p].to == segments[i].from).then_some(p)
}

/// The `count` strongest correlations of the standardised residuals with
/// the recorded quantities, strongest evidence first.
///
/// `long_run` (per component, as from
/// `likelihood::long_run_factors_of_noise`) divides the sample size: the
/// variance of a sample correlation between two series inflates by
/// `1 + 2 sum_k rho_x(k) rho_y(k)` (Bartlett), at most the residual's own
/// long-run factor when the other series is smoother than it, as speed,
/// time and place are. Fisher's z then gives the p-value.
pub fn strongest(
    segments: &[Segment],
    standardised: &[[f64; 3]],
    long_run: [f64; 3],
    count: usize,
) -> Vec<Covariate> {
    let n = segments.len().min(standardised.len());
    if n < 20 {
        return Vec::new();
    }
    let spread_factor = long_run.iter().sum::<f64>() / 3.0;
    let components: [(&str, Vec<f64>, f64); 4] = [
        (
            "along",
            (0..n).map(|i| standardised[i][0]).collect(),
            long_run[0],
        ),
        (
            "across",
            (0..n).map(|i| standardised[i][1]).collect(),
            long_run[1],
        ),
        (
            "heading",
            (0..n).map(|i| standardised[i][2]).collect(),
            long_run[2],
        ),
        (
            "spread",
            (0..n)
                .map(|i| standardised[i].iter().map(|z| z * z).sum())
                .collect(),
            spread_factor,
        ),
    ];
    let normal = Normal::standard();
    let mut tried: Vec<(Covariate, f64)> = Vec::new();
    for (name, values) in
        COVARIATES.map(|(name, of)| (name, (0..n).map(|i| of(segments, i)).collect::<Vec<f64>>()))
    {
        for (component, residual, factor) in &components {
            let Some(r) = correlation(residual, &values) else {
                continue;
            };
            let effective = n as f64 / factor.max(1.0);
            let z = r.clamp(-0.999_999, 0.999_999).atanh() * (effective - 3.0).max(1.0).sqrt();
            tried.push((
                Covariate {
                    component,
                    covariate: name,
                    correlation: r,
                    significance: 0.0,
                },
                2.0 * normal.sf(z.abs()),
            ));
        }
    }
    tried.sort_by(|a, b| a.1.total_cmp(&b.1));
    // Holm: the k-th smallest p-value is multiplied by the tests left, and
    // an adjusted value never falls below the one before it.
    let total = tried.len();
    let mut floor: f64 = 0.0;
    tried
        .into_iter()
        .enumerate()
        .map(|(k, (mut c, p))| {
            floor = floor.max((p * (total - k) as f64).min(1.0));
            c.significance = floor;
            c
        })
        .take(count)
        .collect()
}

/// Pearson's correlation, or `None` when either series is constant.
pub(crate) fn correlation(a: &[f64], b: &[f64]) -> Option<f64> {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    (saa > 1e-12 && sbb > 1e-12).then(|| sab / (saa * sbb).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use shoal_physics::Pose;

    fn run(n: usize, seed: u64) -> Vec<Segment> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        (0..n)
            .map(|i| {
                let speed = rng.random_range(0.0..0.5);
                let turn = rng.random_range(-0.5..0.5);
                Segment {
                    from: i * 50,
                    to: (i + 1) * 50,
                    t_start: i as f64,
                    t_end: (i + 1) as f64,
                    start: Pose::new(0.0, 0.0, rng.random_range(-3.0..3.0)),
                    end: Pose::new(0.0, 0.0, 0.0),
                    speed,
                    turn,
                    distance: speed,
                    mid: [rng.random_range(0.0..10.0), rng.random_range(0.0..10.0)],
                }
            })
            .collect()
    }

    #[test]
    fn a_heading_error_that_follows_the_turn_rate_is_named_first() {
        let segments = run(600, 1);
        let mut rng = rand::rngs::StdRng::seed_from_u64(2);
        let standardised: Vec<[f64; 3]> = segments
            .iter()
            .map(|s| {
                let z =
                    |rng: &mut rand::rngs::StdRng| rng.sample::<f64, _>(rand_distr::StandardNormal);
                [z(&mut rng), z(&mut rng), z(&mut rng) + 2.0 * s.turn]
            })
            .collect();
        let found = strongest(&segments, &standardised, [1.0; 3], 3);
        assert_eq!(found[0].component, "heading");
        assert_eq!(found[0].covariate, "commanded turn rate");
        assert!(
            found[0].correlation > 0.3 && found[0].significance < 1e-6,
            "{found:?}"
        );
    }

    #[test]
    fn white_residuals_follow_nothing_significantly() {
        let mut significant = 0;
        for seed in 0..40 {
            let segments = run(300, seed);
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 100);
            let standardised: Vec<[f64; 3]> = (0..segments.len())
                .map(|_| std::array::from_fn(|_| rng.sample(rand_distr::StandardNormal)))
                .collect();
            let found = strongest(&segments, &standardised, [1.0; 3], 1);
            significant += usize::from(found[0].significance < 0.05);
        }
        // Holm keeps the family-wise rate near 5%: 40 runs, at most 6.
        assert!(significant <= 6, "{significant} of 40 white runs");
    }
}

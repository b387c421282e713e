//! Where the model and the run differ: the plain model's standardised
//! residuals tested by time, by place, by command and by speed. Every test
//! is counted and the p-values are Holm-corrected, so a run with no
//! mismatch reports nothing at the chosen level.

use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};

use crate::segments::Segment;

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Located {
    /// Which test found it: `time`, `place`, `command` or `speed`.
    pub family: &'static str,
    pub t_start: f64,
    pub t_end: f64,
    pub region: Option<[f64; 4]>,
    pub commands: String,
    /// Which part of the motion differs: `along`, `across`, `heading` or `spread`.
    pub component: &'static str,
    /// The Holm-corrected p-value.
    pub significance: f64,
    /// The test statistic, in standard deviations.
    pub z: f64,
    pub segments: usize,
}

struct Group {
    family: &'static str,
    members: Vec<usize>,
    commands: String,
    region: Option<[f64; 4]>,
    /// Position along its family's axis (block or cell), for merging neighbours.
    key: (i64, i64),
}

const COMPONENTS: [&str; 4] = ["along", "across", "heading", "spread"];
const MIN_GROUP: usize = 12;

/// What a segment's commands were, in words.
pub fn command_class(segment: &Segment) -> &'static str {
    if segment.speed < 0.01 && segment.turn.abs() < 0.02 {
        "standing"
    } else if segment.turn.abs() < 0.1 {
        "straight"
    } else if segment.turn > 0.0 {
        "turning left"
    } else {
        "turning right"
    }
}

/// Place: an 8 x 8 grid over where the robot went, a group per cell.
fn place_groups(segments: &[Segment]) -> Vec<Group> {
    let mut out = Vec::new();
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for s in segments {
        x0 = x0.min(s.mid[0]);
        y0 = y0.min(s.mid[1]);
        x1 = x1.max(s.mid[0]);
        y1 = y1.max(s.mid[1]);
    }
    let cell = ((x1 - x0).max(y1 - y0) / 8.0).max(0.05);
    let mut cells: std::collections::BTreeMap<(i64, i64), Vec<usize>> = Default::default();
    for (i, s) in segments.iter().enumerate() {
        let key = (
            ((s.mid[0] - x0) / cell).floor() as i64,
            ((s.mid[1] - y0) / cell).floor() as i64,
        );
        cells.entry(key).or_default().push(i);
    }
    for (key, members) in cells {
        let region = [
            x0 + key.0 as f64 * cell,
            y0 + key.1 as f64 * cell,
            x0 + (key.0 + 1) as f64 * cell,
            y0 + (key.1 + 1) as f64 * cell,
        ];
        out.push(Group {
            family: "place",
            members,
            commands: "any".into(),
            region: Some(region),
            key,
        });
    }
    out
}

fn groups(segments: &[Segment]) -> Vec<Group> {
    let n = segments.len();
    let mut out = Vec::new();
    // Time: contiguous blocks of about 25 segments, 4 to 40 of them.
    let blocks = (n / 25).clamp(4, 40).min(n / MIN_GROUP).max(1);
    for b in 0..blocks {
        let members: Vec<usize> = (b * n / blocks..(b + 1) * n / blocks).collect();
        out.push(Group {
            family: "time",
            members,
            commands: "any".into(),
            region: None,
            key: (b as i64, 0),
        });
    }
    out.extend(place_groups(segments));
    // Command classes.
    for class in ["standing", "straight", "turning left", "turning right"] {
        let members: Vec<usize> = (0..n)
            .filter(|&i| command_class(&segments[i]) == class)
            .collect();
        out.push(Group {
            family: "command",
            members,
            commands: class.into(),
            region: None,
            key: (0, 0),
        });
    }
    // Speed quartiles of the moving segments.
    let mut moving: Vec<usize> = (0..n).filter(|&i| segments[i].speed >= 0.01).collect();
    moving.sort_by(|&a, &b| segments[a].speed.total_cmp(&segments[b].speed));
    for q in 0..4 {
        let members: Vec<usize> = moving[q * moving.len() / 4..(q + 1) * moving.len() / 4].to_vec();
        if let (Some(&lo), Some(&hi)) = (members.first(), members.last()) {
            out.push(Group {
                family: "speed",
                commands: format!(
                    "speed {:.2}-{:.2} m/s",
                    segments[lo].speed, segments[hi].speed
                ),
                members,
                region: None,
                key: (q as i64, 0),
            });
        }
    }
    out.retain(|g| g.members.len() >= MIN_GROUP);
    out
}

/// The variance of a group's standardised residuals about their own mean,
/// at least 1. Noise that grows with what the group has in common (its
/// speed, its turn rate, a rough stretch) makes the group's residuals
/// spread more than the run's noise says; its mean is then judged against
/// that spread (a t-test), not the run's. At least 1, so a quiet group is
/// held to the run's noise.
fn own_variance(values: &[f64]) -> f64 {
    let n = values.len();
    if n < 2 {
        return 1.0;
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    variance.max(1.0)
}

/// Holm's step-down correction of `p`, in the same order.
pub fn holm(p: &[f64]) -> Vec<f64> {
    let m = p.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| p[a].total_cmp(&p[b]));
    let mut adjusted = vec![1.0; m];
    let mut running: f64 = 0.0;
    for (rank, &i) in order.iter().enumerate() {
        running = running.max(((m - rank) as f64 * p[i]).min(1.0));
        adjusted[i] = running;
    }
    adjusted
}

/// Visits of a place this far apart in time are taken as independent: the
/// noise's own memory is seconds (EXPERIMENTS.md 5b's coloured noises last
/// 2-5 s), and a visit is one pass over a cell.
const VISIT_GAP_S: f64 = 10.0;

/// Fewest degrees of freedom (visits beyond the first, over every cell)
/// for the places' own long-run factor ([`visits_factor`]); with fewer the
/// run's stands in.
const MIN_VISIT_DOF: usize = 20;

/// A place group's members cut into visits: runs of segments less than
/// [`VISIT_GAP_S`] apart.
fn visits(group: &Group, segments: &[Segment]) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut last_end = f64::NEG_INFINITY;
    for &i in &group.members {
        let segment = &segments[i];
        match out.last_mut() {
            Some(visit) if segment.t_start - last_end < VISIT_GAP_S => visit.push(i),
            _ => out.push(vec![i]),
        }
        last_end = segment.t_end;
    }
    out
}

/// How much the residuals' correlation in time inflates the variance of a
/// place's sum, read from how the visits of each place differ about that
/// place's own mean (pooled over places, over the variance of the values
/// about those means): `None` with fewer than [`MIN_VISIT_DOF`].
///
/// A place visited lap after lap, where the robot always drives the same
/// way, repeats its mismatch on every visit. The run's long-run factor,
/// read from the residuals in time, takes that repetition for noise that
/// lasts: a carpet patch on an oval course raised the along factor to 7,
/// and the patch was never located. Within a place the repetition is the
/// mean, and what is left between visits far apart is the noise: the sum
/// of a visit of `n` segments varies by `factor * variance * n`, whatever
/// lasts within the visit.
fn visits_factor(places: &[Vec<Vec<usize>>], values: &[f64]) -> Option<f64> {
    // Over places visited at least twice: squares of the visits' sums
    // about the place's mean with what they are worth, squares of the
    // values about it with theirs, and the visits beyond the first.
    let (mut between, mut between_weight, mut within, mut within_weight, mut dof) =
        (0.0, 0.0, 0.0, 0.0, 0usize);
    for visits in places.iter().filter(|v| v.len() >= 2) {
        let members = || visits.iter().flatten().map(|&i| values[i]);
        let n = members().count() as f64;
        let mean = members().sum::<f64>() / n;
        within += members().map(|v| (v - mean).powi(2)).sum::<f64>();
        within_weight += n - 1.0;
        let mut squared_lengths = 0.0;
        for visit in visits {
            let len = visit.len() as f64;
            between += (visit.iter().map(|&i| values[i]).sum::<f64>() - len * mean).powi(2);
            squared_lengths += len * len;
        }
        // For independent visits the expected sum of squares about the
        // place's mean is factor * variance * (n - sum of len^2 / n).
        between_weight += n - squared_lengths / n;
        dof += visits.len() - 1;
    }
    if dof < MIN_VISIT_DOF || between_weight <= 0.0 || within <= 0.0 {
        return None;
    }
    let variance = within / within_weight;
    Some((between / between_weight / variance).max(1.0))
}

/// The tests of one group: the mean of each component (along, across,
/// heading) against its own spread, and the spread against the noise; each
/// as (component, z, two-sided p), the spread as component 3.
fn group_tests(
    group: &Group,
    standardised: &[[f64; 3]],
    long_run: [f64; 3],
) -> Vec<(usize, f64, f64)> {
    let normal = Normal::standard();
    let n = group.members.len() as f64;
    let mut tests = Vec::with_capacity(4);
    for c in 0..3 {
        let values: Vec<f64> = group.members.iter().map(|&i| standardised[i][c]).collect();
        let z = values.iter().sum::<f64>() / (n * long_run[c] * own_variance(&values)).sqrt();
        tests.push((c, z, 2.0 * normal.sf(z.abs())));
    }
    // Spread: are the residuals larger (or smaller) than the noise says?
    let dof = 3.0 * n;
    let sum: f64 = group
        .members
        .iter()
        .map(|&i| standardised[i].iter().map(|z| z * z).sum::<f64>())
        .sum();
    // Correlated residuals make the sum of squares vary more; for
    // Gaussian ones squares correlate with rho^2 <= rho, so the mean
    // inflation of the components bounds it.
    let inflation = long_run.iter().sum::<f64>() / 3.0;
    if inflation <= 1.0 + 1e-9 {
        if let Ok(chi) = ChiSquared::new(dof) {
            let p = 2.0 * chi.cdf(sum).min(chi.sf(sum));
            tests.push((3, (sum - dof) / (2.0 * dof).sqrt(), p.min(1.0)));
        }
    } else {
        let z = (sum - dof) / (2.0 * dof * inflation).sqrt();
        tests.push((3, z, (2.0 * normal.sf(z.abs())).min(1.0)));
    }
    tests
}

/// A group's strongest test: its residual component, p and z.
type Strongest = (usize, f64, f64);

/// Group `g`, whose strongest significant test is `strongest` (component,
/// p, z), with its significant neighbours of the same family (adjacent
/// time blocks or floor cells), which form one span or region: their
/// segments, their region, and the strongest test among them. Marks each
/// neighbour taken.
fn with_neighbours(
    groups: &[Group],
    best: &[Option<Strongest>],
    (g, mut strongest): (usize, Strongest),
    taken: &mut [bool],
) -> (Vec<usize>, Option<[f64; 4]>, Strongest) {
    let mut members = groups[g].members.clone();
    let mut region = groups[g].region;
    if !matches!(groups[g].family, "time" | "place") {
        return (members, region, strongest);
    }
    let mut frontier = vec![g];
    while let Some(h) = frontier.pop() {
        for k in 0..groups.len() {
            let adjacent = groups[k].family == groups[h].family
                && (groups[k].key.0 - groups[h].key.0).abs()
                    + (groups[k].key.1 - groups[h].key.1).abs()
                    == 1;
            let Some(test) = best[k] else { continue };
            if taken[k] || !adjacent {
                continue;
            }
            taken[k] = true;
            frontier.push(k);
            members.extend_from_slice(&groups[k].members);
            if let (Some(r), Some(o)) = (region, groups[k].region) {
                region = Some([
                    r[0].min(o[0]),
                    r[1].min(o[1]),
                    r[2].max(o[2]),
                    r[3].max(o[3]),
                ]);
            }
            if test.1 < strongest.1 {
                strongest = test;
            }
        }
    }
    (members, region, strongest)
}

/// Tests `standardised` residuals (one per segment) and returns what is
/// significant at `alpha` after correction, most significant first.
///
/// `long_run` is how much the residuals' correlation in time inflates the
/// variance of a sum over segments (per component, see
/// [`crate::likelihood::long_run_of_components`]); groups are mostly runs of
/// consecutive segments, so their sums are scaled by it.
pub fn locate(
    segments: &[Segment],
    standardised: &[[f64; 3]],
    long_run: [f64; 3],
    alpha: f64,
) -> Vec<Located> {
    let groups = groups(segments);
    let places: Vec<Vec<Vec<usize>>> = groups
        .iter()
        .filter(|g| g.family == "place")
        .map(|g| visits(g, segments))
        .collect();
    let place_long_run: [f64; 3] = std::array::from_fn(|c| {
        let series: Vec<f64> = standardised.iter().map(|z| z[c]).collect();
        visits_factor(&places, &series).unwrap_or(long_run[c])
    });
    tracing::debug!(
        ?long_run,
        ?place_long_run,
        "locate: long-run factors in time, and of places' visits"
    );
    let tests: Vec<(usize, usize, f64, f64)> = groups
        .iter()
        .enumerate()
        .flat_map(|(g, group)| {
            let long_run = if group.family == "place" {
                place_long_run
            } else {
                long_run
            };
            group_tests(group, standardised, long_run)
                .into_iter()
                .map(move |(c, z, p)| (g, c, z, p))
        })
        .collect();
    let adjusted = holm(&tests.iter().map(|t| t.3).collect::<Vec<_>>());
    // The strongest significant test of each group.
    let mut best: Vec<Option<(usize, f64, f64)>> = vec![None; groups.len()];
    for (&(g, c, z, _), &p) in tests.iter().zip(&adjusted) {
        if p < alpha && best[g].is_none_or(|(_, bp, _)| p < bp) {
            best[g] = Some((c, p, z));
        }
    }
    let mut found = Vec::new();
    let mut taken = vec![false; groups.len()];
    for g in 0..groups.len() {
        let Some(test) = best[g] else { continue };
        if taken[g] {
            continue;
        }
        taken[g] = true;
        let (members, region, (component, p_min, z_best)) =
            with_neighbours(&groups, &best, (g, test), &mut taken);
        let t_start = members
            .iter()
            .map(|&i| segments[i].t_start)
            .fold(f64::MAX, f64::min);
        let t_end = members
            .iter()
            .map(|&i| segments[i].t_end)
            .fold(f64::MIN, f64::max);
        found.push(Located {
            family: groups[g].family,
            t_start,
            t_end,
            region,
            commands: groups[g].commands.clone(),
            component: COMPONENTS[component],
            significance: p_min,
            z: z_best,
            segments: members.len(),
        });
    }
    found.sort_by(|a, b| a.significance.total_cmp(&b.significance));
    found
}

#[cfg(test)]
mod tests {
    use super::{holm, visits_factor};

    /// Ten places of eight visits of five segments each, whose noise lasts
    /// the whole visit (each visit off by its own amount, cancelling over
    /// a place's visits) with white noise beside it, and each place off by
    /// `bias` on every visit.
    fn lasting_within_visits(bias: f64) -> (Vec<Vec<Vec<usize>>>, Vec<f64>) {
        let places = (0..10)
            .map(|p| {
                (0..8)
                    .map(|k| (40 * p + 5 * k..40 * p + 5 * k + 5).collect())
                    .collect()
            })
            .collect();
        let values = (0..400)
            .map(|i| {
                let visit = i / 5;
                let lasting = [0.8, -0.8, 0.4, -0.4][visit % 4];
                let white = [0.3, -0.2, 0.1, -0.4, 0.2][i % 5];
                bias + lasting + white
            })
            .collect();
        (places, values)
    }

    #[test]
    fn a_place_is_judged_by_how_its_visits_differ() {
        // Noise that lasts a visit inflates the variance of a visit's sum:
        // the factor reads it.
        let (places, values) = lasting_within_visits(0.0);
        let factor = visits_factor(&places, &values).expect("70 visits beyond the first");
        assert!(factor > 3.0, "factor {factor}");
        // A mismatch repeated on every visit of a place is that place's
        // mean, not noise: the factor is the same (a long-run factor read
        // from the residuals in time would take it for noise that lasts).
        let (places, biased) = lasting_within_visits(1.0);
        let with_bias = visits_factor(&places, &biased).expect("70 visits beyond the first");
        assert!(
            (with_bias - factor).abs() < 1e-9,
            "{with_bias} against {factor}"
        );
        // White noise reads about 1, never less.
        let white: Vec<f64> = (0..400)
            .map(|i| [0.3, -0.2, 0.1, -0.4, 0.2, 0.5, -0.5][i % 7])
            .collect();
        let factor = visits_factor(&places, &white).expect("70 visits beyond the first");
        assert!((1.0..1.5).contains(&factor), "factor {factor}");
        // Too few visits to tell: the run's factor stands in.
        assert_eq!(visits_factor(&places[..2], &values), None);
    }

    #[test]
    fn holm_matches_hand_computed_values() {
        // m = 4: 0.01*4, max(0.04, 0.02*3), max(0.06, 0.03*2), max(0.06, 0.5)
        let adjusted = holm(&[0.03, 0.01, 0.5, 0.02]);
        let expected = [0.06, 0.04, 0.5, 0.06];
        for (a, e) in adjusted.iter().zip(expected) {
            assert!((a - e).abs() < 1e-12, "{adjusted:?}");
        }
    }
}

//! How well a model predicts the segments: residuals and their likelihood.
//!
//! A segment's residual is the observed end pose minus the predicted one, in
//! the frame of the segment's start: along the heading, across it, and the
//! heading. Motion noise that accrues as a random walk makes the across
//! error grow with the distance driven and correlate with the heading
//! error; the noise model below accounts for both, so that a plain model on
//! plain data does not look speed-dependent.

use rayon::prelude::*;
use shoal_physics::{CommandGrid, Pose, UnicycleModel, wrap_angle};

use crate::segments::Segment;

/// Observed minus predicted: along, across, heading.
pub type Residual = [f64; 3];

/// Base variances of the three residual components.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise {
    pub along: f64,
    /// Across the heading, after removing what the heading error explains.
    pub across: f64,
    /// How the across variance grows with the square of the distance
    /// driven in the segment (per m^2).
    pub across_per_m2: f64,
    pub theta: f64,
}

impl Noise {
    /// Whether a component's variance is at the floor: the residuals it
    /// was estimated from showed no noise there at all.
    pub fn at_floor(&self) -> bool {
        [self.along, self.across, self.theta]
            .iter()
            .any(|v| *v <= VARIANCE_FLOOR)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Score {
    /// Negative log-likelihood of the residuals.
    pub nll: f64,
    pub noise: Noise,
}

const VARIANCE_FLOOR: f64 = 1e-12;

/// Seconds the actuators run before a segment that does not follow the
/// previous one: enough for latency. Actuators with memory (lag, play,
/// inertia) get longer, since play holds its state until the command next
/// changes; consecutive segments carry the state on exactly, but for the
/// first of each chunk traced on its own ([`residuals`]).
const WARMUP_S: f64 = 0.3;
const MEMORY_WARMUP_S: f64 = 3.0;

/// Grid steps the actuators run before a segment that does not follow the
/// previous one, for `model`.
fn warmup_steps(model: &UnicycleModel, grid: &CommandGrid) -> usize {
    let warmup_s = if model.has_actuator_memory() {
        MEMORY_WARMUP_S
    } else {
        WARMUP_S
    };
    (warmup_s / grid.dt).ceil() as usize
}

/// Grid steps of prediction a chunk of segments holds at least
/// ([`residuals`]): enough that one more warm-up per chunk (300 steps for
/// actuators with memory on a 0.01 s grid, 600 on the feedback stage's
/// finest) costs a few percent.
const CHUNK_STEPS: usize = 8192;

/// Each segment's residual under `model`. Every fit scores a model this
/// way, many of them one after another, so the segments are traced in
/// chunks on every core; each chunk's first segment starts its actuators
/// from the warm-up, as a segment that does not follow the one before
/// does, so a model with actuator memory (a lag, play) is predicted there
/// from 3 s of warm-up instead of the whole run before it.
pub fn residuals(model: &UnicycleModel, grid: &CommandGrid, segments: &[Segment]) -> Vec<Residual> {
    let mut chunks = Vec::new();
    let (mut start, mut steps) = (0, 0);
    for (k, s) in segments.iter().enumerate() {
        steps += s.to.saturating_sub(s.from);
        if steps >= CHUNK_STEPS {
            chunks.push(start..k + 1);
            (start, steps) = (k + 1, 0);
        }
    }
    if start < segments.len() {
        chunks.push(start..segments.len());
    }
    chunks
        .into_par_iter()
        .flat_map_iter(|chunk| traced_residuals(model, grid, &segments[chunk], |_, _, _| {}))
        .collect()
}

/// [`residuals`], also handing `on_step` every predicted pose on the way:
/// the segment's index, the grid step just executed and the pose after it.
pub fn traced_residuals(
    model: &UnicycleModel,
    grid: &CommandGrid,
    segments: &[Segment],
    on_step: impl FnMut(usize, usize, Pose),
) -> Vec<Residual> {
    let predicted = model.trace_stretches(
        grid,
        segments.iter().map(|s| (s.start, s.from, s.to)),
        warmup_steps(model, grid),
        on_step,
    );
    segments
        .iter()
        .zip(predicted)
        .map(|(s, predicted)| residual_of(s, predicted))
        .collect()
}

/// Observed minus `predicted` at the segment's end, in the frame of its start.
fn residual_of(segment: &Segment, predicted: Pose) -> Residual {
    let end = segment.end;
    let (dx, dy) = (end.x - predicted.x, end.y - predicted.y);
    let (sin, cos) = segment.start.theta.sin_cos();
    [
        dx * cos + dy * sin,
        -dx * sin + dy * cos,
        wrap_angle(end.theta - predicted.theta),
    ]
}

/// The across residual less the part a heading error accrued linearly over
/// the segment explains.
fn decorrelated(segment: &Segment, r: &Residual) -> f64 {
    r[1] - 0.5 * segment.distance * r[2]
}

/// Variances of segment `s`'s components under `noise` and `multiplier`.
fn variances(noise: &Noise, s: &Segment, multiplier: f64) -> [f64; 3] {
    [
        noise.along * multiplier,
        (noise.across + noise.across_per_m2 * s.distance * s.distance) * multiplier,
        noise.theta * multiplier,
    ]
    .map(|v| v.max(VARIANCE_FLOOR))
}

/// Estimates the noise of `residuals` (moments, given the model's multipliers).
///
/// The across variance grows with the square of the distance driven: a
/// heading error turns into a sideways one in proportion to the distance.
/// How fast is learned from the data (a regression of the squared across
/// residuals on the squared distance) rather than assumed: a random walk
/// in heading gives a twelfth of its variance per m^2, but the error of the
/// observed start heading, which motion capture or odometry adds, counts
/// in full, and the two mix in proportions no model knows beforehand.
/// Where the distances hardly vary, the random walk's share is taken.
pub fn estimate_noise(
    model: &UnicycleModel,
    segments: &[Segment],
    residuals: &[Residual],
) -> Noise {
    let n = segments.len().max(1) as f64;
    let (mut along, mut theta) = (0.0, 0.0);
    let (mut d2_sum, mut y_sum, mut d2d2, mut d2y) = (0.0, 0.0, 0.0, 0.0);
    // The across residual of the segments that stood still.
    let (mut standing, mut standing_sum) = (0usize, 0.0);
    for (s, r) in segments.iter().zip(residuals) {
        let m = model.noise_multiplier(s.speed, s.t_start);
        along += r[0] * r[0] / m;
        theta += r[2] * r[2] / m;
        let (d2, y) = (s.distance * s.distance, decorrelated(s, r).powi(2) / m);
        d2_sum += d2;
        y_sum += y;
        d2d2 += d2 * d2;
        d2y += d2 * y;
        if s.distance < STANDING_M {
            standing += 1;
            standing_sum += y;
        }
    }
    let theta = (theta / n).max(VARIANCE_FLOOR);
    let (d2_mean, y_mean) = (d2_sum / n, y_sum / n);
    let d2_var = d2d2 / n - d2_mean * d2_mean;
    // Heading variance that is all random walk gives a twelfth of it per
    // m^2, all observation error a quarter: the mix lies between, and a
    // regression that leaves that range is fitting a mismatch, not noise.
    // The squared distance must spread over at least a tenth of its mean.
    let (random_walk, observed) = (theta / 12.0, theta / 4.0);
    let across_per_m2 = if d2_var > (0.1 * d2_mean).powi(2) && d2_var > 0.0 {
        ((d2y / n - d2_mean * y_mean) / d2_var).clamp(random_walk, observed)
    } else {
        random_walk
    };
    // Where the robot also stood still, what its across residual shows
    // there (the observation's own error) bounds the intercept from below:
    // a slope held within its range can take the intercept to the floor,
    // and one standing segment then costs 10^6 nats (laps with pauses,
    // EXPERIMENTS.md 5c, "Laps"). Half of it, so that the mean of a few
    // standing segments, itself noisy, does not lift a regression that
    // holds.
    let at_rest = if standing >= MIN_STANDING {
        0.5 * standing_sum / standing as f64
    } else {
        0.0
    };
    Noise {
        along: (along / n).max(VARIANCE_FLOOR),
        across: (y_mean - across_per_m2 * d2_mean)
            .max(at_rest)
            .max(VARIANCE_FLOOR),
        across_per_m2,
        theta,
    }
}

/// A segment commanded this little distance stands still.
const STANDING_M: f64 = 1e-4;

/// Standing segments enough to say what the across residual is at rest:
/// one, since a pause of a few seconds holds only one or two whole 1 s
/// segments, and without them the floor is 10^-12 m^2.
const MIN_STANDING: usize = 1;

/// Negative log-likelihood of one segment's residual, by component (along,
/// across, heading).
fn nll_by_component(model: &UnicycleModel, noise: &Noise, s: &Segment, r: &Residual) -> [f64; 3] {
    let var = variances(noise, s, model.noise_multiplier(s.speed, s.t_start));
    let values = [r[0], decorrelated(s, r), r[2]];
    std::array::from_fn(|c| {
        0.5 * ((2.0 * std::f64::consts::PI * var[c]).ln() + values[c] * values[c] / var[c])
    })
}

/// Negative log-likelihood of each segment's residual.
pub fn segment_nll(
    model: &UnicycleModel,
    noise: &Noise,
    segments: &[Segment],
    residuals: &[Residual],
) -> Vec<f64> {
    segments
        .iter()
        .zip(residuals)
        .map(|(s, r)| nll_by_component(model, noise, s, r).iter().sum())
        .collect()
}

/// The likelihood of `residuals`, with the noise estimated from them unless given.
pub fn score(
    model: &UnicycleModel,
    segments: &[Segment],
    residuals: &[Residual],
    noise: Option<Noise>,
) -> Score {
    let noise = noise.unwrap_or_else(|| estimate_noise(model, segments, residuals));
    let nll = segment_nll(model, &noise, segments, residuals).iter().sum();
    Score { nll, noise }
}

/// Root mean square position and heading error of `residuals`.
pub fn rmse(residuals: &[Residual]) -> (f64, f64) {
    let n = residuals.len().max(1) as f64;
    let pos = residuals
        .iter()
        .map(|r| r[0] * r[0] + r[1] * r[1])
        .sum::<f64>()
        / n;
    let theta = residuals.iter().map(|r| r[2] * r[2]).sum::<f64>() / n;
    (pos.sqrt(), theta.sqrt())
}

/// Residuals divided by their standard deviation under `noise`, for tests.
pub fn standardised(
    model: &UnicycleModel,
    noise: &Noise,
    segments: &[Segment],
    residuals: &[Residual],
) -> Vec<[f64; 3]> {
    segments
        .iter()
        .zip(residuals)
        .map(|(s, r)| {
            let var = variances(noise, s, model.noise_multiplier(s.speed, s.t_start));
            [
                r[0] / var[0].sqrt(),
                decorrelated(s, r) / var[1].sqrt(),
                r[2] / var[2].sqrt(),
            ]
        })
        .collect()
}

/// Negative log-likelihood of `residuals` split by component (along,
/// across, heading), with the noise estimated from them.
pub fn component_nll(
    model: &UnicycleModel,
    segments: &[Segment],
    residuals: &[Residual],
) -> [f64; 3] {
    let noise = estimate_noise(model, segments, residuals);
    let mut total = [0.0; 3];
    for (s, r) in segments.iter().zip(residuals) {
        let nll = nll_by_component(model, &noise, s, r);
        for c in 0..3 {
            total[c] += nll[c];
        }
    }
    total
}

/// How much the residuals' correlation in time inflates the variance of a
/// sum over segments, per component: the long-run variance of the
/// standardised residuals over their variance, `1 + 2 sum_k w_k rho_k`.
///
/// Real motion noise is coloured (slip episodes, floor texture, controller
/// dither, with time constants of 0.2 to 5 s), so back-to-back 1 s segments
/// are not independent, and a likelihood that treats them so counts every
/// second of evidence several times over. The factor is estimated from the
/// data: autocorrelations of consecutive segments (gaps break the chain),
/// weighted by Bartlett's kernel with Andrews' (1991) AR(1) plug-in
/// bandwidth, as in a Newey-West (HAC) variance. Dividing a log-likelihood
/// gain by it keeps likelihood-ratio tests calibrated (a composite, or
/// quasi-, likelihood with an effective sample size of n / factor).
pub fn long_run_of_components(segments: &[Segment], standardised: &[[f64; 3]]) -> [LongRun; 3] {
    components_around(segments, standardised, None)
}

/// Half-width, in segments, of the local mean that
/// [`long_run_factors_of_noise`] removes: two and a half times the longest
/// lag the kernel weighs (`long_run_around`'s 40). A local mean takes from
/// the series what varies slower than its window, and the kernel reads the
/// long-run variance from what varies slower than its bandwidth: with a
/// half-width of 25, inside the 28-segment bandwidth of a 5 s noise on 1 s
/// segments, the along factor came out 0.54-0.60 of the whole run's (two
/// null runs), and 4 of 40 null runs under that noise located a stretch
/// of time that differed; with 100, none (EXPERIMENTS.md 5b).
const LOCAL_MEAN_HALF_WIDTH: usize = 100;

/// [`long_run_of_components`]' factors for the noise alone, for a model that may still miss
/// an effect: a mismatch that comes and goes over minutes (a zone driven
/// into, a fault that starts) would otherwise pass for correlated noise and
/// hide itself. A local mean over about 200 segments is removed first,
/// which keeps the correlation of noise over seconds.
pub fn long_run_factors_of_noise(segments: &[Segment], standardised: &[[f64; 3]]) -> [f64; 3] {
    components_around(segments, standardised, Some(LOCAL_MEAN_HALF_WIDTH)).map(|l| l.factor)
}

fn components_around(
    segments: &[Segment],
    standardised: &[[f64; 3]],
    local_mean: Option<usize>,
) -> [LongRun; 3] {
    std::array::from_fn(|c| {
        let series: Vec<f64> = standardised.iter().map(|z| z[c]).collect();
        long_run_around(segments, &series, local_mean)
    })
}

/// [`long_run_of_components`] of one series over the segments: how much its
/// correlation in time inflates the variance of its sum.
pub fn long_run_factor(segments: &[Segment], series: &[f64]) -> LongRun {
    long_run_around(segments, series, None)
}

/// The sum of `series[i] * series[i + k]` over segments `k` apart with no
/// gap between them (back to back on the grid), and how many such pairs.
pub(crate) fn lagged_products(segments: &[Segment], series: &[f64], k: usize) -> (f64, usize) {
    let n = series.len().min(segments.len());
    let (mut sum, mut pairs) = (0.0, 0usize);
    for i in 0..n.saturating_sub(k) {
        if segments[i + k].from == segments[i].from + k * (segments[i].to - segments[i].from) {
            sum += series[i] * series[i + k];
            pairs += 1;
        }
    }
    (sum, pairs)
}

/// A long-run variance factor and how it was estimated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LongRun {
    /// Long-run variance over variance: 1 for white noise.
    pub factor: f64,
    /// Degrees of freedom of the estimate (Sun 2014: n / (bandwidth x 2/3)
    /// for Bartlett's kernel): a statistic divided by `factor` is close to
    /// k F(k, dof - k + 1) x dof / (dof - k + 1) rather than χ²(k), which
    /// accounts for the estimate's own randomness and bias where the noise
    /// is persistent and the bandwidth therefore wide.
    pub dof: f64,
}

fn long_run_around(segments: &[Segment], series: &[f64], local_mean: Option<usize>) -> LongRun {
    let n = series.len();
    let white = LongRun {
        factor: 1.0,
        dof: n as f64,
    };
    if n < 20 {
        return white;
    }
    let max_lag = (n / 10).clamp(1, 40);
    let mean = series.iter().sum::<f64>() / n as f64;
    let centred: Vec<f64> = match local_mean {
        None => series.iter().map(|x| x - mean).collect(),
        Some(half) => (0..n)
            .map(|i| {
                let (lo, hi) = (i.saturating_sub(half), (i + half + 1).min(n));
                let local = series[lo..hi].iter().sum::<f64>() / (hi - lo) as f64;
                series[i] - local
            })
            .collect(),
    };
    let variance = centred.iter().map(|x| x * x).sum::<f64>() / n as f64;
    if variance <= 0.0 {
        return white;
    }
    // rho_k over pairs k segments apart with no gap between them.
    let rho: Vec<f64> = (1..=max_lag)
        .map(|k| {
            let (sum, pairs) = lagged_products(segments, &centred, k);
            if pairs < 10 {
                0.0
            } else {
                sum / pairs as f64 / variance
            }
        })
        .collect();
    let rho1 = rho[0].clamp(-0.97, 0.97);
    let alpha = 4.0 * rho1 * rho1 / ((1.0 - rho1).powi(2) * (1.0 + rho1).powi(2));
    let bandwidth = (1.1447 * (alpha * n as f64).cbrt())
        .ceil()
        .clamp(1.0, max_lag as f64) as usize;
    let weighted: f64 = rho[..bandwidth]
        .iter()
        .enumerate()
        .map(|(k, r)| (1.0 - (k + 1) as f64 / (bandwidth + 1) as f64) * r)
        .sum();
    // Negative correlation would shrink the variance; never claim more
    // evidence than independent segments give.
    LongRun {
        factor: (1.0 + 2.0 * weighted).max(1.0),
        dof: n as f64 / ((bandwidth + 1) as f64 * 2.0 / 3.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn chain(n: usize) -> Vec<Segment> {
        (0..n)
            .map(|i| Segment {
                from: i * 50,
                to: (i + 1) * 50,
                t_start: i as f64,
                t_end: (i + 1) as f64,
                start: shoal_physics::Pose::new(0.0, 0.0, 0.0),
                end: shoal_physics::Pose::new(0.0, 0.0, 0.0),
                speed: 0.0,
                turn: 0.0,
                distance: 0.0,
                mid: [0.0, 0.0],
            })
            .collect()
    }

    #[test]
    fn white_residuals_count_once_and_ar1_residuals_inflate_as_theory_says() {
        let n = 4000;
        let segments = chain(n);
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let normal = rand_distr::StandardNormal;
        let white: Vec<[f64; 3]> = (0..n)
            .map(|_| [rng.sample(normal), rng.sample(normal), rng.sample(normal)])
            .collect();
        let f = long_run_of_components(&segments, &white).map(|l| l.factor);
        assert!(f.iter().all(|f| *f < 1.25), "{f:?}");
        // AR(1) with rho = 0.6: long-run factor (1 + rho) / (1 - rho) = 4.
        let mut x = 0.0;
        let ar: Vec<[f64; 3]> = (0..n)
            .map(|_| {
                x = 0.6 * x + 0.8 * rng.sample::<f64, _>(normal);
                [x, x, x]
            })
            .collect();
        let f = long_run_of_components(&segments, &ar).map(|l| l.factor);
        assert!(f.iter().all(|f| (2.8..=4.6).contains(f)), "{f:?}");
    }

    #[test]
    fn the_noise_factor_of_a_slow_noise_on_a_ten_minute_run_is_the_whole_runs() {
        // 5 s noise seen on 1 s segments: AR(1) with rho = 0.82. The local
        // mean must not take what the kernel reads: with a mean over 51
        // segments the noise factor came out near half the whole run's.
        let n = 600;
        let segments = chain(n);
        let normal = rand_distr::StandardNormal;
        let ratios: Vec<f64> = (0..10)
            .map(|seed| {
                let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
                let mut x = 0.0;
                let ar: Vec<[f64; 3]> = (0..n)
                    .map(|_| {
                        x = 0.82 * x + rng.sample::<f64, _>(normal);
                        [x, x, x]
                    })
                    .collect();
                let whole = long_run_of_components(&segments, &ar)[0].factor;
                long_run_factors_of_noise(&segments, &ar)[0] / whole
            })
            .collect();
        let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
        // 0.83 with the mean over 201 segments, 0.42 over 51.
        assert!(mean > 0.7, "{ratios:?}");
    }

    #[test]
    fn a_mismatch_that_comes_and_goes_is_not_taken_for_correlated_noise() {
        // White noise plus a shift of 1.5 standard deviations in the middle
        // third of the run: an effect, not coloured noise.
        let n = 3000;
        let segments = chain(n);
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let shifted: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let shift = if (n / 3..2 * n / 3).contains(&i) {
                    1.5
                } else {
                    0.0
                };
                let z: f64 = rng.sample(rand_distr::StandardNormal);
                [z + shift; 3]
            })
            .collect();
        let whole = long_run_of_components(&segments, &shifted).map(|l| l.factor);
        let noise = long_run_factors_of_noise(&segments, &shifted);
        assert!(
            whole[0] > 3.0,
            "the shift inflates the plain factor: {whole:?}"
        );
        assert!(noise[0] < 1.4, "the noise alone is white: {noise:?}");
    }

    /// Segments of 0 to 0.3 m whose across residuals (after the heading's
    /// share) have variance `across + per_m2 d^2`, with heading variance
    /// `theta`.
    fn across_growing(per_m2: f64, theta: f64) -> (Vec<Segment>, Vec<Residual>) {
        let n = 20_000;
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let normal = rand_distr::StandardNormal;
        let mut segments = chain(n);
        let residuals = segments
            .iter_mut()
            .enumerate()
            .map(|(i, s)| {
                s.distance = 0.3 * (i % 100) as f64 / 100.0;
                let heading = theta.sqrt() * rng.sample::<f64, _>(normal);
                let across =
                    (1e-5 + per_m2 * s.distance * s.distance).sqrt() * rng.sample::<f64, _>(normal);
                [
                    1e-3 * rng.sample::<f64, _>(normal),
                    across + 0.5 * s.distance * heading,
                    heading,
                ]
            })
            .collect();
        (segments, residuals)
    }

    #[test]
    fn the_across_growth_with_distance_is_learned_within_what_heading_noise_gives() {
        let theta = 4e-4;
        let plain = UnicycleModel::plain();
        // Inside the physical range (a twelfth to a quarter of the heading
        // variance per m^2): recovered.
        let (segments, residuals) = across_growing(theta / 6.0, theta);
        let noise = estimate_noise(&plain, &segments, &residuals);
        assert!(
            (noise.across_per_m2 / (theta / 6.0) - 1.0).abs() < 0.15,
            "{noise:?}"
        );
        assert!((noise.across / 1e-5 - 1.0).abs() < 0.15, "{noise:?}");
        // Far above it, a mismatch rather than noise: held to a quarter.
        let (segments, residuals) = across_growing(theta * 3.0, theta);
        let noise = estimate_noise(&plain, &segments, &residuals);
        assert!(
            (noise.across_per_m2 - noise.theta / 4.0).abs() < 1e-12,
            "{noise:?}"
        );
    }

    /// A robot whose heading noise while driving is large, but whose across
    /// residual is the motion capture's millimetre everywhere: the slope,
    /// held at least at what the heading noise gives, takes the intercept
    /// below zero; the robot's pauses say what it is at rest.
    #[test]
    fn the_across_noise_at_rest_is_never_below_what_standing_still_shows() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let normal = rand_distr::StandardNormal;
        let mut segments = chain(2000);
        let residuals: Vec<Residual> = segments
            .iter_mut()
            .enumerate()
            .map(|(i, s)| {
                let paused = i % 50 == 0;
                s.distance = if paused { 0.0 } else { 0.3 };
                let heading = if paused {
                    0.0
                } else {
                    0.02 * rng.sample::<f64, _>(normal)
                };
                [
                    1e-3 * rng.sample::<f64, _>(normal),
                    1e-3 * rng.sample::<f64, _>(normal) + 0.5 * s.distance * heading,
                    heading,
                ]
            })
            .collect();
        let noise = estimate_noise(&UnicycleModel::plain(), &segments, &residuals);
        assert!(
            noise.across > 0.3e-6 && noise.across < 1e-6,
            "at rest the across variance is about half the standing 1e-6 at least: {noise:?}"
        );
        // Without the pauses, nothing says what rest is: the regression's.
        let moving: Vec<usize> = (0..segments.len()).filter(|i| i % 50 != 0).collect();
        let noise = estimate_noise(
            &UnicycleModel::plain(),
            &moving
                .iter()
                .map(|&i| segments[i].clone())
                .collect::<Vec<_>>(),
            &moving.iter().map(|&i| residuals[i]).collect::<Vec<_>>(),
        );
        assert!(noise.across <= 1e-11, "{noise:?}");
    }
}

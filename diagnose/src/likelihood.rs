//! How well a model predicts the segments: residuals and their likelihood.
//!
//! A segment's residual is the observed end pose minus the predicted one, in
//! the frame of the segment's start: along the heading, across it, and the
//! heading. Motion noise that accrues as a random walk makes the across
//! error grow with the distance driven and correlate with the heading
//! error; the noise model below accounts for both, so that a plain model on
//! plain data does not look speed-dependent.

use shoal_physics::{CommandGrid, UnicycleModel, wrap_angle};

use crate::segments::Segment;

/// Observed minus predicted: along, across, heading.
pub type Residual = [f64; 3];

/// Base variances of the three residual components.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise {
    pub along: f64,
    /// Across the heading, after removing what the heading error explains.
    pub across: f64,
    pub theta: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Score {
    /// Negative log-likelihood of the residuals.
    pub nll: f64,
    pub noise: Noise,
}

const VARIANCE_FLOOR: f64 = 1e-12;

/// Seconds the actuators run before a segment starts, so that latency,
/// inertia and play have their history.
const WARMUP_S: f64 = 0.3;

pub fn residuals(model: &UnicycleModel, grid: &CommandGrid, segments: &[Segment]) -> Vec<Residual> {
    let warmup = (WARMUP_S / grid.dt).ceil() as usize;
    segments
        .iter()
        .map(|s| {
            let predicted = model.predict(grid, s.start, s.from, s.to, warmup);
            let (dx, dy) = (s.end.x - predicted.x, s.end.y - predicted.y);
            let (sin, cos) = s.start.theta.sin_cos();
            [
                dx * cos + dy * sin,
                -dx * sin + dy * cos,
                wrap_angle(s.end.theta - predicted.theta),
            ]
        })
        .collect()
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
        (noise.across + noise.theta * s.distance * s.distance / 12.0) * multiplier,
        noise.theta * multiplier,
    ]
    .map(|v| v.max(VARIANCE_FLOOR))
}

/// Estimates the noise of `residuals` (moments, given the model's multipliers).
pub fn estimate_noise(
    model: &UnicycleModel,
    segments: &[Segment],
    residuals: &[Residual],
) -> Noise {
    let n = segments.len().max(1) as f64;
    let (mut along, mut across, mut theta, mut lever) = (0.0, 0.0, 0.0, 0.0);
    for (s, r) in segments.iter().zip(residuals) {
        let m = model.noise_multiplier(s.speed, s.t_start);
        along += r[0] * r[0] / m;
        across += decorrelated(s, r).powi(2) / m;
        theta += r[2] * r[2] / m;
        lever += s.distance * s.distance / 12.0;
    }
    let theta = (theta / n).max(VARIANCE_FLOOR);
    Noise {
        along: (along / n).max(VARIANCE_FLOOR),
        across: (across / n - theta * lever / n).max(VARIANCE_FLOOR),
        theta,
    }
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
        .map(|(s, r)| {
            let m = model.noise_multiplier(s.speed, s.t_start);
            let var = variances(noise, s, m);
            let values = [r[0], decorrelated(s, r), r[2]];
            values
                .iter()
                .zip(var)
                .map(|(x, v)| 0.5 * ((2.0 * std::f64::consts::PI * v).ln() + x * x / v))
                .sum()
        })
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

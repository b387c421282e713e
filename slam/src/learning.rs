//! The thesis's learning rule (IV, "Learning the Model"): per command and per
//! motion parameter, a two-Gaussian mixture is moved towards the
//! quality-weighted statistics of the particles that used it, with a gain of
//! this step's weight over the weight of the last k steps.

use std::collections::VecDeque;

use shoal_physics::Mixture2;

/// One particle's draw of a motion parameter and how well its scan fit the map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Draw {
    pub value: f64,
    pub quality: f64,
}

/// Learns one mixture (one command, one parameter).
#[derive(Clone, Debug, PartialEq)]
pub struct MixtureLearner {
    pub mixture: Mixture2,
    /// The window k of the windowed exponential estimator (5 <= k <= 10).
    window: usize,
    /// The per-component weights g_j of the last `window` steps.
    history: VecDeque<[f64; 2]>,
    /// Variances never shrink below this, so a component cannot collapse
    /// onto one draw ([`NARROWEST_SPREAD_OF_START`]).
    pub min_variance: f64,
}

/// What one step changed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Update {
    /// g_j: the weight each component received this step.
    pub weights: [f64; 2],
    /// g_j / G_j: how far each component moved towards this step's statistics.
    pub gains: [f64; 2],
}

/// How narrow a component may become, as a share of the narrower
/// component's spread at the start. A component given only draws near its
/// mean narrows step by step, and once narrow it is given no draws at all,
/// so it stays where it narrowed: with a floor of a tenth of a
/// millimetre (a variance of 1e-8), 8 of 12 lone robots
/// (`slam/tests/unseen.rs`) ended with a walk component 0.0001 m wide,
/// stuck at a stride of 0.11-0.14 m with a third to two thirds of the
/// weight, and the learned stride 5% short of the robot's on average over
/// the run (0.173 m against 0.182 m); with half the start's spread, 1.5%
/// short (EXPERIMENTS.md 8b).
pub const NARROWEST_SPREAD_OF_START: f64 = 0.5;
/// And never narrower than this (a tenth of a millimetre or of a
/// milliradian), whatever a model file starts from.
const NARROWEST_VARIANCE: f64 = 1e-8;

impl MixtureLearner {
    /// Starts as if `mixture` had been seen for a full window of fully
    /// informative steps (total quality 1 each), so the first real steps
    /// move it by about 1/k rather than replacing it with what one step saw.
    pub fn new(mixture: Mixture2, window: usize) -> Self {
        let window = window.clamp(1, 64);
        let history = std::iter::repeat_n(mixture.weights, window).collect();
        Self {
            mixture,
            window,
            history,
            min_variance: (mixture.variances[0].min(mixture.variances[1])
                * NARROWEST_SPREAD_OF_START.powi(2))
            .max(NARROWEST_VARIANCE),
        }
    }

    /// One SLAM step: O(particles), one pass for weights and means, one for variances.
    pub fn update(&mut self, draws: &[Draw]) -> Update {
        let mut g = [0.0; 2];
        let mut weighted_sum = [0.0; 2];
        let responsibilities: Vec<[f64; 2]> = draws
            .iter()
            .map(|d| responsibilities_of(&self.mixture, d.value))
            .collect();
        for (d, r) in draws.iter().zip(&responsibilities) {
            for j in 0..2 {
                let w = d.quality * r[j];
                g[j] += w;
                weighted_sum[j] += w * d.value;
            }
        }
        self.history.push_back(g);
        while self.history.len() > self.window {
            self.history.pop_front();
        }
        let mut gains = [0.0; 2];
        let total_g = g[0] + g[1];
        for j in 0..2 {
            let window_total: f64 = self.history.iter().map(|h| h[j]).sum();
            if g[j] <= 0.0 || window_total <= 0.0 {
                continue;
            }
            let gain = g[j] / window_total;
            gains[j] = gain;
            let share = g[j] / total_g;
            let m = &mut self.mixture;
            m.weights[j] += gain * (share - m.weights[j]);
            m.means[j] += gain * (weighted_sum[j] / g[j] - m.means[j]);
            // Deviations are taken from the updated running mean, not from
            // this step's mean: the particles of one step only say where this
            // one motion went (their spread is the posterior's, far narrower
            // than the motion noise); the spread of the motion shows across steps.
            let variance = draws
                .iter()
                .zip(&responsibilities)
                .map(|(d, r)| d.quality * r[j] * (d.value - m.means[j]).powi(2))
                .sum::<f64>()
                / g[j];
            m.variances[j] =
                (m.variances[j] + gain * (variance - m.variances[j])).max(self.min_variance);
        }
        let total_weight = self.mixture.weights[0] + self.mixture.weights[1];
        if total_weight > 0.0 {
            self.mixture.weights = self.mixture.weights.map(|w| w / total_weight);
        }
        Update { weights: g, gains }
    }
}

/// p_j(x) / (p_1(x) + p_2(x)), computed from log densities so that draws far
/// in the tails do not underflow to 0/0.
fn responsibilities_of(mixture: &Mixture2, value: f64) -> [f64; 2] {
    let log_pdf = |j: usize| {
        let variance = mixture.variances[j].max(1e-300);
        -0.5 * (value - mixture.means[j]).powi(2) / variance
            - 0.5 * (std::f64::consts::TAU * variance).ln()
    };
    let (a, b) = (log_pdf(0), log_pdf(1));
    let top = a.max(b);
    if !top.is_finite() {
        return [0.5, 0.5];
    }
    let (ea, eb) = ((a - top).exp(), (b - top).exp());
    [ea / (ea + eb), eb / (ea + eb)]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn learner(window: usize) -> MixtureLearner {
        MixtureLearner::new(
            Mixture2 {
                weights: [0.5, 0.5],
                means: [0.0, 1.0],
                variances: [0.01, 0.01],
            },
            window,
        )
    }

    /// Two draws 0.05 either side of each centre, each of quality 1/4.
    fn pairs(low: f64, high: f64) -> Vec<Draw> {
        [low - 0.05, low + 0.05, high - 0.05, high + 0.05]
            .map(|value| Draw {
                value,
                quality: 0.25,
            })
            .to_vec()
    }

    #[test]
    fn a_component_whose_draws_all_lie_at_its_mean_narrows_to_half_its_start_and_no_further() {
        let mut learner = learner(5);
        // Every step's best draws sit on the components' means: the spread
        // about each mean is nothing, step after step.
        let at_the_means = [0.0, 1.0].map(|value| Draw {
            value,
            quality: 0.5,
        });
        for _ in 0..200 {
            learner.update(&at_the_means);
        }
        let floor = 0.01 * NARROWEST_SPREAD_OF_START.powi(2);
        for variance in learner.mixture.variances {
            assert!(
                (variance - floor).abs() < 1e-12,
                "{variance} against {floor}"
            );
        }
    }

    /// Hand-computed: each component owns its two draws, so g = (0.5, 0.5);
    /// the window holds 4 prior steps of 0.5 and this one, G = 2.5, gain 0.2.
    /// Mean: 0 + 0.2 (0.2 - 0) = 0.04. Variance about the new mean:
    /// ((0.15 - 0.04)^2 + (0.25 - 0.04)^2) / 2 = 0.0281, so 0.01 + 0.2 (0.0281 - 0.01) = 0.01362.
    #[test]
    fn a_step_moves_each_component_by_its_share_of_the_window() {
        let mut learner = learner(5);
        let update = learner.update(&pairs(0.2, 1.0));
        assert!((update.weights[0] - 0.5).abs() < 1e-9, "{update:?}");
        assert!((update.gains[0] - 0.2).abs() < 1e-9, "{update:?}");
        let m = learner.mixture;
        assert!((m.means[0] - 0.04).abs() < 1e-9, "{m:?}");
        assert!((m.variances[0] - 0.01362).abs() < 1e-9, "{m:?}");
        assert!(
            (m.means[1] - 1.0).abs() < 1e-9,
            "the other component's draws were centred: {m:?}"
        );
        assert!((m.weights[0] - 0.5).abs() < 1e-9, "{m:?}");
    }

    #[test]
    fn a_step_with_little_information_barely_moves_the_model() {
        let mut learner = learner(5);
        for _ in 0..5 {
            learner.update(&pairs(0.0, 1.0));
        }
        let before = learner.mixture;
        let faint: Vec<Draw> = pairs(0.2, 1.0)
            .into_iter()
            .map(|d| Draw {
                quality: 0.0005,
                ..d
            })
            .collect();
        let update = learner.update(&faint);
        assert!(update.gains[0] < 0.001);
        assert!((learner.mixture.means[0] - before.means[0]).abs() < 1e-3);
    }

    #[test]
    fn the_window_forgets_old_steps_so_a_change_is_tracked() {
        let mut learner = learner(5);
        for _ in 0..20 {
            learner.update(&pairs(0.0, 1.0));
        }
        for _ in 0..20 {
            learner.update(&pairs(0.3, 1.0));
        }
        assert!(
            (learner.mixture.means[0] - 0.3).abs() < 0.01,
            "{:?}",
            learner.mixture
        );
    }
}

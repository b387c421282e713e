use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// A mixture of two Gaussians: the thesis found it fits the distribution of a
/// legged robot's per-command motion best in over 90% of its datasets
/// (bimodal strides, skewed drift).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mixture2 {
    /// Weights of the two components; they sum to 1.
    pub weights: [f64; 2],
    pub means: [f64; 2],
    pub variances: [f64; 2],
}

/// Bounds on one step's motion (metres or radians) that a model may state.
pub const MAX_STEP_MEAN: f64 = 10.0;
pub const MAX_STEP_VARIANCE: f64 = 100.0;

impl Mixture2 {
    /// A single Gaussian written as a mixture of two equal halves.
    pub fn gaussian(mean: f64, std_dev: f64) -> Self {
        let variance = std_dev * std_dev;
        Self {
            weights: [0.5, 0.5],
            means: [mean, mean],
            variances: [variance, variance],
        }
    }

    /// Two modes at `mean - gap/2` and `mean + gap/2`.
    pub fn bimodal(mean: f64, gap: f64, std_dev: f64) -> Self {
        let variance = std_dev * std_dev;
        Self {
            weights: [0.5, 0.5],
            means: [mean - gap / 2.0, mean + gap / 2.0],
            variances: [variance, variance],
        }
    }

    /// A skewed distribution: a narrow main mode and a wide minority tail on
    /// the side of `tail_offset`'s sign.
    pub fn skewed(mean: f64, std_dev: f64, tail_offset: f64) -> Self {
        let variance = std_dev * std_dev;
        Self {
            weights: [0.75, 0.25],
            means: [mean, mean + tail_offset],
            variances: [variance, 4.0 * variance],
        }
    }

    pub fn mean(&self) -> f64 {
        self.weights[0] * self.means[0] + self.weights[1] * self.means[1]
    }

    pub fn variance(&self) -> f64 {
        let mean = self.mean();
        (0..2)
            .map(|j| self.weights[j] * (self.variances[j] + (self.means[j] - mean).powi(2)))
            .sum()
    }

    /// Density of component `j` at `value`, without its weight.
    pub fn component_pdf(&self, j: usize, value: f64) -> f64 {
        let variance = self.variances[j].max(1e-18);
        let z = value - self.means[j];
        (-0.5 * z * z / variance).exp() / (std::f64::consts::TAU * variance).sqrt()
    }

    pub fn pdf(&self, value: f64) -> f64 {
        (0..2)
            .map(|j| self.weights[j] * self.component_pdf(j, value))
            .sum()
    }

    pub fn sample(&self, rng: &mut impl Rng) -> f64 {
        let j = usize::from(rng.random::<f64>() >= self.weights[0]);
        let std_dev = self.variances[j].max(0.0).sqrt();
        match Normal::new(self.means[j], std_dev) {
            Ok(normal) => normal.sample(rng),
            Err(_) => self.means[j],
        }
    }

    /// Scales the random variable by `factor` (means by `factor`, variances by its square).
    pub fn scaled(&self, factor: f64) -> Self {
        Self {
            weights: self.weights,
            means: self.means.map(|m| m * factor),
            variances: self.variances.map(|v| v * factor * factor),
        }
    }

    /// Checks the invariants a model file must respect.
    pub fn validate(&self) -> Result<(), String> {
        // One step of a robot moves it metres and turns it radians, not
        // kilometres: larger values are typos, or a bus message that would
        // push a believed pose to infinity.
        for (j, v) in self.variances.iter().enumerate() {
            if !v.is_finite() || *v <= 0.0 || *v > MAX_STEP_VARIANCE {
                return Err(format!(
                    "variance {j} is {v}; it must be positive, at most {MAX_STEP_VARIANCE}"
                ));
            }
        }
        for (j, w) in self.weights.iter().enumerate() {
            if !w.is_finite() || *w < 0.0 {
                return Err(format!("weight {j} is {w}; it must be in [0, 1]"));
            }
        }
        let total = self.weights[0] + self.weights[1];
        if (total - 1.0).abs() > 1e-6 {
            return Err(format!("weights sum to {total}; they must sum to 1"));
        }
        if let Some(m) = self
            .means
            .iter()
            .find(|m| !m.is_finite() || m.abs() > MAX_STEP_MEAN)
        {
            return Err(format!(
                "a mean is {m}; it must be finite, at most {MAX_STEP_MEAN} in size"
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn samples_of_a_bimodal_mixture_match_its_moments() {
        let mixture = Mixture2::bimodal(0.146, 0.06, 0.01);
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let samples: Vec<f64> = (0..20_000).map(|_| mixture.sample(&mut rng)).collect();
        let mean = samples.iter().sum::<f64>() / samples.len() as f64;
        let variance =
            samples.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / samples.len() as f64;
        assert!((mean - mixture.mean()).abs() < 0.002, "mean {mean}");
        assert!(
            (variance - mixture.variance()).abs() < 0.1 * mixture.variance(),
            "variance {variance}"
        );
        // Bimodal: the trough at the mean is rarer than the modes.
        assert!(mixture.pdf(0.146) < 0.5 * mixture.pdf(0.116));
    }

    #[test]
    fn validation_rejects_negative_variance_and_bad_weights() {
        let mut mixture = Mixture2::gaussian(0.0, 1.0);
        mixture.variances[1] = -1.0;
        assert!(mixture.validate().unwrap_err().contains("variance 1"));
        let mut mixture = Mixture2::gaussian(0.0, 1.0);
        mixture.weights = [0.5, 0.6];
        assert!(mixture.validate().unwrap_err().contains("sum to"));
    }
}

//! Maximum-likelihood fit of effect parameters: Nelder-Mead (argmin) on the
//! negative log-likelihood with the noise profiled out, and standard errors
//! from the curvature of that likelihood at its minimum.

use argmin::core::{CostFunction, Error, Executor, State};
use argmin::solver::neldermead::NelderMead;
use shoal_physics::{CommandGrid, Effect, ScopedEffect, UnicycleModel};

use crate::likelihood::{Residual, residuals, score};
use crate::segments::Segment;

/// A fit: the free effects with their fitted values, the likelihood reached
/// and each parameter's standard error (NaN when the curvature is flat).
#[derive(Clone, Debug)]
pub struct Fitted {
    pub effects: Vec<ScopedEffect>,
    pub nll: f64,
    pub stderr: Vec<f64>,
    pub iterations: u64,
}

/// `effects` without the one at `k`: the model an effect is judged against.
pub(crate) fn all_but<T: Clone>(effects: &[T], k: usize) -> Vec<T> {
    effects
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != k)
        .map(|(_, e)| e.clone())
        .collect()
}

/// The simplex step of a parameter: the scale on which it matters.
pub fn step_of(effect: &Effect, name: &str) -> f64 {
    match (effect, name) {
        (Effect::Latency { .. } | Effect::ActuatorLag { .. }, _) => 0.05,
        (Effect::SpeedScale { .. } | Effect::TurnScale { .. }, _) => 0.05,
        (Effect::TurnBias { .. }, _) => 0.02,
        (Effect::HeadingDrift { .. }, _) => 0.05,
        (Effect::AccelLimit { .. }, _) => 1.0,
        (Effect::SpeedLimit { .. }, _) => 0.5,
        (Effect::Slip { .. }, _) => 0.2,
        (Effect::BatteryFade { .. }, _) => 0.01,
        (Effect::SurfaceZone { .. }, _) => 0.1,
        (Effect::ExternalFlow { .. }, _) => 0.01,
        (Effect::Hysteresis { .. }, _) => 0.05,
        (Effect::SpeedNoise { .. }, _) => 0.2,
        (Effect::TurnSpeedLoss { .. }, _) => 0.1,
        (Effect::TurnCentreOffset { .. }, _) => 0.03,
        (Effect::CrabAngle { .. }, _) => 0.02,
        (Effect::EulerStep { .. }, _) => 0.02,
    }
}

#[derive(Clone, Copy)]
struct Problem<'a> {
    grid: &'a CommandGrid,
    segments: &'a [Segment],
    fixed: &'a [ScopedEffect],
    free: &'a [ScopedEffect],
    /// The residuals, when every free effect changes only the noise (they
    /// are then the same for every parameter tried: computed once).
    noise_only: Option<&'a [Residual]>,
    /// What an unphysical parameter costs: worse than anything physical.
    out_of_bounds: f64,
}

impl Problem<'_> {
    fn effects(&self, params: &[f64]) -> Vec<ScopedEffect> {
        let mut offset = 0;
        self.free
            .iter()
            .map(|template| {
                let count = template.effect.params().len();
                let effect = template.effect.with_params(&params[offset..offset + count]);
                offset += count;
                ScopedEffect {
                    effect,
                    during: template.during,
                }
            })
            .collect()
    }

    fn nll(&self, params: &[f64]) -> f64 {
        let free = self.effects(params);
        if free.iter().any(|e| !e.effect.in_bounds()) {
            return self.out_of_bounds;
        }
        let model = UnicycleModel::with_effects(self.fixed.iter().cloned().chain(free).collect());
        let nll = match self.noise_only {
            Some(r) => score(&model, self.segments, r, None).nll,
            None => {
                let r = residuals(&model, self.grid, self.segments);
                score(&model, self.segments, &r, None).nll
            }
        };
        if nll.is_finite() {
            nll
        } else {
            self.out_of_bounds
        }
    }
}

impl CostFunction for Problem<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, params: &Self::Param) -> Result<Self::Output, Error> {
        Ok(self.nll(params))
    }
}

/// The likelihood of `fixed` effects alone.
pub fn nll_of(grid: &CommandGrid, segments: &[Segment], effects: &[ScopedEffect]) -> f64 {
    let model = UnicycleModel::with_effects(effects.to_vec());
    let r = residuals(&model, grid, segments);
    score(&model, segments, &r, None).nll
}

/// Fits the parameters of `free` (starting from their current values) with
/// `fixed` held as they are.
pub fn fit(
    grid: &CommandGrid,
    segments: &[Segment],
    fixed: &[ScopedEffect],
    free: &[ScopedEffect],
    max_iters: u64,
) -> Fitted {
    let start: Vec<f64> = free
        .iter()
        .flat_map(|e| e.effect.params().into_iter().map(|(_, v)| v))
        .collect();
    let steps: Vec<f64> = free
        .iter()
        .flat_map(|e| {
            e.effect
                .params()
                .into_iter()
                .map(|(name, _)| step_of(&e.effect, name))
        })
        .collect();
    let baseline = nll_of(grid, segments, fixed);
    // Nothing to fit (the others beside the one effect named): argmin's
    // Nelder-Mead indexes a simplex of one vertex out of bounds.
    if start.is_empty() {
        let model: Vec<ScopedEffect> = fixed.iter().chain(free).cloned().collect();
        return Fitted {
            effects: free.to_vec(),
            nll: nll_of(grid, segments, &model),
            stderr: Vec::new(),
            iterations: 0,
        };
    }
    let noise_only = free.iter().all(|e| e.effect.only_noise()).then(|| {
        let model = UnicycleModel::with_effects(fixed.iter().chain(free).cloned().collect());
        residuals(&model, grid, segments)
    });
    let problem = Problem {
        grid,
        segments,
        fixed,
        free,
        noise_only: noise_only.as_deref(),
        out_of_bounds: baseline.abs() * 10.0 + 1e12,
    };
    let mut simplex = vec![start.clone()];
    for (i, step) in steps.iter().enumerate() {
        let mut vertex = start.clone();
        vertex[i] += step;
        if problem.nll(&vertex) >= problem.out_of_bounds {
            vertex[i] = start[i] - step;
        }
        simplex.push(vertex);
    }
    let solver = NelderMead::new(simplex)
        .with_sd_tolerance(1e-3)
        .expect("a non-negative tolerance");
    let outcome = Executor::new(problem, solver)
        .configure(|state| state.max_iters(max_iters))
        .run();
    let (best, iterations) = match outcome {
        Ok(result) => {
            let state = result.state();
            (
                state.get_best_param().cloned().unwrap_or(start),
                state.get_iter(),
            )
        }
        Err(_) => (start, 0),
    };
    let nll = problem.nll(&best);
    let stderr = standard_errors(&problem, &best, nll, &steps);
    Fitted {
        effects: problem.effects(&best),
        nll,
        stderr,
        iterations,
    }
}

/// Standard errors from the inverse Hessian of the negative log-likelihood
/// (central differences).
fn standard_errors(problem: &Problem, at: &[f64], at_nll: f64, steps: &[f64]) -> Vec<f64> {
    let n = at.len();
    let h: Vec<f64> = steps.iter().map(|s| s * 0.02).collect();
    let f = |delta: &[(usize, f64)]| {
        let mut p = at.to_vec();
        for &(i, d) in delta {
            p[i] += d;
        }
        problem.nll(&p)
    };
    let mut hessian = vec![vec![0.0; n]; n];
    for i in 0..n {
        hessian[i][i] = (f(&[(i, h[i])]) - 2.0 * at_nll + f(&[(i, -h[i])])) / (h[i] * h[i]);
        for j in 0..i {
            let value = (f(&[(i, h[i]), (j, h[j])])
                - f(&[(i, h[i]), (j, -h[j])])
                - f(&[(i, -h[i]), (j, h[j])])
                + f(&[(i, -h[i]), (j, -h[j])]))
                / (4.0 * h[i] * h[j]);
            hessian[i][j] = value;
            hessian[j][i] = value;
        }
    }
    match invert(hessian) {
        Some(inverse) => (0..n)
            .map(|i| {
                let v = inverse[i][i];
                if v > 0.0 { v.sqrt() } else { f64::NAN }
            })
            .collect(),
        None => vec![f64::NAN; n],
    }
}

/// Gauss-Jordan inverse of a small matrix; `None` when singular.
fn invert(mut a: Vec<Vec<f64>>) -> Option<Vec<Vec<f64>>> {
    let n = a.len();
    let mut inverse: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect();
    for col in 0..n {
        let pivot = (col..n).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))?;
        if a[pivot][col].abs() < 1e-300 || !a[pivot][col].is_finite() {
            return None;
        }
        a.swap(col, pivot);
        inverse.swap(col, pivot);
        let d = a[col][col];
        for k in 0..n {
            a[col][k] /= d;
            inverse[col][k] /= d;
        }
        for row in 0..n {
            if row != col {
                let factor = a[row][col];
                for k in 0..n {
                    a[row][k] -= factor * a[col][k];
                    inverse[row][k] -= factor * inverse[col][k];
                }
            }
        }
    }
    Some(inverse)
}

#[cfg(test)]
mod tests {
    use shoal_physics::{CommandGrid, Effect, Pose, ScopedEffect};

    use super::{fit, invert, nll_of};
    use crate::segments::Segment;

    #[test]
    fn a_fit_with_nothing_free_is_the_likelihood_of_what_is_fixed() {
        // Selection refits the others beside an effect; with one effect
        // named there are none (robot 5's fourth block of MRCLAM, cut by
        // `scripts/transfer-table`, panicked in argmin there).
        let t: Vec<f64> = (0..=100).map(|k| f64::from(k) * 0.1).collect();
        let grid = CommandGrid::from_held(&t, &vec![0.2; t.len()], &vec![0.0; t.len()], 0.1);
        let segments: Vec<Segment> = (0..10)
            .map(|k| {
                let x = 0.2 * f64::from(k);
                let wobble = 0.01 * f64::from(k % 3) - 0.01;
                Segment {
                    from: 10 * k as usize,
                    to: 10 * (k as usize + 1),
                    t_start: f64::from(k),
                    t_end: f64::from(k + 1),
                    start: Pose {
                        x,
                        y: 0.0,
                        theta: 0.0,
                    },
                    end: Pose {
                        x: x + 0.2 + wobble,
                        y: wobble,
                        theta: wobble,
                    },
                    speed: 0.2,
                    turn: 0.0,
                    distance: 0.2,
                    mid: [x + 0.1, 0.0],
                }
            })
            .collect();
        let fitted = fit(&grid, &segments, &[], &[], 50);
        assert!(fitted.effects.is_empty());
        assert!(fitted.nll.is_finite());
        assert_eq!(fitted.nll, nll_of(&grid, &segments, &[]));
    }

    /// Segments standing or driven straight at up to 0.4 m/s, each ending
    /// off the plain model's prediction by noise whose variance is
    /// `1 + 3 (v / 0.2)^exponent` times the resting one.
    fn noise_growing_as(exponent: f64) -> (CommandGrid, Vec<Segment>) {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let normal = rand_distr::StandardNormal;
        let n = 3000;
        let speeds: Vec<f64> = (0..n).map(|k| 0.05 * f64::from(k % 9)).collect();
        let t: Vec<f64> = (0..n).map(f64::from).collect();
        let grid = CommandGrid::from_held(&t, &speeds, &vec![0.0; t.len()], 0.1);
        let segments = (0..n as usize - 1)
            .map(|k| {
                let v = speeds[k];
                let sd = 1e-3 * (1.0 + 3.0 * (v / 0.2).powf(exponent)).sqrt();
                let mut noise = || sd * rng.sample::<f64, _>(normal);
                // Across, a heading error's share on top (as `likelihood`
                // takes it out), else its growth with distance, which on
                // 1 s segments is speed itself, takes part of the exponent.
                let (along, across, heading) = (noise(), noise(), noise());
                Segment {
                    from: 10 * k,
                    to: 10 * (k + 1),
                    t_start: k as f64,
                    t_end: (k + 1) as f64,
                    start: Pose::new(0.0, 0.0, 0.0),
                    end: Pose::new(v + along, across + 0.5 * v * heading, heading),
                    speed: v,
                    turn: 0.0,
                    distance: v,
                    mid: [0.5 * v, 0.0],
                }
            })
            .collect();
        (grid, segments)
    }

    /// Noise that accrues per metre driven and wheel noise in proportion to
    /// wheel speed grow the variance as speed and as its square: the law
    /// written fits better than the other, and its share at the usual speed
    /// is the one written (three quarters of the variance at 0.2 m/s).
    #[test]
    fn speed_noise_tells_noise_per_metre_from_noise_in_proportion_to_speed() {
        let laws = shoal_physics::effects::SPEED_NOISE_EXPONENTS;
        for (written, truth) in laws.into_iter().enumerate() {
            let (grid, segments) = noise_growing_as(truth);
            let fitted = laws.map(|exponent| {
                let start = ScopedEffect::always(Effect::SpeedNoise {
                    driving_share: 0.0,
                    exponent,
                    at_m_per_s: 0.2,
                });
                fit(&grid, &segments, &[], &[start], 400)
            });
            let (right, wrong) = (&fitted[written], &fitted[1 - written]);
            assert!(
                right.nll < wrong.nll - 10.0,
                "{truth}: {} against {}",
                right.nll,
                wrong.nll
            );
            let Effect::SpeedNoise { driving_share, .. } = right.effects[0].effect else {
                panic!("{:?}", right.effects);
            };
            assert!(
                (driving_share - 0.75).abs() < 0.05,
                "{truth}: {driving_share}"
            );
        }
    }

    #[test]
    fn inverts_a_small_matrix() {
        let inverse = invert(vec![vec![4.0, 7.0], vec![2.0, 6.0]]).expect("regular");
        let expected = [[0.6, -0.7], [-0.2, 0.4]];
        for i in 0..2 {
            for j in 0..2 {
                assert!((inverse[i][j] - expected[i][j]).abs() < 1e-12);
            }
        }
        assert!(invert(vec![vec![1.0, 2.0], vec![2.0, 4.0]]).is_none());
    }
}

//! How good a formation is: the numbers the thesis's pictures show.

use glam::DVec2;
use serde::Serialize;

#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FormationMetrics {
    pub agents: usize,
    /// Groups of agents linked by gaps of at most `LINK_FACTOR` spreads.
    pub components: usize,
    /// Mean nearest-neighbour distance divided by the desired spread.
    pub spacing_ratio: f64,
    /// Coefficient of variation of the nearest-neighbour distances.
    pub spacing_cv: f64,
}

/// A formation counts as formed when it is one group with mean spacing within
/// this fraction of the desired spread.
pub const SPACING_TOLERANCE: f64 = 0.15;

impl FormationMetrics {
    /// One group, spaced as the formation asks (within [`SPACING_TOLERANCE`]).
    pub fn is_formed(&self) -> bool {
        self.components == 1 && (self.spacing_ratio - 1.0).abs() <= SPACING_TOLERANCE
    }
}

/// Two agents closer than this many spreads belong to one group.
pub const LINK_FACTOR: f64 = 1.5;

/// The mean of `points`; the origin for none.
pub fn centroid(points: &[DVec2]) -> DVec2 {
    points.iter().copied().sum::<DVec2>() / points.len().max(1) as f64
}

pub fn formation_metrics(positions: &[DVec2], spread: f64) -> FormationMetrics {
    let n = positions.len();
    if n == 0 {
        return FormationMetrics::default();
    }
    let nearest: Vec<f64> = (0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| j != i)
                .map(|j| positions[i].distance(positions[j]))
                .fold(f64::INFINITY, f64::min)
        })
        .filter(|d| d.is_finite())
        .collect();
    let (spacing_ratio, spacing_cv) = if nearest.is_empty() {
        (0.0, 0.0)
    } else {
        let mean = nearest.iter().sum::<f64>() / nearest.len() as f64;
        let variance =
            nearest.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / nearest.len() as f64;
        (
            mean / spread,
            if mean > 0.0 {
                variance.sqrt() / mean
            } else {
                0.0
            },
        )
    };
    FormationMetrics {
        agents: n,
        components: components(positions, LINK_FACTOR * spread),
        spacing_ratio,
        spacing_cv,
    }
}

fn components(positions: &[DVec2], link: f64) -> usize {
    let n = positions.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for j in i + 1..n {
            if positions[i].distance(positions[j]) <= link {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a] = b;
            }
        }
    }
    (0..n).filter(|&i| root(&mut parent, i) == i).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_lattice_is_one_evenly_spaced_group() {
        let lattice: Vec<DVec2> = (0..16)
            .map(|i| DVec2::new(f64::from(i % 4), f64::from(i / 4)))
            .collect();
        let metrics = formation_metrics(&lattice, 1.0);
        assert_eq!(metrics.components, 1);
        assert!((metrics.spacing_ratio - 1.0).abs() < 1e-12 && metrics.spacing_cv < 1e-12);
    }

    #[test]
    fn distant_clusters_count_as_separate_groups() {
        let clusters = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(10.0, 0.0),
            DVec2::new(11.0, 0.0),
        ];
        assert_eq!(formation_metrics(&clusters, 1.0).components, 2);
    }
}

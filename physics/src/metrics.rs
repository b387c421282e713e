//! How good a formation is: the numbers the thesis's pictures show.

use std::collections::HashMap;

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
    let grid = Grid::new(positions, LINK_FACTOR * spread);
    let nearest: Vec<f64> = (0..n)
        .map(|i| grid.nearest(i))
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
        components: components(&grid),
        spacing_ratio,
        spacing_cv,
    }
}

/// Positions bucketed in square cells of side `side`: every position within
/// `side` of a point lies in the 3 x 3 cells around that point's own, so the
/// metrics of a thousand robots need not compare every pair (they did, 20
/// times a second in `shoal up`, for a tenth of a core).
struct Grid<'a> {
    positions: &'a [DVec2],
    side: f64,
    cells: HashMap<(i64, i64), Vec<usize>>,
}

impl<'a> Grid<'a> {
    fn new(positions: &'a [DVec2], side: f64) -> Self {
        let mut grid = Self {
            positions,
            side,
            cells: HashMap::new(),
        };
        for (i, p) in positions.iter().enumerate() {
            grid.cells.entry(grid.key(*p)).or_default().push(i);
        }
        grid
    }

    fn key(&self, p: DVec2) -> (i64, i64) {
        (
            (p.x / self.side).floor() as i64,
            (p.y / self.side).floor() as i64,
        )
    }

    /// The others in the 3 x 3 cells around position `i`.
    fn around(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        let (cx, cy) = self.key(self.positions[i]);
        (cx - 1..=cx + 1)
            .flat_map(move |x| (cy - 1..=cy + 1).map(move |y| (x, y)))
            .filter_map(|key| self.cells.get(&key))
            .flatten()
            .copied()
            .filter(move |&j| j != i)
    }

    /// The distance from position `i` to its nearest other.
    fn nearest(&self, i: usize) -> f64 {
        let p = self.positions[i];
        let near = self
            .around(i)
            .map(|j| p.distance(self.positions[j]))
            .fold(f64::INFINITY, f64::min);
        if near <= self.side {
            return near;
        }
        // Nothing within a cell's side: the nearest may lie further out.
        (0..self.positions.len())
            .filter(|&j| j != i)
            .map(|j| p.distance(self.positions[j]))
            .fold(f64::INFINITY, f64::min)
    }
}

/// Groups of positions linked by gaps of at most the grid's side.
fn components(grid: &Grid) -> usize {
    let n = grid.positions.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for j in grid.around(i).filter(|&j| j > i) {
            if grid.positions[i].distance(grid.positions[j]) <= grid.side {
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

    #[test]
    fn the_grid_agrees_with_comparing_every_pair() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        for (count, side) in [(2, 1.0), (50, 3.0), (400, 20.0), (400, 60.0)] {
            let positions: Vec<DVec2> = (0..count)
                .map(|_| DVec2::new(rng.random_range(0.0..side), rng.random_range(0.0..side)))
                .collect();
            let n = positions.len();
            let link = LINK_FACTOR;
            let nearest: Vec<f64> = (0..n)
                .map(|i| {
                    (0..n)
                        .filter(|&j| j != i)
                        .map(|j| positions[i].distance(positions[j]))
                        .fold(f64::INFINITY, f64::min)
                })
                .collect();
            let mut groups: Vec<usize> = (0..n).collect();
            // Label propagation over every pair, slow and plain.
            loop {
                let mut changed = false;
                for i in 0..n {
                    for j in 0..n {
                        if positions[i].distance(positions[j]) <= link && groups[j] < groups[i] {
                            groups[i] = groups[j];
                            changed = true;
                        }
                    }
                }
                if !changed {
                    break;
                }
            }
            groups.sort_unstable();
            groups.dedup();
            let grid = Grid::new(&positions, link);
            for (i, expected) in nearest.iter().enumerate() {
                assert_eq!(grid.nearest(i), *expected, "{count} in {side} m, robot {i}");
            }
            assert_eq!(components(&grid), groups.len(), "{count} in {side} m");
        }
    }
}

//! An occupancy grid in log-odds, stored as copy-on-write tiles: particles
//! that descend from one another share every tile neither has changed since,
//! so no particle copies a whole map per step.

use std::sync::Arc;

use glam::DVec2;

/// Cells per tile side.
const TILE: usize = 16;
/// Log-odds added to a cell a beam ended in, and to one it passed through.
const HIT: f32 = 0.9;
const MISS: f32 = -0.4;
/// A beam that hit something frees no cell this near its end (in metres,
/// each way): the inverse sensor model's obstacle thickness (Thrun, Burgard
/// and Fox, Probabilistic Robotics, table 9.2). A beam that meets a wall at
/// a grazing angle runs along the wall's own cells for several cells before
/// it ends; freeing them all, every such beam eroded walls that steeper
/// beams had drawn, more on the side the robot saw them at a slant, and the
/// scan was matched off them: when the stop came (3df61ae), the crowd's
/// robot 0 ended 0.25 m off (seeds 0-19) where it then ended 0.13 m, and a
/// lone robot with its true model had been 5 cm off from its first steps.
/// 0.1-0.25 m did alike (EXPERIMENTS.md 8b says on which runs).
const FREE_STOP_M: f64 = 0.15;
/// Log-odds are clamped so a cell can change its mind.
const CLAMP: f32 = 6.0;

type Tile = [f32; TILE * TILE];

#[derive(Clone, Debug)]
pub struct TiledGrid {
    /// World position of the corner of cell (0, 0).
    pub origin: DVec2,
    pub cell_size: f64,
    pub width: usize,
    pub height: usize,
    tiles_x: usize,
    tiles: Vec<Arc<Tile>>,
}

impl TiledGrid {
    /// An unknown map covering `[0, width_m] x [0, height_m]`.
    pub fn new(width_m: f64, height_m: f64, cell_size: f64) -> Self {
        Self::covering(DVec2::ZERO, DVec2::new(width_m, height_m), cell_size)
    }

    /// An unknown map covering the rectangle from `min` to `max`.
    pub fn covering(min: DVec2, max: DVec2, cell_size: f64) -> Self {
        let width = ((max.x - min.x) / cell_size).ceil().max(1.0) as usize;
        let height = ((max.y - min.y) / cell_size).ceil().max(1.0) as usize;
        let tiles_x = width.div_ceil(TILE);
        let tiles_y = height.div_ceil(TILE);
        let blank = Arc::new([0.0; TILE * TILE]);
        Self {
            origin: min,
            cell_size,
            width,
            height,
            tiles_x,
            tiles: vec![blank; tiles_x * tiles_y],
        }
    }

    pub fn cell_of(&self, p: DVec2) -> Option<(usize, usize)> {
        let local = p - self.origin;
        let (cx, cy) = (
            (local.x / self.cell_size).floor(),
            (local.y / self.cell_size).floor(),
        );
        (cx >= 0.0 && cy >= 0.0 && (cx as usize) < self.width && (cy as usize) < self.height)
            .then_some((cx as usize, cy as usize))
    }

    fn index(&self, (cx, cy): (usize, usize)) -> (usize, usize) {
        (
            (cy / TILE) * self.tiles_x + cx / TILE,
            (cy % TILE) * TILE + cx % TILE,
        )
    }

    pub fn log_odds(&self, cell: (usize, usize)) -> f32 {
        let (tile, offset) = self.index(cell);
        self.tiles[tile][offset]
    }

    /// Probability that the cell is occupied.
    pub fn occupancy(&self, cell: (usize, usize)) -> f32 {
        1.0 / (1.0 + (-self.log_odds(cell)).exp())
    }

    /// The highest occupancy near `p`, each cell's discounted by the
    /// Gaussian weight `tolerance` gives its distance from `p`: a beam that
    /// ends where the range noise could have put it off an obstacle still
    /// scores. Far beams are noisier, so their tolerance is wider; with a
    /// fixed one-cell tolerance a 10 m beam scores by chance. Only cells
    /// more likely occupied than not count: a beam ending in space never
    /// seen scores as one ending in free space, nothing. Scored by the
    /// occupancy of the unseen cell (a half), a robot whose beams reached
    /// past the walls it had mapped, onto unseen ground, was scored higher
    /// the farther behind it was believed, and the estimate lagged (one
    /// robot of the crowd 0.6-1.2 m off, a lone robot 0.26 m). The distance
    /// is from `p` itself, not from the cell it lies in, so the score
    /// changes within a cell and a scan can be matched finer than the map.
    pub fn occupancy_within(&self, p: DVec2, tolerance: &Tolerance) -> f32 {
        let Some((cx, cy)) = self.cell_of(p) else {
            return 0.0;
        };
        let local = (p - self.origin) / self.cell_size;
        let mut best = 0.0f32;
        // Nearest cells first: once no cell left can weigh more than the
        // best found (a wall at the beam's end usually settles it within
        // the first ring), the rest of the window holds nothing better.
        for &(i, j, bound) in &tolerance.by_distance {
            if bound <= best {
                break;
            }
            let (Some(x), Some(y)) = (cx.checked_add_signed(i), cy.checked_add_signed(j)) else {
                continue;
            };
            if x >= self.width || y >= self.height {
                continue;
            }
            let odds = self.log_odds((x, y));
            // Only cells more likely occupied than not count.
            if odds > 0.0 {
                let (dx, dy) = (local.x - (x as f64 + 0.5), local.y - (y as f64 + 0.5));
                let weight = tolerance.weight(dx * dx + dy * dy);
                // An occupancy is at most 1: a cell whose weight alone
                // does not beat the best needs no exp.
                if weight > best {
                    best = best.max(weight / (1.0 + (-odds).exp()));
                }
            }
        }
        best
    }

    /// Marks the cells from `from` towards `to` free, and the last one
    /// occupied when the beam hit something; a beam that hit frees none
    /// within [`FREE_STOP_M`] of its end.
    pub fn integrate_beam(&mut self, from: DVec2, to: DVec2, hit: bool) {
        let (Some(start), Some(end)) = (self.cell_of(from), self.cell_of(to)) else {
            return;
        };
        let (mut x, mut y) = (start.0 as i64, start.1 as i64);
        let (x1, y1) = (end.0 as i64, end.1 as i64);
        let stop = (FREE_STOP_M / self.cell_size).round() as i64;
        let (dx, dy) = ((x1 - x).abs(), -(y1 - y).abs());
        let (sx, sy) = (if x < x1 { 1 } else { -1 }, if y < y1 { 1 } else { -1 });
        let mut error = dx + dy;
        // A beam crosses few tiles: each is made writable once, not once a
        // cell (copy-on-write shares tiles between particles).
        let tiles_x = self.tiles_x;
        let mut writable: Option<(usize, &mut Tile)> = None;
        loop {
            let last = (x, y) == (x1, y1);
            let (cx, cy) = (x as usize, y as usize);
            let tile = (cy / TILE) * tiles_x + cx / TILE;
            if writable.as_ref().is_none_or(|(t, _)| *t != tile) {
                writable = Some((tile, Arc::make_mut(&mut self.tiles[tile])));
            }
            if let Some((_, cells)) = writable.as_mut() {
                let offset = (cy % TILE) * TILE + cx % TILE;
                let delta = if last && hit {
                    HIT
                } else if hit && (x - x1).abs().max((y - y1).abs()) <= stop {
                    // Where a wall may be: neither free nor hit.
                    0.0
                } else {
                    MISS
                };
                cells[offset] = (cells[offset] + delta).clamp(-CLAMP, CLAMP);
            }
            if last {
                break;
            }
            let doubled = 2 * error;
            if doubled >= dy {
                error += dy;
                x += sx;
            }
            if doubled <= dx {
                error += dx;
                y += sy;
            }
        }
    }

    /// How many tiles this grid shares with `other` (same allocation).
    /// The map coarsened so neither side exceeds `max_side` cells, as ROS
    /// occupancy (0 free .. 100 occupied, 255 never observed): returns
    /// width, height, the coarse cell size and the cells, row by row from
    /// the origin.
    pub fn coarsened(&self, max_side: usize) -> (usize, usize, f64, Vec<u8>) {
        let factor = self.width.max(self.height).div_ceil(max_side.max(1)).max(1);
        let (width, height) = (self.width.div_ceil(factor), self.height.div_ceil(factor));
        let mut cells = vec![255u8; width * height];
        for row in 0..height {
            for col in 0..width {
                // A coarse cell is as occupied as its most occupied fine cell,
                // so thin walls survive coarsening.
                let mut observed = false;
                let mut most = 0.0f32;
                for y in row * factor..((row + 1) * factor).min(self.height) {
                    for x in col * factor..((col + 1) * factor).min(self.width) {
                        let odds = self.log_odds((x, y));
                        if odds != 0.0 {
                            observed = true;
                            most = most.max(1.0 / (1.0 + (-odds).exp()));
                        }
                    }
                }
                if observed {
                    cells[row * width + col] = (most * 100.0).round() as u8;
                }
            }
        }
        (width, height, self.cell_size * factor as f64, cells)
    }

    pub fn shared_tiles(&self, other: &Self) -> usize {
        self.tiles
            .iter()
            .zip(&other.tiles)
            .filter(|(a, b)| Arc::ptr_eq(a, b))
            .count()
    }

    pub fn tile_count(&self) -> usize {
        self.tiles.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_coarsened_map_keeps_walls_and_unknown_space() {
        let mut grid = TiledGrid::new(4.0, 2.0, 0.05);
        grid.integrate_beam(DVec2::new(0.5, 1.0), DVec2::new(3.0, 1.0), true);
        let (width, height, cell, cells) = grid.coarsened(20);
        assert_eq!((width, height), (20, 10));
        assert!((cell - 0.2).abs() < 1e-12);
        let at = |x: f64, y: f64| cells[(y / cell) as usize * width + (x / cell) as usize];
        assert!(at(3.0, 1.0) > 50, "the hit is occupied");
        assert!(at(1.5, 1.0) < 50, "the beam's path is free");
        assert_eq!(at(1.5, 0.1), 255, "never observed");
    }

    /// The window's best weighted occupancy, cell by cell: what
    /// `occupancy_within`'s tile runs and row skipping must equal.
    fn occupancy_within_cell_by_cell(grid: &TiledGrid, p: DVec2, tolerance: &Tolerance) -> f32 {
        let Some((cx, cy)) = grid.cell_of(p) else {
            return 0.0;
        };
        let local = (p - grid.origin) / grid.cell_size;
        let reach = tolerance
            .by_distance
            .iter()
            .map(|&(i, _, _)| i.unsigned_abs())
            .max()
            .unwrap_or(0);
        let mut best = 0.0f32;
        for y in cy.saturating_sub(reach)..=(cy + reach).min(grid.height - 1) {
            for x in cx.saturating_sub(reach)..=(cx + reach).min(grid.width - 1) {
                let (dx, dy) = (local.x - (x as f64 + 0.5), local.y - (y as f64 + 0.5));
                let weight = tolerance.weight(dx * dx + dy * dy);
                if grid.log_odds((x, y)) > 0.0 {
                    best = best.max(weight * grid.occupancy((x, y)));
                }
            }
        }
        best
    }

    #[test]
    fn the_window_scan_equals_scoring_cell_by_cell_across_tile_edges() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut grid = TiledGrid::new(3.0, 2.0, 0.05);
        for _ in 0..300 {
            let from = DVec2::new(rng.random_range(0.0..3.0), rng.random_range(0.0..2.0));
            let to = DVec2::new(rng.random_range(0.0..3.0), rng.random_range(0.0..2.0));
            grid.integrate_beam(from, to, rng.random_bool(0.7));
        }
        for sigma in [0.03, 0.1, 0.3] {
            let tolerance = Tolerance::new(sigma, 0.05);
            for _ in 0..3000 {
                let p = DVec2::new(rng.random_range(-0.1..3.1), rng.random_range(-0.1..2.1));
                let (fast, slow) = (
                    grid.occupancy_within(p, &tolerance),
                    occupancy_within_cell_by_cell(&grid, p, &tolerance),
                );
                assert!((fast - slow).abs() < 1e-6, "{p}: {fast} against {slow}");
            }
        }
    }

    #[test]
    fn a_beam_frees_its_path_and_occupies_its_end() {
        let mut grid = TiledGrid::new(2.0, 1.0, 0.05);
        for _ in 0..3 {
            grid.integrate_beam(DVec2::new(0.1, 0.5), DVec2::new(1.5, 0.5), true);
        }
        assert!(grid.occupancy(grid.cell_of(DVec2::new(1.5, 0.5)).expect("in map")) > 0.9);
        assert!(grid.occupancy(grid.cell_of(DVec2::new(0.8, 0.5)).expect("in map")) < 0.3);
        assert!(
            (grid.occupancy(grid.cell_of(DVec2::new(0.8, 0.9)).expect("in map")) - 0.5).abs()
                < 1e-6,
            "untouched"
        );
    }

    #[test]
    fn a_beam_grazing_a_wall_does_not_erase_it_near_its_end() {
        let mut grid = TiledGrid::new(2.0, 1.0, 0.05);
        let wall = DVec2::new(1.01, 0.52);
        // Seen head on once: one hit.
        grid.integrate_beam(DVec2::new(1.01, 0.1), wall, true);
        let cell = grid.cell_of(wall).expect("in map");
        assert!(grid.occupancy(cell) > 0.6);
        // Three beams that run along the wall's row for its last ten cells
        // and end two cells past it: each would have freed it.
        for _ in 0..3 {
            grid.integrate_beam(DVec2::new(0.21, 0.46), DVec2::new(1.11, 0.52), true);
        }
        assert!(
            grid.occupancy(cell) > 0.6,
            "the wall's cell, {} cells from the grazing beams' end, stays occupied",
            grid.cell_of(DVec2::new(1.11, 0.52)).expect("in map").0 - cell.0
        );
        // Farther back along the beam, cells are freed as before.
        let behind = grid.cell_of(DVec2::new(0.4, 0.47)).expect("in map");
        assert!(grid.occupancy(behind) < 0.3);
    }

    #[test]
    fn copies_share_tiles_until_one_changes_them() {
        let mut a = TiledGrid::new(3.2, 3.2, 0.05);
        let mut b = a.clone();
        assert_eq!(a.shared_tiles(&b), a.tile_count());
        b.integrate_beam(DVec2::new(0.1, 0.1), DVec2::new(0.5, 0.1), true);
        let shared = a.shared_tiles(&b);
        assert!(
            shared < a.tile_count() && shared >= a.tile_count() - 2,
            "only the touched tile was copied: {shared}"
        );
        a.integrate_beam(DVec2::new(3.0, 3.0), DVec2::new(3.1, 3.0), false);
        assert!(a.shared_tiles(&b) < shared);
    }
}

/// How far from a beam's end an obstacle still explains it, for
/// [`TiledGrid::occupancy_within`]: Gaussian weights by cell offset,
/// computed once per beam rather than once per particle.
#[derive(Clone, Debug)]
pub struct Tolerance {
    /// Weight by squared distance in cells, in steps of 1 / [`Self::STEPS`].
    weights: Vec<f32>,
    /// The window's cell offsets, nearest first, each with the most any
    /// point of the centre cell can weigh it (its nearest edge's distance).
    by_distance: Vec<(isize, isize, f32)>,
}

impl Tolerance {
    /// Most cells a tolerance reaches out, each way: past 2 sigma the
    /// weight is below 0.14, and a wider window costs quadratically.
    const MAX_REACH: usize = 6;
    /// Steps per squared cell of the weight table: a sixteenth of a cell
    /// squared, finer than a scan is matched.
    const STEPS: f64 = 16.0;

    /// A tolerance of `sigma` metres (at least one cell) on cells of `cell_size`.
    pub fn new(sigma: f64, cell_size: f64) -> Self {
        let sigma_cells = sigma.max(cell_size) / cell_size;
        let reach = ((2.0 * sigma_cells).ceil() as usize).clamp(1, Self::MAX_REACH);
        // The farthest cell centre in the window from a point in its
        // middle cell: reach + 1/2 cells on each axis.
        let farthest = 2.0 * (reach as f64 + 0.5).powi(2);
        let weights = (0..=(farthest * Self::STEPS).ceil() as usize)
            .map(|k| {
                let squared = k as f64 / Self::STEPS;
                (-0.5 * squared / (sigma_cells * sigma_cells)).exp() as f32
            })
            .collect();
        let mut tolerance = Self {
            weights,
            by_distance: Vec::new(),
        };
        let r = reach as isize;
        let nearest = |k: isize| (k.abs() as f64 - 0.5).max(0.0);
        let mut by_distance: Vec<(isize, isize, f32)> = (-r..=r)
            .flat_map(|j| (-r..=r).map(move |i| (i, j)))
            .map(|(i, j)| {
                let squared = nearest(i).powi(2) + nearest(j).powi(2);
                (i, j, tolerance.weight(squared))
            })
            .collect();
        // Heaviest bound first; ties keep their order.
        by_distance.sort_by(|a, b| b.2.total_cmp(&a.2));
        tolerance.by_distance = by_distance;
        tolerance
    }

    /// The weight at `squared` cells squared from the beam's end.
    fn weight(&self, squared: f64) -> f32 {
        // Rounded by truncation after adding a half (the distance is never
        // negative): `f64::round` was 13% of the filter's time (perf,
        // BENCHMARKS.md "SLAM").
        self.weights
            .get((squared * Self::STEPS + 0.5) as usize)
            .copied()
            .unwrap_or(0.0)
    }
}

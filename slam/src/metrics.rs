//! How good a SLAM run was, against the truth: the map's share of wrongly
//! classified cells and the learned model's distance from the body's.

use glam::DVec2;
use shoal_physics::Arena;

/// A coarse map as viewers get it: ROS occupancy (0 free .. 100 occupied,
/// 255 unknown), row by row from `origin`.
pub struct CoarseMap<'a> {
    pub width: usize,
    pub height: usize,
    pub cell_size: f64,
    pub origin: DVec2,
    pub cells: &'a [u8],
}

/// Of the cells the map has observed, the share classified wrongly: a cell
/// is truly occupied when any of nine points across it is inside an
/// obstacle or outside the arena (the coarse map keeps a cell's most
/// occupied part, so thin walls count).
pub fn map_error(map: &CoarseMap, arena: &Arena) -> Option<f64> {
    let (mut observed, mut wrong) = (0usize, 0usize);
    for row in 0..map.height {
        for col in 0..map.width {
            let value = map.cells.get(row * map.width + col).copied().unwrap_or(255);
            if value == 255 {
                continue;
            }
            observed += 1;
            let corner = map.origin + DVec2::new(col as f64, row as f64) * map.cell_size;
            let occupied = (0..3).any(|i| {
                (0..3).any(|j| {
                    let p = corner
                        + DVec2::new(0.25 + 0.25 * i as f64, 0.25 + 0.25 * j as f64)
                            * map.cell_size;
                    arena.blocks(p, 1e-9)
                })
            });
            if (value >= 50) != occupied {
                wrong += 1;
            }
        }
    }
    (observed > 0).then(|| wrong as f64 / observed as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use shoal_physics::Obstacle;

    #[test]
    fn a_map_that_matches_the_arena_has_no_error_and_a_wrong_cell_counts() {
        let arena = Arena {
            width: 2.0,
            height: 1.0,
            walls: vec![],
            obstacles: vec![Obstacle::Box {
                min: [1.0, 0.0],
                max: [2.0, 1.0],
            }],
            surfaces: vec![],
        };
        // Four cells of 0.5 m from (0, 0): two free, two occupied, one row of each.
        let map = |cells| CoarseMap {
            width: 4,
            height: 2,
            cell_size: 0.5,
            origin: DVec2::ZERO,
            cells,
        };
        assert_eq!(
            map_error(&map(&[0, 0, 100, 100, 0, 0, 100, 100]), &arena),
            Some(0.0)
        );
        // One free cell taken for occupied, one cell never seen.
        let error = map_error(&map(&[100, 0, 100, 100, 0, 0, 100, 255]), &arena);
        assert_eq!(error, Some(1.0 / 7.0));
    }
}

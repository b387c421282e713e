//! Which cells' poses a host asks the others for: every cell within the
//! widest listening radius of one of its robots. A cell is let go only
//! once no robot is within half a cell more, so a robot near the edge does
//! not make the link declare and undeclare its subscription period after
//! period.

use std::collections::BTreeSet;

use shoal_broker::{CellExchange, CellKey};

pub struct Interest {
    cells: CellExchange,
    cell_size: f64,
    /// How far the farthest-listening robot listens.
    radius: f64,
}

/// What changed in the cells asked for.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct Change {
    pub add: Vec<CellKey>,
    pub drop: Vec<CellKey>,
}

impl Interest {
    pub fn new(cell_size: f64, radius: f64) -> Self {
        Self {
            cells: CellExchange::new(cell_size),
            cell_size,
            radius,
        }
    }

    /// The cells to add and drop, given the cells asked for now and where
    /// this host's robots stand.
    pub fn update(&self, wanted: &BTreeSet<CellKey>, robots: &[(f64, f64)]) -> Change {
        let needed: BTreeSet<CellKey> = robots
            .iter()
            .flat_map(|&(x, y)| self.cells.cells_within(x, y, self.radius))
            .collect();
        let kept: BTreeSet<CellKey> = robots
            .iter()
            .flat_map(|&(x, y)| {
                self.cells
                    .cells_within(x, y, self.radius + self.cell_size / 2.0)
            })
            .collect();
        Change {
            add: needed.difference(wanted).copied().collect(),
            drop: wanted
                .iter()
                .filter(|cell| !kept.contains(cell))
                .copied()
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_are_asked_for_near_robots_and_let_go_only_well_away() {
        // 2 m cells, a 3 m radius: cell 0 spans x in [0, 2), cell 4 [8, 10).
        let interest = Interest::new(2.0, 3.0);
        let start = interest.update(&BTreeSet::new(), &[(4.5, 5.0)]);
        assert!(start.drop.is_empty());
        let wanted: BTreeSet<CellKey> = start.add.iter().copied().collect();
        // From x = 4.5: cell 0 is 2.5 m away, cell 4 3.5 m.
        assert!(wanted.contains(&(0, 2)) && wanted.contains(&(3, 2)));
        assert!(!wanted.contains(&(4, 2)), "{wanted:?}");
        // From x = 4.9 cell 0 is still within reach: nothing changes.
        assert_eq!(interest.update(&wanted, &[(4.9, 5.0)]), Change::default());
        // From x = 6.2 cell 4 comes within 3 m, and cell 0 is 4.2 m away,
        // beyond the half cell it is kept for.
        let moved = interest.update(&wanted, &[(6.2, 5.0)]);
        assert!(moved.add.contains(&(4, 2)), "{moved:?}");
        assert!(moved.drop.contains(&(0, 2)), "{moved:?}");
        // No robot left: every cell goes.
        let gone = interest.update(&wanted, &[]);
        assert!(gone.add.is_empty());
        assert_eq!(gone.drop.len(), wanted.len());
    }
}

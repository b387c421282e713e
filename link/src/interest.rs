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
        let interest = Interest::new(2.0, 3.0);
        let start = interest.update(&BTreeSet::new(), &[(5.0, 5.0)]);
        assert!(start.drop.is_empty());
        let wanted: BTreeSet<CellKey> = start.add.iter().copied().collect();
        // Within the radius: 3 m from (5, 5) reaches cells 0 and 4, not 5.
        assert!(wanted.contains(&(0, 2)) && wanted.contains(&(4, 2)));
        assert!(!wanted.contains(&(5, 2)), "{wanted:?}");
        // Moved 0.4 m: cell 4 is 3.4 m away, within the half cell kept.
        assert_eq!(interest.update(&wanted, &[(4.6, 5.0)]), Change::default());
        // Moved 1.1 m: cell 4 is 4.1 m away and goes; nothing is added.
        let moved = interest.update(&wanted, &[(3.9, 5.0)]);
        assert!(
            moved.add.is_empty() && moved.drop.contains(&(4, 2)),
            "{moved:?}"
        );
        // No robot left: every cell goes.
        let gone = interest.update(&wanted, &[]);
        assert!(gone.add.is_empty());
        assert_eq!(gone.drop.len(), wanted.len());
    }
}

//! Which cells' poses a host asks the others for: the cells its robots
//! listen to now, read from its iceoryx2 domain (a cell service with a
//! subscriber; `shoal_broker::listened_cells`). Robots already keep a cell
//! half a cell past their listening radius before they let it go, so the
//! link follows them without hysteresis of its own.

use std::collections::BTreeSet;

use shoal_broker::CellKey;

/// What changed in the cells asked for.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct Change {
    pub add: Vec<CellKey>,
    pub drop: Vec<CellKey>,
}

/// The cells to start and stop asking for, given those asked for now and
/// those this host's robots listen to.
pub fn change(asked: &BTreeSet<CellKey>, listened: &BTreeSet<CellKey>) -> Change {
    Change {
        add: listened.difference(asked).copied().collect(),
        drop: asked.difference(listened).copied().collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cells_asked_for_follow_the_cells_listened_to() {
        let asked: BTreeSet<CellKey> = [(0, 0), (0, 1), (1, 1)].into();
        let listened: BTreeSet<CellKey> = [(0, 1), (1, 1), (2, 1)].into();
        assert_eq!(
            change(&asked, &listened),
            Change {
                add: vec![(2, 1)],
                drop: vec![(0, 0)]
            }
        );
        assert_eq!(change(&listened, &listened), Change::default());
        assert_eq!(change(&asked, &BTreeSet::new()).drop.len(), 3);
    }
}

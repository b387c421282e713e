//! How far a robot listens and senses. It listens to the cells within
//! `listen_ring` steps of it and senses robots up to a margin short of
//! that. When it widens its listening, it widens its sensing only two
//! periods later: robots entering its sensing range were then already
//! heard, which keeps lockstep runs deterministic.

/// Ticks between widening the listening and widening the sensing.
const WIDEN_DELAY_TICKS: u64 = 2;
/// How far inside the surely-covered square the sensing stops: more than two
/// periods of two robots' motion towards each other.
pub const SENSE_MARGIN_M: f64 = 1.0;

#[derive(Clone, Debug, PartialEq)]
pub struct SensingRange {
    pub listen_ring: u32,
    /// The ring whose radius the robot senses with.
    pub sense_ring: u32,
    max_ring: u32,
    widen_at: Option<u64>,
    /// The tick of the first period it was updated after: a robot that has
    /// just subscribed to its cells may not have heard its neighbours yet.
    first_tick: Option<u64>,
}

impl SensingRange {
    pub fn new(max_ring: u32) -> Self {
        Self {
            listen_ring: 1,
            sense_ring: 1,
            max_ring: max_ring.max(1),
            widen_at: None,
            first_tick: None,
        }
    }

    /// How far a robot senses at `ring` rings of `step` metres: short of
    /// what it listens to by the margin.
    pub fn radius(ring: u32, step: f64) -> f64 {
        (f64::from(ring) * step - SENSE_MARGIN_M).max(0.0)
    }

    pub fn sense_radius(&self, step: f64) -> f64 {
        Self::radius(self.sense_ring, step)
    }

    /// How far it listens.
    pub fn listen_radius(&self, step: f64) -> f64 {
        f64::from(self.listen_ring) * step
    }

    /// Updates the rings after a period in which the robot sensed `sensed`
    /// robots, `within_inner` of them within one ring less, and wants at least `wanted`.
    ///
    /// It never widens after its first period: its cells' robots publish
    /// once a period, so a robot that subscribed during the period has not
    /// heard all of them yet. Widening then made nearly every robot of a
    /// starting swarm open and drop a ring of cells it did not need.
    pub fn update(&mut self, tick: u64, sensed: usize, within_inner: usize, wanted: usize) {
        if *self.first_tick.get_or_insert(tick) == tick {
            return;
        }
        if let Some(at) = self.widen_at {
            if tick >= at {
                self.sense_ring = self.listen_ring;
                self.widen_at = None;
            }
            return;
        }
        if sensed < wanted && self.listen_ring < self.max_ring {
            self.listen_ring += 1;
            self.widen_at = Some(tick + WIDEN_DELAY_TICKS);
        } else if self.sense_ring > 1 && within_inner >= wanted {
            self.sense_ring -= 1;
            self.listen_ring = self.sense_ring;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensing_widens_only_after_listening_did() {
        let mut range = SensingRange::new(3);
        range.update(9, 0, 0, 2);
        assert_eq!(
            (range.sense_ring, range.listen_ring),
            (1, 1),
            "nothing heard in the first period says nothing"
        );
        range.update(10, 1, 0, 2);
        assert_eq!((range.sense_ring, range.listen_ring), (1, 2));
        range.update(11, 1, 0, 2);
        assert_eq!(range.sense_ring, 1);
        range.update(12, 1, 0, 2);
        assert_eq!((range.sense_ring, range.listen_ring), (2, 2));
        range.update(13, 1, 0, 2);
        range.update(15, 1, 0, 2);
        assert_eq!((range.sense_ring, range.listen_ring), (3, 3));
        range.update(16, 1, 0, 2);
        assert_eq!(range.listen_ring, 3, "already at the widest ring");
        range.update(17, 6, 5, 2);
        assert_eq!((range.sense_ring, range.listen_ring), (2, 2));
    }

    #[test]
    fn the_sense_radius_keeps_a_margin_inside_the_listened_cells() {
        assert!((SensingRange::radius(1, 3.0) - 2.0).abs() < 1e-12);
        assert!((SensingRange::radius(2, 3.0) - 5.0).abs() < 1e-12);
    }
}

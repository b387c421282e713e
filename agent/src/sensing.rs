//! How far a robot listens. It listens one ring of cells further than it
//! senses, and widens its sensing only two periods after it widened its
//! listening: robots entering its sensing range were then already heard, which
//! keeps lockstep runs deterministic.

/// Ticks between widening the listening and widening the sensing.
const WIDEN_DELAY_TICKS: u64 = 2;

#[derive(Clone, Debug, PartialEq)]
pub struct SensingRange {
    pub sense_ring: u32,
    pub listen_ring: u32,
    max_sense_ring: u32,
    widen_at: Option<u64>,
}

impl SensingRange {
    pub fn new(max_ring: u32) -> Self {
        let max_sense_ring = max_ring.saturating_sub(1).max(1);
        Self { sense_ring: 1, listen_ring: 2, max_sense_ring, widen_at: None }
    }

    pub fn sense_radius(&self, cell_size: f64) -> f64 {
        f64::from(self.sense_ring) * cell_size
    }

    /// Updates the rings after a period in which the robot sensed `sensed`
    /// robots and wanted `wanted`; `within_inner` counts those inside one ring less.
    pub fn update(&mut self, tick: u64, sensed: usize, within_inner: usize, wanted: usize) {
        if let Some(at) = self.widen_at {
            if tick >= at {
                self.sense_ring = self.listen_ring - 1;
                self.widen_at = None;
            }
            return;
        }
        if sensed < wanted && self.sense_ring < self.max_sense_ring {
            self.listen_ring = self.sense_ring + 2;
            self.widen_at = Some(tick + WIDEN_DELAY_TICKS);
        } else if self.sense_ring > 1 && within_inner >= wanted {
            self.sense_ring -= 1;
            self.listen_ring = self.sense_ring + 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensing_widens_only_after_listening_did() {
        let mut range = SensingRange::new(3);
        range.update(10, 1, 0, 4);
        assert_eq!((range.sense_ring, range.listen_ring), (1, 3));
        range.update(11, 1, 0, 4);
        assert_eq!(range.sense_ring, 1);
        range.update(12, 1, 0, 4);
        assert_eq!((range.sense_ring, range.listen_ring), (2, 3));
        range.update(13, 1, 0, 4);
        assert_eq!(range.sense_ring, 2, "already at the widest ring");
        range.update(14, 6, 5, 4);
        assert_eq!((range.sense_ring, range.listen_ring), (1, 2));
    }
}

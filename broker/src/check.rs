//! Samples from the bus are never trusted: a robot that publishes NaN or a
//! pose far outside the map is rejected and counted.

use crate::wire::PoseSample;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejection {
    NotFinite,
    OutsideMap,
    BadNeighbourCount,
}

/// Checks pose samples against the map and counts what it rejects.
#[derive(Clone, Debug)]
pub struct SampleCheck {
    /// `[xmin, ymin, xmax, ymax]` of what is plausible.
    bounds: [f64; 4],
    pub rejected: u64,
}

impl SampleCheck {
    /// Poses more than `margin` metres outside a `width` x `height` map are implausible.
    pub fn for_map(width: f64, height: f64, margin: f64) -> Self {
        Self {
            bounds: [-margin, -margin, width + margin, height + margin],
            rejected: 0,
        }
    }

    pub fn inspect(&self, sample: &PoseSample) -> Result<(), Rejection> {
        let values = [
            sample.x,
            sample.y,
            sample.theta,
            sample.believed_x,
            sample.believed_y,
            sample.believed_theta,
            sample.vx,
            sample.vy,
            sample.sim_time,
        ];
        if values.iter().any(|v| !v.is_finite()) {
            return Err(Rejection::NotFinite);
        }
        let [x0, y0, x1, y1] = self.bounds;
        if sample.x < x0 || sample.x > x1 || sample.y < y0 || sample.y > y1 {
            return Err(Rejection::OutsideMap);
        }
        if sample.neighbour_count as usize > crate::wire::MAX_NEIGHBOURS {
            return Err(Rejection::BadNeighbourCount);
        }
        Ok(())
    }

    /// True when the sample may be used; counts it otherwise.
    pub fn accept(&mut self, sample: &PoseSample) -> bool {
        match self.inspect(sample) {
            Ok(()) => true,
            Err(rejection) => {
                self.rejected += 1;
                tracing::warn!(
                    agent = sample.agent_id,
                    ?rejection,
                    "rejected a malformed pose sample"
                );
                false
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x: f64, y: f64) -> PoseSample {
        PoseSample::standing(1, 1, 0, x, y, 0.0)
    }

    #[test]
    fn non_finite_and_far_away_poses_are_rejected_and_counted() {
        let mut check = SampleCheck::for_map(10.0, 10.0, 1.0);
        assert!(check.accept(&sample(5.0, 5.0)));
        assert!(!check.accept(&sample(f64::NAN, 5.0)));
        assert!(!check.accept(&sample(5.0, f64::INFINITY)));
        assert!(!check.accept(&sample(5.0, 1e6)));
        let mut bad = sample(5.0, 5.0);
        bad.neighbour_count = 99;
        assert!(!check.accept(&bad));
        assert_eq!(check.rejected, 4);
    }
}

//! A robot that explores on its own: walk until something is close ahead,
//! then turn away, and veer now and then so it does not trace one loop.
//! Used where a robot must move without a swarm (SLAM experiments).

use crate::legged::Command;
use crate::range::RangeSensor;

/// Turn away when something is this close ahead, metres.
const TOO_CLOSE_M: f64 = 0.7;
/// Once turning, keep turning until this much is free ahead.
const CLEAR_M: f64 = 1.2;
/// Veer every this many steps.
const VEER_EVERY: u64 = 9;

/// The nearest range within 10 degrees of straight ahead.
pub fn range_ahead(ranges: &[f64], sensor: &RangeSensor) -> f64 {
    (0..ranges.len().min(sensor.beams))
        .filter(|&b| sensor.bearing(b).abs() < 10f64.to_radians())
        .map(|b| ranges[b])
        .filter(|r| r.is_finite())
        .fold(sensor.max_range, f64::min)
}

/// The next command of a wandering robot at `step`, given how far is free ahead.
pub fn wander_command(step: u64, ahead: f64, previous: Command) -> Command {
    if ahead < TOO_CLOSE_M || (matches!(previous, Command::Turn(_)) && ahead < CLEAR_M) {
        Command::Turn(2)
    } else if step.is_multiple_of(VEER_EVERY) {
        // Veer right, then left: both small turns get used.
        if (step / VEER_EVERY).is_multiple_of(2) {
            Command::Turn(-1)
        } else {
            Command::Turn(1)
        }
    } else {
        Command::Walk(2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wanderer_turns_away_from_what_is_close_and_walks_otherwise() {
        assert_eq!(wander_command(1, 0.5, Command::Walk(2)), Command::Turn(2));
        assert_eq!(wander_command(1, 1.0, Command::Turn(2)), Command::Turn(2));
        assert_eq!(wander_command(1, 1.0, Command::Walk(2)), Command::Walk(2));
        assert_eq!(wander_command(9, 3.0, Command::Walk(2)), Command::Turn(1));
        assert_eq!(wander_command(18, 3.0, Command::Walk(2)), Command::Turn(-1));
    }
}

//! Surface zones: where the robot drove during a located span, how wide a
//! zone must be, when a zone is the whole floor, and the fit of a zone's
//! edges.

use shoal_physics::{CommandGrid, Effect, ScopedEffect};

use crate::fit::{fit, nll_of};
use crate::segments::Segment;

/// Where the robot drove during a speed or turn effect's span, as a
/// region; `None` for other effects.
pub(crate) fn zone_of_span(segments: &[Segment], scoped: &ScopedEffect) -> Option<[f64; 4]> {
    let during = scoped.during?;
    if !matches!(
        scoped.effect,
        Effect::SpeedScale { .. } | Effect::Slip { .. } | Effect::TurnScale { .. }
    ) {
        return None;
    }
    region_driven(segments, during)
}

/// A surface zone that holds more of the robot's driving than this is the
/// whole floor: a speed or turn gain everywhere, which the library names as
/// such. Named as a zone, one global mismatch would read as a place (and,
/// with a fading battery beside it, hide the fade behind the zone's mean).
pub(crate) const MAX_ZONE_SHARE: f64 = 0.75;

/// The share of the moving segments whose midpoint lies in `region`.
pub(crate) fn zone_share(segments: &[Segment], region: &[f64; 4]) -> f64 {
    let moving = segments.iter().filter(|s| s.speed > 0.01);
    let (mut inside, mut all) = (0usize, 0usize);
    for s in moving {
        all += 1;
        let [x, y] = s.mid;
        if x >= region[0] && x <= region[2] && y >= region[1] && y <= region[3] {
            inside += 1;
        }
    }
    inside as f64 / all.max(1) as f64
}

/// Whether `effect` is a surface zone that covers the whole floor (see
/// [`MAX_ZONE_SHARE`]).
pub(crate) fn is_whole_floor(segments: &[Segment], effect: &Effect) -> bool {
    matches!(effect, Effect::SurfaceZone { region, .. } if zone_share(segments, region) > MAX_ZONE_SHARE)
}

/// The narrowest side a surface zone may have. A patch of floor narrower
/// than a robot's footprint is crossed in a fraction of a second and cannot
/// be told from an event that happened there; a fit that shrinks a zone to a
/// sliver has found a few odd segments, not a surface.
pub(crate) const MIN_ZONE_SIDE_M: f64 = 0.3;

/// `region` widened about its centre until each side is at least
/// [`MIN_ZONE_SIDE_M`].
pub(crate) fn at_least_min_side(region: [f64; 4]) -> [f64; 4] {
    let widen = |lo: f64, hi: f64| {
        let missing = (MIN_ZONE_SIDE_M - (hi - lo)).max(0.0);
        (lo - missing / 2.0, hi + missing / 2.0)
    };
    let (x0, x1) = widen(region[0], region[2]);
    let (y0, y1) = widen(region[1], region[3]);
    [x0, y0, x1, y1]
}

/// The box the robot drove in during `[a, b]` seconds (at least
/// [`MIN_ZONE_SIDE_M`] a side), if it drove there for at least a few
/// segments.
pub(crate) fn region_driven(segments: &[Segment], [a, b]: [f64; 2]) -> Option<[f64; 4]> {
    let inside: Vec<&Segment> = segments
        .iter()
        .filter(|s| s.t_start >= a && s.t_end <= b && s.speed > 0.01)
        .collect();
    if inside.len() < 5 {
        return None;
    }
    let mut region = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for s in inside {
        for p in [&s.start, &s.end] {
            region = [
                region[0].min(p.x),
                region[1].min(p.y),
                region[2].max(p.x),
                region[3].max(p.y),
            ];
        }
    }
    Some(at_least_min_side(region))
}

/// Fits a surface zone's region edge by edge: each edge in turn moves to
/// where the likelihood is best, the factors held, then the factors are
/// refitted inside the new edges; coarse steps (a tenth of the zone's
/// size), then fine ones. A box of where the robot drove, or of coarse
/// located cells, becomes the zone's own edges. Other effects pass through.
pub(crate) fn refine_zone(
    grid: &CommandGrid,
    segs: &[Segment],
    base: &[ScopedEffect],
    mut zone: ScopedEffect,
    max_iters: u64,
) -> ScopedEffect {
    let Effect::SurfaceZone { region, .. } = zone.effect else {
        return zone;
    };
    let size = (region[2] - region[0]).max(region[3] - region[1]).max(0.1);
    for step in [0.1 * size, 0.03 * size] {
        let with = |effect: &Effect| {
            let mut effects = base.to_vec();
            effects.push(ScopedEffect::always(effect.clone()));
            nll_of(grid, segs, &effects)
        };
        let mut best = with(&zone.effect);
        for edge in 0..4 {
            for shift in [-3.0, -2.0, -1.0, 1.0, 2.0, 3.0] {
                let Effect::SurfaceZone {
                    region,
                    speed_factor,
                    turn_factor,
                } = zone.effect
                else {
                    return zone;
                };
                let mut moved = region;
                moved[edge] += shift * step;
                if moved[2] - moved[0] < MIN_ZONE_SIDE_M
                    || moved[3] - moved[1] < MIN_ZONE_SIDE_M
                    || zone_share(segs, &moved) > MAX_ZONE_SHARE
                {
                    continue;
                }
                let candidate = Effect::SurfaceZone {
                    region: moved,
                    speed_factor,
                    turn_factor,
                };
                let nll = with(&candidate);
                if nll < best {
                    (best, zone.effect) = (nll, candidate);
                }
            }
        }
        zone = fit(grid, segs, base, std::slice::from_ref(&zone), max_iters).effects[0].clone();
    }
    zone
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_zone_is_never_narrower_than_a_robot() {
        let sliver = at_least_min_side([2.40, 2.75, 2.43, 2.99]);
        assert!((sliver[2] - sliver[0] - MIN_ZONE_SIDE_M).abs() < 1e-12);
        assert!((sliver[3] - sliver[1] - MIN_ZONE_SIDE_M).abs() < 1e-12);
        // Widened about its centre.
        assert!(((sliver[0] + sliver[2]) / 2.0 - 2.415).abs() < 1e-12);
        // A zone wide enough already is left as it is.
        assert_eq!(
            at_least_min_side([0.0, 0.0, 1.0, 2.0]),
            [0.0, 0.0, 1.0, 2.0]
        );
    }
}

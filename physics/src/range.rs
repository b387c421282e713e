//! The body's range sensor: beams cast against walls, obstacles and other
//! robots, with noise, dropouts and a maximum range.

use glam::DVec2;
use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::arena::{Arena, Obstacle};
use crate::pose::Pose;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RangeSensor {
    pub beams: usize,
    /// Field of view, radians, centred on the heading.
    pub field_of_view: f64,
    pub max_range: f64,
    /// Standard deviation of the range noise at 1 m; it grows with distance.
    pub noise_per_m: f64,
    /// Chance that a beam returns nothing (reads max range).
    pub dropout: f64,
}

impl Default for RangeSensor {
    fn default() -> Self {
        Self {
            beams: 181,
            field_of_view: std::f64::consts::PI,
            max_range: 4.0,
            noise_per_m: 0.01,
            dropout: 0.01,
        }
    }
}

impl RangeSensor {
    /// Bearing of beam `i` relative to the heading.
    pub fn bearing(&self, i: usize) -> f64 {
        if self.beams <= 1 {
            return 0.0;
        }
        -self.field_of_view / 2.0 + self.field_of_view * i as f64 / (self.beams - 1) as f64
    }

    /// Noise-free ranges from `pose`; `robots` are other bodies of `radius`.
    pub fn cast_exact(
        &self,
        arena: &Arena,
        pose: &Pose,
        robots: &[DVec2],
        radius: f64,
    ) -> Vec<f64> {
        let origin = pose.position();
        let directions = self.directions(pose);
        let mut ranges: Vec<f64> = directions
            .iter()
            .map(|direction| ray_distance(arena, origin, *direction, &[], radius))
            .collect();
        // A robot can only stop the beams that point at it: casting each beam
        // against every robot around was most of a scan's cost.
        for center in robots {
            for beams in self.beams_towards(pose, *center, radius) {
                for i in beams {
                    ranges[i] = ranges[i].min(ray_circle(origin, directions[i], *center, radius));
                }
            }
        }
        for range in &mut ranges {
            *range = range.min(self.max_range);
        }
        ranges
    }

    /// The same ranges as [`Self::cast_exact`], cast the plain way: every
    /// beam against every robot. The reference the fast cast is held to,
    /// and `shoal-bench scan`'s baseline.
    pub fn cast_every_pair(
        &self,
        arena: &Arena,
        pose: &Pose,
        robots: &[DVec2],
        radius: f64,
    ) -> Vec<f64> {
        self.directions(pose)
            .into_iter()
            .map(|direction| {
                ray_distance(arena, pose.position(), direction, robots, radius).min(self.max_range)
            })
            .collect()
    }

    /// Each beam's direction in the world from `pose`.
    fn directions(&self, pose: &Pose) -> Vec<DVec2> {
        (0..self.beams)
            .map(|i| DVec2::from_angle(pose.theta + self.bearing(i)))
            .collect()
    }

    /// The beams that may hit a body of `radius` at `center`, with a beam to
    /// spare on each side; all of them when the sensor is inside it.
    fn beams_towards(
        &self,
        pose: &Pose,
        center: DVec2,
        radius: f64,
    ) -> Vec<std::ops::RangeInclusive<usize>> {
        let last = self.beams.saturating_sub(1);
        let offset = center - pose.position();
        let distance = offset.length();
        let step = if last == 0 {
            0.0
        } else {
            self.field_of_view / last as f64
        };
        if self.beams == 0 || distance <= radius || step <= 0.0 || !distance.is_finite() {
            return vec![0..=last];
        }
        let half_width = (radius / distance).asin() + step;
        let bearing = (offset.to_angle() - pose.theta + std::f64::consts::PI)
            .rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        let index = |angle: f64| (angle + self.field_of_view / 2.0) / step;
        [-std::f64::consts::TAU, 0.0, std::f64::consts::TAU]
            .into_iter()
            .filter_map(|turn| {
                let low = index(bearing + turn - half_width).floor();
                let high = index(bearing + turn + half_width).ceil();
                (high >= 0.0 && low <= last as f64)
                    .then(|| (low.max(0.0) as usize)..=(high.min(last as f64) as usize))
            })
            .collect()
    }

    /// What the sensor reads: exact ranges with distance-proportional noise and dropouts.
    pub fn read(
        &self,
        arena: &Arena,
        pose: &Pose,
        robots: &[DVec2],
        radius: f64,
        rng: &mut impl Rng,
    ) -> Vec<f64> {
        self.cast_exact(arena, pose, robots, radius)
            .into_iter()
            .map(|range| {
                if range >= self.max_range || rng.random::<f64>() < self.dropout {
                    return self.max_range;
                }
                let noise = Normal::new(0.0, self.noise_per_m * range.max(0.1))
                    .map_or(0.0, |n| n.sample(rng));
                (range + noise).clamp(0.0, self.max_range)
            })
            .collect()
    }
}

/// Distance along a unit `direction` from `origin` to the first wall,
/// obstacle or robot; infinite if none.
pub fn ray_distance(
    arena: &Arena,
    origin: DVec2,
    direction: DVec2,
    robots: &[DVec2],
    radius: f64,
) -> f64 {
    let walls = arena
        .all_walls()
        .map(|w| ray_segment(origin, direction, w.from.into(), w.to.into()));
    let obstacles = arena.obstacles.iter().map(|o| match *o {
        Obstacle::Disc { center, radius } => ray_circle(origin, direction, center.into(), radius),
        Obstacle::Box { min, max } => {
            let corners = [
                DVec2::new(min[0], min[1]),
                DVec2::new(max[0], min[1]),
                DVec2::new(max[0], max[1]),
                DVec2::new(min[0], max[1]),
            ];
            (0..4)
                .map(|k| ray_segment(origin, direction, corners[k], corners[(k + 1) % 4]))
                .fold(f64::INFINITY, f64::min)
        }
    });
    let bodies = robots
        .iter()
        .map(|c| ray_circle(origin, direction, *c, radius));
    walls
        .chain(obstacles)
        .chain(bodies)
        .fold(f64::INFINITY, f64::min)
}

fn ray_segment(origin: DVec2, direction: DVec2, a: DVec2, b: DVec2) -> f64 {
    let edge = b - a;
    let denominator = direction.perp_dot(edge);
    if denominator.abs() < 1e-12 {
        return f64::INFINITY;
    }
    let offset = a - origin;
    let t = offset.perp_dot(edge) / denominator;
    let u = offset.perp_dot(direction) / denominator;
    if t >= 0.0 && (0.0..=1.0).contains(&u) {
        t
    } else {
        f64::INFINITY
    }
}

fn ray_circle(origin: DVec2, direction: DVec2, center: DVec2, radius: f64) -> f64 {
    let offset = origin - center;
    let b = offset.dot(direction);
    let c = offset.length_squared() - radius * radius;
    let discriminant = b * b - c;
    if discriminant < 0.0 {
        return f64::INFINITY;
    }
    let root = discriminant.sqrt();
    let near = -b - root;
    let far = -b + root;
    if near >= 0.0 {
        near
    } else if far >= 0.0 {
        // Inside the circle (a robot's own body is never passed in).
        far
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn room() -> Arena {
        Arena {
            width: 4.0,
            height: 3.0,
            walls: vec![],
            obstacles: vec![Obstacle::Disc {
                center: [3.0, 1.5],
                radius: 0.25,
            }],
            surfaces: vec![],
        }
    }

    #[test]
    fn a_scan_reads_exactly_what_casting_every_beam_at_every_robot_reads() {
        use rand::Rng;
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let arena = room();
        for (beams, field_of_view) in [
            (181, std::f64::consts::PI),
            (360, std::f64::consts::TAU),
            (7, 0.5),
            (1, 1.0),
        ] {
            let sensor = RangeSensor {
                beams,
                field_of_view,
                max_range: 4.0,
                ..RangeSensor::default()
            };
            for _ in 0..200 {
                let pose = Pose::new(
                    rng.random_range(0.2..3.8),
                    rng.random_range(0.2..2.8),
                    rng.random_range(-7.0..7.0),
                );
                let robots: Vec<DVec2> = (0..rng.random_range(0..12))
                    .map(|_| DVec2::new(rng.random_range(-1.0..5.0), rng.random_range(-1.0..4.0)))
                    .collect();
                let every_pair = sensor.cast_every_pair(&arena, &pose, &robots, 0.15);
                assert_eq!(sensor.cast_exact(&arena, &pose, &robots, 0.15), every_pair);
            }
        }
    }

    #[test]
    fn beams_hit_walls_obstacles_and_robots_at_the_right_distance() {
        let arena = room();
        let origin = DVec2::new(1.0, 1.5);
        assert!(
            (ray_distance(&arena, origin, DVec2::X, &[], 0.15) - 1.75).abs() < 1e-9,
            "disc"
        );
        assert!(
            (ray_distance(&arena, origin, -DVec2::X, &[], 0.15) - 1.0).abs() < 1e-9,
            "left wall"
        );
        assert!(
            (ray_distance(&arena, origin, DVec2::Y, &[], 0.15) - 1.5).abs() < 1e-9,
            "top wall"
        );
        let robot = [DVec2::new(2.0, 1.5)];
        assert!(
            (ray_distance(&arena, origin, DVec2::X, &robot, 0.15) - 0.85).abs() < 1e-9,
            "robot"
        );
    }

    #[test]
    fn a_scan_spans_the_field_of_view_and_respects_max_range() {
        let sensor = RangeSensor {
            beams: 181,
            max_range: 1.2,
            ..Default::default()
        };
        let ranges = sensor.cast_exact(&room(), &Pose::new(1.0, 1.5, 0.0), &[], 0.15);
        assert_eq!(ranges.len(), 181);
        assert!((sensor.bearing(0) + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((sensor.bearing(90)).abs() < 1e-12);
        assert!(ranges.iter().all(|r| *r <= 1.2));
        assert!(
            (ranges[90] - 1.2).abs() < 1e-12,
            "the disc at 1.75 m is out of range"
        );
    }

    #[test]
    fn noisy_reads_stay_close_to_the_truth() {
        let sensor = RangeSensor {
            dropout: 0.0,
            ..Default::default()
        };
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let pose = Pose::new(1.0, 1.5, 0.0);
        let exact = sensor.cast_exact(&room(), &pose, &[], 0.15);
        let noisy = sensor.read(&room(), &pose, &[], 0.15, &mut rng);
        let mean_error = exact
            .iter()
            .zip(&noisy)
            .map(|(a, b)| (a - b).abs())
            .sum::<f64>()
            / exact.len() as f64;
        assert!(mean_error > 0.0 && mean_error < 0.05, "{mean_error}");
    }
}

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::legged::MotionSample;

/// A straight wall segment.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Wall {
    pub from: [f64; 2],
    pub to: [f64; 2],
}

/// An obstacle: a disc or an axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged, deny_unknown_fields)]
pub enum Obstacle {
    Disc { center: [f64; 2], radius: f64 },
    Box { min: [f64; 2], max: [f64; 2] },
}

/// A region of floor that changes how a body moves (carpet, tile, ...).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Surface {
    pub name: String,
    /// `[xmin, ymin, xmax, ymax]`.
    pub region: [f64; 4],
    #[serde(default = "one")]
    pub along_scale: f64,
    #[serde(default = "one")]
    pub across_scale: f64,
    #[serde(default = "one")]
    pub turn_scale: f64,
    /// Seconds into the run from which the surface is there (a floor that
    /// changes part-way: wet, cleaned, worn).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub from_s: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn one() -> f64 {
    1.0
}

impl Surface {
    /// Whether walking on it differs from the base floor, which is all a
    /// robot's own motion model knows.
    pub fn changes_motion(&self) -> bool {
        self.along_scale != 1.0 || self.across_scale != 1.0 || self.turn_scale != 1.0
    }

    pub fn contains(&self, p: DVec2) -> bool {
        let [x0, y0, x1, y1] = self.region;
        p.x >= x0 && p.x <= x1 && p.y >= y0 && p.y <= y1
    }

    /// What the surface does to a step drawn on the robot's base floor.
    pub fn apply(&self, step: MotionSample) -> MotionSample {
        MotionSample {
            command: step.command,
            along: step.along * self.along_scale,
            across: step.across * self.across_scale,
            turn: step.turn * self.turn_scale,
        }
    }
}

/// The static world: a rectangle `[0, width] x [0, height]` bounded by walls,
/// with interior walls, obstacles and surfaces.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Arena {
    pub width: f64,
    pub height: f64,
    #[serde(default)]
    pub walls: Vec<Wall>,
    #[serde(default)]
    pub obstacles: Vec<Obstacle>,
    #[serde(default)]
    pub surfaces: Vec<Surface>,
}

impl Arena {
    /// Interior walls plus the four boundary walls.
    pub fn all_walls(&self) -> impl Iterator<Item = Wall> + '_ {
        let (w, h) = (self.width, self.height);
        let boundary = [
            Wall {
                from: [0.0, 0.0],
                to: [w, 0.0],
            },
            Wall {
                from: [w, 0.0],
                to: [w, h],
            },
            Wall {
                from: [w, h],
                to: [0.0, h],
            },
            Wall {
                from: [0.0, h],
                to: [0.0, 0.0],
            },
        ];
        boundary.into_iter().chain(self.walls.iter().copied())
    }

    pub fn contains(&self, p: DVec2) -> bool {
        p.x >= 0.0 && p.y >= 0.0 && p.x <= self.width && p.y <= self.height
    }

    /// The surface under `p`, if any; later surfaces lie on top of earlier ones.
    pub fn surface_at(&self, p: DVec2) -> Option<&Surface> {
        self.surfaces.iter().rev().find(|s| s.contains(p))
    }

    /// The surface under `p` at `t` seconds into the run.
    pub fn surface_at_time(&self, p: DVec2, t: f64) -> Option<&Surface> {
        self.surfaces
            .iter()
            .rev()
            .find(|s| s.contains(p) && t >= s.from_s)
    }

    /// Whether a disc of `radius` at `p` overlaps a wall or an obstacle, or leaves the arena.
    pub fn blocks(&self, p: DVec2, radius: f64) -> bool {
        if p.x < radius || p.y < radius || p.x > self.width - radius || p.y > self.height - radius {
            return true;
        }
        let hits_wall = self
            .walls
            .iter()
            .any(|w| distance_to_segment(p, DVec2::from(w.from), DVec2::from(w.to)) < radius);
        hits_wall || self.obstacles.iter().any(|o| o.distance(p) < radius)
    }
}

impl Obstacle {
    /// Distance from `p` to the obstacle's boundary; zero or negative inside.
    pub fn distance(&self, p: DVec2) -> f64 {
        match *self {
            Obstacle::Disc { center, radius } => p.distance(DVec2::from(center)) - radius,
            Obstacle::Box { min, max } => {
                let clamped = p.clamp(DVec2::from(min), DVec2::from(max));
                p.distance(clamped)
            }
        }
    }
}

pub fn distance_to_segment(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let length_sq = ab.length_squared();
    let t = if length_sq > 0.0 {
        ((p - a).dot(ab) / length_sq).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn room() -> Arena {
        Arena {
            width: 4.0,
            height: 3.0,
            walls: vec![Wall {
                from: [2.0, 0.0],
                to: [2.0, 2.0],
            }],
            obstacles: vec![
                Obstacle::Disc {
                    center: [1.0, 2.0],
                    radius: 0.2,
                },
                Obstacle::Box {
                    min: [3.0, 2.0],
                    max: [3.5, 2.5],
                },
            ],
            surfaces: vec![Surface {
                name: "tile".into(),
                region: [0.0, 0.0, 1.0, 1.0],
                along_scale: 1.3,
                across_scale: 1.0,
                turn_scale: 0.8,
                from_s: 0.0,
            }],
        }
    }

    #[test]
    fn walls_obstacles_and_the_boundary_block_a_body() {
        let arena = room();
        assert!(!arena.blocks(DVec2::new(1.0, 1.0), 0.15));
        assert!(arena.blocks(DVec2::new(2.1, 1.0), 0.15), "interior wall");
        assert!(arena.blocks(DVec2::new(1.0, 1.7), 0.15), "disc");
        assert!(arena.blocks(DVec2::new(3.2, 1.9), 0.15), "box");
        assert!(arena.blocks(DVec2::new(0.1, 1.0), 0.15), "boundary");
        assert!(
            !arena.blocks(DVec2::new(2.3, 2.5), 0.15),
            "past the wall's end"
        );
    }

    #[test]
    fn surfaces_scale_steps_where_they_lie() {
        let arena = room();
        let surface = arena.surface_at(DVec2::new(0.5, 0.5)).expect("tile");
        let step = MotionSample {
            command: crate::Command::Walk(1),
            along: 0.1,
            across: 0.0,
            turn: 0.5,
        };
        let scaled = surface.apply(step);
        assert!((scaled.along - 0.13).abs() < 1e-12 && (scaled.turn - 0.4).abs() < 1e-12);
        assert!(arena.surface_at(DVec2::new(3.0, 1.0)).is_none());
    }
}

use glam::DVec2;
use serde::{Deserialize, Serialize};

/// A planar pose: position in metres, heading in radians.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub x: f64,
    pub y: f64,
    pub theta: f64,
}

impl Pose {
    pub const fn new(x: f64, y: f64, theta: f64) -> Self {
        Self { x, y, theta }
    }

    pub fn position(&self) -> DVec2 {
        DVec2::new(self.x, self.y)
    }

    /// Applies one motion step in the thesis's parameterisation: `along` the
    /// heading, `across` it (to the left) and a `turn`.
    pub fn advanced(&self, along: f64, across: f64, turn: f64) -> Self {
        let (sin, cos) = self.theta.sin_cos();
        Self {
            x: self.x + along * cos - across * sin,
            y: self.y + along * sin + across * cos,
            theta: wrap_angle(self.theta + turn),
        }
    }

    /// This pose seen from `origin`'s frame.
    pub fn relative_to(&self, origin: &Pose) -> Pose {
        let offset = DVec2::from_angle(-origin.theta).rotate(self.position() - origin.position());
        Pose::new(offset.x, offset.y, wrap_angle(self.theta - origin.theta))
    }

    /// `relative`, given in this pose's frame, in world coordinates.
    pub fn compose(&self, relative: &Pose) -> Pose {
        let offset = DVec2::from_angle(self.theta).rotate(relative.position());
        Pose::new(
            self.x + offset.x,
            self.y + offset.y,
            wrap_angle(self.theta + relative.theta),
        )
    }

    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.theta.is_finite()
    }
}

/// The heading about z (yaw) of the rotation a quaternion (x, y, z, w)
/// holds, as ROS messages carry orientations; or why it holds none: a
/// quaternion far from unit norm is no rotation (an unset orientation is
/// written as all zeros).
pub fn yaw_of_quaternion(x: f64, y: f64, z: f64, w: f64) -> Result<f64, String> {
    let q = glam::DQuat::from_xyzw(x, y, z, w);
    let norm = q.length();
    if !(0.5..=1.5).contains(&norm) {
        return Err(format!("not a rotation: its quaternion has norm {norm:.3}"));
    }
    Ok(q.normalize().to_euler(glam::EulerRot::ZYX).0)
}

/// Wraps an angle into (-pi, pi].
pub fn wrap_angle(angle: f64) -> f64 {
    let wrapped = angle.rem_euclid(std::f64::consts::TAU);
    if wrapped > std::f64::consts::PI {
        wrapped - std::f64::consts::TAU
    } else {
        wrapped
    }
}

/// Comma-separated finite numbers as typed on a command line.
fn finite_numbers(text: &str) -> Result<Vec<f64>, String> {
    text.split(',')
        .map(|v| {
            let value = v
                .trim()
                .parse::<f64>()
                .map_err(|e| format!("`{}`: {e}", v.trim()))?;
            if value.is_finite() {
                Ok(value)
            } else {
                Err(format!("`{}` is not finite", v.trim()))
            }
        })
        .collect()
}

/// A pose typed as `X,Y` or `X,Y,THETA` (heading 0 when left out).
pub fn parse_pose(text: &str) -> Result<Pose, String> {
    match finite_numbers(text)?[..] {
        [x, y] => Ok(Pose::new(x, y, 0.0)),
        [x, y, theta] => Ok(Pose::new(x, y, theta)),
        _ => Err("expected X,Y or X,Y,THETA".to_owned()),
    }
}

/// A point typed as `X,Y`.
pub fn parse_point(text: &str) -> Result<[f64; 2], String> {
    match finite_numbers(text)?[..] {
        [x, y] => Ok([x, y]),
        _ => Err("expected X,Y".to_owned()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    #[test]
    fn poses_and_points_typed_on_a_command_line_are_finite_numbers() {
        assert_eq!(parse_pose("1, 2"), Ok(Pose::new(1.0, 2.0, 0.0)));
        assert_eq!(parse_pose("1,2,0.5"), Ok(Pose::new(1.0, 2.0, 0.5)));
        assert_eq!(parse_point("3,-4"), Ok([3.0, -4.0]));
        assert!(parse_pose("1").is_err());
        assert!(parse_point("1,2,3").is_err());
        assert_eq!(parse_point("1,NaN"), Err("`NaN` is not finite".to_owned()));
        assert!(parse_pose("1,x").is_err_and(|e| e.starts_with("`x`")));
    }

    #[test]
    fn advancing_along_and_across_follows_the_heading() {
        let pose = Pose::new(1.0, 2.0, FRAC_PI_2).advanced(1.0, 0.5, 0.0);
        assert!((pose.x - 0.5).abs() < 1e-12);
        assert!((pose.y - 3.0).abs() < 1e-12);
    }

    #[test]
    fn composing_a_relative_pose_undoes_taking_it() {
        let origin = Pose::new(1.0, 2.0, 0.7);
        let pose = Pose::new(-3.0, 0.5, -2.9);
        let back = origin.compose(&pose.relative_to(&origin));
        assert!((back.x - pose.x).abs() < 1e-12 && (back.y - pose.y).abs() < 1e-12);
        assert!((wrap_angle(back.theta - pose.theta)).abs() < 1e-12);
    }

    #[test]
    fn angles_wrap_into_half_open_interval() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.25)).abs() - 0.25 < 1e-12);
    }
}

//! Trajectories in the TUM format (`timestamp tx ty tz qx qy qz qw`), which
//! `evo_traj` and `evo_ape` read.

use std::fmt::Write as _;

/// One line of a planar pose: z is 0 and the rotation is about z.
pub fn line(time_s: f64, x: f64, y: f64, theta: f64) -> String {
    let (sin, cos) = (theta / 2.0).sin_cos();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{time_s:.6} {x:.6} {y:.6} 0.0 0.0 0.0 {sin:.9} {cos:.9}"
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quarter_turn_is_a_unit_quaternion_about_z() {
        let text = line(1.5, 2.0, 3.0, std::f64::consts::FRAC_PI_2);
        let values: Vec<f64> = text
            .split_whitespace()
            .map(|v| v.parse().expect("number"))
            .collect();
        assert_eq!(values.len(), 8);
        assert!((values[6] - values[7]).abs() < 1e-9);
        assert!((values[6].powi(2) + values[7].powi(2) - 1.0).abs() < 1e-9);
    }
}

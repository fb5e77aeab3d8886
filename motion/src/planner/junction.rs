//! The corner rule: grbl's junction deviation, in step space.
//!
//! At the junction of two lines with unit vectors `u_prev`, `u_next` (step
//! space: each axis's steps, not millimetres), let θ be the angle between
//! `−u_prev` and `u_next` (`cos θ = −u_prev·u_next`: θ = π on a straight
//! line, 0 on a full reversal). A circle tangent to both lines whose
//! closest point is `δ` steps from the corner has radius
//! `R = δ·sin(θ/2)/(1 − sin(θ/2))`; the junction speed is the speed at
//! which that circle would be taken with centripetal acceleration `a`:
//!
//! ```text
//! v_j = √(a·R) = √(a·δ·sin(θ/2)/(1 − sin(θ/2)))
//! ```
//!
//! Straight on (θ = π) it is unlimited, a reversal (θ = 0) gives 0.
//!
//! Alone, that circle grows without bound as corners get shallower
//! (`R ≈ 8δ/φ²` for a turn of φ = π − θ), so an arc cut into many short
//! chords would be run at any speed. As Klipper does, the circle must also
//! touch each line no further than its middle: for a line of `ℓ` steps,
//! `R ≤ ℓ/2·tan(θ/2)`, so
//!
//! ```text
//! v_j ≤ √(a·ℓ/2·tan(θ/2))        for each of the two lines
//! ```
//!
//! ([`chord_speed`]). On a circle of radius `r` cut into chords of turn φ,
//! `ℓ = 2r·sin(φ/2)` and `tan(θ/2) = cot(φ/2)`, so this is
//! `√(a·r·cos(φ/2))`: the circle's own `√(a·r)` as the chords shrink,
//! whatever their number.
//!
//! Why not a per-axis velocity-jump limit ("jerk" in Marlin, square-corner
//! velocity aside in Klipper): a fixed jump allowed at every corner lets an
//! arc cut into many short chords run at any speed, since each corner's
//! jump `v·|u_next − u_prev|` shrinks with the chord, so the centripetal
//! acceleration on a fine arc is unbounded. Junction deviation with the
//! chord bound ties every corner to the acceleration limit and to a path
//! error `δ`, and on a fine arc to the circle's own `√(a·r)`. It is one
//! setting, in steps here. Neither rule removes the velocity step each axis takes
//! at a sharp corner (the path has a kink); the cosine ramps keep the
//! acceleration along the path continuous on both sides of it.

use super::sqrt::sqrt;

/// `cos θ` beyond which the lines are taken as straight on (no limit) or
/// as a reversal (0), as grbl does: where `1 − sin(θ/2)` loses its digits.
const STRAIGHT_OR_REVERSAL_COS: f64 = 0.999_999;

/// `1 + cos θ` at or below which [`chord_speed`] takes the lines as
/// straight on (a turn below about 1.4e-6 rad).
const STRAIGHT_ON_CHORD: f64 = 1e-12;

/// The junction deviation speed limit (steps/s along the step-space path)
/// between two lines with unit vectors `prev_unit` and `next_unit`, for a
/// centripetal acceleration `accel_steps_per_s2` and a deviation of
/// `deviation_steps`: `f64::INFINITY` straight on, 0 on a reversal.
pub fn junction_deviation_speed(
    prev_unit: &[f64],
    next_unit: &[f64],
    accel_steps_per_s2: f64,
    deviation_steps: f64,
) -> f64 {
    let dot: f64 = prev_unit.iter().zip(next_unit).map(|(p, n)| p * n).sum();
    let cos_theta = -dot;
    if cos_theta < -STRAIGHT_OR_REVERSAL_COS {
        return f64::INFINITY;
    }
    if cos_theta > STRAIGHT_OR_REVERSAL_COS {
        return 0.0;
    }
    let sin_half = sqrt(0.5 * (1.0 - cos_theta));
    sqrt(accel_steps_per_s2 * deviation_steps * sin_half / (1.0 - sin_half))
}

/// The chord bound (steps/s along the path): the speed at which the
/// circle tangent to both lines that touches a line of `path_steps` at its
/// middle is taken at `accel_steps_per_s2`, `√(a·ℓ/2·tan(θ/2))`;
/// `f64::INFINITY` straight on, 0 on a reversal.
pub fn chord_speed(
    prev_unit: &[f64],
    next_unit: &[f64],
    path_steps: f64,
    accel_steps_per_s2: f64,
) -> f64 {
    let dot: f64 = prev_unit.iter().zip(next_unit).map(|(p, n)| p * n).sum();
    let cos_theta = -dot;
    if cos_theta > STRAIGHT_OR_REVERSAL_COS {
        return 0.0;
    }
    // Unlike the deviation's, this bound must hold on the shallow turns of
    // fine arcs: only turns below about 1.4e-6 rad count as straight on,
    // where 1 − dot is at the rounding of the unit vectors.
    let one_plus_cos = 1.0 + cos_theta;
    if one_plus_cos <= STRAIGHT_ON_CHORD {
        return f64::INFINITY;
    }
    let tan_half = sqrt(0.5 * (1.0 - cos_theta)) / sqrt(0.5 * one_plus_cos);
    sqrt(accel_steps_per_s2 * path_steps / 2.0 * tan_half)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fine_arc_runs_at_its_centripetal_speed() {
        // A circle of radius 10 000 steps in n chords, δ large: the chord
        // bound sets √(a·r·cos(φ/2)).
        let (radius, accel) = (10_000.0f64, 50_000.0);
        for chords in [100u32, 1_000, 10_000] {
            let turn = 2.0 * core::f64::consts::PI / f64::from(chords);
            let prev = [1.0, 0.0];
            let next = [turn.cos(), turn.sin()];
            let length = 2.0 * radius * (turn / 2.0).sin();
            let chord = chord_speed(&prev, &next, length, accel);
            let expected = (accel * radius * (turn / 2.0).cos()).sqrt();
            assert!(
                (chord - expected).abs() <= 1e-6 * expected,
                "{chords}: {chord} {expected}"
            );
            // Junction deviation alone grows with the number of chords.
            assert!(junction_deviation_speed(&prev, &next, accel, 50.0) > chord || chords == 100);
        }
    }

    #[test]
    fn straight_right_angle_and_reversal() {
        let x = [1.0, 0.0];
        let y = [0.0, 1.0];
        let minus_x = [-1.0, 0.0];
        assert_eq!(junction_deviation_speed(&x, &x, 1000.0, 5.0), f64::INFINITY);
        assert_eq!(junction_deviation_speed(&x, &minus_x, 1000.0, 5.0), 0.0);
        // θ = 90°: sin 45° = 1/√2, R = δ/(√2 − 1).
        let expected = (1000.0 * 5.0 / (2f64.sqrt() - 1.0)).sqrt();
        let got = junction_deviation_speed(&x, &y, 1000.0, 5.0);
        assert!(
            (got - expected).abs() <= 1e-9 * expected,
            "{got} {expected}"
        );
        assert_eq!(junction_deviation_speed(&x, &y, 1000.0, 0.0), 0.0);
    }

    #[test]
    fn sharper_corners_are_slower() {
        let x = [1.0, 0.0];
        let mut last = f64::INFINITY;
        for deg in [10.0f64, 45.0, 90.0, 135.0, 170.0] {
            let turn = deg.to_radians();
            let next = [turn.cos(), turn.sin()];
            let speed = junction_deviation_speed(&x, &next, 1000.0, 2.0);
            assert!(speed < last, "{deg}");
            last = speed;
        }
    }
}

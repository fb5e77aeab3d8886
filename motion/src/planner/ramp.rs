//! The junction ramp: the seed's cosine, from one lead speed to another,
//! with its acceleration, its jerk, and the two questions the planner asks
//! of it (how long must a ramp be, how fast may a line be entered).
//!
//! # The curve
//!
//! The seed's S-curve is a cosine **in time**: from rest to `v`, the speed
//! is `v·(1 − cos θ)/2` with θ running from 0 to π over the ramp's time.
//! The junction ramp is the same curve between any two speeds. Over a time
//! `T`, from `v0` to `v1` (lead steps/s), at `τ` into it:
//!
//! ```text
//! θ(τ) = π·τ/T                              θ from 0 to π
//! v(θ) = v0 + (v1 − v0)·(1 − cos θ)/2  = m − h·cos θ
//!        m = (v0 + v1)/2,   h = (v1 − v0)/2
//! s(τ) = m·τ − h·(T/π)·sin θ                distance so far
//! d    = s(T) = m·T                          so T = d/m = 2d/(v0 + v1)
//! ```
//!
//! A ramp is given by its distance `d` (whole lead steps, the planner's
//! unit) and its two speeds; its time follows.
//!
//! # Acceleration
//!
//! ```text
//! a(θ) = dv/dt = (π/T)·h·sin θ = (π·m/d)·h·sin θ
//! ```
//!
//! It is 0 at θ = 0 and at θ = π: a line's ramps and its cruise meet with
//! zero acceleration, and so do two lines at their junction. Acceleration
//! is continuous everywhere on a planned path. Its peak is at θ = π/2:
//!
//! ```text
//! a_peak = π·m·|h|/d = π·|v1² − v0²|/(4d)
//! ```
//!
//! so the ramp needs `d = π·|v1² − v0²|/(4·a_max)`: exactly a constant
//! acceleration of `2·a_max/π` (a trapezoid's ramp at `0.64·a_max`), `π/2`
//! times a trapezoid's distance at the same peak. Everything is symmetric in
//! `v0` and `v1`: a decelerating ramp is an accelerating one read backwards.
//!
//! # Jerk
//!
//! ```text
//! j = da/dt = (π/T)²·h·cos θ,     |j| ≤ (π·m/d)²·|h|
//! ```
//!
//! It is largest at the ramp's ends, where it steps from the cruise's 0:
//! bounded, as in every acceleration-continuous (third-order) profile.
//!
//! # From rest
//!
//! From `v0 = 0` the distance grows as `s ∝ τ³` near the start: the ramp
//! leaves rest at once and its first step comes after a finite time, as the
//! seed's curve does (the seed adds its 40° offset so that its first period
//! is not long; a single move keeps that curve; the planner's lines use this
//! one).
//!
//! # Distance and entry speed
//!
//! [`ramp_length`] is the closed form `π·|v1² − v0²|/(4·a_max)`;
//! [`ramp_distance`] is its ceiling in whole steps. [`max_entry_speed`]
//! inverts it: `√(v1² + 4·a_max·d/π)`, taken down by the ulps that keep
//! `ramp_distance(max_entry_speed(v1, d, a), v1, a) ≤ d` (safe by
//! construction) while staying within a few ulps of the exact inverse.
//! A higher exit allows a higher entry, and more distance too: what the
//! planner's frozen lines rely on.

use core::f64::consts::PI;

use super::sqrt::sqrt;

/// The peak acceleration (steps/s², a magnitude) of the cosine ramp from
/// `v0` to `v1` (steps/s) over `d_steps` lead steps: `π·|v1² − v0²|/(4d)`.
pub fn peak_acceleration(v0: f64, v1: f64, d_steps: f64) -> f64 {
    PI * (v1 * v1 - v0 * v0).abs() / (4.0 * d_steps)
}

/// The peak jerk (steps/s³, a magnitude) of the cosine ramp from `v0` to
/// `v1` over `d_steps` lead steps: `(π·m/d)²·|h|`.
pub fn peak_jerk(v0: f64, v1: f64, d_steps: f64) -> f64 {
    let m = (v0 + v1) / 2.0;
    let h = (v1 - v0).abs() / 2.0;
    let rate = PI * m / d_steps;
    rate * rate * h
}

/// The time (seconds) the cosine ramp from `v0` to `v1` takes over
/// `d_steps` lead steps: `2d/(v0 + v1)` (infinite from rest to rest).
pub fn ramp_time(v0: f64, v1: f64, d_steps: f64) -> f64 {
    if d_steps <= 0.0 {
        return 0.0;
    }
    2.0 * d_steps / (v0 + v1)
}

/// The shortest distance (lead steps, not rounded) over which the cosine
/// ramp from `v0` to `v1` keeps its peak acceleration at or below
/// `a_max`: `π·|v1² − v0²|/(4·a_max)`, exact. 0 when `v0 == v1`.
pub fn ramp_length(v0: f64, v1: f64, a_max: f64) -> f64 {
    PI * (v1 * v1 - v0 * v0).abs() / (4.0 * a_max)
}

/// The shortest whole number of lead steps over which the cosine ramp from
/// `v0` to `v1` (steps/s, ≥ 0) keeps its peak acceleration at or below
/// `a_max` (steps/s², > 0): the ceiling of [`ramp_length`], held at
/// `u32::MAX`. 0 when `v0 == v1`.
pub fn ramp_distance(v0: f64, v1: f64, a_max: f64) -> u32 {
    ceil_steps(ramp_length(v0, v1, a_max))
}

/// The highest speed `v0 ≥ v1` from which the cosine ramp reaches `v1`
/// within `d_steps` lead steps at no more than `a_max`:
/// `ramp_distance(max_entry_speed(v1, d, a), v1, a) ≤ d` always. By the
/// ramp's symmetry it is also the highest speed reachable from `v1`
/// (accelerating) within `d_steps`.
pub fn max_entry_speed(v1: f64, d_steps: u32, a_max: f64) -> f64 {
    max_speed_within(v1, f64::from(d_steps), a_max)
}

/// The highest `w ≥ v` with `ramp_length(v, w, a_max) ≤ d_steps`: the
/// closed form, stepped down by ulps while rounding puts it over.
pub(crate) fn max_speed_within(v: f64, d_steps: f64, a_max: f64) -> f64 {
    if d_steps <= 0.0 {
        return v;
    }
    let mut w = sqrt(v * v + 4.0 * a_max * d_steps / PI);
    if w == f64::INFINITY {
        w = f64::MAX;
    }
    let mut tries = 0;
    while w > v && ramp_length(v, w, a_max) > d_steps && tries < 64 {
        w = next_down(w);
        tries += 1;
    }
    if ramp_length(v, w, a_max) > d_steps {
        return v;
    }
    w.max(v)
}

/// The lowest `w ≤ v` (≥ 0) with `ramp_length(w, v, a_max) ≤ d_steps`:
/// how far a line of `d_steps` can bring a speed `v` down. The closed form,
/// stepped up by ulps while rounding puts it over.
pub(crate) fn min_speed_within(v: f64, d_steps: f64, a_max: f64) -> f64 {
    if d_steps <= 0.0 {
        return v;
    }
    let square = v * v - 4.0 * a_max * d_steps / PI;
    if square <= 0.0 {
        return 0.0;
    }
    let mut w = sqrt(square);
    let mut tries = 0;
    while w < v && ramp_length(w, v, a_max) > d_steps && tries < 64 {
        w = f64::from_bits(w.to_bits() + 1);
        tries += 1;
    }
    w.min(v)
}

/// The next `f64` towards 0 from a positive finite `x` (`f64::next_down`
/// is newer than the crate's minimum Rust).
fn next_down(x: f64) -> f64 {
    if x <= 0.0 || !x.is_finite() {
        return x;
    }
    f64::from_bits(x.to_bits() - 1)
}

/// `⌈length⌉` for `length ≥ 0` (no `libm`), held at `u32::MAX`; NaN gives
/// `u32::MAX` (never a ramp that fits by accident).
pub(crate) fn ceil_steps(length: f64) -> u32 {
    if length.is_nan() || length >= f64::from(u32::MAX) {
        return u32::MAX;
    }
    if length <= 0.0 {
        return 0;
    }
    let whole = length as u32;
    if f64::from(whole) < length {
        whole + 1
    } else {
        whole
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The curve sampled in time: (distance covered, peak |a|, peak |j|)
    /// over 20 000 steps of a ramp of `d` steps, by the trapezoid rule and
    /// finite differences: the reference the closed forms are checked
    /// against.
    fn sampled(v0: f64, v1: f64, d: f64) -> (f64, f64, f64) {
        const SAMPLES: u32 = 20_000;
        let t = 2.0 * d / (v0 + v1);
        let dt = t / f64::from(SAMPLES);
        let speed = |i: u32| {
            let theta = PI * f64::from(i) / f64::from(SAMPLES);
            v0 + (v1 - v0) * (1.0 - libm::cos(theta)) / 2.0
        };
        let (mut distance, mut peak_a, mut peak_j) = (0.0, 0.0f64, 0.0f64);
        let mut last_a: Option<f64> = None;
        for i in 0..SAMPLES {
            distance += (speed(i) + speed(i + 1)) / 2.0 * dt;
            let a = (speed(i + 1) - speed(i)) / dt;
            peak_a = peak_a.max(a.abs());
            if let Some(last) = last_a {
                peak_j = peak_j.max(((a - last) / dt).abs());
            }
            last_a = Some(a);
        }
        (distance, peak_a, peak_j)
    }

    #[test]
    fn from_rest_it_is_pi_over_two_a_trapezoid() {
        // 5 000 steps/s at 100 000 steps/s²: a trapezoid's 125 steps, π/2 of them.
        let length = ramp_length(0.0, 5000.0, 100_000.0);
        assert!((length - 125.0 * PI / 2.0).abs() < 1e-9);
        assert_eq!(ramp_distance(0.0, 5000.0, 100_000.0), 197);
        assert_eq!(ramp_distance(500.0, 500.0, 1.0), 0);
        assert_eq!(max_entry_speed(300.0, 0, 1000.0), 300.0);
        assert_eq!(ramp_time(0.0, 5000.0, 100.0), 0.04);
    }

    #[test]
    fn ceiling() {
        assert_eq!(ceil_steps(0.0), 0);
        assert_eq!(ceil_steps(1.0), 1);
        assert_eq!(ceil_steps(1.000_001), 2);
        assert_eq!(ceil_steps(0.2), 1);
        assert_eq!(ceil_steps(f64::NAN), u32::MAX);
        assert_eq!(ceil_steps(1e30), u32::MAX);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn closed_forms_match_sampling(v0 in 0.0f64..1e5, v1 in 0.0f64..1e5, d in 1.0f64..1e5) {
            prop_assume!(v0 + v1 > 1.0);
            let (distance, peak_a, peak_j) = sampled(v0, v1, d);
            prop_assert!((distance - d).abs() <= 1e-6 * d, "{} over {}", distance, d);
            let closed = peak_acceleration(v0, v1, d);
            // Differences over a sample average the acceleration: never above the
            // peak beyond rounding. The rounding of a difference of two speeds
            // is about an ulp of the speed over a sample's time, whatever the
            // difference: for speeds 7e-6 apart at 5.5e4 that is 1.2e-8 of the
            // peak (a CI run read that once), so it is allowed for as such.
            let dt = 2.0 * d / (v0 + v1) / 20_000.0;
            let rounding = 4.0 * f64::EPSILON * v0.max(v1) / dt;
            prop_assert!(peak_a <= closed * (1.0 + 1e-9) + rounding + 1e-9, "{} > {}", peak_a, closed);
            prop_assert!(peak_a >= closed * (1.0 - 1e-6) - 1e-9, "{} < {}", peak_a, closed);
            // Second differences of nearly equal speeds are rounding noise.
            if (v1 - v0).abs() >= 0.1 * v0.max(v1) {
                prop_assert!(peak_j <= peak_jerk(v0, v1, d) * (1.0 + 1e-4) + 1e-6);
            }
            prop_assert_eq!(peak_acceleration(v1, v0, d), closed);
        }

        #[test]
        fn ramp_distance_is_the_shortest_that_fits(v0 in 0.0f64..1e5, v1 in 0.0f64..1e5, a_max in 10.0f64..1e7) {
            let d = ramp_distance(v0, v1, a_max);
            prop_assume!((1..1 << 30).contains(&d));
            prop_assert!(peak_acceleration(v0, v1, f64::from(d)) <= a_max * (1.0 + 1e-12));
            if d > 1 {
                prop_assert!(peak_acceleration(v0, v1, f64::from(d - 1)) > a_max);
            }
        }

        #[test]
        fn max_entry_speed_is_the_highest_that_fits(v1 in 0.0f64..1e5, d in 1u32..100_000, a_max in 10.0f64..1e7) {
            let v0 = max_entry_speed(v1, d, a_max);
            prop_assert!(v0 >= v1);
            prop_assert!(ramp_distance(v0, v1, a_max) <= d);
            prop_assert!(peak_acceleration(v0, v1, f64::from(d)) <= a_max * (1.0 + 1e-12));
            // A hair faster needs more than d steps at a_max.
            let faster = v0 * (1.0 + 1e-9) + 1e-9;
            prop_assert!(peak_acceleration(faster, v1, f64::from(d)) > a_max);
        }

        #[test]
        fn max_entry_speed_grows_with_exit_and_distance(v1 in 0.0f64..1e5, more in 0.0f64..1e4, d in 1u32..100_000, a_max in 10.0f64..1e7) {
            let v0 = max_entry_speed(v1, d, a_max);
            prop_assert!(max_entry_speed(v1 + more, d, a_max) >= v0);
            prop_assert!(max_entry_speed(v1, d + 1, a_max) >= v0);
        }
    }
}

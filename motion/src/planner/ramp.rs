//! The junction ramp: a cosine from one lead speed to another over a
//! distance, with its acceleration, its jerk, and the two questions the
//! planner asks of it (how long must a ramp be, how fast may a segment be
//! entered).
//!
//! # The curve
//!
//! Over `d` lead steps, from `v0` to `v1` (steps/s), at `s` steps in:
//!
//! ```text
//! θ(s) = π·s/d                           θ from 0 to π
//! v(θ) = v0 + (v1 − v0)·(1 − cos θ)/2  = m − h·cos θ
//!        m = (v0 + v1)/2,   h = (v1 − v0)/2
//! ```
//!
//! # Acceleration
//!
//! With `dθ/ds = π/d`, the acceleration is `a = dv/dt = v·dv/ds`:
//!
//! ```text
//! a(θ) = (π/d)·v·dv/dθ = (π/d)·h·(m − h·cos θ)·sin θ
//! ```
//!
//! It is 0 at θ = 0 and at θ = π: a segment's ramps and its cruise meet
//! with zero acceleration, and so do two segments at their junction.
//! Acceleration is continuous everywhere on a planned path.
//!
//! Its peak: `d/dθ[(m − h cos θ) sin θ] = −2h·c² + m·c + h` with
//! `c = cos θ`; for an accelerating ramp (`h > 0`, and `m ≥ h` since
//! `v0 ≥ 0`) the root in `[−1, 1]` is
//!
//! ```text
//! c* = (m − √(m² + 8h²))/(4h) = −2h/(m + √(m² + 8h²))     (no cancellation)
//! Q  = h·(m − h·c*)·√(1 − c*²)                           peak of v·dv/dθ
//! a_peak = π·Q/d
//! ```
//!
//! From rest (`v0 = 0`) `c* = −1/2` (θ = 120°) and `Q = 3√3·v1²/16`. A
//! decelerating ramp is the accelerating one from `v1` to `v0` read
//! backwards (`v(π − θ)`), so `Q` depends only on the lower and the higher
//! speed and has the same peak: everything below is symmetric in `v0`, `v1`.
//!
//! # Jerk
//!
//! `j = da/dt = v·da/ds = (π/d)²·h·v·(h·sin²θ + v·cos θ)`, so
//! `|j| ≤ (π/d)²·|h|·w·(|h| + w)` with `w = max(v0, v1)`. At the ends it
//! is `(π/d)²·h·v0²` and `−(π/d)²·h·v1²`: jerk is bounded but steps at a
//! ramp's ends (from the cruise's 0), as in every acceleration-continuous
//! (third-order) profile; only a ramp from or to rest starts or ends with
//! zero jerk.
//!
//! # Distance and entry speed
//!
//! [`ramp_length`] is the closed form `π·Q/a_max`, the exact shortest
//! distance whose peak stays at `a_max`; [`ramp_distance`] is its ceiling
//! in whole steps. [`max_entry_speed`] inverts it by bisection, keeping
//! the feasible end: its answer `v0` always satisfies
//! `ramp_distance(v0, v1, a_max) ≤ d` (safe by construction) and is within
//! a few ulps of the exact inverse (tight).
//!
//! The bisection is valid because `Q` grows with the higher speed `w` for
//! a fixed lower one `u`: with `h = (w − u)/2`, `m = (w + u)/2`, for every
//! θ, `∂/∂w [h·(m − h·cos θ)·sin θ] = ½·(m − h·cos θ + h·(1 − cos θ))·sin θ
//! ≥ 0` (as `m − h·cos θ ≥ m − h = u ≥ 0`), so the maximum grows too. And
//! `Q` falls as `u` rises for a fixed `w` (at the peak,
//! `∂/∂u = ½·(h·(1 + 2c*) − m)·sin θ* < 0` since `c* < 0` and `m ≥ h`):
//! a higher exit allows a higher entry, which is what the planner's
//! frozen lines rely on.
//!
//! The cosine costs distance: from rest it needs `3√3π/8 ≈ 2.04` times the
//! distance of a constant-acceleration ramp with the same peak. Its bound
//! `(w² − v²)/(2·a_max)` (the peak is at least the mean of `v·dv/ds`)
//! brackets the bisection.
//!
//! In the time domain a ramp that starts from rest (`v0 = 0`) leaves
//! `s = 0` with `v ∝ s²`, which in the continuum never starts; the
//! executor (not written yet) will start from rest with the seed's curve or
//! evaluate the speed at the first step, not at `s = 0`.

use core::f64::consts::PI;

use super::sqrt::sqrt;

/// The peak of `v·dv/dθ` over a cosine ramp between `v0` and `v1`
/// (steps²/s²): `Q` above. Symmetric in its arguments; 0 when they are
/// equal.
pub fn peak_v_dv_dtheta(v0: f64, v1: f64) -> f64 {
    let low = v0.min(v1);
    let high = v0.max(v1);
    let h = (high - low) / 2.0;
    if h <= 0.0 {
        return 0.0;
    }
    let m = (high + low) / 2.0;
    let cos_peak = -2.0 * h / (m + sqrt(m * m + 8.0 * h * h));
    let sin_peak = sqrt(1.0 - cos_peak * cos_peak);
    h * (m - h * cos_peak) * sin_peak
}

/// The peak acceleration (steps/s², a magnitude) of the cosine ramp from
/// `v0` to `v1` (steps/s) over `d_steps` lead steps: `π·Q/d`.
pub fn peak_acceleration(v0: f64, v1: f64, d_steps: f64) -> f64 {
    PI * peak_v_dv_dtheta(v0, v1) / d_steps
}

/// The shortest distance (lead steps, not rounded) over which the cosine
/// ramp from `v0` to `v1` keeps its peak acceleration at or below
/// `a_max`: `π·Q/a_max`, exact. 0 when `v0 == v1`.
pub fn ramp_length(v0: f64, v1: f64, a_max: f64) -> f64 {
    PI * peak_v_dv_dtheta(v0, v1) / a_max
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

/// The highest `w ≥ v` with `ramp_length(v, w, a_max) ≤ d_steps`, by
/// bisection that keeps the feasible end.
pub(crate) fn max_speed_within(v: f64, d_steps: f64, a_max: f64) -> f64 {
    if d_steps <= 0.0 {
        return v;
    }
    let fits = |w: f64| ramp_length(v, w, a_max) <= d_steps;
    let mut low = v;
    // A constant acceleration of a_max is the fastest any ramp can be.
    let mut high = sqrt(v * v + 2.0 * a_max * d_steps) * (1.0 + 1e-9) + 1e-9;
    if high == f64::INFINITY {
        high = f64::MAX;
    }
    if fits(high) {
        return high;
    }
    for _ in 0..200 {
        let mid = low + (high - low) / 2.0;
        if mid <= low || mid >= high {
            break;
        }
        if fits(mid) {
            low = mid;
        } else {
            high = mid;
        }
    }
    low
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

    /// The peak of `a(s) = v·dv/ds`, sampled: the reference the closed form
    /// is checked against.
    fn brute_peak_acceleration(v0: f64, v1: f64, d: f64) -> f64 {
        const SAMPLES: u32 = 20_000;
        let mut peak: f64 = 0.0;
        for i in 0..=SAMPLES {
            let theta = PI * f64::from(i) / f64::from(SAMPLES);
            let v = v0 + (v1 - v0) * (1.0 - theta.cos()) / 2.0;
            let dv_ds = (v1 - v0) * theta.sin() / 2.0 * PI / d;
            peak = peak.max((v * dv_ds).abs());
        }
        peak
    }

    /// The peak jerk `|v·da/ds|`, sampled by finite differences.
    fn brute_peak_jerk(v0: f64, v1: f64, d: f64) -> f64 {
        const SAMPLES: u32 = 20_000;
        let accel = |s: f64| {
            let theta = PI * s / d;
            let v = v0 + (v1 - v0) * (1.0 - theta.cos()) / 2.0;
            (v, v * (v1 - v0) * theta.sin() / 2.0 * PI / d)
        };
        let ds = d / f64::from(SAMPLES);
        let mut peak: f64 = 0.0;
        for i in 0..SAMPLES {
            let s = (f64::from(i) + 0.5) * ds;
            let (v, _) = accel(s);
            let jerk = v * (accel(s + ds / 2.0).1 - accel(s - ds / 2.0).1) / ds;
            peak = peak.max(jerk.abs());
        }
        peak
    }

    #[test]
    fn from_rest_peaks_at_120_degrees() {
        let q = peak_v_dv_dtheta(0.0, 1000.0);
        let expected = 3.0 * 3f64.sqrt() / 16.0 * 1000.0 * 1000.0;
        assert!((q - expected).abs() <= 1e-9 * expected);
        assert_eq!(peak_v_dv_dtheta(500.0, 500.0), 0.0);
        assert_eq!(ramp_distance(500.0, 500.0, 1.0), 0);
        assert_eq!(max_entry_speed(300.0, 0, 1000.0), 300.0);
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
        fn closed_form_peak_matches_sampling(v0 in 0.0f64..1e5, v1 in 0.0f64..1e5, d in 1.0f64..1e5) {
            let closed = peak_acceleration(v0, v1, d);
            let sampled = brute_peak_acceleration(v0, v1, d);
            // Sampling can only miss the top; 20 000 samples miss it by < 1e-7.
            prop_assert!(closed >= sampled * (1.0 - 1e-12), "{} < {}", closed, sampled);
            prop_assert!(closed <= sampled * (1.0 + 1e-7) + 1e-12, "{} > {}", closed, sampled);
            prop_assert_eq!(peak_acceleration(v1, v0, d), closed);
        }

        #[test]
        fn jerk_within_its_bound(v0 in 0.0f64..1e4, v1 in 0.0f64..1e4, d in 10.0f64..1e4) {
            let h = (v1 - v0).abs() / 2.0;
            let w = v0.max(v1);
            let bound = (PI / d).powi(2) * h * w * (h + w);
            prop_assert!(brute_peak_jerk(v0, v1, d) <= bound * (1.0 + 1e-6) + 1e-9);
        }

        #[test]
        fn ramp_distance_is_the_shortest_that_fits(v0 in 0.0f64..1e5, v1 in 0.0f64..1e5, a_max in 10.0f64..1e7) {
            let d = ramp_distance(v0, v1, a_max);
            prop_assume!((1..1 << 30).contains(&d));
            prop_assert!(brute_peak_acceleration(v0, v1, f64::from(d)) <= a_max * (1.0 + 1e-12));
            if d > 1 {
                // One step shorter is over the limit (by more than sampling misses).
                prop_assert!(brute_peak_acceleration(v0, v1, f64::from(d - 1)) > a_max * (1.0 - 1e-7));
            }
        }

        #[test]
        fn max_entry_speed_is_the_highest_that_fits(v1 in 0.0f64..1e5, d in 1u32..100_000, a_max in 10.0f64..1e7) {
            let v0 = max_entry_speed(v1, d, a_max);
            prop_assert!(v0 >= v1);
            prop_assert!(ramp_distance(v0, v1, a_max) <= d);
            prop_assert!(brute_peak_acceleration(v0, v1, f64::from(d)) <= a_max * (1.0 + 1e-12));
            // A hair faster needs more than d steps at a_max.
            let faster = v0 * (1.0 + 1e-9) + 1e-9;
            prop_assert!(brute_peak_acceleration(faster, v1, f64::from(d)) > a_max * (1.0 - 1e-7));
        }

        #[test]
        fn max_entry_speed_grows_with_exit_and_distance(v1 in 0.0f64..1e5, more in 0.0f64..1e4, d in 1u32..100_000, a_max in 10.0f64..1e7) {
            let v0 = max_entry_speed(v1, d, a_max);
            prop_assert!(max_entry_speed(v1 + more, d, a_max) >= v0);
            prop_assert!(max_entry_speed(v1, d + 1, a_max) >= v0);
        }
    }
}

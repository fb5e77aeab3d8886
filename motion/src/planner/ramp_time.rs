//! When a cosine ramp has covered a distance: the inverse of
//! `x(τ) = m·τ − h·(T/π)·sin(πτ/T)`, the runner's question for every
//! step it times inside a ramp.
//!
//! With the ramp's phase `θ = πτ/T` (0 to π) it is Kepler's equation,
//!
//! ```text
//! θ − e·sin θ = M,   e = h/m = (u1 − u0)/(u1 + u0) ∈ [−1, 1],   M = π·x/d
//! ```
//!
//! solved as astronomers solve it: a starting phase from the cubic that
//! the equation is near θ = 0 (`(1 − e)·θ + e·θ³/6 = M`, exact in the
//! limit where the solver has the least slope to work with: a ramp from
//! rest, `e = 1`), then Halley's steps (`sin`, `cos` of one `sincos` give
//! the slope and the curvature), kept inside a bracket. A ramp down
//! (`e < 0`) is solved as the ramp up it mirrors (`θ ↦ π − θ`), so the
//! flat end is always at θ = 0, where the starting cubic is exact.
//!
//! One to four evaluations a step (2.4 on average over the tests'
//! 12,080 ramp steps), where plain Newton from `τ = x/m` took six on
//! average and up to 37 (a ramp's last steps, where rounding put each
//! Newton step a hair outside the bracket and bisection took over). A
//! Halley step whose cubic error bound is well inside the tolerance is
//! taken without the evaluation that would confirm it (28,472
//! evaluations there, where confirming every step took 38,734 and plain
//! Newton 75,553). On a Cortex-M0+ each evaluation is two `f64`
//! trigonometric functions in software (tens of thousands of cycles a
//! step), what limits a grbl path's speed there (docs/performance.md).

use core::f64::consts::PI;

/// More evaluations than the solver ever needs (the tests bound it at 5);
/// a guard, not a budget.
const MAX_EVALUATIONS: u32 = 100;

/// The time at which the cosine ramp of length `d` from `u0` to `u1` (per
/// tick, both ≥ 0) has covered `x` (0 ≤ x ≤ d), to within `10⁻⁹·max(T, 1)`
/// ticks of the exact time (`T` the ramp's duration).
pub(super) fn time_in_ramp(x: f64, d: f64, u0: f64, u1: f64) -> f64 {
    ramp_time_evaluations(x, d, u0, u1).0
}

/// [`time_in_ramp`], and how many times it evaluated the ramp.
fn ramp_time_evaluations(x: f64, d: f64, u0: f64, u1: f64) -> (f64, u32) {
    if d <= 0.0 || x <= 0.0 {
        return (0.0, 0);
    }
    let m = (u0 + u1) / 2.0;
    let t = d / m;
    if x >= d {
        return (t, 0);
    }
    if u0 == u1 {
        return (x / m, 0);
    }
    let e = (u1 - u0) / (u1 + u0);
    let mean = PI * x / d;
    // The time's tolerance as a phase.
    let tolerance = 1e-9 * t.max(1.0) * PI / t;
    if e >= 0.0 {
        let (theta, evaluations) = phase(mean, e, tolerance);
        (theta * t / PI, evaluations)
    } else {
        let (theta, evaluations) = phase(PI - mean, -e, tolerance);
        ((PI - theta) * t / PI, evaluations)
    }
}

/// The phase θ ∈ [0, π] with `θ − e·sin θ = mean` (0 ≤ e ≤ 1, 0 ≤ mean ≤
/// π), to `tolerance`; and the evaluations it took.
fn phase(mean: f64, e: f64, tolerance: f64) -> (f64, u32) {
    let (mut low, mut high) = (0.0, PI);
    let mut theta = starting_phase(mean, e);
    for evaluation in 1..=MAX_EVALUATIONS {
        let (sin, cos) = libm::sincos(theta);
        let f = theta - e * sin - mean;
        if f > 0.0 {
            high = theta;
        } else {
            low = theta;
        }
        let slope = 1.0 - e * cos;
        // Converged when Newton's own step would be within the tolerance:
        // take it (its error is that step's square), inside the bracket
        // (at the root, rounding can put it a hair outside).
        if slope > 0.0 && (f / slope).abs() <= tolerance {
            return ((theta - f / slope).clamp(low, high), evaluation);
        }
        let denominator = 2.0 * slope * slope - f * e * sin;
        let mut next = if slope > 0.0 && denominator > 0.0 {
            theta - 2.0 * f * slope / denominator
        } else {
            f64::NAN
        };
        if next > low && next < high {
            // Halley's step leaves an error of about `k·δ³` (δ = f/slope,
            // Newton's step; `k` bounds the curvature terms, |sin|, |cos|
            // and e all at most 1). Well inside the tolerance, it is taken
            // without another evaluation to confirm it (a `sincos` in
            // software on an M0+: about a third of a step's solve).
            let step = f / slope;
            let k = 1.0 / (6.0 * slope) + 1.0 / (4.0 * slope * slope);
            if k * step * step * step.abs() <= tolerance / 4.0 {
                return (next, evaluation);
            }
        } else {
            next = low + (high - low) / 2.0;
        }
        if high - low <= 1e-12 * PI {
            return (next, evaluation);
        }
        theta = next;
    }
    (theta, MAX_EVALUATIONS)
}

/// The root of the equation's cubic near θ = 0, `(1 − e)·θ + e·θ³/6 =
/// mean` (one real root: the cubic rises), in [0, π].
fn starting_phase(mean: f64, e: f64) -> f64 {
    let theta = if e < 1e-6 {
        mean / (1.0 - e)
    } else {
        // θ³ + p·θ − q = 0 with p ≥ 0: θ = A − p/(3A), A the cube root
        // below (Cardano's, without its cancellation).
        let p = 6.0 * (1.0 - e) / e;
        let q = 6.0 * mean / e;
        let a = libm::cbrt(q / 2.0 + libm::sqrt(q * q / 4.0 + p * p * p / 27.0));
        if a > 0.0 {
            a - p / (3.0 * a)
        } else {
            mean
        }
    };
    if theta.is_finite() {
        theta.clamp(0.0, PI)
    } else {
        mean
    }
}

#[cfg(test)]
mod tests {
    use super::super::run::distance_in_ramp;
    use super::*;
    use proptest::prelude::*;

    /// The exact time by bisection alone, to the last bit it can resolve.
    fn by_bisection(x: f64, d: f64, u0: f64, u1: f64) -> f64 {
        let t = 2.0 * d / (u0 + u1);
        let (mut low, mut high) = (0.0, t);
        for _ in 0..200 {
            let middle = low + (high - low) / 2.0;
            if distance_in_ramp(middle, d, u0, u1) > x {
                high = middle;
            } else {
                low = middle;
            }
        }
        low + (high - low) / 2.0
    }

    /// The solver this one replaced: Newton from `τ = x/m` with
    /// bisection where a step would leave the bracket.
    fn newton_evaluations(x: f64, d: f64, u0: f64, u1: f64) -> u32 {
        let m = (u0 + u1) / 2.0;
        let t = d / m;
        let h = (u1 - u0) / 2.0;
        let w = PI / t;
        let (mut low, mut high) = (0.0, t);
        let mut tau = x / m;
        for evaluation in 1..=100 {
            let f = m * tau - h / w * libm::sin(w * tau) - x;
            if f > 0.0 {
                high = tau;
            } else {
                low = tau;
            }
            let v = m - h * libm::cos(w * tau);
            let mut next = if v > 0.0 { tau - f / v } else { f64::NAN };
            if !(next > low && next < high) {
                next = low + (high - low) / 2.0;
            }
            if (next - tau).abs() <= 1e-9 * t.max(1.0) || high - low <= 1e-12 * t {
                return evaluation;
            }
            tau = next;
        }
        100
    }

    /// Every half-step crossing of ramps a path makes: from rest, to
    /// rest, between speeds, at 125 MHz and 1 MHz ticks.
    fn ramps() -> impl Iterator<Item = (f64, f64, f64)> {
        let cases = [
            (0.0, 2_500.0, 600.0),
            (0.0, 50_000.0, 4_000.0),
            (2_500.0, 0.0, 600.0),
            (500.0, 2_500.0, 600.0),
            (2_500.0, 2_000.0, 100.0),
            (2_000.0, 2_500.0, 100.0),
            (100.0, 0.0, 37.0),
            (1.0, 0.0, 3.0),
        ];
        [125e6, 1e6].into_iter().flat_map(move |clock| {
            cases
                .into_iter()
                .map(move |(u0, u1, d)| (u0 / clock, u1 / clock, d))
        })
    }

    #[test]
    fn every_step_of_a_ramp_within_five_evaluations_and_the_tolerance() {
        let (mut new, mut old, mut steps) = (0, 0, 0);
        for (u0, u1, d) in ramps() {
            let t = 2.0 * d / (u0 + u1);
            for step in 1..=d as u32 {
                let x = f64::from(step) - 0.5;
                let (tau, evaluations) = ramp_time_evaluations(x, d, u0, u1);
                assert!(
                    evaluations <= 5,
                    "{evaluations} evaluations: {x} of {d}, {u0} → {u1}"
                );
                let exact = by_bisection(x, d, u0, u1);
                assert!(
                    (tau - exact).abs() <= 1e-9 * t.max(1.0),
                    "{tau} for {exact}: {x} of {d}, {u0} → {u1}"
                );
                new += evaluations;
                old += newton_evaluations(x, d, u0, u1);
                steps += 1;
            }
        }
        // What this solver is for: fewer evaluations (each a `sin` and a
        // `cos` in software on the firmware's cores) than the Newton it
        // replaced, on the same steps.
        assert!(
            f64::from(new) <= 0.6 * f64::from(old),
            "{new} evaluations against Newton's {old} over {steps} steps"
        );
    }

    #[test]
    fn the_ends_and_a_constant_speed() {
        assert_eq!(time_in_ramp(0.0, 10.0, 0.0, 1.0), 0.0);
        assert_eq!(time_in_ramp(-1.0, 10.0, 0.0, 1.0), 0.0);
        assert_eq!(time_in_ramp(10.0, 10.0, 0.0, 1.0), 20.0);
        assert_eq!(time_in_ramp(12.0, 10.0, 0.0, 1.0), 20.0);
        assert_eq!(time_in_ramp(5.0, 0.0, 0.0, 1.0), 0.0);
        assert_eq!(time_in_ramp(5.0, 10.0, 0.5, 0.5), 10.0);
        // Halfway through a ramp from rest to 1 over 10 (20 ticks) it has
        // covered m·T/2 − h·T/π.
        let x = 5.0 - 0.5 * 20.0 / PI;
        let tau = time_in_ramp(x, 10.0, 0.0, 1.0);
        assert!((tau - 10.0).abs() <= 1e-9, "{tau}");
        // And the ramp down that mirrors it, the same time from its end.
        let tau = time_in_ramp(10.0 - x, 10.0, 1.0, 0.0);
        assert!((tau - 10.0).abs() <= 1e-9, "{tau}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]
        #[test]
        fn the_time_at_which_the_ramp_covers_the_distance(
            u0 in 0.0f64..1.0,
            u1 in 0.0f64..1.0,
            d in 0.5f64..10_000.0,
            fraction in 0.0f64..=1.0,
            scale in prop::sample::select(vec![1e-2, 1e-4, 1e-6]),
        ) {
            let (u0, u1) = (u0 * scale, u1 * scale);
            prop_assume!(u0 + u1 > 1e-9 * scale);
            let x = fraction * d;
            let t = 2.0 * d / (u0 + u1);
            let (tau, evaluations) = ramp_time_evaluations(x, d, u0, u1);
            prop_assert!(evaluations <= 8, "{} evaluations", evaluations);
            prop_assert!((0.0..=t).contains(&tau));
            let exact = by_bisection(x, d, u0, u1);
            prop_assert!((tau - exact).abs() <= 1e-9 * t.max(1.0), "{} for {}", tau, exact);
        }
    }
}

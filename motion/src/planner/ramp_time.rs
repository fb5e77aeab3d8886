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
//! solved as astronomers solve it: Markley's starting phase (a cubic from
//! a Padé approximant of sin θ, within 5·10⁻⁴ rad of the root for every
//! e and M), then Halley's steps (`sin`, `cos` of one `sincos` give the
//! slope and the curvature), kept inside a bracket. A ramp down (`e < 0`)
//! is solved as the ramp up it mirrors (`θ ↦ π − θ`), so the flat end is
//! always at θ = 0.
//!
//! One evaluation a step: over the tests' 12,080 ramp steps, and 182,080
//! random ones, the first Halley step always lands well inside the
//! tolerance and is taken without the evaluation that would confirm it.
//! Plain Newton from `τ = x/m` took six on average and up to 37 (75,553
//! there); the cubic near θ = 0 as the start, up to half a radian off
//! mid-ramp, 2.4 (28,472). The runner's solves come a step at a time, so
//! each starts where the axis's last one landed ([`Warm`]: a second-order
//! prediction, no cube root or square root), Markley's start only for a
//! ramp's first step or near its flat end. The `sincos` comes from the P2
//! CORDIC's cosine table (`cordic_core::sin_cos`) rather than `libm`,
//! and a [`Ramp`]'s divisions are made once a line. On a Cortex-M0+, whose
//! `f64` is software, a step's solve took 56,000 cycles and takes about
//! 13,000 to 15,000 (22,600 from Markley's start): docs/performance.md,
//! what limits a grbl path's speed there.

use core::f64::consts::{FRAC_1_PI, PI};

use cordic_core::SIN_COS_ERROR;

/// More evaluations than the solver ever needs (the tests bound it at 5);
/// a guard, not a budget.
const MAX_EVALUATIONS: u32 = 100;

/// The time at which the cosine ramp of length `d` from `u0` to `u1` (per
/// tick, both ≥ 0) has covered `x` (0 ≤ x ≤ d), to within `10⁻⁹·max(T, 1)`
/// ticks of the exact time (`T` the ramp's duration).
pub(super) fn time_in_ramp(x: f64, d: f64, u0: f64, u1: f64) -> f64 {
    Ramp::new(d, u0, u1).time(x)
}

/// A cosine ramp's constants for its inverse, worked out once (a line's
/// two ramps when it is timed): the divisions a step's solve would
/// otherwise repeat (each in software on an M0+).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Ramp {
    /// Length (steps); no ramp at all when 0 or less.
    d: f64,
    /// Duration (ticks).
    t: f64,
    /// Ticks per step, when the speed is constant (`u0 == u1`); else 0.
    flat_ticks_per_step: f64,
    /// |e| (see the module), and whether the ramp runs down (`e < 0`,
    /// solved as the ramp up it mirrors).
    e: f64,
    down: bool,
    /// The phase a step covers (π/d), the ticks a radian of phase takes
    /// (T/π), and the time's tolerance as a phase.
    radians_per_step: f64,
    ticks_per_radian: f64,
    tolerance: f64,
}

/// Where a solve landed, for the next solve of the same ramp to start
/// from (the runner keeps one an axis: its steps come in order, a step's
/// phase a little past its last).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Warm {
    /// The solved equation's mean (mirrored for a ramp down) and phase,
    /// and `1 − e·cos θ`, `e·sin θ` where the solve evaluated it.
    mean: f64,
    phase: f64,
    slope: f64,
    e_sin: f64,
}

/// The largest first-order phase step a warm start predicts across (past
/// it, Markley's start is as good and needs no slope to be large).
const WARM_STEP_MAX: f64 = 0.05;

/// The least slope a warm start predicts from (near a ramp's flat end the
/// phase curves too fast for the prediction; Markley's start is exact in
/// that limit).
const WARM_SLOPE_MIN: f64 = 0.2;

impl Ramp {
    /// The ramp of length `d` from `u0` to `u1` (per tick, both ≥ 0).
    pub(super) fn new(d: f64, u0: f64, u1: f64) -> Self {
        if d <= 0.0 {
            return Ramp::default();
        }
        let m = (u0 + u1) / 2.0;
        let t = d / m;
        if u0 == u1 {
            return Ramp {
                d,
                t,
                flat_ticks_per_step: 1.0 / m,
                ..Ramp::default()
            };
        }
        let e = (u1 - u0) / (u1 + u0);
        // Ticks per radian of phase.
        let ticks_per_radian = t * FRAC_1_PI;
        Ramp {
            d,
            t,
            flat_ticks_per_step: 0.0,
            e: e.abs(),
            down: e < 0.0,
            radians_per_step: PI / d,
            ticks_per_radian,
            // 10⁻⁹·max(T, 1) ticks as a phase.
            tolerance: if t >= 1.0 {
                1e-9 * PI
            } else {
                1e-9 / ticks_per_radian
            },
        }
    }

    /// Its duration (ticks).
    pub(super) fn duration(&self) -> f64 {
        self.t
    }

    /// The equation's mean at `x`, as the solver takes it (mirrored for a
    /// ramp down).
    fn mean_at(&self, x: f64) -> f64 {
        let mean = x * self.radians_per_step;
        if self.down {
            PI - mean
        } else {
            mean
        }
    }

    /// The time (ticks into the ramp) at which it has covered `x`.
    pub(super) fn time(&self, x: f64) -> f64 {
        self.time_from(x, None).0
    }

    /// [`Self::time`], starting from where a solve of this ramp landed
    /// (`warm`, an earlier step's); and where this one landed (`None` when
    /// it solved nothing: an end, a constant speed). The time is within the
    /// tolerance either way, but its last bits depend on the start: the
    /// runner keeps the chain of starts the same however its edges are
    /// asked for.
    pub(super) fn time_from(&self, x: f64, warm: Option<&Warm>) -> (f64, Option<Warm>) {
        let (time, landed, _) = self.time_evaluations(x, warm);
        (time, landed)
    }

    /// [`Self::time_from`], and how many times it evaluated the ramp.
    fn time_evaluations(&self, x: f64, warm: Option<&Warm>) -> (f64, Option<Warm>, u32) {
        if self.d <= 0.0 || x <= 0.0 {
            return (0.0, None, 0);
        }
        if x >= self.d {
            return (self.t, None, 0);
        }
        if self.flat_ticks_per_step > 0.0 {
            return (x * self.flat_ticks_per_step, None, 0);
        }
        let mean = self.mean_at(x);
        let start = warm
            .and_then(|warm| warm.predict(mean))
            .unwrap_or_else(|| starting_phase(mean, self.e));
        let (landed, evaluations) = phase(mean, self.e, self.tolerance, start);
        let theta = if self.down {
            PI - landed.phase
        } else {
            landed.phase
        };
        (theta * self.ticks_per_radian, Some(landed), evaluations)
    }
}

impl Warm {
    /// The phase at `mean` to second order from where the last solve
    /// landed (`dθ/dM = 1/slope`, `d²θ/dM² = −e·sin θ/slope³`), if that is
    /// near enough to trust.
    fn predict(&self, mean: f64) -> Option<f64> {
        if self.slope < WARM_SLOPE_MIN {
            return None;
        }
        let step = (mean - self.mean) / self.slope;
        if step.abs() > WARM_STEP_MAX {
            return None;
        }
        Some(self.phase + step - 0.5 * self.e_sin * step * step / self.slope)
    }
}

/// The phase θ ∈ [0, π] with `θ − e·sin θ = mean` (0 ≤ e ≤ 1, 0 ≤ mean ≤
/// π), to `tolerance`, from `start`: where it landed, and the evaluations
/// it took.
fn phase(mean: f64, e: f64, tolerance: f64, start: f64) -> (Warm, u32) {
    let (mut low, mut high) = (0.0, PI);
    let mut theta = start.clamp(0.0, PI);
    for evaluation in 1..=MAX_EVALUATIONS {
        // The P2 CORDIC's cosine table (2^-41), turned by the rest of the
        // binary angle: a fifth of `libm`'s cycles on an M0+.
        let (mut sin, mut cos) = cordic_core::sin_cos(theta);
        let mut slope = 1.0 - e * cos;
        // The table's error moves the root by up to `SIN_COS_ERROR / slope`:
        // where the slope is that small (a ramp from rest, its first steps
        // of a long ramp) the exact functions answer instead.
        if slope * tolerance < 8.0 * SIN_COS_ERROR {
            (sin, cos) = libm::sincos(theta);
            slope = 1.0 - e * cos;
        }
        let e_sin = e * sin;
        let landed = |phase| Warm {
            mean,
            phase,
            slope,
            e_sin,
        };
        let f = theta - e_sin - mean;
        if f > 0.0 {
            high = theta;
        } else {
            low = theta;
        }
        let mut next = f64::NAN;
        if slope > 0.0 {
            // Newton's step.
            let step = f / slope;
            // Converged when Newton's own step is within the tolerance:
            // take it (its error is that step's square), inside the
            // bracket (at the root, rounding can put it a hair outside).
            if step.abs() <= tolerance {
                let phase = (theta - step).clamp(low, high);
                return (landed(phase), evaluation);
            }
            // Halley's: θ − 2·f·slope / (2·slope² − f·e·sin θ).
            let slope_squared = slope * slope;
            let denominator = 2.0 * slope_squared - f * e_sin;
            if denominator > 0.0 {
                next = theta - 2.0 * f * slope / denominator;
            }
            if next > low && next < high {
                // Halley's step leaves an error of about `k·|δ|³` (δ
                // Newton's step, `k = 1/(6·slope) + 1/(4·slope²)` bounding
                // the curvature terms, |sin|, |cos| and e all at most 1).
                // Well inside the tolerance it is taken without another
                // evaluation to confirm it: `k·|δ|³ ≤ tolerance/4`, that is
                // `(2·slope + 3)·|δ|³ ≤ 3·tolerance·slope²`, with no
                // division (each an `f64` division in software on an M0+).
                let cube = step * step * step.abs();
                if (2.0 * slope + 3.0) * cube <= 3.0 * tolerance * slope_squared {
                    return (landed(next), evaluation);
                }
            }
        }
        if !(next > low && next < high) {
            next = low + (high - low) / 2.0;
        }
        if high - low <= 1e-12 * PI {
            return (landed(next), evaluation);
        }
        theta = next;
    }
    // Never reached (the guard); no slope to predict the next start from.
    let landed = Warm {
        mean,
        phase: theta,
        slope: 0.0,
        e_sin: 0.0,
    };
    (landed, MAX_EVALUATIONS)
}

/// A starting phase within 5·10⁻⁴ rad of the root for every `e` in
/// [0, 1] and `mean` in [0, π], and within 10⁻³ of the root relative to
/// it at a ramp's flat end: Markley's starter (F. L. Markley, "Kepler
/// equation solver", Celestial Mechanics and Dynamical Astronomy 63,
/// 1995), the root of a cubic from a Padé approximant of sin θ. From
/// there one Halley step lands within the tolerance (the tests' ramps: one
/// evaluation every step, where the cubic near θ = 0, up to half a radian
/// off mid-ramp, took 2.4).
fn starting_phase(mean: f64, e: f64) -> f64 {
    const PI_SQUARED: f64 = PI * PI;
    let alpha =
        (3.0 * PI_SQUARED + 1.6 * PI * (PI - mean) / (1.0 + e)) * (1.0 / (PI_SQUARED - 6.0));
    let one_minus_e = 1.0 - e;
    let d = 3.0 * one_minus_e + alpha * e;
    let alpha_d = alpha * d;
    let mean_squared = mean * mean;
    let q = 2.0 * alpha_d * one_minus_e - mean_squared;
    let r = (3.0 * alpha_d * (d - one_minus_e) + mean_squared) * mean;
    let root = cube_root(r.abs() + super::sqrt::sqrt(q * q * q + r * r));
    let w = root * root;
    let theta = (2.0 * r * w / (w * w + w * q + q * q) + mean) / d;
    if theta.is_finite() {
        theta.clamp(0.0, PI)
    } else {
        mean
    }
}

/// The most [`cube_root`] is off by, relative to the root (its tests).
#[cfg(test)]
const CUBE_ROOT_ERROR: f64 = 2.5e-5;

/// The cube root of `value` (> 0) within 2.5·10⁻⁵ of it (a starting
/// phase needs no more: it moves Markley's start by far less than its own
/// error): a first guess from the exponent's bits, then one of Halley's
/// steps, where `libm::cbrt` rounds correctly at several times the cost.
fn cube_root(value: f64) -> f64 {
    if !(value >= f64::MIN_POSITIVE && value.is_finite()) {
        return libm::cbrt(value);
    }
    // The high word's third (a 32-bit division: the RP2040's divider),
    // rebiased (fdlibm's constant): within 3.3 % of the root.
    let high = (value.to_bits() >> 32) as u32;
    let guess = f64::from_bits(u64::from(high / 3 + 715_094_163) << 32);
    let cube = guess * guess * guess;
    guess * ((cube + value + value) / (cube + cube + value))
}

#[cfg(test)]
mod tests {
    use super::super::run::distance_in_ramp;
    use super::*;
    use proptest::prelude::*;

    /// A cold solve's time and evaluations.
    fn ramp_time_evaluations(x: f64, d: f64, u0: f64, u1: f64) -> (f64, u32) {
        let (time, _, evaluations) = Ramp::new(d, u0, u1).time_evaluations(x, None);
        (time, evaluations)
    }

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
    fn every_step_of_a_ramp_in_one_evaluation_within_the_tolerance() {
        let (mut new, mut old, mut steps) = (0, 0, 0);
        for (u0, u1, d) in ramps() {
            let t = 2.0 * d / (u0 + u1);
            for step in 1..=d as u32 {
                let x = f64::from(step) - 0.5;
                let (tau, evaluations) = ramp_time_evaluations(x, d, u0, u1);
                assert_eq!(evaluations, 1, "{x} of {d}, {u0} → {u1}");
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
        // replaced, on the same steps (12,080 against 75,553).
        assert!(
            f64::from(new) <= 0.2 * f64::from(old),
            "{new} evaluations against Newton's {old} over {steps} steps"
        );
    }

    #[test]
    fn a_ramps_steps_in_order_start_from_the_last_and_land_as_near() {
        // As the runner asks: each step's solve starts where the axis's
        // last one landed.
        let (mut warm_starts, mut steps) = (0, 0);
        for (u0, u1, d) in ramps() {
            let ramp = Ramp::new(d, u0, u1);
            let t = 2.0 * d / (u0 + u1);
            let mut warm: Option<Warm> = None;
            for step in 1..=d as u32 {
                let x = f64::from(step) - 0.5;
                if warm.is_some_and(|warm| warm.predict(ramp.mean_at(x)).is_some()) {
                    warm_starts += 1;
                }
                let (tau, landed, evaluations) = ramp.time_evaluations(x, warm.as_ref());
                assert_eq!(evaluations, 1, "{x} of {d}, {u0} → {u1}");
                let exact = by_bisection(x, d, u0, u1);
                assert!(
                    (tau - exact).abs() <= 1e-9 * t.max(1.0),
                    "{tau} for {exact}: {x} of {d}, {u0} → {u1}"
                );
                warm = landed;
                steps += 1;
            }
        }
        // Nearly every step starts from its last (11,884 of 12,080): a
        // ramp's first step, and those near a flat end, from Markley's.
        assert!(warm_starts * 100 >= steps * 95, "{warm_starts} of {steps}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        #[test]
        fn a_solve_from_any_earlier_landing_is_within_the_tolerance(
            u0 in 0.0f64..1.0,
            u1 in 0.0f64..1.0,
            d in 0.5f64..10_000.0,
            from in 0.0f64..=1.0,
            to in 0.0f64..=1.0,
            scale in prop::sample::select(vec![1e-2, 1e-4, 1e-6]),
        ) {
            let (u0, u1) = (u0 * scale, u1 * scale);
            prop_assume!(u0 + u1 > 1e-9 * scale);
            let ramp = Ramp::new(d, u0, u1);
            let t = 2.0 * d / (u0 + u1);
            let (_, warm, _) = ramp.time_evaluations(from * d, None);
            let (tau, _, evaluations) = ramp.time_evaluations(to * d, warm.as_ref());
            prop_assert!(evaluations <= 8, "{} evaluations", evaluations);
            let exact = by_bisection(to * d, d, u0, u1);
            prop_assert!((tau - exact).abs() <= 1e-9 * t.max(1.0), "{} for {}", tau, exact);
        }
    }

    /// The root of Kepler's equation by bisection alone.
    fn kepler_root(mean: f64, e: f64) -> f64 {
        let (mut low, mut high) = (0.0, PI);
        for _ in 0..200 {
            let middle = low + (high - low) / 2.0;
            if middle - e * libm::sin(middle) > mean {
                high = middle;
            } else {
                low = middle;
            }
        }
        low + (high - low) / 2.0
    }

    #[test]
    fn markleys_start_is_within_half_a_milliradian_of_the_root() {
        let mut worst: f64 = 0.0;
        for i in 0..=100 {
            let e = f64::from(i) / 100.0;
            for j in 1..=200 {
                let mean = PI * f64::from(j) / 200.0;
                let error = (starting_phase(mean, e) - kepler_root(mean, e)).abs();
                worst = worst.max(error);
            }
            // And the flat end of a ramp from rest.
            for mean in [1e-12, 1e-9, 1e-6, 1e-3] {
                let root = kepler_root(mean, e);
                let error = (starting_phase(mean, e) - root).abs();
                assert!(error <= 1e-3 * root, "e {e}, M {mean}: {error}");
            }
        }
        assert!(worst <= 5e-4, "{worst}");
    }

    proptest! {
        #[test]
        fn the_cube_root_within_its_bound(value in 1e-300f64..1e300) {
            let root = cube_root(value);
            let exact = libm::cbrt(value);
            prop_assert!((root - exact).abs() <= CUBE_ROOT_ERROR * exact, "{} for {}", root, exact);
        }
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

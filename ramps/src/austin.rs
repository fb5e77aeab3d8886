//! David Austin's real-time linear ramp ("Generate stepper-motor speed
//! profiles in real time", 2004), in `f64` and in the paper's 24.8 fixed
//! point.
//!
//! # The equations (Austin's numbering; in steps, so the step angle α = 1)
//!
//! A timer at `f` Hz is loaded with a count `c` per step. Ramping from rest
//! with acceleration `a` (the paper's ω′):
//!
//! ```text
//! Eq. 7   c0 = f·sqrt(2/a)                     first delay, exact      c0_exact
//! Eq. 8   c_n = c0·(sqrt(n+1) − sqrt(n))       exact delay of step n   exact_delay
//! Eq. 13  c_n = c_{n−1} − 2·c_{n−1}/(4n + 1)   the approximation       Ramp::next
//! Eq. 14  n < 0 decelerates; the last steps of an m-step move have n_i = i − m
//! Eq. 15  c0 = 0.676·f·sqrt(2/a)               absorbs Eq. 13's error  c0_corrected
//! Eq. 16  n = v²/(2a)                          steps to reach speed v  steps_to_speed
//! Eq. 18  (n + ½)·a constant across a change of acceleration  Ramp::change_accel
//! Eq. 19  n = m·a2/(a1 + a2)                   short move: where to start decelerating
//!                                                                      short_move_decel_start
//! Eq. 22  Δc scaled by (n2 − n)/(n2 − n1)      linear-factor transition linear_factor
//! ```
//!
//! Eq. 13 is exact in the limit but 45% off at n = 1 (the ratio c1/c0 is 0.6
//! instead of 0.4142, the paper's Table 1); its error falls as 1/n³. The
//! product of its ratios tends to `0.7397/sqrt(n)` where the exact delays go
//! as `0.5/sqrt(n)`, so starting from `0.676·c0` (= 0.5/0.7397, Eq. 15) makes
//! the approximate delays converge on the exact ones after the first few
//! steps (measured here: within 0.1% from n = 10 on).
//!
//! The linear-factor transition (Eq. 22 onward) tapers the acceleration to
//! zero over ramp indices `n1 … n2` instead of stopping it abruptly at the
//! top speed. In the continuous limit of Eq. 13 (`dc/dn = −k·c/(2n)`, `k` the
//! factor) the speed gained over the taper is
//!
//! ```text
//! ω(n2)/ω(n1) = exp(½·(n2·ln(n2/n1)/(n2 − n1) − 1))     linear_transition_gain
//! ```
//!
//! and [`linear_transition_start`] solves it for the `n1` at which a taper of
//! a given length must start to end at the speed a plain ramp reaches at
//! `n`; for long ramps `n1 ≈ n − length/2`.
//!
//! # The move profiles
//!
//! [`AustinProfile`] (`f64`) and [`AustinFixedProfile`] (24.8 fixed point)
//! run the same plan:
//!
//! - `r` = the number of ramp steps: the steps `k` whose midpoint `k + ½`
//!   lies below `min(v²/(2a), m/2)` — Eq. 16 for a long move, Eq. 19 (equal
//!   accelerations, so `m/2`) for a short one, and exactly the exact
//!   trapezoid's ([`Trapezoid`](super::trapezoid::Trapezoid)) acceleration
//!   steps;
//! - steps `0 … r−1` accelerate: `c0` from Eq. 15, then Eq. 13 with `n = i`;
//! - the steps in between run at the top speed, `max(f/v, c_r)`: `f/v` for a
//!   long move, the ramp's own next value `c_r` for the peak step of an odd
//!   short move;
//! - the last `r` steps decelerate with Eq. 13 and `n_i = i − m` (Eq. 14),
//!   starting from the ramp's value at `n = r`, which makes the deceleration
//!   the mirror image of the acceleration;
//! - every delay is at least `f/v` (Eq. 13 may step below it), so no step is
//!   faster than requested.
//!
//! Planning (c0, `f/v`, `r`) is done once in `f64`; per step, the `f64`
//! profile evaluates Eq. 13 in `f64` and the fixed-point profile in 24.8
//! ([`U24F8`], the paper's format: integer part up to 2^24 − 1 ticks, delta
//! rounded to the nearest 1/256 tick). `delay_ticks` is `c` rounded to the
//! nearest tick, `velocity_steps_per_s` is `f/c`.
//!
//! # Against the exact trapezoid
//!
//! Measured with [`compare_edge_times`](super::trapezoid::compare_edge_times):
//! nearly all the timing error is Eq. 15's first delay, 0.324·c0 short on
//! each ramp, so a long move ends about 0.67·c0 (c0 = `f·sqrt(2/a)`) early
//! (200 MHz, 20,000 steps/s, 50,000 steps/s², 20,000 steps: 849,874 ticks,
//! 4.2 ms, RMS 424,969); a one-step move is the worst, 0.74·c0. The tests
//! hold every edge within `0.75·c0 + f/v + ½ tick per step` (delays are
//! rounded one by one). The 24.8 profile stays within 2 ticks of the `f64`
//! one per delay.

use fixed::types::{U24F8, U56F8};

use super::trapezoid::{round_ticks, LinearMove, MAX_DELAY_TICKS};
use super::{Phase, PlanError, Profile, Step};

/// Eq. 15's correction factor for the first delay, `0.676` (the paper's
/// value; in closed form `Γ(3/4)/(2·Γ(5/4))` = 0.67598).
pub const FIRST_DELAY_FACTOR: f64 = 0.676;

/// The state of an Austin ramp: the current delay `c` (timer counts) and the
/// ramp index `n` (steps from standstill at the current acceleration;
/// negative while decelerating, Eq. 14).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ramp {
    c: f64,
    n: f64,
}

impl Ramp {
    /// A ramp at delay `c` (timer counts) and index `n`. Starting from rest
    /// is `Ramp::new(c0, 0.0)` with `c0` from [`c0_exact`] or
    /// [`c0_corrected`]; decelerating to rest in `k` steps is
    /// `Ramp::new(c, -(k as f64) - 1.0)` with `c` the delay at index `k`.
    pub fn new(c: f64, n: f64) -> Self {
        Self { c, n }
    }

    /// The current delay, timer counts.
    pub fn c(&self) -> f64 {
        self.c
    }

    /// The current ramp index.
    pub fn n(&self) -> f64 {
        self.n
    }

    /// Eq. 13: advances `n` by one and returns the new delay
    /// `c − 2c/(4n + 1)` (shorter for `n > 0`, longer for `n < 0`).
    /// `4n + 1` must not be 0 (an `n` of −¼ after the step): the result would
    /// not be finite.
    #[allow(clippy::should_implement_trait)] // the paper's step, not an iterator
    pub fn next(&mut self) -> f64 {
        self.next_scaled(1.0)
    }

    /// Eq. 22: like [`Ramp::next`], with the change in `c` scaled by
    /// `factor` (from [`linear_factor`]; 1 is Eq. 13, 0 holds the speed).
    pub fn next_scaled(&mut self, factor: f64) -> f64 {
        self.n += 1.0;
        self.c -= factor * 2.0 * self.c / (4.0 * self.n + 1.0);
        self.c
    }

    /// Eq. 18: the acceleration changes from `from` to `to` (signed, negative
    /// to decelerate) at the current speed, so `n` becomes
    /// `(n + ½)·from/to − ½`; `c` is unchanged. A `to` that is zero or not
    /// finite leaves the ramp unchanged (hold a speed by not stepping the
    /// ramp).
    pub fn change_accel(&mut self, from: f64, to: f64) {
        if to != 0.0 && to.is_finite() {
            self.n = (self.n + 0.5) * from / to - 0.5;
        }
    }
}

/// Eq. 8: the exact delay of step `n` (`n ≥ 0`) of a ramp from rest whose
/// first delay is `c0`: `c0·(sqrt(n+1) − sqrt(n))`, evaluated as
/// `c0/(sqrt(n+1) + sqrt(n))` to avoid cancellation for large `n`.
pub fn exact_delay(c0: f64, n: f64) -> f64 {
    c0 / (libm::sqrt(n + 1.0) + libm::sqrt(n))
}

/// Eq. 7: the exact first delay from rest, `f·sqrt(2/a)` timer counts
/// (`timer_hz` = f, acceleration `a` in steps/s²).
pub fn c0_exact(timer_hz: f64, accel_steps_per_s2: f64) -> f64 {
    timer_hz * libm::sqrt(2.0 / accel_steps_per_s2)
}

/// Eq. 15: the first delay corrected for Eq. 13's error at `n = 1`,
/// [`FIRST_DELAY_FACTOR`] × [`c0_exact`].
pub fn c0_corrected(timer_hz: f64, accel_steps_per_s2: f64) -> f64 {
    FIRST_DELAY_FACTOR * c0_exact(timer_hz, accel_steps_per_s2)
}

/// Eq. 16: steps from rest to `speed` at acceleration `accel`,
/// `speed²/(2·accel)` (steps, steps/s, steps/s²).
pub fn steps_to_speed(speed_steps_per_s: f64, accel_steps_per_s2: f64) -> f64 {
    speed_steps_per_s * speed_steps_per_s / (2.0 * accel_steps_per_s2)
}

/// Eq. 19: in a move of `steps` too short to reach the top speed,
/// accelerating at `accel` and decelerating at `decel` (both magnitudes),
/// deceleration starts after `steps·decel/(accel + decel)` steps.
pub fn short_move_decel_start(steps: f64, accel: f64, decel: f64) -> f64 {
    steps * decel / (accel + decel)
}

/// Eq. 22's linear factor `(n2 − n)/(n2 − n1)`, clamped to `[0, 1]`: full
/// acceleration up to `n1`, none from `n2` on.
pub fn linear_factor(n: f64, n1: f64, n2: f64) -> f64 {
    if n <= n1 {
        1.0
    } else if n >= n2 {
        0.0
    } else {
        (n2 - n) / (n2 - n1)
    }
}

/// The speed ratio `ω(n2)/ω(n1)` that the linear-factor taper over ramp
/// indices `n1 … n2` (`0 < n1 < n2`) adds, in the continuous limit of
/// Eq. 13: `exp(½·(n2·ln(n2/n1)/(n2 − n1) − 1))`. (A plain ramp over the
/// same indices gains `sqrt(n2/n1)`.)
pub fn linear_transition_gain(n1: f64, n2: f64) -> f64 {
    let length = n2 - n1;
    if length <= 0.0 {
        return 1.0;
    }
    libm::exp(0.5 * (n2 * libm::log(n2 / n1) / length - 1.0))
}

/// Where a linear-factor taper of `length` ramp steps must start (`n1`) so
/// that it ends at the speed a plain ramp reaches at index `n_top` (for a
/// top speed `v`, `n_top` is [`steps_to_speed`]): the root of
/// `sqrt(n1/n_top)·gain(n1, n1 + length) = 1`. `None` unless
/// `0 < length < e·n_top` (a longer taper cannot reach the speed). The
/// taper then ends at `n2 = n1 + length`; for `length ≪ n_top`,
/// `n1 ≈ n_top − length/2`.
pub fn linear_transition_start(n_top: f64, length: f64) -> Option<f64> {
    if !(n_top > 0.0 && length > 0.0 && n_top.is_finite() && length.is_finite()) {
        return None;
    }
    if length >= core::f64::consts::E * n_top {
        return None;
    }
    // ln(speed at the end / top speed), increasing in n1: negative near 0,
    // positive at n_top.
    let excess =
        |n1: f64| 0.5 * libm::log(n1 / n_top) + libm::log(linear_transition_gain(n1, n1 + length));
    let (mut low, mut high) = (0.0_f64, n_top);
    for _ in 0..200 {
        let mid = 0.5 * (low + high);
        if mid <= low || mid >= high {
            break;
        }
        if mid > 0.0 && excess(mid) < 0.0 {
            low = mid;
        } else {
            high = mid;
        }
    }
    Some(0.5 * (low + high))
}

/// The plan both Austin profiles share, in `f64` timer counts.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Plan {
    clkfreq_hz: f64,
    steps: u32,
    /// Steps accelerating, and as many decelerating.
    ramp_steps: u32,
    /// Eq. 15's first delay.
    c0: f64,
    /// `f / v`.
    slew_delay: f64,
}

impl Plan {
    fn new(
        clkfreq: u32,
        speed_steps_per_s: f64,
        accel_steps_per_s2: f64,
        steps: u32,
    ) -> Result<Self, PlanError> {
        let inputs = LinearMove::check(clkfreq, speed_steps_per_s, accel_steps_per_s2, steps)?;
        let c0 = c0_corrected(inputs.clkfreq_hz, accel_steps_per_s2);
        // The longest delay is the first (or f/v, checked with the inputs).
        if c0.is_nan() || c0 > MAX_DELAY_TICKS {
            return Err(PlanError::DelayOverflow);
        }
        Ok(Self {
            clkfreq_hz: inputs.clkfreq_hz,
            steps,
            ramp_steps: inputs.ramp_steps(),
            c0,
            slew_delay: inputs.slew_delay_ticks,
        })
    }
}

/// The arithmetic a profile evaluates Eq. 13 in: `f64` or 24.8.
trait Counts: Copy + PartialOrd {
    /// Eq. 13 from `self` for the ramp index `n` (already advanced, ≠ 0).
    fn eq13(self, n: i64) -> Self;
    /// The delay in timer counts as `f64`.
    fn to_f64(self) -> f64;
    /// Rounded to the nearest tick, ≥ 1.
    fn delay_ticks(self) -> u32;
}

impl Counts for f64 {
    fn eq13(self, n: i64) -> Self {
        Ramp::new(self, (n - 1) as f64).next()
    }

    fn to_f64(self) -> f64 {
        self
    }

    fn delay_ticks(self) -> u32 {
        round_ticks(self)
    }
}

impl Counts for U24F8 {
    fn eq13(self, n: i64) -> Self {
        // 2c/(4n + 1), in a wider type (2c overflows 24.8 from 2^23 counts),
        // rounded to the nearest 1/256; for n < 0 it is added:
        // −2c/(4n + 1) = 2c/(4|n| − 1).
        let divisor = if n > 0 {
            4 * n.unsigned_abs() + 1
        } else {
            4 * n.unsigned_abs() - 1
        };
        let twice = U56F8::from(self) * 2;
        let half_divisor = U56F8::from_bits(divisor / 2);
        let delta = (twice + half_divisor) / divisor;
        let wide = if n > 0 {
            U56F8::from(self) - delta
        } else {
            U56F8::from(self) + delta
        };
        // A deceleration rounding up past 2^24 counts saturates.
        U24F8::saturating_from_num(wide)
    }

    fn to_f64(self) -> f64 {
        self.to_num::<f64>()
    }

    fn delay_ticks(self) -> u32 {
        // Round half up, in the wide type so that 2^24 − ½ cannot overflow.
        let rounded = (U56F8::from(self) + U56F8::from_bits(0x80)).to_num::<u64>();
        u32::try_from(rounded).unwrap_or(u32::MAX).max(1)
    }
}

/// The per-step state machine of an Austin move, generic over the
/// arithmetic.
#[derive(Clone, Debug, PartialEq)]
struct Run<C: Counts> {
    plan: Plan,
    c0: C,
    slew_delay: C,
    /// Ramp delay `c` at ramp index `n`: while accelerating `n ≥ 0` is the
    /// index of the last value computed; while decelerating `n < 0`.
    c: C,
    n: i64,
    decelerating: bool,
    index: u32,
}

impl<C: Counts> Run<C> {
    fn new(plan: Plan, c0: C, slew_delay: C) -> Self {
        Self {
            plan,
            c0,
            slew_delay,
            c: c0,
            n: 0,
            decelerating: false,
            index: 0,
        }
    }

    /// Advances the accelerating ramp to index `k` (never backwards).
    fn ramp_to(&mut self, k: i64) {
        while self.n < k {
            self.n += 1;
            self.c = self.c.eq13(self.n);
        }
    }

    fn at_least_slew(&self, c: C) -> C {
        if c < self.slew_delay {
            self.slew_delay
        } else {
            c
        }
    }

    fn next_step(&mut self) -> Option<Step> {
        let steps = self.plan.steps;
        if self.index >= steps {
            return None;
        }
        let i = self.index;
        let ramp = self.plan.ramp_steps;
        let (phase, c) = if i < ramp {
            self.ramp_to(i64::from(i));
            (Phase::Accel, self.at_least_slew(self.c))
        } else if i < steps - ramp {
            // The top: f/v, or the ramp's next value at the peak of a short move.
            self.ramp_to(i64::from(ramp));
            (Phase::Slew, self.at_least_slew(self.c))
        } else {
            if !self.decelerating {
                // Eq. 14: from the ramp's value at n = r, with n_i = i − m.
                self.ramp_to(i64::from(ramp));
                self.n = i64::from(i) - i64::from(steps) - 1;
                self.decelerating = true;
            }
            self.n += 1;
            self.c = self.c.eq13(self.n);
            (Phase::Decel, self.at_least_slew(self.c))
        };
        self.index += 1;
        Some(Step {
            index: i,
            phase,
            binary_angle: None,
            velocity_steps_per_s: self.plan.clkfreq_hz / c.to_f64(),
            delay_ticks: c.delay_ticks(),
        })
    }

    fn remaining_steps(&self) -> u32 {
        self.plan.steps - self.index
    }
}

macro_rules! austin_profile {
    ($(#[$doc:meta])* $name:ident, $counts:ty, $from_f64:expr, $slew_from_f64:expr) => {
        $(#[$doc])*
        #[derive(Clone, Debug, PartialEq)]
        pub struct $name {
            run: Run<$counts>,
        }

        impl $name {
            /// Plans a move of `steps` steps from rest to rest at up to
            /// `speed_steps_per_s`, accelerating and decelerating at
            /// `accel_steps_per_s2`, with a `clkfreq`-Hz timer.
            ///
            /// # Errors
            ///
            /// [`PlanError::ZeroClock`], [`PlanError::ZeroSteps`],
            /// [`PlanError::BadSpeed`] and [`PlanError::BadAccel`] for inputs
            /// out of range (zero, negative or not finite);
            /// [`PlanError::SpeedTooHigh`] when a step at the top speed would
            /// be shorter than one tick; [`PlanError::DelayOverflow`] when
            /// the first delay (Eq. 15) or `clkfreq/speed` does not fit the
            /// profile's counter.
            pub fn new(
                clkfreq: u32,
                speed_steps_per_s: f64,
                accel_steps_per_s2: f64,
                steps: u32,
            ) -> Result<Self, PlanError> {
                let plan = Plan::new(clkfreq, speed_steps_per_s, accel_steps_per_s2, steps)?;
                let convert: fn(f64) -> Option<$counts> = $from_f64;
                let convert_slew: fn(f64) -> Option<$counts> = $slew_from_f64;
                let c0 = convert(plan.c0).ok_or(PlanError::DelayOverflow)?;
                let slew_delay = convert_slew(plan.slew_delay).ok_or(PlanError::DelayOverflow)?;
                Ok(Self {
                    run: Run::new(plan, c0, slew_delay),
                })
            }

            /// Steps accelerating (and, as many, decelerating).
            pub fn ramp_steps(&self) -> u32 {
                self.run.plan.ramp_steps
            }

            /// The first delay, Eq. 15, timer counts.
            pub fn first_delay_ticks(&self) -> f64 {
                self.run.c0.to_f64()
            }
        }

        impl Iterator for $name {
            type Item = Step;

            fn next(&mut self) -> Option<Step> {
                self.run.next_step()
            }

            fn size_hint(&self) -> (usize, Option<usize>) {
                let left = self.run.remaining_steps() as usize;
                (left, Some(left))
            }
        }

        impl ExactSizeIterator for $name {}
        impl core::iter::FusedIterator for $name {}

        impl Profile for $name {
            fn remaining_steps(&self) -> u32 {
                self.run.remaining_steps()
            }
        }
    };
}

austin_profile!(
    /// An Austin linear-ramp move computed in `f64` (see the module docs).
    AustinProfile,
    f64,
    Some,
    Some
);

austin_profile!(
    /// An Austin linear-ramp move computed in the paper's 24.8 fixed point
    /// ([`U24F8`]): delays up to 2^24 − 1 timer counts, the change of each
    /// step rounded to 1/256 count (see the module docs).
    AustinFixedProfile,
    U24F8,
    U24F8::checked_from_num,
    // Rounded up, so that no step runs faster than requested.
    |ticks| U24F8::checked_from_num(libm::ceil(ticks * 256.0) / 256.0)
);

#[cfg(test)]
mod tests {
    use crate::test_support::{any_linear_input, check_error_or_sane};
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use crate::trapezoid::{compare_edge_times, Trapezoid};
    use proptest::prelude::*;

    fn close(actual: f64, expected: f64, tolerance: f64) -> bool {
        (actual - expected).abs() <= tolerance
    }

    /// Austin's Table 1: for each n, the exact ratio c_n/c_{n−1} (Eq. 8), the
    /// approximation (Eq. 13) and its relative error, to 4 decimals.
    const TABLE_1: [(f64, f64, f64, f64); 8] = [
        (1.0, 0.4142, 0.6000, 0.4485),
        (2.0, 0.7673, 0.7778, 0.0136),
        (3.0, 0.8430, 0.8462, 0.0037),
        (4.0, 0.8810, 0.8824, 0.0015),
        (5.0, 0.9041, 0.9048, 0.0008),
        (10.0, 0.9511, 0.9512, 0.0001),
        (100.0, 0.9950, 0.9950, 0.0000),
        (1000.0, 0.9995, 0.9995, 0.0000),
    ];

    #[test]
    fn table_1_exact_and_approximate_ratios() {
        let c0 = 1_000.0;
        for (n, exact, approx, error) in TABLE_1 {
            let exact_ratio = exact_delay(c0, n) / exact_delay(c0, n - 1.0);
            let mut ramp = Ramp::new(c0, n - 1.0);
            let approx_ratio = ramp.next() / c0;
            assert_eq!(ramp.n(), n);
            let relative_error = (approx_ratio - exact_ratio) / exact_ratio;
            assert!(
                close(exact_ratio, exact, 5e-4),
                "n={n}: exact {exact_ratio}"
            );
            assert!(
                close(approx_ratio, approx, 5e-4),
                "n={n}: approx {approx_ratio}"
            );
            assert!(
                close(relative_error, error, 5e-4),
                "n={n}: error {relative_error}"
            );
        }
    }

    #[test]
    fn eq_8_exact_delays() {
        let c0 = c0_exact(1_000_000.0, 10_000.0);
        assert!(close(c0, 14_142.136, 1e-3));
        assert_eq!(exact_delay(c0, 0.0), c0);
        assert!(close(
            exact_delay(c0, 3.0),
            c0 * (2.0 - libm::sqrt(3.0)),
            1e-9
        ));
        // The sum of the first n exact delays is the time to n steps, c0·sqrt(n).
        let sum: f64 = (0..10_000).map(|n| exact_delay(c0, f64::from(n))).sum();
        assert!(close(sum, c0 * 100.0, 1e-6 * c0));
    }

    #[test]
    fn eq_15_factor_makes_the_ramp_converge_on_the_exact_delays() {
        // The product of Eq. 13's ratios goes as 0.7397/sqrt(n), the exact
        // delays as 0.5/sqrt(n): 0.5/0.7397 = 0.676.
        let mut ramp = Ramp::new(1.0, 0.0);
        for _ in 0..1_000_000 {
            ramp.next();
        }
        let asymptote = ramp.c() * libm::sqrt(1_000_000.0);
        assert!(close(asymptote, 0.7397, 5e-4), "{asymptote}");
        assert!(close(0.5 / asymptote, FIRST_DELAY_FACTOR, 5e-4));

        let (f, a) = (1_000_000.0, 10_000.0);
        let exact_c0 = c0_exact(f, a);
        assert!(close(c0_corrected(f, a) / exact_c0, 0.676, 1e-12));
        let mut corrected = Ramp::new(c0_corrected(f, a), 0.0);
        let mut uncorrected = Ramp::new(exact_c0, 0.0);
        for n in 1..=1_000 {
            let c = corrected.next();
            let u = uncorrected.next();
            let exact = exact_delay(exact_c0, f64::from(n));
            if n == 1 {
                // 0.676 × 0.6 = 0.4056 against 0.4142: 2% short, not 45% long.
                assert!(close(c / exact, 0.979, 5e-4), "{}", c / exact);
                assert!(close(u / exact, 1.4485, 5e-4));
            }
            if n >= 10 {
                assert!(close(c / exact, 1.0, 1e-3), "n={n}: {}", c / exact);
            }
            if n == 1_000 {
                // Without the factor the error never goes away.
                assert!(close(u / exact, 1.0 / 0.676, 1e-3));
            }
        }
    }

    #[test]
    fn eq_14_negative_n_runs_the_ramp_backwards() {
        let mut ramp = Ramp::new(c0_corrected(1_000_000.0, 10_000.0), 0.0);
        let up: Vec<f64> = (0..20).map(|_| ramp.next()).collect();
        // At n = 20; decelerate to rest in 20 steps: n from −20 to −1.
        let mut down = Ramp::new(ramp.c(), -21.0);
        for k in (0..20).rev() {
            let c = down.next();
            let expected = if k == 0 { ramp_c0() } else { up[k - 1] };
            assert!(close(c, expected, 1e-9 * expected), "k={k}");
        }
        assert_eq!(down.n(), -1.0);

        fn ramp_c0() -> f64 {
            c0_corrected(1_000_000.0, 10_000.0)
        }
    }

    #[test]
    fn eq_18_change_of_acceleration() {
        // The worked example: at n = 100 with ω′1 = 1000, switching to
        // ω′2 = 3000 gives n′ = 100.5·1000/3000 − 0.5 = 33.0.
        let mut ramp = Ramp::new(500.0, 100.0);
        ramp.change_accel(1_000.0, 3_000.0);
        assert!(close(ramp.n(), 33.0, 5e-4));
        assert_eq!(ramp.c(), 500.0);
        // And back.
        ramp.change_accel(3_000.0, 1_000.0);
        assert!(close(ramp.n(), 100.0, 5e-4));
        // Halving the acceleration at n = 10: n′ = 10.5·2 − 0.5 = 20.5.
        let mut half = Ramp::new(500.0, 10.0);
        half.change_accel(1_000.0, 500.0);
        assert!(close(half.n(), 20.5, 5e-4));
        // Decelerating at the same rate from n = 10: n′ = −11, and the next
        // delay is the one before (Eq. 14).
        let mut turn = Ramp::new(500.0, 10.0);
        turn.change_accel(1_000.0, -1_000.0);
        assert!(close(turn.n(), -11.0, 5e-4));
        assert!(close(turn.next(), 500.0 * 41.0 / 39.0, 1e-9));
        // A zero acceleration leaves the ramp alone.
        let mut hold = Ramp::new(500.0, 10.0);
        hold.change_accel(1_000.0, 0.0);
        assert_eq!(hold, Ramp::new(500.0, 10.0));
    }

    #[test]
    fn eq_18_keeps_the_speed_continuous() {
        // 200 steps at 1000 steps/s², then 300 at 3000: the delay must match
        // the exact ramp at 3000 steps/s² from the same speed.
        let (f, a1, a2) = (1_000_000.0, 1_000.0, 3_000.0);
        let mut ramp = Ramp::new(c0_corrected(f, a1), 0.0);
        for _ in 0..200 {
            ramp.next();
        }
        ramp.change_accel(a1, a2);
        let n_switch = ramp.n();
        assert!(close(n_switch, 200.5 / 3.0 - 0.5, 1e-9));
        for _ in 0..300 {
            ramp.next();
        }
        let exact = exact_delay(c0_exact(f, a2), n_switch + 300.0);
        assert!(close(ramp.c() / exact, 1.0, 1e-3), "{}", ramp.c() / exact);
    }

    #[test]
    fn eq_16_and_eq_19() {
        // 1000 steps/s at 10,000 steps/s²: 50 steps.
        assert!(close(steps_to_speed(1_000.0, 10_000.0), 50.0, 1e-12));
        // A 1000-step move, accelerating at 1000, decelerating at 3000:
        // decelerate from n = 750.
        assert!(close(
            short_move_decel_start(1_000.0, 1_000.0, 3_000.0),
            750.0,
            5e-4
        ));
        assert!(close(
            short_move_decel_start(1_001.0, 500.0, 500.0),
            500.5,
            5e-4
        ));
    }

    #[test]
    fn linear_factor_transition() {
        assert_eq!(linear_factor(5.0, 10.0, 20.0), 1.0);
        assert_eq!(linear_factor(15.0, 10.0, 20.0), 0.5);
        assert_eq!(linear_factor(25.0, 10.0, 20.0), 0.0);
        assert_eq!(linear_transition_gain(100.0, 100.0), 1.0);
        // A plain ramp gains sqrt(n2/n1); the taper gains less.
        let gain = linear_transition_gain(900.0, 1_100.0);
        assert!(gain > 1.0 && gain < libm::sqrt(1_100.0 / 900.0));

        // Taper 1000 ramp steps into the speed of n_top = 10,000: starts near
        // n_top − length/2.
        let (f, a, n_top, length) = (10_000_000.0, 1_000.0, 10_000.0, 1_000.0);
        let n1 = linear_transition_start(n_top, length).expect("short enough");
        assert!(close(n1, n_top - length / 2.0, 10.0), "{n1}");
        let n2 = n1 + length;
        // Discrete check: plain ramp up to n1, Eq. 22 up to n2.
        let mut ramp = Ramp::new(c0_corrected(f, a), 0.0);
        while ramp.n() + 1.0 <= n1 {
            ramp.next();
        }
        while ramp.n() < n2 {
            let factor = linear_factor(ramp.n() + 1.0, n1, n2);
            ramp.next_scaled(factor);
        }
        let target = exact_delay(c0_exact(f, a), n_top);
        assert!(close(ramp.c() / target, 1.0, 1e-3), "{}", ramp.c() / target);
        // Held from there on.
        let held = ramp.c();
        assert_eq!(
            ramp.next_scaled(linear_factor(ramp.n() + 1.0, n1, n2)),
            held
        );

        assert_eq!(linear_transition_start(10.0, 30.0), None);
        assert_eq!(linear_transition_start(0.0, 1.0), None);
        assert_eq!(linear_transition_start(10.0, f64::NAN), None);
    }

    #[test]
    fn profile_rejects_bad_inputs() {
        // Both arithmetics reject the same inputs with the same error.
        let error = |clkfreq: u32, speed: f64, accel: f64, steps: u32| {
            let float = AustinProfile::new(clkfreq, speed, accel, steps).err();
            let fixed = AustinFixedProfile::new(clkfreq, speed, accel, steps).err();
            assert_eq!(float, fixed);
            float
        };
        assert_eq!(error(0, 100.0, 100.0, 10), Some(PlanError::ZeroClock));
        assert_eq!(error(1_000, 100.0, 100.0, 0), Some(PlanError::ZeroSteps));
        assert_eq!(error(1_000, f64::NAN, 100.0, 10), Some(PlanError::BadSpeed));
        assert_eq!(error(1_000, -1.0, 100.0, 10), Some(PlanError::BadSpeed));
        assert_eq!(error(1_000, 100.0, 0.0, 10), Some(PlanError::BadAccel));
        assert_eq!(
            error(1_000, 100.0, f64::INFINITY, 10),
            Some(PlanError::BadAccel)
        );
        assert_eq!(
            error(1_000, 2_000.0, 100.0, 10),
            Some(PlanError::SpeedTooHigh {
                speed: 2_000,
                clkfreq: 1_000
            })
        );
        assert_eq!(
            error(200_000_000, 100.0, 1e-6, 10),
            Some(PlanError::DelayOverflow)
        );
        assert_eq!(
            error(200_000_000, 100.0, 5e-324, 10),
            Some(PlanError::DelayOverflow)
        );
        // 24.8 holds up to 2^24 − 1 counts: c0 = 0.676·200e6·sqrt(2/100) = 19.1M does not fit.
        assert_eq!(
            AustinFixedProfile::new(200_000_000, 1_000.0, 100.0, 10).err(),
            Some(PlanError::DelayOverflow)
        );
        assert!(AustinProfile::new(200_000_000, 1_000.0, 100.0, 10).is_ok());
    }

    #[test]
    fn profile_of_a_long_move() {
        // 1 MHz, 1000 steps/s, 10,000 steps/s²: 50 ramp steps, c0 = 9560.1.
        let profile = AustinProfile::new(1_000_000, 1_000.0, 10_000.0, 1_000).expect("valid");
        assert_eq!(profile.ramp_steps(), 50);
        assert!(close(profile.first_delay_ticks(), 9_560.1, 0.1));
        let steps: Vec<Step> = profile.collect();
        assert_eq!(steps.len(), 1_000);
        assert_eq!(steps[0].delay_ticks, 9_560);
        assert_eq!(steps[1].delay_ticks, 5_736); // 0.6·c0
        assert!(steps[..50].iter().all(|s| s.phase == Phase::Accel));
        assert!(steps[50..950]
            .iter()
            .all(|s| s.phase == Phase::Slew && s.delay_ticks == 1_000));
        assert!(steps[950..].iter().all(|s| s.phase == Phase::Decel));
        assert_eq!(steps[999].delay_ticks, 9_560);
        assert!(close(steps[500].velocity_steps_per_s, 1_000.0, 1e-9));
    }

    #[test]
    fn profile_of_short_moves() {
        let delays = |steps: u32| -> Vec<u32> {
            AustinProfile::new(1_000_000, 1_000.0, 10_000.0, steps)
                .expect("valid")
                .map(|s| s.delay_ticks)
                .collect()
        };
        // One step: the peak, at c0.
        assert_eq!(delays(1), [9_560]);
        assert_eq!(delays(2), [9_560, 9_560]);
        assert_eq!(delays(3), [9_560, 5_736, 9_560]);
        assert_eq!(delays(4), [9_560, 5_736, 5_736, 9_560]);
        let phases: Vec<Phase> = AustinProfile::new(1_000_000, 1_000.0, 10_000.0, 3)
            .expect("valid")
            .map(|s| s.phase)
            .collect();
        assert_eq!(phases, [Phase::Accel, Phase::Slew, Phase::Decel]);
    }

    #[test]
    fn fixed_point_follows_f64() {
        let float: Vec<Step> = AustinProfile::new(200_000_000, 20_000.0, 50_000.0, 20_000)
            .expect("valid")
            .collect();
        let fixed: Vec<Step> = AustinFixedProfile::new(200_000_000, 20_000.0, 50_000.0, 20_000)
            .expect("valid")
            .collect();
        assert_eq!(float.len(), fixed.len());
        for (f, x) in float.iter().zip(&fixed) {
            assert_eq!(f.phase, x.phase);
            assert!(f.delay_ticks.abs_diff(x.delay_ticks) <= 1, "{f:?} {x:?}");
        }
    }

    fn check_profile(
        steps: &[Step],
        count: u32,
        speed: f64,
        mirror_ticks: u32,
    ) -> Result<(), TestCaseError> {
        prop_assert_eq!(steps.len() as u32, count);
        for (i, s) in steps.iter().enumerate() {
            prop_assert_eq!(s.index, i as u32);
            prop_assert!(s.delay_ticks >= 1);
            prop_assert!(s.velocity_steps_per_s <= speed * (1.0 + 1e-9));
        }
        for w in steps.windows(2) {
            if w[1].phase == Phase::Accel {
                prop_assert!(w[1].delay_ticks <= w[0].delay_ticks);
            }
            if w[0].phase == Phase::Decel {
                prop_assert!(w[1].delay_ticks >= w[0].delay_ticks);
            }
        }
        let n = steps.len();
        for i in 0..n {
            let (a, b) = (steps[i].delay_ticks, steps[n - 1 - i].delay_ticks);
            prop_assert!(a.abs_diff(b) <= mirror_ticks, "step {}: {} vs {}", i, a, b);
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

        #[test]
        fn never_panics((clkfreq, speed, accel, steps) in any_linear_input()) {
            check_error_or_sane(AustinProfile::new(clkfreq, speed, accel, steps), steps)?;
            check_error_or_sane(AustinFixedProfile::new(clkfreq, speed, accel, steps), steps)?;
        }
    }
    proptest! {
        #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

        #[test]
        fn austin_properties(
            clkfreq in 1_000_000u32..=200_000_000,
            speed in 10.0f64..50_000.0,
            accel in 100.0f64..1_000_000.0,
            steps in 1u32..4_000,
        ) {
            let profile = AustinProfile::new(clkfreq, speed, accel, steps).expect("valid");
            let c0 = profile.first_delay_ticks();
            let float: Vec<Step> = profile.collect();
            check_profile(&float, steps, speed, 1)?;

            // Against the exact trapezoid.
            let reference = Trapezoid::new(clkfreq, speed, accel, steps).expect("valid");
            let slew = f64::from(clkfreq) / speed;
            let error = compare_edge_times(reference, float.iter().copied());
            let bound = ERROR_C0 * c0 / FIRST_DELAY_FACTOR + ERROR_SLEW * slew + f64::from(steps) * 0.5;
            prop_assert!((error.max_abs_ticks as f64) <= bound, "{:?} > {}", error, bound);

            match AustinFixedProfile::new(clkfreq, speed, accel, steps) {
                Ok(fixed) => {
                    let fixed: Vec<Step> = fixed.collect();
                    check_profile(&fixed, steps, speed, 2)?;
                    for (f, x) in float.iter().zip(&fixed) {
                        prop_assert_eq!(f.phase, x.phase);
                        prop_assert!(f.delay_ticks.abs_diff(x.delay_ticks) <= 2, "{:?} {:?}", f, x);
                    }
                }
                Err(e) => {
                    prop_assert_eq!(e, PlanError::DelayOverflow);
                    prop_assert!(c0 >= 16_777_216.0 || slew >= 16_777_216.0);
                }
            }
        }
    }

    /// Measured bound on |Austin − trapezoid| edge times: this many exact
    /// first delays (`f·sqrt(2/a)`), plus this many top-speed delays, plus
    /// half a tick of rounding per step.
    const ERROR_C0: f64 = 0.75;
    const ERROR_SLEW: f64 = 1.0;

    /// The cases `examples/ramp_errors.rs` measures (long moves too, past
    /// the property's 4,000 steps).
    const MEASURED: [(u32, f64, f64, u32); 5] = [
        (200_000_000, 20_000.0, 50_000.0, 20_000),
        (200_000_000, 5_000.0, 20_000.0, 3_000),
        (1_000_000, 1_000.0, 10_000.0, 1_000),
        (1_000_000, 1_000.0, 10_000.0, 31),
        (200_000_000, 50_000.0, 1_000_000.0, 100_000),
    ];

    #[test]
    fn the_measured_cases_lie_within_the_bound() {
        for (f, v, a, n) in MEASURED {
            let reference = Trapezoid::new(f, v, a, n).expect("valid");
            let c0 = c0_exact(f64::from(f), a);
            let bound = ERROR_C0 * c0 + ERROR_SLEW * f64::from(f) / v + f64::from(n) * 0.5;
            let float = reference.compare(AustinProfile::new(f, v, a, n).expect("valid"));
            assert!(
                (float.max_abs_ticks as f64) <= bound,
                "f={f} v={v} a={a} n={n}: f64 {float:?} > {bound}"
            );
            // The last edge is one of the edges compared.
            assert!(float.end_diff_ticks.unsigned_abs() <= float.max_abs_ticks);
            // The fixed-point ramp: within 2 ticks a step of the f64 one.
            let fixed = reference.compare(AustinFixedProfile::new(f, v, a, n).expect("fits"));
            assert!(
                (fixed.max_abs_ticks as f64) <= bound + 2.0 * f64::from(n),
                "f={f} v={v} a={a} n={n}: fixed {fixed:?} > {bound}"
            );
        }
    }
}

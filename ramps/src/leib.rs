//! The Leib ramp (Aryeh Eiderman, "Real Time Stepper Motor Linear Ramping
//! Just by Addition and Multiplication"): a linear ramp whose delays need
//! no division and no square root per step.
//!
//! # The equations
//!
//! With timer frequency `F` (Hz), acceleration `a` (steps/s²), base speed
//! `v0` (0 here: moves start from rest) and top speed `v` (steps/s), a delay
//! `p` is the timer count for the speed `F/p` after the step:
//!
//! ```text
//! p1 = F / sqrt(v0² + 2a)        first delay (the speed after one step)   first_delay
//! ps = F / v                     delay at the top speed
//! R  = a / F²
//! q  = m·p²,  p ← p·(1 + q + 1.5·q²)                                       next_delay
//! ```
//!
//! with `m = −R` accelerating, `0` at speed and `+R` decelerating, and `p`
//! kept within `[ps, p1]`. The update is the Taylor expansion, to second
//! order, of the exact `p ← p/sqrt(1 ∓ 2a·p²/F²)` (the speed changes by
//! `v² ± 2a` each step); its error is largest on the first steps (`q = ½` at
//! `p1`: 0.875 against 0.707) and falls quickly as the speed rises.
//!
//! # When to decelerate
//!
//! From the speed `u = F/p` of the last step, stopping takes
//! `j = u²/(2a) = 1/(2·R·p²)` steps (Eq. 4 of the paper with `v0 = 0`).
//! With `left` the steps still to make, this one included, step by step:
//!
//! - `left < j`: decelerate (`m = +R`), [`Phase::Decel`];
//! - `left ≥ j + 1` and below the top speed: accelerate (`m = −R`),
//!   [`Phase::Accel`];
//! - at the top speed: hold (`m = 0`), [`Phase::Slew`];
//! - otherwise (`j ≤ left < j + 1`, the peak of a short move): hold one
//!   step, labelled [`Phase::Decel`] as the first step of the way down.
//!
//! For exact speeds (`j` a whole number of steps) this is the mirror of the
//! acceleration: `p1, p2, …, p2, p1`. Because the approximation runs a little
//! slower than the exact ramp on the way up (so `j` lags the step count) and
//! a little faster on the way down, a Leib move is not exactly symmetric and
//! its last delay is somewhat shorter than `p1`; the step count is always
//! exact. Delays are rounded to the nearest tick; `velocity_steps_per_s` is
//! `F/p`.
//!
//! Note that Leib's delays stand for the speed *after* each step, where the
//! exact trapezoid ([`Trapezoid`](super::trapezoid::Trapezoid)) times the
//! whole step: the first Leib delay, `F/sqrt(2a)`, is half the exact first
//! step `F·sqrt(2/a)`, and a Leib ramp reaches its top speed earlier than
//! the exact one (the sum of `1/sqrt(2a·i)` falls short of `sqrt(2n/a)` by
//! about `1.03/sqrt(a)` seconds, before the approximation's own error).
//! Measured with [`compare_edge_times`](super::trapezoid::compare_edge_times),
//! a long move ends about 0.93·c0 (c0 = `F·sqrt(2/a)`, the exact first step)
//! early (200 MHz, 20,000 steps/s, 50,000 steps/s², 20,000 steps: 1,171,777
//! ticks, RMS 131,991); short moves reach 1.01·c0. The tests hold every edge
//! within `1.05·c0 + F/v + ½ tick per step`.

use super::trapezoid::{round_ticks, LinearMove, MAX_DELAY_TICKS};
use super::{Phase, PlanError, Profile, Step};

/// The first Leib delay, `F/sqrt(v0² + 2a)` timer counts: the speed after
/// one step from `base_speed` (steps/s) at `accel` (steps/s²), with a
/// `timer_hz` clock.
pub fn first_delay(timer_hz: f64, base_speed_steps_per_s: f64, accel_steps_per_s2: f64) -> f64 {
    timer_hz
        / libm::sqrt(base_speed_steps_per_s * base_speed_steps_per_s + 2.0 * accel_steps_per_s2)
}

/// One Leib update: `q = m·p²`, returns `p·(1 + q + 1.5·q²)` (`m = −R`
/// accelerating, `+R` decelerating, `R = a/F²`; no clamping).
pub fn next_delay(p: f64, m: f64) -> f64 {
    let q = m * p * p;
    p * (1.0 + q + 1.5 * q * q)
}

/// A Leib ramp move from rest to rest, one [`Step`] per motor step (see the
/// module docs for the deceleration rule).
#[derive(Clone, Debug, PartialEq)]
pub struct LeibProfile {
    clkfreq_hz: f64,
    steps: u32,
    /// `R = a/F²`.
    r: f64,
    /// `max(p1, ps)`: the longest delay.
    p_first: f64,
    /// `ps = F/v`: the shortest delay.
    p_slew: f64,
    /// The delay of the last step yielded (0 before the first).
    p: f64,
    index: u32,
}

impl LeibProfile {
    /// Plans a move of `steps` steps from rest to rest at up to
    /// `speed_steps_per_s`, accelerating and decelerating at
    /// `accel_steps_per_s2`, with a `clkfreq`-Hz timer.
    ///
    /// # Errors
    ///
    /// [`PlanError::ZeroClock`], [`PlanError::ZeroSteps`],
    /// [`PlanError::BadSpeed`] and [`PlanError::BadAccel`] for inputs out of
    /// range (zero, negative or not finite); [`PlanError::SpeedTooHigh`] when
    /// a step at the top speed would be shorter than one tick;
    /// [`PlanError::DelayOverflow`] when `p1` or `ps` does not fit a `u32` of
    /// ticks.
    pub fn new(
        clkfreq: u32,
        speed_steps_per_s: f64,
        accel_steps_per_s2: f64,
        steps: u32,
    ) -> Result<Self, PlanError> {
        let inputs = LinearMove::check(clkfreq, speed_steps_per_s, accel_steps_per_s2, steps)?;
        let f = inputs.clkfreq_hz;
        let p1 = first_delay(f, 0.0, accel_steps_per_s2);
        if p1.is_nan() || p1 > MAX_DELAY_TICKS {
            return Err(PlanError::DelayOverflow);
        }
        let p_slew = inputs.slew_delay_ticks;
        Ok(Self {
            clkfreq_hz: f,
            steps,
            r: accel_steps_per_s2 / (f * f),
            // If one step from rest already passes the top speed, every step is at it.
            p_first: p1.max(p_slew),
            p_slew,
            p: 0.0,
            index: 0,
        })
    }

    /// Steps needed to stop from the speed of the last step, `u²/(2a)`
    /// (0 before the first step).
    pub fn steps_to_stop(&self) -> f64 {
        if self.p == 0.0 {
            0.0
        } else {
            1.0 / (2.0 * self.r * self.p * self.p)
        }
    }

    fn clamp(&self, p: f64) -> f64 {
        p.clamp(self.p_slew, self.p_first)
    }
}

impl Iterator for LeibProfile {
    type Item = Step;

    fn next(&mut self) -> Option<Step> {
        if self.index >= self.steps {
            return None;
        }
        let left = f64::from(self.steps - self.index);
        let to_stop = self.steps_to_stop();
        let at_speed = self.p != 0.0 && self.p <= self.p_slew;
        let (phase, p) = if self.p == 0.0 {
            // The first step from rest: p1.
            let phase = if self.p_first > self.p_slew {
                Phase::Accel
            } else {
                Phase::Slew
            };
            (phase, self.p_first)
        } else if left < to_stop {
            (Phase::Decel, self.clamp(next_delay(self.p, self.r)))
        } else if at_speed {
            (Phase::Slew, self.p)
        } else if left >= to_stop + 1.0 {
            (Phase::Accel, self.clamp(next_delay(self.p, -self.r)))
        } else {
            // The peak of a short move: hold it for the first step down.
            (Phase::Decel, self.p)
        };
        let step = Step {
            index: self.index,
            phase,
            binary_angle: None,
            velocity_steps_per_s: self.clkfreq_hz / p,
            delay_ticks: round_ticks(p),
        };
        self.p = p;
        self.index += 1;
        Some(step)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.remaining_steps() as usize;
        (left, Some(left))
    }
}

impl ExactSizeIterator for LeibProfile {}
impl core::iter::FusedIterator for LeibProfile {}

impl Profile for LeibProfile {
    fn remaining_steps(&self) -> u32 {
        self.steps - self.index
    }
}

#[cfg(test)]
mod tests {
    use crate::test_support::{any_linear_input, check_error_or_sane};
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use crate::trapezoid::{compare_edge_times, Trapezoid};
    use proptest::prelude::*;

    fn delays(clkfreq: u32, speed: f64, accel: f64, steps: u32) -> Vec<Step> {
        LeibProfile::new(clkfreq, speed, accel, steps)
            .expect("valid move")
            .collect()
    }

    #[test]
    fn rejects_bad_inputs() {
        assert_eq!(LeibProfile::new(0, 1.0, 1.0, 1), Err(PlanError::ZeroClock));
        assert_eq!(
            LeibProfile::new(1_000, 1.0, 1.0, 0),
            Err(PlanError::ZeroSteps)
        );
        assert_eq!(
            LeibProfile::new(1_000, 0.0, 1.0, 1),
            Err(PlanError::BadSpeed)
        );
        assert_eq!(
            LeibProfile::new(1_000, f64::NEG_INFINITY, 1.0, 1),
            Err(PlanError::BadSpeed)
        );
        assert_eq!(
            LeibProfile::new(1_000, 1.0, f64::NAN, 1),
            Err(PlanError::BadAccel)
        );
        assert_eq!(
            LeibProfile::new(1_000, 1e12, 1.0, 1),
            Err(PlanError::SpeedTooHigh {
                speed: u32::MAX,
                clkfreq: 1_000
            })
        );
        assert_eq!(
            LeibProfile::new(200_000_000, 100.0, 1e-6, 5),
            Err(PlanError::DelayOverflow)
        );
    }

    #[test]
    fn first_delay_and_update() {
        // F = 1 MHz, a = 5000: p1 = 1e6/sqrt(10,000) = 10,000.
        assert_eq!(first_delay(1e6, 0.0, 5_000.0), 10_000.0);
        assert_eq!(
            first_delay(1e6, 300.0, 5_000.0),
            1e6 / libm::sqrt(100_000.0)
        );
        // q = −R·p1² = −½: 1 − ½ + 3/8.
        let r = 5_000.0 / 1e12;
        assert!((next_delay(10_000.0, -r) - 8_750.0).abs() < 1e-9);
        assert_eq!(next_delay(10_000.0, 0.0), 10_000.0);
        // Against the exact p/sqrt(1 + 2a·p²/F²) where q is small.
        let p = 1_000.0;
        let exact = p / libm::sqrt(1.0 + 2.0 * r * p * p);
        assert!((next_delay(p, -r) / exact - 1.0).abs() < 1e-5);
    }

    #[test]
    fn long_move() {
        // F = 1 MHz, v = 1000, a = 5000: ps = 1000, p1 = 10,000, 100 ramp steps.
        let steps = delays(1_000_000, 1_000.0, 5_000.0, 1_000);
        assert_eq!(steps.len(), 1_000);
        assert_eq!(steps[0].delay_ticks, 10_000);
        assert_eq!(steps[1].delay_ticks, 8_750);
        assert_eq!(steps[500].delay_ticks, 1_000);
        assert_eq!(steps[500].phase, Phase::Slew);
        let accel = steps.iter().filter(|s| s.phase == Phase::Accel).count();
        let decel = steps.iter().filter(|s| s.phase == Phase::Decel).count();
        // The approximation lags on the way up: a few more than 100 steps.
        assert!((100..=110).contains(&accel), "{accel}");
        // Stopping from 1000 steps/s takes v²/(2a) = 100 steps; the
        // deceleration starts when fewer than that are left.
        assert_eq!(decel, 99);
        assert_eq!(steps[900].phase, Phase::Slew);
        assert_eq!(steps[901].phase, Phase::Decel);
        let last = steps[999].delay_ticks;
        assert!((5_000..=10_000).contains(&last), "{last}");
    }

    #[test]
    fn short_moves() {
        let ticks = |n: u32| -> Vec<(Phase, u32)> {
            delays(1_000_000, 1_000.0, 5_000.0, n)
                .iter()
                .map(|s| (s.phase, s.delay_ticks))
                .collect()
        };
        assert_eq!(ticks(1), [(Phase::Accel, 10_000)]);
        assert_eq!(ticks(2), [(Phase::Accel, 10_000), (Phase::Decel, 10_000)]);
        assert_eq!(
            ticks(3),
            [
                (Phase::Accel, 10_000),
                (Phase::Accel, 8_750),
                (Phase::Decel, 10_000)
            ]
        );
        // Slow enough that p1 < ps: every step at the top speed.
        let slow = delays(1_000_000, 10.0, 5_000.0, 3);
        assert!(slow
            .iter()
            .all(|s| s.phase == Phase::Slew && s.delay_ticks == 100_000));
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

        #[test]
        fn never_panics((clkfreq, speed, accel, steps) in any_linear_input()) {
            check_error_or_sane(LeibProfile::new(clkfreq, speed, accel, steps), steps)?;
        }
    }
    proptest! {
        #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

        #[test]
        fn leib_properties(
            clkfreq in 1_000_000u32..=200_000_000,
            speed in 10.0f64..50_000.0,
            accel in 100.0f64..1_000_000.0,
            steps in 1u32..4_000,
        ) {
            let leib: Vec<Step> = delays(clkfreq, speed, accel, steps);
            prop_assert_eq!(leib.len() as u32, steps);
            let p1 = first_delay(f64::from(clkfreq), 0.0, accel);
            let slew = f64::from(clkfreq) / speed;
            for (i, s) in leib.iter().enumerate() {
                prop_assert_eq!(s.index, i as u32);
                prop_assert!(s.delay_ticks >= 1);
                prop_assert!(s.velocity_steps_per_s <= speed * (1.0 + 1e-9));
                prop_assert!(f64::from(s.delay_ticks) <= libm::round(p1.max(slew)));
            }
            let mut seen_decel = false;
            for w in leib.windows(2) {
                if w[1].phase == Phase::Accel {
                    prop_assert!(w[1].delay_ticks <= w[0].delay_ticks);
                }
                if w[0].phase == Phase::Decel {
                    prop_assert!(w[1].delay_ticks >= w[0].delay_ticks);
                }
                // Accelerate, hold, decelerate: never back up once slowing.
                seen_decel |= w[0].phase == Phase::Decel;
                prop_assert!(!seen_decel || w[1].phase == Phase::Decel);
            }
            // Against the exact trapezoid (the bound measured; see ERROR_C0).
            let reference = Trapezoid::new(clkfreq, speed, accel, steps).expect("valid");
            let error = compare_edge_times(reference, leib.iter().copied());
            let c0 = f64::from(clkfreq) * libm::sqrt(2.0 / accel);
            let bound = ERROR_C0 * c0 + ERROR_SLEW * slew + 0.5 * f64::from(steps);
            prop_assert!((error.max_abs_ticks as f64) <= bound, "{:?} > {}", error, bound);
        }
    }

    /// Measured bound on |Leib − trapezoid| edge times: this many exact
    /// first delays (`F·sqrt(2/a)`), plus this many top-speed delays, plus
    /// half a tick of rounding per step.
    const ERROR_C0: f64 = 1.05;
    const ERROR_SLEW: f64 = 1.0;

    /// The cases `examples/ramp_errors.rs` measures (long moves too, past
    /// the property's 4,000 steps).
    #[test]
    fn the_measured_cases_lie_within_the_bound() {
        for (f, v, a, n) in [
            (200_000_000u32, 20_000.0, 50_000.0, 20_000u32),
            (200_000_000, 5_000.0, 20_000.0, 3_000),
            (1_000_000, 1_000.0, 10_000.0, 1_000),
            (1_000_000, 1_000.0, 10_000.0, 31),
            (200_000_000, 50_000.0, 1_000_000.0, 100_000),
        ] {
            let reference = Trapezoid::new(f, v, a, n).expect("valid");
            let c0 = f64::from(f) * libm::sqrt(2.0 / a);
            let bound = ERROR_C0 * c0 + ERROR_SLEW * f64::from(f) / v + 0.5 * f64::from(n);
            let error = reference.compare(LeibProfile::new(f, v, a, n).expect("valid"));
            assert!(
                (error.max_abs_ticks as f64) <= bound,
                "f={f} v={v} a={a} n={n}: {error:?} > {bound}"
            );
        }
    }
}

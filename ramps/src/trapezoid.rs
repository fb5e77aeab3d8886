//! The exact trapezoid: a constant-acceleration move from its closed form,
//! the reference the approximate ramps ([`austin`](super::austin),
//! [`leib`](super::leib)) are measured against.
//!
//! # Model
//!
//! A move of `N` steps is a motion from position 0 to position `N` (in
//! steps), from rest to rest, with acceleration `a` (steps/s²) up to the
//! speed `v` (steps/s), then at `v`, then decelerating with `a`. Step `n`'s
//! rising edge is the moment the motion passes position `n` (`n = 0 … N−1`;
//! edge 0 at `t = 0`), and the move ends at `t_N`, when it stops at `N`.
//!
//! Ramp length (Austin's Eq. 16 in steps), capped for a short move:
//!
//! ```text
//! d  = min(v² / (2a), N / 2)      steps spent accelerating (and decelerating)
//! vp = sqrt(2a·d)                 peak speed: v, or sqrt(a·N) for a triangle
//! Ta = vp / a                     ramp time
//! T  = 2·Ta + (N − 2d) / vp       time of the whole move
//! ```
//!
//! Edge times (the closed form):
//!
//! ```text
//! t(p) = sqrt(2p / a)                   p ≤ d            accelerating
//! t(p) = Ta + (p − d) / vp              d ≤ p ≤ N − d    at speed
//! t(p) = T − sqrt(2(N − p) / a)         p ≥ N − d        decelerating (mirror)
//! ```
//!
//! # Per step
//!
//! - `delay_ticks` of step `n` = `round(t(n+1)·f) − round(t(n)·f)`: each edge
//!   is rounded to the nearest tick on its own, so the cumulative time never
//!   drifts (every edge is within half a tick of the exact time, while the
//!   single delays may differ from the exact interval by up to one tick:
//!   neighbouring delays of a constant speed alternate, e.g. 10,000 and
//!   10,001 ticks for 10,000.4). Exact while the move lasts less than 2^53
//!   ticks.
//! - `velocity_steps_per_s` = `1 / (t(n+1) − t(n))`, the mean speed over the
//!   step, never above `v`.
//! - phase by the step's midpoint `n + ½`: [`Phase::Accel`] below `d`,
//!   [`Phase::Decel`] above `N − d`, [`Phase::Slew`] in between (including
//!   the middle step of an odd triangle, the peak).
//!
//! [`compare_edge_times`] measures another profile's edge times against this
//! one (maximum and RMS difference in ticks).

use super::{Phase, PlanError, Profile, Step};

/// The inputs every linear-ramp profile of this crate takes, checked once:
/// clock, top speed, acceleration, steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LinearMove {
    /// The clock (timer) frequency, Hz, as `f64`.
    pub clkfreq_hz: f64,
    /// The top speed, steps/s.
    pub speed_steps_per_s: f64,
    /// The acceleration (and deceleration), steps/s².
    pub accel_steps_per_s2: f64,
    /// Steps in the move, ≥ 1.
    pub steps: u32,
    /// `clkfreq / speed`: the delay at the top speed, ticks (≥ 1).
    pub slew_delay_ticks: f64,
}

impl LinearMove {
    /// Checks the inputs in the order: clock, steps, speed, acceleration,
    /// speed against the clock (a step at the top speed must last at least
    /// one tick).
    pub(crate) fn check(
        clkfreq: u32,
        speed_steps_per_s: f64,
        accel_steps_per_s2: f64,
        steps: u32,
    ) -> Result<Self, PlanError> {
        if clkfreq == 0 {
            return Err(PlanError::ZeroClock);
        }
        if steps == 0 {
            return Err(PlanError::ZeroSteps);
        }
        if !(speed_steps_per_s.is_finite() && speed_steps_per_s > 0.0) {
            return Err(PlanError::BadSpeed);
        }
        if !(accel_steps_per_s2.is_finite() && accel_steps_per_s2 > 0.0) {
            return Err(PlanError::BadAccel);
        }
        let clkfreq_hz = f64::from(clkfreq);
        let slew_delay_ticks = clkfreq_hz / speed_steps_per_s;
        if slew_delay_ticks < 1.0 {
            return Err(PlanError::SpeedTooHigh {
                // `as` saturates: a speed beyond u32 reports u32::MAX.
                speed: speed_steps_per_s as u32,
                clkfreq,
            });
        }
        if slew_delay_ticks > MAX_DELAY_TICKS {
            return Err(PlanError::DelayOverflow);
        }
        Ok(Self {
            clkfreq_hz,
            speed_steps_per_s,
            accel_steps_per_s2,
            steps,
            slew_delay_ticks,
        })
    }

    /// Austin's Eq. 16 in steps, `v² / (2a)`: the steps a ramp from rest
    /// needs to reach the top speed (not capped by the move's length).
    pub(crate) fn ramp_steps_to_speed(&self) -> f64 {
        self.speed_steps_per_s * self.speed_steps_per_s / (2.0 * self.accel_steps_per_s2)
    }

    /// The number of whole steps of each ramp (acceleration, and by symmetry
    /// deceleration): the steps whose midpoint `k + ½` lies below
    /// `min(v²/(2a), N/2)`, as in the exact trapezoid's phases. For an odd
    /// short move this leaves the middle step as the peak.
    pub(crate) fn ramp_steps(&self) -> u32 {
        let limit = self.ramp_steps_to_speed().min(f64::from(self.steps) / 2.0);
        // Count of k ≥ 0 with k + ½ < limit; `as` saturates (and maps NaN to 0).
        libm::ceil(limit - 0.5).max(0.0) as u32
    }
}

/// The largest delay a `u32` of ticks holds, less one tick of headroom for
/// rounding.
pub(crate) const MAX_DELAY_TICKS: f64 = 4_294_967_294.0;

/// Rounds a delay in ticks to the integer count a timer is loaded with:
/// nearest, at least 1, saturating at `u32::MAX`.
pub(crate) fn round_ticks(delay_ticks: f64) -> u32 {
    // `as` saturates and maps NaN to 0, hence the max(1).
    (libm::round(delay_ticks) as u32).max(1)
}

/// The exact constant-acceleration trapezoid (triangle for a short move),
/// one [`Step`] per motor step, delays rounded so that edge times stay exact.
#[derive(Clone, Debug, PartialEq)]
pub struct Trapezoid {
    clkfreq_hz: f64,
    accel_steps_per_s2: f64,
    steps: u32,
    /// `d`: steps (continuous) spent accelerating, = steps decelerating.
    ramp_steps: f64,
    /// `vp`: the top speed actually reached, steps/s.
    peak_speed_steps_per_s: f64,
    /// `Ta = vp / a`, s.
    ramp_time_s: f64,
    /// `T`, s.
    total_time_s: f64,
    /// The next step to yield.
    index: u32,
    /// `round(t(index)·f)`: the rising edge of the next step, ticks.
    edge_ticks: u64,
}

impl Trapezoid {
    /// Plans a move of `steps` steps at up to `speed_steps_per_s` with
    /// acceleration (and deceleration) `accel_steps_per_s2`, on a
    /// `clkfreq`-Hz clock.
    ///
    /// # Errors
    ///
    /// [`PlanError::ZeroClock`], [`PlanError::ZeroSteps`],
    /// [`PlanError::BadSpeed`] and [`PlanError::BadAccel`] for inputs out of
    /// range (zero, negative or not finite); [`PlanError::SpeedTooHigh`] when
    /// a step at the top speed would be shorter than one tick;
    /// [`PlanError::DelayOverflow`] when the longest step (the first) would
    /// not fit a `u32` of ticks.
    pub fn new(
        clkfreq: u32,
        speed_steps_per_s: f64,
        accel_steps_per_s2: f64,
        steps: u32,
    ) -> Result<Self, PlanError> {
        let inputs = LinearMove::check(clkfreq, speed_steps_per_s, accel_steps_per_s2, steps)?;
        let a = accel_steps_per_s2;
        let n = f64::from(steps);
        let (ramp_steps, peak_speed_steps_per_s) = if inputs.ramp_steps_to_speed() < n / 2.0 {
            (inputs.ramp_steps_to_speed(), speed_steps_per_s)
        } else {
            // A triangle: vp = sqrt(2a·N/2).
            (n / 2.0, libm::sqrt(a * n))
        };
        let ramp_time_s = peak_speed_steps_per_s / a;
        let total_time_s = 2.0 * ramp_time_s + (n - 2.0 * ramp_steps) / peak_speed_steps_per_s;
        let trapezoid = Self {
            clkfreq_hz: inputs.clkfreq_hz,
            accel_steps_per_s2: a,
            steps,
            ramp_steps,
            peak_speed_steps_per_s,
            ramp_time_s,
            total_time_s,
            index: 0,
            edge_ticks: 0,
        };
        // The first step (and its mirror, the last) is the longest.
        if trapezoid.edge_time_s(1) * trapezoid.clkfreq_hz > MAX_DELAY_TICKS {
            return Err(PlanError::DelayOverflow);
        }
        Ok(trapezoid)
    }

    /// The exact time of step `n`'s rising edge, seconds from the first
    /// (`n = steps` gives the end of the move; larger `n` are clamped to it).
    pub fn edge_time_s(&self, n: u32) -> f64 {
        let a = self.accel_steps_per_s2;
        let end = f64::from(self.steps);
        let p = f64::from(n.min(self.steps));
        let d = self.ramp_steps;
        if p <= d {
            libm::sqrt(2.0 * p / a)
        } else if p <= end - d {
            self.ramp_time_s + (p - d) / self.peak_speed_steps_per_s
        } else {
            self.total_time_s - libm::sqrt(2.0 * (end - p) / a)
        }
    }

    /// Time of the whole move, seconds (first rising edge to standstill).
    pub fn total_time_s(&self) -> f64 {
        self.total_time_s
    }

    /// Steps (continuous) spent accelerating; as many are spent decelerating.
    pub fn ramp_steps(&self) -> f64 {
        self.ramp_steps
    }

    /// The top speed the move reaches: the requested speed, or less for a
    /// short move (a triangle).
    pub fn peak_speed_steps_per_s(&self) -> f64 {
        self.peak_speed_steps_per_s
    }

    /// Measures `other`'s edge times against this move's, from its first
    /// step (whatever this value has already yielded): see
    /// [`compare_edge_times`].
    pub fn compare<I: IntoIterator<Item = Step>>(&self, other: I) -> EdgeTimingError {
        let fresh = Self {
            index: 0,
            edge_ticks: 0,
            ..self.clone()
        };
        compare_edge_times(fresh, other)
    }

    fn edge_ticks_of(&self, n: u32) -> u64 {
        // `as` saturates; exact below 2^53 ticks.
        libm::round(self.edge_time_s(n) * self.clkfreq_hz) as u64
    }
}

impl Iterator for Trapezoid {
    type Item = Step;

    fn next(&mut self) -> Option<Step> {
        if self.index >= self.steps {
            return None;
        }
        let n = self.index;
        let next_edge_ticks = self.edge_ticks_of(n + 1);
        let delay = next_edge_ticks.saturating_sub(self.edge_ticks);
        let delay_ticks = u32::try_from(delay).unwrap_or(u32::MAX).max(1);
        let interval_s = self.edge_time_s(n + 1) - self.edge_time_s(n);
        let midpoint = f64::from(n) + 0.5;
        let phase = if midpoint < self.ramp_steps {
            Phase::Accel
        } else if midpoint > f64::from(self.steps) - self.ramp_steps {
            Phase::Decel
        } else {
            Phase::Slew
        };
        self.index += 1;
        self.edge_ticks = next_edge_ticks;
        Some(Step {
            index: n,
            phase,
            binary_angle: None,
            velocity_steps_per_s: 1.0 / interval_s,
            delay_ticks,
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.remaining_steps() as usize;
        (left, Some(left))
    }
}

impl ExactSizeIterator for Trapezoid {}
impl core::iter::FusedIterator for Trapezoid {}

impl Profile for Trapezoid {
    fn remaining_steps(&self) -> u32 {
        self.steps - self.index
    }
}

/// How far one step sequence's edge times are from a reference's, in ticks.
///
/// Edge `k` (for `k = 1 …`) is the sum of the first `k` delays: the rising
/// edge of step `k`, and for the last `k` the end of the move. Edge 0 is at
/// 0 in both and not counted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeTimingError {
    /// Edges compared: the shorter sequence's length.
    pub edges: u32,
    /// The largest |other − reference| over the compared edges, ticks.
    pub max_abs_ticks: u64,
    /// The edge (1-based, as above) where that largest difference is.
    pub worst_edge: u32,
    /// Root mean square of the differences, ticks.
    pub rms_ticks: f64,
    /// `other − reference` at the last compared edge (for sequences of the
    /// same length, the difference of the two moves' durations), ticks.
    pub end_diff_ticks: i64,
}

/// Compares `other`'s edge times with `reference`'s (cumulative delays, both
/// from 0), over as many steps as the shorter of the two has.
pub fn compare_edge_times<R, O>(reference: R, other: O) -> EdgeTimingError
where
    R: IntoIterator<Item = Step>,
    O: IntoIterator<Item = Step>,
{
    let mut reference_ticks: u64 = 0;
    let mut other_ticks: u64 = 0;
    let mut result = EdgeTimingError {
        edges: 0,
        max_abs_ticks: 0,
        worst_edge: 0,
        rms_ticks: 0.0,
        end_diff_ticks: 0,
    };
    let mut sum_squares = 0.0;
    for (reference_step, other_step) in reference.into_iter().zip(other) {
        reference_ticks = reference_ticks.saturating_add(u64::from(reference_step.delay_ticks));
        other_ticks = other_ticks.saturating_add(u64::from(other_step.delay_ticks));
        result.edges = result.edges.saturating_add(1);
        let diff = i128::from(other_ticks) - i128::from(reference_ticks);
        let abs = u64::try_from(diff.unsigned_abs()).unwrap_or(u64::MAX);
        if abs > result.max_abs_ticks {
            result.max_abs_ticks = abs;
            result.worst_edge = result.edges;
        }
        sum_squares += (diff as f64) * (diff as f64);
        result.end_diff_ticks =
            i64::try_from(diff).unwrap_or(if diff < 0 { i64::MIN } else { i64::MAX });
    }
    if result.edges > 0 {
        result.rms_ticks = libm::sqrt(sum_squares / f64::from(result.edges));
    }
    result
}

#[cfg(test)]
mod tests {
    use crate::test_support::{any_linear_input, check_error_or_sane};
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use proptest::prelude::*;

    fn run(clkfreq: u32, speed: f64, accel: f64, steps: u32) -> Vec<Step> {
        Trapezoid::new(clkfreq, speed, accel, steps)
            .expect("valid move")
            .collect()
    }

    #[test]
    fn rejects_bad_inputs() {
        assert_eq!(
            Trapezoid::new(0, 100.0, 100.0, 10),
            Err(PlanError::ZeroClock)
        );
        assert_eq!(
            Trapezoid::new(1_000, 100.0, 100.0, 0),
            Err(PlanError::ZeroSteps)
        );
        for speed in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(
                Trapezoid::new(1_000, speed, 100.0, 10),
                Err(PlanError::BadSpeed)
            );
        }
        for accel in [0.0, -5.0, f64::NAN, f64::INFINITY] {
            assert_eq!(
                Trapezoid::new(1_000, 100.0, accel, 10),
                Err(PlanError::BadAccel)
            );
        }
        assert_eq!(
            Trapezoid::new(1_000, 1_500.0, 100.0, 10),
            Err(PlanError::SpeedTooHigh {
                speed: 1_500,
                clkfreq: 1_000
            })
        );
        // 200 MHz, 1e-6 steps/s²: the first step takes 1414 s.
        assert_eq!(
            Trapezoid::new(200_000_000, 100.0, 1e-6, 10),
            Err(PlanError::DelayOverflow)
        );
        // Slew delay alone too long: 0.01 steps/s at 200 MHz.
        assert_eq!(
            Trapezoid::new(200_000_000, 0.01, 1e6, 10),
            Err(PlanError::DelayOverflow)
        );
    }

    #[test]
    fn closed_form_edges_of_a_trapezoid() {
        // 1 MHz, v = 1000 steps/s, a = 10,000 steps/s²: d = 50 steps, Ta = 0.1 s.
        let t = Trapezoid::new(1_000_000, 1_000.0, 10_000.0, 1_000).expect("valid");
        assert!((t.ramp_steps() - 50.0).abs() < 1e-12);
        assert!((t.peak_speed_steps_per_s() - 1_000.0).abs() < 1e-9);
        assert!((t.total_time_s() - 1.1).abs() < 1e-12); // 0.2 s ramps + 900 steps / 1000
        assert!((t.edge_time_s(2) - libm::sqrt(4.0 / 10_000.0)).abs() < 1e-15);
        assert!((t.edge_time_s(500) - 0.55).abs() < 1e-12);
        assert!((t.edge_time_s(1_000) - 1.1).abs() < 1e-12);
        let steps: Vec<Step> = t.collect();
        assert_eq!(steps.len(), 1_000);
        let total: u64 = steps.iter().map(|s| u64::from(s.delay_ticks)).sum();
        assert_eq!(total, 1_100_000);
        // First step: sqrt(2/a) = 14,142.1 ticks; slew steps 1000 ticks.
        assert_eq!(steps[0].delay_ticks, 14_142);
        assert_eq!(steps[500].delay_ticks, 1_000);
        assert_eq!(steps[500].phase, Phase::Slew);
        assert_eq!(steps[49].phase, Phase::Accel);
        assert_eq!(steps[50].phase, Phase::Slew);
        assert_eq!(steps[949].phase, Phase::Slew);
        assert_eq!(steps[950].phase, Phase::Decel);
    }

    #[test]
    fn short_moves_are_triangles() {
        // 9 steps, d would be 50: a triangle with its peak at 4.5.
        let t = Trapezoid::new(1_000_000, 1_000.0, 10_000.0, 9).expect("valid");
        assert!((t.ramp_steps() - 4.5).abs() < 1e-12);
        assert!((t.peak_speed_steps_per_s() - libm::sqrt(90_000.0)).abs() < 1e-9);
        assert!((t.total_time_s() - 2.0 * libm::sqrt(9.0 / 10_000.0)).abs() < 1e-12);
        let phases: Vec<Phase> = t.map(|s| s.phase).collect();
        assert_eq!(&phases[..4], &[Phase::Accel; 4]);
        assert_eq!(phases[4], Phase::Slew); // the peak step
        assert_eq!(&phases[5..], &[Phase::Decel; 4]);
        // A single step: the whole triangle, 2/sqrt(a) = 20,000 ticks.
        let one = run(1_000_000, 1_000.0, 10_000.0, 1);
        assert_eq!(one.len(), 1);
        assert_eq!(one[0].delay_ticks, 20_000);
    }

    #[test]
    fn comparing_a_profile_with_itself_gives_zero() {
        let t = Trapezoid::new(200_000_000, 5_000.0, 20_000.0, 3_000).expect("valid");
        let same = t.compare(t.clone());
        assert_eq!(same.edges, 3_000);
        assert_eq!(same.max_abs_ticks, 0);
        assert_eq!(same.rms_ticks, 0.0);
        // One tick more on every step: the error grows to the step count.
        let slower = t.clone().map(|s| Step {
            delay_ticks: s.delay_ticks + 1,
            ..s
        });
        let e = t.compare(slower);
        assert_eq!(e.max_abs_ticks, 3_000);
        assert_eq!(e.worst_edge, 3_000);
        assert_eq!(e.end_diff_ticks, 3_000);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

        #[test]
        fn never_panics((clkfreq, speed, accel, steps) in any_linear_input()) {
            check_error_or_sane(Trapezoid::new(clkfreq, speed, accel, steps), steps)?;
        }
    }
    proptest! {
        #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

        #[test]
        fn trapezoid_properties(
            clkfreq in 1_000_000u32..=200_000_000,
            speed in 10.0f64..50_000.0,
            accel in 100.0f64..1_000_000.0,
            steps in 1u32..4_000,
        ) {
            let t = Trapezoid::new(clkfreq, speed, accel, steps).expect("valid");
            let total_s = t.total_time_s();
            let ticks: Vec<Step> = t.collect();
            prop_assert_eq!(ticks.len() as u32, steps);
            let mut edge: u64 = 0;
            for (i, s) in ticks.iter().enumerate() {
                prop_assert_eq!(s.index, i as u32);
                prop_assert!(s.delay_ticks >= 1);
                prop_assert!(s.velocity_steps_per_s <= speed * (1.0 + 1e-9));
                edge += u64::from(s.delay_ticks);
            }
            // The end of the move is the exact time, rounded once.
            prop_assert_eq!(edge, libm::round(total_s * f64::from(clkfreq)) as u64);
            // Non-increasing while accelerating, non-decreasing while
            // decelerating, to within the one tick of edge rounding.
            for w in ticks.windows(2) {
                if w[1].phase == Phase::Accel {
                    prop_assert!(w[1].delay_ticks <= w[0].delay_ticks + 1);
                }
                if w[0].phase == Phase::Decel {
                    prop_assert!(w[1].delay_ticks + 1 >= w[0].delay_ticks);
                }
            }
            // Mirror symmetry, to within one tick.
            let n = ticks.len();
            for i in 0..n {
                let (a, b) = (ticks[i].delay_ticks, ticks[n - 1 - i].delay_ticks);
                prop_assert!(a.abs_diff(b) <= 1, "step {}: {} vs {}", i, a, b);
                let mirror = match ticks[i].phase {
                    Phase::Accel => Phase::Decel,
                    Phase::Decel => Phase::Accel,
                    Phase::Slew => Phase::Slew,
                };
                prop_assert_eq!(ticks[n - 1 - i].phase, mirror);
            }
        }
    }
}

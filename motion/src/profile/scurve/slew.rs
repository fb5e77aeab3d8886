//! The slew short path: steps at the top speed from the cached delay and
//! the carry alone, and [`SlewSpan`], the closed form of the steps it
//! yields next.

use crate::profile::{Phase, Step};

use super::curve::SCurve;
use super::HALF_TURN;

impl SCurve {
    /// A step at the top speed, in the steady state the general path set up:
    /// the ramp position stays at the top, the delay is the cached one plus
    /// the carried fraction (in `0..2^32`, so whole ticks never need the
    /// clamps), and only the counters and the carry change. Gives exactly
    /// what [`SCurve::next_general`] would.
    #[inline(always)]
    pub(super) fn next_slew(&mut self) -> Step {
        // In range by construction (see `arm_slew`): no overflow, ticks ≥ 1.
        let total = self.slew_delay_q32 + self.carry as u64;
        let delay_ticks = (total >> 32) as u32;
        self.carry = (total & 0xFFFF_FFFF) as i64;
        self.last_emitted = Some((Phase::Slew, delay_ticks));
        let index = self.index;
        self.index += 1;
        self.remaining -= 1;
        Step {
            index,
            phase: Phase::Slew,
            binary_angle: Some(HALF_TURN),
            velocity_steps_per_s: self.slew_velocity,
            delay_ticks,
        }
    }

    /// After a slew step of the general path: turns the fast path on for
    /// the slew steps that follow, when their arithmetic needs no clamp.
    pub(super) fn arm_slew(&mut self, delay_q32: u64, velocity: f64) {
        let carry_in_range = (0..1i64 << 32).contains(&self.carry);
        let delay_in_range = (1u64 << 32..=u64::MAX - (1u64 << 32)).contains(&delay_q32);
        if self.pending_ramp.is_none()
            && self.position == Some(self.ramp.accel_steps)
            && carry_in_range
            && delay_in_range
        {
            // The walk stays at the top while more than `accel_steps` remain.
            self.slew_floor = self.ramp.accel_steps;
            self.slew_delay_q32 = delay_q32;
            self.slew_velocity = velocity;
        }
    }
}

/// The slew steps [`SCurve`]'s short path will yield next with nothing
/// re-planned in between (see [`SCurve::slew_span`]): every one a
/// [`Phase::Slew`] step of `velocity_steps_per_s` whose delay is the whole
/// ticks of a 32.32 running sum, so any of them is known in closed form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlewSpan {
    /// How many steps the short path has left (at least 1).
    pub steps: u32,
    /// The delay of each step before rounding, 32.32 ticks.
    pub delay_q32: u64,
    /// The fraction carried into the first of them, 32.32 ticks (< 1 tick).
    pub carry_q32: u64,
    /// The velocity each reports, steps/s.
    pub velocity_steps_per_s: f64,
}

impl SlewSpan {
    /// The whole-tick delays of the first `steps` steps, summed.
    pub fn ticks_before(&self, steps: u64) -> u64 {
        ((u128::from(steps) * u128::from(self.delay_q32) + u128::from(self.carry_q32)) >> 32) as u64
    }

    /// The whole-tick delay of step `i` (0 is the next one).
    pub fn delay_ticks(&self, i: u64) -> u32 {
        (self.ticks_before(i + 1) - self.ticks_before(i)) as u32
    }

    /// How many of the steps begin within `ticks` of the first: the count
    /// of `i` with `ticks_before(i) <= ticks` (at least 1; may exceed `steps`).
    pub fn steps_within(&self, ticks: u64) -> u64 {
        // ticks_before(i) <= ticks  ⇔  i·delay + carry < (ticks + 1)·2^32.
        let bound = ((u128::from(ticks) + 1) << 32) - 1 - u128::from(self.carry_q32);
        let steps = bound / u128::from(self.delay_q32.max(1)) + 1;
        u64::try_from(steps).unwrap_or(u64::MAX)
    }
}

impl SCurve {
    /// The steps the slew short path yields next, or `None` when the next
    /// step takes the general path (a ramp, a re-planning, the last steps).
    pub fn slew_span(&self) -> Option<SlewSpan> {
        (self.remaining > self.slew_floor).then(|| SlewSpan {
            steps: self.remaining - self.slew_floor,
            delay_q32: self.slew_delay_q32,
            // In 0..2^32 while the short path holds (see `arm_slew`).
            carry_q32: self.carry as u64,
            velocity_steps_per_s: self.slew_velocity,
        })
    }

    /// Yields `steps` steps of [`SCurve::slew_span`] at once (1 to its
    /// `steps`, else nothing happens): the state after is bit for bit what
    /// `steps` calls of `next` leave. Returns the delay of the last one.
    pub fn skip_slew(&mut self, steps: u32) -> Option<u32> {
        let span = self.slew_span()?;
        if steps == 0 || steps > span.steps {
            return None;
        }
        let total = u128::from(steps) * u128::from(span.delay_q32) + u128::from(span.carry_q32);
        let last = span.delay_ticks(u64::from(steps) - 1);
        self.carry = (total & 0xFFFF_FFFF) as i64;
        self.last_emitted = Some((Phase::Slew, last));
        self.index += steps;
        self.remaining -= steps;
        Some(last)
    }
}

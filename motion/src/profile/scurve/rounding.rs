//! Whole-tick delays: the rounding remainder carried from step to step, and
//! the monotonic rule that keeps a ramp's delays in order.

use crate::profile::Phase;

use super::curve::SCurve;

impl SCurve {
    /// Turns an exact delay into whole ticks, carrying the remainder so that
    /// edge times stay on the ideal curve, while never letting a delay grow
    /// during acceleration or shrink during deceleration.
    pub(super) fn round_delay(&mut self, delay_q32: u64, phase: Phase) -> u32 {
        let previous = self.last_emitted.and_then(|(previous_phase, previous)| {
            // After a stop, the first deceleration step is held to the last
            // step's delay too, whatever that step's phase.
            (previous_phase == phase || (self.stopping && phase == Phase::Decel))
                .then_some(previous)
        });
        let (ticks, carry) = carry_round(delay_q32, self.carry, phase, previous);
        self.carry = carry;
        self.last_emitted = Some((phase, ticks));
        ticks
    }
}

/// [`SCurve::round_delay`]'s arithmetic: (whole ticks, carry after), the
/// ticks held to `previous` (no longer when accelerating, no shorter when
/// decelerating) where the monotonic rule applies.
#[inline(always)]
pub(super) fn carry_round(
    delay_q32: u64,
    carry: i64,
    phase: Phase,
    previous: Option<u32>,
) -> (u32, i64) {
    let held = previous.unwrap_or(match phase {
        Phase::Accel => u32::MAX,
        _ => 0,
    });
    carry_round_held(delay_q32, carry, phase, held)
}

/// [`carry_round`] with the ticks held to `previous` (`u32::MAX` when
/// accelerating, 0 otherwise, hold nothing). Every real delay takes the
/// 64-bit arithmetic, a chain of additions, shifts and selects without a
/// branch; the 128-bit one is for delays of 2^30 ticks and more.
#[inline(always)]
pub(super) fn carry_round_held(
    delay_q32: u64,
    carry: i64,
    phase: Phase,
    previous: u32,
) -> (u32, i64) {
    // The carry is within ±2^50: below 2^62 + 2^50 the sum fits, and with
    // the ticks below 2^31 so does `ticks << 32`.
    if (delay_q32 >> 62) | u64::from(previous >> 31) != 0 {
        return carry_round_wide(delay_q32, carry, phase, previous);
    }
    let total = delay_q32 as i64 + carry;
    let ticks = hold(phase, (total >> 32).max(1) as u32, previous);
    // In practice the carry holds a few ticks at most (what the monotonic
    // clamp held back); the bound only keeps it finite on absurd input.
    let carry = (total - (i64::from(ticks) << 32)).clamp(-(1 << 50), 1 << 50);
    (ticks, carry)
}

/// The monotonic rule: `whole` ticks held to `previous` (no longer when
/// accelerating, no shorter when decelerating).
#[inline(always)]
fn hold(phase: Phase, whole: u32, previous: u32) -> u32 {
    match phase {
        Phase::Accel => whole.min(previous),
        Phase::Decel => whole.max(previous),
        Phase::Slew => whole,
    }
}

/// [`carry_round_held`] in 128-bit arithmetic, for any delay.
#[cold]
fn carry_round_wide(delay_q32: u64, carry: i64, phase: Phase, previous: u32) -> (u32, i64) {
    let total = i128::from(delay_q32) + i128::from(carry);
    let ticks = hold(
        phase,
        (total >> 32).clamp(1, i128::from(u32::MAX)) as u32,
        previous,
    );
    let carry = (total - (i128::from(ticks) << 32)).clamp(-(1 << 50), 1 << 50) as i64;
    (ticks, carry)
}

//! [`Arithmetic::Smooth`](super::Arithmetic::Smooth): exact angles, the
//! velocity at full precision and each delay as one IEEE division.

use super::ramp::Ramp;
use super::HALF_TURN;

/// Full scale of the cosine used by the smooth arithmetic.
pub(super) const COS_SCALE: i32 = 1 << 30;

/// 2^63 as an `f64`.
pub(super) const TWO_TO_THE_63: f64 = 9_223_372_036_854_775_808.0;

/// clkfreq / (sp·(1 − cos θ)/2) in 32.32 ticks from `one_minus_cos` =
/// (1 − cos θ)·2^30 (in 1..=2^31): `(clkfreq·2^63/sp) / one_minus_cos` as
/// one IEEE division (the numerator rounded once per ramp, the divisor
/// exact), so a relative error below 2^-52, truncated to 32.32 ticks and
/// held below 2^63. The same bits on every target (IEEE arithmetic is
/// exact-rounded); a division on a host FPU overlaps the next step's, where
/// a 64-bit integer division would not.
#[inline(always)]
pub(super) fn smooth_delay_q32(numerator: u64, one_minus_cos: u64) -> u64 {
    DelayNumerator::new(numerator).delay_q32(one_minus_cos)
}

/// A ramp's delay numerator (clkfreq·2^63/sp as an `f64`'s bits) made ready
/// for the divisions of [`smooth_delay_q32`]: the `f64` on a host; taken
/// apart once ([`Dividend`]) where there is no FPU, so that a run of ramp
/// steps does it once, not at every step.
///
/// [`Dividend`]: crate::profile::ieee_div::Dividend
#[derive(Clone, Copy, Debug)]
pub(super) struct DelayNumerator {
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    value: f64,
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    value: crate::profile::ieee_div::Dividend,
}

impl DelayNumerator {
    #[inline(always)]
    pub(super) fn new(numerator: u64) -> Self {
        #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
        return Self {
            value: f64::from_bits(numerator),
        };
        #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
        return Self {
            value: crate::profile::ieee_div::Dividend::new(numerator),
        };
    }

    /// [`smooth_delay_q32`] of this numerator.
    #[inline(always)]
    pub(super) fn delay_q32(self, one_minus_cos: u64) -> u64 {
        // `as` saturates (the value is never NaN: both operands are
        // positive), at 2^63 − 1 for `i64`.
        #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
        return (self.value / one_minus_cos as f64) as i64 as u64;
        // No FPU: the same bits from integer arithmetic (32-bit UDIV, no
        // soft-float calls); `one_minus_cos` is at most 2^31.
        #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
        return self.value.div_trunc(one_minus_cos as u32);
    }
}

/// Smooth: (velocity, delay in 32.32 ticks) from the cosine X (2^30 scale).
#[inline(always)]
pub(super) fn smooth_velocity_delay(ramp: Ramp, x: i32) -> (f64, u64) {
    let one_minus_cos = smooth_one_minus_cos(x);
    let velocity = scaled_velocity(ramp.speed, one_minus_cos as u32, 1.0 / f64::from(HALF_TURN));
    (velocity, smooth_delay_q32(ramp.numerator, one_minus_cos))
}

/// `scale · units · pow2` in steps/s (`pow2` a power of two): the exact
/// integer product rounded once to `f64` (as `f64::from(scale) *
/// f64::from(units)` would round it, but one conversion instead of two and a
/// multiplication, which a microcontroller does in software), then scaled
/// exactly.
#[inline(always)]
pub(super) fn scaled_velocity(scale: u32, units: u32, pow2: f64) -> f64 {
    // Below 2^63 (Smooth: scale < 2^32 and units = (1 − cos θ)·2^30 ≤ 2^31;
    // P2Exact: a scale of 1), so the signed conversion, the cheaper one,
    // rounds alike.
    // One widening product, inline even where there is no widening multiply.
    let product = cordic_core::wide_mul::mul_u32_wide(scale, units);
    debug_assert!(product < 1 << 63);
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    return product as i64 as f64 * pow2;
    // No FPU: the conversion and the scaling as integer and exponent
    // arithmetic, the same bits.
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    return crate::profile::ieee_div::u64_times_pow2(product, pow2);
}

/// Smooth: (1 − cos θ)·2^30 from the cosine X (2^30 scale), in 1..=2^31:
/// twice the velocity fraction.
#[inline(always)]
fn smooth_one_minus_cos(x: i32) -> u64 {
    (i64::from(COS_SCALE) - i64::from(x)).max(1) as u64
}

/// A Smooth ramp step's (velocity units, 32.32 delay) from its cosine X.
#[inline(always)]
pub(super) fn smooth_run_timing(numerator: DelayNumerator, x: i32) -> (u32, u64) {
    let one_minus_cos = smooth_one_minus_cos(x);
    (one_minus_cos as u32, numerator.delay_q32(one_minus_cos))
}

/// [`smooth_angle`]'s span (180° − offset, in units of 1/360 of a binary
/// angle unit) and the divisor of its numerator, `360·accel_steps`.
pub(super) fn smooth_angle_span(offset_deg: u32, accel_steps: u32) -> (u64, u64) {
    let span = (180u64 << 32) - (u64::from(offset_deg) << 32);
    (span, 360 * u64::from(accel_steps.max(1)))
}

/// offset + position·(180° − offset)/accel_steps as a binary angle, rounded
/// once from exact wide arithmetic.
pub(super) fn smooth_angle(offset_deg: u32, accel_steps: u32, position: u32) -> u32 {
    if accel_steps == 0 || position >= accel_steps {
        return HALF_TURN;
    }
    // Binary angles scaled by 360 so that whole degrees are exact.
    let offset = u64::from(offset_deg) << 32;
    let span = (180u64 << 32) - offset;
    // span < 2^40: 64 bits hold the product for ramps up to 2^24 positions
    // (every speed below 167 M steps/s), and give the same bits as 128.
    let climbed = match span.checked_mul(u64::from(position)) {
        Some(product) => product / u64::from(accel_steps),
        // Below `span` (position < accel_steps), so it fits again.
        None => (u128::from(span) * u128::from(position) / u128::from(accel_steps)) as u64,
    };
    ((offset + climbed + 180) / 360) as u32
}

//! [`Arithmetic::P2Exact`](super::Arithmetic::P2Exact): the reference cog's
//! integer arithmetic (its angle mapping, `v = max(halfsp − X, 1)`, QDIV and
//! the delay cap) and its step period on the board.

use super::planning::ScurveConfig;
use super::ramp::Ramp;

/// The reference's cap on a step delay, in ticks.
pub const P2_MAX_DELAY_TICKS: u32 = 95_000_000;

/// The reference's degrees·128 to binary angle factor (2^32 / 46,080, truncated).
pub const P2_DEG128_TO_BINARY: u32 = 93_206;

/// The reference's step pulse (`delayh`): the step pin is high for 1,000
/// ticks (5 µs at 200 MHz), and that time is part of the step period.
pub const P2_PULSE_TICKS: u32 = 1_000;

/// The reference cog's fixed instruction overhead in a step period, in
/// clocks: from the moment CT reaches the CT2 target (`cv`) to the moment
/// the next `GETCT cv` samples CT.
///
/// The cog keeps one running target. Right after a rising edge it reads
/// CT into `cv` (`drvh steppin` / `getct cv`); `addct1 cv, delayh` moves
/// `cv` on by the pulse and `_ws2 addct2 cv, delay` by the step's delay,
/// so the next wait ends at `cv + delayh + delay`. Everything else the cog
/// does between two steps (the hub writes, the CORDIC's `_getdelay`, the
/// main loop's tests) runs while it waits, inside the pulse or the delay,
/// and costs nothing. What is *not* hidden is the path from the end of the
/// wait to the next `GETCT`, in cog execution (P2 silicon documentation:
/// 2 clocks an instruction, 4 for a branch taken, `WAITxxx` 2+):
///
/// | instruction | clocks | why |
/// |---|---|---|
/// | `waitct2` (in `_waitstep`) | 2 | the CT2 event flag is set as CT passes the target (MSB of CT − CT2 turns 0); the stalled wait then completes its 2 clocks |
/// | `tjnz steps, #_dostep1` | 4 | steps left: the branch is taken (2 + 2 to reload the pipeline) |
/// | `drvh steppin` | 2 | the rising edge |
/// | `getct cv` | 0 | CT is sampled as it executes: the new `cv` |
///
/// 2 + 4 + 2 = 8 clocks, so rising edge to rising edge is
/// `delay + delayh + 8` ([`p2_period_ticks`]): at 20,000 steps/s
/// (delay 10,000) the board makes 200 MHz / 11,008 = 18,169 steps/s, at
/// 45,000 (delay 4,444) 36,684. The wake-up is the least certain term; a
/// clock more or less moves those rates by under 0.01 %.
///
/// The sum holds while the cog's own work between two edges fits in the
/// period: at least the `_getdelay` CORDIC chain (about 300 clocks) after
/// the pulse, so delays above a few hundred ticks (every speed below
/// 500,000 steps/s at 200 MHz). The pulse edge itself (`drvh`) is a fixed
/// offset before `getct`, so the edges are spaced like the `cv` values.
pub const P2_STEP_OVERHEAD_TICKS: u32 = 8;

/// The reference cog's step period, rising edge to rising edge, in ticks:
/// the step's delay, plus the pulse the running target adds before it,
/// plus the cog's fixed overhead ([`P2_STEP_OVERHEAD_TICKS`]).
///
/// ```
/// use cogstep_motion::profile::scurve::{p2_period_ticks, P2_PULSE_TICKS};
/// // Asked for 20,000 steps/s (delay 10,000 ticks), the P2 board steps
/// // every 11,008 ticks: 18,169 steps/s at 200 MHz.
/// assert_eq!(p2_period_ticks(10_000, P2_PULSE_TICKS), 11_008);
/// ```
pub fn p2_period_ticks(delay_ticks: u32, pulse_ticks: u32) -> u64 {
    u64::from(delay_ticks) + u64::from(pulse_ticks) + u64::from(P2_STEP_OVERHEAD_TICKS)
}

/// The reference's `v = max(halfsp − X, 1)` and `delay = min(QDIV(clkfreq, v), cap)`.
#[inline(always)]
pub(super) fn p2_velocity_delay(clkfreq: u32, ramp: Ramp, x: i32) -> (u32, u32) {
    let halfsp = (ramp.speed / 2) as i32;
    let velocity = (i64::from(halfsp) - i64::from(x)).max(1) as u32;
    // The dividend fits 32 bits and v ≥ 1: QDIV's quotient is the 32-bit
    // one (`div_u32` is tested against `qdiv`).
    let delay = div_u32(clkfreq, velocity).min(P2_MAX_DELAY_TICKS);
    (velocity, delay)
}

/// `dividend / divisor` (`divisor ≥ 1`), exactly, the fastest way the target
/// has. On a host with an FPU: the IEEE quotient, truncated. It is exact:
/// were a/b = n − k/b (k ≥ 1) rounded up to n, its relative error would be
/// at least 1/(b·n) > 2^-32 (as b·n ≤ a + b < 2^33), but an IEEE division's is
/// at most 2^-53; and an exact integer a/b is exact in f64. A host's divider
/// is slow and not pipelined for integers, fast for `f64`. Elsewhere (a
/// Cortex-M has a 32-bit divider and no FPU): the integer division.
#[inline(always)]
pub(super) fn div_u32(dividend: u32, divisor: u32) -> u32 {
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    {
        (f64::from(dividend) / f64::from(divisor)) as u32
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        dividend / divisor
    }
}

/// P2Exact: the rotations of the cosine keys `first..first + angles.len()`
/// of a ramp: fills `angles` with [`SCurve::rotation`]'s angles and returns
/// its radius, stepping the angle's quotient and remainder instead of
/// dividing per key. (Smooth's angles come with its cosines, from
/// [`smooth_cosines`].)
///
/// [`SCurve::rotation`]: super::SCurve::rotation
/// [`smooth_cosines`]: super::cosines::smooth_cosines
pub(super) fn p2_ramp_angles(
    config: &ScurveConfig,
    ramp: Ramp,
    first: u32,
    angles: &mut [u32],
) -> i32 {
    let offset = config.offset_deg;
    // deg·128 = key·(360 − 2·offset)·128 / stom + offset·128.
    let range = u64::from(360 - 2 * offset) * 128;
    let base = offset * 128;
    match core::num::NonZeroU64::new(u64::from(2 * ramp.accel_steps)) {
        None => angles.fill((180 * 128u32).wrapping_mul(P2_DEG128_TO_BINARY)),
        Some(stom) => {
            let product = u64::from(first) * range;
            let (mut quotient, mut remainder) = (product / stom, product % stom);
            let (step_quotient, step_remainder) = (range / stom, range % stom);
            for angle in angles.iter_mut() {
                // As the reference: the 32-bit sum, then the wrapping multiply.
                *angle = (quotient as u32 + base).wrapping_mul(P2_DEG128_TO_BINARY);
                quotient += step_quotient;
                remainder += step_remainder;
                if remainder >= stom.get() {
                    remainder -= stom.get();
                    quotient += 1;
                }
            }
        }
    }
    (ramp.speed / 2) as i32
}

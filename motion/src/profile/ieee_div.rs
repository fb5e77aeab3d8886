//! IEEE-754 double arithmetic of the Smooth S-curve, in integers, for cores
//! without an FPU.
//!
//! A Smooth ramp step divides an `f64` numerator by an integer and truncates
//! the quotient ([`div_trunc`]), and scales an integer product by a power of
//! two ([`u64_times_pow2`]). On a Cortex-M3 these are soft-float library
//! calls (ddiv, d2ulz, l2d, dmul): hundreds of instructions. The functions
//! here give bit for bit what the `f64` expressions give (IEEE arithmetic is
//! correctly rounded: round to nearest, ties to even), with 32-bit divisions
//! (`UDIV`) and multiplications only: no 64-bit division library call.
//!
//! The S-curve uses them on targets without an FPU; the host keeps its
//! hardware `f64`. Their tests compare bits against the `f64` expressions.

/// Bits of an `f64`'s fraction field.
const FRACTION_BITS: u32 = 52;
/// The fraction field's mask.
const FRACTION_MASK: u64 = (1 << FRACTION_BITS) - 1;
/// An `f64`'s exponent bias.
const EXPONENT_BIAS: i32 = 1023;
/// The biased exponent's mask (after shifting the fraction out).
const EXPONENT_MASK: u64 = 0x7FF;
/// The largest result [`div_trunc`] gives.
const QUOTIENT_MAX: u64 = u64::MAX >> 1;

/// `((f64::from_bits(numerator) / divisor as f64) as u64).min(u64::MAX >> 1)`
/// for a positive finite `numerator` (subnormals included) and `divisor` in
/// `1..=2^31`: the quotient rounded to an `f64` (nearest, ties to even),
/// truncated towards zero and held below 2^63.
///
/// Zero gives 0; a sign bit is ignored; infinities and NaNs (outside the
/// domain) give an unspecified value, never a panic.
pub fn div_trunc(numerator: u64, divisor: u32) -> u64 {
    Dividend::new(numerator).div_trunc(divisor)
}

/// A numerator of [`div_trunc`] taken apart and normalized once, for
/// divisions by many divisors (a ramp's steps share their numerator).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dividend {
    /// The numerator's significand normalized to [2^62, 2^63), or 0 for a
    /// numerator of zero.
    dividend: u64,
    /// numerator = dividend · 2^exponent.
    exponent: i32,
}

impl Dividend {
    /// `numerator`'s bits taken apart (a sign bit ignored).
    pub fn new(numerator: u64) -> Self {
        let biased = ((numerator >> FRACTION_BITS) & EXPONENT_MASK) as i32;
        let fraction = numerator & FRACTION_MASK;
        // numerator = significand · 2^exponent
        let (significand, exponent) = if biased == 0 {
            (fraction, 1 - EXPONENT_BIAS - FRACTION_BITS as i32)
        } else {
            (
                fraction | (1 << FRACTION_BITS),
                biased - EXPONENT_BIAS - FRACTION_BITS as i32,
            )
        };
        if significand == 0 {
            return Self {
                dividend: 0,
                exponent: 0,
            };
        }
        // A normal numerator's significand has its top bit at 2^52.
        let shift = if biased == 0 {
            significand.leading_zeros() - 1
        } else {
            10
        };
        Self {
            dividend: significand << shift,
            exponent: exponent - shift as i32,
        }
    }

    /// [`div_trunc`] of the numerator by `divisor` (in `1..=2^31`).
    pub fn div_trunc(self, divisor: u32) -> u64 {
        debug_assert!((1..=1 << 31).contains(&divisor), "divisor {divisor}");
        let Self { dividend, exponent } = self;
        if dividend == 0 {
            return 0;
        }
        // Both normalized: the dividend in [2^62, 2^63), the divisor in
        // [2^31, 2^32), so dividend·2^32 / divisor is in (2^62, 2^64): a
        // quotient of 63 or 64 bits, two 32-bit digits, its sticky bit the
        // remainder.
        let divisor = divisor.max(1);
        let divisor_shift = leading_zeros_u32(divisor);
        let divisor = divisor << divisor_shift;
        let (high, remainder) = div_2by1((dividend >> 32) as u32, dividend as u32, divisor);
        // numerator / divisor = (quotient + remainder/divisor) · 2^scale
        let scale = exponent - 32 + divisor_shift as i32;
        // Rounded to 53 significant bits: drop 11 of a 64-bit quotient, 10
        // of a 63-bit one.
        let dropped = if high >> 31 != 0 { 11 } else { 10 };
        // The rounded quotient will be significand (in [2^52, 2^53]) ·
        // 2^power.
        let power = scale + dropped;

        // The quotient's third 16-bit digit.
        let (third, remainder) = div_digit(remainder, 0, divisor);
        let top = (u64::from(high) << 16) | u64::from(third);
        // The short way, where the result drops enough bits (t > 16 below:
        // a delay of fewer than 2^14 whole ticks, a step above about
        // 7,600 steps/s at 125 MHz, above 61 steps/s on 1 µs ticks): of
        // the quotient's 64 bits, it keeps the top 64 − t, t = dropped −
        // power. Rounding to 53 bits changes them only by carrying into
        // them, through bits dropped − 1 to t − 1, which must then all be
        // ones. The top 48 bits (three digits) hold bits 16 to t − 1:
        // unless those are all ones, the result is the top bits as they
        // are, and the fourth digit (a quarter of the division) is not
        // needed. About one quotient in 2^(t − 16) takes the long way.
        if power < 0 && power > -54 {
            let guard = dropped - power - 16;
            if guard > 0 {
                let guard = guard as u32;
                let kept = cordic_core::wide_mul::shift_right_i64(top as i64, guard);
                if cordic_core::wide_mul::shift_right_i64(top as i64 + 1, guard) == kept {
                    return kept as u64;
                }
            }
        }
        let (fourth, remainder) = div_digit(remainder, 0, divisor);
        let quotient = (top << 16) | u64::from(fourth);

        let sticky = remainder != 0;
        let significand = if dropped == 11 {
            round_shift(quotient, 11, sticky)
        } else {
            round_shift(quotient, 10, sticky)
        };
        if power >= 0 {
            // significand · 2^11 ≥ 2^63: held.
            if power > 10 {
                QUOTIENT_MAX
            } else {
                (significand << power).min(QUOTIENT_MAX)
            }
        } else if power > -54 {
            // Truncated, as `as u64` does (significand < 2^54: a positive
            // `i64`, shifted on 32-bit words where there is no 64-bit
            // shift).
            cordic_core::wide_mul::shift_right_i64(significand as i64, (-power) as u32) as u64
        } else {
            // Below 1 (a subnormal quotient included): 0.
            0
        }
    }
}

/// `value.leading_zeros()`: on a core without a count-leading-zeros
/// instruction (ARMv6-M: there `leading_zeros` calls `__clzsi2`, which
/// rp2040-hal routes to the boot ROM, some 60 cycles with the call), a
/// binary search of five compares and shifts, inline.
#[inline(always)]
fn leading_zeros_u32(value: u32) -> u32 {
    #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
    return leading_zeros_by_search(value);
    #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
    return value.leading_zeros();
}

/// [`leading_zeros_u32`] by binary search.
#[cfg(any(test, all(target_arch = "arm", not(target_has_atomic = "32"))))]
#[inline(always)]
fn leading_zeros_by_search(mut value: u32) -> u32 {
    if value == 0 {
        return 32;
    }
    let mut zeros = 0;
    for width in [16, 8, 4, 2, 1] {
        if value >> (32 - width) == 0 {
            zeros += width;
            value <<= width;
        }
    }
    zeros
}

/// `value >> dropped` rounded to nearest, ties to even, where `sticky` says
/// that the exact value lies above `value` (a nonzero remainder below it).
/// `dropped` is in 1..=63.
#[inline(always)]
fn round_shift(value: u64, dropped: u32, sticky: bool) -> u64 {
    let kept = value >> dropped;
    let half = 1u64 << (dropped - 1);
    let rest = value & ((half << 1) - 1);
    let up = rest > half || (rest == half && (sticky || kept & 1 == 1));
    kept + u64::from(up)
}

/// `(high·2^32 + low) / divisor` and its remainder, for a normalized
/// `divisor` (top bit set) and `high < divisor` (so the quotient fits 32
/// bits): Knuth's algorithm D with 16-bit digits, each estimated with a
/// 32-bit division and corrected at most twice.
#[inline(always)]
fn div_2by1(high: u32, low: u32, divisor: u32) -> (u32, u32) {
    debug_assert!(divisor >= 1 << 31 && high < divisor);
    let (digit_high, remainder) = div_digit(high, low >> 16, divisor);
    let (digit_low, remainder) = div_digit(remainder, low & 0xFFFF, divisor);
    ((digit_high << 16) | digit_low, remainder)
}

/// One 16-bit digit of `(upper·2^16 + next) / divisor` and its remainder,
/// for a normalized `divisor` (top bit set), `upper < divisor` and `next
/// < 2^16`: estimated with a 32-bit division, corrected at most twice
/// (the remainder wraps into 32 bits exactly: it is below the divisor).
#[inline(always)]
fn div_digit(upper: u32, next: u32, divisor: u32) -> (u32, u32) {
    let divisor_high = divisor >> 16;
    let divisor_low = divisor & 0xFFFF;
    let mut digit = upper / divisor_high;
    let mut rest = upper - digit * divisor_high;
    while digit > 0xFFFF || digit * divisor_low > ((rest << 16) | next) {
        digit -= 1;
        rest += divisor_high;
        if rest > 0xFFFF {
            break;
        }
    }
    let remainder = ((upper << 16) | next).wrapping_sub(digit.wrapping_mul(divisor));
    (digit, remainder)
}

/// `value as f64` (round to nearest, ties to even), as bits.
pub fn u64_to_f64_bits(value: u64) -> u64 {
    if value == 0 {
        return 0;
    }
    let top = 63 - value.leading_zeros();
    let significand = if top <= FRACTION_BITS {
        value << (FRACTION_BITS - top)
    } else {
        round_shift(value, top - FRACTION_BITS, false)
    };
    // The significand's leading bit (2^52, or 2^53 after rounding up) adds
    // one to the exponent field.
    ((u64::from(top) + (EXPONENT_BIAS as u64 - 1)) << FRACTION_BITS) + significand
}

/// `product as f64 * pow2` for `product` below 2^63 (where it equals the
/// S-curve's `product as i64 as f64 * pow2`) and `pow2` an exact power of
/// two: the conversion rounded once, the scaling an exponent shift while
/// the result stays normal. Anything else (a `pow2` that is no normal
/// power of two, a result out of the normal range) takes the `f64`
/// multiplication, which gives the same bits by definition.
pub fn u64_times_pow2(product: u64, pow2: f64) -> f64 {
    let value = u64_to_f64_bits(product);
    let scale = pow2.to_bits();
    let scale_exponent = (scale >> FRACTION_BITS) as i64;
    let value_exponent = (value >> FRACTION_BITS) as i64;
    let exponent = value_exponent + scale_exponent - i64::from(EXPONENT_BIAS);
    let plain = scale & FRACTION_MASK == 0 && (1..=2046).contains(&scale_exponent);
    if plain && value != 0 && (1..=2046).contains(&exponent) {
        let shift = ((scale_exponent - i64::from(EXPONENT_BIAS)) << FRACTION_BITS) as u64;
        f64::from_bits(value.wrapping_add(shift))
    } else {
        f64::from_bits(value) * pow2
    }
}

/// `value as u32` — truncated towards zero, negative values and NaN 0,
/// values from 2^32 and infinity `u32::MAX` — for velocities on their way
/// to a status line. A host converts with its FPU; a core without one
/// takes [`f64_bits_to_u32`] (a few shifts, where the soft-float
/// conversion and the two comparisons its saturation needs are library
/// calls).
#[inline]
pub fn f64_to_u32(value: f64) -> u32 {
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    return value as u32;
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    return f64_bits_to_u32(value.to_bits());
}

/// [`f64_to_u32`] of the `f64` with these bits, in integer arithmetic.
pub fn f64_bits_to_u32(bits: u64) -> u32 {
    let biased = ((bits >> FRACTION_BITS) & EXPONENT_MASK) as i32;
    let negative = bits >> 63 != 0;
    if biased == EXPONENT_MASK as i32 {
        // Infinity saturates (the negative one to 0); NaN is 0.
        return if bits & FRACTION_MASK == 0 && !negative {
            u32::MAX
        } else {
            0
        };
    }
    // value = (2^52 + fraction) · 2^(biased − 1023 − 52) for a normal value;
    // below 1 (subnormals and zero included) it truncates to 0.
    let exponent = biased - EXPONENT_BIAS;
    if negative || exponent < 0 {
        return 0;
    }
    if exponent >= 32 {
        return u32::MAX;
    }
    let significand = (bits & FRACTION_MASK) | (1 << FRACTION_BITS);
    (significand >> (FRACTION_BITS as i32 - exponent)) as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn reference_div(numerator: u64, divisor: u32) -> u64 {
        ((f64::from_bits(numerator) / divisor as f64) as u64).min(u64::MAX >> 1)
    }

    fn reference_velocity(scale: u32, units: u32, pow2: f64) -> f64 {
        (u64::from(scale) * u64::from(units)) as i64 as f64 * pow2
    }

    fn check_div(numerator: u64, divisor: u32) {
        assert_eq!(
            div_trunc(numerator, divisor),
            reference_div(numerator, divisor),
            "{:e} / {divisor}",
            f64::from_bits(numerator)
        );
    }

    /// Numerators from quotient `q` (as an f64) times divisor, and its
    /// neighbours: the quotients that land on and around integers, ties
    /// and the clamp.
    fn around(quotient: f64, divisor: u32) {
        let numerator = quotient * divisor as f64;
        if numerator.is_finite() && numerator > 0.0 {
            let bits = numerator.to_bits();
            for bits in bits.saturating_sub(3)..=bits.saturating_add(3) {
                if f64::from_bits(bits).is_finite() && bits != 0 {
                    check_div(bits, divisor);
                }
            }
        }
    }

    #[test]
    fn two_by_one_divides_like_u64() {
        let cases = [
            (0, 0, 1 << 31),
            (0x7FFF_FFFF, 0xFFFF_FFFF, 1 << 31),
            (0xFFFF_FFFE, 0xFFFF_FFFF, 0xFFFF_FFFF),
            (0x8000_0000, 0, 0x8000_0001),
            (0x7FFF_0000, 0xFFFF, 0x8000_FFFF),
        ];
        for (high, low, divisor) in cases {
            let dividend = (u64::from(high) << 32) | u64::from(low);
            let expected = (dividend / u64::from(divisor), dividend % u64::from(divisor));
            let (q, r) = div_2by1(high, low, divisor);
            assert_eq!((u64::from(q), u64::from(r)), expected);
        }
    }

    #[test]
    fn edge_cases_match_f64() {
        let divisors = [
            1,
            2,
            3,
            5,
            7,
            0xFFFF,
            0x1_0001,
            0x7FFF_FFFF,
            1 << 31,
            1 << 30,
            3 << 29,
        ];
        let numerators = [
            f64::MIN_POSITIVE,
            f64::from_bits(1),
            f64::from_bits(FRACTION_MASK),
            f64::MAX,
            0.5,
            1.0,
            1.5,
            2.5,
            (1u64 << 53) as f64,
            (1u64 << 63) as f64,
            (1u64 << 63) as f64 * 2.0,
            ((1u64 << 63) - 1024) as f64,
            1e19,
            1e-300,
        ];
        for &divisor in &divisors {
            for &numerator in &numerators {
                for bits in numerator.to_bits().saturating_sub(2)..=numerator.to_bits() + 2 {
                    if f64::from_bits(bits).is_finite() && bits != 0 {
                        check_div(bits, divisor);
                    }
                }
            }
            // Quotients at and near the clamp, powers of two, ties (x.5),
            // integers, just below 1 and 0.5.
            for quotient in [
                ((1u64 << 63) - 1024) as f64,
                (1u64 << 63) as f64,
                ((1u64 << 62) + 1) as f64,
                (1u64 << 54) as f64 + 2.0,
                (1u64 << 53) as f64 + 1.0,
                4_503_599_627_370_495.5,
                2.5,
                3.5,
                1.0,
                0.5,
                1.0 - f64::EPSILON / 4.0,
                1.0 - f64::EPSILON / 2.0,
                1e-10,
            ] {
                around(quotient, divisor);
            }
        }
        assert_eq!(div_trunc(0, 7), 0);
    }

    #[test]
    fn conversions_match_f64() {
        for value in [
            0u64,
            1,
            (1 << 53) - 1,
            1 << 53,
            (1 << 53) + 1,
            (1 << 54) + 2,
            (1 << 54) + 6,
            (1 << 63) - 1,
            (1 << 63) - 1024,
            (1 << 63) - 1025,
            (1 << 62) + (1 << 9),
            (1 << 62) + (3 << 9),
            u64::MAX,
        ] {
            assert_eq!(u64_to_f64_bits(value), (value as f64).to_bits(), "{value}");
        }
        for pow2 in [
            1.0,
            0.5,
            2.0,
            1.0 / f64::from(1u32 << 31),
            0.0,
            1.5,
            f64::MIN_POSITIVE,
        ] {
            for (scale, units) in [(0, 5), (1, 1), (20_000, 1 << 31), (u32::MAX, 1 << 31)] {
                assert_eq!(
                    u64_times_pow2(u64::from(scale) * u64::from(units), pow2).to_bits(),
                    reference_velocity(scale, units, pow2).to_bits()
                );
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn two_by_one_matches_u64(high in any::<u32>(), low in any::<u32>(), divisor in (1u32 << 31)..=u32::MAX) {
            let high = high % divisor;
            let dividend = (u64::from(high) << 32) | u64::from(low);
            let (q, r) = div_2by1(high, low, divisor);
            prop_assert_eq!((u64::from(q), u64::from(r)),
                (dividend / u64::from(divisor), dividend % u64::from(divisor)));
        }

        #[test]
        fn leading_zeros_by_search_counts(value in any::<u32>(), shift in 0u32..32) {
            prop_assert_eq!(leading_zeros_by_search(value), value.leading_zeros());
            prop_assert_eq!(leading_zeros_by_search(value >> shift), (value >> shift).leading_zeros());
        }

        #[test]
        fn division_matches_f64(numerator in 1u64..0x7FF0_0000_0000_0000, divisor in 1u32..=1 << 31) {
            prop_assert_eq!(div_trunc(numerator, divisor), reference_div(numerator, divisor));
        }

        /// Numerators in the S-curve's range (quotients of 2^20 to 2^63
        /// in 32.32 ticks), divisors small and large.
        #[test]
        fn scurve_range_matches_f64(quotient_log in 20.0f64..63.5, divisor_log in 0.0f64..31.0, nudge in -4i64..=4) {
            let divisor = (2f64.powf(divisor_log) as u32).max(1);
            let numerator = (2f64.powf(quotient_log) * divisor as f64).to_bits().wrapping_add_signed(nudge);
            prop_assert_eq!(div_trunc(numerator, divisor), reference_div(numerator, divisor));
        }

        /// Near ties: a quotient halfway between two f64s (an odd 54-bit
        /// integer, scaled) times the divisor, and its neighbours. (An
        /// exact tie cannot happen: an f64 numerator has 53 significant
        /// bits, an odd 54-bit quotient times an integer has more.)
        #[test]
        fn near_ties_match_f64(half in (1u64 << 52)..(1u64 << 53), shift in 0i32..12, divisor in 1u32..=1 << 31) {
            let tie = u128::from(2 * half + 1) * u128::from(divisor);
            let numerator = (tie as f64 * 2f64.powi(shift - 12)).to_bits();
            for bits in numerator - 2..=numerator + 2 {
                check_div(bits, divisor);
            }
        }

        /// Quotients at and next to a whole number of 2^-32 ticks (the
        /// truncation's boundary), where the rounding to 53 bits may carry
        /// into the bits kept: the short way (three digits) must step
        /// aside for every one that does.
        #[test]
        fn boundaries_of_the_kept_bits_match_f64(
            units in (1u64 << 20)..(1u64 << 53),
            divisor in 1u32..=1 << 31,
        ) {
            around(units as f64 / 4_294_967_296.0, divisor);
            around(units as f64 / 4_294_967_296.0 * 1_024.0, divisor);
        }

        #[test]
        fn conversion_matches_f64(value in any::<u64>(), shift in 0u32..64) {
            let value = value >> shift;
            prop_assert_eq!(u64_to_f64_bits(value), (value as f64).to_bits());
        }

        #[test]
        fn velocity_matches_f64(scale in any::<u32>(), units in 0u32..=1 << 31, power in -40i32..8) {
            let pow2 = 2f64.powi(power);
            prop_assert_eq!(
                u64_times_pow2(u64::from(scale) * u64::from(units), pow2).to_bits(),
                reference_velocity(scale, units, pow2).to_bits()
            );
        }
    }

    fn check_to_u32(bits: u64) {
        let value = f64::from_bits(bits);
        assert_eq!(f64_bits_to_u32(bits), value as u32, "{value:e} ({bits:#x})");
    }

    #[test]
    fn f64_to_u32_edges() {
        let values = [
            0.0,
            -0.0,
            0.5,
            0.999_999_999,
            1.0,
            1.5,
            -1.0,
            -0.5,
            4_294_967_295.0,
            4_294_967_295.5,
            4_294_967_296.0,
            1e300,
            -1e300,
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
            50_000.0,
            2_147_483_648.0,
        ];
        for value in values {
            check_to_u32(value.to_bits());
        }
        for exponent in 0..40 {
            let power = 2f64.powi(exponent);
            for value in [power, power - 1.0, power + 1.0, power * 1.5] {
                check_to_u32(value.to_bits());
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

        /// Any bits at all, and velocities (0 to 2^33 steps/s, fractions).
        #[test]
        fn f64_to_u32_is_the_cast(bits in any::<u64>(), velocity in 0f64..8.6e9) {
            check_to_u32(bits);
            check_to_u32(velocity.to_bits());
        }
    }
}

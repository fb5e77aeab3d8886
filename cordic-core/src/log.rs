//! QLOG and QEXP: base-2 logarithm and exponential in 5.27 fixed point.
//!
//! The chip computes these with its hyperbolic CORDIC mode; the exact bits
//! of its results are not published beyond a few values, so cogstep computes
//! the mathematically correct result and rounds it to nearest (at most 1 LSB
//! off, measured in the tests). The silicon value QLOG(256) = $4000_0000 is
//! reproduced exactly, as is every power of two.

use crate::tables::EXP2_BIT_Q62;

/// Fraction bits of the 5.27 log format.
const FRAC_BITS: u32 = 27;

/// QLOG: log2(`value`) as unsigned 5.27 fixed point (the whole part in the top
/// 5 bits). `qlog(0)` is defined as 0, as is `qlog(1)`; values above
/// 2^32 − 2^5 (whose log rounds to 32.0, which 5.27 cannot hold) give `u32::MAX`.
///
/// ```
/// assert_eq!(cordic_core::qlog(256), 0x4000_0000); // 8.0
/// ```
pub fn qlog(value: u32) -> u32 {
    if value == 0 {
        return 0;
    }
    let whole = 31 - value.leading_zeros();
    // Mantissa in [1, 2) as 2.62 fixed point; each squaring yields one bit.
    let mut mantissa = u64::from(value) << (62 - whole);
    let mut fraction: u32 = 0;
    // One extra bit for rounding; the rest of the tail decides ties upward.
    for _ in 0..=FRAC_BITS {
        let square = (u128::from(mantissa) * u128::from(mantissa)) >> 62;
        fraction <<= 1;
        if square >= 1 << 63 {
            fraction |= 1;
            mantissa = (square >> 1) as u64;
        } else {
            mantissa = square as u64;
        }
    }
    let rounded = (fraction + 1) >> 1;
    // A fraction that rounds up to 1.0 carries into the whole part; only
    // log2 of values just below 2^32 would round to 32.0, which saturates.
    (whole << FRAC_BITS).saturating_add(rounded)
}

/// QEXP: 2^x for `value` = x as unsigned 5.27 fixed point, rounded to nearest.
/// The result always fits: at most 2^31.99999999 < 2^32.
///
/// ```
/// assert_eq!(cordic_core::qexp(0x4000_0000), 256);
/// assert_eq!(cordic_core::qexp(cordic_core::qlog(1_000_000)), 1_000_000);
/// ```
pub fn qexp(value: u32) -> u32 {
    let whole = value >> FRAC_BITS;
    let fraction = value & ((1 << FRAC_BITS) - 1);
    // 2^fraction as the product of 2^(2^-j) over its set bits, in 2.62.
    let mut power: u64 = 1 << 62;
    for (j, &factor) in EXP2_BIT_Q62.iter().enumerate() {
        if fraction & (1 << (FRAC_BITS - 1 - j as u32)) != 0 {
            power = ((u128::from(power) * u128::from(factor) + (1 << 61)) >> 62) as u64;
        }
    }
    let shift = 62 - whole;
    ((power + (1 << (shift - 1))) >> shift).min(u64::from(u32::MAX)) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn silicon_qlog_256() {
        assert_eq!(qlog(256), 0x4000_0000);
    }

    #[test]
    fn powers_of_two_are_exact() {
        for bit in 0..32 {
            assert_eq!(qlog(1 << bit), bit << FRAC_BITS);
            assert_eq!(qexp(bit << FRAC_BITS), 1 << bit);
        }
    }

    #[test]
    fn extremes_do_not_panic() {
        assert_eq!(qlog(u32::MAX), u32::MAX); // log2(2^32 - 1) would round to 32.0
        assert_eq!(qexp(u32::MAX), 4_294_967_274); // 2^31.9999999925
        assert_eq!(qlog(0), 0);
    }
}

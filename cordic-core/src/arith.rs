//! QMUL, QDIV, QFRAC and QSQRT: the solver's exact integer commands.
//!
//! On the chip these also run through the CORDIC pipeline (and take its 55
//! clocks); their results are exact, so here they are plain integer
//! arithmetic. Edge cases the silicon defines by construction (division by
//! zero, quotients wider than 32 bits) are given fixed, documented results.

/// QMUL: the unsigned 64-bit product of `d` and `s`, as (low 32 bits, high 32 bits)
/// (GETQX gives the low half, GETQY the high half).
///
/// ```
/// assert_eq!(cordic_core::qmul(0xFFFF_FFFF, 0xFFFF_FFFF), (1, 0xFFFF_FFFE));
/// ```
#[inline]
pub fn qmul(d: u32, s: u32) -> (u32, u32) {
    let product = u64::from(d) * u64::from(s);
    (product as u32, (product >> 32) as u32)
}

/// QDIV with `SETQ` high: divides the 64-bit `dividend` by `divisor`,
/// returning (quotient, remainder).
///
/// Defined results where the exact quotient does not fit:
/// - `divisor == 0`: quotient `u32::MAX`, remainder the low 32 bits of the dividend;
/// - quotient above `u32::MAX`: quotient saturates to `u32::MAX`, the remainder
///   is the true remainder `dividend % divisor`.
///
/// ```
/// assert_eq!(cordic_core::qdiv(0x8000_0000, 0x8000_0000), (1, 0));
/// assert_eq!(cordic_core::qdiv(200_000_000, 50_000), (4_000, 0));
/// ```
#[inline]
pub fn qdiv(dividend: u64, divisor: u32) -> (u32, u32) {
    if divisor == 0 {
        return (u32::MAX, dividend as u32);
    }
    let divisor = u64::from(divisor);
    let (quotient, remainder) = (dividend / divisor, dividend % divisor);
    (quotient.min(u64::from(u32::MAX)) as u32, remainder as u32)
}

/// QFRAC: divides `{d:0}` (that is, `d · 2^32`) by `s`, returning (quotient,
/// remainder): the fraction d/s as 0.32 fixed point when d < s. Same defined
/// results as [`qdiv`] for `s == 0` and for quotients above `u32::MAX`.
///
/// ```
/// assert_eq!(cordic_core::qfrac(1, 4), (0x4000_0000, 0));
/// ```
#[inline]
pub fn qfrac(d: u32, s: u32) -> (u32, u32) {
    qdiv(u64::from(d) << 32, s)
}

/// QSQRT: the square root of a 64-bit value, rounded down (exact for every input).
///
/// ```
/// assert_eq!(cordic_core::qsqrt(u64::MAX), u32::MAX);
/// assert_eq!(cordic_core::qsqrt(99), 9);
/// ```
#[inline]
pub fn qsqrt(value: u64) -> u32 {
    value.isqrt() as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn division_edge_cases_are_defined() {
        assert_eq!(qdiv(1234, 0), (u32::MAX, 1234));
        assert_eq!(qdiv(u64::MAX, 1), (u32::MAX, 0));
        assert_eq!(qdiv(u64::MAX, 3), (u32::MAX, 0));
        assert_eq!(qfrac(5, 0), (u32::MAX, 0));
        assert_eq!(qfrac(1, 1), (u32::MAX, 0));
    }

    proptest! {
        #[test]
        fn qdiv_is_exact(dividend: u64, divisor in 1u32..) {
            let (q, r) = qdiv(dividend, divisor);
            let exact = dividend / u64::from(divisor);
            if exact <= u64::from(u32::MAX) {
                prop_assert_eq!(u64::from(q) * u64::from(divisor) + u64::from(r), dividend);
                prop_assert!(r < divisor);
            } else {
                prop_assert_eq!(q, u32::MAX);
            }
        }

        #[test]
        fn qmul_is_exact(d: u32, s: u32) {
            let (lo, hi) = qmul(d, s);
            prop_assert_eq!(u64::from(hi) << 32 | u64::from(lo), u64::from(d) * u64::from(s));
        }

        #[test]
        fn qsqrt_is_the_floor(value: u64) {
            let root = u64::from(qsqrt(value));
            prop_assert!(root * root <= value);
            prop_assert!((root + 1).checked_mul(root + 1).is_none_or(|sq| sq > value));
        }
    }
}

//! The high half of a 64 × 64-bit product: the emulated CORDIC's
//! fixed-point products and the Smooth cosine recurrence's one
//! multiplication a ramp step (`cogstep-motion`).
//!
//! A host multiplies in 128 bits in a few instructions. A Cortex-M0+ has
//! only a 32 × 32 → 32-bit multiply: Rust's 128-bit product there is a
//! chain of `__aeabi_lmul` library calls (each a 64 × 64 → 64-bit product
//! from 32-bit pieces, behind a call and its spills). There the functions
//! here build the same bits from four 32 × 32 → 64-bit products, each of
//! four 16-bit ones, inline. Integer arithmetic is exact: every target gets
//! the bits the 128-bit product gives (the tests compare them).

/// ARMv6-M (the Cortex-M0+ of the Raspberry Pi Pico): no widening multiply.
/// It is the one ARM profile among Rust's targets without 32-bit atomics,
/// which is what this names it by.
macro_rules! if_no_widening_multiply {
    ($by_parts:expr, $wide:expr) => {{
        #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
        let value = $by_parts;
        #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
        let value = $wide;
        value
    }};
}

/// `(a·b) >> 64` of the exact 128-bit product (rounded down, as the
/// arithmetic shift of the `i128` product gives).
#[inline(always)]
pub fn mul_high_i64(a: i64, b: i64) -> i64 {
    if_no_widening_multiply!(
        mul_i64_wide_by_parts(a, b, mul_u32_wide_by_halves).0,
        ((i128::from(a) * i128::from(b)) >> 64) as i64
    )
}

/// `(a·b) >> 64` of the exact unsigned 128-bit product.
#[inline(always)]
pub fn mul_high_u64(a: u64, b: u64) -> u64 {
    if_no_widening_multiply!(
        mul_u64_wide_by_parts(a, b, mul_u32_wide_by_halves).0,
        ((u128::from(a) * u128::from(b)) >> 64) as u64
    )
}

/// `a·b` exactly (a 32 × 32 → 64-bit product).
#[inline(always)]
pub fn mul_u32_wide(a: u32, b: u32) -> u64 {
    if_no_widening_multiply!(mul_u32_wide_by_halves(a, b), u64::from(a) * u64::from(b))
}

/// The exact 128-bit product `a·b` as its (high, low) 64-bit halves: the
/// high half rounded down, as [`mul_high_i64`] gives it.
#[inline(always)]
pub fn mul_i64_wide(a: i64, b: i64) -> (i64, u64) {
    if_no_widening_multiply!(mul_i64_wide_by_parts(a, b, mul_u32_wide_by_halves), {
        let product = i128::from(a) * i128::from(b);
        ((product >> 64) as i64, product as u64)
    })
}

/// The unsigned 128-bit product `a·b` as its (high, low) halves, from
/// 32 × 32 → 64-bit products `mul`.
#[inline(always)]
pub fn mul_u64_wide_by_parts(a: u64, b: u64, mul: impl Fn(u32, u32) -> u64) -> (u64, u64) {
    let (a0, a1) = (a as u32, (a >> 32) as u32);
    let (b0, b1) = (b as u32, (b >> 32) as u32);
    let low = mul(a0, b0);
    let cross_a = mul(a0, b1);
    let cross_b = mul(a1, b0);
    let high = mul(a1, b1);
    // Below 3·2^32: no overflow.
    let middle = (low >> 32) + (cross_a & 0xFFFF_FFFF) + (cross_b & 0xFFFF_FFFF);
    // The exact high half is below 2^64: no overflow either.
    let top = high + (cross_a >> 32) + (cross_b >> 32) + (middle >> 32);
    (top, (middle << 32) | (low & 0xFFFF_FFFF))
}

/// [`mul_i64_wide`] from 32 × 32 → 64-bit products `mul`: the unsigned
/// product, then the two's complement corrections to its high half (a
/// negative factor stands for itself plus 2^64, which adds the other
/// factor to the high half).
#[inline(always)]
pub fn mul_i64_wide_by_parts(a: i64, b: i64, mul: impl Fn(u32, u32) -> u64) -> (i64, u64) {
    let (ua, ub) = (a as u64, b as u64);
    let (mut high, low) = mul_u64_wide_by_parts(ua, ub, mul);
    if a < 0 {
        high = high.wrapping_sub(ub);
    }
    if b < 0 {
        high = high.wrapping_sub(ua);
    }
    (high as i64, low)
}

/// `a·b` exactly, from four 16 × 16 → 32-bit products (one `MULS` each on a
/// Cortex-M0+).
#[inline(always)]
pub fn mul_u32_wide_by_halves(a: u32, b: u32) -> u64 {
    let (a0, a1) = (a & 0xFFFF, a >> 16);
    let (b0, b1) = (b & 0xFFFF, b >> 16);
    let low = a0 * b0;
    let high = a1 * b1;
    // Each below 2^32; their sum below 2^33.
    let middle = u64::from(a0 * b1) + u64::from(a1 * b0);
    ((u64::from(high) << 32) | u64::from(low)) + (middle << 16)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn reference(a: i64, b: i64) -> i64 {
        ((i128::from(a) * i128::from(b)) >> 64) as i64
    }

    fn check(a: i64, b: i64) {
        let product = i128::from(a) * i128::from(b);
        let wide = ((product >> 64) as i64, product as u64);
        assert_eq!(
            mul_i64_wide_by_parts(a, b, mul_u32_wide_by_halves),
            wide,
            "{a} × {b}"
        );
        assert_eq!(
            mul_i64_wide_by_parts(a, b, |x, y| u64::from(x) * u64::from(y)),
            wide,
            "{a} × {b}"
        );
        assert_eq!(mul_i64_wide(a, b), wide, "{a} × {b}");
        assert_eq!(mul_high_i64(a, b), reference(a, b), "{a} × {b}");
        let (ua, ub) = (a as u64, b as u64);
        let unsigned = u128::from(ua) * u128::from(ub);
        let unsigned_wide = ((unsigned >> 64) as u64, unsigned as u64);
        assert_eq!(
            mul_u64_wide_by_parts(ua, ub, mul_u32_wide_by_halves),
            unsigned_wide,
            "{ua} × {ub}"
        );
        assert_eq!(mul_high_u64(ua, ub), unsigned_wide.0, "{ua} × {ub}");
    }

    #[test]
    fn extremes_match_i128() {
        let values = [
            0,
            1,
            -1,
            2,
            -2,
            i64::MAX,
            i64::MIN,
            i64::MIN + 1,
            u32::MAX as i64,
            -(u32::MAX as i64),
            1 << 32,
            -(1 << 32),
            1 << 61,
            (1 << 62) - 1,
            -(1 << 62),
            0x0000_FFFF_FFFF_0000,
            -0x0000_FFFF_FFFF_0000,
        ];
        for a in values {
            for b in values {
                check(a, b);
            }
        }
    }

    #[test]
    fn halves_multiply_like_u64() {
        for a in [
            0,
            1,
            0xFFFF,
            0x1_0000,
            0xFFFF_FFFF,
            0x8000_0000,
            0x1234_5678,
        ] {
            for b in [
                0,
                1,
                0xFFFF,
                0x1_0000,
                0xFFFF_FFFF,
                0x8000_0000,
                0x9ABC_DEF0,
            ] {
                assert_eq!(mul_u32_wide_by_halves(a, b), u64::from(a) * u64::from(b));
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2_000))]

        #[test]
        fn high_halves_match_i128(a in any::<i64>(), b in any::<i64>()) {
            check(a, b);
        }

        /// The recurrence's range: a cosine in 2.62 (either sign) by a
        /// mantissa in 2^61..2^62.
        #[test]
        fn recurrence_products_match_i128(c in -(1i64 << 62)..=(1 << 62), d in (1i64 << 61)..(1 << 62)) {
            check(c, d);
        }

        #[test]
        fn wide_halves_match_u64(a in any::<u32>(), b in any::<u32>()) {
            prop_assert_eq!(mul_u32_wide_by_halves(a, b), u64::from(a) * u64::from(b));
            prop_assert_eq!(mul_u32_wide(a, b), u64::from(a) * u64::from(b));
        }
    }
}

//! The high half of a 64 × 64-bit product: the emulated CORDIC's
//! fixed-point products and the Smooth cosine recurrence's one
//! multiplication a ramp step (`cogstep-motion`).
//!
//! A host multiplies in 128 bits in a few instructions. A Cortex-M0+ has
//! only a 32 × 32 → 32-bit multiply: Rust's 128-bit product there is a
//! chain of `__aeabi_lmul` library calls (each a 64 × 64 → 64-bit product
//! from 32-bit pieces, behind a call and its spills). There the functions
//! here build the same bits from four 32 × 32 → 64-bit products, each of
//! four 16-bit ones: inline, or by a call to a routine written for the
//! M0+'s registers ([`mul_high_u64_by_call`]). Integer arithmetic is
//! exact: every target gets the bits the 128-bit product gives (the tests
//! compare them).

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

/// [`mul_high_u64`] by a call, not inline: on ARMv6-M a routine written
/// for its eight low registers (`mul_u64_high_armv6m`), elsewhere
/// [`mul_high_u64`] itself. For a loop that leaves an inline product no
/// registers: the Smooth ramp's cosine recurrence (four words of state a
/// chain), where the compiler's inline product, sign and shift took about
/// 210 cycles under rp2040py and the routine takes about 110 with its
/// call. Where the surroundings are light the inline product is the faster
/// (the CORDIC's rotations: a P2Exact ramp step took 1,887 cycles with the
/// routine in them, 1,860 inline).
#[inline(always)]
pub fn mul_high_u64_by_call(a: u64, b: u64) -> u64 {
    if_no_widening_multiply!(mul_u64_high_armv6m(a, b), mul_high_u64(a, b))
}

/// The high half of `a·b` for a signed `a` and a non-negative `b`, from
/// the unsigned product's high half `unsigned_high` ([`mul_high_u64`] or
/// [`mul_high_u64_by_call`] of `a as u64` and `b`): less `b` where `a` is
/// negative (its unsigned reading is a + 2^64). One correction of the two
/// a signed product needs, without a branch.
#[inline(always)]
pub fn high_of_signed_by_unsigned(a: i64, b: u64, unsigned_high: u64) -> i64 {
    unsigned_high.wrapping_sub(b & (a >> 63) as u64) as i64
}

/// [`mul_high_u64`] on ARMv6-M, by hand: the same four 32 × 32 → 64-bit
/// products as the tests' `mul_u64_high_by_limbs` (each of four `MULS`), added in
/// as they are made with the carries in the flags, in the eight low
/// registers with two words on the stack. Under rp2040py it takes about
/// 110 cycles a call; the compiler's code for the same sum (with the
/// sign's correction and the shift of the cosine recurrence, a function of
/// their own) took about 210, spilling its partial products to the stack.
/// The Smooth ramp's cosine recurrence makes one a step. Its bits are
/// checked where it runs: the Pico's ramps are compared edge for edge, to
/// the cycle, with the host's (`tests/tests/firmware_pico*.rs`), whose
/// cosines come from the `u128` product; the limb algorithm it follows is
/// tested on the host against `u128`.
#[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
#[unsafe(naked)]
extern "C" fn mul_u64_high_armv6m(a: u64, b: u64) -> u64 {
    // a = r1:r0, b = r3:r2 (AAPCS); the result in r1:r0.
    // UMUL x, y, lo, t1, t2: (lo, x) = x·y, 32 × 32 → 64; y, t1 and t2
    // clobbered.
    core::arch::naked_asm!(
        ".macro UMUL x, y, lo, t1, t2",
        r"uxth \t1, \x",
        r"lsrs \x, \x, #16",
        r"uxth \t2, \y",
        r"lsrs \y, \y, #16",
        r"mov \lo, \t1",
        r"muls \lo, \t2, \lo",
        r"muls \t1, \y, \t1",
        r"muls \t2, \x, \t2",
        r"muls \x, \y, \x",
        // The middle sum's carry is 2^48 of the product.
        r"adds \t1, \t1, \t2",
        r"movs \t2, #0",
        r"adcs \t2, \t2, \t2",
        r"lsls \t2, \t2, #16",
        r"adds \x, \x, \t2",
        r"lsls \t2, \t1, #16",
        r"lsrs \t1, \t1, #16",
        r"adds \lo, \lo, \t2",
        r"adcs \x, \x, \t1",
        ".endm",
        "push {{r4, r5, r6, r7, lr}}",
        // a1 and b1 kept on the stack.
        "push {{r1, r3}}",
        // a0·b0: its high word only (r4).
        "mov r4, r0",
        "mov r5, r2",
        "UMUL r4, r5, r6, r7, r1",
        // a0·b1 = (r5, r0); word 1 = h00 + l01, its carry in r3.
        "UMUL r0, r3, r5, r6, r7",
        "adds r4, r4, r5",
        "movs r3, #0",
        "adcs r3, r3, r3",
        // a1·b0 = (r5, r2); word 1 += l10, the carries (0 to 2) in r3.
        "ldr r1, [sp, #0]",
        "UMUL r2, r1, r5, r6, r7",
        "adds r4, r4, r5",
        "movs r5, #0",
        "adcs r3, r3, r5",
        // Word 2 = h01 + h10 + carries (+ l11 below), its carries in r2.
        "adds r0, r0, r2",
        "movs r2, #0",
        "adcs r2, r2, r2",
        "adds r0, r0, r3",
        "adcs r2, r2, r5",
        // a1·b1 = (r4, r1); word 2 += l11; word 3 = h11 + the carries.
        "ldr r1, [sp, #0]",
        "ldr r3, [sp, #4]",
        "UMUL r1, r3, r4, r6, r7",
        "adds r0, r0, r4",
        "adcs r1, r1, r2",
        "add sp, #8",
        "pop {{r4, r5, r6, r7, pc}}",
        ".purgem UMUL",
    )
}

/// `value >> shift` (arithmetic, `shift` in 0..64): inline on 32-bit
/// words where the core has no 64-bit shift (a Cortex-M0+ calls
/// `__aeabi_lasr` for it).
#[inline(always)]
pub fn shift_right_i64(value: i64, shift: u32) -> i64 {
    debug_assert!(shift < 64);
    if_no_widening_multiply!(shift_right_i64_by_words(value, shift), value >> shift)
}

/// [`shift_right_i64`] on 32-bit words.
#[inline(always)]
pub fn shift_right_i64_by_words(value: i64, shift: u32) -> i64 {
    let (low, high) = (value as u32, (value >> 32) as i32);
    let (low, high) = if shift >= 32 {
        ((high >> (shift - 32)) as u32, high >> 31)
    } else if shift == 0 {
        (low, high)
    } else {
        (
            (low >> shift) | ((high as u32) << (32 - shift)),
            high >> shift,
        )
    };
    (i64::from(high) << 32) | i64::from(low)
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

    /// `a·b` exactly as its (low, high) 32-bit words, from four 16 × 16 →
    /// 32-bit products with the carries taken one 32-bit addition at a
    /// time.
    fn mul_u32_limbs(a: u32, b: u32) -> (u32, u32) {
        let (a0, a1) = (a & 0xFFFF, a >> 16);
        let (b0, b1) = (b & 0xFFFF, b >> 16);
        let (middle, middle_carry) = (a0 * b1).overflowing_add(a1 * b0);
        let (low, low_carry) = (a0 * b0).overflowing_add(middle << 16);
        // The exact product is below 2^64: the high word does not overflow.
        let high = (a1 * b1)
            .wrapping_add((u32::from(middle_carry) << 16) | (middle >> 16))
            .wrapping_add(u32::from(low_carry));
        (low, high)
    }

    /// The M0+'s routine (`mul_u64_high_armv6m`), step for step in Rust: the
    /// four 32 × 32 → 64-bit products, the lowest one's low word never
    /// formed, only its carry; the carries summed into words 2 and 3.
    fn mul_u64_high_by_limbs(a: u64, b: u64) -> u64 {
        let (a0, a1) = (a as u32, (a >> 32) as u32);
        let (b0, b1) = (b as u32, (b >> 32) as u32);
        let (_, low_high) = mul_u32_limbs(a0, b0);
        let (cross_a_low, cross_a_high) = mul_u32_limbs(a0, b1);
        let (cross_b_low, cross_b_high) = mul_u32_limbs(a1, b0);
        let (top_low, top_high) = mul_u32_limbs(a1, b1);
        // Word 1's carries (0 to 2) into word 2.
        let (w1, carry_a) = low_high.overflowing_add(cross_a_low);
        let (_, carry_b) = w1.overflowing_add(cross_b_low);
        let carry = u32::from(carry_a) + u32::from(carry_b);
        // Words 2 and 3: the product is below 2^128, so word 3 does not
        // overflow.
        let (w2, carry_a) = top_low.overflowing_add(cross_a_high);
        let (w2, carry_b) = w2.overflowing_add(cross_b_high);
        let (w2, carry_c) = w2.overflowing_add(carry);
        let w3 = top_high
            .wrapping_add(u32::from(carry_a))
            .wrapping_add(u32::from(carry_b))
            .wrapping_add(u32::from(carry_c));
        (u64::from(w3) << 32) | u64::from(w2)
    }

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
        assert_eq!(
            high_of_signed_by_unsigned(
                a,
                ub & (u64::MAX >> 1),
                mul_high_u64(ua, ub & (u64::MAX >> 1))
            ),
            reference(a, b & i64::MAX),
            "{a} × {}",
            b & i64::MAX
        );
        // The reference of the M0+'s routine.
        assert_eq!(
            mul_u64_high_by_limbs(ua, ub),
            unsigned_wide.0,
            "{ua} × {ub}"
        );
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
                let (low, high) = mul_u32_limbs(a, b);
                assert_eq!(
                    (u64::from(high) << 32) | u64::from(low),
                    u64::from(a) * u64::from(b)
                );
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
        fn word_shifts_match_i64(value in any::<i64>(), shift in 0u32..64) {
            prop_assert_eq!(shift_right_i64_by_words(value, shift), value >> shift);
            prop_assert_eq!(shift_right_i64(value, shift), value >> shift);
        }

        #[test]
        fn wide_halves_match_u64(a in any::<u32>(), b in any::<u32>()) {
            prop_assert_eq!(mul_u32_wide_by_halves(a, b), u64::from(a) * u64::from(b));
            prop_assert_eq!(mul_u32_wide(a, b), u64::from(a) * u64::from(b));
            let (low, high) = mul_u32_limbs(a, b);
            prop_assert_eq!((u64::from(high) << 32) | u64::from(low), u64::from(a) * u64::from(b));
        }
    }
}

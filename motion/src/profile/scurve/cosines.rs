//! Ramp cosines a block at a time ([`CosineBlock`]) and Smooth's cosine
//! recurrence ([`smooth_cosines`]: one multiplication a key, with its error
//! bound).

use cordic_core::cos_sin_q62;
use cordic_core::wide_mul::{
    high_of_signed_by_unsigned, mul_high_u64_by_call, mul_i64_wide, shift_right_i64,
};

use super::planning::ScurveConfig;
use super::ramp::Ramp;
use super::runs::same_words;
use super::smooth::smooth_angle_span;

/// Cosines per block: enough that the CORDIC runs in full blocks, few
/// enough that a short move wastes little.
pub(super) const COSINE_BLOCK: usize = 64;

/// A block of consecutive cosine keys of one ramp, with their rotation
/// angles and the X each rotation gave.
#[derive(Clone, Copy, Debug)]
pub(super) struct CosineBlock {
    /// The ramp the keys belong to (`None`: empty).
    pub(super) ramp: Option<Ramp>,
    pub(super) first: u32,
    pub(super) len: u32,
    pub(super) angles: [u32; COSINE_BLOCK],
    pub(super) cosines: [i32; COSINE_BLOCK],
}

/// Field by field, the arrays a word at a time (see [`same_words`]).
impl PartialEq for CosineBlock {
    fn eq(&self, other: &Self) -> bool {
        // Every field: `same_but_arrays` names each one.
        self.same_but_arrays(other)
            && same_words(&self.angles, &other.angles)
            && same_words(&self.cosines, &other.cosines)
    }
}

impl CosineBlock {
    pub(super) const EMPTY: Self = Self {
        ramp: None,
        first: 0,
        len: 0,
        angles: [0; COSINE_BLOCK],
        cosines: [0; COSINE_BLOCK],
    };

    /// Whether two blocks hold the same keys of the same ramp: then the
    /// same cosines (a block is filled whole from its ramp and first key,
    /// `SCurve::fill_cosines`), whatever the arrays hold past `len`.
    pub(super) fn same_but_arrays(&self, other: &Self) -> bool {
        // Every field named: a new one does not compile until compared.
        let CosineBlock {
            ramp,
            first,
            len,
            angles: _,
            cosines: _,
        } = self;
        *ramp == other.ramp && *first == other.first && *len == other.len
    }

    pub(super) fn holds(&self, ramp: Ramp, key: u32) -> bool {
        self.ramp == Some(ramp) && key.wrapping_sub(self.first) < self.len
    }

    /// (angle, X) of a key the block holds.
    pub(super) fn get(&self, key: u32) -> (u32, i32) {
        let i = (key - self.first) as usize;
        (self.angles[i], self.cosines[i])
    }
}

/// Smooth: the constants of [`smooth_cosines`]' recurrence for a ramp whose
/// positions are Δ apart (Δ < 29°): for one chain over every key, and for
/// two chains side by side, each over every other key (2Δ < 29°), whose
/// multiplications overlap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Recurrence {
    /// Turning by Δ.
    one: Turn,
    /// Turning by 2Δ, when 2Δ < 29°.
    two: Option<Turn>,
}

/// The constants of one turn of the recurrence, by an angle φ < 29°.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Turn {
    /// sin φ in 2.62, within 2^-51.
    sin: i64,
    /// d = 2 − 2·cos φ = 4·sin²(φ/2) as `d_mantissa · 2^-(64 + d_shift)`,
    /// the mantissa in 2^61..2^62 (relative error below 2^-50), so that
    /// `d·c` is one multiplication and two shifts ([`mul_step`]) however
    /// small φ is.
    d_mantissa: i64,
    d_shift: u32,
}

impl Turn {
    /// From sin φ and d in `f64` (each within a few units in the last
    /// place); `None` when d ≥ 1/4 (φ ≥ 29°).
    pub(super) fn new(sin: f64, d: f64) -> Option<Self> {
        if d >= 0.25 {
            return None;
        }
        // d = significand·2^(exponent − 52), significand in 2^52..2^53
        // (d is normal: φ ≥ 2^-33 rad for any u32 ramp).
        let bits = d.to_bits();
        let exponent = ((bits >> 52) & 0x7FF) as i32 - 1023;
        let significand = (bits & ((1 << 52) - 1)) | (1 << 52);
        // d·2^(64 + shift) in 2^61..2^62: shift = −3 − exponent ≥ 0 (d < 1/4).
        let shift = (-3 - exponent) as u32;
        let (d_mantissa, d_shift) = if shift <= 62 {
            ((significand << 9) as i64, shift)
        } else {
            // d < 2^-65: d·c is below 2^-65 and rounds to nothing in 2.62.
            (0, 0)
        };
        Some(Self {
            // sin φ < 1/2: the product is exact and fits.
            sin: (sin * TWO_TO_THE_62) as i64,
            d_mantissa,
            d_shift,
        })
    }

    /// `d·c` in 2.62 for `c` in 2.62, rounded down (within 2^-62).
    #[inline(always)]
    fn d_times(&self, c: i64) -> i64 {
        mul_step(c, self.d_mantissa, self.d_shift)
    }

    /// `(1 − cos φ)·c = d·c/2` in 2.62, rounded down.
    fn half_d_times(&self, c: i64) -> i64 {
        mul_step(c, self.d_mantissa, self.d_shift + 1)
    }

    /// `D(0) = c(0) − c(−1) = c(0)·(1 − cos φ) − sin θ·sin φ` for a chain
    /// anchored at (cos θ, sin θ), 2.62.
    fn first_difference(&self, (cos, sin): (i64, i64)) -> i64 {
        self.half_d_times(cos) - mul_q62(sin, self.sin)
    }

    /// (cos θ, sin θ) turned by φ, 2.62: the input's error plus 2^-61.
    fn turn(&self, (cos, sin): (i64, i64)) -> (i64, i64) {
        (
            cos - self.half_d_times(cos) - mul_q62(sin, self.sin),
            sin - self.half_d_times(sin) + mul_q62(cos, self.sin),
        )
    }
}

impl Recurrence {
    /// The constants for Δ = (180° − offset)/accel_steps, or `None` when
    /// d ≥ 1/4 (Δ ≥ 29°: ramps of at most six positions).
    ///
    /// sin(Δ/2) and cos(Δ/2) come from their Taylor series in `f64` (13
    /// terms each, Δ/2 ≤ 90°: the first term left out is below 2^-60 of
    /// the sum), with `+`, `−` and `×` only: IEEE arithmetic is
    /// exact-rounded, so every target gets the same bits (a
    /// microcontroller's software floating point included). Each is within
    /// a few units in the last place (2^-50 relative); so are `sin Δ =
    /// 2·sin(Δ/2)·cos(Δ/2)`, `d = 4·sin²(Δ/2)`, and for 2Δ, `sin 2Δ =
    /// 2·sin Δ·(1 − d/2)` and `4·sin²Δ`.
    pub(super) fn new(offset_deg: u32, accel_steps: u32) -> Option<Self> {
        let half_step = f64::from(180 - offset_deg) * core::f64::consts::PI
            / (360.0 * f64::from(accel_steps.max(1)));
        let (sin_half, cos_half) = sin_cos_series(half_step);
        let d = 4.0 * sin_half * sin_half;
        let sin = 2.0 * sin_half * cos_half;
        let one = Turn::new(sin, d)?;
        let two = Turn::new(2.0 * sin * (1.0 - 0.5 * d), 4.0 * sin * sin);
        Some(Self { one, two })
    }
}

/// 2^62 as an `f64`.
const TWO_TO_THE_62: f64 = 4_611_686_018_427_387_904.0;

/// (sin x, cos x) for 0 ≤ x ≤ π/2 from their Taylor series, Horner's way,
/// in `f64` additions and multiplications only (the same bits on every
/// target): `sin x = x·(1 − x²/(2·3)·(1 − x²/(4·5)·(…)))`, `cos x = 1 −
/// x²/(1·2)·(1 − x²/(3·4)·(…))`, 13 factors each.
fn sin_cos_series(x: f64) -> (f64, f64) {
    let square = x * x;
    let (mut sin, mut cos) = (1.0, 1.0);
    for n in (1..=13u32).rev() {
        // The reciprocals are exact-rounded constants (a division, once).
        sin = 1.0 - square * (1.0 / f64::from((2 * n) * (2 * n + 1))) * sin;
        cos = 1.0 - square * (1.0 / f64::from((2 * n - 1) * (2 * n))) * cos;
    }
    (x * sin, cos)
}

/// `d·c` in 2.62 for the `d` of a [`Recurrence`] and `c` in 2.62, rounded
/// down (within 2^-62): the high half of one 64 × 64-bit product
/// ([`mul_high_u64_by_call`]: on a Cortex-M0+ 32-bit products by hand,
/// not a chain of library calls).
#[inline(always)]
fn mul_step(c: i64, d_mantissa: i64, d_shift: u32) -> i64 {
    debug_assert!(d_mantissa >= 0);
    // The mantissa is never negative: only the cosine's sign corrects the
    // unsigned product.
    let mantissa = d_mantissa as u64;
    let unsigned = mul_high_u64_by_call(c as u64, mantissa);
    shift_right_i64(high_of_signed_by_unsigned(c, mantissa, unsigned), d_shift)
}

/// One angle unit of [`smooth_angle`] (1/360 of a binary angle unit,
/// 2π/(360·2^32) rad) in radians, 2.62 fixed point: 18,740,330.145, rounded
/// down (the 0.145 left out is at most 27 units of 2^-62 for the ≤ 181
/// units it is ever multiplied by).
///
/// [`smooth_angle`]: super::smooth::smooth_angle
const RADIANS_Q62_PER_UNIT: i64 = 18_740_330;

/// (a·b) / 2^62 for 2.62 fixed-point values, rounded down (the low 64 bits
/// of the 128-bit shift, as `((a·b) >> 62) as i64` keeps them).
#[inline(always)]
fn mul_q62(a: i64, b: i64) -> i64 {
    let (high, low) = mul_i64_wide(a, b);
    ((high as u64) << 2 | low >> 62) as i64
}

/// (cos, sin) in 2.62 of the angle `units + remainder/divisor` in
/// [`smooth_angle`]'s units (360·2^32 a turn; `remainder < divisor`): the
/// nearest binary angle's from [`cos_sin_q62`] (within 2^-41), turned by the
/// rest, |ε| ≤ 181 units < 2^-30.2 rad, to first order (the ε²/2 left out
/// is below 2^-61).
///
/// [`smooth_angle`]: super::smooth::smooth_angle
fn cos_sin_of_units(units: u64, remainder: u64, divisor: u64) -> (i64, i64) {
    let binary = (units + 180) / 360;
    let rest_units = units as i64 - (binary * 360) as i64;
    let epsilon = rest_units * RADIANS_Q62_PER_UNIT
        + (remainder * RADIANS_Q62_PER_UNIT as u64 / divisor.max(1)) as i64;
    let (cos, sin) = cos_sin_q62(binary as u32);
    (cos - mul_q62(epsilon, sin), sin + mul_q62(epsilon, cos))
}

/// Smooth: the binary angles (as [`smooth_angle`]) and cosines (2^30 scale)
/// of the keys `first..first + cosines.len()` of a ramp, all below
/// `accel_steps`.
///
/// The cosines follow the second-order recurrence `c(k+1) = 2·cos Δ·c(k) −
/// c(k−1)` in Reinsch's form, which keeps its precision however small the
/// step Δ between two ramp positions is: with `D(k) = c(k) − c(k−1)` and `d
/// = 2 − 2·cos Δ`,
///
/// ```text
/// D(k+1) = D(k) − d·c(k)        c(k+1) = c(k) + D(k+1)
/// ```
///
/// one multiplication a key (the rotation it replaces took four), anchored
/// at `first`: `c(0) = cos θ_first` from [`cos_sin_of_units`] (within e =
/// 2^-41) and `D(0) = c(0)·d/2 − sin θ_first·sin Δ`.
///
/// Error bound, for n ≤ 63 keys from the anchor, everything in units of
/// 1 (so 2^-30 is one LSB of the result). A perturbation of the start
/// values, ε in c(0) and δ in D(0), reaches c(n) as
/// `ε·cos((n+½)Δ)/cos(Δ/2) + δ·sin(nΔ)/sin Δ`: at most 1.15·ε (Δ < 29°) and
/// n·δ. Here ε ≤ e and δ ≤ e·(d/2 + sin Δ) + 2^-50 (the anchor's sine times
/// sin Δ, its cosine times d/2, and the constants' own errors), and n·(d/2 +
/// sin Δ) ≤ nΔ·(1 + Δ) < 2·π·1.6 (as nΔ < 180°), so the start contributes
/// below 12·e. Each step's product is rounded down (2^-62) and the
/// constants are within 2^-50 relative: together below 2^-47 over 63 keys.
/// So every cosine is within 2^-37 < 0.01 LSB of the exact 2^30·cos θ_k
/// before it is rounded, within 0.51 LSB after (tested against `f64`).
///
/// Where 2Δ < 29° too, two such chains run side by side, each turning by
/// 2Δ, on the even and the odd keys (so that their multiplications
/// overlap); the odd chain's anchor is the even one's turned by Δ, within
/// 1.6·e, and each chain takes at most 31 turns with n·2Δ < 180°: the same
/// bound holds. Ramps of six positions or fewer (Δ ≥ 29°) take each cosine
/// from its own anchor.
///
/// [`smooth_angle`]: super::smooth::smooth_angle
pub(super) fn smooth_cosines(
    config: &ScurveConfig,
    ramp: Ramp,
    first: u32,
    angles: &mut [u32],
    cosines: &mut [i32],
) {
    debug_assert!(first as usize + cosines.len() <= ramp.accel_steps as usize);
    let asteps = u64::from(ramp.accel_steps.max(1));
    let offset_units = u64::from(config.offset_deg) << 32;
    let (span, divisor) = smooth_angle_span(config.offset_deg, ramp.accel_steps);
    // The exact angle of the first key, first·span/asteps = quotient +
    // remainder/asteps units past the offset: one division a block.
    let (quotient, remainder) = div_rem_wide(u128::from(span) * u128::from(first), asteps);
    // smooth_angle's floor((offset + floor(k·span/asteps) + 180)/360) is
    // floor((k·span + (offset + 180)·asteps) / (360·asteps)): stepped, from
    // the first key's, which is floor((offset + quotient + 180)/360) with the
    // rest (that sum mod 360)·asteps + remainder.
    let whole = offset_units + quotient + 180;
    let (angle, angle_rest) = (whole / 360, whole % 360 * asteps + remainder);
    // Two chains, on the even and the odd keys ([`two_chains`]).
    let advance = |(angle, rest): (u64, u64), (step, step_rest): (u64, u64)| {
        let rest = rest + step_rest;
        if rest >= divisor {
            (angle + step + 1, rest - divisor)
        } else {
            (angle + step, rest)
        }
    };
    let [one, two] = ramp.angle_steps;
    let chains = [(angle, angle_rest), advance((angle, angle_rest), one)];
    two_chains(
        chains,
        angles,
        |&(angle, _)| angle as u32,
        |chain| advance(chain, two),
    );
    let Some(recurrence) = ramp.recurrence else {
        // A short ramp: each key from its own anchor.
        let (mut units, mut rest) = (offset_units + quotient, remainder);
        let (units_step, rest_step) = (span / asteps, span % asteps);
        for cosine in cosines.iter_mut() {
            *cosine = round_q62_to_q30(cos_sin_of_units(units, rest, asteps).0);
            units += units_step;
            rest += rest_step;
            if rest >= asteps {
                rest -= asteps;
                units += 1;
            }
        }
        return;
    };
    let anchor = cos_sin_of_units(offset_units + quotient, remainder, asteps);
    let Some(two) = recurrence.two else {
        // One chain.
        let one = recurrence.one;
        let mut difference = one.first_difference(anchor);
        let mut cos = anchor.0;
        for cosine in cosines.iter_mut() {
            *cosine = round_q62_to_q30(cos);
            difference -= one.d_times(cos);
            cos += difference;
        }
        return;
    };
    // Two chains turning by 2Δ, on the even and the odd keys
    // ([`two_chains`]); the odd chain's anchor is the even one's turned by
    // Δ (within 2^-40).
    let odd_anchor = recurrence.one.turn(anchor);
    let chains = [
        (anchor.0, two.first_difference(anchor)),
        (odd_anchor.0, two.first_difference(odd_anchor)),
    ];
    two_chains(
        chains,
        cosines,
        |&(cos, _)| round_q62_to_q30(cos),
        |(cos, difference)| {
            let difference = difference - two.d_times(cos);
            (cos + difference, difference)
        },
    );
}

/// Fills `out` from two chains, the even entries from the first and the
/// odd from the second: each entry is `value` of its chain, which then
/// takes a `step`. A host runs the chains side by side, so that their
/// short dependency chains overlap; a core without a widening multiply (a
/// Cortex-M0+) runs out of registers holding both chains' state (the
/// cosines' are four words each) and spills at every step, so there it
/// runs one chain over its entries, then the other. The chains never touch:
/// every target gets the same entries (tested).
#[inline(always)]
fn two_chains<T: Copy, O>(
    chains: [T; 2],
    out: &mut [O],
    value: impl Fn(&T) -> O,
    step: impl Fn(T) -> T,
) {
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    two_chains_side_by_side(chains, out, value, step);
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    two_chains_in_turn(chains, out, value, step);
}

/// [`two_chains`], the chains side by side.
#[cfg(any(test, target_arch = "x86_64", target_arch = "aarch64"))]
#[inline(always)]
fn two_chains_side_by_side<T: Copy, O>(
    mut chains: [T; 2],
    out: &mut [O],
    value: impl Fn(&T) -> O,
    step: impl Fn(T) -> T,
) {
    let mut pairs = out.chunks_exact_mut(2);
    for pair in &mut pairs {
        for (entry, chain) in pair.iter_mut().zip(&mut chains) {
            *entry = value(chain);
            *chain = step(*chain);
        }
    }
    if let [last] = pairs.into_remainder() {
        *last = value(&chains[0]);
    }
}

/// [`two_chains`], one chain after the other.
#[cfg(any(test, not(any(target_arch = "x86_64", target_arch = "aarch64"))))]
#[inline(always)]
fn two_chains_in_turn<T: Copy, O>(
    chains: [T; 2],
    out: &mut [O],
    value: impl Fn(&T) -> O,
    step: impl Fn(T) -> T,
) {
    for (parity, mut chain) in chains.into_iter().enumerate() {
        for entry in out.iter_mut().skip(parity).step_by(2) {
            *entry = value(&chain);
            chain = step(chain);
        }
    }
}

/// (quotient, remainder) of a 128-bit value by a 64-bit one whose quotient
/// fits 64 bits, in 64-bit arithmetic where the value fits (every ramp
/// below 2^23 positions): a 128-bit division is a slow library call.
#[inline(always)]
fn div_rem_wide(value: u128, divisor: u64) -> (u64, u64) {
    match u64::try_from(value) {
        Ok(value) => (value / divisor, value % divisor),
        Err(_) => (
            (value / u128::from(divisor)) as u64,
            (value % u128::from(divisor)) as u64,
        ),
    }
}

/// A 2.62 value to 2^30 scale, rounded half up.
#[inline(always)]
fn round_q62_to_q30(value: i64) -> i32 {
    ((value + (1 << 31)) >> 32) as i32
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// The M0+'s order (one chain, then the other) gives the entries
        /// the host's (side by side) gives, for the cosine recurrence's
        /// own step on random states and any block length.
        #[test]
        fn chains_in_turn_give_the_entries_side_by_side_gives(
            states in proptest::array::uniform2((-(1i64 << 62)..=(1 << 62), -(1i64 << 40)..(1 << 40))),
            mantissa in (1i64 << 61)..(1 << 62),
            shift in 0u32..40,
            len in 0usize..=COSINE_BLOCK,
        ) {
            let step = |(cos, difference): (i64, i64)| {
                let difference = difference - mul_step(cos, mantissa, shift);
                (cos.wrapping_add(difference), difference)
            };
            let value = |&(cos, _): &(i64, i64)| round_q62_to_q30(cos);
            let mut side_by_side = [0; COSINE_BLOCK];
            let mut in_turn = [1; COSINE_BLOCK];
            two_chains_side_by_side(states, &mut side_by_side[..len], value, step);
            two_chains_in_turn(states, &mut in_turn[..len], value, step);
            prop_assert_eq!(&side_by_side[..len], &in_turn[..len]);
        }
    }
}

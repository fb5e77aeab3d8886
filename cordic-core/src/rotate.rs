//! QROTATE and QVECTOR: the circular CORDIC, rotating and vectoring.
//!
//! # QROTATE
//!
//! The rotation of (x, y) by θ is (x, y) times the unit vector (cos θ, sin θ),
//! so the CORDIC runs once per angle on a unit vector and the operand is
//! multiplied in at the end (rotation is linear: this is the same function as
//! feeding (x, y) through the iteration). In order:
//!
//! 1. **Quadrant.** The nearest multiple of 90° is turned exactly at the end
//!    (a swap and negations), leaving at most ±45° for the iteration.
//! 2. **Coarse stage, exact in 32 bits.** The first 8 shift-and-add
//!    iterations start from (2^28, 0); they shift right by 0 + 1 + … + 7 = 28
//!    bits in all, so no bit is ever shifted out and the stage is exact. Its
//!    angle runs in `i32` (2^33 = 360°); the rounding of that short table is
//!    summed apart so that the angle left over is known exactly.
//! 3. **Fine stage, 2.62 fixed point in 64 bits**, iterations 8 to
//!    `ROTATE_ITERATIONS` − 1 (10 iterations in all). After them the angle
//!    still to turn, z, is below atan 2^-9 ≈ 0.11°.
//! 4. **Residual.** One last small rotation by z, with cos z and sin z to
//!    third order: (1 − z²/2, z − z³/6). Its error is below z⁴/24 < 2^-40.5
//!    of the length, 0.002 LSB for the longest vector (where a first-order
//!    step, (1, z), would need 21 iterations for the same error).
//! 5. **Gain and operand.** The iterations lengthen the vector by
//!    K ≈ 1.6468; the operand is scaled by 1/K (one multiply per component,
//!    to 2^-32 of an LSB), multiplied with the vector in 128 bits, and rounded
//!    to nearest, as the silicon does.
//!
//! Each iteration is branch free (the direction of a turn is a sign mask), so
//! random angles cost no mispredicted branches.
//!
//! [`cos_batch`] gives the same bits another way: a 513-entry table of
//! cosines over a quarter turn and a third-order correction (error below
//! 2^-41 of the radius), falling back to [`qrotate`] for the few angles whose
//! value lies within 1/64 LSB of a rounding boundary, where the two could
//! round apart.
//!
//! # QVECTOR
//!
//! The textbook vectoring iteration (40 steps) on `i64` values normalised so
//! that the larger component lies in [2^60, 2^61): the angle depends only on
//! the direction, so even (1, 1) gets a full-precision angle. The angle is
//! kept in "wide" binary units (2^64 = 360°) so the table of arctangents adds
//! no error of its own; the gain is taken out at the end with one 64-bit
//! multiply, then both results are rounded to nearest.

use crate::tables::{
    ATAN_WIDE, COS_TABLE_Q62, INV_GAIN_Q64, ROTATE_INV_GAIN_Q62, ROTATE_ITERATIONS, TWO_PI_Q57,
};
use crate::wide_mul::{high_of_signed_by_unsigned, mul_high_i64, mul_high_u64};

/// Iterations of QROTATE's coarse stage, exact in 32 bits: with 1.0 = 2^28
/// the shifts 0..=7 add up to 28 bits, so none of them drops a set bit.
const COARSE_ITERATIONS: usize = 8;

/// 1.0 in the coarse stage.
const COARSE_ONE: i32 = 1 << 28;

/// The coarse stage's arctangents in "half binary units" (2^33 = 360°):
/// `ATAN_WIDE` rounded to nearest.
const COARSE_ATAN: [i32; COARSE_ITERATIONS] = coarse_atan();

/// What that rounding left out of each entry, in units of 2^4 wide units.
const COARSE_ATAN_ERROR: [i32; COARSE_ITERATIONS] = coarse_atan_error();

/// The sum of [`COARSE_ATAN_ERROR`].
const COARSE_ATAN_ERROR_SUM: i64 = {
    let mut sum = 0;
    let mut i = 0;
    while i < COARSE_ITERATIONS {
        sum += COARSE_ATAN_ERROR[i] as i64;
        i += 1;
    }
    sum
};

const fn coarse_atan() -> [i32; COARSE_ITERATIONS] {
    let mut table = [0; COARSE_ITERATIONS];
    let mut i = 0;
    while i < COARSE_ITERATIONS {
        table[i] = ((ATAN_WIDE[i] + (1 << 30)) >> 31) as i32;
        i += 1;
    }
    table
}

const fn coarse_atan_error() -> [i32; COARSE_ITERATIONS] {
    let mut table = [0; COARSE_ITERATIONS];
    let mut i = 0;
    while i < COARSE_ITERATIONS {
        table[i] = ((ATAN_WIDE[i] - ((COARSE_ATAN[i] as i64) << 31)) >> 4) as i32;
        i += 1;
    }
    table
}

/// The fine stage carries y with this bias, so that it is never negative and
/// a logical shift (which SSE2 has for 64-bit lanes) gives the arithmetic
/// shift plus `Y_BIAS >> i`, a constant.
const Y_BIAS: u64 = 1 << 63;

/// Guard bits below the result's LSB in [`rotate_operand`]'s scaled operand.
const OPERAND_FRACTION_BITS: u32 = 30;

/// 1/3 in 0.64 fixed point, rounded down.
const ONE_THIRD_Q64: i64 = 0x5555_5555_5555_5555;

/// Rotates the vector (`x`, `y`) counter-clockwise by `angle`, a binary angle
/// (2^32 = 360°, `0x4000_0000` = 90°): QROTATE with `SETQ y`.
///
/// The result is the true rotation (gain compensated), rounded to nearest;
/// its error is at most 1 LSB against the exact value (measured: see the
/// crate docs). Components whose exact value falls outside `i32` (possible
/// only for vectors longer than 2^31, such as (`i32::MAX`, `i32::MAX`)
/// rotated by 45°) are **saturated** to `i32::MIN`/`i32::MAX`; nothing wraps
/// and nothing panics.
///
/// ```
/// use cordic_core::qrotate;
/// assert_eq!(qrotate(100, 100, 0x4000_0000), (-100, 100));
/// // As a cosine: rotate (r, 0) and read X.
/// assert_eq!(qrotate(1_000_000, 0, 0x2AAA_AAAB).0, 500_000); // cos 60°
/// ```
#[inline] // so that a caller's y = 0, or an unused Y, leaves out the sine
pub fn qrotate(x: i32, y: i32, angle: u32) -> (i32, i32) {
    let (quadrant, fine) = iterate(angle);
    let cos = fine.turned_cos(quadrant);
    // sin θ = cos(θ − 90°).
    let sin = fine.turned_cos(quadrant.wrapping_sub(1) & 3);
    let (x, y) = (rotate_operand(x), rotate_operand(y));
    (
        round_result(cos.times(x) - sin.times(y)),
        round_result(sin.times(x) + cos.times(y)),
    )
}

/// Cosines of many angles: `cosines[k] = qrotate(radius, 0, angles[k]).0`,
/// bit for bit, that is `radius · cos(angles[k])` rounded to nearest.
///
/// The fast path for a table of step velocities. Each cosine comes from a
/// table of 513 cosines over a quarter turn (2.62 fixed point) and a
/// third-order correction for the ≤ 0.088° to the nearest entry, with no
/// iteration and no branch: its error is below 2^-41 of the radius
/// (0.001 LSB). [`qrotate`]'s own value lies within 0.002 LSB of the exact
/// one, so wherever the fast value is more than a tie margin away from a
/// rounding boundary (x.5), both round to the same integer: 2^-37 of the
/// radius plus 2^-22 LSB, that is `TIE_MARGIN` (1/64 LSB) at full scale,
/// eight times what the two values are ever measured apart. The ~3 % of
/// angles nearer than that at full scale (about one in two million at a
/// radius of 25,000) take [`qrotate`] itself. The result
/// is therefore `qrotate`'s, bit for bit (tested over a million angles),
/// at the cost of a few multiplications.
///
/// # Panics
///
/// If `angles` and `cosines` differ in length.
///
/// ```
/// let mut cosines = [0; 3];
/// cordic_core::cos_batch(1_000, &[0, 0x4000_0000, 0x8000_0000], &mut cosines);
/// assert_eq!(cosines, [1_000, 0, -1_000]);
/// ```
pub fn cos_batch(radius: i32, angles: &[u32], cosines: &mut [i32]) {
    assert_eq!(angles.len(), cosines.len(), "one cosine per angle");
    if radius == i32::MIN {
        // The one radius whose cosine can leave i32 (−2^31 · −1): saturate
        // through the scalar path.
        for (cosine, &angle) in cosines.iter_mut().zip(angles) {
            *cosine = qrotate(radius, 0, angle).0;
        }
        return;
    }
    // |radius| < 2^31: the shifted operand fits, and so does every result.
    let operand = i64::from(radius) << 32;
    let margin = tie_margin(radius);
    for (cosine, &angle) in cosines.iter_mut().zip(angles) {
        let (rounded, near_tie) = table_cos(angle, operand, margin);
        *cosine = if near_tie {
            qrotate(radius, 0, angle).0
        } else {
            rounded
        };
    }
}

/// How close (in 2^-30 LSB) to a rounding boundary [`cos_batch`]'s fast
/// value may come before it asks [`qrotate`]: 1/64 LSB, eight times the
/// two values' combined error bound (0.001 + 0.002 LSB).
const TIE_MARGIN: i64 = 1 << 24;

/// The tie margin for one radius, in 2^-30 LSB: both values' errors are
/// relative to the radius (the table's below 2^-41 of it, `qrotate`'s
/// iterations and residual below 2^-40 of it) but for the last few units of
/// 2^-30 LSB (the operand's scaling and the products' truncation), so the
/// margin is 2^-37 of the radius (which is [`TIE_MARGIN`] at full scale)
/// plus 2^-22 LSB. A small radius then almost never needs `qrotate` (at
/// 25,000 about one angle in two million instead of one in 32).
#[inline(always)]
fn tie_margin(radius: i32) -> i64 {
    ((i64::from(radius.unsigned_abs()) * TIE_MARGIN) >> 31) + (1 << 8)
}

/// 2π · 2^31, rounded: a binary angle (2^32 = 360°) times this is radians
/// in 1.63 fixed point.
const TWO_PI_Q31: i64 = 13_493_037_705;

/// Binary-angle bits below one step of [`COS_TABLE_Q62`] (2^30 / 512).
const COS_TABLE_SHIFT: u32 = 21;

/// The cosine and sine of a binary angle (2^32 = 360°) in 2.62 fixed point
/// (2^62 = 1.0), each within 2^-41 of the exact value (from the table
/// [`cos_batch`] uses and a third-order correction; no rounding to an
/// integer). For callers that need more than an `i32`'s precision, such as
/// a rotation recurrence anchored at this value.
///
/// ```
/// let (cos, sin) = cordic_core::cos_sin_q62(0x2AAA_AAAB); // 60°, rounded
/// assert!((cos - (1i64 << 61)).abs() < 1 << 32);
/// assert!((sin as f64 / 2f64.powi(62) - 3f64.sqrt() / 2.0).abs() < 1e-9);
/// ```
pub fn cos_sin_q62(angle: u32) -> (i64, i64) {
    // sin θ = cos(θ − 90°).
    (
        table_cos_q62(angle),
        table_cos_q62(angle.wrapping_sub(1 << 30)),
    )
}

/// The most [`sin_cos`] is off by, either value, for |θ| ≤ 1,024 rad
/// (beyond, the rest's rounding adds up to |θ|·2^-52).
pub const SIN_COS_ERROR: f64 = 1.0 / (1u64 << 40) as f64;

/// Binary-angle units (2^32 a turn) per radian, and radians per unit.
const ANGLE_PER_RADIAN: f64 = 4_294_967_296.0 / core::f64::consts::TAU;
const RADIAN_PER_ANGLE: f64 = core::f64::consts::TAU / 4_294_967_296.0;

/// The sine and cosine of `theta` (radians) as `f64`, each within
/// [`SIN_COS_ERROR`] of the exact value for |θ| ≤ 1,024: [`cos_sin_q62`]
/// at the binary angle below θ, turned by the rest (under 1.5·10⁻⁹ rad,
/// whose second-order terms are below 1.1·10⁻¹⁸). Integer arithmetic and a
/// few products where a `libm` `sin` and `cos` take about forty `f64`
/// operations: on a core whose `f64` is software (a Cortex-M0+) about a
/// fifth of the cycles. NaN for a θ that is not finite.
///
/// ```
/// let (sin, cos) = cordic_core::sin_cos(1.0);
/// assert!((sin - 1f64.sin()).abs() < 1e-12 && (cos - 1f64.cos()).abs() < 1e-12);
/// ```
pub fn sin_cos(theta: f64) -> (f64, f64) {
    if !theta.is_finite() {
        return (f64::NAN, f64::NAN);
    }
    // Toward zero: the rest has θ's sign, under one unit.
    let units = (theta * ANGLE_PER_RADIAN) as i64;
    let rest = theta - units as f64 * RADIAN_PER_ANGLE;
    // The angle modulo a turn.
    let (cos, sin) = cos_sin_q62(units as u32);
    let (cos, sin) = (from_q62(cos), from_q62(sin));
    (sin + rest * cos, cos - rest * sin)
}

/// A 2.62 fixed-point value as `f64`: the conversion's exponent lowered
/// by 62 (exact; a product by 2^-62 is a library call on an M0+).
fn from_q62(value: i64) -> f64 {
    if value == 0 {
        return 0.0;
    }
    // |value| ≥ 1, so the lowered exponent stays normal.
    f64::from_bits((value as f64).to_bits() - (62 << 52))
}

/// cos(`angle`) in 2.62, error below 2^-41 (see [`table_cos`]).
#[inline(always)]
fn table_cos_q62(angle: u32) -> i64 {
    // cos is even, and cos θ = −cos(180° − θ): fold to φ in [0°, 90°].
    let folded = (angle as i32).unsigned_abs();
    let flip = folded > 1 << 30;
    let phi = if flip { (1 << 31) - folded } else { folded };
    let index = (phi + (1 << (COS_TABLE_SHIFT - 1))) >> COS_TABLE_SHIFT;
    // What is left to the nearest entry, ±2^20 binary units (±0.088°).
    let rest = i64::from(phi) - (i64::from(index) << COS_TABLE_SHIFT);
    let cos_a = COS_TABLE_Q62[index as usize];
    let sin_a = COS_TABLE_Q62[COS_TABLE_Q62.len() - 1 - index as usize];
    // t in radians, 1.63 (|t| < 2^-9.3); t²/2 and sin t − t in 1.63 too.
    let t = rest * TWO_PI_Q31;
    let half_t_squared = mul_high(t, t);
    let sin_t = t - 2 * mul_high(mul_high(t, half_t_squared), ONE_THIRD_Q64);
    // cos(a + t) = cos a · (1 − t²/2) − sin a · sin t, 2.62; the t⁴/24 left
    // out is below 2^-41.5.
    let cos = cos_a - 2 * mul_high(cos_a, half_t_squared) - 2 * mul_high(sin_a, sin_t);
    if flip {
        -cos
    } else {
        cos
    }
}

/// `operand`·cos(`angle`) / 2^32 rounded to nearest (`operand` = radius ·
/// 2^32), and whether the value lay within [`TIE_MARGIN`] of a rounding
/// boundary.
#[inline(always)]
fn table_cos(angle: u32, operand: i64, margin: i64) -> (i32, bool) {
    let cos = table_cos_q62(angle);
    // OPERAND_FRACTION_BITS (30) fraction bits, rounded half up as qrotate does.
    let value = mul_high(cos, operand) + (1 << (OPERAND_FRACTION_BITS - 1));
    let fraction = value & ((1 << OPERAND_FRACTION_BITS) - 1);
    let near_tie = (fraction - margin) as u64 >= ((1 << OPERAND_FRACTION_BITS) - 2 * margin) as u64;
    ((value >> OPERAND_FRACTION_BITS) as i32, near_tie)
}

/// One angle through the iterations: its quadrant, and the fine stage's
/// vector with the residual rotation still to apply.
#[inline(always)]
fn iterate(angle: u32) -> (u32, Fine) {
    let (quadrant, mut z) = split_quadrant(angle);
    let (mut x, mut y, mut atan_error) = (COARSE_ONE, 0, 0);
    for i in 0..COARSE_ITERATIONS {
        coarse_step(i, &mut x, &mut y, &mut z, &mut atan_error);
    }
    let (mut x, mut y, mut z) = to_fine(x, y, z, atan_error);
    for i in COARSE_ITERATIONS..ROTATE_ITERATIONS {
        fine_step(i, &mut x, &mut y, &mut z);
    }
    let fine = Fine {
        x,
        y: unbias(y),
        residual: Residual::of(z),
    };
    (quadrant, fine)
}

/// The fine stage's vector (2.62, lengthened by the gain K; x > 0) and the
/// residual rotation that finishes it: together, K·(cos r, sin r) for the
/// angle r left after the quadrant.
struct Fine {
    x: i64,
    y: i64,
    residual: Residual,
}

impl Fine {
    /// K·cos(r + `quadrant`·90°): the residual rotation worked out for the
    /// one component wanted, the quadrant turned exactly, without branches.
    /// [`qrotate`] and [`cos_batch`] both go through here, so they agree bit
    /// for bit.
    #[inline(always)]
    fn turned_cos(&self, quadrant: u32) -> Signed {
        let (x, y) = (self.x, self.y);
        // Odd quadrants want the sine: (x, y) → (y, −x) picks it.
        let swap = -i64::from(quadrant & 1);
        let (u, v) = (x ^ ((x ^ y) & swap), y ^ ((y ^ -x) & swap));
        Signed {
            magnitude: self.residual.rotate_x(u, v),
            // cos(r + q·90°) is cos r, −sin r, −cos r, sin r.
            negate: -i64::from(quadrant.wrapping_add(1) >> 1 & 1),
        }
    }
}

/// A value whose sign is still to apply: `negate` is −1 (all ones) to negate.
/// Kept apart so that the sign of the operand can join it (see [`Signed::times`]).
#[derive(Clone, Copy)]
struct Signed {
    magnitude: i64,
    negate: i64,
}

impl Signed {
    /// The high half of the value times `operand`. The operand's sign joins
    /// the value's, so that the multiply is by a non-negative factor: where
    /// the operand is a loop invariant (a radius), a signed 128-bit product
    /// compiles to three multiplies, an unsigned one to one.
    #[inline(always)]
    fn times(self, operand: i64) -> i64 {
        let value = negate_if(self.magnitude, self.negate ^ (operand >> 63));
        mul_high_by_unsigned(value, operand.unsigned_abs())
    }
}

/// The nearest multiple of 90° (as a quadrant 0..=3) and what is left of the
/// angle, ±45°, in half binary units (2^33 = 360°, so ±2^30).
#[inline(always)]
fn split_quadrant(angle: u32) -> (u32, i32) {
    let quadrant = angle.wrapping_add(1 << 29) >> 30;
    let residual = angle.wrapping_sub(quadrant << 30) as i32;
    (quadrant, residual << 1)
}

/// One coarse iteration: turn (x, y) by ±atan 2^-i towards z, exactly.
/// `atan_error` sums the table's rounding over the clockwise turns.
#[inline(always)]
fn coarse_step(i: usize, x: &mut i32, y: &mut i32, z: &mut i32, atan_error: &mut i32) {
    // 0 to turn counter-clockwise (z ≥ 0), −1 (all ones) to turn clockwise.
    // With that mask, d ^ mask is d or −d − 1, so (v + mask) − (d ^ mask) is
    // v − d or v + d: the sum and the xor run side by side.
    let clockwise = *z >> 31;
    let (y_shifted, x_shifted) = (*y >> i, *x >> i);
    *x = (*x + clockwise) - (y_shifted ^ clockwise);
    *y = (*y - clockwise) + (x_shifted ^ clockwise);
    *z = (*z + clockwise) - (COARSE_ATAN[i] ^ clockwise);
    *atan_error += COARSE_ATAN_ERROR[i] & clockwise;
}

/// From the coarse stage to the fine one: (x, y) to 2.62 (exact), y biased,
/// and the exact angle left in wide units.
#[inline(always)]
fn to_fine(x: i32, y: i32, z: i32, atan_error: i32) -> (i64, u64, i64) {
    // Turned: Σσ·(COARSE_ATAN·2^31 + error·2^4); error sum over all turns is
    // the total minus twice the clockwise ones.
    let error = COARSE_ATAN_ERROR_SUM - 2 * i64::from(atan_error);
    let z = (i64::from(z) << 31) - (error << 4);
    let y = ((i64::from(y) << 34) as u64).wrapping_add(Y_BIAS);
    (i64::from(x) << 34, y, z)
}

/// One fine iteration on x (2.62, always positive: the vector stays within
/// ±72° of +X), biased y and z (wide units).
#[inline(always)]
fn fine_step(i: usize, x: &mut i64, y: &mut u64, z: &mut i64) {
    // The mask as in `coarse_step`.
    let clockwise = *z >> 63;
    // (y + bias) >> i = (y >> i) + (bias >> i), exactly.
    let y_shifted = (*y >> i) as i64;
    let bias_shifted = (Y_BIAS >> i) as i64;
    let x_shifted = ((*x as u64) >> i) as i64;
    *x = *x - (y_shifted ^ clockwise) + (bias_shifted ^ clockwise);
    *y = y
        .wrapping_sub(clockwise as u64)
        .wrapping_add((x_shifted ^ clockwise) as u64);
    *z = (*z + clockwise) - (ATAN_WIDE[i] ^ clockwise);
}

/// The fine stage's y without its bias.
#[inline(always)]
fn unbias(y: u64) -> i64 {
    y.wrapping_sub(Y_BIAS) as i64
}

/// The last small rotation, by the angle the iterations left, z (below
/// atan 2^-8 for 9 iterations or more): (cos z, sin z) to third order, in
/// 0.64 fixed point.
struct Residual {
    /// 1 − cos z ≈ z²/2.
    one_minus_cos: i64,
    /// sin z ≈ z − z³/6.
    sin: i64,
}

impl Residual {
    /// From the angle left in wide units (2^64 = 360°).
    #[inline(always)]
    fn of(z: i64) -> Self {
        // z · 2π in radians · 2^64; |z| < 2^53.4 wide units, so z << 7 fits.
        let z = mul_high(z << 7, TWO_PI_Q57);
        let half_z_squared = mul_high(z, z) >> 1;
        Residual {
            one_minus_cos: half_z_squared,
            sin: z - mul_high(mul_high(z, half_z_squared), ONE_THIRD_Q64),
        }
    }

    /// X of the vector (x, y) rotated by the residual: x·cos z − y·sin z.
    #[inline(always)]
    fn rotate_x(&self, x: i64, y: i64) -> i64 {
        x - mul_high(x, self.one_minus_cos) - mul_high(y, self.sin)
    }
}

/// `v`, or −`v` where `mask` is −1 (all ones).
#[inline(always)]
fn negate_if(v: i64, mask: i64) -> i64 {
    (v ^ mask) - mask
}

/// An operand scaled by 1/K with [`OPERAND_FRACTION_BITS`] + 2 fraction bits
/// (so that its product with a 2.62 vector component, high half, carries
/// `OPERAND_FRACTION_BITS` fraction bits); |result| < 2^62.3.
#[inline(always)]
fn rotate_operand(v: i32) -> i64 {
    let shift = 62 - (OPERAND_FRACTION_BITS + 2);
    ((i128::from(v) * i128::from(ROTATE_INV_GAIN_Q62) + (1 << (shift - 1))) >> shift) as i64
}

/// A result with [`OPERAND_FRACTION_BITS`] fraction bits, rounded half up and
/// saturated to `i32`.
#[inline(always)]
fn round_result(v: i64) -> i32 {
    ((v + (1 << (OPERAND_FRACTION_BITS - 1))) >> OPERAND_FRACTION_BITS)
        .clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

/// The high 64 bits of the 128-bit product (rounded down): inline 32-bit
/// products where there is no widening multiply ([`mul_high_i64`]).
#[inline(always)]
fn mul_high(a: i64, b: i64) -> i64 {
    mul_high_i64(a, b)
}

/// [`mul_high`] for a factor known to be non-negative, bit for bit
/// ([`high_of_signed_by_unsigned`]).
#[inline(always)]
fn mul_high_by_unsigned(a: i64, b: u64) -> i64 {
    high_of_signed_by_unsigned(a, b, mul_high_u64(a as u64, b))
}

/// Converts the vector (`x`, `y`) to polar form: QVECTOR. Returns
/// (length, angle), the length rounded to nearest (it always fits: at most
/// 2^31·√2) and the angle a binary angle (2^32 = 360°) rounded to nearest,
/// measured counter-clockwise from +X.
///
/// The zero vector gives (0, 0).
///
/// ```
/// use cordic_core::qvector;
/// assert_eq!(qvector(100, 100), (141, 0x2000_0000));
/// assert_eq!(qvector(0, -5), (5, 0xC000_0000));
/// ```
pub fn qvector(x: i32, y: i32) -> (u32, u32) {
    if x == 0 && y == 0 {
        return (0, 0);
    }
    let (mut x, mut y) = (i64::from(x), i64::from(y));
    // Into the right half plane with an exact 180° turn: the iteration then
    // has at most ±90° to cover.
    let mut z: u64 = 0;
    if x < 0 {
        x = -x;
        y = -y;
        z = 1 << 63;
    }
    // The larger component into [2^60, 2^61): room for the gain (×1.65) and
    // √2, and ~30 guard bits even for the shortest vectors.
    let scale = x.unsigned_abs().max(y.unsigned_abs()).leading_zeros() - 3;
    x <<= scale;
    y <<= scale;
    for (i, &atan) in ATAN_WIDE.iter().enumerate() {
        // Turn towards the +X axis: clockwise while y > 0. The mask is −1
        // (all ones) to turn counter-clockwise, which negates the steps.
        let counter_clockwise = -i64::from(y <= 0);
        let dx = ((y >> i) ^ counter_clockwise) - counter_clockwise;
        let dy = ((x >> i) ^ counter_clockwise) - counter_clockwise;
        x += dx;
        y -= dy;
        z = z.wrapping_add(((atan ^ counter_clockwise) - counter_clockwise) as u64);
    }
    // Gain out, scale out, rounded half up; x < 2^62.3, so the product fits.
    let shift = 64 + scale;
    let length = (i128::from(x) * i128::from(INV_GAIN_Q64) + (1i128 << (shift - 1))) >> shift;
    let angle = (z.wrapping_add(1 << 31) >> 32) as u32;
    (length as u32, angle)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_within_its_bound_over_a_thousand_radians() {
        let mut worst: f64 = 0.0;
        for i in -200_000..=200_000 {
            let theta = f64::from(i) * 0.005_123_456_789;
            let (sin, cos) = sin_cos(theta);
            worst = worst
                .max((sin - theta.sin()).abs())
                .max((cos - theta.cos()).abs());
        }
        assert!(worst <= SIN_COS_ERROR, "{worst}");
        for theta in [
            0.0,
            -0.0,
            1e-300,
            core::f64::consts::PI,
            -core::f64::consts::PI,
            1024.0,
        ] {
            let (sin, cos) = sin_cos(theta);
            assert!((sin - theta.sin()).abs() <= SIN_COS_ERROR, "{theta}");
            assert!((cos - theta.cos()).abs() <= SIN_COS_ERROR, "{theta}");
        }
        assert!(sin_cos(f64::NAN).0.is_nan() && sin_cos(f64::INFINITY).1.is_nan());
    }

    #[test]
    fn silicon_rotate_100_100_by_90() {
        assert_eq!(qrotate(100, 100, 0x4000_0000), (-100, 100));
    }

    #[test]
    fn silicon_rotate_full_scale_by_180() {
        assert_eq!(
            qrotate(0x7FFF_FFFF, 0, 0x8000_0000),
            (0x8000_0001u32 as i32, 0)
        );
    }

    #[test]
    fn silicon_vector_100_100() {
        assert_eq!(qvector(100, 100), (141, 0x2000_0000));
    }

    #[test]
    fn chip_rounds_where_spinsim_truncates() {
        // spinsim truncates a float result and reports 99 here.
        for angle in [0x4000_0000u32, 0x8000_0000, 0xC000_0000, 0] {
            let (x, y) = qrotate(100, 0, angle);
            assert_eq!(x.abs() + y.abs(), 100, "angle {angle:#x}");
        }
    }

    #[test]
    fn overflowing_results_saturate() {
        // (MAX, MAX) by 45° is (0, MAX·√2): Y saturates, X stays exact.
        let (x, y) = qrotate(i32::MAX, i32::MAX, 0x2000_0000);
        assert!(x.abs() <= 1);
        assert_eq!(y, i32::MAX);
        // Negating i32::MIN cannot be represented: saturates to MAX.
        assert_eq!(qrotate(i32::MIN, 0, 0x8000_0000), (i32::MAX, 0));
        assert_eq!(qrotate(i32::MIN, i32::MIN, 0x2000_0000).0, 0);
    }

    #[test]
    fn vector_of_extremes() {
        let (len, angle) = qvector(i32::MIN, i32::MIN);
        assert_eq!(len, 3_037_000_500); // 2^31·√2 = 3037000499.98
        assert_eq!(angle, 0xA000_0000);
        assert_eq!(qvector(i32::MIN, 0), (1 << 31, 0x8000_0000));
        assert_eq!(qvector(0, 0), (0, 0));
        assert_eq!(qvector(1, 1), (1, 0x2000_0000));
        assert_eq!(qvector(-1, 0), (1, 0x8000_0000));
        assert_eq!(qvector(0, 1), (1, 0x4000_0000));
    }

    #[test]
    fn coarse_tables_add_up() {
        // Rounded entry · 2^31 + error · 2^4 is the wide entry to within the
        // dropped 4 bits.
        for i in 0..COARSE_ITERATIONS {
            let rebuilt =
                (i64::from(COARSE_ATAN[i]) << 31) + (i64::from(COARSE_ATAN_ERROR[i]) << 4);
            assert!(
                (ATAN_WIDE[i] - rebuilt) < 16 && ATAN_WIDE[i] >= rebuilt,
                "entry {i}"
            );
        }
    }

    #[test]
    fn cos_batch_matches_qrotate_bit_for_bit() {
        let mut state = 0x1234_5678_9ABC_DEF0_u64;
        let angles: [u32; 200] = core::array::from_fn(|k| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            match k % 4 {
                0 => (state >> 32) as u32,
                // Near the axes and the octant edges.
                1 => ((k as u32 / 4) << 29)
                    .wrapping_add((state >> 60) as u32)
                    .wrapping_sub(8),
                2 => (k as u32) << 30,
                _ => (state >> 40) as u32,
            }
        });
        for radius in [i32::MAX, i32::MIN, -i32::MAX, 1, -1, 0, 25_000, 123_456_789] {
            let mut cosines = [0; 200];
            // Every length, so that blocks end part way.
            for len in [0, 1, 63, 64, 65, 200] {
                cos_batch(radius, &angles[..len], &mut cosines[..len]);
                for (&angle, &cosine) in angles[..len].iter().zip(&cosines[..len]) {
                    assert_eq!(
                        cosine,
                        qrotate(radius, 0, angle).0,
                        "r {radius} a {angle:#x}"
                    );
                }
            }
        }
    }

    /// `qrotate`'s X before rounding, 30 fraction bits.
    fn qrotate_unrounded(radius: i32, angle: u32) -> i64 {
        let (quadrant, fine) = iterate(angle);
        fine.turned_cos(quadrant).times(rotate_operand(radius))
    }

    /// `table_cos`'s value before rounding, 30 fraction bits.
    fn table_unrounded(radius: i32, angle: u32) -> i64 {
        // table_cos's arithmetic, stopped before it rounds.
        let folded = (angle as i32).unsigned_abs();
        let flip = folded > 1 << 30;
        let phi = if flip { (1 << 31) - folded } else { folded };
        let index = (phi + (1 << (COS_TABLE_SHIFT - 1))) >> COS_TABLE_SHIFT;
        let rest = i64::from(phi) - (i64::from(index) << COS_TABLE_SHIFT);
        let cos_a = COS_TABLE_Q62[index as usize];
        let sin_a = COS_TABLE_Q62[COS_TABLE_Q62.len() - 1 - index as usize];
        let t = rest * TWO_PI_Q31;
        let half_t_squared = mul_high(t, t);
        let sin_t = t - 2 * mul_high(mul_high(t, half_t_squared), ONE_THIRD_Q64);
        let cos = cos_a - 2 * mul_high(cos_a, half_t_squared) - 2 * mul_high(sin_a, sin_t);
        let cos = if flip { -cos } else { cos };
        mul_high(cos, i64::from(radius) << 32)
    }

    /// The tie margin's premise: the table's value and `qrotate`'s stay far
    /// closer than [`TIE_MARGIN`] (measured: under 1/8 of it), so outside
    /// the margin they round alike.
    #[test]
    fn the_table_cosine_stays_well_inside_the_tie_margin() {
        let mut state = 0x0BAD_CAFE_F00D_0001_u64;
        let mut worst = 0i64;
        for k in 0..200_000u32 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1442695040888963407);
            let angle = match k % 3 {
                0 => (state >> 32) as u32,
                // Near table entries, the axes and 45°.
                1 => (((state >> 55) as u32) << 21)
                    .wrapping_add((state >> 20) as u32 % 64)
                    .wrapping_sub(32),
                _ => ((k % 8) << 29)
                    .wrapping_add((state >> 40) as u32 % 4096)
                    .wrapping_sub(2048),
            };
            for radius in [i32::MAX, -i32::MAX, 1 << 30, 25_000, (state >> 33) as i32] {
                let difference =
                    (table_unrounded(radius, angle) - qrotate_unrounded(radius, angle)).abs();
                worst = worst.max(difference);
            }
        }
        assert!(worst < TIE_MARGIN / 8, "{worst} of {TIE_MARGIN}");
    }

    /// The same for the margin of each radius ([`tie_margin`]): the two
    /// values stay within 1/8 of it for small radii too.
    #[test]
    fn the_table_cosine_stays_well_inside_each_radius_tie_margin() {
        let mut state = 0x0DDB_A11C_AFE0_0001_u64;
        for k in 0..100_000u32 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1442695040888963407);
            let angle = match k % 2 {
                0 => (state >> 32) as u32,
                _ => (((state >> 55) as u32) << 21)
                    .wrapping_add((state >> 20) as u32 % 64)
                    .wrapping_sub(32),
            };
            let random = (state >> (33 + k % 31)) as i32;
            for radius in [
                1,
                -1,
                7,
                1_000,
                25_000,
                -25_000,
                1 << 20,
                random,
                -random,
                i32::MAX,
            ] {
                let difference =
                    (table_unrounded(radius, angle) - qrotate_unrounded(radius, angle)).abs();
                assert!(
                    difference < tie_margin(radius) / 8,
                    "r {radius} a {angle:#x}: {difference} of {}",
                    tie_margin(radius)
                );
            }
        }
    }

    #[test]
    fn cos_sin_q62_is_within_2_to_the_minus_41() {
        extern crate std;
        let mut state = 0x5EED_0000_0000_0001_u64;
        let scale = (1u64 << 62) as f64;
        for k in 0..100_000u32 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            let angle = if k < 64 {
                k << 26
            } else {
                (state >> 32) as u32
            };
            let (cos, sin) = cos_sin_q62(angle);
            // f64's own error (2^-53) is far below the bound checked.
            let radians = f64::from(angle) * (core::f64::consts::TAU / 4_294_967_296.0);
            let bound = 2f64.powi(-41);
            let (exact_sin, exact_cos) = std::primitive::f64::sin_cos(radians);
            assert!((cos as f64 / scale - exact_cos).abs() < bound, "{angle:#x}");
            assert!((sin as f64 / scale - exact_sin).abs() < bound, "{angle:#x}");
        }
    }

    #[test]
    #[should_panic(expected = "one cosine per angle")]
    fn cos_batch_wants_equal_lengths() {
        cos_batch(1, &[0, 1], &mut [0]);
    }
}

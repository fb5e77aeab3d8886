//! QROTATE and QVECTOR: the circular CORDIC, rotating and vectoring.
//!
//! Both run the textbook shift-and-add iteration on `i64` values that carry
//! [`SCALE_BITS`] guard bits below the P2's 32-bit result, with the angle kept
//! in "wide" binary units (2^64 = 360°) so the table of arctangents adds no
//! error of its own. The gain (≈1.6468) is taken out at the end with one
//! 64-bit multiply, then the result is rounded to nearest, as the silicon does.
//!
//! Range: intermediate magnitudes stay below 2^61.3, so no iteration can
//! overflow for any 32-bit input. Results that do not fit in 32 bits are
//! saturated (see [`qrotate`]).

use crate::tables::{ATAN_WIDE, INV_GAIN_Q64};

/// CORDIC iterations: after 40 of them the residual angle is below 2^-39 rad,
/// so even a full-scale vector is off by less than 1/64 LSB before rounding.
pub(crate) const ITERATIONS: usize = ATAN_WIDE.len();

/// Guard bits carried below the result's LSB.
const SCALE_BITS: u32 = 29;

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
pub fn qrotate(x: i32, y: i32, angle: u32) -> (i32, i32) {
    // Turn by the nearest multiple of 90° exactly, leaving at most ±45° for
    // the iteration (whose convergence range is ±99.9°).
    let quadrant = angle.wrapping_add(1 << 29) >> 30;
    let residual = angle.wrapping_sub(quadrant << 30) as i32;
    let (x, y) = (i64::from(x), i64::from(y));
    let (x, y) = match quadrant {
        0 => (x, y),
        1 => (-y, x),
        2 => (-x, -y),
        _ => (y, -x),
    };
    let (x, y) = rotate_scaled(x << SCALE_BITS, y << SCALE_BITS, i64::from(residual) << 32);
    (round_to_i32(x), round_to_i32(y))
}

/// The rotating iteration on scaled values; `z` is the angle still to turn,
/// in wide units, |z| ≤ 2^61 (45°).
#[inline(always)]
fn rotate_scaled(mut x: i64, mut y: i64, mut z: i64) -> (i64, i64) {
    for (i, &atan) in ATAN_WIDE.iter().enumerate() {
        let (dx, dy) = (y >> i, x >> i);
        if z >= 0 {
            x -= dx;
            y += dy;
            z -= atan;
        } else {
            x += dx;
            y -= dy;
            z += atan;
        }
    }
    (x, y)
}

/// Removes the gain and the guard bits, rounding half up, saturating.
#[inline(always)]
fn compensate(v: i64) -> i128 {
    let product = i128::from(v) * i128::from(INV_GAIN_Q64);
    let shift = 64 + SCALE_BITS;
    (product + (1i128 << (shift - 1))) >> shift
}

#[inline(always)]
fn round_to_i32(v: i64) -> i32 {
    compensate(v).clamp(i128::from(i32::MIN), i128::from(i32::MAX)) as i32
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
    x <<= SCALE_BITS;
    y <<= SCALE_BITS;
    for (i, &atan) in ATAN_WIDE.iter().enumerate() {
        let (dx, dy) = (y >> i, x >> i);
        if y > 0 {
            x += dx;
            y -= dy;
            z = z.wrapping_add(atan as u64);
        } else {
            x -= dx;
            y += dy;
            z = z.wrapping_sub(atan as u64);
        }
    }
    let length = compensate(x).clamp(0, i128::from(u32::MAX)) as u32;
    let angle = (z.wrapping_add(1 << 31) >> 32) as u32;
    (length, angle)
}

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}

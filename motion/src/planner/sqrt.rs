//! A square root on `f64` without `libm`: Newton's iteration from an
//! exponent-halving first guess. The planner needs it for unit vectors,
//! junction speeds and the ramp's peak; it is not correctly rounded (within
//! a few ulps, tested against `std`), which the planner's margins absorb.

/// `√x` for a finite `x ≥ 0` (within a few ulps); 0 for zero, negatives and
/// NaN, `x` for +∞.
pub(crate) fn sqrt(x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    if x == f64::INFINITY {
        return x;
    }
    // Halving the biased exponent: a first guess within a factor of about
    // 1.06 for normals; Newton then doubles the correct bits each round.
    let mut root = f64::from_bits((x.to_bits() >> 1) + (1023u64 << 51));
    // Subnormals start further away (their exponent field is 0): more rounds.
    let rounds = if x < f64::MIN_POSITIVE { 40 } else { 6 };
    for _ in 0..rounds {
        root = 0.5 * (root + x / root);
    }
    root
}

#[cfg(test)]
mod tests {
    use super::sqrt;
    use proptest::prelude::*;

    fn ulps_apart(a: f64, b: f64) -> u64 {
        a.to_bits().abs_diff(b.to_bits())
    }

    #[test]
    fn edges() {
        assert_eq!(sqrt(0.0), 0.0);
        assert_eq!(sqrt(-1.0), 0.0);
        assert_eq!(sqrt(f64::NAN), 0.0);
        assert_eq!(sqrt(f64::INFINITY), f64::INFINITY);
        assert_eq!(sqrt(4.0), 2.0);
        for x in [f64::MIN_POSITIVE, 5e-324, 1e-310, f64::MAX, 2.0, 0.5] {
            assert!(ulps_apart(sqrt(x), x.sqrt()) <= 2, "{x}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        #[test]
        fn matches_std(bits in 1u64..0x7FF0_0000_0000_0000) {
            let x = f64::from_bits(bits);
            prop_assert!(ulps_apart(sqrt(x), x.sqrt()) <= 2, "{}", x);
        }
    }
}

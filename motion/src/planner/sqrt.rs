//! The planner's square root: `libm`'s, correctly rounded (the hardware
//! instruction on x86-64; software on the Cortex-M targets, which have no
//! `f64` square root), with the planner's conventions at the edges. With
//! the feature `core-sqrt`, `core`'s own (`core::f64::math::sqrt`, not
//! yet stable: the firmware's toolchain allows it), which on a core with no
//! such instruction calls the C `sqrt` the binary links: on the Raspberry
//! Pi Pico rp2040-hal's, the boot ROM's, about 8 times faster than `libm`'s
//! integer square root on its M0+.

/// `√x` for a finite `x ≥ 0`; 0 for zero, negatives and NaN, `x` for +∞.
#[inline]
pub(crate) fn sqrt(x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    #[cfg(feature = "core-sqrt")]
    {
        core::f64::math::sqrt(x)
    }
    #[cfg(not(feature = "core-sqrt"))]
    {
        libm::sqrt(x)
    }
}

#[cfg(test)]
mod tests {
    use super::sqrt;
    use proptest::prelude::*;

    #[test]
    fn edges() {
        assert_eq!(sqrt(0.0), 0.0);
        assert_eq!(sqrt(-1.0), 0.0);
        assert_eq!(sqrt(f64::NAN), 0.0);
        assert_eq!(sqrt(f64::INFINITY), f64::INFINITY);
        assert_eq!(sqrt(4.0), 2.0);
        for x in [f64::MIN_POSITIVE, 5e-324, 1e-310, f64::MAX, 2.0, 0.5] {
            assert_eq!(sqrt(x), x.sqrt(), "{x}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        #[test]
        fn matches_std(bits in 1u64..0x7FF0_0000_0000_0000) {
            let x = f64::from_bits(bits);
            prop_assert_eq!(sqrt(x), x.sqrt());
        }
    }
}

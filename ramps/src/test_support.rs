//! Test helpers shared by the linear-ramp profiles' tests.

use proptest::prelude::*;

use super::{PlanError, Profile};

/// Any input at all for a (clkfreq, speed, accel, steps) constructor:
/// zeros, negatives, NaN, infinities, the extremes.
pub(crate) fn any_linear_input() -> impl Strategy<Value = (u32, f64, f64, u32)> {
    let number = prop_oneof![
        any::<f64>(),
        (-1e6f64..1e7),
        Just(0.0),
        Just(f64::MIN_POSITIVE),
        Just(5e-324),
        Just(f64::MAX),
        Just(f64::INFINITY),
        Just(f64::NAN),
    ];
    let count = prop_oneof![any::<u32>(), 0u32..10, Just(u32::MAX)];
    (count.clone(), number.clone(), number, count)
}

/// What a constructor made of any input: an error, or a profile whose first
/// steps are well formed and whose count is exact. Never a panic.
pub(crate) fn check_error_or_sane<P: Profile>(
    made: Result<P, PlanError>,
    steps: u32,
) -> Result<(), TestCaseError> {
    if let Ok(mut profile) = made {
        for step in profile.by_ref().take(64) {
            prop_assert!(step.delay_ticks >= 1);
        }
        prop_assert_eq!(profile.remaining_steps(), steps - steps.min(64));
    }
    Ok(())
}

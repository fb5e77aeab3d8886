//! The step accounts: no step vanishes unaccounted.

use cogstep_hub::Axis;
use cogstep_motion::axis_core::StepLedger;

/// Where the ledger says an idle axis stands: `base + accepted − dropped
/// + jogged`, without overflow.
pub fn accounted(ledger: &StepLedger) -> i128 {
    i128::from(ledger.base) + i128::from(ledger.accepted) - i128::from(ledger.dropped)
        + i128::from(ledger.jogged)
}

/// Asserts that `axis` has nothing to make and stands where its ledger
/// says, the identity that holds whenever an axis is idle.
pub fn assert_accounted(axis: &Axis) {
    let ledger = axis.ledger();
    assert_eq!(axis.steps_to_go(), 0);
    assert_eq!(
        i128::from(axis.position()),
        accounted(&ledger),
        "{ledger:?}"
    );
}

//! What the core's own tests share: an axis on step/dir pins 1 and 2 with
//! its stop pin high, and the step accounts' identity.

use super::{AxisCore, AxisCoreConfig, Outputs};

/// An idle sd axis (step 1, dir 2) at CT 0, its stop pin high.
pub(super) fn core() -> AxisCore {
    let mut core = AxisCore::new(AxisCoreConfig::new(Outputs::StepDir { step: 1, dir: 2 }), 0);
    core.set_stop_pin(0, true);
    core
}

/// `position = base + accepted − dropped + jogged` whenever the axis is idle.
pub(super) fn assert_accounts(core: &AxisCore) {
    let ledger = core.ledger();
    assert!(!core.is_moving());
    assert_eq!(
        core.position(),
        ledger.base + ledger.accepted - ledger.dropped + ledger.jogged,
        "{ledger:?}"
    );
}

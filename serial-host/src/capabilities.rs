//! What a board lets the host do besides moving and reading status.

/// What a board lets the host do besides moving and reading status.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Capabilities {
    /// `set_stop_pin` (and `jog_release`, which needs it) work.
    pub stop_pin: bool,
    /// `jog` works.
    pub jog: bool,
    /// `emergency_stop` works.
    pub emergency_stop: bool,
    /// `set_position` works.
    pub set_position: bool,
}

impl Capabilities {
    /// Everything (a cogstep board).
    pub const ALL: Capabilities = Capabilities {
        stop_pin: true,
        jog: true,
        emergency_stop: true,
        set_position: true,
    };
    /// Moves and status only (the P2 demo: stop and jog are pins there).
    pub const MOVE_ONLY: Capabilities = Capabilities {
        stop_pin: false,
        jog: false,
        emergency_stop: false,
        set_position: false,
    };
    /// A grbl board: the stop pin is the board's feed hold (`!`, all axes;
    /// `~` resumes), the emergency stop its soft reset (0x18), an axis's
    /// `clear_limit_fault` its `$X` (the alarm lock is the board's, for
    /// every axis); no jog and no set position.
    pub const GRBL: Capabilities = Capabilities {
        stop_pin: true,
        jog: false,
        emergency_stop: true,
        set_position: false,
    };
}

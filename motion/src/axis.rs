//! The axis contract: what every backend offers for one motor axis.
//!
//! The emulated hub's `Axis` (`cogstep-hub`) and the serial backend both
//! implement [`AxisContract`], so the demo, scripts and tests drive either
//! the same way. The trait and its types are `no_std`, so a board's firmware
//! can implement it over its own pins and timer and reuse the serial
//! protocol's board side unchanged.

pub use crate::profile::motion::Direction;
use crate::profile::PlanError;

/// The reference driver's mode long, plus cogstep's own flags above bit 7.
///
/// | bit | meaning (reference) |
/// |---|---|
/// | 0 | moving |
/// | 1 | accelerating |
/// | 2 | decelerating |
/// | 3 | at slew speed |
/// | 4 | direction: set when steps < 0 |
/// | 5 | decelerate-to-stop latched (kept after the move ends, cleared by the next move) |
/// | 8 | emergency stopped (cogstep) |
/// | 9 | holding: a move waits for the stop pin to go high (cogstep) |
/// | 10 | jogging (cogstep) |
/// | 11 | a hard limit tripped: the fault is latched until cleared (cogstep) |
/// | 12 | homing (cogstep) |
///
/// Typed flags ([`bitflags`]): `Mode::MOVING | Mode::REVERSE`,
/// `mode.contains(..)`; [`Mode::bits`] is the whole long and
/// [`Mode::reference_bits`] the reference's six. The tuple field is the raw
/// long (unknown bits kept), as a status line or a hub word carries it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Mode(pub u32);

bitflags::bitflags! {
    impl Mode: u32 {
        /// Bit 0: a move is in progress.
        const MOVING = 1 << 0;
        /// Bit 1: accelerating.
        const ACCEL = 1 << 1;
        /// Bit 2: decelerating.
        const DECEL = 1 << 2;
        /// Bit 3: at slew speed.
        const SLEW = 1 << 3;
        /// Bit 4: moving in the negative direction.
        const REVERSE = 1 << 4;
        /// Bit 5: a controlled stop (stop pin low) happened; cleared by the next move.
        const STOP_LATCHED = 1 << 5;
        /// Bit 8 (cogstep): emergency stopped; cleared by the next move.
        const ESTOP = 1 << 8;
        /// Bit 9 (cogstep): a move is waiting for the stop pin to go high.
        const HOLD = 1 << 9;
        /// Bit 10 (cogstep): the move is a jog (kept alive by heartbeats).
        const JOG = 1 << 10;
        /// Bit 11 (cogstep): a hard limit tripped; latched until cleared.
        const LIMIT = 1 << 11;
        /// Bit 12 (cogstep): homing is under way.
        const HOMING = 1 << 12;
    }
}

impl Mode {
    /// The reference driver's six flags (bits 0–5).
    pub const REFERENCE: Mode = Mode(0x3F);

    /// The reference driver's 6-bit layout (bits 0–5), as its mode long
    /// and the P2 demo's screen carry it.
    pub fn reference_bits(self) -> u32 {
        self.0 & Self::REFERENCE.0
    }

    /// Whether all of `flags` are set.
    pub fn has(self, flags: Mode) -> bool {
        self.contains(flags)
    }

    /// The 6 reference bits as binary digits, bit 5 first (as the P2 demo shows them).
    pub fn binary(self) -> [u8; 6] {
        let mut digits = [b'0'; 6];
        for (i, digit) in digits.iter_mut().enumerate() {
            if self.0 & (1 << (5 - i)) != 0 {
                *digit = b'1';
            }
        }
        digits
    }

    /// The state in words, for status lines and screens.
    pub fn describe(self) -> &'static str {
        if self.has(Self::ESTOP) {
            "emergency stopped"
        } else if self.has(Self::HOMING) {
            "homing"
        } else if self.has(Self::LIMIT) && !self.has(Self::MOVING) {
            "stopped by a hard limit"
        } else if self.has(Self::HOLD) {
            "holding (stop pin low)"
        } else if !self.has(Self::MOVING) {
            if self.has(Self::STOP_LATCHED) {
                "stopped by stop pin"
            } else {
                "idle"
            }
        } else if self.has(Self::ACCEL) {
            "accelerating"
        } else if self.has(Self::SLEW) {
            "at speed"
        } else if self.has(Self::DECEL) {
            "decelerating"
        } else {
            "moving"
        }
    }
}

/// The state of an axis as the serial protocol's status line names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AxisState {
    /// Ready for a command.
    Idle,
    /// Running a move.
    Run,
    /// Running a jog.
    Jog,
    /// Stopped or held by the stop pin.
    Hold,
    /// Emergency stopped.
    Alarm,
}

impl AxisState {
    /// The state as the protocol spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            AxisState::Idle => "Idle",
            AxisState::Run => "Run",
            AxisState::Jog => "Jog",
            AxisState::Hold => "Hold",
            AxisState::Alarm => "Alarm",
        }
    }

    /// The state a mode and stop pin amount to.
    pub fn from_mode(mode: Mode, stop_pin_high: bool) -> Self {
        if mode.has(Mode::ESTOP) {
            AxisState::Alarm
        } else if mode.has(Mode::HOLD) || (!stop_pin_high && mode.has(Mode::STOP_LATCHED)) {
            AxisState::Hold
        } else if mode.has(Mode::JOG) && mode.has(Mode::MOVING) {
            AxisState::Jog
        } else if mode.has(Mode::MOVING) {
            AxisState::Run
        } else {
            AxisState::Idle
        }
    }
}

/// A snapshot of one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisStatus {
    /// Steps from the origin, signed.
    pub position: i64,
    /// The reference's STM: the signed steps of a command not yet taken,
    /// 0 once the axis has it (a move then runs, merges, queues or is held).
    pub stm: i32,
    /// Steps still to make (the move in progress, a queued reversal, a held
    /// move); 0 exactly when the axis is idle.
    pub steps_to_go: u64,
    /// The mode bits.
    pub mode: Mode,
    /// The velocity of the last step, steps/s (0 when idle).
    pub velocity_steps_per_s: u32,
    /// Whether the stop pin is high (running allowed).
    pub stop_pin_high: bool,
}

impl AxisStatus {
    /// Idle, Run, Jog, Hold or Alarm. `Run` means steps are left to make:
    /// while the last step's period runs (the reference's cog keeps b0 of
    /// the mode until it ends) the axis is `Idle` already, as it is for
    /// every command (a new move's first step waits for that period).
    pub fn state(&self) -> AxisState {
        match AxisState::from_mode(self.mode, self.stop_pin_high) {
            AxisState::Run if self.steps_to_go == 0 => AxisState::Idle,
            state => state,
        }
    }
}

/// Why an axis refused a request. A refused request changes nothing.
/// Every error but the transport errors (`Unavailable`, `Fault`,
/// `Unsupported`) is one [`Refusal`](crate::refusal::Refusal)
/// ([`AxisError::refusal`], [`AxisError::from_refusal`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum AxisError {
    /// The move cannot be planned (zero speed, zero steps, too fast, ...).
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// A command is already waiting to be taken (or a reversal to finish).
    #[error("busy: a command is already waiting")]
    Busy,
    /// The request needs an idle axis.
    #[error("the axis is not idle")]
    NotIdle,
    /// The step pulse or direction set-up does not fit between steps at this speed.
    #[error("{speed} steps/s leaves no room for the step pulse and direction set-up")]
    PulseTooLong {
        /// The speed asked for, steps/s.
        speed: u32,
    },
    /// The backend cannot do this (for example a board whose stop is a pin).
    #[error("not supported by this backend: {0}")]
    Unsupported(&'static str),
    /// The axis is gone: its cog was stopped, or the board is disconnected.
    #[error("the axis is not available (stopped or disconnected)")]
    Unavailable,
    /// The backend reported a fault (a board reset or lost mid-move, a timeout).
    #[error("fault: {0}")]
    Fault(&'static str),
    /// A jog owns the axis: release it (or let it time out) before a move.
    #[error("a jog is running: release it before a move")]
    Jogging,
    /// The stop pin is low: a jog cannot start.
    #[error("the stop pin is low")]
    StopPinLow,
    /// Merging would pass 2^32 - 1 steps in one move.
    #[error("the move would exceed 2^32 - 1 steps")]
    TooManySteps,
    /// The move could carry the position past the range of an i64.
    #[error("the move could carry the position out of range")]
    PositionOutOfRange,
    /// Steps must lie in -(2^31 - 1) ..= 2^31 - 1 (i32::MIN has no opposite).
    #[error("steps must lie in -2147483647..=2147483647")]
    StepsOutOfRange,
    /// A group move names one axis twice.
    #[error("an axis appears twice in the group move")]
    DuplicateAxis,
    /// Homing owns the axis until it ends (see the home outcome).
    #[error("the axis is homing")]
    Homing,
    /// The move would end beyond a soft limit.
    #[error("the move would end beyond a soft limit")]
    BeyondSoftLimit,
    /// The move or jog goes towards a hard limit that tripped (until the
    /// fault is cleared) or reads active now.
    #[error("a hard limit is tripped or active on the {0:?} side")]
    IntoLimit(Direction),
    /// The home switch did not trip within `max_travel` steps (the axis
    /// stopped under control).
    #[error("the home switch did not trip within max_travel steps")]
    HomeSwitchNotFound,
    /// The home switch still read active after backing off.
    #[error("the home switch still reads active after backing off")]
    HomeSwitchStuck,
    /// Homing was cut short by the stop pin, an emergency stop or a hard limit.
    #[error("homing was interrupted (stop pin, emergency stop or hard limit)")]
    HomingAborted,
    /// A homing, soft-limit or limit-pin setting that cannot work.
    #[error("bad setting: {0}")]
    BadSetting(&'static str),
}

/// How to home an axis (see [`AxisCore`](crate::axis_core::AxisCore)'s
/// homing): seek the switch at `seek_speed`, back off, approach it again at
/// `latch_speed`, and set the position so that the switch point is
/// `set_position`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct HomeConfig {
    /// The input pin the home switch drives.
    pub switch_pin: u8,
    /// The level the switch reads while pressed.
    pub active_level: bool,
    /// Which way the switch lies.
    pub direction: Direction,
    /// Speed of the first pass, steps/s.
    pub seek_speed: u32,
    /// Speed of the second (latching) pass, steps/s.
    pub latch_speed: u32,
    /// How far before the switch point the axis backs off between the passes, steps (≥ 1).
    pub backoff_steps: u32,
    /// The most steps each pass travels looking for the switch (1 ..= 2³¹ − 1).
    pub max_travel: u32,
    /// The position the switch point gets.
    pub set_position: i64,
}

impl Default for HomeConfig {
    fn default() -> Self {
        Self {
            switch_pin: 0,
            active_level: true,
            direction: Direction::Reverse,
            seek_speed: 8_000,
            latch_speed: 500,
            backoff_steps: 200,
            max_travel: 100_000,
            set_position: 0,
        }
    }
}

/// Where homing found the switch. Positions are the position counter
/// before homing set it; physical positions are the signed count of the
/// axis's own step edges since it started (set_position and homing leave
/// them alone).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HomeReport {
    /// The position at the step on which the switch changed, first pass.
    pub seek_position: i64,
    /// The physical position of that step.
    pub seek_physical: i64,
    /// The position at the step on which the switch changed, second pass.
    pub latch_position: i64,
    /// The physical position of that step: the switch point.
    pub latch_physical: i64,
    /// The position when homing ended (`set_position` + the offset from
    /// the switch point).
    pub position: i64,
}

/// A hard limit that tripped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LimitTrip {
    /// The side: `Forward` is the max limit, `Reverse` the min limit.
    pub side: Direction,
    /// The position at the step on which the limit read active.
    pub position: i64,
    /// The physical position of that step.
    pub physical: i64,
    /// The steps the axis still made after that step to stop (0 for an
    /// emergency stop): no step edge goes further.
    pub stopping_steps: u64,
}

/// The limit and homing state of an axis, as one call reads it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LimitStatus {
    /// The soft limits `(min, max)`, if set.
    pub soft_limits: Option<(i64, i64)>,
    /// The hard limit inputs `[min, max]`: `(pin, active level)`.
    pub limit_pins: [Option<(u8, bool)>; 2],
    /// The hard limit that tripped, until cleared.
    pub trip: Option<LimitTrip>,
    /// Whether homing is under way.
    pub homing: bool,
    /// How the last homing ended (`None` while homing or never homed).
    pub home_outcome: Option<Result<HomeReport, AxisError>>,
}

/// What every backend offers for one axis.
pub trait AxisContract {
    /// The reference `move(speed, steps)`: speed in steps/s, steps signed.
    /// While moving: same direction and speed merges, another speed changes
    /// speed without stopping, the other direction stops and then reverses.
    fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError>;
    /// A jog heartbeat: run at `speed` in `direction` while heartbeats keep
    /// coming; decelerate when they stop (after the backend's timeout).
    fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError>;
    /// End a jog at once (key released): controlled deceleration.
    fn jog_release(&self) -> Result<(), AxisError>;
    /// Drive the stop pin: low = controlled stop, high = running allowed.
    fn set_stop_pin(&self, high: bool) -> Result<(), AxisError>;
    /// Emergency stop: no more steps, position kept.
    fn emergency_stop(&self) -> Result<(), AxisError>;
    /// Set the position counter; only while idle.
    fn set_position(&self, position: i64) -> Result<(), AxisError>;
    /// A snapshot of the axis.
    fn status(&self) -> Result<AxisStatus, AxisError>;
    /// Starts homing (idle only); the outcome is read later with
    /// [`AxisContract::limit_status`]. Backends without homing say
    /// [`AxisError::Unsupported`].
    fn home(&self, _config: HomeConfig) -> Result<(), AxisError> {
        Err(AxisError::Unsupported("homing"))
    }
    /// Soft limits on the position: a move that would end beyond them is
    /// refused, a jog stops exactly on them.
    fn set_soft_limits(&self, _min: i64, _max: i64) -> Result<(), AxisError> {
        Err(AxisError::Unsupported("soft limits"))
    }
    /// Removes the soft limits.
    fn clear_soft_limits(&self) -> Result<(), AxisError> {
        Err(AxisError::Unsupported("soft limits"))
    }
    /// The hard limit inputs, `(pin, active level)` for the min and max side.
    fn set_limit_pins(
        &self,
        _min: Option<(u8, bool)>,
        _max: Option<(u8, bool)>,
    ) -> Result<(), AxisError> {
        Err(AxisError::Unsupported("hard limits"))
    }
    /// Forgets a tripped hard limit.
    fn clear_limit_fault(&self) -> Result<(), AxisError> {
        Err(AxisError::Unsupported("hard limits"))
    }
    /// The limit and homing state.
    fn limit_status(&self) -> Result<LimitStatus, AxisError> {
        Err(AxisError::Unsupported("limits"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The flags sit where the reference's mode long has them (`Step_driver2`:
    /// bit 0 moving, 1 accel, 2 decel, 3 at speed, 4 direction, 5 stop
    /// latched); cogstep's own are above bit 7, out of the demo's six.
    #[test]
    fn mode_flags_keep_the_reference_layout() {
        let layout = [
            (Mode::MOVING, 0),
            (Mode::ACCEL, 1),
            (Mode::DECEL, 2),
            (Mode::SLEW, 3),
            (Mode::REVERSE, 4),
            (Mode::STOP_LATCHED, 5),
            (Mode::ESTOP, 8),
            (Mode::HOLD, 9),
            (Mode::JOG, 10),
        ];
        for (flag, bit) in layout {
            assert_eq!(flag.bits(), 1 << bit, "{flag:?}");
        }
        let mode = Mode::MOVING | Mode::ACCEL | Mode::REVERSE | Mode::JOG;
        assert_eq!(mode.bits(), 0b100_0001_0011);
        assert_eq!(mode.reference_bits(), 0b01_0011);
        assert_eq!(&mode.binary(), b"010011");
        // A status word from elsewhere keeps bits cogstep does not name.
        assert_eq!(Mode(1 << 20 | 1).bits(), 1 << 20 | 1);
        assert!(Mode(1 << 20 | 1).contains(Mode::MOVING));
    }
}

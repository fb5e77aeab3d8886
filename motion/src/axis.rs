//! The axis contract: what every backend offers for one motor axis.
//!
//! The emulated hub's [`Axis`](crate::Axis) and the serial backend both
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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Mode(pub u32);

impl Mode {
    /// Bit 0: a move is in progress.
    pub const MOVING: u32 = 1 << 0;
    /// Bit 1: accelerating.
    pub const ACCEL: u32 = 1 << 1;
    /// Bit 2: decelerating.
    pub const DECEL: u32 = 1 << 2;
    /// Bit 3: at slew speed.
    pub const SLEW: u32 = 1 << 3;
    /// Bit 4: moving in the negative direction.
    pub const REVERSE: u32 = 1 << 4;
    /// Bit 5: a controlled stop (stop pin low) happened; cleared by the next move.
    pub const STOP_LATCHED: u32 = 1 << 5;
    /// Bit 8 (cogstep): emergency stopped; cleared by the next move.
    pub const ESTOP: u32 = 1 << 8;
    /// Bit 9 (cogstep): a move is waiting for the stop pin to go high.
    pub const HOLD: u32 = 1 << 9;
    /// Bit 10 (cogstep): the move is a jog (kept alive by heartbeats).
    pub const JOG: u32 = 1 << 10;

    /// The reference driver's 6-bit layout (bits 0–5).
    pub fn bits(self) -> u32 {
        self.0 & 0x3F
    }

    /// Every flag, cogstep's included.
    pub fn raw(self) -> u32 {
        self.0
    }

    /// Whether all of `flags` are set.
    pub fn has(self, flags: u32) -> bool {
        self.0 & flags == flags
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
    /// Idle, Run, Jog, Hold or Alarm.
    pub fn state(&self) -> AxisState {
        AxisState::from_mode(self.mode, self.stop_pin_high)
    }
}

/// Why an axis refused a request. A refused request changes nothing.
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
}

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

/// The texts of the [`AxisError::BadSetting`]s the axis core and the hub
/// give, one per setting that cannot work, so that a backend that reads a
/// refusal back (the serial host) gives the very same error.
pub mod bad_setting {
    /// Soft limits whose min is above their max.
    pub const SOFT_MIN_ABOVE_MAX: &str = "the soft min is above the soft max";
    /// A limit pin of 64 or more.
    pub const LIMIT_PIN_OUT_OF_RANGE: &str = "limit pins are 0 to 63";
    /// A limit pin that is one of the axis's step outputs.
    pub const LIMIT_PIN_IS_OUTPUT: &str = "a limit pin is an output of the axis";
    /// A limit pin that is the axis's stop pin (the hub checks this).
    pub const LIMIT_PIN_IS_STOP_PIN: &str = "a limit pin is the stop pin";
    /// The min and max limits on one pin.
    pub const LIMITS_SHARE_A_PIN: &str = "the min and max limits share a pin";
    /// A home switch pin of 64 or more.
    pub const SWITCH_PIN_OUT_OF_RANGE: &str = "the switch pin must be 0 to 63";
    /// A home switch pin that is one of the axis's step outputs.
    pub const SWITCH_PIN_IS_OUTPUT: &str = "the switch pin is an output of the axis";
    /// A homing travel of 0 or beyond 2^31 - 1 steps.
    pub const MAX_TRAVEL_OUT_OF_RANGE: &str = "max_travel must be 1 to 2^31 - 1";
    /// A homing back-off of 0 or beyond 2^30 steps.
    pub const BACKOFF_OUT_OF_RANGE: &str = "backoff_steps must be 1 to 2^30";
}

/// Every refusal an axis can give, as one fieldless kind: what
/// [`AxisError`] says apart from the transport errors (`Unavailable`,
/// `Fault`, `Unsupported`) and apart from the numbers a few refusals carry
/// ([`RefusalValues`]).
///
/// Each has a stable [`code`](Refusal::code) (for a mailbox or a binary
/// link) and a stable kebab-case [`token`](Refusal::token) (for text);
/// neither changes once given, and new refusals get new ones. Codes are
/// grouped: 1–31 what the axis is doing and the move's own range, 32–63
/// the plan ([`PlanError`]), 64–95 settings ([`bad_setting`]).
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Refusal {
    /// [`AxisError::Busy`].
    Busy = 1,
    /// [`AxisError::NotIdle`].
    NotIdle = 2,
    /// [`AxisError::Jogging`].
    Jogging = 3,
    /// [`AxisError::StopPinLow`].
    StopPinLow = 4,
    /// [`AxisError::TooManySteps`].
    TooManySteps = 5,
    /// [`AxisError::PositionOutOfRange`].
    PositionOutOfRange = 6,
    /// [`AxisError::StepsOutOfRange`].
    StepsOutOfRange = 7,
    /// [`AxisError::DuplicateAxis`].
    DuplicateAxis = 8,
    /// [`AxisError::PulseTooLong`] (carries the speed).
    PulseTooLong = 9,
    /// [`AxisError::Homing`].
    Homing = 10,
    /// [`AxisError::BeyondSoftLimit`].
    BeyondSoftLimit = 11,
    /// [`AxisError::IntoLimit`]`(Reverse)`: the min limit.
    IntoLimitMin = 12,
    /// [`AxisError::IntoLimit`]`(Forward)`: the max limit.
    IntoLimitMax = 13,
    /// [`AxisError::HomeSwitchNotFound`].
    HomeSwitchNotFound = 14,
    /// [`AxisError::HomeSwitchStuck`].
    HomeSwitchStuck = 15,
    /// [`AxisError::HomingAborted`].
    HomingAborted = 16,
    /// [`PlanError::ZeroSpeed`].
    ZeroSpeed = 32,
    /// [`PlanError::ZeroSteps`].
    ZeroSteps = 33,
    /// [`PlanError::ZeroClock`].
    ZeroClock = 34,
    /// [`PlanError::SpeedTooHigh`] (carries the speed and the clock).
    SpeedTooHigh = 35,
    /// [`PlanError::BadOffset`] (carries the offset).
    BadOffset = 36,
    /// [`PlanError::BadAccelDiv`].
    BadAccelDiv = 37,
    /// [`PlanError::BadAccel`].
    BadAccel = 38,
    /// [`PlanError::BadSpeed`].
    BadSpeed = 39,
    /// [`PlanError::DelayOverflow`].
    DelayOverflow = 40,
    /// [`bad_setting::SOFT_MIN_ABOVE_MAX`].
    SoftMinAboveMax = 64,
    /// [`bad_setting::LIMIT_PIN_OUT_OF_RANGE`].
    LimitPinOutOfRange = 65,
    /// [`bad_setting::LIMIT_PIN_IS_OUTPUT`].
    LimitPinIsOutput = 66,
    /// [`bad_setting::LIMIT_PIN_IS_STOP_PIN`].
    LimitPinIsStopPin = 67,
    /// [`bad_setting::LIMITS_SHARE_A_PIN`].
    LimitsShareAPin = 68,
    /// [`bad_setting::SWITCH_PIN_OUT_OF_RANGE`].
    SwitchPinOutOfRange = 69,
    /// [`bad_setting::SWITCH_PIN_IS_OUTPUT`].
    SwitchPinIsOutput = 70,
    /// [`bad_setting::MAX_TRAVEL_OUT_OF_RANGE`].
    MaxTravelOutOfRange = 71,
    /// [`bad_setting::BACKOFF_OUT_OF_RANGE`].
    BackoffOutOfRange = 72,
}

/// The numbers a refusal carries besides its kind: the speed of
/// [`Refusal::PulseTooLong`] and [`Refusal::SpeedTooHigh`], the clock of
/// `SpeedTooHigh`, the offset of [`Refusal::BadOffset`]; 0 where the
/// refusal has none.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct RefusalValues {
    /// Steps/s.
    pub speed: u32,
    /// Hz.
    pub clkfreq: u32,
    /// Degrees.
    pub offset_deg: u32,
}

impl Refusal {
    /// Every refusal, in code order.
    pub const ALL: [Refusal; 34] = [
        Refusal::Busy,
        Refusal::NotIdle,
        Refusal::Jogging,
        Refusal::StopPinLow,
        Refusal::TooManySteps,
        Refusal::PositionOutOfRange,
        Refusal::StepsOutOfRange,
        Refusal::DuplicateAxis,
        Refusal::PulseTooLong,
        Refusal::Homing,
        Refusal::BeyondSoftLimit,
        Refusal::IntoLimitMin,
        Refusal::IntoLimitMax,
        Refusal::HomeSwitchNotFound,
        Refusal::HomeSwitchStuck,
        Refusal::HomingAborted,
        Refusal::ZeroSpeed,
        Refusal::ZeroSteps,
        Refusal::ZeroClock,
        Refusal::SpeedTooHigh,
        Refusal::BadOffset,
        Refusal::BadAccelDiv,
        Refusal::BadAccel,
        Refusal::BadSpeed,
        Refusal::DelayOverflow,
        Refusal::SoftMinAboveMax,
        Refusal::LimitPinOutOfRange,
        Refusal::LimitPinIsOutput,
        Refusal::LimitPinIsStopPin,
        Refusal::LimitsShareAPin,
        Refusal::SwitchPinOutOfRange,
        Refusal::SwitchPinIsOutput,
        Refusal::MaxTravelOutOfRange,
        Refusal::BackoffOutOfRange,
    ];

    /// The stable code.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The refusal with this code; `None` for a code no refusal has.
    pub fn from_code(code: u8) -> Option<Refusal> {
        Self::ALL.into_iter().find(|refusal| refusal.code() == code)
    }

    /// The stable kebab-case name.
    pub fn token(self) -> &'static str {
        match self {
            Refusal::Busy => "busy",
            Refusal::NotIdle => "not-idle",
            Refusal::Jogging => "jogging",
            Refusal::StopPinLow => "stop-pin-low",
            Refusal::TooManySteps => "too-many-steps",
            Refusal::PositionOutOfRange => "position-out-of-range",
            Refusal::StepsOutOfRange => "steps-out-of-range",
            Refusal::DuplicateAxis => "duplicate-axis",
            Refusal::PulseTooLong => "pulse-too-long",
            Refusal::Homing => "homing",
            Refusal::BeyondSoftLimit => "beyond-soft-limit",
            Refusal::IntoLimitMin => "into-limit-min",
            Refusal::IntoLimitMax => "into-limit-max",
            Refusal::HomeSwitchNotFound => "home-switch-not-found",
            Refusal::HomeSwitchStuck => "home-switch-stuck",
            Refusal::HomingAborted => "homing-aborted",
            Refusal::ZeroSpeed => "zero-speed",
            Refusal::ZeroSteps => "zero-steps",
            Refusal::ZeroClock => "zero-clock",
            Refusal::SpeedTooHigh => "speed-too-high",
            Refusal::BadOffset => "bad-offset",
            Refusal::BadAccelDiv => "bad-accel-div",
            Refusal::BadAccel => "bad-accel",
            Refusal::BadSpeed => "bad-speed",
            Refusal::DelayOverflow => "delay-overflow",
            Refusal::SoftMinAboveMax => "soft-min-above-max",
            Refusal::LimitPinOutOfRange => "limit-pin-out-of-range",
            Refusal::LimitPinIsOutput => "limit-pin-is-output",
            Refusal::LimitPinIsStopPin => "limit-pin-is-stop-pin",
            Refusal::LimitsShareAPin => "limits-share-a-pin",
            Refusal::SwitchPinOutOfRange => "switch-pin-out-of-range",
            Refusal::SwitchPinIsOutput => "switch-pin-is-output",
            Refusal::MaxTravelOutOfRange => "max-travel-out-of-range",
            Refusal::BackoffOutOfRange => "backoff-out-of-range",
        }
    }

    /// The refusal with this token (exactly, case and all); `None` for
    /// any other text.
    pub fn from_token(token: &str) -> Option<Refusal> {
        Self::ALL
            .into_iter()
            .find(|refusal| refusal.token() == token)
    }

    /// The [`bad_setting`] text of a setting refusal.
    pub fn bad_setting_text(self) -> Option<&'static str> {
        match AxisError::from_refusal(self, RefusalValues::default()) {
            AxisError::BadSetting(text) => Some(text),
            _ => None,
        }
    }
}

impl AxisError {
    /// Which refusal this is; `None` for the transport errors
    /// (`Unavailable`, `Fault`, `Unsupported`) and for a `BadSetting`
    /// whose text is none of [`bad_setting`]'s.
    pub fn refusal(&self) -> Option<Refusal> {
        Some(match *self {
            AxisError::Plan(plan) => match plan {
                PlanError::ZeroSpeed => Refusal::ZeroSpeed,
                PlanError::ZeroSteps => Refusal::ZeroSteps,
                PlanError::ZeroClock => Refusal::ZeroClock,
                PlanError::SpeedTooHigh { .. } => Refusal::SpeedTooHigh,
                PlanError::BadOffset(_) => Refusal::BadOffset,
                PlanError::BadAccelDiv => Refusal::BadAccelDiv,
                PlanError::BadAccel => Refusal::BadAccel,
                PlanError::BadSpeed => Refusal::BadSpeed,
                PlanError::DelayOverflow => Refusal::DelayOverflow,
            },
            AxisError::Busy => Refusal::Busy,
            AxisError::NotIdle => Refusal::NotIdle,
            AxisError::PulseTooLong { .. } => Refusal::PulseTooLong,
            AxisError::Unsupported(_) | AxisError::Unavailable | AxisError::Fault(_) => {
                return None
            }
            AxisError::Jogging => Refusal::Jogging,
            AxisError::StopPinLow => Refusal::StopPinLow,
            AxisError::TooManySteps => Refusal::TooManySteps,
            AxisError::PositionOutOfRange => Refusal::PositionOutOfRange,
            AxisError::StepsOutOfRange => Refusal::StepsOutOfRange,
            AxisError::DuplicateAxis => Refusal::DuplicateAxis,
            AxisError::Homing => Refusal::Homing,
            AxisError::BeyondSoftLimit => Refusal::BeyondSoftLimit,
            AxisError::IntoLimit(Direction::Reverse) => Refusal::IntoLimitMin,
            AxisError::IntoLimit(Direction::Forward) => Refusal::IntoLimitMax,
            AxisError::HomeSwitchNotFound => Refusal::HomeSwitchNotFound,
            AxisError::HomeSwitchStuck => Refusal::HomeSwitchStuck,
            AxisError::HomingAborted => Refusal::HomingAborted,
            AxisError::BadSetting(text) => {
                return Refusal::ALL
                    .into_iter()
                    .find(|refusal| refusal.bad_setting_text() == Some(text))
            }
        })
    }

    /// The numbers this error carries (see [`RefusalValues`]).
    pub fn refusal_values(&self) -> RefusalValues {
        match *self {
            AxisError::PulseTooLong { speed } => RefusalValues {
                speed,
                ..RefusalValues::default()
            },
            AxisError::Plan(PlanError::SpeedTooHigh { speed, clkfreq }) => RefusalValues {
                speed,
                clkfreq,
                ..RefusalValues::default()
            },
            AxisError::Plan(PlanError::BadOffset(offset_deg)) => RefusalValues {
                offset_deg,
                ..RefusalValues::default()
            },
            _ => RefusalValues::default(),
        }
    }

    /// The error a refusal and its numbers stand for: the inverse of
    /// [`AxisError::refusal`] and [`AxisError::refusal_values`].
    pub fn from_refusal(refusal: Refusal, values: RefusalValues) -> AxisError {
        match refusal {
            Refusal::Busy => AxisError::Busy,
            Refusal::NotIdle => AxisError::NotIdle,
            Refusal::Jogging => AxisError::Jogging,
            Refusal::StopPinLow => AxisError::StopPinLow,
            Refusal::TooManySteps => AxisError::TooManySteps,
            Refusal::PositionOutOfRange => AxisError::PositionOutOfRange,
            Refusal::StepsOutOfRange => AxisError::StepsOutOfRange,
            Refusal::DuplicateAxis => AxisError::DuplicateAxis,
            Refusal::PulseTooLong => AxisError::PulseTooLong {
                speed: values.speed,
            },
            Refusal::Homing => AxisError::Homing,
            Refusal::BeyondSoftLimit => AxisError::BeyondSoftLimit,
            Refusal::IntoLimitMin => AxisError::IntoLimit(Direction::Reverse),
            Refusal::IntoLimitMax => AxisError::IntoLimit(Direction::Forward),
            Refusal::HomeSwitchNotFound => AxisError::HomeSwitchNotFound,
            Refusal::HomeSwitchStuck => AxisError::HomeSwitchStuck,
            Refusal::HomingAborted => AxisError::HomingAborted,
            Refusal::ZeroSpeed => PlanError::ZeroSpeed.into(),
            Refusal::ZeroSteps => PlanError::ZeroSteps.into(),
            Refusal::ZeroClock => PlanError::ZeroClock.into(),
            Refusal::SpeedTooHigh => PlanError::SpeedTooHigh {
                speed: values.speed,
                clkfreq: values.clkfreq,
            }
            .into(),
            Refusal::BadOffset => PlanError::BadOffset(values.offset_deg).into(),
            Refusal::BadAccelDiv => PlanError::BadAccelDiv.into(),
            Refusal::BadAccel => PlanError::BadAccel.into(),
            Refusal::BadSpeed => PlanError::BadSpeed.into(),
            Refusal::DelayOverflow => PlanError::DelayOverflow.into(),
            Refusal::SoftMinAboveMax => AxisError::BadSetting(bad_setting::SOFT_MIN_ABOVE_MAX),
            Refusal::LimitPinOutOfRange => {
                AxisError::BadSetting(bad_setting::LIMIT_PIN_OUT_OF_RANGE)
            }
            Refusal::LimitPinIsOutput => AxisError::BadSetting(bad_setting::LIMIT_PIN_IS_OUTPUT),
            Refusal::LimitPinIsStopPin => AxisError::BadSetting(bad_setting::LIMIT_PIN_IS_STOP_PIN),
            Refusal::LimitsShareAPin => AxisError::BadSetting(bad_setting::LIMITS_SHARE_A_PIN),
            Refusal::SwitchPinOutOfRange => {
                AxisError::BadSetting(bad_setting::SWITCH_PIN_OUT_OF_RANGE)
            }
            Refusal::SwitchPinIsOutput => AxisError::BadSetting(bad_setting::SWITCH_PIN_IS_OUTPUT),
            Refusal::MaxTravelOutOfRange => {
                AxisError::BadSetting(bad_setting::MAX_TRAVEL_OUT_OF_RANGE)
            }
            Refusal::BackoffOutOfRange => AxisError::BadSetting(bad_setting::BACKOFF_OUT_OF_RANGE),
        }
    }
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

    /// Every error an axis core (or the hub over it) can refuse with, one
    /// of each kind, with the numbers some carry.
    fn every_refusing_error() -> std::vec::Vec<AxisError> {
        let mut errors = std::vec![
            AxisError::Busy,
            AxisError::NotIdle,
            AxisError::Jogging,
            AxisError::StopPinLow,
            AxisError::TooManySteps,
            AxisError::PositionOutOfRange,
            AxisError::StepsOutOfRange,
            AxisError::DuplicateAxis,
            AxisError::PulseTooLong { speed: 50_000_000 },
            AxisError::Homing,
            AxisError::BeyondSoftLimit,
            AxisError::IntoLimit(Direction::Reverse),
            AxisError::IntoLimit(Direction::Forward),
            AxisError::HomeSwitchNotFound,
            AxisError::HomeSwitchStuck,
            AxisError::HomingAborted,
            PlanError::ZeroSpeed.into(),
            PlanError::ZeroSteps.into(),
            PlanError::ZeroClock.into(),
            PlanError::SpeedTooHigh {
                speed: u32::MAX,
                clkfreq: 200_000_000,
            }
            .into(),
            PlanError::BadOffset(90).into(),
            PlanError::BadAccelDiv.into(),
            PlanError::BadAccel.into(),
            PlanError::BadSpeed.into(),
            PlanError::DelayOverflow.into(),
        ];
        errors.extend(
            [
                bad_setting::SOFT_MIN_ABOVE_MAX,
                bad_setting::LIMIT_PIN_OUT_OF_RANGE,
                bad_setting::LIMIT_PIN_IS_OUTPUT,
                bad_setting::LIMIT_PIN_IS_STOP_PIN,
                bad_setting::LIMITS_SHARE_A_PIN,
                bad_setting::SWITCH_PIN_OUT_OF_RANGE,
                bad_setting::SWITCH_PIN_IS_OUTPUT,
                bad_setting::MAX_TRAVEL_OUT_OF_RANGE,
                bad_setting::BACKOFF_OUT_OF_RANGE,
            ]
            .map(AxisError::BadSetting),
        );
        errors
    }

    #[test]
    fn every_refusal_round_trips_by_code_token_and_error() {
        let mut codes = std::collections::BTreeSet::new();
        let mut tokens = std::collections::BTreeSet::new();
        for refusal in Refusal::ALL {
            assert!(codes.insert(refusal.code()), "{refusal:?}");
            assert!(tokens.insert(refusal.token()), "{refusal:?}");
            assert_eq!(Refusal::from_code(refusal.code()), Some(refusal));
            assert_eq!(Refusal::from_token(refusal.token()), Some(refusal));
            let token = refusal.token();
            assert!(
                token.bytes().all(|b| b.is_ascii_lowercase() || b == b'-')
                    && !token.starts_with('-')
                    && !token.ends_with('-')
                    && !token.contains("--"),
                "{token} is not kebab-case"
            );
            let values = RefusalValues {
                speed: 7,
                clkfreq: 11,
                offset_deg: 13,
            };
            let error = AxisError::from_refusal(refusal, values);
            assert_eq!(error.refusal(), Some(refusal), "{error:?}");
            assert_eq!(
                AxisError::from_refusal(refusal, error.refusal_values()),
                error
            );
        }
        // Code order, and no code without a refusal.
        assert!(Refusal::ALL.windows(2).all(|pair| pair[0] < pair[1]));
        for code in 0..=u8::MAX {
            let known = Refusal::ALL.iter().any(|refusal| refusal.code() == code);
            assert_eq!(Refusal::from_code(code).is_some(), known, "{code}");
        }
        assert_eq!(Refusal::from_token("Busy"), None);
        assert_eq!(Refusal::from_token("busy "), None);
    }

    #[test]
    fn every_refusing_error_is_exactly_one_refusal() {
        let errors = every_refusing_error();
        let mut seen = std::collections::BTreeSet::new();
        for error in &errors {
            let refusal = error.refusal().unwrap_or_else(|| panic!("{error:?}"));
            assert!(seen.insert(refusal), "{refusal:?} twice");
            assert_eq!(
                AxisError::from_refusal(refusal, error.refusal_values()),
                *error
            );
        }
        assert_eq!(seen.len(), Refusal::ALL.len(), "a refusal no error gives");
        for transport in [
            AxisError::Unavailable,
            AxisError::Fault("lost"),
            AxisError::Unsupported("jog"),
            AxisError::BadSetting("a text no core gives"),
        ] {
            assert_eq!(transport.refusal(), None, "{transport:?}");
        }
    }

    /// The axis core's setting refusals use [`bad_setting`]'s texts, so
    /// that they decode to a [`Refusal`].
    #[test]
    fn the_core_refuses_settings_with_the_shared_texts() {
        use crate::axis_core::{AxisCore, AxisCoreConfig, CoreCommand, Outputs};
        let config = AxisCoreConfig::new(Outputs::StepDir { step: 1, dir: 2 });
        let mut core = AxisCore::new(config, 0);
        let home = |change: fn(&mut HomeConfig)| {
            let mut home = HomeConfig {
                switch_pin: 9,
                ..HomeConfig::default()
            };
            change(&mut home);
            CoreCommand::Home(home)
        };
        let cases = [
            (
                CoreCommand::SetSoftLimits(Some((10, -10))),
                Refusal::SoftMinAboveMax,
            ),
            (
                CoreCommand::SetLimitPins {
                    min: Some((64, true)),
                    max: None,
                },
                Refusal::LimitPinOutOfRange,
            ),
            (
                CoreCommand::SetLimitPins {
                    min: None,
                    max: Some((2, true)),
                },
                Refusal::LimitPinIsOutput,
            ),
            (
                CoreCommand::SetLimitPins {
                    min: Some((9, true)),
                    max: Some((9, false)),
                },
                Refusal::LimitsShareAPin,
            ),
            (
                home(|home| home.switch_pin = 64),
                Refusal::SwitchPinOutOfRange,
            ),
            (home(|home| home.switch_pin = 1), Refusal::SwitchPinIsOutput),
            (
                home(|home| home.max_travel = 0),
                Refusal::MaxTravelOutOfRange,
            ),
            (
                home(|home| home.backoff_steps = (1 << 30) + 1),
                Refusal::BackoffOutOfRange,
            ),
        ];
        for (command, refusal) in cases {
            let error = core.command(0, command).unwrap_err();
            assert_eq!(error.refusal(), Some(refusal), "{command:?}: {error:?}");
        }
    }

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

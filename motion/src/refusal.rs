//! An axis's refusals as one kind: [`Refusal`], every reason an axis can
//! refuse a request apart from the transport errors, each with a stable
//! code and token, so that every backend and every link (a mailbox, the
//! serial protocol) carries the same refusal and a host gets back the
//! very [`AxisError`] the axis gave. The texts of the setting refusals
//! are here too ([`bad_setting`]), shared by the core and its readers.

use crate::axis::{AxisError, Direction};
use crate::profile::PlanError;

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
    /// A limit or home switch pin that is not one of the board's switch
    /// inputs (a board with inputs checks this; see its pin map).
    pub const PIN_NOT_A_SWITCH_INPUT: &str = "the pin is not a switch input of the board";
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
    /// [`bad_setting::PIN_NOT_A_SWITCH_INPUT`].
    PinNotASwitchInput = 73,
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
    pub const ALL: [Refusal; 35] = [
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
        Refusal::PinNotASwitchInput,
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
            Refusal::PinNotASwitchInput => "pin-not-a-switch-input",
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
            Refusal::PinNotASwitchInput => {
                AxisError::BadSetting(bad_setting::PIN_NOT_A_SWITCH_INPUT)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis::HomeConfig;

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
                bad_setting::PIN_NOT_A_SWITCH_INPUT,
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
}

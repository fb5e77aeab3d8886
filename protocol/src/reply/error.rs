//! The refusals: [`ErrorCode`] (the numbers on the wire), [`ProtocolError`]
//! (why a line was refused) and its reply line, an axis's refusals
//! written through the refusal table.

use core::fmt;

use cogstep_motion::axis::AxisError;

use super::printable::{write_printable, BACKEND_TEXT_MAX};
use super::LINE_END;

/// The protocol's error codes (`error:<code> <text>`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorCode {
    /// 1: the command letter is unknown (or this board does not support it).
    UnknownCommand = 1,
    /// 2: an argument is missing, extra or malformed, or the line holds a
    /// byte that is not printable ASCII.
    BadArgument = 2,
    /// 3: the axis already has a command waiting.
    Busy = 3,
    /// 4: no axis with that number (or it is not available).
    NoSuchAxis = 4,
    /// 5: the line was longer than [`LINE_MAX`](crate::LINE_MAX) bytes.
    LineTooLong = 5,
    /// 6: the speed is outside what the axis can run.
    SpeedOutOfRange = 6,
    /// 7: the command needs an idle axis.
    NotIdle = 7,
    /// 8: the line's `*HH` checksum does not match.
    Checksum = 8,
    /// 9: a limit refuses the move: it would end beyond a soft limit, or
    /// goes towards a hard limit that tripped or reads active.
    Limit = 9,
    /// 10: the axis is homing, or homing failed.
    Homing = 10,
}

impl ErrorCode {
    /// Every code, in order.
    pub const ALL: [ErrorCode; 10] = [
        ErrorCode::UnknownCommand,
        ErrorCode::BadArgument,
        ErrorCode::Busy,
        ErrorCode::NoSuchAxis,
        ErrorCode::LineTooLong,
        ErrorCode::SpeedOutOfRange,
        ErrorCode::NotIdle,
        ErrorCode::Checksum,
        ErrorCode::Limit,
        ErrorCode::Homing,
    ];

    /// The number on the wire.
    pub fn number(self) -> u8 {
        self as u8
    }

    /// The code with this number.
    pub fn from_number(number: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|code| code.number() == number)
    }

    /// The text the board sends after the code (unless the error carries
    /// its own, see [`ProtocolError::write_reply`]).
    pub fn text(self) -> &'static str {
        match self {
            ErrorCode::UnknownCommand => "unknown command",
            ErrorCode::BadArgument => "bad argument",
            ErrorCode::Busy => "busy",
            ErrorCode::NoSuchAxis => "no such axis",
            ErrorCode::LineTooLong => "line too long",
            ErrorCode::SpeedOutOfRange => "speed out of range",
            ErrorCode::NotIdle => "not idle",
            ErrorCode::Checksum => "checksum",
            ErrorCode::Limit => "limit",
            ErrorCode::Homing => "homing",
        }
    }
}

/// Why a command line was refused. A refused line changes nothing (but see
/// `S *` and `R *` in the protocol notes: every axis is tried).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ProtocolError {
    /// No command letter, or one the protocol does not know.
    #[error("unknown command")]
    UnknownCommand,
    /// A byte that is not printable ASCII (control bytes, 0x7F, non-ASCII).
    #[error("byte {0:#04x} is not allowed in a command line")]
    BadByte(u8),
    /// The command needs more arguments.
    #[error("missing argument")]
    MissingArgument,
    /// The command takes fewer arguments.
    #[error("too many arguments")]
    ExtraArgument,
    /// An argument is not a decimal number (or a position outside `i64`).
    #[error("not a number")]
    BadNumber,
    /// A jog direction other than `+` or `-`.
    #[error("the direction must be + or -")]
    BadDirection,
    /// A pin above 255, a level other than 0 or 1, or a limit pin not
    /// written `<pin>/<level>` or `-` (which pins an axis can use is the
    /// axis's to say).
    #[error("a pin must be 0 to 255 and a level 0 or 1 (<pin>/<level> or -)")]
    BadPin,
    /// Steps of 0, or of more than 2,147,483,647 either way (a homing
    /// count: more than 4,294,967,295).
    #[error("steps must be 1 to 2147483647, either sign")]
    StepsOutOfRange,
    /// A speed of 0, negative, or above `u32::MAX` steps/s.
    #[error("speed must be 1 to 4294967295 steps/s")]
    SpeedOutOfRange,
    /// The line was longer than [`LINE_MAX`](crate::LINE_MAX) bytes.
    #[error("line too long")]
    LineTooLong,
    /// The `*HH` suffix does not match the line.
    #[error("checksum: the line XORs to {computed:02X}, it states {stated:02X}")]
    Checksum {
        /// The XOR of the bytes before `*`.
        computed: u8,
        /// The two hex digits after `*`.
        stated: u8,
    },
    /// The board has no axis with this number.
    #[error("no such axis: {0}")]
    NoSuchAxis(usize),
    /// The axis refused the request.
    #[error(transparent)]
    Axis(#[from] AxisError),
}

impl ProtocolError {
    /// The code on the wire.
    pub fn code(&self) -> ErrorCode {
        match self {
            ProtocolError::UnknownCommand => ErrorCode::UnknownCommand,
            ProtocolError::BadByte(_)
            | ProtocolError::MissingArgument
            | ProtocolError::ExtraArgument
            | ProtocolError::BadNumber
            | ProtocolError::BadDirection
            | ProtocolError::BadPin
            | ProtocolError::StepsOutOfRange => ErrorCode::BadArgument,
            ProtocolError::SpeedOutOfRange => ErrorCode::SpeedOutOfRange,
            ProtocolError::LineTooLong => ErrorCode::LineTooLong,
            ProtocolError::Checksum { .. } => ErrorCode::Checksum,
            ProtocolError::NoSuchAxis(_) => ErrorCode::NoSuchAxis,
            ProtocolError::Axis(error) => axis_error_code(error),
        }
    }

    /// Writes the reply line: `error:<code> <text>` and [`LINE_END`]. An
    /// axis's refusal is written as the refusal table has it
    /// ([`write_refusal_line`](crate::write_refusal_line)); the transport
    /// errors name what went wrong: `not supported: <what>` (code 1), `axis
    /// not available` (code 4), `fault: <what>` (code 2), and a setting no
    /// refusal names `bad argument: <what>` (code 2); every other error is
    /// its code's [`text`](ErrorCode::text).
    pub fn write_reply<W: fmt::Write + ?Sized>(&self, out: &mut W) -> fmt::Result {
        if let ProtocolError::Axis(error) = self {
            if let Some(refusal) = error.refusal() {
                return crate::write_refusal_line(out, refusal, &error.refusal_values());
            }
        }
        let code = self.code();
        write!(out, "error:{} ", code.number())?;
        match self {
            ProtocolError::Axis(AxisError::Unsupported(what)) => {
                out.write_str("not supported: ")?;
                write_printable(out, what, BACKEND_TEXT_MAX)?;
            }
            ProtocolError::Axis(AxisError::Unavailable) => out.write_str("axis not available")?,
            ProtocolError::Axis(AxisError::Fault(what)) => {
                out.write_str("fault: ")?;
                write_printable(out, what, BACKEND_TEXT_MAX)?;
            }
            ProtocolError::Axis(AxisError::BadSetting(what)) => {
                out.write_str("bad argument: ")?;
                write_printable(out, what, BACKEND_TEXT_MAX)?;
            }
            _ => out.write_str(code.text())?,
        }
        out.write_str(LINE_END)
    }
}

/// The code an axis's error is reported with: a refusal's from the
/// refusal table, the transport errors' own.
fn axis_error_code(error: &AxisError) -> ErrorCode {
    if let Some(refusal) = error.refusal() {
        return crate::refusal_code(refusal);
    }
    match error {
        AxisError::Unsupported(_) => ErrorCode::UnknownCommand,
        AxisError::Unavailable => ErrorCode::NoSuchAxis,
        _ => ErrorCode::BadArgument,
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::string::String;

    use super::*;
    use cogstep_motion::profile::PlanError;

    fn reply_of(error: ProtocolError) -> String {
        let mut out = String::new();
        error.write_reply(&mut out).unwrap();
        out
    }

    #[test]
    fn every_code_has_its_number_and_text() {
        let expected = [
            (1, "unknown command"),
            (2, "bad argument"),
            (3, "busy"),
            (4, "no such axis"),
            (5, "line too long"),
            (6, "speed out of range"),
            (7, "not idle"),
            (8, "checksum"),
            (9, "limit"),
            (10, "homing"),
        ];
        for (code, (number, text)) in ErrorCode::ALL.into_iter().zip(expected) {
            assert_eq!(code.number(), number);
            assert_eq!(code.text(), text);
            assert_eq!(ErrorCode::from_number(number), Some(code));
        }
        assert_eq!(ErrorCode::from_number(0), None);
        assert_eq!(ErrorCode::from_number(11), None);
    }

    #[test]
    fn axis_errors_map_to_codes() {
        let cases: [(AxisError, &str); 14] = [
            (
                PlanError::ZeroSpeed.into(),
                "error:6 speed out of range: below 1 step/s\n",
            ),
            (
                PlanError::SpeedTooHigh {
                    speed: 1,
                    clkfreq: 1,
                }
                .into(),
                "error:6 speed out of range: 1 steps/s is too fast for 1 Hz\n",
            ),
            (
                PlanError::BadSpeed.into(),
                "error:6 speed out of range: not positive and finite\n",
            ),
            (
                PlanError::DelayOverflow.into(),
                "error:6 speed out of range: a step longer than 2^32 ticks\n",
            ),
            (
                PlanError::ZeroSteps.into(),
                "error:2 bad argument: zero steps\n",
            ),
            (
                PlanError::ZeroClock.into(),
                "error:2 bad argument: a 0 Hz clock\n",
            ),
            (
                PlanError::BadOffset(0).into(),
                "error:2 bad argument: an S-curve offset of 0 degrees\n",
            ),
            (
                PlanError::BadAccel.into(),
                "error:2 bad argument: an acceleration not positive and finite\n",
            ),
            (AxisError::Busy, "error:3 busy\n"),
            (AxisError::NotIdle, "error:7 not idle\n"),
            (
                AxisError::PulseTooLong { speed: 9 },
                "error:6 speed out of range: no room for the step pulse at 9 steps/s\n",
            ),
            (
                AxisError::Unsupported("jog"),
                "error:1 not supported: jog\n",
            ),
            (AxisError::Unavailable, "error:4 axis not available\n"),
            (
                AxisError::Fault("driver\nhot\u{e9}"),
                "error:2 fault: driver?hot?\n",
            ),
        ];
        for (error, line) in cases {
            assert_eq!(reply_of(error.into()), line, "{error:?}");
        }
    }

    #[test]
    fn backend_texts_are_cut_to_fit_a_line() {
        const LONG: &str = "a fault description far longer than any reply line should ever be, \
                            really much longer than that";
        let line = reply_of(AxisError::Fault(LONG).into());
        assert_eq!(
            line.len(),
            "error:2 fault: ".len() + BACKEND_TEXT_MAX + LINE_END.len()
        );
        assert!(line.len() <= crate::REPLY_LINE_MAX);
    }

    #[test]
    fn protocol_errors_use_the_fixed_texts() {
        assert_eq!(
            reply_of(ProtocolError::LineTooLong),
            "error:5 line too long\n"
        );
        assert_eq!(
            reply_of(ProtocolError::Checksum {
                computed: 1,
                stated: 2
            }),
            "error:8 checksum\n"
        );
        assert_eq!(
            reply_of(ProtocolError::BadByte(0)),
            "error:2 bad argument\n"
        );
        assert_eq!(
            reply_of(ProtocolError::NoSuchAxis(9)),
            "error:4 no such axis\n"
        );
        assert_eq!(
            reply_of(ProtocolError::UnknownCommand),
            "error:1 unknown command\n"
        );
    }
}

//! An axis's refusals on the wire: the one table from each [`Refusal`] to
//! its `error:<code> <text>` line, which the board writes and the host
//! reads back.
//!
//! Every refusal has its own text, so the line says exactly which refusal
//! it is; where two refusals share a code's text they differ by a
//! `: <detail>` after it (`not idle`, `not idle: stop pin low`). The three
//! refusals that carry numbers write them in the text (`{}` in the table):
//!
//! ```text
//! error:6 speed out of range: no room for the step pulse at 50000000 steps/s
//! ```

use core::fmt;

use cogstep_motion::axis::AxisError;
use cogstep_motion::refusal::{bad_setting, Refusal, RefusalValues};

use super::reply::{ErrorCode, LINE_END};

/// A number a refusal's text carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Value {
    /// [`RefusalValues::speed`].
    Speed,
    /// [`RefusalValues::clkfreq`].
    Clock,
    /// [`RefusalValues::offset_deg`].
    Offset,
}

/// One row of the table: a refusal, its code, its text (a `{}` for each of
/// `values`, in order) and the numbers that fill the text.
struct Row {
    refusal: Refusal,
    code: ErrorCode,
    text: Text,
    values: &'static [Value],
}

/// A refusal's text: a whole line's text, or `bad argument: ` and a
/// [`bad_setting`] text.
#[derive(Clone, Copy)]
enum Text {
    Fixed(&'static str),
    Setting(&'static str),
}

const SETTING_PREFIX: &str = "bad argument: ";

const fn row(refusal: Refusal, code: ErrorCode, text: &'static str) -> Row {
    Row {
        refusal,
        code,
        text: Text::Fixed(text),
        values: &[],
    }
}

const fn setting(refusal: Refusal, text: &'static str) -> Row {
    Row {
        refusal,
        code: ErrorCode::BadArgument,
        text: Text::Setting(text),
        values: &[],
    }
}

const fn valued(
    refusal: Refusal,
    code: ErrorCode,
    text: &'static str,
    values: &'static [Value],
) -> Row {
    Row {
        refusal,
        code,
        text: Text::Fixed(text),
        values,
    }
}

use ErrorCode::{BadArgument, Busy, Homing, Limit, NotIdle, SpeedOutOfRange};

/// Every refusal's line, in [`Refusal::ALL`]'s order (tested).
const TABLE: [Row; Refusal::ALL.len()] = [
    row(Refusal::Busy, Busy, "busy"),
    row(Refusal::NotIdle, NotIdle, "not idle"),
    row(Refusal::Jogging, Busy, "busy: a jog is running"),
    row(Refusal::StopPinLow, NotIdle, "not idle: stop pin low"),
    row(
        Refusal::TooManySteps,
        BadArgument,
        "bad argument: too many steps",
    ),
    row(
        Refusal::PositionOutOfRange,
        BadArgument,
        "bad argument: position out of range",
    ),
    row(
        Refusal::StepsOutOfRange,
        BadArgument,
        "bad argument: steps out of range",
    ),
    row(
        Refusal::DuplicateAxis,
        BadArgument,
        "bad argument: an axis twice in a group move",
    ),
    valued(
        Refusal::PulseTooLong,
        SpeedOutOfRange,
        "speed out of range: no room for the step pulse at {} steps/s",
        &[Value::Speed],
    ),
    row(Refusal::Homing, Homing, "homing"),
    row(
        Refusal::BeyondSoftLimit,
        Limit,
        "limit: beyond a soft limit",
    ),
    row(Refusal::IntoLimitMin, Limit, "limit: min limit"),
    row(Refusal::IntoLimitMax, Limit, "limit: max limit"),
    row(
        Refusal::HomeSwitchNotFound,
        Homing,
        "homing: switch not found",
    ),
    row(Refusal::HomeSwitchStuck, Homing, "homing: switch stuck"),
    row(Refusal::HomingAborted, Homing, "homing: aborted"),
    row(
        Refusal::ZeroSpeed,
        SpeedOutOfRange,
        "speed out of range: below 1 step/s",
    ),
    row(Refusal::ZeroSteps, BadArgument, "bad argument: zero steps"),
    row(
        Refusal::ZeroClock,
        BadArgument,
        "bad argument: a 0 Hz clock",
    ),
    valued(
        Refusal::SpeedTooHigh,
        SpeedOutOfRange,
        "speed out of range: {} steps/s is too fast for {} Hz",
        &[Value::Speed, Value::Clock],
    ),
    valued(
        Refusal::BadOffset,
        BadArgument,
        "bad argument: an S-curve offset of {} degrees",
        &[Value::Offset],
    ),
    row(
        Refusal::BadAccelDiv,
        BadArgument,
        "bad argument: an acceleration divisor of 0",
    ),
    row(
        Refusal::BadAccel,
        BadArgument,
        "bad argument: an acceleration not positive and finite",
    ),
    row(
        Refusal::BadSpeed,
        SpeedOutOfRange,
        "speed out of range: not positive and finite",
    ),
    row(
        Refusal::DelayOverflow,
        SpeedOutOfRange,
        "speed out of range: a step longer than 2^32 ticks",
    ),
    setting(Refusal::SoftMinAboveMax, bad_setting::SOFT_MIN_ABOVE_MAX),
    setting(
        Refusal::LimitPinOutOfRange,
        bad_setting::LIMIT_PIN_OUT_OF_RANGE,
    ),
    setting(Refusal::LimitPinIsOutput, bad_setting::LIMIT_PIN_IS_OUTPUT),
    setting(
        Refusal::LimitPinIsStopPin,
        bad_setting::LIMIT_PIN_IS_STOP_PIN,
    ),
    setting(Refusal::LimitsShareAPin, bad_setting::LIMITS_SHARE_A_PIN),
    setting(
        Refusal::SwitchPinOutOfRange,
        bad_setting::SWITCH_PIN_OUT_OF_RANGE,
    ),
    setting(
        Refusal::SwitchPinIsOutput,
        bad_setting::SWITCH_PIN_IS_OUTPUT,
    ),
    setting(
        Refusal::MaxTravelOutOfRange,
        bad_setting::MAX_TRAVEL_OUT_OF_RANGE,
    ),
    setting(
        Refusal::BackoffOutOfRange,
        bad_setting::BACKOFF_OUT_OF_RANGE,
    ),
    setting(
        Refusal::PinNotASwitchInput,
        bad_setting::PIN_NOT_A_SWITCH_INPUT,
    ),
];

fn row_of(refusal: Refusal) -> &'static Row {
    // TABLE is in Refusal::ALL's order (tested), so the search always hits.
    TABLE
        .iter()
        .find(|row| row.refusal == refusal)
        .unwrap_or(&TABLE[0])
}

fn value_of(value: Value, values: &RefusalValues) -> u32 {
    match value {
        Value::Speed => values.speed,
        Value::Clock => values.clkfreq,
        Value::Offset => values.offset_deg,
    }
}

/// The code a refusal is sent with.
pub fn refusal_code(refusal: Refusal) -> ErrorCode {
    row_of(refusal).code
}

/// Writes a refusal's text (what follows `error:<code> `), its numbers
/// filled in.
pub fn write_refusal_text<W: fmt::Write + ?Sized>(
    out: &mut W,
    refusal: Refusal,
    values: &RefusalValues,
) -> fmt::Result {
    let row = row_of(refusal);
    match row.text {
        Text::Setting(text) => {
            out.write_str(SETTING_PREFIX)?;
            out.write_str(text)
        }
        Text::Fixed(text) => {
            let mut pieces = text.split("{}");
            out.write_str(pieces.next().unwrap_or_default())?;
            for (value, piece) in row.values.iter().zip(pieces) {
                write!(out, "{}{piece}", value_of(*value, values))?;
            }
            Ok(())
        }
    }
}

/// Writes a refusal's whole reply line, `error:<code> <text>` and
/// [`LINE_END`].
pub fn write_refusal_line<W: fmt::Write + ?Sized>(
    out: &mut W,
    refusal: Refusal,
    values: &RefusalValues,
) -> fmt::Result {
    write!(out, "error:{} ", refusal_code(refusal).number())?;
    write_refusal_text(out, refusal, values)?;
    out.write_str(LINE_END)
}

/// Reads an `error:<code> <text>` (split as [`Reply::Error`](super::Reply)
/// holds it) back to the refusal it is and its numbers; `None` for any
/// other code and text (a transport error, a parse error, a board's text
/// this table does not have).
pub fn refusal_of_error(code: u8, text: &str) -> Option<(Refusal, RefusalValues)> {
    TABLE
        .iter()
        .filter(|row| row.code.number() == code)
        .find_map(|row| Some((row.refusal, match_row(row, text)?)))
}

/// Reads a whole reply line (its line end, if any, ignored) back to the
/// refusal it is; see [`refusal_of_error`].
pub fn refusal_of_reply(line: &str) -> Option<(Refusal, RefusalValues)> {
    match super::Reply::parse(line)? {
        super::Reply::Error { code, text } => refusal_of_error(code, text),
        _ => None,
    }
}

/// Reads a reply line back to the [`AxisError`] it stands for, when it is
/// a refusal.
pub fn axis_error_of_reply(line: &str) -> Option<AxisError> {
    refusal_of_reply(line).map(|(refusal, values)| AxisError::from_refusal(refusal, values))
}

/// The numbers in `text` if it is `row`'s text exactly.
fn match_row(row: &Row, text: &str) -> Option<RefusalValues> {
    let template = match row.text {
        Text::Setting(setting) => {
            return (text.strip_prefix(SETTING_PREFIX)? == setting)
                .then_some(RefusalValues::default())
        }
        Text::Fixed(template) => template,
    };
    let mut values = RefusalValues::default();
    let mut pieces = template.split("{}");
    let mut rest = text.strip_prefix(pieces.next()?)?;
    for (value, piece) in row.values.iter().zip(pieces) {
        let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
        let (number, after) = rest.split_at(digits);
        // Only the number as the board writes it: no leading zeros.
        if number.is_empty() || (number.len() > 1 && number.starts_with('0')) {
            return None;
        }
        let number: u32 = number.parse().ok()?;
        match value {
            Value::Speed => values.speed = number,
            Value::Clock => values.clkfreq = number,
            Value::Offset => values.offset_deg = number,
        }
        rest = after.strip_prefix(piece)?;
    }
    rest.is_empty().then_some(values)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::string::String;

    use super::*;

    fn line_of(refusal: Refusal, values: &RefusalValues) -> String {
        let mut line = String::new();
        write_refusal_line(&mut line, refusal, values).unwrap();
        line
    }

    #[test]
    fn the_table_has_every_refusal_once_in_order_with_its_values() {
        for (row, refusal) in TABLE.iter().zip(Refusal::ALL) {
            assert_eq!(row.refusal, refusal);
            if let Text::Fixed(text) = row.text {
                assert_eq!(text.matches("{}").count(), row.values.len(), "{text}");
                assert!(
                    text == row.code.text() || text.starts_with(row.code.text()),
                    "{text} does not start with its code's text"
                );
            }
        }
        // The numbers a row writes are the ones the error carries.
        for refusal in Refusal::ALL {
            let values = RefusalValues {
                speed: 1,
                clkfreq: 2,
                offset_deg: 3,
            };
            let carried = AxisError::from_refusal(refusal, values).refusal_values();
            let written: std::vec::Vec<Value> = row_of(refusal).values.to_vec();
            assert_eq!(carried.speed != 0, written.contains(&Value::Speed));
            assert_eq!(carried.clkfreq != 0, written.contains(&Value::Clock));
            assert_eq!(carried.offset_deg != 0, written.contains(&Value::Offset));
        }
    }

    #[test]
    fn every_refusal_line_is_distinct_fits_and_reads_back() {
        let mut lines = std::collections::BTreeSet::new();
        for refusal in Refusal::ALL {
            for values in [
                RefusalValues::default(),
                RefusalValues {
                    speed: u32::MAX,
                    clkfreq: u32::MAX,
                    offset_deg: u32::MAX,
                },
                RefusalValues {
                    speed: 50_000_000,
                    clkfreq: 200_000_000,
                    offset_deg: 90,
                },
            ] {
                let error = AxisError::from_refusal(refusal, values);
                let line = line_of(refusal, &error.refusal_values());
                assert!(line.len() <= crate::REPLY_LINE_MAX, "{line}");
                // The board's writer is this table.
                let mut written = String::new();
                let refused = crate::ProtocolError::Axis(error);
                refused.write_reply(&mut written).unwrap();
                assert_eq!(written, line);
                assert_eq!(refused.code(), refusal_code(refusal));
                assert_eq!(axis_error_of_reply(&line), Some(error), "{line}");
                assert_eq!(
                    refusal_of_reply(line.trim_end()),
                    Some((refusal, error.refusal_values()))
                );
            }
            assert!(lines.insert(line_of(refusal, &RefusalValues::default())));
        }
    }

    /// docs/protocol.md lists every refusal with its token, code and line.
    #[test]
    fn the_protocol_document_lists_every_refusal_line() {
        let doc = include_str!("../../docs/protocol.md");
        for refusal in Refusal::ALL {
            let row = row_of(refusal);
            let mut text = String::new();
            match row.text {
                Text::Setting(setting) => text = std::format!("{SETTING_PREFIX}{setting}"),
                Text::Fixed(template) => {
                    let mut pieces = template.split("{}");
                    text.push_str(pieces.next().unwrap());
                    for (value, piece) in row.values.iter().zip(pieces) {
                        text.push_str(match value {
                            Value::Speed => "<speed>",
                            Value::Clock => "<clkfreq>",
                            Value::Offset => "<offset>",
                        });
                        text.push_str(piece);
                    }
                }
            }
            let entry = std::format!("| `{}` ({}) |", refusal.token(), refusal.code());
            let line = std::format!("| `error:{} {text}` |", row.code.number());
            let found = doc
                .lines()
                .any(|doc_line| doc_line.starts_with(&entry) && doc_line.ends_with(&line));
            assert!(found, "docs/protocol.md has no row {entry} ... {line}");
        }
    }

    #[test]
    fn other_lines_are_no_refusal() {
        for line in [
            "ok",
            "error:2 bad argument",
            "error:6 speed out of range",
            "error:2 fault: driver hot",
            "error:1 not supported: jog",
            "error:4 axis not available",
            "error:3 not idle",
            "error:7 busy",
            "error:7 not idle: stop pin low ",
            "error:6 speed out of range: no room for the step pulse at 050 steps/s",
            "error:6 speed out of range: no room for the step pulse at -5 steps/s",
            "error:6 speed out of range: no room for the step pulse at 4294967296 steps/s",
            "error:6 speed out of range: no room for the step pulse at  steps/s",
            "error:2 bad argument: a made-up setting",
            "[cogstep 0.1.0 proto:1 axes:2 clkfreq:200000000]",
        ] {
            assert_eq!(refusal_of_reply(line), None, "{line}");
        }
    }
}

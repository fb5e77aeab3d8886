//! Reply lines: error codes, status lines, and reading replies back.
//!
//! Every command line gets exactly one final reply, `ok` or
//! `error:<code> <text>`; information lines (`[...]`) and status lines
//! (`<...>`) may come before it. The board ends every reply line with
//! [`LINE_END`].

use core::fmt;

use cogstep_motion::axis::{AxisError, AxisState, AxisStatus, Direction, HomeReport};
use cogstep_motion::axis::{LimitStatus, LimitTrip, Mode};

/// What the board ends each reply line with: LF, as the protocol's lines
/// are ended (hosts also accept CR LF from boards that send it).
pub const LINE_END: &str = "\n";

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
    /// 5: the line was longer than [`LINE_MAX`](super::LINE_MAX) bytes.
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
    /// The line was longer than [`LINE_MAX`](super::LINE_MAX) bytes.
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
    /// ([`write_refusal_line`](super::write_refusal_line)); the transport
    /// errors name what went wrong: `not supported: <what>` (code 1), `axis
    /// not available` (code 4), `fault: <what>` (code 2), and a setting no
    /// refusal names `bad argument: <what>` (code 2); every other error is
    /// its code's [`text`](ErrorCode::text).
    pub fn write_reply<W: fmt::Write + ?Sized>(&self, out: &mut W) -> fmt::Result {
        if let ProtocolError::Axis(error) = self {
            if let Some(refusal) = error.refusal() {
                return super::write_refusal_line(out, refusal, &error.refusal_values());
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
        return super::refusal_code(refusal);
    }
    match error {
        AxisError::Unsupported(_) => ErrorCode::UnknownCommand,
        AxisError::Unavailable => ErrorCode::NoSuchAxis,
        _ => ErrorCode::BadArgument,
    }
}

/// The most characters of text from a backend (a fault's or an
/// unsupported request's description, an error message) that go into one
/// reply line; the rest is cut, so that every line fits in
/// [`REPLY_LINE_MAX`](super::REPLY_LINE_MAX).
pub(crate) const BACKEND_TEXT_MAX: usize = 64;

/// Writes `text` with every character outside printable ASCII replaced by
/// `?`, cut at `max_chars` characters, so that no text from a backend can
/// break a reply line or make it too long.
pub(crate) fn write_printable<W: fmt::Write + ?Sized>(
    out: &mut W,
    text: &str,
    max_chars: usize,
) -> fmt::Result {
    write_display_printable(out, &text, max_chars)
}

/// Formats anything [`fmt::Display`] as [`write_printable`] writes text.
pub(crate) fn write_display_printable<W: fmt::Write + ?Sized>(
    out: &mut W,
    value: &dyn fmt::Display,
    max_chars: usize,
) -> fmt::Result {
    let mut printable = Printable {
        out,
        remaining: max_chars,
    };
    fmt::write(&mut printable, format_args!("{value}"))
}

struct Printable<'w, W: fmt::Write + ?Sized> {
    out: &'w mut W,
    /// Characters still allowed.
    remaining: usize,
}

impl<W: fmt::Write + ?Sized> fmt::Write for Printable<'_, W> {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        for c in text.chars() {
            if self.remaining == 0 {
                break;
            }
            self.remaining -= 1;
            self.out
                .write_char(if (' '..='~').contains(&c) { c } else { '?' })?;
        }
        Ok(())
    }
}

/// The `L` reply's three information lines: an axis's limit and homing
/// state (three lines, so that each stays within
/// [`REPLY_LINE_MAX`](super::REPLY_LINE_MAX) whatever the numbers).
///
/// ```text
/// [limits 0 soft:-1000,50000 min:11/1 max:-]
/// [fault 0 max,51234,51234,120]
/// [home 0 ok,-1783,-3217,-3217,-3217,12]
/// ```
///
/// - `soft:` `<min>,<max>` or `none`; `min:`, `max:` the hard limit
///   inputs, `<pin>/<active level>` or `-`;
/// - `fault` `none`, or `<min|max>,<position>,<physical>,<stopping steps>`
///   of the trip;
/// - `home` `none` (never homed), `homing`, `ok,<seek position>,<seek
///   physical>,<latch position>,<latch physical>,<position>`, or
///   `error,<notfound|stuck|aborted|limit-min|limit-max|range|failed>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LimitLine {
    /// The axis, 0-based.
    pub axis: usize,
    /// Its limit and homing state.
    pub status: LimitStatus,
}

fn side_word(side: Direction) -> &'static str {
    match side {
        Direction::Forward => "max",
        Direction::Reverse => "min",
    }
}

const HOME_ERRORS: [(&str, AxisError); 6] = [
    ("notfound", AxisError::HomeSwitchNotFound),
    ("stuck", AxisError::HomeSwitchStuck),
    ("aborted", AxisError::HomingAborted),
    ("limit-min", AxisError::IntoLimit(Direction::Reverse)),
    ("limit-max", AxisError::IntoLimit(Direction::Forward)),
    ("range", AxisError::PositionOutOfRange),
];

impl LimitLine {
    /// Writes the three lines, each with its line end.
    pub fn write_lines<W: fmt::Write + ?Sized>(&self, out: &mut W) -> fmt::Result {
        let status = &self.status;
        write!(out, "[limits {} soft:", self.axis)?;
        match status.soft_limits {
            Some((min, max)) => write!(out, "{min},{max}")?,
            None => out.write_str("none")?,
        }
        out.write_str(" min:")?;
        super::command::write_limit_pin(out, status.limit_pins[0])?;
        out.write_str(" max:")?;
        super::command::write_limit_pin(out, status.limit_pins[1])?;
        write!(out, "]{LINE_END}[fault {} ", self.axis)?;
        match status.trip {
            Some(trip) => write!(
                out,
                "{},{},{},{}",
                side_word(trip.side),
                trip.position,
                trip.physical,
                trip.stopping_steps
            )?,
            None => out.write_str("none")?,
        }
        write!(out, "]{LINE_END}[home {} ", self.axis)?;
        match (status.homing, status.home_outcome) {
            (true, _) => out.write_str("homing")?,
            (false, None) => out.write_str("none")?,
            (false, Some(Ok(report))) => write!(
                out,
                "ok,{},{},{},{},{}",
                report.seek_position,
                report.seek_physical,
                report.latch_position,
                report.latch_physical,
                report.position
            )?,
            (false, Some(Err(error))) => {
                let word = HOME_ERRORS
                    .iter()
                    .find(|(_, known)| *known == error)
                    .map_or("failed", |(word, _)| word);
                write!(out, "error,{word}")?
            }
        }
        write!(out, "]{LINE_END}")
    }

    /// Reads one of the three lines (host side; with or without brackets
    /// and line end) into `status`, and returns its axis; `None` for a
    /// line that is none of them or is out of shape (`status` unchanged).
    pub fn parse_into(line: &str, status: &mut LimitStatus) -> Option<usize> {
        let inner = line.trim_end_matches(['\r', '\n']);
        let inner = inner.strip_prefix('[').unwrap_or(inner);
        let inner = inner.strip_suffix(']').unwrap_or(inner);
        let mut words = inner.split(' ');
        let kind = words.next()?;
        let axis = words.next()?.parse().ok()?;
        let mut read = *status;
        match kind {
            "limits" => {
                read.soft_limits = match words.next()?.strip_prefix("soft:")? {
                    "none" => None,
                    pair => {
                        let (min, max) = pair.split_once(',')?;
                        Some((min.parse().ok()?, max.parse().ok()?))
                    }
                };
                let pin = |word: &str| super::command::parse_limit_pin(word.as_bytes()).ok();
                read.limit_pins = [
                    pin(words.next()?.strip_prefix("min:")?)?,
                    pin(words.next()?.strip_prefix("max:")?)?,
                ];
            }
            "fault" => {
                read.trip = match words.next()? {
                    "none" => None,
                    fault => {
                        let mut parts = fault.split(',');
                        let side = match parts.next()? {
                            "max" => Direction::Forward,
                            "min" => Direction::Reverse,
                            _ => return None,
                        };
                        let trip = LimitTrip {
                            side,
                            position: parts.next()?.parse().ok()?,
                            physical: parts.next()?.parse().ok()?,
                            stopping_steps: parts.next()?.parse().ok()?,
                        };
                        if parts.next().is_some() {
                            return None;
                        }
                        Some(trip)
                    }
                };
            }
            "home" => {
                (read.homing, read.home_outcome) = match words.next()? {
                    "none" => (false, None),
                    "homing" => (true, None),
                    home => {
                        let mut parts = home.split(',');
                        let outcome = match parts.next()? {
                            "ok" => {
                                let mut number = || parts.next()?.parse::<i64>().ok();
                                Ok(HomeReport {
                                    seek_position: number()?,
                                    seek_physical: number()?,
                                    latch_position: number()?,
                                    latch_physical: number()?,
                                    position: number()?,
                                })
                            }
                            "error" => {
                                let word = parts.next()?;
                                Err(HOME_ERRORS
                                    .iter()
                                    .find(|(known, _)| *known == word)
                                    .map_or(AxisError::Fault("homing failed"), |(_, e)| *e))
                            }
                            _ => return None,
                        };
                        if parts.next().is_some() {
                            return None;
                        }
                        (false, Some(outcome))
                    }
                };
            }
            _ => return None,
        }
        if words.next().is_some() {
            return None;
        }
        *status = read;
        Some(axis)
    }
}

/// One status line: `<0|Run|pos:1200|stm:0|togo:800|mode:001011|vel:20000|stop:high>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StatusLine {
    /// The axis, 0-based.
    pub axis: usize,
    /// `Idle`, `Run`, `Jog`, `Hold` or `Alarm`.
    pub state: AxisState,
    /// Steps from the origin.
    pub position: i64,
    /// The reference's STM: the signed steps of a command not yet taken
    /// (0 once the axis has it, which is always so when a board replies).
    pub stm: i32,
    /// Steps still to make; 0 exactly when the axis is idle.
    pub steps_to_go: u64,
    /// The reference driver's 6 mode bits (bits 0–5).
    pub mode_bits: u8,
    /// The velocity of the last step, steps/s.
    pub velocity_steps_per_s: u32,
    /// Whether the stop pin is high.
    pub stop_pin_high: bool,
}

impl StatusLine {
    /// The status line of one axis.
    pub fn new(axis: usize, status: &AxisStatus) -> Self {
        StatusLine {
            axis,
            state: status.state(),
            position: status.position,
            stm: status.stm,
            steps_to_go: status.steps_to_go,
            // bits() keeps 6 bits, so the cast is exact.
            mode_bits: status.mode.reference_bits() as u8,
            velocity_steps_per_s: status.velocity_steps_per_s,
            stop_pin_high: status.stop_pin_high,
        }
    }

    /// Reads a status line back (host side). The line end, if any, is
    /// ignored; anything else out of shape gives `None`.
    pub fn parse(line: &str) -> Option<Self> {
        let inner = line
            .trim_end_matches(['\r', '\n'])
            .strip_prefix('<')?
            .strip_suffix('>')?;
        let mut fields = inner.split('|');
        let axis = fields.next()?.parse().ok()?;
        let state = match fields.next()? {
            "Idle" => AxisState::Idle,
            "Run" => AxisState::Run,
            "Jog" => AxisState::Jog,
            "Hold" => AxisState::Hold,
            "Alarm" => AxisState::Alarm,
            _ => return None,
        };
        let position = fields.next()?.strip_prefix("pos:")?.parse().ok()?;
        let stm = fields.next()?.strip_prefix("stm:")?.parse().ok()?;
        let steps_to_go = fields.next()?.strip_prefix("togo:")?.parse().ok()?;
        let mode = fields.next()?.strip_prefix("mode:")?;
        if mode.len() != 6 || !mode.bytes().all(|b| b == b'0' || b == b'1') {
            return None;
        }
        let mode_bits = u8::from_str_radix(mode, 2).ok()?;
        let velocity_steps_per_s = fields.next()?.strip_prefix("vel:")?.parse().ok()?;
        let stop_pin_high = match fields.next()?.strip_prefix("stop:")? {
            "high" => true,
            "low" => false,
            _ => return None,
        };
        if fields.next().is_some() {
            return None;
        }
        Some(StatusLine {
            axis,
            state,
            position,
            stm,
            steps_to_go,
            mode_bits,
            velocity_steps_per_s,
            stop_pin_high,
        })
    }
}

/// The status line without its line end.
impl fmt::Display for StatusLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mode = Mode(u32::from(self.mode_bits)).binary();
        write!(
            f,
            "<{}|{}|pos:{}|stm:{}|togo:{}|mode:",
            self.axis,
            self.state.as_str(),
            self.position,
            self.stm,
            self.steps_to_go
        )?;
        for digit in mode {
            fmt::Write::write_char(f, char::from(digit))?;
        }
        let stop = if self.stop_pin_high { "high" } else { "low" };
        write!(f, "|vel:{}|stop:{stop}>", self.velocity_steps_per_s)
    }
}

/// One reply line as a host reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reply<'a> {
    /// `ok`: the command was carried out.
    Ok,
    /// `error:<code> <text>`: the command was refused; nothing changed.
    Error {
        /// The code number (see [`ErrorCode::from_number`]).
        code: u8,
        /// The text after the code.
        text: &'a str,
    },
    /// `[...]`: information, the brackets removed.
    Info(&'a str),
    /// `<...>`: an axis's status.
    Status(StatusLine),
}

impl<'a> Reply<'a> {
    /// Reads one reply line (its line end, if any, is ignored). `None` for a
    /// line the protocol does not define.
    pub fn parse(line: &'a str) -> Option<Self> {
        let line = line.trim_end_matches(['\r', '\n']);
        if line == "ok" {
            return Some(Reply::Ok);
        }
        if let Some(rest) = line.strip_prefix("error:") {
            let (code, text) = rest.split_once(' ').unwrap_or((rest, ""));
            return Some(Reply::Error {
                code: code.parse().ok()?,
                text,
            });
        }
        if let Some(info) = line.strip_prefix('[') {
            return info.strip_suffix(']').map(Reply::Info);
        }
        if line.starts_with('<') {
            return StatusLine::parse(line).map(Reply::Status);
        }
        None
    }

    /// Whether this line ends the reply to a command (`ok` or `error:`).
    pub fn is_final(&self) -> bool {
        matches!(self, Reply::Ok | Reply::Error { .. })
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::string::String;

    use super::*;
    use cogstep_motion::profile::PlanError;

    fn limit_lines(line: &LimitLine) -> String {
        let mut out = String::new();
        line.write_lines(&mut out).unwrap();
        out
    }

    #[test]
    fn limit_lines_read_back_and_fit_a_reply_line() {
        let report = HomeReport {
            seek_position: -1_783,
            seek_physical: -3_217,
            latch_position: -3_217,
            latch_physical: -3_217,
            position: 12,
        };
        let shown = LimitLine {
            axis: 0,
            status: LimitStatus {
                soft_limits: Some((-1_000, 50_000)),
                limit_pins: [Some((11, true)), None],
                trip: Some(LimitTrip {
                    side: Direction::Forward,
                    position: 51_234,
                    physical: 51_234,
                    stopping_steps: 120,
                }),
                homing: false,
                home_outcome: Some(Ok(report)),
            },
        };
        let text = limit_lines(&shown);
        assert_eq!(
            text,
            "[limits 0 soft:-1000,50000 min:11/1 max:-]\n\
             [fault 0 max,51234,51234,120]\n\
             [home 0 ok,-1783,-3217,-3217,-3217,12]\n"
        );
        let mut read = LimitStatus::default();
        for line in text.lines() {
            assert_eq!(LimitLine::parse_into(line, &mut read), Some(0));
        }
        assert_eq!(read, shown.status);
        let extreme = LimitLine {
            axis: 63,
            status: LimitStatus {
                soft_limits: Some((i64::MIN, i64::MAX)),
                limit_pins: [Some((63, false)), Some((62, true))],
                trip: Some(LimitTrip {
                    side: Direction::Reverse,
                    position: i64::MIN,
                    physical: i64::MIN,
                    stopping_steps: u64::MAX,
                }),
                homing: false,
                home_outcome: Some(Ok(HomeReport {
                    seek_position: i64::MIN,
                    seek_physical: i64::MIN,
                    latch_position: i64::MIN,
                    latch_physical: i64::MIN,
                    position: i64::MIN,
                })),
            },
        };
        let text = limit_lines(&extreme);
        let mut read = LimitStatus::default();
        for line in text.split_inclusive('\n') {
            assert!(line.len() <= crate::REPLY_LINE_MAX, "{line}");
            assert_eq!(LimitLine::parse_into(line, &mut read), Some(63));
        }
        assert_eq!(read, extreme.status);
        for error in HOME_ERRORS.map(|(_, error)| error) {
            let failed = LimitLine {
                axis: 1,
                status: LimitStatus {
                    home_outcome: Some(Err(error)),
                    ..LimitStatus::default()
                },
            };
            let mut read = LimitStatus::default();
            for line in limit_lines(&failed).lines() {
                LimitLine::parse_into(line, &mut read).unwrap();
            }
            assert_eq!(read, failed.status);
        }
        for bad in [
            "[home 0 ok,1,2]",
            "[fault 0 up,1,2,3]",
            "[limits x soft:none min:- max:-]",
        ] {
            let mut read = LimitStatus::default();
            assert_eq!(LimitLine::parse_into(bad, &mut read), None, "{bad}");
            assert_eq!(read, LimitStatus::default());
        }
    }

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

    #[test]
    fn the_status_line_format_is_exact() {
        let status = AxisStatus {
            position: 1200,
            stm: 0,
            steps_to_go: 800,
            mode: Mode(0b001011),
            velocity_steps_per_s: 20_000,
            stop_pin_high: true,
        };
        let line = StatusLine::new(0, &status);
        assert_eq!(
            std::format!("{line}"),
            "<0|Run|pos:1200|stm:0|togo:800|mode:001011|vel:20000|stop:high>"
        );
        assert_eq!(
            StatusLine::parse(
                "<0|Run|pos:1200|stm:0|togo:800|mode:001011|vel:20000|stop:high>\r\n"
            ),
            Some(line)
        );

        let alarm = AxisStatus {
            position: -5,
            stm: 0,
            steps_to_go: 0,
            mode: Mode::ESTOP | Mode::STOP_LATCHED | Mode::REVERSE,
            velocity_steps_per_s: 0,
            stop_pin_high: false,
        };
        assert_eq!(
            std::format!("{}", StatusLine::new(7, &alarm)),
            "<7|Alarm|pos:-5|stm:0|togo:0|mode:110000|vel:0|stop:low>"
        );
    }

    #[test]
    fn status_lines_out_of_shape_are_not_read() {
        for line in [
            "<0|Run|pos:1|stm:0|togo:1|mode:00101|vel:1|stop:high>",
            "<0|Walk|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:high>",
            "<0|Run|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:high|x>",
            "<0|Run|pos:1|stm:0|togo:1|mode:001021|vel:1|stop:high>",
            "<0|Run|pos:1|stm:-1|mode:001011|vel:1|stop:high>",
            "<0|Run|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:up>",
            "0|Run|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:high>",
            "<0|Run|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:high",
        ] {
            assert_eq!(StatusLine::parse(line), None, "{line}");
        }
    }

    #[test]
    fn replies_are_read_back() {
        assert_eq!(Reply::parse("ok\n"), Some(Reply::Ok));
        assert_eq!(
            Reply::parse("error:7 not idle"),
            Some(Reply::Error {
                code: 7,
                text: "not idle"
            })
        );
        assert_eq!(
            Reply::parse("[cogstep 0.1.0 proto:1 axes:2 clkfreq:200000000]\n"),
            Some(Reply::Info(
                "cogstep 0.1.0 proto:1 axes:2 clkfreq:200000000"
            ))
        );
        assert!(matches!(
            Reply::parse("<1|Idle|pos:0|stm:0|togo:0|mode:000000|vel:0|stop:high>"),
            Some(Reply::Status(StatusLine { axis: 1, .. }))
        ));
        assert_eq!(Reply::parse("okay"), None);
        assert_eq!(Reply::parse("error:x y"), None);
        assert!(Reply::Ok.is_final());
        assert!(!Reply::Info("").is_final());
    }
}
